// SPDX-License-Identifier: BSD-3-Clause
// Dense stereo candidates for real time: every DisparityEstimator algorithm, full and
// half resolution, timed on the real Karlsruhe frame 10 (1344x372, 128 disparities, as
// the main job's stereo_disparity stage runs it) on 1 and 2 OpenCV threads, and scored
// on Middlebury Aloe (bad-pixel rates and end-point error against the ground truth,
// docs/STEREO.md). Wall time per call (UseRealTime: OpenCV's worker threads are not in
// the calling thread's CPU time).
//   build-bench/tests/benchmarks/bench_disparity --benchmark_filter=Karlsruhe
//       --benchmark_repetitions=5 --benchmark_report_aggregates_only=true
//   build-bench/tests/benchmarks/bench_disparity --benchmark_filter=Aloe
#include <planar_grid/stereo/disparity_estimator.h>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include <cmath>
#include <string>
#include <vector>

#include "../stereo/disparity_metrics.h"
#include "karlsruhe_frame.h"

namespace {

using planar_grid::DisparityAlgorithm;
using planar_grid::DisparityEstimator;

/** \brief One configuration of the comparison: the main job's parameters with another
 * matcher, scale or block. */
struct Candidate {
  std::string name;
  DisparityAlgorithm algorithm;
  int downscale;
  int block_size_px;
  int row_downscale{1};
};

const std::vector<Candidate>&
candidates()
{
  static const std::vector<Candidate> list = {
    {"sgbm", DisparityAlgorithm::SGBM, 1, 5},
    {"sgbm_3way", DisparityAlgorithm::SGBM_3WAY, 1, 5},
    {"sgbm_hh", DisparityAlgorithm::SGBM_HH, 1, 5},
    {"sgbm_hh4", DisparityAlgorithm::SGBM_HH4, 1, 5},
    {"block_matching_b9", DisparityAlgorithm::BLOCK_MATCHING, 1, 9},
    {"block_matching_b15", DisparityAlgorithm::BLOCK_MATCHING, 1, 15},
    {"sgbm_ds2", DisparityAlgorithm::SGBM, 2, 5},
    {"sgbm_3way_ds2", DisparityAlgorithm::SGBM_3WAY, 2, 5},
    {"sgbm_3way_ds2_b3", DisparityAlgorithm::SGBM_3WAY, 2, 3},
    {"block_matching_b9_ds2", DisparityAlgorithm::BLOCK_MATCHING, 2, 9},
    {"sgbm_3way_rows2", DisparityAlgorithm::SGBM_3WAY, 1, 5, 2},
    {"sgbm_3way_rows2_b3", DisparityAlgorithm::SGBM_3WAY, 1, 3, 2},
    {"sgbm_3way_rows2_b1", DisparityAlgorithm::SGBM_3WAY, 1, 1, 2},
    {"sgbm_3way_b3", DisparityAlgorithm::SGBM_3WAY, 1, 3},
  };
  return list;
}

/** \brief The main job's stereo_disparity parameters (config/karlsruhe.yaml) with the
 * candidate's matcher. */
DisparityEstimator::Params
paramsOf(const Candidate& candidate, int num_threads, int num_disparities_px)
{
  DisparityEstimator::Params params;
  params.algorithm = candidate.algorithm;
  params.downscale = candidate.downscale;
  params.row_downscale = candidate.row_downscale;
  params.block_size_px = candidate.block_size_px;
  params.num_threads = num_threads;
  params.num_disparities_px = num_disparities_px;
  return params;
}

void
BM_Karlsruhe(benchmark::State& state, const Candidate& candidate)
{
  static const planar_grid::bench::KarlsruhePair pair =
    planar_grid::bench::loadKarlsruhePair(10);
  if (!pair.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found under PLANAR_GRID_DATA_DIR");
    return;
  }
  const DisparityEstimator estimator(
    paramsOf(candidate, static_cast<int>(state.range(0)), 128));
  cv::Mat disparity;
  for (auto _ : state) {
    estimator.compute(pair.left, pair.right, disparity);
    benchmark::DoNotOptimize(disparity.data);
  }
  // Share of the image with a positive disparity (what the reprojection keeps before
  // its range cut).
  std::size_t positive = 0;
  for (int v = 0; v < disparity.rows; ++v)
    for (int u = 0; u < disparity.cols; ++u)
      positive += disparity.at<float>(v, u) > 0.0f; // NaN compares false
  state.counters["positive_fraction"] =
    static_cast<double>(positive) / static_cast<double>(disparity.total());
}

void
BM_Aloe(benchmark::State& state, const Candidate& candidate)
{
  const std::string dir = std::string(PLANAR_GRID_DATA_DIR) + "/middlebury_aloe";
  static const cv::Mat left = cv::imread(dir + "/aloeL.jpg", cv::IMREAD_COLOR);
  static const cv::Mat right = cv::imread(dir + "/aloeR.jpg", cv::IMREAD_COLOR);
  static const cv::Mat truth = cv::imread(dir + "/aloeGT.png", cv::IMREAD_UNCHANGED);
  if (left.empty() || right.empty() || truth.empty()) {
    state.SkipWithError("middlebury_aloe not found under PLANAR_GRID_DATA_DIR");
    return;
  }
  // 224 = 14 * 16 disparities cover the GT's 211 px (a multiple of 32 for
  // downscale 2).
  const DisparityEstimator estimator(paramsOf(candidate, 2, 224));
  cv::Mat disparity;
  for (auto _ : state) {
    estimator.compute(left, right, disparity);
    benchmark::DoNotOptimize(disparity.data);
  }
  const auto errors = planar_grid::test::compareWithGroundTruth(disparity, truth);
  state.counters["density"] = errors.density;
  state.counters["bad1_percent"] = 100.0 * errors.bad1;
  state.counters["bad2_percent"] = 100.0 * errors.bad2;
  state.counters["epe_px"] = errors.epe_px;
}

const bool registered = [] {
  for (const Candidate& candidate : candidates()) {
    benchmark::RegisterBenchmark(("BM_Karlsruhe/" + candidate.name).c_str(),
                                 BM_Karlsruhe, candidate)
      ->ArgName("threads")
      ->Arg(1)
      ->Arg(2)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
    // One pass on Aloe is enough for its (deterministic) errors; the slow 8-path mode
    // takes seconds there.
    benchmark::RegisterBenchmark(("BM_Aloe/" + candidate.name).c_str(), BM_Aloe,
                                 candidate)
      ->Iterations(1)
      ->Unit(benchmark::kMillisecond)
      ->UseRealTime();
  }
  return true;
}();

} // namespace

BENCHMARK_MAIN();
