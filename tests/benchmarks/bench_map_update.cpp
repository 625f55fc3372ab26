// SPDX-License-Identifier: BSD-3-Clause
// The whole map update of one real frame against OctoMap in the same run:
// Karlsruhe frame 10, SGBM to 30 m, camera frame = world frame.
//
// BM_PlanarGridMapUpdate: what the pipeline does per frame once the planes are known:
//   PlanarCuboidApproximation (0.1 m) on the ground-free voxelised cloud and its
//   planes, KLDivergenceOccupancyFilter on the frame's SIFT stereo features (eq. 4),
//   PlanarGridMap::integrateSurface (cuboids + feature occupancies),
//   the depth image from the disparity (f B / d) and PlanarGridMap::integrateDepthImage
//   (explicit free / occupied / unknown space to 25 m at 0.1 m),
//   on a fresh map each iteration. Arg prior: 2 = unknown (default), 0 = free (paper).
// BM_OctoMapInsertPointCloud: octomap::OcTree(0.1)::insertPointCloud of every finite
//   SGBM point of the same frame (max range 25 m, OctoMap's default sensor model), on a
//   fresh tree each iteration.
// BM_BonxaiInsertPointCloud (only with PLANAR_GRID_BONXAI_DIR, a Bonxai source
//   checkout): Bonxai::ProbabilisticMap(0.1)::insertPointCloud of the same points from
//   the same origin to the same range (its default sensor model, OctoMap's), on a fresh
//   map each iteration.
// Counters: bytes = the map's getMemory().total_bytes / OcTree::memoryUsage() /
//   Bonxai's VoxelGrid::memUsage(); cells.
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>
#ifdef PLANAR_GRID_WITH_BONXAI
#include <bonxai_map/probabilistic_map.hpp>
#endif

#include <cmath>
#include <limits>

#include "karlsruhe_scene.h"

namespace {

constexpr int FRAME = 10;
constexpr double RESOLUTION_M = 0.1;
constexpr double MAP_MAX_RANGE_M = 25.0;

const planar_grid::StereoFeatures&
features()
{
  static const planar_grid::StereoFeatures f = [] {
    planar_grid::StereoFeatures out;
    const auto& scene = planar_grid::bench::karlsruhe(FRAME);
    if (scene.ok)
      planar_grid::StereoFeatureMatcher().match(scene.pair.left, scene.pair.right,
                                                scene.pair.model.calibration, out);
    return out;
  }();
  return f;
}

void
BM_PlanarGridMapUpdate(benchmark::State& state)
{
  const auto& scene = planar_grid::bench::karlsruhe(FRAME);
  if (!scene.ok) {
    state.SkipWithError("Karlsruhe data not found");
    return;
  }
  const auto& calibration = scene.pair.model.calibration;
  const auto& f = features();
  pcl::PointCloud<pcl::PointXYZ>::Ptr feature_cloud(
    new pcl::PointCloud<pcl::PointXYZ>(f.points));

  planar_grid::PlanarGridMap::Params params;
  params.resolution_m = RESOLUTION_M;
  params.space.max_range_m = MAP_MAX_RANGE_M;
  // Arg 0: the prior, 2 = unknown (our default), 0 = free (the paper's; occluded space
  // is then stored explicitly as unknown).
  params.space.prior = static_cast<planar_grid::SpaceState>(state.range(0));
  planar_grid::PlaneModels planes;
  for (const auto& p : scene.planes)
    planes.emplace_back(p.model_coefficients.values.data());

  std::size_t bytes = 0, cuboid_count = 0, voxels = 0;
  for (auto _ : state) {
    planar_grid::PlanarGridMap map(params);
    // Cells (Sec. III-F).
    planar_grid::PlanarCuboidApproximation<pcl::PointXYZI> approximation;
    // A non-planar box stops at D_T (the class's 0.25 is the pipeline's).
    approximation.setNonPlanarDensityThreshold(0.0);
    approximation.setInputCloud(scene.cloud);
    approximation.setPlanes(scene.planes);
    approximation.setMinCellSize(RESOLUTION_M);
    approximation.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
    approximation.setSensorOrigin(Eigen::Vector3f::Zero());
    planar_grid::PlanarCuboids cuboids;
    approximation.approximate(cuboids);
    // Occupancy of the features (eq. 4).
    planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ> filter;
    filter.setStereoParameters(calibration.focal_length_px, calibration.baseline_m);
    filter.setInputCloud(feature_cloud);
    pcl::Indices occupied;
    filter.filter(occupied);
    map.integrateSurface(cuboids, planes, f.points, filter.getProbabilities());
    // Explicit space (Fig. 5c) from the depth image.
    const auto depth = planar_grid::DepthImage::fromDisparity(
      scene.disparity.ptr<float>(0), scene.disparity.cols, scene.disparity.rows,
      scene.disparity.step, calibration);
    map.integrateDepthImage(depth, Eigen::Isometry3d::Identity());
    benchmark::DoNotOptimize(map);
    bytes = map.getMemory().total_bytes;
    cuboid_count = map.getSurfaceLayer().getCuboids().size();
    const auto& space = map.getSpaceLayer();
    voxels = space.getVoxelCount(planar_grid::SpaceState::FREE)
             + space.getVoxelCount(planar_grid::SpaceState::OCCUPIED)
             + space.getVoxelCount(planar_grid::SpaceState::UNKNOWN);
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["cuboids"] = static_cast<double>(cuboid_count);
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["features"] = static_cast<double>(f.size());
}
BENCHMARK(BM_PlanarGridMapUpdate)
  ->ArgName("prior")
  ->Arg(2)
  ->Arg(0)
  ->Unit(benchmark::kMillisecond)
  ->MinTime(2.0);

void
BM_OctoMapInsertPointCloud(benchmark::State& state)
{
  const auto& scene = planar_grid::bench::karlsruhe(FRAME);
  if (!scene.ok) {
    state.SkipWithError("Karlsruhe data not found");
    return;
  }
  octomap::Pointcloud points;
  points.reserve(scene.dense->size());
  for (const auto& p : scene.dense->points)
    points.push_back(p.x, p.y, p.z);
  std::size_t bytes = 0, leaves = 0;
  for (auto _ : state) {
    octomap::OcTree tree(RESOLUTION_M);
    tree.insertPointCloud(points, octomap::point3d(0.0f, 0.0f, 0.0f), MAP_MAX_RANGE_M);
    benchmark::DoNotOptimize(tree);
    bytes = tree.memoryUsage();
    leaves = tree.getNumLeafNodes();
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["leaves"] = static_cast<double>(leaves);
  state.counters["points"] = static_cast<double>(points.size());
}
BENCHMARK(BM_OctoMapInsertPointCloud)->Unit(benchmark::kMillisecond)->Iterations(3);

#ifdef PLANAR_GRID_WITH_BONXAI
void
BM_BonxaiInsertPointCloud(benchmark::State& state)
{
  const auto& scene = planar_grid::bench::karlsruhe(FRAME);
  if (!scene.ok) {
    state.SkipWithError("Karlsruhe data not found");
    return;
  }
  std::vector<Eigen::Vector3d> points;
  points.reserve(scene.dense->size());
  for (const auto& p : scene.dense->points)
    points.emplace_back(p.x, p.y, p.z);
  std::size_t bytes = 0, voxels = 0;
  for (auto _ : state) {
    Bonxai::ProbabilisticMap map(RESOLUTION_M);
    map.insertPointCloud(points, Eigen::Vector3d::Zero().eval(), MAP_MAX_RANGE_M);
    benchmark::DoNotOptimize(map);
    bytes = map.grid().memUsage();
    voxels = map.grid().activeCellsCount();
  }
  state.counters["bytes"] = static_cast<double>(bytes);
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["points"] = static_cast<double>(points.size());
}
BENCHMARK(BM_BonxaiInsertPointCloud)->Unit(benchmark::kMillisecond)->MinTime(2.0);
#endif

} // namespace

BENCHMARK_MAIN();
