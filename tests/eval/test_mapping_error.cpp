// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/map/planar_grid_map.h>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <set>
#include <tuple>
#include <vector>

#include "mapping_error_oracle.h"

namespace {

using planar_grid::AxisAlignedBox;
using planar_grid::AxisAlignedBoxes;
using planar_grid::Completeness;
using planar_grid::GroundTruthSurface;
using planar_grid::MappingError;
using planar_grid::MappingErrorRegion;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::StandardVoxelGrid;
using planar_grid::TruthVoxels;
using planar_grid::VoxelIndex;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using planar_grid::test::OracleBox;
using planar_grid::test::oracleCompleteness;
using planar_grid::test::oracleCuboid;
using planar_grid::test::oracleCuboids;
using planar_grid::test::oracleDistance;
using planar_grid::test::OracleTruth;
using planar_grid::test::oracleTruth;
using planar_grid::test::oracleVoxel;

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

TEST(MappingError, OwnErrorIsErroneousOverTheMethodsOwnSamples)
{
  const GroundTruthSurface truth = horizontalTruth();
  // 100 samples on the truth and 24 samples 1 m above it: 24 / 124 of the boxes'
  // own volume is off the truth, however many cells another method has.
  AxisAlignedBoxes boxes;
  boxes.push_back({VoxelIndex(5, 5, 10), Eigen::Vector3i(10, 10, 1), true});
  boxes.push_back({VoxelIndex(0, 0, 20), Eigen::Vector3i(4, 3, 2), true});
  const MappingError e =
    planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M);
  ASSERT_EQ(e.samples, 124u);
  ASSERT_EQ(e.erroneous, 24u);
  EXPECT_DOUBLE_EQ(e.ownError(), 24.0 / 124.0);
  // Dropping the cells on the truth raises it to 1 (all that is left is wrong).
  boxes.erase(boxes.begin());
  EXPECT_DOUBLE_EQ(
    planar_grid::evaluateBoxes(boxes, RESOLUTION_M, truth, TOLERANCE_M).ownError(),
    1.0);
  // Voxels on the truth: 0; nothing mapped: undefined.
  EXPECT_DOUBLE_EQ(
    planar_grid::evaluateVoxels(planeGrid(10), truth, TOLERANCE_M).ownError(), 0.0);
  EXPECT_TRUE(std::isnan(MappingError{}.ownError()));
  MappingError counts;
  counts.samples = 7;
  counts.erroneous = 3;
  EXPECT_DOUBLE_EQ(counts.ownError(), 3.0 / 7.0);
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
  EXPECT_DOUBLE_EQ(e.ownError(), 0.5);
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

// The completeness and the planar share, against brute-force oracles.

/** \brief Points every 0.02 m (offset 0.01 m) on origin + s u + t v, s in [0,
 * width_m), t in [0, height_m). */
void
addRectangle(Cloud& cloud,
             const Eigen::Vector3f& origin,
             const Eigen::Vector3f& u,
             const Eigen::Vector3f& v,
             float width_m,
             float height_m)
{
  for (float t = 0.01f; t < height_m; t += 0.02f)
    for (float s = 0.01f; s < width_m; s += 0.02f) {
      const Eigen::Vector3f p = origin + s * u + t * v;
      cloud.push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
    }
}

/** \brief A wall in the plane x = 1.05 m (the centres of voxel layer 10 at 0.1 m),
 * y and z in [0, 2): 20 x 20 truth voxels at 0.1 m. */
Cloud::Ptr
wallPoints()
{
  Cloud::Ptr cloud(new Cloud);
  addRectangle(*cloud, Eigen::Vector3f(1.05f, 0.0f, 0.0f), Eigen::Vector3f::UnitY(),
               Eigen::Vector3f::UnitZ(), 2.0f, 2.0f);
  return cloud;
}

TEST(TruthVoxels, VoxelizesAndFindsTheGroundLikeTheOracle)
{
  // A floor (z = 0) over x, y in [0, 3) and a wall x = 1.55 m from the floor to
  // z = 2 m, both sampled every 0.02 m, voxelized at 0.1 m.
  Cloud::Ptr cloud(new Cloud);
  addRectangle(*cloud, Eigen::Vector3f(0.0f, 0.0f, 0.0f), Eigen::Vector3f::UnitX(),
               Eigen::Vector3f::UnitY(), 3.0f, 3.0f);
  addRectangle(*cloud, Eigen::Vector3f(1.55f, 0.0f, 0.0f), Eigen::Vector3f::UnitY(),
               Eigen::Vector3f::UnitZ(), 3.0f, 2.0f);
  const GroundTruthSurface truth(cloud);
  EXPECT_EQ(truth.getPoints()->size(), cloud->size());
  const TruthVoxels voxels(truth, RESOLUTION_M);
  const OracleTruth oracle = oracleTruth(*cloud, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), oracle.voxels.size());
  // Floor 30 x 30 voxels; the wall's 30 x 20 share their bottom row with the floor.
  EXPECT_EQ(voxels.size(), 900u + 30u * 19u);
  std::set<std::tuple<int, int, int>> got;
  std::size_t ground = 0;
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const VoxelIndex& k = voxels.getIndex(i);
    got.emplace(k.x(), k.y(), k.z());
    const auto at = std::find(oracle.voxels.begin(), oracle.voxels.end(), k);
    ASSERT_NE(at, oracle.voxels.end());
    EXPECT_EQ(voxels.isGround(i),
              oracle.ground[static_cast<std::size_t>(at - oracle.voxels.begin())])
      << k.transpose();
    EXPECT_NEAR(voxels.getCentre(i).z(), (k.z() + 0.5) * 0.1, 1e-6);
    ground += voxels.isGround(i) ? 1 : 0;
  }
  EXPECT_EQ(got.size(), voxels.size());
  // Ground: the floor, and the wall up to 0.3 m above it (centres 0.15, 0.25, 0.35:
  // 3 rows of 30; the row at 0.45 m is not).
  EXPECT_EQ(voxels.getGroundCount(), 900u + 3u * 30u);
  EXPECT_EQ(ground, voxels.getGroundCount());
  EXPECT_THROW(TruthVoxels(truth, 0.0), planar_grid::Exception);
}

TEST(Completeness, CuboidCoveringHalfAWall)
{
  const Cloud::Ptr cloud = wallPoints();
  const GroundTruthSurface truth(cloud);
  const TruthVoxels voxels(truth, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 400u);
  // A cuboid on the wall over y in [0, 1) (0.1 m thick, centred on it): the 10 voxel
  // columns under it (centres y = 0.05 .. 0.95) and the next one (1.05, 0.05 m from its
  // edge) are within 0.1 m; the one after (1.15) is 0.15 m away. So 11 of 20 columns:
  // 0.55 exactly. At a tolerance of 0.04 m only the 10 columns under it: 0.5.
  PlanarCuboids cuboids;
  cuboids.push_back(cuboid(Eigen::Vector3f(1.05f, 0.5f, 1.0f), Eigen::Vector3f::UnitX(),
                           Eigen::Vector3f::UnitY(), 1.0f, 2.0f, 0.1f));
  Completeness c =
    planar_grid::evaluateCompleteness(cuboids, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(c.truth_voxels, 400u);
  EXPECT_EQ(c.covered, 11u * 20u);
  EXPECT_DOUBLE_EQ(c.ratio(), 0.55);
  c = planar_grid::evaluateCompleteness(cuboids, 0.5, voxels, 0.04);
  EXPECT_EQ(c.covered, 10u * 20u);
  EXPECT_DOUBLE_EQ(c.ratio(), 0.5);
  // Moved 0.3 m off the wall along its normal: the wall is 0.25 m from its back face.
  PlanarCuboids off = cuboids;
  off[0].centre.x() += 0.3f;
  EXPECT_EQ(planar_grid::evaluateCompleteness(off, 0.5, voxels, RESOLUTION_M).covered,
            0u);
  EXPECT_EQ(planar_grid::evaluateCompleteness(off, 0.5, voxels, 0.26).covered,
            11u * 20u); // y up to 1.05 is within 0.26 m (sqrt(0.25^2 + 0.05^2) = 0.255)
  // Below the occupancy threshold: not a cell of the map.
  cuboids[0].probability = 0.4f;
  EXPECT_EQ(
    planar_grid::evaluateCompleteness(cuboids, 0.5, voxels, RESOLUTION_M).covered, 0u);
}

TEST(Completeness, CuboidsMatchTheBruteForceOracle)
{
  // Random truth points in a 3 m cube and random cuboids (any orientation, size,
  // probability, planar or not), random regions: counts equal the oracle's.
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> coord(0.0f, 3.0f);
  std::uniform_real_distribution<float> unit(-1.0f, 1.0f);
  std::uniform_real_distribution<float> extent(0.0f, 1.2f);
  std::uniform_real_distribution<float> probability(0.2f, 1.0f);
  for (int trial = 0; trial < 6; ++trial) {
    Cloud::Ptr cloud(new Cloud);
    for (int i = 0; i < 3000; ++i)
      cloud->push_back(pcl::PointXYZ(coord(rng), coord(rng), coord(rng) * 0.5f));
    const GroundTruthSurface truth(cloud);
    const double r = trial % 2 == 0 ? 0.1 : 0.25;
    const double tolerance_m = r * (0.5 + 0.25 * trial); // 0.5 to 1.75 cells
    const TruthVoxels voxels(truth, r);
    const OracleTruth oracle = oracleTruth(*cloud, r);
    ASSERT_EQ(voxels.size(), oracle.voxels.size());
    PlanarCuboids cuboids;
    for (int k = 0; k < 25; ++k) {
      const Eigen::Vector3f n =
        Eigen::Vector3f(unit(rng), unit(rng), unit(rng)).normalized();
      const Eigen::Vector3f u =
        n.cross(Eigen::Vector3f(unit(rng), unit(rng), unit(rng))).normalized();
      PlanarCuboid c =
        cuboid(Eigen::Vector3f(coord(rng), coord(rng), coord(rng) * 0.5f), n, u,
               extent(rng), extent(rng), extent(rng) * 0.3f, probability(rng));
      c.is_planar = k % 3 != 0;
      cuboids.push_back(c);
    }
    MappingErrorRegion ball;
    ball.centre_m = Eigen::Vector3f(1.5f, 1.5f, 0.5f);
    ball.max_distance_m = 1.2;
    for (const MappingErrorRegion& region : {MappingErrorRegion{}, ball}) {
      const Completeness all =
        planar_grid::evaluateCompleteness(cuboids, 0.5, voxels, tolerance_m, region);
      const Completeness all_oracle = oracleCompleteness(
        oracle, r, oracleCuboids(cuboids, false), tolerance_m, region);
      EXPECT_EQ(all.truth_voxels, all_oracle.truth_voxels) << trial;
      EXPECT_EQ(all.covered, all_oracle.covered) << trial;
      EXPECT_GT(all.covered, 0u) << trial;
      EXPECT_LT(all.covered, all.truth_voxels) << trial;
      const Completeness planar =
        planar_grid::evaluatePlanarShare(cuboids, 0.5, voxels, tolerance_m, region);
      const Completeness planar_oracle = oracleCompleteness(
        oracle, r, oracleCuboids(cuboids, true), tolerance_m, region, true);
      EXPECT_EQ(planar.truth_voxels, planar_oracle.truth_voxels) << trial;
      EXPECT_EQ(planar.covered, planar_oracle.covered) << trial;
      EXPECT_LT(planar.truth_voxels, all.truth_voxels) << trial; // ground left out
    }
  }
}

TEST(Completeness, LatticeMethodsMatchTheBruteForceOracle)
{
  // Random occupied voxels (SG), their boxes (RA) and an octree holding them (OG),
  // random truth points, several tolerances: counts equal the oracle's (the distance
  // from a truth voxel's centre to the nearest occupied voxel cube).
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> index(-6, 25);
  std::uniform_real_distribution<float> coord(-0.6f, 2.6f);
  Cloud occupied_points;
  std::set<std::tuple<int, int, int>> occupied;
  for (int k = 0; k < 150; ++k) {
    const VoxelIndex v(index(rng), index(rng), index(rng) / 4);
    occupied.emplace(v.x(), v.y(), v.z());
    occupied_points.push_back(pcl::PointXYZ(static_cast<float>((v.x() + 0.5) * 0.1),
                                            static_cast<float>((v.y() + 0.5) * 0.1),
                                            static_cast<float>((v.z() + 0.5) * 0.1)));
  }
  StandardVoxelGrid::Params params;
  params.resolution_m = RESOLUTION_M;
  StandardVoxelGrid grid(params);
  grid.insertPointCloud(occupied_points, Eigen::Vector3f(1.0f, 1.0f, 30.0f));
  ASSERT_EQ(grid.getOccupiedCount(), occupied.size()); // one scan: end points win
  AxisAlignedBoxes boxes;
  planar_grid::RectangularCuboidApproximation().compute(grid, boxes);
  octomap::OcTree tree(RESOLUTION_M);
  for (const auto& [x, y, z] : occupied)
    tree.setNodeValue(octomap::OcTreeKey(static_cast<octomap::key_type>(x + 32768),
                                         static_cast<octomap::key_type>(y + 32768),
                                         static_cast<octomap::key_type>(z + 32768)),
                      tree.getClampingThresMaxLog());
  std::vector<OracleBox> oracle_voxels;
  for (const auto& [x, y, z] : occupied)
    oracle_voxels.push_back(oracleVoxel(VoxelIndex(x, y, z), RESOLUTION_M));

  Cloud::Ptr cloud(new Cloud);
  for (int i = 0; i < 4000; ++i)
    cloud->push_back(pcl::PointXYZ(coord(rng), coord(rng), coord(rng) * 0.3f));
  const GroundTruthSurface truth(cloud);
  const TruthVoxels voxels(truth, RESOLUTION_M);
  const OracleTruth oracle = oracleTruth(*cloud, RESOLUTION_M);
  MappingErrorRegion box_region;
  box_region.min_m = Eigen::Vector3f(0.3f, -1.0f, -1.0f);
  box_region.max_m = Eigen::Vector3f(1.7f, 1.2f, 1.0f);
  // (No tolerance equals a distance from a voxel centre to a cube, 0.1 sqrt(sum e^2)
  // with e in {0, 0.5, 1.5, ...}, where rounding would decide.)
  for (const double tolerance_m : {0.0, 0.04, 0.06, 0.1, 0.16, 0.22, 0.33})
    for (const MappingErrorRegion& region : {MappingErrorRegion{}, box_region}) {
      const Completeness expected =
        oracleCompleteness(oracle, RESOLUTION_M, oracle_voxels, tolerance_m, region);
      ASSERT_GT(expected.covered, 0u);
      ASSERT_LT(expected.covered, expected.truth_voxels);
      const Completeness sg =
        planar_grid::evaluateCompleteness(grid, voxels, tolerance_m, region);
      const Completeness ra = planar_grid::evaluateCompleteness(
        boxes, RESOLUTION_M, voxels, tolerance_m, region);
      const Completeness og =
        planar_grid::evaluateCompleteness(tree, voxels, tolerance_m, region);
      for (const Completeness& c : {sg, ra, og}) {
        EXPECT_EQ(c.truth_voxels, expected.truth_voxels) << tolerance_m;
        EXPECT_EQ(c.covered, expected.covered) << tolerance_m;
      }
    }
  // At exactly one cell the 27 voxels around a truth voxel cover it (a corner
  // neighbour's cube is 0.087 m from the centre), two cells along an axis do not
  // (0.15 m).
  Cloud::Ptr one(new Cloud);
  one->push_back(pcl::PointXYZ(0.05f, 0.05f, 0.05f));
  const TruthVoxels single(GroundTruthSurface{one}, RESOLUTION_M);
  for (const auto& [offset, covered] :
       {std::pair{VoxelIndex(1, 1, 1), 1u}, std::pair{VoxelIndex(-1, 1, -1), 1u},
        std::pair{VoxelIndex(2, 0, 0), 0u}, std::pair{VoxelIndex(0, -2, 1), 0u}}) {
    AxisAlignedBoxes b{{offset, Eigen::Vector3i(1, 1, 1), true}};
    EXPECT_EQ(
      planar_grid::evaluateCompleteness(b, RESOLUTION_M, single, RESOLUTION_M).covered,
      covered)
      << offset.transpose();
  }
}

TEST(Completeness, PrunedOcTreeLeavesCoverTheirVoxels)
{
  // An occupied 8 x 8 x 2 block (x, y 0 .. 7, z layers 10 and 11), pruned into
  // 2 x 2 x 2 leaves, against truth voxels at x = 0, 7 (over the block), 8 (next to
  // it), 9 (two voxels beyond) in layers 10 (the block's), 12 (next to it) and 13 (two
  // layers above), at a tolerance of one cell (the 27 neighbours).
  octomap::OcTree tree(RESOLUTION_M);
  for (int z = 10; z < 12; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        tree.setNodeValue(octomap::OcTreeKey(static_cast<octomap::key_type>(x + 32768),
                                             static_cast<octomap::key_type>(y + 32768),
                                             static_cast<octomap::key_type>(z + 32768)),
                          tree.getClampingThresMaxLog());
  tree.updateInnerOccupancy();
  tree.prune();
  ASSERT_LT(tree.getNumLeafNodes(), 128u);
  Cloud::Ptr cloud(new Cloud);
  for (const int z : {10, 12, 13})
    for (const int x : {0, 7, 8, 9})
      cloud->push_back(pcl::PointXYZ(static_cast<float>((x + 0.5) * 0.1), 0.35f,
                                     static_cast<float>((z + 0.5) * 0.1)));
  const TruthVoxels voxels(GroundTruthSurface{cloud}, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 12u);
  // Layer 10: x 0 and 7 inside, 8 adjacent, 9 not; layer 12: x 0, 7 adjacent, 8
  // diagonally, 9 not; layer 13: none.
  EXPECT_EQ(planar_grid::evaluateCompleteness(tree, voxels, RESOLUTION_M).covered, 6u);
}

TEST(Completeness, GridHoldingTheTruthVoxelsIsCompleteAndAnEmptyMapIsNot)
{
  const Cloud::Ptr cloud = wallPoints();
  const GroundTruthSurface truth(cloud);
  const TruthVoxels voxels(truth, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 400u);
  // SG fed the truth voxels' centres in one scan: its occupied voxels are exactly
  // the truth voxels.
  StandardVoxelGrid::Params params;
  params.resolution_m = RESOLUTION_M;
  StandardVoxelGrid grid(params);
  Cloud centres;
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const Eigen::Vector3f c = voxels.getCentre(i);
    centres.push_back(pcl::PointXYZ(c.x(), c.y(), c.z()));
  }
  grid.insertPointCloud(centres, Eigen::Vector3f(-3.0f, 1.0f, 1.0f));
  ASSERT_EQ(grid.getOccupiedCount(), 400u);
  for (const double tolerance_m : {0.0, RESOLUTION_M}) {
    const Completeness c = planar_grid::evaluateCompleteness(grid, voxels, tolerance_m);
    EXPECT_EQ(c.truth_voxels, 400u);
    EXPECT_EQ(c.covered, 400u);
    EXPECT_DOUBLE_EQ(c.ratio(), 1.0);
  }
  // The same wall 0.2 m behind (two voxel layers): not within 0.1 m.
  Cloud behind = centres;
  for (auto& p : behind.points)
    p.x += 0.2f;
  StandardVoxelGrid displaced(params);
  displaced.insertPointCloud(behind, Eigen::Vector3f(-3.0f, 1.0f, 1.0f));
  EXPECT_EQ(planar_grid::evaluateCompleteness(displaced, voxels, RESOLUTION_M).covered,
            0u);
  // Empty maps: every truth voxel counted, none covered.
  const StandardVoxelGrid empty(params);
  const octomap::OcTree empty_tree(RESOLUTION_M);
  for (const Completeness& c :
       {planar_grid::evaluateCompleteness(empty, voxels, RESOLUTION_M),
        planar_grid::evaluateCompleteness(AxisAlignedBoxes{}, RESOLUTION_M, voxels,
                                          RESOLUTION_M),
        planar_grid::evaluateCompleteness(empty_tree, voxels, RESOLUTION_M),
        planar_grid::evaluateCompleteness(PlanarCuboids{}, 0.5, voxels,
                                          RESOLUTION_M)}) {
    EXPECT_EQ(c.truth_voxels, 400u);
    EXPECT_EQ(c.covered, 0u);
    EXPECT_DOUBLE_EQ(c.ratio(), 0.0);
  }
  // A region holding no truth voxel: nothing counted, the ratio undefined.
  MappingErrorRegion far_away;
  far_away.centre_m = Eigen::Vector3f(50.0f, 0.0f, 0.0f);
  far_away.max_distance_m = 1.0;
  const Completeness none =
    planar_grid::evaluateCompleteness(grid, voxels, RESOLUTION_M, far_away);
  EXPECT_EQ(none.truth_voxels, 0u);
  EXPECT_TRUE(std::isnan(none.ratio()));
}

TEST(Completeness, PlanarShareOfAWallOnFlatGround)
{
  // Flat ground (z = 0) over x, y in [0, 4) and a wall x = 2.05 m (voxel layer
  // 20), y in [0, 4), z in [0, 2): at 0.1 m the ground is the floor layer and the
  // wall's rows up to 0.3 m above it (centres 0.05 .. 0.35: 4 rows, the bottom one
  // shared with the floor); the non-ground truth is the wall's rows 4 .. 19: 16 x 40.
  Cloud::Ptr cloud(new Cloud);
  addRectangle(*cloud, Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(),
               Eigen::Vector3f::UnitY(), 4.0f, 4.0f);
  addRectangle(*cloud, Eigen::Vector3f(2.05f, 0.0f, 0.0f), Eigen::Vector3f::UnitY(),
               Eigen::Vector3f::UnitZ(), 4.0f, 2.0f);
  const GroundTruthSurface truth(cloud);
  const TruthVoxels voxels(truth, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 1600u + 40u * 19u);
  EXPECT_EQ(voxels.getGroundCount(), 1600u + 40u * 3u);
  const OracleTruth oracle = oracleTruth(*cloud, RESOLUTION_M);

  // Planar cuboids over the wall only (two halves along y): all of the non-ground
  // truth is covered; the ground does not count.
  PlanarCuboids wall;
  wall.push_back(cuboid(Eigen::Vector3f(2.05f, 1.0f, 1.0f), Eigen::Vector3f::UnitX(),
                        Eigen::Vector3f::UnitY(), 2.0f, 2.0f, 0.1f));
  wall.push_back(cuboid(Eigen::Vector3f(2.05f, 3.0f, 1.0f), Eigen::Vector3f::UnitX(),
                        Eigen::Vector3f::UnitY(), 2.0f, 2.0f, 0.1f));
  Completeness share =
    planar_grid::evaluatePlanarShare(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.truth_voxels, 16u * 40u);
  EXPECT_EQ(share.covered, 16u * 40u);
  EXPECT_DOUBLE_EQ(share.ratio(), 1.0);
  // Its completeness counts the ground too: the wall's own 800 voxels and the floor
  // voxels beside it (x centres 1.95 and 2.15 are 0.05 m from its faces; the floor
  // under it is the wall's bottom row): 800 + 2 x 40.
  const Completeness complete =
    planar_grid::evaluateCompleteness(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(complete.covered, 800u + 80u);
  EXPECT_EQ(
    complete.covered,
    oracleCompleteness(oracle, RESOLUTION_M, oracleCuboids(wall, false), RESOLUTION_M)
      .covered);

  // Over the non-ground truth alone, the wall's cuboids reach all of it, for every
  // method: PG's cuboids, and SG, RA and OG holding the wall's voxels (layer 20).
  EXPECT_EQ(complete.nonground_voxels, 16u * 40u);
  EXPECT_EQ(complete.nonground_covered, 16u * 40u);
  EXPECT_DOUBLE_EQ(complete.nongroundRatio(), 1.0);
  {
    StandardVoxelGrid::Params gp;
    gp.resolution_m = RESOLUTION_M;
    StandardVoxelGrid grid(gp);
    octomap::OcTree tree(RESOLUTION_M);
    Cloud wall_points;
    for (const auto& p : cloud->points)
      if (std::abs(p.x - 2.05f) < 1e-4f)
        wall_points.push_back(p);
    for (const auto& p : wall_points.points)
      tree.updateNode(octomap::point3d(p.x, p.y, p.z), true);
    grid.insertPointCloud(wall_points, Eigen::Vector3f(0.0f, 2.0f, 1.0f));
    AxisAlignedBoxes boxes;
    planar_grid::RectangularCuboidApproximation().compute(grid, boxes);
    for (const Completeness& c :
         {planar_grid::evaluateCompleteness(grid, voxels, RESOLUTION_M),
          planar_grid::evaluateCompleteness(boxes, RESOLUTION_M, voxels, RESOLUTION_M),
          planar_grid::evaluateCompleteness(tree, voxels, RESOLUTION_M)}) {
      EXPECT_EQ(c.nonground_voxels, 16u * 40u);
      EXPECT_EQ(c.nonground_covered, 16u * 40u);
      // over all the truth, the floor beyond one voxel of the wall is missed
      EXPECT_EQ(c.truth_voxels, voxels.size());
      EXPECT_EQ(c.covered, 800u + 2u * 40u);
    }
  }
  // Only the floor: none of the non-ground truth.
  const Completeness floor_only = planar_grid::evaluateCompleteness(
    PlanarCuboids{cuboid(Eigen::Vector3f(2.0f, 2.0f, 0.05f), Eigen::Vector3f::UnitZ(),
                         Eigen::Vector3f::UnitX(), 4.0f, 4.0f, 0.1f)},
    0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(floor_only.nonground_voxels, 16u * 40u);
  EXPECT_EQ(floor_only.nonground_covered, 0u);

  // The same cuboids non-planar (Fig. 7 boxes): planar share 0, completeness alike.
  PlanarCuboids boxes = wall;
  for (auto& c : boxes)
    c.is_planar = false;
  share = planar_grid::evaluatePlanarShare(boxes, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.truth_voxels, 16u * 40u);
  EXPECT_EQ(share.covered, 0u);
  EXPECT_EQ(planar_grid::evaluateCompleteness(boxes, 0.5, voxels, RESOLUTION_M).covered,
            complete.covered);

  // A planar cuboid on the ground only: the lowest non-ground wall row (centre 0.45 m)
  // is 0.35 m above its top face: planar share 0, while it covers the floor.
  PlanarCuboids floor;
  floor.push_back(cuboid(Eigen::Vector3f(2.0f, 2.0f, 0.05f), Eigen::Vector3f::UnitZ(),
                         Eigen::Vector3f::UnitX(), 4.0f, 4.0f, 0.1f));
  EXPECT_EQ(planar_grid::evaluatePlanarShare(floor, 0.5, voxels, RESOLUTION_M).covered,
            0u);
  EXPECT_GT(planar_grid::evaluateCompleteness(floor, 0.5, voxels, RESOLUTION_M).covered,
            1600u);

  // Half the wall's height (z in [1, 2)): rows 9 .. 19 within 0.1 m (9's centre 0.95
  // is 0.05 m below the cuboid): 11 of the 16 non-ground rows.
  PlanarCuboids upper;
  upper.push_back(cuboid(Eigen::Vector3f(2.05f, 2.0f, 1.5f), Eigen::Vector3f::UnitX(),
                         Eigen::Vector3f::UnitY(), 4.0f, 1.0f, 0.1f));
  share = planar_grid::evaluatePlanarShare(upper, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.covered, 11u * 40u);
  EXPECT_DOUBLE_EQ(share.ratio(), 11.0 / 16.0);
  // A region: the ball of 1 m around (2.05, 2, 1.5), against the oracle.
  MappingErrorRegion ball;
  ball.centre_m = Eigen::Vector3f(2.05f, 2.0f, 1.5f);
  ball.max_distance_m = 1.0;
  share = planar_grid::evaluatePlanarShare(upper, 0.5, voxels, RESOLUTION_M, ball);
  const Completeness expected = oracleCompleteness(
    oracle, RESOLUTION_M, oracleCuboids(upper, true), RESOLUTION_M, ball, true);
  EXPECT_EQ(share.truth_voxels, expected.truth_voxels);
  EXPECT_EQ(share.covered, expected.covered);
  EXPECT_LT(share.truth_voxels, 16u * 40u);
}

/** \brief The pose of a camera at \a position looking along world +x (camera z), its
 * x (right) along world -y and y (down) along world -z. */
Eigen::Isometry3d
lookingAlongX(const Eigen::Vector3d& position)
{
  Eigen::Matrix3d rotation;
  rotation << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation;
  pose.translation() = position;
  return pose;
}

TEST(Completeness, PlanarShareWithinTheMappedRange)
{
  // A facade along a street: the wall y = 1.05 m (voxel layer 10), x in [0, 10),
  // z in [0, 2), 100 x 20 truth voxels at 0.1 m. A column without floor: its lowest
  // 4 rows (centres 0.05 .. 0.35) are ground, the 16 above not: 1600 non-ground.
  Cloud::Ptr cloud(new Cloud);
  addRectangle(*cloud, Eigen::Vector3f(0.0f, 1.05f, 0.0f), Eigen::Vector3f::UnitX(),
               Eigen::Vector3f::UnitZ(), 10.0f, 2.0f);
  const GroundTruthSurface truth(cloud);
  TruthVoxels voxels(truth, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 2000u);
  ASSERT_EQ(voxels.getGroundCount(), 400u);
  // A planar cuboid on the wall over x in [0, 2]: the columns with centres 0.05 .. 2.05
  // (the last 0.05 m from its end) are within 0.1 m: 21 of 100.
  const PlanarCuboids wall{cuboid(Eigen::Vector3f(1.0f, 1.05f, 1.0f),
                                  Eigen::Vector3f::UnitY(), Eigen::Vector3f::UnitX(),
                                  2.0f, 2.0f, 0.1f)};
  // Without a range every voxel is in it.
  Completeness share =
    planar_grid::evaluatePlanarShare(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.covered, 21u * 16u);
  EXPECT_EQ(share.range_nonground_voxels, 1600u);
  EXPECT_EQ(share.range_nonground_covered, 21u * 16u);
  EXPECT_TRUE(std::isinf(voxels.getMappedRange()));

  // A range of 4 m depth, no view yet: nothing is in it.
  voxels.setMappedRange(4.0);
  share = planar_grid::evaluatePlanarShare(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.range_nonground_voxels, 0u);
  EXPECT_TRUE(std::isnan(share.rangeNongroundRatio()));

  // A camera at the origin looking along +x with an image 200 px wide (f = 80 px,
  // cx = 100 px: 51 degrees to each side) and tall enough for the whole wall. The
  // wall is 1.05 m to its left: in the image from a depth of 1.05 x 80 / 100 = 0.84 m,
  // within the 4 m from x centres 0.85 to 3.95: 32 columns of 16 non-ground rows.
  planar_grid::RangeView view;
  view.world_T_camera = lookingAlongX(Eigen::Vector3d::Zero());
  view.focal_length_px = 80.0;
  view.cx_px = 100.0;
  view.cy_px = 500.0;
  view.width_px = 200;
  view.height_px = 1000;
  voxels.addView(view);
  share = planar_grid::evaluatePlanarShare(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.range_nonground_voxels, 32u * 16u);
  // Of them the cuboid covers the columns 0.85 .. 2.05: 13.
  EXPECT_EQ(share.range_nonground_covered, 13u * 16u);
  EXPECT_DOUBLE_EQ(share.rangeNongroundRatio(), 13.0 / 32.0);
  // The planar share over all of the non-ground truth does not change.
  EXPECT_EQ(share.truth_voxels, 1600u);
  EXPECT_EQ(share.covered, 21u * 16u);

  // A second view 6 m along, without image bounds (a point-cloud input): the columns
  // 6.05 .. 9.95 (depth up to 3.95 m) join the range, none of them covered.
  planar_grid::RangeView far;
  far.world_T_camera = lookingAlongX(Eigen::Vector3d(6.0, 0.0, 1.0));
  voxels.addView(far);
  share = planar_grid::evaluatePlanarShare(wall, 0.5, voxels, RESOLUTION_M);
  EXPECT_EQ(share.range_nonground_voxels, (32u + 40u) * 16u);
  EXPECT_EQ(share.range_nonground_covered, 13u * 16u);
  // Every method counts the same range: SG holding the whole wall covers all of it.
  StandardVoxelGrid::Params gp;
  gp.resolution_m = RESOLUTION_M;
  StandardVoxelGrid grid(gp);
  grid.insertPointCloud(*cloud, Eigen::Vector3f(0.0f, 0.0f, 1.0f));
  const Completeness sg = planar_grid::evaluateCompleteness(grid, voxels, RESOLUTION_M);
  EXPECT_EQ(sg.range_nonground_voxels, (32u + 40u) * 16u);
  EXPECT_EQ(sg.range_nonground_covered, (32u + 40u) * 16u);
  EXPECT_THROW(voxels.setMappedRange(0.0), planar_grid::Exception);
}

TEST(Completeness, WholeMapCoversWithBothLayers)
{
  // The wall x = 1.05 m, y and z in [0, 2): 20 columns (along y) of 20 voxels at 0.1 m.
  const GroundTruthSurface truth(wallPoints());
  const TruthVoxels voxels(truth, RESOLUTION_M);
  ASSERT_EQ(voxels.size(), 400u);
  planar_grid::PlanarGridMap::Params params;
  params.resolution_m = RESOLUTION_M;
  planar_grid::PlanarGridMap map(params);
  // The surface layer: a cell on the wall over y in [0, 0.5): the columns with centres
  // 0.05 .. 0.55 (0.05 m beyond its end) are within 0.1 m: 6 of 20.
  PlanarCuboid box =
    cuboid(Eigen::Vector3f(1.05f, 0.25f, 1.0f), Eigen::Vector3f::UnitX(),
           Eigen::Vector3f::UnitY(), 0.5f, 2.0f, 0.1f);
  box.is_planar = false;
  box.plane_id = -1;
  map.integrateSurface({box}, {}, Cloud(), {});
  const PlanarCuboids cuboids = map.getSurfaceLayer().getCuboids();
  ASSERT_EQ(cuboids.size(), 1u);
  const double thres = map.getParams().surface.occupancy_thres;
  ASSERT_GE(static_cast<double>(cuboids[0].probability), thres);
  const Completeness cells =
    planar_grid::evaluateCompleteness(cuboids, thres, voxels, RESOLUTION_M);
  EXPECT_EQ(cells.covered, 6u * 20u);
  // The space layer: the wall's voxels of the columns 10 .. 14 occupied: they and
  // their neighbours, columns 9 .. 15, are covered (7 columns).
  for (int y = 10; y <= 14; ++y)
    for (int z = 0; z < 20; ++z)
      map.getSpaceLayer().setState({10, y, z}, planar_grid::SpaceState::OCCUPIED);
  // Measuring leaves the map's memory as it was (no query index kept).
  const std::size_t memory_bytes = map.getMemory().total_bytes;
  Completeness whole = planar_grid::evaluateMapCompleteness(map, voxels, RESOLUTION_M);
  EXPECT_EQ(map.getMemory().total_bytes, memory_bytes);
  EXPECT_EQ(whole.truth_voxels, 400u);
  EXPECT_EQ(whole.covered, (6u + 7u) * 20u);
  EXPECT_DOUBLE_EQ(whole.ratio(), 13.0 / 20.0);
  // Ground split as for the other methods: the lowest 4 rows of each column.
  EXPECT_EQ(whole.nonground_voxels, 20u * 16u);
  EXPECT_EQ(whole.nonground_covered, 13u * 16u);
  // An occupied voxel where a query reads FREE (inside a cell below the threshold)
  // is not part of the map's occupied space: column 18's voxels under a free cell.
  // A non-planar cell's probability is the mean of its frame's features inside it: one
  // feature of probability 0.1 in it.
  PlanarCuboid free_box = box;
  free_box.centre = Eigen::Vector3f(1.05f, 1.85f, 1.0f);
  free_box.width_m = 0.1f;
  Cloud free_feature;
  free_feature.push_back(pcl::PointXYZ(1.05f, 1.85f, 1.0f));
  planar_grid::PlanarGridMap shaded(params);
  shaded.integrateSurface({box, free_box}, {}, free_feature, {0.1f});
  ASSERT_EQ(shaded.getSurfaceLayer().getCuboids().size(), 2u);
  for (int z = 0; z < 20; ++z)
    shaded.getSpaceLayer().setState({10, 18, z}, planar_grid::SpaceState::OCCUPIED);
  ASSERT_EQ(shaded.getState(Eigen::Vector3f(1.05f, 1.85f, 1.05f)),
            planar_grid::SpaceState::FREE);
  EXPECT_EQ(planar_grid::evaluateMapCompleteness(shaded, voxels, RESOLUTION_M).covered,
            6u * 20u);
  // Outside the cell the same voxels count: columns 17 .. 19.
  planar_grid::PlanarGridMap unshaded(params);
  unshaded.integrateSurface({box}, {}, Cloud(), {});
  for (int z = 0; z < 20; ++z)
    unshaded.getSpaceLayer().setState({10, 18, z}, planar_grid::SpaceState::OCCUPIED);
  EXPECT_EQ(
    planar_grid::evaluateMapCompleteness(unshaded, voxels, RESOLUTION_M).covered,
    (6u + 3u) * 20u);
  // A region counts the truth voxels in it against the whole map: the ball of 0.5 m
  // around the wall's point (1.05, 1.2, 1.0).
  MappingErrorRegion ball;
  ball.centre_m = Eigen::Vector3f(1.05f, 1.2f, 1.0f);
  ball.max_distance_m = 0.5;
  whole = planar_grid::evaluateMapCompleteness(map, voxels, RESOLUTION_M, ball);
  EXPECT_GT(whole.truth_voxels, 0u);
  EXPECT_LT(whole.truth_voxels, 400u);
  std::size_t expected = 0;
  for (std::size_t i = 0; i < voxels.size(); ++i) {
    const Eigen::Vector3f c = voxels.getCentre(i);
    if (ball.contains(c) && ((c.y() > 0.85f && c.y() < 1.6f) || c.y() < 0.6f))
      ++expected;
  }
  EXPECT_EQ(whole.covered, expected);
  // The map's resolution must be the truth voxels'.
  const TruthVoxels coarse(truth, 0.2);
  EXPECT_THROW(planar_grid::evaluateMapCompleteness(map, coarse, 0.2),
               planar_grid::Exception);
}

TEST(Completeness, RejectsBadArguments)
{
  const Cloud::Ptr cloud = wallPoints();
  const TruthVoxels voxels(GroundTruthSurface{cloud}, RESOLUTION_M);
  StandardVoxelGrid::Params params;
  params.resolution_m = 0.2;
  const StandardVoxelGrid coarse(params); // another cell size than the truth voxels
  EXPECT_THROW(planar_grid::evaluateCompleteness(coarse, voxels, 0.1),
               planar_grid::Exception);
  const octomap::OcTree tree(0.2);
  EXPECT_THROW(planar_grid::evaluateCompleteness(tree, voxels, 0.1),
               planar_grid::Exception);
  EXPECT_THROW(
    planar_grid::evaluateCompleteness(AxisAlignedBoxes{}, 0.2, voxels, RESOLUTION_M),
    planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateCompleteness(AxisAlignedBoxes{}, 0.1, voxels, -0.1),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluateCompleteness(AxisAlignedBoxes{}, 0.1, voxels, 2.0),
               planar_grid::Exception); // 20 cells: above the lattice's limit
  EXPECT_THROW(planar_grid::evaluateCompleteness(PlanarCuboids{}, 1.5, voxels, 0.1),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluatePlanarShare(PlanarCuboids{}, 0.5, voxels, NAN),
               planar_grid::Exception);
  // A non-finite cuboid is skipped.
  PlanarCuboids bad;
  bad.push_back(cuboid(Eigen::Vector3f::Constant(NAN), Eigen::Vector3f::UnitX(),
                       Eigen::Vector3f::UnitY(), 1.0f, 1.0f, 0.1f));
  bad.push_back(cuboid(Eigen::Vector3f(1.05f, 1.0f, 1.0f), Eigen::Vector3f::UnitX(),
                       Eigen::Vector3f::UnitY(), -1.0f, 1.0f, 0.1f));
  EXPECT_EQ(planar_grid::evaluateCompleteness(bad, 0.5, voxels, 0.1).covered, 0u);
}

} // namespace
