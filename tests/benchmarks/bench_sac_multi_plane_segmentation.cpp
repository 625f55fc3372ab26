// SPDX-License-Identifier: BSD-3-Clause
// Multi-plane segmentation of Karlsruhe frame 10 (dense SGBM cloud, ~10^5 points):
// PCL's idiom (SACSegmentation + ExtractIndices in a loop) against
// SACMultiPlaneSegmentation with the SIFT feature points as sample cloud (paper
// Sec. III-C) and with its own dense subsample. Counters: planes, coverage = dense
// inliers / finite points.
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

#include <memory>
#include <string>

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

void
runPCLLoop(benchmark::State& state, bool voxelised)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  std::size_t covered = 0, planes = 0;
  for (auto _ : state) {
    covered = planes = 0;
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
      covered += inliers->indices.size();
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
  const std::size_t points = voxelised ? f.voxelised->size() : f.finite;
  state.counters["points"] = static_cast<double>(points);
  state.counters["planes"] = static_cast<double>(planes);
  state.counters["coverage"] = static_cast<double>(covered) / points;
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

void
runOurs(benchmark::State& state, bool with_features, double sample_threshold_m)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  std::size_t covered = 0, planes_found = 0;
  for (auto _ : state) {
    planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
    seg.setInputCloud(f.dense);
    seg.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
    if (with_features)
      seg.setSampleCloud(f.features);
    if (sample_threshold_m > 0.0)
      seg.setSampleDistanceThreshold(sample_threshold_m);
    seg.setDistanceThreshold(DISTANCE_THRESHOLD_M);
    seg.setMaxIterations(MAX_ITERATIONS);
    seg.setMaxPlanes(MAX_PLANES);
    planar_grid::PlanarSegments planes;
    seg.segment(planes);
    covered = 0;
    for (const auto& p : planes)
      covered += p.inliers.indices.size();
    planes_found = planes.size();
    benchmark::DoNotOptimize(planes);
  }
  state.counters["points"] = static_cast<double>(f.finite);
  state.counters["sample_points"] =
    static_cast<double>(with_features ? f.features->size() : 0);
  state.counters["planes"] = static_cast<double>(planes_found);
  state.counters["coverage"] = static_cast<double>(covered) / f.finite;
}

void
BM_SACMultiPlaneSegmentationFeatures(benchmark::State& state)
{
  // Arg: the sample consensus threshold on the features in cm (0 = d_T); stereo
  // depth noise grows as z^2, so features at 10-40 m need more than d_T = 5 cm.
  runOurs(state, true, 0.01 * static_cast<double>(state.range(0)));
}

/** \brief The pipeline's setting (config/karlsruhe.yaml): the 0.1 m voxelised cloud
 * (~40k points), SIFT sample cloud, sample threshold 0.15 m, 8 planes, min_inliers
 * 300 (the pipeline's statistical outlier removal is left out). */
void
BM_SACMultiPlaneSegmentationVoxelisedPipeline(benchmark::State& state)
{
  const Frame& f = frame();
  if (!f.ok) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  std::size_t covered = 0, planes_found = 0;
  for (auto _ : state) {
    planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
    seg.setInputCloud(f.voxelised);
    seg.setSampleCloud(f.features);
    seg.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
    seg.setDistanceThreshold(DISTANCE_THRESHOLD_M);
    seg.setSampleDistanceThreshold(0.15);
    seg.setMaxIterations(MAX_ITERATIONS);
    seg.setMaxPlanes(8);
    seg.setMinInliers(300);
    planar_grid::PlanarSegments planes;
    seg.segment(planes);
    covered = 0;
    for (const auto& p : planes)
      covered += p.inliers.indices.size();
    planes_found = planes.size();
    benchmark::DoNotOptimize(planes);
  }
  state.counters["points"] = static_cast<double>(f.voxelised->size());
  state.counters["sample_points"] = static_cast<double>(f.features->size());
  state.counters["planes"] = static_cast<double>(planes_found);
  state.counters["coverage"] =
    static_cast<double>(covered) / static_cast<double>(f.voxelised->size());
}

void
BM_SACMultiPlaneSegmentationDenseSubsample(benchmark::State& state)
{
  runOurs(state, false, 0.0);
}

} // namespace

BENCHMARK(BM_PCLSACSegmentationLoop)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationFeatures)
  ->Arg(0)
  ->Arg(10)
  ->Arg(20)
  ->Arg(40)
  ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationDenseSubsample)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PCLSACSegmentationLoopVoxelised)->Unit(benchmark::kMillisecond);
BENCHMARK(BM_SACMultiPlaneSegmentationVoxelisedPipeline)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
