// SPDX-License-Identifier: BSD-3-Clause
// Multi-plane segmentation of Karlsruhe frame 10 (dense SGBM cloud, ~3 10^5 points):
// PCL's idiom (SACSegmentation + ExtractIndices in a loop) against
// SACMultiPlaneSegmentation with the SIFT feature points as sample cloud (paper
// Sec. III-C) and with its own dense subsample, on the full and the 0.1 m voxelised
// cloud. Counters: planes; coverage = points within d_T of the plane that reports them,
// each counted once, / points (the same test for every row); coverage_reported = the
// sum of the reported inlier counts / points.
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/common/io.h>
#include <pcl/common/point_tests.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/method_types.h>
#include <pcl/sample_consensus/model_types.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

#include "karlsruhe_frame.h"

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZI>;

constexpr double DISTANCE_THRESHOLD_M = 0.05; // the paper's d_T (eq. 11)
constexpr int MAX_ITERATIONS = 1000;
constexpr int MAX_PLANES = 6;

/** \brief Frame 10's dense cloud and feature points, computed once. */
struct Frame {
  Cloud::Ptr dense{new Cloud};
  Cloud::Ptr features{new Cloud};
  Cloud::Ptr voxelised{new Cloud}; // dense, NaNs removed, 0.1 m VoxelGrid (pipeline)
  std::size_t finite{0};
  bool ok{false};
};

const Frame&
frame()
{
  static const Frame f = [] {
    Frame out;
    const auto pair = planar_grid::bench::loadKarlsruhePair(10);
    if (!pair.ok)
      return out;
    planar_grid::bench::denseCloud(pair, 40.0, *out.dense);
    planar_grid::StereoFeatures features;
    planar_grid::StereoFeatureMatcher().match(pair.left, pair.right,
                                              pair.model.calibration, features);
    pcl::copyPointCloud(features.points, *out.features);
    for (const auto& p : *out.dense)
      out.finite += pcl::isFinite(p) ? 1 : 0;
    out.ok = out.finite > 0;
    Cloud::Ptr finite_cloud(new Cloud);
    pcl::Indices unused;
    pcl::removeNaNFromPointCloud(*out.dense, *finite_cloud, unused);
    pcl::VoxelGrid<pcl::PointXYZI> voxel_grid;
    voxel_grid.setInputCloud(finite_cloud);
    voxel_grid.setLeafSize(0.1f, 0.1f, 0.1f);
    voxel_grid.filter(*out.voxelised);
    return out;
  }();
  return f;
}

/** \brief Points of `indices` within d_T of the plane `coefficients` (normalised
 * here): the eq. 11 test, applied to every row's reported planes alike. */
std::size_t
countWithinThreshold(const Cloud& cloud,
                     const pcl::Indices& indices,
                     const std::vector<float>& coefficients)
{
  if (coefficients.size() != 4)
    return 0;
  const Eigen::Vector4f c(coefficients[0], coefficients[1], coefficients[2],
                          coefficients[3]);
  const Eigen::Vector4f plane = c / c.head<3>().norm();
  std::size_t count = 0;
  for (const auto i : indices) {
    const auto& p = cloud[static_cast<std::size_t>(i)];
    count += std::abs(plane[0] * p.x + plane[1] * p.y + plane[2] * p.z + plane[3])
                 <= static_cast<float>(DISTANCE_THRESHOLD_M)
               ? 1
               : 0;
  }
  return count;
}

void
runPCLLoop(benchmark::State& state, bool voxelised)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  std::size_t covered = 0, reported = 0, planes = 0;
  for (auto _ : state) {
    covered = reported = planes = 0;
    Cloud::Ptr remaining(new Cloud);
    pcl::Indices unused;
    pcl::removeNaNFromPointCloud(voxelised ? *f.voxelised : *f.dense, *remaining,
                                 unused);
    pcl::SACSegmentation<pcl::PointXYZI> seg;
    seg.setOptimizeCoefficients(true);
    seg.setModelType(pcl::SACMODEL_PLANE);
    seg.setMethodType(pcl::SAC_RANSAC);
    seg.setDistanceThreshold(DISTANCE_THRESHOLD_M);
    seg.setMaxIterations(MAX_ITERATIONS);
    pcl::ExtractIndices<pcl::PointXYZI> extract;
    for (int k = 0; k < MAX_PLANES && remaining->size() >= 3; ++k) {
      pcl::PointIndices::Ptr inliers(new pcl::PointIndices);
      pcl::ModelCoefficients coefficients;
      seg.setInputCloud(remaining);
      seg.segment(*inliers, coefficients);
      if (inliers->indices.empty())
        break;
      // Each point is counted once: its plane's inliers leave the cloud.
      state.PauseTiming();
      reported += inliers->indices.size();
      covered +=
        countWithinThreshold(*remaining, inliers->indices, coefficients.values);
      state.ResumeTiming();
      ++planes;
      Cloud::Ptr rest(new Cloud);
      extract.setInputCloud(remaining);
      extract.setIndices(inliers);
      extract.setNegative(true);
      extract.filter(*rest);
      remaining = rest;
    }
    benchmark::DoNotOptimize(remaining);
  }
  const auto points = static_cast<double>(voxelised ? f.voxelised->size() : f.finite);
  state.counters["points"] = points;
  state.counters["planes"] = static_cast<double>(planes);
  state.counters["coverage"] = static_cast<double>(covered) / points;
  state.counters["coverage_reported"] = static_cast<double>(reported) / points;
}

void
BM_PCLSACSegmentationLoop(benchmark::State& state)
{
  runPCLLoop(state, false);
}

void
BM_PCLSACSegmentationLoopVoxelised(benchmark::State& state)
{
  runPCLLoop(state, true);
}

/** \brief One configuration of SACMultiPlaneSegmentation: d_T, iterations and planes
 * as the PCL loop; merging off unless stated (the loop does not merge). */
struct Setting {
  bool voxelised{false};
  bool features{true};
  bool dense_hypothesis{true};
  int lo_iterations{50};
  bool merge{false};
  double sample_threshold_m{0.0}; // 0: = d_T
  int max_planes{MAX_PLANES};
  int min_inliers{500};
  unsigned seed{0};
};

/** \brief Runs one setting once; returns the planes. */
planar_grid::PlanarSegments
segmentOnce(const Frame& f, const Setting& setting)
{
  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
  seg.setInputCloud(setting.voxelised ? f.voxelised : f.dense);
  seg.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
  if (setting.features)
    seg.setSampleCloud(f.features);
  // 0: the sample threshold is d_T, as in PCL's loop.
  seg.setSampleDistanceThreshold(setting.sample_threshold_m > 0.0
                                   ? setting.sample_threshold_m
                                   : DISTANCE_THRESHOLD_M);
  seg.setDistanceThreshold(DISTANCE_THRESHOLD_M);
  // The paper's distance-only eq. 11, as PCL's loop (the class's default normal
  // test is the pipeline's).
  seg.setMaxNormalAngle(0.0);
  seg.setMinNormalAgreement(0.0);
  seg.setMinTerrainSensorHeight(0.0);
  seg.setMaxIterations(MAX_ITERATIONS);
  seg.setMaxPlanes(setting.max_planes);
  seg.setMinInliers(setting.min_inliers);
  seg.setDenseHypothesis(setting.dense_hypothesis);
  seg.setLocalOptimizationIterations(setting.lo_iterations);
  seg.setMergePlanes(setting.merge);
  seg.setSeed(setting.seed);
  planar_grid::PlanarSegments planes;
  seg.segment(planes);
  return planes;
}

/** \brief Points within d_T of the plane that reports them, each counted once. */
std::size_t
coveredPoints(const Cloud& cloud, const planar_grid::PlanarSegments& planes)
{
  std::vector<std::uint8_t> seen(cloud.size(), 0);
  std::size_t covered = 0;
  for (const auto& plane : planes) {
    pcl::Indices fresh;
    for (const auto i : plane.inliers.indices)
      if (!seen[static_cast<std::size_t>(i)]) {
        seen[static_cast<std::size_t>(i)] = 1;
        fresh.push_back(i);
      }
    covered += countWithinThreshold(cloud, fresh, plane.model_coefficients.values);
  }
  return covered;
}

void
runOurs(benchmark::State& state, const Setting& setting)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  planar_grid::PlanarSegments planes;
  for (auto _ : state) {
    planes = segmentOnce(f, setting);
    benchmark::DoNotOptimize(planes);
  }
  // Each point counted once, and only when within d_T of the plane that reports it
  // (after a merge the united inliers need not be).
  const Cloud& cloud = setting.voxelised ? *f.voxelised : *f.dense;
  std::size_t reported = 0;
  for (const auto& plane : planes)
    reported += plane.inliers.indices.size();
  const auto points =
    static_cast<double>(setting.voxelised ? f.voxelised->size() : f.finite);
  state.counters["points"] = points;
  state.counters["sample_points"] =
    static_cast<double>(setting.features ? f.features->size() : 0);
  state.counters["planes"] = static_cast<double>(planes.size());
  state.counters["coverage"] =
    static_cast<double>(coveredPoints(cloud, planes)) / points;
  state.counters["coverage_reported"] = static_cast<double>(reported) / points;
}

/** \brief The spread over seeds: one iteration runs seeds 0 .. range(0) - 1 of the
 * default setting (full cloud, or voxelised when range(1) is 1); counters are the
 * smallest, mean and largest coverage (the time is for all seeds together). */
void
BM_SACMultiPlaneSegmentationFeaturesSeeds(benchmark::State& state)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  Setting setting;
  setting.voxelised = state.range(1) == 1;
  const Cloud& cloud = setting.voxelised ? *f.voxelised : *f.dense;
  const auto points =
    static_cast<double>(setting.voxelised ? f.voxelised->size() : f.finite);
  const auto seeds = static_cast<unsigned>(state.range(0));
  double smallest = 1.0, largest = 0.0, sum = 0.0;
  for (auto _ : state) {
    smallest = 1.0;
    largest = sum = 0.0;
    for (unsigned seed = 0; seed < seeds; ++seed) {
      setting.seed = seed;
      const auto planes = segmentOnce(f, setting);
      const double coverage =
        static_cast<double>(coveredPoints(cloud, planes)) / points;
      smallest = std::min(smallest, coverage);
      largest = std::max(largest, coverage);
      sum += coverage;
    }
  }
  state.counters["coverage_min"] = smallest;
  state.counters["coverage_mean"] = sum / seeds;
  state.counters["coverage_max"] = largest;
}

/** \brief The class defaults (dense hypothesis, local optimisation) with the SIFT
 * feature points as sample cloud; merging off as in the PCL loop. */
void
BM_SACMultiPlaneSegmentationFeatures(benchmark::State& state)
{
  runOurs(state, Setting{});
}

/** \brief The paper's feature-only multi-RANSAC (the previous default): no dense
 * hypothesis, no local optimisation. */
void
BM_SACMultiPlaneSegmentationFeaturesSampleOnly(benchmark::State& state)
{
  Setting setting;
  setting.dense_hypothesis = false;
  setting.lo_iterations = 0;
  runOurs(state, setting);
}

/** \brief The class defaults including merging (coverage counts only the united
 * inliers within d_T of the merged plane). */
void
BM_SACMultiPlaneSegmentationFeaturesMerged(benchmark::State& state)
{
  Setting setting;
  setting.merge = true;
  runOurs(state, setting);
}

/** \brief Hypotheses from a 20k subsample of the cloud itself (no sample cloud). */
void
BM_SACMultiPlaneSegmentationDenseSubsample(benchmark::State& state)
{
  Setting setting;
  setting.features = false;
  runOurs(state, setting);
}

/** \brief As BM_SACMultiPlaneSegmentationFeatures, on the 0.1 m voxelised cloud. */
void
BM_SACMultiPlaneSegmentationVoxelised(benchmark::State& state)
{
  Setting setting;
  setting.voxelised = true;
  runOurs(state, setting);
}

/** \brief The pipeline's setting (config/karlsruhe.yaml) on the 0.1 m voxelised cloud:
 * SIFT sample cloud, sample threshold 0.15 m, 8 planes, min_inliers 300, merging on
 * (the pipeline's statistical outlier removal is left out). Not comparable with the
 * 6-plane PCL loop; shown for the pipeline's time. */
void
BM_SACMultiPlaneSegmentationVoxelisedPipeline(benchmark::State& state)
{
  Setting setting;
  setting.voxelised = true;
  setting.merge = true;
  setting.sample_threshold_m = 0.15;
  setting.max_planes = 8;
  setting.min_inliers = 300;
  runOurs(state, setting);
}

} // namespace

BENCHMARK(BM_PCLSACSegmentationLoop)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationFeatures)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationFeaturesSampleOnly)
  ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationFeaturesMerged)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationDenseSubsample)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationFeaturesSeeds)
  ->Args({16, 0})
  ->Args({16, 1})
  ->Iterations(1)
  ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PCLSACSegmentationLoopVoxelised)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationVoxelised)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationVoxelisedPipeline)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
