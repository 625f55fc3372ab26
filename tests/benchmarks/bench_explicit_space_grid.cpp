// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid::integrateDepthImage vs octomap::OcTree::insertPointCloud on
// Karlsruhe frame 10 (SGBM disparity, depth = f B / d) at 0.1 m, 25 m max range, into
// an empty grid and as a drive of 8 views into one grid; and
// ExplicitSpaceGrid::integratePointCloud (ray casting) vs insertPointCloud on PCL's
// room_scan1.pcd (a 360 degree LiDAR scan, voxel grid 0.05 m) at 0.1 m.
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>

#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>

#include <cstdint>
#include <cstdio>
#include <limits>
#include <memory>
#include <string>
#include <vector>

#include "karlsruhe_frame.h"

namespace planar_grid {
/** \brief Benchmark access to the thread count of integrateDepthImage() (a friend). */
struct ExplicitSpaceGridThreads {
  static void set(ExplicitSpaceGrid& grid, int n) { grid.num_threads_ = n; }
};
} // namespace planar_grid

namespace {

using planar_grid::DepthImage;
using planar_grid::ExplicitSpaceGrid;

/** \brief Frame 10 as a depth image (computed once). */
const DepthImage&
frame10()
{
  static const DepthImage image = [] {
    DepthImage d;
    const auto pair = planar_grid::bench::loadKarlsruhePair(10);
    if (!pair.ok)
      return d;
    cv::Mat disparity;
    planar_grid::DisparityEstimator().compute(pair.left, pair.right, disparity);
    d =
      DepthImage::fromDisparity(disparity.ptr<float>(0), disparity.cols, disparity.rows,
                                disparity.step, pair.model.calibration);
    return d;
  }();
  return image;
}

void
BM_ExplicitSpaceGridIntegrate(benchmark::State& state)
{
  const DepthImage& image = frame10();
  if (image.depth_m.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  ExplicitSpaceGrid::Params p;
  p.resolution_m = 0.1;
  p.max_range_m = 25.0;
  p.prior = static_cast<planar_grid::SpaceState>(state.range(0));
  std::size_t bytes = 0, blocks = 0;
  for (auto _ : state) {
    ExplicitSpaceGrid grid(p);
    planar_grid::ExplicitSpaceGridThreads::set(grid, static_cast<int>(state.range(1)));
    grid.integrateDepthImage(image, Eigen::Isometry3d::Identity());
    bytes = grid.getMemoryBytes();
    blocks = grid.getBlockCount();
    benchmark::DoNotOptimize(blocks);
  }
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["blocks"] = static_cast<double>(blocks);
}
// Args: prior (2 = unknown, the default; 0 = free: occluded space is written too),
// threads of the free / occluded pass (1 = the default; the result is the same).
// Report CPU time for 1 thread, real time for 2 (CPU time sums the threads).
BENCHMARK(BM_ExplicitSpaceGridIntegrate)
  ->ArgNames({"prior", "threads"})
  ->Args({2, 1})
  ->Args({2, 2})
  ->Args({0, 1})
  ->Args({0, 2})
  ->Unit(benchmark::kMillisecond);

void
BM_ExplicitSpaceGridDrive(benchmark::State& state)
{
  // Frame 10 integrated 8 times into one grid, the camera 1 m further along its
  // optical axis each time: most blocks of a view are already stored (mixed ones
  // decoded, updated and re-encoded), as in a sequence. Time per view.
  const DepthImage& image = frame10();
  if (image.depth_m.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  ExplicitSpaceGrid::Params p;
  p.resolution_m = 0.1;
  p.max_range_m = 25.0;
  p.prior = static_cast<planar_grid::SpaceState>(state.range(0));
  constexpr int VIEWS = 8;
  std::size_t bytes = 0, blocks = 0;
  for (auto _ : state) {
    ExplicitSpaceGrid grid(p);
    for (int k = 0; k < VIEWS; ++k) {
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.translation().z() = static_cast<double>(k);
      grid.integrateDepthImage(image, pose);
    }
    bytes = grid.getMemoryBytes();
    blocks = grid.getBlockCount();
    benchmark::DoNotOptimize(blocks);
  }
  // seconds per view (printed with its unit, e.g. "31.4ms")
  state.counters["time_per_view"] =
    benchmark::Counter(static_cast<double>(state.iterations()) * VIEWS,
                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["blocks"] = static_cast<double>(blocks);
}
// Arg: prior (2 = unknown, the default; 0 = free).
BENCHMARK(BM_ExplicitSpaceGridDrive)
  ->ArgNames({"prior"})
  ->Arg(2)
  ->Arg(0)
  ->Unit(benchmark::kMillisecond);

/** \brief The main job's views (config/karlsruhe.yaml): every frame's SGBM disparity
 * from its stereo_disparity stage as a depth image, with the frame's pose (computed
 * once). */
struct SequenceViews {
  std::vector<DepthImage> depths;
  std::vector<Eigen::Isometry3d> poses;
};

const SequenceViews&
karlsruheSequence()
{
  static const SequenceViews views = [] {
    SequenceViews out;
    const auto config = planar_grid::loadPipelineConfig(
      std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml");
    const auto source = planar_grid::createFrameSource(config.input);
    std::unique_ptr<planar_grid::Stage> stereo;
    for (const auto& sc : config.stages)
      if (sc.type == "stereo_disparity")
        stereo = planar_grid::findStage(sc.type)->create(sc.params);
    if (!stereo)
      return out;
    planar_grid::PipelineState state;
    stereo->start(state);
    for (std::size_t i = 0; i < source->size(); ++i) {
      planar_grid::Frame frame;
      source->load(i, frame);
      frame.sequence_number = i;
      stereo->process(frame, state);
      const cv::Mat& d = frame.disparity;
      out.depths.push_back(DepthImage::fromDisparity(d.ptr<float>(0), d.cols, d.rows,
                                                     d.step, frame.calibration));
      out.poses.push_back(frame.world_T_camera);
    }
    stereo->finish(state);
    return out;
  }();
  return views;
}

/** \brief FNV-1a of a byte string, in hexadecimal. */
std::string
fnv64(const std::vector<std::uint8_t>& bytes)
{
  std::uint64_t h = 1469598103934665603ULL;
  for (const auto b : bytes)
    h = (h ^ b) * 1099511628211ULL;
  char text[24];
  std::snprintf(text, sizeof(text), "%016llx", static_cast<unsigned long long>(h));
  return text;
}

void
BM_ExplicitSpaceGridSequence(benchmark::State& state)
{
  // The main job's map_integration, space layer only: all 112 Karlsruhe views in
  // order into one grid (0.1 m, 25 m, unknown prior); time per view. The counters
  // and the label identify the final grid (voxel counts, blocks, a hash of
  // serialize()).
  const SequenceViews& views = karlsruheSequence();
  if (views.depths.empty()) {
    state.SkipWithError("Karlsruhe sequence not found");
    return;
  }
  ExplicitSpaceGrid::Params p;
  p.resolution_m = 0.1;
  p.max_range_m = 25.0;
  p.prior = static_cast<planar_grid::SpaceState>(state.range(0));
  std::vector<std::uint8_t> bytes;
  std::size_t free_voxels = 0, occupied_voxels = 0, blocks = 0;
  for (auto _ : state) {
    ExplicitSpaceGrid grid(p);
    for (std::size_t k = 0; k < views.depths.size(); ++k)
      grid.integrateDepthImage(views.depths[k], views.poses[k]);
    state.PauseTiming();
    free_voxels = grid.getVoxelCount(planar_grid::SpaceState::FREE);
    occupied_voxels = grid.getVoxelCount(planar_grid::SpaceState::OCCUPIED);
    blocks = grid.getBlockCount();
    bytes.clear();
    grid.serialize(bytes);
    state.ResumeTiming();
  }
  state.counters["time_per_view"] =
    benchmark::Counter(static_cast<double>(state.iterations() * views.depths.size()),
                       benchmark::Counter::kIsRate | benchmark::Counter::kInvert);
  state.counters["free"] = static_cast<double>(free_voxels);
  state.counters["occupied"] = static_cast<double>(occupied_voxels);
  state.counters["blocks"] = static_cast<double>(blocks);
  state.SetLabel("serialize() FNV-1a " + fnv64(bytes));
}
// Arg: prior (2 = unknown, the main job's; 0 = free). CPU time of the thread.
BENCHMARK(BM_ExplicitSpaceGridSequence)
  ->ArgNames({"prior"})
  ->Arg(2)
  ->Arg(0)
  ->Unit(benchmark::kMillisecond);

void
BM_OctoMapInsertPointCloud(benchmark::State& state)
{
  const DepthImage& image = frame10();
  if (image.depth_m.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  octomap::Pointcloud cloud;
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u) {
      const float d = image.at(u, v);
      if (!(d > 0.0f) || d > 25.0f)
        continue;
      cloud.push_back((u - image.cx) / image.fx * d, (v - image.cy) / image.fy * d, d);
    }
  std::size_t bytes = 0;
  for (auto _ : state) {
    octomap::OcTree tree(0.1);
    tree.insertPointCloud(cloud, octomap::point3d(0, 0, 0), 25.0);
    bytes = tree.memoryUsage();
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["points"] = static_cast<double>(cloud.size());
}
BENCHMARK(BM_OctoMapInsertPointCloud)->Unit(benchmark::kMillisecond)->Iterations(2);

/** \brief room_scan1.pcd through a 0.05 m voxel grid (loaded once); its sensor origin
 * is the PCD's VIEWPOINT, the scan's frame is the world frame. */
const pcl::PointCloud<pcl::PointXYZ>&
roomScan()
{
  static const pcl::PointCloud<pcl::PointXYZ> scan = [] {
    pcl::PointCloud<pcl::PointXYZ>::Ptr raw(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::PointCloud<pcl::PointXYZ> out;
    if (pcl::io::loadPCDFile(
          std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/room_scan1.pcd", *raw)
        != 0)
      return out;
    pcl::VoxelGrid<pcl::PointXYZ> grid;
    grid.setLeafSize(0.05f, 0.05f, 0.05f);
    grid.setInputCloud(raw);
    grid.filter(out);
    out.sensor_origin_ = raw->sensor_origin_;
    return out;
  }();
  return scan;
}

void
BM_ExplicitSpaceGridRays(benchmark::State& state)
{
  const auto& scan = roomScan();
  if (scan.empty()) {
    state.SkipWithError("room_scan1.pcd not found");
    return;
  }
  ExplicitSpaceGrid::Params p;
  p.resolution_m = 0.1;
  p.max_range_m = 25.0;
  std::size_t bytes = 0, blocks = 0;
  for (auto _ : state) {
    ExplicitSpaceGrid grid(p);
    grid.integratePointCloud(scan, scan.sensor_origin_.head<3>());
    bytes = grid.getMemoryBytes();
    blocks = grid.getBlockCount();
    benchmark::DoNotOptimize(blocks);
  }
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["points"] = static_cast<double>(scan.size());
}
BENCHMARK(BM_ExplicitSpaceGridRays)->Unit(benchmark::kMillisecond);

void
BM_OctoMapInsertScan(benchmark::State& state)
{
  const auto& scan = roomScan();
  if (scan.empty()) {
    state.SkipWithError("room_scan1.pcd not found");
    return;
  }
  octomap::Pointcloud cloud;
  for (const auto& q : scan)
    cloud.push_back(q.x, q.y, q.z);
  const octomap::point3d origin(scan.sensor_origin_.x(), scan.sensor_origin_.y(),
                                scan.sensor_origin_.z());
  std::size_t bytes = 0;
  for (auto _ : state) {
    octomap::OcTree tree(0.1);
    tree.insertPointCloud(cloud, origin, 25.0);
    bytes = tree.memoryUsage();
    benchmark::DoNotOptimize(bytes);
  }
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["points"] = static_cast<double>(cloud.size());
}
BENCHMARK(BM_OctoMapInsertScan)->Unit(benchmark::kMillisecond);

} // namespace

BENCHMARK_MAIN();
