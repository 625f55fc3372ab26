// SPDX-License-Identifier: BSD-3-Clause
// The main job's kl_occupancy_filter stage (config/karlsruhe.yaml) over the Karlsruhe
// sequence: the features of every frame come from the job's feature_matching stage
// once, then each iteration runs a fresh stage over all 112 frames in order, as the
// pipeline does (the tracks need consecutive frames). The label is a hash of every
// frame's feature probabilities and track ids, so that two builds can be compared for
// the same result; the counters give the tracks' re-observations.
//   build-bench/tests/benchmarks/bench_kl_occupancy_filter
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/stage.h>

#include <benchmark/benchmark.h>

#include <cstdint>
#include <cstdio>
#include <cstring>
#include <memory>
#include <string>
#include <vector>

namespace {

using planar_grid::Frame;
using planar_grid::PipelineState;
using planar_grid::Stage;

/** The kl_occupancy_filter stage's configuration and its input on every frame. */
struct Sequence {
  planar_grid::StageConfig kl_config;
  std::vector<Frame> frames;
};

const Sequence&
sequence()
{
  static const Sequence s = [] {
    Sequence out;
    const auto config = planar_grid::loadPipelineConfig(
      std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml");
    const auto source = planar_grid::createFrameSource(config.input);
    std::unique_ptr<Stage> features;
    for (const auto& sc : config.stages) {
      if (sc.type == "feature_matching")
        features = planar_grid::findStage(sc.type)->create(sc.params);
      if (sc.type == "kl_occupancy_filter")
        out.kl_config = sc;
    }
    PipelineState state;
    features->start(state);
    for (std::size_t i = 0; i < source->size(); ++i) {
      Frame frame;
      source->load(i, frame);
      frame.sequence_number = i;
      features->process(frame, state);
      frame.right.release(); // the stage needs only to know the input is stereo
      out.frames.push_back(std::move(frame));
    }
    features->finish(state);
    return out;
  }();
  return s;
}

/** FNV-1a over \a size bytes. */
void
hashBytes(std::uint64_t& hash, const void* data, std::size_t size)
{
  const auto* bytes = static_cast<const unsigned char*>(data);
  for (std::size_t k = 0; k < size; ++k) {
    hash ^= bytes[k];
    hash *= 0x100000001b3ULL;
  }
}

/** The kl_occupancy_filter stage of config/karlsruhe.yaml over all frames; one
 * iteration is the whole sequence (counter "frames"). */
void
BM_KLOccupancyFilterSequence(benchmark::State& st)
{
  const Sequence& s = sequence();
  std::uint64_t hash = 0;
  double reobserved = 0.0, occupied = 0.0, features = 0.0, probability_sum = 0.0;
  for (auto _ : st) {
    st.PauseTiming();
    auto stage = planar_grid::findStage(s.kl_config.type)->create(s.kl_config.params);
    PipelineState state;
    stage->start(state);
    std::vector<Frame> frames = s.frames; // cv::Mat copies share their pixels
    hash = 0xcbf29ce484222325ULL;
    reobserved = occupied = features = probability_sum = 0.0;
    st.ResumeTiming();
    for (auto& frame : frames) {
      stage->process(frame, state);
      st.PauseTiming();
      hashBytes(hash, frame.feature_probabilities.data(),
                frame.feature_probabilities.size() * sizeof(float));
      hashBytes(hash, frame.feature_track_ids.data(),
                frame.feature_track_ids.size() * sizeof(std::int64_t));
      std::vector<std::pair<std::string, double>> values;
      stage->counters(frame, values);
      for (const auto& v : values) {
        if (v.first == "reobserved")
          reobserved += v.second;
        else if (v.first == "occupied")
          occupied += v.second;
        else if (v.first == "features")
          features += v.second;
      }
      for (const float p : frame.feature_probabilities)
        probability_sum += p;
      st.ResumeTiming();
    }
    stage->finish(state);
  }
  char label[32];
  std::snprintf(label, sizeof(label), "%016llx", static_cast<unsigned long long>(hash));
  st.SetLabel(label);
  st.counters["frames"] = static_cast<double>(s.frames.size());
  st.counters["features"] = features;
  st.counters["reobserved"] = reobserved;
  st.counters["occupied"] = occupied;
  st.counters["mean_probability"] = features > 0.0 ? probability_sum / features : 0.0;
}

} // namespace

BENCHMARK(BM_KLOccupancyFilterSequence)
  ->Unit(benchmark::kMillisecond)
  ->MeasureProcessCPUTime();

BENCHMARK_MAIN();
