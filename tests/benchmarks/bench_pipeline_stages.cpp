// SPDX-License-Identifier: BSD-3-Clause
// Every stage of the main job (config/karlsruhe.yaml) on a real frame: the
// stages are built from the configuration through the registry, frame 10 of the
// Karlsruhe sequence (after frame 9, so that the feature tracks and the map hold a
// previous frame) is run up to each stage once, and the benchmark times that stage
// alone on a copy of its input. Wall time per iteration; stateful stages (the KL
// filter, the map) see the same frame again on every iteration.
//   build-bench/tests/benchmarks/bench_pipeline_stages
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/fast_voxel_grid.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>

#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstdio>
#include <memory>
#include <string>
#include <vector>

namespace {

using planar_grid::Frame;
using planar_grid::PipelineState;
using planar_grid::Stage;

/** The main job's stages and the input of each on frame 10. */
struct Prepared {
  std::vector<std::unique_ptr<Stage>> stages;
  std::vector<std::string> types;
  std::vector<Frame> inputs; // inputs[s]: the frame entering stage s
  PipelineState state;
  bool ok{false};
};

Frame
deepCopy(const Frame& frame)
{
  Frame copy = frame;
  if (frame.cloud)
    copy.cloud.reset(new Frame::Cloud(*frame.cloud));
  copy.left = frame.left.clone();
  copy.right = frame.right.clone();
  copy.disparity = frame.disparity.clone();
  return copy;
}

Prepared&
prepared()
{
  static Prepared p = [] {
    Prepared out;
    const auto config = planar_grid::loadPipelineConfig(
      std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml");
    const auto source = planar_grid::createFrameSource(config.input);
    for (const auto& sc : config.stages) {
      out.stages.push_back(planar_grid::findStage(sc.type)->create(sc.params));
      out.types.push_back(sc.type);
    }
    for (auto& s : out.stages)
      s->start(out.state);
    for (std::size_t i = 9; i <= 10; ++i) {
      Frame frame;
      source->load(i, frame);
      frame.sequence_number = i;
      for (std::size_t s = 0; s < out.stages.size(); ++s) {
        if (i == 10)
          out.inputs.push_back(deepCopy(frame));
        out.stages[s]->process(frame, out.state);
      }
    }
    out.ok = true;
    return out;
  }();
  return p;
}

void
BM_Stage(benchmark::State& st)
{
  Prepared& p = prepared();
  const auto s = static_cast<std::size_t>(st.range(0));
  st.SetLabel(p.types[s]);
  for (auto _ : st) {
    st.PauseTiming();
    Frame frame = deepCopy(p.inputs[s]);
    st.ResumeTiming();
    p.stages[s]->process(frame, p.state);
    benchmark::DoNotOptimize(frame.cloud);
  }
  if (p.inputs[s].cloud)
    st.counters["points_in"] = static_cast<double>(p.inputs[s].cloud->size());
}

/** PCL's StatisticalOutlierRemoval, the peer of the statistical_outlier_removal stage
 * (FastStatisticalOutlierRemoval, the same kept points), on the same input cloud with
 * the stage's parameters from config/karlsruhe.yaml (mean_k 20, 2 sigma). */
void
BM_PclStatisticalOutlierRemoval(benchmark::State& st)
{
  Prepared& p = prepared();
  std::size_t s = 0;
  while (s < p.types.size() && p.types[s] != "statistical_outlier_removal")
    ++s;
  if (s == p.types.size()) {
    st.SkipWithError("config/karlsruhe.yaml has no statistical_outlier_removal");
    return;
  }
  pcl::StatisticalOutlierRemoval<pcl::PointXYZI> filter;
  filter.setMeanK(20);
  filter.setStddevMulThresh(2.0);
  filter.setInputCloud(p.inputs[s].cloud);
  for (auto _ : st) {
    Frame::Cloud out;
    filter.filter(out);
    benchmark::DoNotOptimize(out);
  }
  st.counters["points_in"] = static_cast<double>(p.inputs[s].cloud->size());
}

/** The frame entering the main job's stage \a stage_type, for every 8th Karlsruhe
 * frame: the stages before it run (all but the KL filter, which changes no point or
 * feature); the images and the disparity are released. */
std::vector<Frame>
stageInputs(const std::string& stage_type)
{
  std::vector<Frame> out;
  const auto config = planar_grid::loadPipelineConfig(
    std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml");
  const auto source = planar_grid::createFrameSource(config.input);
  std::vector<std::unique_ptr<Stage>> stages;
  for (const auto& sc : config.stages) {
    if (sc.type == stage_type)
      break;
    if (sc.type != "kl_occupancy_filter")
      stages.push_back(planar_grid::findStage(sc.type)->create(sc.params));
  }
  PipelineState state;
  for (auto& s : stages)
    s->start(state);
  for (std::size_t i = 0; i < source->size(); i += 8) {
    Frame frame;
    source->load(i, frame);
    frame.sequence_number = i;
    for (auto& s : stages)
      s->process(frame, state);
    frame.left.release();
    frame.right.release();
    frame.disparity.release();
    out.push_back(std::move(frame));
  }
  for (auto& s : stages)
    s->finish(state);
  return out;
}

/** The statistical_outlier_removal stage's input (the 0.1 m voxel grid's output) of
 * every 8th Karlsruhe frame (stageInputs()): the filter's cost over a sequence rather
 * than one frame. */
const std::vector<Frame::Cloud::ConstPtr>&
outlierRemovalInputs()
{
  static const std::vector<Frame::Cloud::ConstPtr> clouds = [] {
    std::vector<Frame::Cloud::ConstPtr> out;
    for (const auto& frame : stageInputs("statistical_outlier_removal"))
      out.push_back(frame.cloud);
    return out;
  }();
  return clouds;
}

/** FastStatisticalOutlierRemoval (range(0) = 0) or PCL's StatisticalOutlierRemoval
 * (1) with the main job's parameters (mean_k 20, 2 sigma) over outlierRemovalInputs():
 * the time of one iteration is that of all the frames (counter "frames"). Both keep the
 * same points (test_filters). */
void
BM_OutlierRemovalSequence(benchmark::State& st)
{
  const auto& clouds = outlierRemovalInputs();
  const bool pcl_filter = st.range(0) == 1;
  st.SetLabel(pcl_filter ? "pcl::StatisticalOutlierRemoval"
                         : "FastStatisticalOutlierRemoval");
  for (auto _ : st)
    for (const auto& cloud : clouds) {
      pcl::Indices kept;
      if (pcl_filter) {
        pcl::StatisticalOutlierRemoval<pcl::PointXYZI> filter;
        filter.setMeanK(20);
        filter.setStddevMulThresh(2.0);
        filter.setInputCloud(cloud);
        filter.filter(kept);
      } else {
        planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZI> filter;
        filter.setMeanK(20);
        filter.setStddevMulThresh(2.0);
        filter.setInputCloud(cloud);
        filter.filter(kept);
      }
      benchmark::DoNotOptimize(kept);
    }
  st.counters["frames"] = static_cast<double>(clouds.size());
}

/** The voxel_grid stage's input (the depth_error_filter's output, the whole stereo
 * cloud of a frame) of every 8th Karlsruhe frame (stageInputs()). */
const std::vector<Frame::Cloud::ConstPtr>&
voxelGridInputs()
{
  static const std::vector<Frame::Cloud::ConstPtr> clouds = [] {
    std::vector<Frame::Cloud::ConstPtr> out;
    for (const auto& frame : stageInputs("voxel_grid"))
      out.push_back(frame.cloud);
    return out;
  }();
  return clouds;
}

/** FastVoxelGrid (range(0) = 0) or PCL's VoxelGrid (1) with the main job's leaf size
 * (0.1 m) over voxelGridInputs(): the time of one iteration is that of all the frames
 * (counter "frames"). Both give the same cloud, bit for bit (test_filters). */
void
BM_VoxelGridSequence(benchmark::State& st)
{
  const auto& clouds = voxelGridInputs();
  const bool pcl_filter = st.range(0) == 1;
  st.SetLabel(pcl_filter ? "pcl::VoxelGrid" : "FastVoxelGrid");
  double points_in = 0.0, points_out = 0.0;
  for (auto _ : st) {
    points_in = points_out = 0.0;
    for (const auto& cloud : clouds) {
      Frame::Cloud out;
      if (pcl_filter) {
        pcl::VoxelGrid<pcl::PointXYZI> filter;
        filter.setLeafSize(0.1f, 0.1f, 0.1f);
        filter.setInputCloud(cloud);
        filter.filter(out);
      } else {
        planar_grid::FastVoxelGrid<pcl::PointXYZI> filter;
        filter.setLeafSize(0.1f, 0.1f, 0.1f);
        filter.setInputCloud(cloud);
        filter.filter(out);
      }
      benchmark::DoNotOptimize(out);
      points_in += static_cast<double>(cloud->size());
      points_out += static_cast<double>(out.size());
    }
  }
  st.counters["frames"] = static_cast<double>(clouds.size());
  st.counters["points_in"] = points_in;
  st.counters["points_out"] = points_out;
}

/** The multi_plane_segmentation stage's input frame (after transform_to_world) for
 * every 8th Karlsruhe frame (stageInputs()). */
const std::vector<Frame>&
segmentationInputs()
{
  static const std::vector<Frame> frames = stageInputs("multi_plane_segmentation");
  return frames;
}

/** The main job's multi_plane_segmentation stage over segmentationInputs(): one
 * iteration segments all the frames (counter "frames"); the label is a hash of every
 * plane's coefficients and inliers, so that two builds can be compared. */
void
BM_PlaneSegmentationSequence(benchmark::State& st)
{
  const auto& frames = segmentationInputs();
  const auto config = planar_grid::loadPipelineConfig(
    std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml");
  std::unique_ptr<Stage> stage;
  for (const auto& sc : config.stages)
    if (sc.type == "multi_plane_segmentation")
      stage = planar_grid::findStage(sc.type)->create(sc.params);
  PipelineState state;
  stage->start(state);
  std::uint64_t hash = 0;
  double planes = 0.0, inliers = 0.0;
  for (auto _ : st) {
    hash = 0xcbf29ce484222325ULL;
    planes = inliers = 0.0;
    for (const auto& input : frames) {
      Frame frame = input; // the stage reads the cloud and writes only the planes
      stage->process(frame, state);
      st.PauseTiming();
      const auto mix = [&hash](const void* data, std::size_t size) {
        const auto* bytes = static_cast<const unsigned char*>(data);
        for (std::size_t k = 0; k < size; ++k) {
          hash ^= bytes[k];
          hash *= 0x100000001b3ULL;
        }
      };
      for (const auto& plane : frame.planes) {
        mix(plane.model_coefficients.values.data(),
            plane.model_coefficients.values.size() * sizeof(float));
        mix(plane.inliers.indices.data(),
            plane.inliers.indices.size() * sizeof(pcl::index_t));
        inliers += static_cast<double>(plane.inliers.indices.size());
      }
      planes += static_cast<double>(frame.planes.size());
      st.ResumeTiming();
    }
  }
  stage->finish(state);
  char label[32];
  std::snprintf(label, sizeof(label), "%016llx", static_cast<unsigned long long>(hash));
  st.SetLabel(label);
  st.counters["frames"] = static_cast<double>(frames.size());
  st.counters["planes"] = planes;
  st.counters["inliers"] = inliers;
}

} // namespace

// The 12 stages of config/karlsruhe.yaml, in order.
BENCHMARK(BM_Stage)->DenseRange(0, 11)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(BM_PclStatisticalOutlierRemoval)
  ->Unit(benchmark::kMillisecond)
  ->UseRealTime();

BENCHMARK(BM_OutlierRemovalSequence)
  ->Arg(0)
  ->Arg(1)
  ->Unit(benchmark::kMillisecond)
  ->MeasureProcessCPUTime();

BENCHMARK(BM_VoxelGridSequence)
  ->Arg(0)
  ->Arg(1)
  ->Unit(benchmark::kMillisecond)
  ->MeasureProcessCPUTime();

BENCHMARK(BM_PlaneSegmentationSequence)
  ->Unit(benchmark::kMillisecond)
  ->MeasureProcessCPUTime();

BENCHMARK_MAIN();
