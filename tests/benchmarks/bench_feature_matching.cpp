// SPDX-License-Identifier: BSD-3-Clause
// The feature_matching stage's front ends on one real Karlsruhe frame (10, 1344x372):
// detection, description, left-right matching and triangulation per stereo pair, for
// SIFT, ORB (OpenCV defaults) and ORB_GRID (bucketed FAST + upright ORB + sub-pixel
// disparities), each at 2000 and 4000 key points per image, in the same run.
//
//   cmake -S . -B build -DPLANAR_GRID_BUILD_BENCHMARKS=ON && make -C build
//   bench_feature_matching build/tests/benchmarks/bench_feature_matching
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <benchmark/benchmark.h>

#include "karlsruhe_frame.h"

namespace {

using planar_grid::FeatureType;

void
matchFrame10(benchmark::State& state, FeatureType type)
{
  const planar_grid::bench::KarlsruhePair pair =
    planar_grid::bench::loadKarlsruhePair(10);
  if (!pair.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found under PLANAR_GRID_DATA_DIR");
    return;
  }
  planar_grid::StereoFeatureMatcher::Params params;
  params.feature_type = type;
  params.max_features = static_cast<int>(state.range(0));
  const planar_grid::StereoFeatureMatcher matcher(params);
  planar_grid::StereoFeatures features;
  for (auto _ : state) {
    matcher.match(pair.left, pair.right, pair.model.calibration, features);
    benchmark::DoNotOptimize(features.points.data());
  }
  state.counters["features"] = static_cast<double>(features.size());
}

void
BM_FeatureMatchingSIFT(benchmark::State& state)
{
  matchFrame10(state, FeatureType::SIFT);
}

void
BM_FeatureMatchingORB(benchmark::State& state)
{
  matchFrame10(state, FeatureType::ORB);
}

void
BM_FeatureMatchingORBGrid(benchmark::State& state)
{
  matchFrame10(state, FeatureType::ORB_GRID);
}

} // namespace

BENCHMARK(BM_FeatureMatchingSIFT)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FeatureMatchingORB)->Arg(2000)->Arg(4000)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_FeatureMatchingORBGrid)
  ->Arg(2000)
  ->Arg(4000)
  ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
