// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <pcl/io/pcd_io.h>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>

#include <cmath>
#include <cstddef>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <vector>

namespace {

using planar_grid::StandardVoxelGrid;
using planar_grid::VoxelIndex;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Key = std::tuple<int, int, int>;
using VoxelMap = std::map<Key, float>;

StandardVoxelGrid::Params
params(double resolution_m, double max_range_m = -1.0)
{
  StandardVoxelGrid::Params p;
  p.resolution_m = resolution_m;
  p.max_range_m = max_range_m;
  return p;
}

/** \brief An OcTree with the grid's sensor model (the same float parameters). */
octomap::OcTree
makeOcTree(const StandardVoxelGrid::Params& p)
{
  octomap::OcTree tree(p.resolution_m);
  tree.setProbHit(p.prob_hit);
  tree.setProbMiss(p.prob_miss);
  tree.setClampingThresMin(p.clamping_thres_min);
  tree.setClampingThresMax(p.clamping_thres_max);
  tree.setOccupancyThres(p.occupancy_thres);
  return tree;
}

/** \brief insertPointCloud(discretize = false, lazy_eval = false) of the finite points
 * (OctoMap has no NaN check of its own). */
void
insertOcTree(octomap::OcTree& tree,
             const Cloud& cloud,
             const Eigen::Vector3f& origin,
             double max_range_m)
{
  octomap::Pointcloud scan;
  for (const auto& p : cloud.points)
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
      scan.push_back(p.x, p.y, p.z);
  tree.insertPointCloud(scan, octomap::point3d(origin.x(), origin.y(), origin.z()),
                        max_range_m, false, false);
}

/** \brief Every voxel of the tree (pruned leaves expanded) with its log-odds, by our
 * index (OctoMap key - 32768). */
VoxelMap
octreeVoxels(const octomap::OcTree& tree, VoxelMap* occupied)
{
  VoxelMap voxels;
  const double r = tree.getResolution();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const int n = 1 << (tree.getTreeDepth() - it.getDepth());
    const octomap::point3d c = it.getCoordinate();
    const double half = 0.5 * it.getSize();
    // floor at the centre of the first voxel: robust to the rounding of c
    const int x0 = static_cast<int>(std::floor((c.x() - half) / r + 0.5));
    const int y0 = static_cast<int>(std::floor((c.y() - half) / r + 0.5));
    const int z0 = static_cast<int>(std::floor((c.z() - half) / r + 0.5));
    for (int k = 0; k < n; ++k)
      for (int j = 0; j < n; ++j)
        for (int i = 0; i < n; ++i) {
          const Key key{x0 + i, y0 + j, z0 + k};
          voxels[key] = it->getLogOdds();
          if (occupied != nullptr && tree.isNodeOccupied(*it))
            (*occupied)[key] = it->getLogOdds();
        }
  }
  return voxels;
}

VoxelMap
gridVoxels(const StandardVoxelGrid& grid, VoxelMap* occupied)
{
  std::vector<StandardVoxelGrid::Voxel> voxels;
  grid.getVoxels(voxels);
  VoxelMap out;
  for (const auto& v : voxels) {
    const Key key{v.index.x(), v.index.y(), v.index.z()};
    out[key] = v.log_odds;
    if (occupied != nullptr && grid.isOccupied(v.index))
      (*occupied)[key] = v.log_odds;
  }
  return out;
}

/** \brief Counts of the comparison with OctoMap. */
struct Agreement {
  std::size_t observed_grid{0}, observed_tree{0}, occupied_grid{0}, occupied_tree{0};
  std::size_t observed_common{0}, occupied_common{0}, equal_log_odds{0};
};

Agreement
compare(const StandardVoxelGrid& grid, const octomap::OcTree& tree)
{
  VoxelMap grid_occupied, tree_occupied;
  const VoxelMap g = gridVoxels(grid, &grid_occupied);
  const VoxelMap t = octreeVoxels(tree, &tree_occupied);
  Agreement a;
  a.observed_grid = g.size();
  a.observed_tree = t.size();
  a.occupied_grid = grid_occupied.size();
  a.occupied_tree = tree_occupied.size();
  for (const auto& kv : g) {
    const auto it = t.find(kv.first);
    if (it == t.end())
      continue;
    ++a.observed_common;
    a.equal_log_odds += it->second == kv.second ? 1 : 0; // bitwise: same float ops
  }
  for (const auto& kv : grid_occupied)
    a.occupied_common += tree_occupied.count(kv.first);
  return a;
}

/** \brief Required agreement: exact. The grid repeats computeRayKeys' arithmetic
 * (same float / double steps, same tie-breaking of equal tMax), the same per-scan
 * key sets and the same clamped float update, so every voxel and every log-odds must
 * be identical, not merely > 99 %. */
void
expectExactAgreement(const Agreement& a)
{
  EXPECT_GT(a.occupied_grid, 0u);
  EXPECT_EQ(a.observed_grid, a.observed_tree);
  EXPECT_EQ(a.observed_common, a.observed_tree);
  EXPECT_EQ(a.equal_log_odds, a.observed_tree);
  EXPECT_EQ(a.occupied_grid, a.occupied_tree);
  EXPECT_EQ(a.occupied_common, a.occupied_tree);
}

/** \brief Points of the plane 0.2 x - 0.1 y + z = 3 over x, y in [-2, 2] with
 * Gaussian noise (sigma 2 cm along z), fixed seed. */
Cloud
noisyPlane(unsigned seed, int n)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uv(-2.0f, 2.0f);
  std::normal_distribution<float> noise(0.0f, 0.02f);
  Cloud cloud;
  for (int i = 0; i < n; ++i) {
    const float x = uv(rng), y = uv(rng);
    cloud.push_back(pcl::PointXYZ(x, y, 3.0f - 0.2f * x + 0.1f * y + noise(rng)));
  }
  return cloud;
}

TEST(StandardVoxelGrid, MatchesOctoMapOnNoisyPlaneFromTwoOrigins)
{
  const auto p = params(0.1);
  StandardVoxelGrid grid(p);
  octomap::OcTree tree = makeOcTree(p);
  const Eigen::Vector3f origins[2] = {Eigen::Vector3f(0.0f, 0.0f, 0.0f),
                                      Eigen::Vector3f(0.53f, -0.31f, 0.22f)};
  for (int scan = 0; scan < 4; ++scan) {
    const Cloud cloud = noisyPlane(42u + static_cast<unsigned>(scan), 3000);
    grid.insertPointCloud(cloud, origins[scan % 2]);
    insertOcTree(tree, cloud, origins[scan % 2], -1.0);
  }
  expectExactAgreement(compare(grid, tree));
}

TEST(StandardVoxelGrid, MatchesOctoMapWithMaxRange)
{
  // 3.2 m cuts the plane (3 m at the centre, up to ~3.8 m at the corners): both the
  // end point and the max-range branch are used.
  const auto p = params(0.1, 3.2);
  StandardVoxelGrid grid(p);
  octomap::OcTree tree = makeOcTree(p);
  const Eigen::Vector3f origins[2] = {Eigen::Vector3f(0.0f, 0.0f, 0.0f),
                                      Eigen::Vector3f(-0.47f, 0.28f, 0.11f)};
  for (int scan = 0; scan < 2; ++scan) {
    const Cloud cloud = noisyPlane(7u + static_cast<unsigned>(scan), 3000);
    grid.insertPointCloud(cloud, origins[scan]);
    insertOcTree(tree, cloud, origins[scan], 3.2);
  }
  expectExactAgreement(compare(grid, tree));
}

TEST(StandardVoxelGrid, MatchesOctoMapOnRealCloud)
{
  // office1.pcd: an organized 640 x 480 Kinect cloud (camera frame, origin 0) with
  // NaNs; every 4th pixel of every 4th row (160 x 120), NaNs kept for the grid (it
  // skips them), removed for OctoMap.
  Cloud full;
  ASSERT_EQ(pcl::io::loadPCDFile(
              std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/office1.pcd", full),
            0);
  ASSERT_EQ(full.width, 640u);
  Cloud cloud;
  std::size_t nan_count = 0;
  for (std::uint32_t v = 0; v < full.height; v += 4)
    for (std::uint32_t u = 0; u < full.width; u += 4) {
      const auto& q = full.at(u, v);
      nan_count += std::isfinite(q.x) ? 0 : 1;
      cloud.push_back(q);
    }
  ASSERT_GT(nan_count, 0u);
  ASSERT_GT(cloud.size() - nan_count, 10000u);
  for (const double resolution_m : {0.05, 0.1}) {
    const auto p = params(resolution_m);
    StandardVoxelGrid grid(p);
    octomap::OcTree tree = makeOcTree(p);
    grid.insertPointCloud(cloud, Eigen::Vector3f::Zero());
    insertOcTree(tree, cloud, Eigen::Vector3f::Zero(), -1.0);
    SCOPED_TRACE("resolution_m " + std::to_string(resolution_m));
    expectExactAgreement(compare(grid, tree));
  }
}

TEST(StandardVoxelGrid, OccupiedWinsAndOneUpdatePerScan)
{
  // 1 m voxels, origin in voxel (0, 0, 0). Two rays along +x: to A in voxel (5, 0, 0)
  // and to B in voxel (2, 0, 0), which the ray to A passes through.
  StandardVoxelGrid grid(params(1.0));
  Cloud cloud;
  cloud.push_back(pcl::PointXYZ(5.5f, 0.5f, 0.5f)); // A
  cloud.push_back(pcl::PointXYZ(2.5f, 0.5f, 0.5f)); // B
  cloud.push_back(pcl::PointXYZ(5.5f, 0.5f, 0.5f)); // A again: still one update
  grid.insertPointCloud(cloud, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  const float hit = grid.getProbHitLogOdds(), miss = grid.getProbMissLogOdds();
  EXPECT_NEAR(hit, std::log(0.7 / 0.3), 1e-6);
  EXPECT_NEAR(miss, std::log(0.4 / 0.6), 1e-6);
  // voxels 0..5 along x observed, nothing else
  EXPECT_EQ(grid.getVoxelCount(), 6u);
  EXPECT_EQ(grid.getOccupiedCount(), 2u);
  EXPECT_EQ(grid.getFreeCount(), 4u);
  float l = 0.0f;
  for (int x : {0, 1, 3, 4}) {
    ASSERT_TRUE(grid.getLogOdds(VoxelIndex(x, 0, 0), l)) << x;
    EXPECT_EQ(l, miss) << x; // one miss although 2-3 rays cross voxels 0 and 1
    EXPECT_FALSE(grid.isOccupied(VoxelIndex(x, 0, 0)));
  }
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(2, 0, 0), l));
  EXPECT_EQ(l, hit); // occupied wins over the ray to A
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(5, 0, 0), l));
  EXPECT_EQ(l, hit);
  EXPECT_TRUE(grid.isOccupied(VoxelIndex(2, 0, 0)));
  EXPECT_FALSE(grid.getLogOdds(VoxelIndex(6, 0, 0), l));
  EXPECT_FALSE(grid.isOccupied(VoxelIndex(6, 0, 0)));

  // The next scan adds once more; repeated scans clamp.
  grid.insertPointCloud(cloud, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(2, 0, 0), l));
  EXPECT_EQ(l, hit + hit);
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(0, 0, 0), l));
  EXPECT_EQ(l, miss + miss);
  for (int i = 0; i < 20; ++i)
    grid.insertPointCloud(cloud, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(2, 0, 0), l));
  EXPECT_EQ(l, grid.getClampingThresMaxLogOdds());
  ASSERT_TRUE(grid.getLogOdds(VoxelIndex(0, 0, 0), l));
  EXPECT_EQ(l, grid.getClampingThresMinLogOdds());
  EXPECT_NEAR(grid.getClampingThresMaxLogOdds(), std::log(0.971 / 0.029), 1e-5);
  EXPECT_NEAR(grid.getClampingThresMinLogOdds(), std::log(0.1192 / 0.8808), 1e-5);
}

TEST(StandardVoxelGrid, MaxRangeClearsAndMarksNothing)
{
  // 1 m voxels, max range 3 m from (0.5, 0.5, 0.5): the point at x = 10.5 is beyond
  // it; its ray is cut at x = 3.5 and, as in OctoMap, clears the voxels before the
  // cut point's voxel: 0, 1, 2. Voxels 3 and 10 stay unobserved. The point at x = 2.5
  // (2 m) is within range: occupied.
  StandardVoxelGrid grid(params(1.0, 3.0));
  Cloud far_only;
  far_only.push_back(pcl::PointXYZ(10.5f, 0.5f, 0.5f));
  grid.insertPointCloud(far_only, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  EXPECT_EQ(grid.getVoxelCount(), 3u);
  EXPECT_EQ(grid.getOccupiedCount(), 0u);
  float l = 0.0f;
  for (int x : {0, 1, 2})
    EXPECT_TRUE(grid.getLogOdds(VoxelIndex(x, 0, 0), l)) << x;
  EXPECT_FALSE(grid.getLogOdds(VoxelIndex(3, 0, 0), l));
  EXPECT_FALSE(grid.getLogOdds(VoxelIndex(10, 0, 0), l));

  StandardVoxelGrid grid2(params(1.0, 3.0));
  Cloud both = far_only;
  both.push_back(pcl::PointXYZ(0.5f, 2.5f, 0.5f)); // 2 m along +y
  grid2.insertPointCloud(both, Eigen::Vector3f(0.5f, 0.5f, 0.5f));
  EXPECT_TRUE(grid2.isOccupied(VoxelIndex(0, 2, 0)));
  EXPECT_EQ(grid2.getOccupiedCount(), 1u);
  // x: 0, 1, 2 free; y: (0, 1, 0) free; (0, 0, 0) shared
  EXPECT_EQ(grid2.getVoxelCount(), 5u);
}

TEST(StandardVoxelGrid, SkipsNonFinitePoints)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  Cloud valid;
  valid.push_back(pcl::PointXYZ(1.25f, -0.75f, 2.05f));
  Cloud mixed;
  mixed.push_back(pcl::PointXYZ(nan, 0.0f, 1.0f));
  mixed.push_back(valid[0]);
  mixed.push_back(pcl::PointXYZ(0.0f, inf, 1.0f));
  mixed.push_back(pcl::PointXYZ(0.0f, 0.0f, -inf));
  StandardVoxelGrid a(params(0.1)), b(params(0.1));
  a.insertPointCloud(valid, Eigen::Vector3f::Zero());
  b.insertPointCloud(mixed, Eigen::Vector3f::Zero());
  VoxelMap va = gridVoxels(a, nullptr), vb = gridVoxels(b, nullptr);
  EXPECT_EQ(va, vb);
  EXPECT_EQ(b.getOccupiedCount(), 1u);

  // All NaN, an empty cloud: nothing. A NaN origin: end points only.
  Cloud all_nan;
  all_nan.push_back(pcl::PointXYZ(nan, nan, nan));
  StandardVoxelGrid c(params(0.1));
  c.insertPointCloud(all_nan, Eigen::Vector3f::Zero());
  c.insertPointCloud(Cloud(), Eigen::Vector3f::Zero());
  EXPECT_EQ(c.getVoxelCount(), 0u);
  c.insertPointCloud(valid, Eigen::Vector3f::Constant(nan));
  EXPECT_EQ(c.getVoxelCount(), 1u);
  EXPECT_TRUE(c.isOccupied(c.toIndex(valid[0].getVector3fMap())));
}

TEST(StandardVoxelGrid, RejectsBadParams)
{
  const auto expectThrow = [](auto mutate) {
    StandardVoxelGrid::Params p;
    mutate(p);
    EXPECT_THROW(StandardVoxelGrid grid(p), planar_grid::Exception);
  };
  expectThrow([](auto& p) { p.resolution_m = 0.0; });
  expectThrow([](auto& p) { p.resolution_m = -0.1; });
  expectThrow([](auto& p) { p.resolution_m = 101.0; });
  expectThrow(
    [](auto& p) { p.resolution_m = std::numeric_limits<double>::quiet_NaN(); });
  expectThrow(
    [](auto& p) { p.max_range_m = std::numeric_limits<double>::quiet_NaN(); });
  expectThrow([](auto& p) { p.prob_hit = 0.5f; });
  expectThrow([](auto& p) { p.prob_hit = 1.0f; });
  expectThrow([](auto& p) { p.prob_miss = 0.5f; });
  expectThrow([](auto& p) { p.prob_miss = 0.0f; });
  expectThrow([](auto& p) { p.clamping_thres_min = 0.0f; });
  expectThrow([](auto& p) { p.clamping_thres_min = 0.6f; });
  expectThrow([](auto& p) { p.clamping_thres_max = 1.0f; });
  expectThrow([](auto& p) { p.clamping_thres_max = 0.4f; });
  expectThrow([](auto& p) { p.occupancy_thres = 0.0f; });
  expectThrow([](auto& p) { p.occupancy_thres = 0.99f; }); // above clamping_thres_max
  EXPECT_NO_THROW(StandardVoxelGrid grid(StandardVoxelGrid::Params{}));
}

TEST(StandardVoxelGrid, OrderCentresMemoryAndClear)
{
  const auto p = params(0.1);
  StandardVoxelGrid grid(p);
  EXPECT_EQ(grid.getParams().resolution_m, 0.1);
  const std::size_t empty_bytes = grid.getMemoryBytes();
  grid.insertPointCloud(noisyPlane(3u, 500), Eigen::Vector3f(0.1f, -0.2f, 0.0f));
  std::vector<StandardVoxelGrid::Voxel> voxels;
  grid.getVoxels(voxels);
  ASSERT_EQ(voxels.size(), grid.getVoxelCount());
  for (std::size_t i = 1; i < voxels.size(); ++i) {
    const auto& a = voxels[i - 1].index;
    const auto& b = voxels[i].index;
    EXPECT_TRUE(std::make_tuple(a.z(), a.y(), a.x())
                < std::make_tuple(b.z(), b.y(), b.x()))
      << i;
  }
  Cloud centres;
  grid.getOccupiedCentres(centres);
  ASSERT_EQ(centres.size(), grid.getOccupiedCount());
  EXPECT_EQ(centres.width, centres.size());
  for (const auto& c : centres.points) {
    const VoxelIndex index = grid.toIndex(c.getVector3fMap());
    EXPECT_TRUE(grid.isOccupied(index));
    EXPECT_TRUE(grid.toCentre(index).isApprox(c.getVector3fMap(), 1e-6f));
  }
  // Every voxel at least one node of 8 + 16 + 8 bytes plus its bucket pointer share.
  EXPECT_GE(grid.getMemoryBytes(), empty_bytes + 32 * grid.getVoxelCount());
  // Negative indices: floor, not truncation.
  EXPECT_EQ(grid.toIndex(Eigen::Vector3f(-0.05f, 0.05f, -1.0e-4f)),
            VoxelIndex(-1, 0, -1));
  grid.clear();
  EXPECT_EQ(grid.getVoxelCount(), 0u);
  EXPECT_EQ(grid.getOccupiedCount(), 0u);
}

TEST(StandardVoxelGrid, MovesKeepTheVoxels)
{
  StandardVoxelGrid grid(params(0.1));
  grid.insertPointCloud(noisyPlane(5u, 200), Eigen::Vector3f::Zero());
  const VoxelMap before = gridVoxels(grid, nullptr);
  StandardVoxelGrid moved(std::move(grid));
  EXPECT_EQ(gridVoxels(moved, nullptr), before);
  // insertion keeps working after the move (the scratch table moved with it)
  StandardVoxelGrid again(params(0.1));
  again = std::move(moved);
  again.insertPointCloud(noisyPlane(6u, 200), Eigen::Vector3f::Zero());
  EXPECT_GE(again.getVoxelCount(), before.size());
}

} // namespace
