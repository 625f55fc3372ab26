// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <map>
#include <random>
#include <tuple>
#include <vector>

namespace {

using planar_grid::AxisAlignedBox;
using planar_grid::AxisAlignedBoxes;
using planar_grid::RectangularCuboidApproximation;
using planar_grid::StandardVoxelGrid;
using planar_grid::VoxelIndex;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Key = std::tuple<int, int, int>;

StandardVoxelGrid::Params
gridParams(double resolution_m)
{
  StandardVoxelGrid::Params p;
  p.resolution_m = resolution_m;
  return p;
}

/** \brief Brute-force check that the boxes partition the observed voxels by class:
 * every voxel of every box is observed and of the box's class, no voxel is in two
 * boxes, every observed voxel is in one (total box volume = voxel count). */
void
expectExactCover(const StandardVoxelGrid& grid, const AxisAlignedBoxes& boxes)
{
  std::map<Key, int> covered;
  std::size_t volume = 0;
  for (const auto& box : boxes) {
    ASSERT_TRUE((box.size.array() >= 1).all());
    for (int k = 0; k < box.size.z(); ++k)
      for (int j = 0; j < box.size.y(); ++j)
        for (int i = 0; i < box.size.x(); ++i) {
          const VoxelIndex v = box.min_index + VoxelIndex(i, j, k);
          float l = 0.0f;
          ASSERT_TRUE(grid.getLogOdds(v, l)) << "unobserved voxel in a box";
          ASSERT_EQ(grid.isOccupied(v), box.occupied) << "voxel of the other class";
          ++covered[Key{v.x(), v.y(), v.z()}];
          ++volume;
        }
  }
  std::vector<StandardVoxelGrid::Voxel> voxels;
  grid.getVoxels(voxels);
  for (const auto& v : voxels) {
    const auto it = covered.find(Key{v.index.x(), v.index.y(), v.index.z()});
    ASSERT_NE(it, covered.end()) << "observed voxel in no box";
    EXPECT_EQ(it->second, 1) << "voxel in more than one box";
  }
  EXPECT_EQ(volume, voxels.size());
  EXPECT_EQ(covered.size(), voxels.size());
}

std::size_t
countOccupied(const AxisAlignedBoxes& boxes)
{
  std::size_t n = 0;
  for (const auto& b : boxes)
    n += b.occupied ? 1 : 0;
  return n;
}

/** \brief A vertical wall of n x m voxels of 0.1 m: the plane x' = 2.05 m (a voxel
 * centre), y' in [0, n r), z in [0, m r), rotated by \a yaw_rad about the z axis
 * through the origin; points every r / 4 at sub-voxel centres, so that the unrotated
 * wall fills exactly the voxels x = 20, y in [0, n), z in [0, m). */
Cloud
voxelWall(int n, int m, double yaw_rad)
{
  const double r = 0.1, step = r / 4.0;
  const double c = std::cos(yaw_rad), s = std::sin(yaw_rad);
  Cloud cloud;
  for (int k = 0; k < 4 * m; ++k)
    for (int j = 0; j < 4 * n; ++j) {
      const double x = 2.05, y = (j + 0.5) * step, z = (k + 0.5) * step;
      cloud.push_back(pcl::PointXYZ(static_cast<float>(c * x - s * y),
                                    static_cast<float>(s * x + c * y),
                                    static_cast<float>(z)));
    }
  return cloud;
}

TEST(RectangularCuboidApproximation, CoversEveryObservedVoxelOnceByClass)
{
  // Random scans of random points from random origins (fixed seeds): free and
  // occupied voxels interleave, and some voxels flip class between scans.
  for (unsigned seed : {1u, 2u, 3u}) {
    std::mt19937 rng(seed);
    std::uniform_real_distribution<float> coord(-1.0f, 1.0f);
    StandardVoxelGrid grid(gridParams(0.1));
    for (int scan = 0; scan < 5; ++scan) {
      Cloud cloud;
      for (int i = 0; i < 300; ++i)
        cloud.push_back(pcl::PointXYZ(coord(rng), coord(rng), coord(rng)));
      grid.insertPointCloud(cloud, Eigen::Vector3f(0.3f * coord(rng), 0.3f * coord(rng),
                                                   0.3f * coord(rng)));
    }
    ASSERT_GT(grid.getOccupiedCount(), 100u);
    ASSERT_GT(grid.getFreeCount(), 100u);
    AxisAlignedBoxes boxes;
    RectangularCuboidApproximation().compute(grid, boxes);
    SCOPED_TRACE(seed);
    expectExactCover(grid, boxes);
    EXPECT_LT(boxes.size(), grid.getVoxelCount()); // something was merged
    EXPECT_EQ(RectangularCuboidApproximation::getMemoryBytes(boxes),
              boxes.size() * sizeof(AxisAlignedBox)); // shrunk to fit
    // Boxes come in the (z, y, x) order of their min_index.
    for (std::size_t i = 1; i < boxes.size(); ++i) {
      const auto& a = boxes[i - 1].min_index;
      const auto& b = boxes[i].min_index;
      EXPECT_LT(std::make_tuple(a.z(), a.y(), a.x()),
                std::make_tuple(b.z(), b.y(), b.x()));
    }
  }
}

TEST(RectangularCuboidApproximation, GreedyOrderOnHandBuiltGrid)
{
  // 1 m voxels. A scan from (0.5, 0.5, 0.5) to points at x = 3.5 in rows y = 0, 1
  // (z = 0): free voxels x = 0..2 in both rows, occupied x = 3 in both rows: the
  // greedy merge gives one 3 x 2 x 1 free box at (0, 0, 0) and one 1 x 2 x 1
  // occupied box at (3, 0, 0).
  StandardVoxelGrid::Params p = gridParams(1.0);
  StandardVoxelGrid grid(p);
  Cloud cloud;
  cloud.push_back(pcl::PointXYZ(3.5f, 0.5f, 0.5f));
  grid.insertPointCloud(cloud, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  cloud.clear();
  cloud.push_back(pcl::PointXYZ(3.5f, 1.5f, 0.5f));
  grid.insertPointCloud(cloud, Eigen::Vector3f(0.5f, 1.5f, 0.5f));
  ASSERT_EQ(grid.getVoxelCount(), 8u);
  AxisAlignedBoxes boxes;
  RectangularCuboidApproximation().compute(grid, boxes);
  ASSERT_EQ(boxes.size(), 2u);
  EXPECT_EQ(boxes[0].min_index, VoxelIndex(0, 0, 0));
  EXPECT_EQ(boxes[0].size, Eigen::Vector3i(3, 2, 1));
  EXPECT_FALSE(boxes[0].occupied);
  EXPECT_EQ(boxes[1].min_index, VoxelIndex(3, 0, 0));
  EXPECT_EQ(boxes[1].size, Eigen::Vector3i(1, 2, 1));
  EXPECT_TRUE(boxes[1].occupied);
  expectExactCover(grid, boxes);
}

TEST(RectangularCuboidApproximation, AxisAlignedWallIsOneBox)
{
  // A 24 x 16-voxel wall seen from (0.05, 1.25, 0.85): its 384 voxels are occupied and
  // form one 1 x 24 x 16 box.
  StandardVoxelGrid grid(gridParams(0.1));
  grid.insertPointCloud(voxelWall(24, 16, 0.0), Eigen::Vector3f(0.05f, 1.25f, 0.85f));
  ASSERT_EQ(grid.getOccupiedCount(), 24u * 16u);
  AxisAlignedBoxes boxes;
  RectangularCuboidApproximation().compute(grid, boxes);
  expectExactCover(grid, boxes);
  ASSERT_EQ(countOccupied(boxes), 1u);
  for (const auto& b : boxes)
    if (b.occupied) {
      EXPECT_EQ(b.min_index, VoxelIndex(20, 0, 0));
      EXPECT_EQ(b.size, Eigen::Vector3i(1, 24, 16));
    }
}

TEST(RectangularCuboidApproximation, RotatedWallNeedsManyBoxes)
{
  // The same wall rotated 30 degrees about z is a staircase in x-y: each z layer is
  // identical, so boxes span the full height, but a run along x covers only 1-2
  // voxels of the wall (the wall advances 1 / tan 30 = 1.7 rows in y per voxel in x),
  // so about one box per row of the staircase (~21 rows) where the aligned wall
  // needed 1.
  StandardVoxelGrid grid(gridParams(0.1));
  grid.insertPointCloud(voxelWall(24, 16, 30.0 * M_PI / 180.0),
                        Eigen::Vector3f(0.05f, 1.25f, 0.85f));
  AxisAlignedBoxes boxes;
  RectangularCuboidApproximation().compute(grid, boxes);
  expectExactCover(grid, boxes);
  const std::size_t occupied = countOccupied(boxes);
  EXPECT_GT(occupied, 5u);
  // and still far fewer than the voxels (whole-height boxes)
  EXPECT_LT(occupied, grid.getOccupiedCount() / 8);
}

TEST(RectangularCuboidApproximation, EmptyGridAndMemory)
{
  StandardVoxelGrid grid(gridParams(0.1));
  AxisAlignedBoxes boxes(3); // replaced
  RectangularCuboidApproximation().compute(grid, boxes);
  EXPECT_TRUE(boxes.empty());
  EXPECT_EQ(sizeof(AxisAlignedBox), 28u);
  boxes.reserve(10);
  EXPECT_EQ(RectangularCuboidApproximation::getMemoryBytes(boxes),
            boxes.capacity() * sizeof(AxisAlignedBox));
}

} // namespace
