// SPDX-License-Identifier: BSD-3-Clause
// The main job against the classic mapping pipeline on the same Karlsruhe frames, in
// one process:
//
// BM_MainJob: PipelineRunner with config/karlsruhe.yaml (its stereo, features, filters,
//   planes, cells, KL filter and map; frames overlapping on two threads) over frames
//   [8, 8 + frames); wall time per frame.
// BM_ClassicSgbmOctoMap: the same frames loaded with the same poses, OpenCV StereoSGBM
//   in its default 5-path mode (DisparityEstimator's defaults, 128 disparities, block
//   5), the organized cloud to 30 m, moved to the world frame, and
//   octomap::OcTree(0.1)::insertPointCloud of every finite point from the camera centre
//   (max range 25 m) into one tree; wall time per frame.
// BM_ClassicSgbmStandardGrid: the same with our standard voxel grid (StandardVoxelGrid,
//   OctoMap's sensor model, the evaluation's SG) instead of OctoMap.
// Arg: the number of frames (6: 8-13). Wall time (UseRealTime): the main job's second
// thread does not show in the CPU time of the benchmark's thread. The main job's time
// includes building its stages and its first frame's pipeline fill.
#include <planar_grid/eval/standard_voxel_grid.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>

#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <string>

namespace {

constexpr std::size_t FIRST_FRAME = 8;
constexpr double RESOLUTION_M = 0.1;
constexpr double MAP_MAX_RANGE_M = 25.0;
constexpr double STEREO_MAX_RANGE_M = 30.0;

planar_grid::PipelineConfig
mainJob()
{
  return planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                         + "/config/karlsruhe.yaml");
}

bool
dataPresent()
{
  return std::filesystem::exists(std::string(PLANAR_GRID_DATA_DIR)
                                 + "/karlsruhe_2010_03_09_drive_0023/calib.txt");
}

void
BM_MainJob(benchmark::State& state)
{
  if (!dataPresent()) {
    state.SkipWithError("Karlsruhe data not found");
    return;
  }
  const auto frames = static_cast<std::size_t>(state.range(0));
  const auto config = mainJob();
  double map_bytes = 0.0;
  for (auto _ : state) {
    planar_grid::PipelineRunner runner(config);
    runner.setFrameRange(FIRST_FRAME, FIRST_FRAME + frames);
    const auto report = runner.run();
    benchmark::DoNotOptimize(report);
    map_bytes = static_cast<double>(runner.state().map->getMemory().total_bytes);
  }
  state.counters["ms_per_frame"] = benchmark::Counter(
    static_cast<double>(frames),
    benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["map_bytes"] = map_bytes;
}

/** The classic pipeline over the frames: SGBM, the cloud in the world frame, and
 * \a insert(cloud, sensor_origin) per frame into a map made by \a make_map. */
template <typename MakeMap, typename Insert, typename Bytes>
void
classicPipeline(benchmark::State& state, MakeMap make_map, Insert insert, Bytes bytes)
{
  if (!dataPresent()) {
    state.SkipWithError("Karlsruhe data not found");
    return;
  }
  const auto frames = static_cast<std::size_t>(state.range(0));
  const auto config = mainJob();
  const auto source = planar_grid::createFrameSource(config.input);
  const planar_grid::DisparityEstimator::Params stereo_params; // OpenCV's classic SGBM
  double map_bytes = 0.0;
  for (auto _ : state) {
    auto map = make_map();
    planar_grid::DisparityEstimator estimator(stereo_params);
    for (std::size_t i = FIRST_FRAME; i < FIRST_FRAME + frames; ++i) {
      planar_grid::Frame frame;
      source->load(i, frame);
      estimator.compute(frame.left, frame.right, frame.disparity);
      pcl::PointCloud<pcl::PointXYZI> camera;
      planar_grid::disparityToPointCloud(frame.disparity, frame.left, frame.calibration,
                                         STEREO_MAX_RANGE_M, camera);
      pcl::PointCloud<pcl::PointXYZ> world;
      world.reserve(camera.size());
      const Eigen::Affine3f world_T_camera(frame.world_T_camera.cast<float>().matrix());
      for (const auto& p : camera.points)
        if (std::isfinite(p.z)) {
          const Eigen::Vector3f q = world_T_camera * p.getVector3fMap();
          world.push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
        }
      insert(*map, world, world_T_camera.translation());
    }
    map_bytes = static_cast<double>(bytes(*map));
    benchmark::DoNotOptimize(map);
  }
  state.counters["ms_per_frame"] = benchmark::Counter(
    static_cast<double>(frames),
    benchmark::Counter::kIsIterationInvariantRate | benchmark::Counter::kInvert);
  state.counters["map_bytes"] = map_bytes;
}

void
BM_ClassicSgbmOctoMap(benchmark::State& state)
{
  classicPipeline(
    state, [] { return std::make_unique<octomap::OcTree>(RESOLUTION_M); },
    [](octomap::OcTree& tree, const pcl::PointCloud<pcl::PointXYZ>& cloud,
       const Eigen::Vector3f& origin) {
      octomap::Pointcloud points;
      points.reserve(cloud.size());
      for (const auto& p : cloud.points)
        points.push_back(p.x, p.y, p.z);
      tree.insertPointCloud(
        points, octomap::point3d(origin.x(), origin.y(), origin.z()), MAP_MAX_RANGE_M);
    },
    [](const octomap::OcTree& tree) { return tree.memoryUsage(); });
}

void
BM_ClassicSgbmStandardGrid(benchmark::State& state)
{
  classicPipeline(
    state,
    [] {
      planar_grid::StandardVoxelGrid::Params params;
      params.resolution_m = RESOLUTION_M;
      params.max_range_m = MAP_MAX_RANGE_M;
      return std::make_unique<planar_grid::StandardVoxelGrid>(params);
    },
    [](planar_grid::StandardVoxelGrid& grid,
       const pcl::PointCloud<pcl::PointXYZ>& cloud,
       const Eigen::Vector3f& origin) { grid.insertPointCloud(cloud, origin); },
    [](const planar_grid::StandardVoxelGrid& grid) { return grid.getMemoryBytes(); });
}

} // namespace

BENCHMARK(BM_MainJob)
  ->Arg(6)
  ->Unit(benchmark::kMillisecond)
  ->Iterations(1)
  ->UseRealTime();
BENCHMARK(BM_ClassicSgbmOctoMap)
  ->Arg(6)
  ->Unit(benchmark::kMillisecond)
  ->Iterations(1)
  ->UseRealTime();
BENCHMARK(BM_ClassicSgbmStandardGrid)
  ->Arg(6)
  ->Unit(benchmark::kMillisecond)
  ->Iterations(1)
  ->UseRealTime();

BENCHMARK_MAIN();
