// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>

namespace {

using planar_grid::disparityToPointCloud;
using planar_grid::StereoCalibration;

StereoCalibration
karlsruheCalibration()
{
  StereoCalibration calibration;
  calibration.focal_length_px = 645.2401;
  calibration.cx_px = 635.9587;
  calibration.cy_px = 194.1291;
  calibration.baseline_m = 0.5707;
  return calibration;
}

// Constant disparity d: every pixel lies on the plane z = f B / d, and x, y follow the
// pinhole formula. 1e-5 m is float rounding at these magnitudes (|x| <= 15 m, float
// epsilon 1.2e-7 relative -> 2e-6 m).
TEST(PointCloudFromDisparity, ConstantDisparityGivesFrontoParallelPlane)
{
  const StereoCalibration calibration = karlsruheCalibration();
  const float d = 24.0f;
  const cv::Mat disparity(40, 1344, CV_32FC1, cv::Scalar(d));
  cv::Mat intensity(40, 1344, CV_8UC1);
  for (int v = 0; v < intensity.rows; ++v)
    for (int u = 0; u < intensity.cols; ++u)
      intensity.at<std::uint8_t>(v, u) = static_cast<std::uint8_t>((u + v) % 256);

  pcl::PointCloud<pcl::PointXYZI> cloud;
  disparityToPointCloud(disparity, intensity, calibration, 100.0, cloud);
  ASSERT_EQ(cloud.width, 1344u);
  ASSERT_EQ(cloud.height, 40u);
  ASSERT_EQ(cloud.size(), 1344u * 40u);
  EXPECT_FALSE(cloud.is_dense);
  const double z = calibration.focal_length_px * calibration.baseline_m / d; // 15.34 m
  for (int v = 0; v < 40; ++v)
    for (int u = 0; u < 1344; ++u) {
      const pcl::PointXYZI& p = cloud.at(u, v);
      EXPECT_NEAR(p.z, z, 1e-5);
      EXPECT_NEAR(p.x, (u - calibration.cx_px) * z / calibration.focal_length_px, 1e-5);
      EXPECT_NEAR(p.y, (v - calibration.cy_px) * z / calibration.focal_length_px, 1e-5);
      EXPECT_EQ(p.intensity, static_cast<float>((u + v) % 256));
    }
}

// Colour intensity is converted to grey (BGR weights 0.114, 0.587, 0.299).
TEST(PointCloudFromDisparity, ColourIntensityIsGrey)
{
  const cv::Mat disparity(2, 3, CV_32FC1, cv::Scalar(10.0f));
  const cv::Mat colour(2, 3, CV_8UC3, cv::Scalar(0, 0, 255)); // pure red
  pcl::PointCloud<pcl::PointXYZI> cloud;
  disparityToPointCloud(disparity, colour, karlsruheCalibration(), 100.0, cloud);
  // 0.299 * 255 = 76.2 -> 76
  for (const auto& p : cloud)
    EXPECT_EQ(p.intensity, 76.0f);
  // No intensity image: intensity 0.
  disparityToPointCloud(disparity, cv::Mat(), karlsruheCalibration(), 100.0, cloud);
  for (const auto& p : cloud)
    EXPECT_EQ(p.intensity, 0.0f);
}

// NaN, zero and negative disparities, and points beyond max_range_m, are NaN points
// (x = y = z = NaN), and the cloud stays organized.
TEST(PointCloudFromDisparity, InvalidAndFarPixelsAreNaN)
{
  const StereoCalibration calibration = karlsruheCalibration();
  cv::Mat disparity(1, 5, CV_32FC1);
  disparity.at<float>(0, 0) = std::numeric_limits<float>::quiet_NaN();
  disparity.at<float>(0, 1) = 0.0f;
  disparity.at<float>(0, 2) = -3.0f;
  // z = 368.26 / 10 = 36.83 m at u = 3: range ~ sqrt(36.83^2 + 36.0^2 ...) > 30 m.
  disparity.at<float>(0, 3) = 10.0f;
  // z = 368.26 / 40 = 9.21 m, |x| ~ 9.1 m, range ~ 13 m < 30 m: kept.
  disparity.at<float>(0, 4) = 40.0f;
  pcl::PointCloud<pcl::PointXYZI> cloud;
  disparityToPointCloud(disparity, cv::Mat(), calibration, 30.0, cloud);
  ASSERT_EQ(cloud.size(), 5u);
  EXPECT_EQ(cloud.width, 5u);
  EXPECT_EQ(cloud.height, 1u);
  for (int u = 0; u < 4; ++u) {
    EXPECT_TRUE(std::isnan(cloud[u].x)) << u;
    EXPECT_TRUE(std::isnan(cloud[u].y)) << u;
    EXPECT_TRUE(std::isnan(cloud[u].z)) << u;
  }
  EXPECT_NEAR(cloud[4].z, calibration.focal_length_px * calibration.baseline_m / 40.0,
              1e-5);
  // The range cut is Euclidean, not on z alone: a point at z = 20 m far off-axis.
  const float d_off_axis = 18.413f; // z = f B / d = 20.0 m
  const cv::Mat off_axis(1, 1, CV_32FC1, cv::Scalar(d_off_axis));
  StereoCalibration shifted = calibration;
  shifted.cx_px = 1000.0; // x = -1000 / 645.24 * 20 = -31 m: range 36.9 m
  disparityToPointCloud(off_axis, cv::Mat(), shifted, 30.0, cloud);
  EXPECT_TRUE(std::isnan(cloud[0].z));
  disparityToPointCloud(off_axis, cv::Mat(), shifted, 40.0, cloud);
  EXPECT_NEAR(cloud[0].z,
              calibration.focal_length_px * calibration.baseline_m / d_off_axis, 1e-5);
}

TEST(PointCloudFromDisparity, RejectsMismatchedInput)
{
  pcl::PointCloud<pcl::PointXYZI> cloud;
  const StereoCalibration calibration = karlsruheCalibration();
  const cv::Mat disparity(10, 20, CV_32FC1, cv::Scalar(5.0f));
  EXPECT_THROW(disparityToPointCloud(cv::Mat(10, 20, CV_16SC1), cv::Mat(), calibration,
                                     30.0, cloud),
               planar_grid::Exception);
  EXPECT_THROW(disparityToPointCloud(disparity, cv::Mat(10, 21, CV_8UC1), calibration,
                                     30.0, cloud),
               planar_grid::Exception);
  EXPECT_THROW(disparityToPointCloud(disparity, cv::Mat(10, 20, CV_16UC1), calibration,
                                     30.0, cloud),
               planar_grid::Exception);
  EXPECT_THROW(disparityToPointCloud(disparity, cv::Mat(), calibration, 0.0, cloud),
               planar_grid::Exception);
  // The range the stage's table declares too: (0, 1000] m.
  EXPECT_THROW(disparityToPointCloud(disparity, cv::Mat(), calibration, 1000.5, cloud),
               planar_grid::Exception);
  EXPECT_NO_THROW(
    disparityToPointCloud(disparity, cv::Mat(), calibration, 1000.0, cloud));
  EXPECT_THROW(
    disparityToPointCloud(disparity, cv::Mat(), StereoCalibration(), 30.0, cloud),
    planar_grid::Exception);
}

// An empty disparity gives an empty organized cloud, no crash.
TEST(PointCloudFromDisparity, EmptyDisparityGivesEmptyCloud)
{
  pcl::PointCloud<pcl::PointXYZI> cloud;
  disparityToPointCloud(cv::Mat(0, 0, CV_32FC1), cv::Mat(), karlsruheCalibration(),
                        30.0, cloud);
  EXPECT_TRUE(cloud.empty());
}

} // namespace
