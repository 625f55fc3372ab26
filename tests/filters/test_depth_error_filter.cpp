// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/depth_error_filter.h>

#include <pcl/point_types.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <string>

namespace {

using planar_grid::DepthErrorFilter;

planar_grid::StereoCalibration
kittiLikeCalibration()
{
  planar_grid::StereoCalibration calibration;
  calibration.focal_length_px = 718.856;
  calibration.baseline_m = 0.537;
  return calibration;
}

TEST(DepthErrorFilter, TheBoundIsEquationFourSolvedForTheDepth)
{
  // Delta z = z^2 Delta d / (B f) = max  <=>  z = sqrt(max B f / Delta d).
  DepthErrorFilter<pcl::PointXYZ> filter;
  filter.setCalibration(kittiLikeCalibration());
  filter.setDisparityError(0.5);
  filter.setMaxDepthError(0.3);
  const double expected = std::sqrt(0.3 * 0.537 * 718.856 / 0.5);
  EXPECT_NEAR(filter.getMaxDepth(), expected, 1e-9);
  // at the bound the calibration's depth error is the bound itself
  EXPECT_NEAR(kittiLikeCalibration().depthError(filter.getMaxDepth(), 0.5), 0.3, 1e-9);
  filter.setMaxDepthError(1.2); // four times the error: twice the depth
  EXPECT_NEAR(filter.getMaxDepth(), 2.0 * expected, 1e-9);
}

TEST(DepthErrorFilter, KeepsExactlyThePointsWithinTheBoundInTheCameraFrame)
{
  // Random points in a world frame, a camera turned and moved in it, some points not
  // finite: the kept, the negative and the removed indices against a brute-force
  // test of each point's depth in the camera frame.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> coordinate(-30.0f, 30.0f);
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (int i = 0; i < 5000; ++i)
    cloud->push_back(pcl::PointXYZ(coordinate(rng), coordinate(rng), coordinate(rng)));
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (const int i : {3, 700, 4999})
    (*cloud)[static_cast<std::size_t>(i)].y = nan;
  const Eigen::Affine3f camera_T_cloud =
    Eigen::Translation3f(1.0f, -2.0f, 0.5f)
    * Eigen::AngleAxisf(0.6f, Eigen::Vector3f(1.0f, 2.0f, 0.5f).normalized());
  DepthErrorFilter<pcl::PointXYZ> filter(true);
  filter.setCalibration(kittiLikeCalibration());
  filter.setMaxDepthError(0.3);
  filter.setCameraTransform(camera_T_cloud);
  filter.setInputCloud(cloud);
  const double bound = filter.getMaxDepth();
  pcl::Indices kept;
  filter.filter(kept);
  const pcl::Indices removed = *filter.getRemovedIndices();
  filter.setNegative(true);
  pcl::Indices beyond;
  filter.filter(beyond);
  std::size_t within = 0, outside = 0, not_finite = 0;
  std::vector<int> state(cloud->size(), -1); // -1 not finite, 0 within, 1 beyond
  for (std::size_t i = 0; i < cloud->size(); ++i) {
    const auto& p = (*cloud)[i];
    if (!std::isfinite(p.y)) {
      ++not_finite;
      continue;
    }
    const double depth =
      (camera_T_cloud.cast<double>() * Eigen::Vector3d(p.x, p.y, p.z)).z();
    ASSERT_GT(std::abs(depth - bound), 1e-4) << "a point on the bound: move the seed";
    state[i] = depth > bound ? 1 : 0;
    (depth > bound ? outside : within) += 1;
  }
  ASSERT_EQ(not_finite, 3u);
  ASSERT_GT(within, 1000u);
  ASSERT_GT(outside, 1000u);
  ASSERT_EQ(kept.size(), within);
  for (const auto index : kept)
    EXPECT_EQ(state[static_cast<std::size_t>(index)], 0) << index;
  ASSERT_EQ(beyond.size(), outside);
  for (const auto index : beyond)
    EXPECT_EQ(state[static_cast<std::size_t>(index)], 1) << index;
  // kept mode: the removed are those beyond and the non-finite ones
  ASSERT_EQ(removed.size(), outside + not_finite);
  for (const auto index : removed)
    EXPECT_NE(state[static_cast<std::size_t>(index)], 0) << index;
  // the output cloud of the kept mode
  filter.setNegative(false);
  pcl::PointCloud<pcl::PointXYZ> out;
  filter.filter(out);
  EXPECT_EQ(out.size(), within);
}

TEST(DepthErrorFilter, BadParametersAreRefusedByName)
{
  const auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  cloud->push_back(pcl::PointXYZ(0.0f, 0.0f, 1.0f));
  const auto refused = [&](DepthErrorFilter<pcl::PointXYZ>& filter,
                           const std::string& name) {
    filter.setInputCloud(cloud);
    pcl::Indices indices;
    try {
      filter.filter(indices);
      ADD_FAILURE() << name << " accepted";
    } catch (const planar_grid::Exception& e) {
      EXPECT_NE(std::string(e.what()).find(name), std::string::npos) << e.what();
    }
  };
  for (const double bad : {0.0, -0.5, 20.0, std::nan("")}) {
    DepthErrorFilter<pcl::PointXYZ> filter;
    filter.setCalibration(kittiLikeCalibration());
    filter.setDisparityError(bad);
    refused(filter, "disparity_error_px");
  }
  for (const double bad : {0.0, -1.0, 1000.0}) {
    DepthErrorFilter<pcl::PointXYZ> filter;
    filter.setCalibration(kittiLikeCalibration());
    filter.setMaxDepthError(bad);
    refused(filter, "max_depth_error_m");
  }
  DepthErrorFilter<pcl::PointXYZ> uncalibrated; // baseline and focal length 0
  refused(uncalibrated, "baseline_m");
}

} // namespace
