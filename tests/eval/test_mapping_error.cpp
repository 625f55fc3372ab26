// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <vector>

namespace {

using planar_grid::AxisAlignedBox;
using planar_grid::AxisAlignedBoxes;
using planar_grid::GroundTruthSurface;
using planar_grid::MappingError;
using planar_grid::MappingErrorRegion;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::StandardVoxelGrid;
using planar_grid::VoxelIndex;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

constexpr double RESOLUTION_M = 0.1;
/** \brief Half a voxel: a sample on the truth is within 0.0071 m of a truth point
 * (spacing 0.01 m), one a voxel off is 0.1 m away. */
constexpr double TOLERANCE_M = 0.05;

/** \brief The truth: the rectangle origin + s u + t v, s, t in [-1, 1], sampled every
 * 0.01 m (201 x 201 points). */
GroundTruthSurface
rectangleTruth(const Eigen::Vector3f& origin,
               const Eigen::Vector3f& u,
               const Eigen::Vector3f& v)
{
  Cloud::Ptr cloud(new Cloud);
  for (int j = -100; j <= 100; ++j)
    for (int i = -100; i <= 100; ++i) {
      const Eigen::Vector3f p = origin + (0.01f * static_cast<float>(i)) * u
                                + (0.01f * static_cast<float>(j)) * v;
      cloud->push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    }
  return GroundTruthSurface(cloud);
}

/** \brief The horizontal truth plane z = 1.05 m (the centres of voxel layer 10) over
 * x, y in [0, 2]. */
GroundTruthSurface
horizontalTruth()
{
  return rectangleTruth(Eigen::Vector3f(1.0f, 1.0f, 1.05f), Eigen::Vector3f::UnitX(),
                        Eigen::Vector3f::UnitY());
}

/** \brief A grid whose occupied voxels are x, y in [5, 15), z = layer (points at
 * sub-voxel centres of the plane z = (layer + 0.5) r, seen from 2 m above). */
StandardVoxelGrid
planeGrid(int layer)
{
  StandardVoxelGrid::Params p;
  p.resolution_m = RESOLUTION_M;
  StandardVoxelGrid grid(p);
  Cloud cloud;
  const float z = (static_cast<float>(layer) + 0.5f) * 0.1f;
  for (int j = 0; j < 40; ++j)
    for (int i = 0; i < 40; ++i)
      cloud.push_back(pcl::PointXYZ(0.5f + 0.025f * (static_cast<float>(i) + 0.5f),
                                    0.5f + 0.025f * (static_cast<float>(j) + 0.5f), z));
  grid.insertPointCloud(cloud, Eigen::Vector3f(1.0f, 1.0f, z + 2.0f));
  return grid;
}

PlanarCuboid
cuboid(const Eigen::Vector3f& centre,
       const Eigen::Vector3f& normal,
       const Eigen::Vector3f& horizontal_axis,
       float width_m,
       float height_m,
       float thickness_m,
       float probability = 0.9f)
{
  PlanarCuboid c;
  c.centre = centre;
  c.normal = normal;
  c.horizontal_axis = horizontal_axis;
  c.width_m = width_m;
  c.height_m = height_m;
  c.thickness_m = thickness_m;
  c.probability = probability;
  c.is_planar = true;
  c.plane_id = 0;
  return c;
}

TEST(GroundTruthSurface, DistanceMatchesBruteForce)
{
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> coord(-2.0f, 2.0f);
  Cloud::Ptr truth_points(new Cloud);
  for (int i = 0; i < 500; ++i)
    truth_points->push_back(pcl::PointXYZ(coord(rng), coord(rng), coord(rng)));
  truth_points->push_back(
    pcl::PointXYZ(std::numeric_limits<float>::quiet_NaN(), 0.0f, 0.0f)); // dropped
  const GroundTruthSurface truth(truth_points);
  EXPECT_EQ(truth.size(), 500u);
  for (int q = 0; q < 200; ++q) {
    const Eigen::Vector3f p(coord(rng), coord(rng), coord(rng));
    float best = std::numeric_limits<float>::infinity();
    for (std::size_t i = 0; i < 500; ++i)
      best = std::min(best, (truth_points->points[i].getVector3fMap() - p).norm());
    EXPECT_NEAR(truth.distance(p), best, 1e-5f) << q;
  }
  EXPECT_TRUE(std::isinf(truth.distance(Eigen::Vector3f::Constant(NAN))));
}

TEST(GroundTruthSurface, ThrowsOnEmpty)
{
  EXPECT_THROW(GroundTruthSurface{Cloud::ConstPtr()}, planar_grid::Exception);
  EXPECT_THROW(GroundTruthSurface{Cloud::Ptr(new Cloud)}, planar_grid::Exception);
  Cloud::Ptr all_nan(new Cloud);
  all_nan->push_back(pcl::PointXYZ(NAN, NAN, NAN));
  EXPECT_THROW(GroundTruthSurface{all_nan}, planar_grid::Exception);
}

TEST(MappingError, VoxelsOnTruthAndDisplaced)
{
  const GroundTruthSurface truth = horizontalTruth();
  const StandardVoxelGrid on = planeGrid(10);
  ASSERT_EQ(on.getOccupiedCount(), 100u); // 10 x 10 voxels
  MappingError e = planar_grid::evaluateVoxels(on, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 100u);
  EXPECT_EQ(e.erroneous, 0u);
  // The same voxels 1 m higher (layer 20): every one erroneous.
  const StandardVoxelGrid off = planeGrid(20);
  e = planar_grid::evaluateVoxels(off, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 100u);
  EXPECT_EQ(e.erroneous, 100u);
  // One layer off (0.1 m) is erroneous at half a voxel, fine at 0.15 m.
  const StandardVoxelGrid next = planeGrid(11);
  EXPECT_EQ(planar_grid::evaluateVoxels(next, truth, TOLERANCE_M).erroneous, 100u);
  EXPECT_EQ(planar_grid::evaluateVoxels(next, truth, 0.15).erroneous, 0u);
}

TEST(MappingError, BoxesOnTruthAndDisplaced)
{
  const GroundTruthSurface truth = horizontalTruth();
  AxisAlignedBoxes boxes;
  boxes.push_back({VoxelIndex(5, 5, 10), Eigen::Vector3i(10, 10, 1), true});
  boxes.push_back({VoxelIndex(5, 5, 11), Eigen::Vector3i(10, 10, 5), false}); // free
  MappingError e = planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 100u); // 10 x 10 x 1 voxels; the free box is not counted
  EXPECT_EQ(e.erroneous, 0u);
  boxes.push_back({VoxelIndex(0, 0, 20), Eigen::Vector3i(4, 3, 2), true}); // 1 m up
  e = planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 124u); // + 4 x 3 x 2
  EXPECT_EQ(e.erroneous, 24u);
}

TEST(MappingError, CuboidsOnTruthAndDisplaced)
{
  // A tilted truth plane (normal 40 deg from z) and a cuboid lying on it, 1 m x
  // 0.8 m x 0.1 m: 10 x 8 x 1 samples, all on the plane.
  const float a = 40.0f * static_cast<float>(M_PI) / 180.0f;
  const Eigen::Vector3f n(0.0f, -std::sin(a), std::cos(a));
  const Eigen::Vector3f u = Eigen::Vector3f::UnitX();
  const Eigen::Vector3f v = n.cross(u);
  const Eigen::Vector3f p0(1.0f, 1.0f, 1.0f);
  const GroundTruthSurface truth = rectangleTruth(p0, u, v);
  PlanarCuboids cuboids;
  cuboids.push_back(cuboid(p0, n, u, 1.0f, 0.8f, 0.1f));
  MappingError e =
    planar_grid::evaluateCuboids(cuboids, 0.5, RESOLUTION_M, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 80u);
  EXPECT_EQ(e.erroneous, 0u);
  // Displaced 1 m along its normal: all 80 erroneous.
  cuboids.push_back(cuboid(p0 + n, n, u, 1.0f, 0.8f, 0.1f));
  e = planar_grid::evaluateCuboids(cuboids, 0.5, RESOLUTION_M, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 160u);
  EXPECT_EQ(e.erroneous, 80u);
  // Below occupancy_thres: not counted; exactly at it: counted.
  cuboids.push_back(cuboid(p0 + 2.0f * n, n, u, 1.0f, 0.8f, 0.1f, 0.3f));
  cuboids.push_back(cuboid(p0, n, u, 0.1f, 0.1f, 0.1f, 0.5f));
  e = planar_grid::evaluateCuboids(cuboids, 0.5, RESOLUTION_M, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 161u);
  EXPECT_EQ(e.erroneous, 80u);
}

TEST(MappingError, CuboidSampleCountIsVolumeOverVoxel)
{
  // 0.6 x 0.4 x 0.3 m = 0.072 m^3 = 72 voxels of 0.1 m, 576 of 0.05 m, whatever the
  // orientation; 0.3f is 0.30000001 m (the 1e-3 margin keeps it 3 samples).
  const GroundTruthSurface truth = horizontalTruth();
  const Eigen::Vector3f centre(1.0f, 1.0f, 1.05f);
  const Eigen::Vector3f n_tilted = Eigen::Vector3f(0.3f, -0.5f, 0.8f).normalized();
  const Eigen::Vector3f u_tilted =
    n_tilted.cross(Eigen::Vector3f::UnitZ()).normalized();
  for (const bool tilted : {false, true}) {
    PlanarCuboids cuboids;
    cuboids.push_back(cuboid(centre, tilted ? n_tilted : Eigen::Vector3f::UnitZ(),
                             tilted ? u_tilted : Eigen::Vector3f::UnitX(), 0.6f, 0.4f,
                             0.3f));
    const double volume_m3 = 0.6 * 0.4 * 0.3;
    for (const double r : {0.1, 0.05}) {
      const MappingError e = planar_grid::evaluateCuboids(cuboids, 0.5, r, truth, 10.0);
      EXPECT_EQ(e.samples,
                static_cast<std::size_t>(std::lround(volume_m3 / (r * r * r))))
        << tilted << " " << r;
      EXPECT_EQ(e.erroneous, 0u); // 10 m tolerance
    }
  }
  // A thin cuboid (2 cm) and a degenerate one (0 m) still count one sample across.
  PlanarCuboids thin;
  thin.push_back(cuboid(centre, Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitX(),
                        0.5f, 0.2f, 0.02f));
  thin.push_back(cuboid(centre, Eigen::Vector3f::UnitZ(), Eigen::Vector3f::UnitX(),
                        0.0f, 0.0f, 0.0f));
  EXPECT_EQ(planar_grid::evaluateCuboids(thin, 0.5, 0.1, truth, TOLERANCE_M).samples,
            5u * 2u + 1u);
}

TEST(MappingError, OcTreePrunedLeavesAreExpanded)
{
  // An 8 x 8 x 2 occupied block at voxel layers z = 10, 11 (OctoMap keys +32768, even:
  // pruned into 2 x 2 x 2 leaves), plus free voxels above: 128 samples; layer 10
  // (centres z = 1.05) is on the truth, layer 11 (1.15) 0.1 m off: 64 erroneous.
  octomap::OcTree tree(RESOLUTION_M);
  for (int z = 10; z < 14; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x) {
        const octomap::OcTreeKey key(static_cast<octomap::key_type>(x + 32768),
                                     static_cast<octomap::key_type>(y + 32768),
                                     static_cast<octomap::key_type>(z + 32768));
        tree.setNodeValue(key, z < 12 ? tree.getClampingThresMaxLog()
                                      : tree.getClampingThresMinLog());
      }
  tree.updateInnerOccupancy();
  tree.prune();
  ASSERT_LT(tree.getNumLeafNodes(), 256u); // pruning happened
  const GroundTruthSurface truth = horizontalTruth();
  const MappingError e = planar_grid::evaluateOcTree(tree, truth, TOLERANCE_M);
  EXPECT_EQ(e.samples, 128u);
  EXPECT_EQ(e.erroneous, 64u);
}

TEST(MappingError, RegionOfInterest)
{
  const GroundTruthSurface truth = horizontalTruth();
  AxisAlignedBoxes boxes;
  boxes.push_back({VoxelIndex(5, 5, 10), Eigen::Vector3i(10, 10, 1), true});
  boxes.push_back({VoxelIndex(5, 5, 20), Eigen::Vector3i(10, 10, 1), true}); // 1 m up
  // Box region x <= 1.0: voxel columns 5..9 (centres 0.55..0.95), both layers.
  MappingErrorRegion box_region;
  box_region.max_m.x() = 1.0f;
  MappingError e =
    planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M, box_region);
  EXPECT_EQ(e.samples, 100u);
  EXPECT_EQ(e.erroneous, 50u);
  EXPECT_EQ(e.cells, 2u); // both boxes reach into the region
  // Ball of 0.35 m around (1, 1, 1.05): centres (0.05 + 0.1 i, 0.05 + 0.1 j) within it,
  // counted by brute force; the upper layer is outside.
  MappingErrorRegion ball;
  ball.centre_m = Eigen::Vector3f(1.0f, 1.0f, 1.05f);
  ball.max_distance_m = 0.35;
  std::size_t inside = 0;
  for (int j = 5; j < 15; ++j)
    for (int i = 5; i < 15; ++i)
      inside +=
        ball.contains(Eigen::Vector3f(0.1f * (static_cast<float>(i) + 0.5f),
                                      0.1f * (static_cast<float>(j) + 0.5f), 1.05f))
          ? 1
          : 0;
  ASSERT_GT(inside, 20u);
  e = planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M, ball);
  EXPECT_EQ(e.samples, inside);
  EXPECT_EQ(e.erroneous, 0u);
  EXPECT_EQ(e.cells, 1u); // only the lower box
  // The same region for voxels, cuboids and the octree; a voxel is one cell.
  const StandardVoxelGrid grid = planeGrid(10);
  const MappingError voxels =
    planar_grid::evaluateVoxels(grid, truth, TOLERANCE_M, ball);
  EXPECT_EQ(voxels.samples, inside);
  EXPECT_EQ(voxels.cells, inside);
  EXPECT_EQ(planar_grid::evaluateVoxels(grid, truth, TOLERANCE_M).cells, 100u);
  PlanarCuboids cuboids;
  cuboids.push_back(cuboid(Eigen::Vector3f(1.0f, 1.0f, 1.05f), Eigen::Vector3f::UnitZ(),
                           Eigen::Vector3f::UnitX(), 1.0f, 1.0f, 0.1f));
  const MappingError in_cuboids =
    planar_grid::evaluateCuboids(cuboids, 0.5, RESOLUTION_M, truth, TOLERANCE_M, ball);
  EXPECT_EQ(in_cuboids.samples, inside);
  EXPECT_EQ(in_cuboids.cells, 1u);
  MappingErrorRegion far_away;
  far_away.centre_m = Eigen::Vector3f(10.0f, 10.0f, 10.0f);
  far_away.max_distance_m = 1.0;
  EXPECT_EQ(planar_grid::evaluateCuboids(cuboids, 0.5, RESOLUTION_M, truth, TOLERANCE_M,
                                         far_away)
              .cells,
            0u);
  octomap::OcTree tree(RESOLUTION_M);
  for (int y = 5; y < 15; ++y)
    for (int x = 5; x < 15; ++x)
      tree.setNodeValue(octomap::OcTreeKey(static_cast<octomap::key_type>(x + 32768),
                                           static_cast<octomap::key_type>(y + 32768),
                                           static_cast<octomap::key_type>(10 + 32768)),
                        tree.getClampingThresMaxLog());
  const MappingError leaves =
    planar_grid::evaluateOcTree(tree, truth, TOLERANCE_M, ball);
  EXPECT_EQ(leaves.samples, inside);
  EXPECT_LE(leaves.cells, inside); // pruned leaves may hold several samples
  EXPECT_GE(leaves.cells, 1u);
  EXPECT_EQ(planar_grid::evaluateOcTree(tree, truth, TOLERANCE_M).samples, 100u);
}

TEST(MappingError, RejectsBadArguments)
{
  const GroundTruthSurface truth = horizontalTruth();
  const StandardVoxelGrid grid = planeGrid(10);
  const AxisAlignedBoxes boxes;
  const PlanarCuboids cuboids;
  octomap::OcTree tree(RESOLUTION_M);
  EXPECT_THROW(planar_grid::evaluateVoxels(grid, truth, -0.1), planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateVoxels(grid, truth, NAN), planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateBoxes(boxes, 0.0, truth, 0.1),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateBoxes(boxes, 0.1, truth, -1.0),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateCuboids(cuboids, 0.5, -0.1, truth, 0.1),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateCuboids(cuboids, 1.5, 0.1, truth, 0.1),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateOcTree(tree, truth, -0.1), planar_grid::Exception);
  // Empty inputs: zero counts.
  const MappingError e = planar_grid::evaluateBoxes(boxes, 0.1, truth, 0.1);
  EXPECT_EQ(e.samples, 0u);
  EXPECT_EQ(e.erroneous, 0u);
  EXPECT_EQ(planar_grid::evaluateOcTree(tree, truth, 0.1).samples, 0u);
  // A non-finite cuboid is skipped.
  PlanarCuboids bad;
  bad.push_back(cuboid(Eigen::Vector3f::Constant(NAN), Eigen::Vector3f::UnitZ(),
                       Eigen::Vector3f::UnitX(), 1.0f, 1.0f, 0.1f));
  EXPECT_EQ(planar_grid::evaluateCuboids(bad, 0.5, 0.1, truth, 0.1).samples, 0u);
}

} // namespace
