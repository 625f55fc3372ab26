// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_normals.h>

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace {

using planar_grid::DisparityNormalParams;
using planar_grid::estimateDisparityNormals;
using planar_grid::StereoCalibration;
using Points = std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>;

StereoCalibration
calibration()
{
  StereoCalibration c;
  c.focal_length_px = 645.24;
  c.cx_px = 635.96;
  c.cy_px = 194.13;
  c.baseline_m = 0.5707;
  c.width = 1344;
  c.height = 372;
  return c;
}

/** The disparity image of the plane n . X + d = 0 (camera frame) where the ray of
 * each pixel meets it in front of the camera, plus Gaussian noise of \a sigma_px;
 * NaN elsewhere. */
cv::Mat
renderPlane(const StereoCalibration& c,
            const Eigen::Vector3d& n,
            double d,
            double sigma_px,
            unsigned seed)
{
  cv::Mat disparity(c.height, c.width, CV_32FC1,
                    cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  std::mt19937 rng(seed);
  std::normal_distribution<double> noise(0.0, sigma_px);
  for (int v = 0; v < c.height; ++v)
    for (int u = 0; u < c.width; ++u) {
      const Eigen::Vector3d ray((u - c.cx_px) / c.focal_length_px,
                                (v - c.cy_px) / c.focal_length_px, 1.0);
      const double denominator = n.dot(ray);
      if (std::abs(denominator) < 1e-9)
        continue;
      const double z = -d / denominator;
      if (z > 0.5 && z < 60.0)
        disparity.at<float>(v, u) =
          static_cast<float>(c.focal_length_px * c.baseline_m / z + noise(rng));
    }
  return disparity;
}

/** Points of the plane seen at pixels on a grid (camera frame). */
Points
planePoints(const StereoCalibration& c, const Eigen::Vector3d& n, double d)
{
  Points points;
  for (int v = 10; v < c.height; v += 37)
    for (int u = 10; u < c.width; u += 53) {
      const Eigen::Vector3d ray((u - c.cx_px) / c.focal_length_px,
                                (v - c.cy_px) / c.focal_length_px, 1.0);
      const double z = -d / n.dot(ray);
      if (z > 1.0 && z < 40.0)
        points.emplace_back((z * ray).cast<float>());
    }
  return points;
}

double
angleDeg(const Eigen::Vector3f& a, const Eigen::Vector3d& b)
{
  return std::acos(std::min(1.0, std::abs(a.cast<double>().normalized().dot(b))))
         * 180.0 / M_PI;
}

TEST(DisparityNormals, ExactOnNoiselessPlanes)
{
  const StereoCalibration c = calibration();
  // A road 1.57 m below the camera (y down), a facade at a grazing angle, a tilted
  // slab: a plane is a plane in (u, v, disparity), so the fit is exact.
  const std::vector<std::pair<Eigen::Vector3d, double>> planes{
    {Eigen::Vector3d(0.0, 1.0, 0.0), -1.57},
    {Eigen::Vector3d(-1.0, 0.0, 0.15).normalized(), -4.0},
    {Eigen::Vector3d(0.3, -0.5, -0.8).normalized(), 9.0}};
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const auto& [n, d] = planes[k];
    const cv::Mat disparity = renderPlane(c, n, d, 0.0, 1);
    const Points points = planePoints(c, n, d);
    ASSERT_GT(points.size(), 20u) << k;
    Points normals;
    estimateDisparityNormals(disparity, c, points, DisparityNormalParams{}, normals);
    ASSERT_EQ(normals.size(), points.size());
    std::size_t defined = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      if (!normals[i].allFinite())
        continue;
      ++defined;
      EXPECT_NEAR(normals[i].norm(), 1.0f, 1e-5f);
      EXPECT_LT(angleDeg(normals[i], n), 0.05) << k << " point " << i;
      // Toward the camera.
      EXPECT_LT(normals[i].dot(points[i]), 0.0f) << k << " point " << i;
    }
    // Only points whose window leaves the image or the plane's visible part lack one.
    EXPECT_GT(defined, points.size() * 8 / 10) << k;
  }
}

TEST(DisparityNormals, NoisyDisparityGivesNormalsWithinAFewDegrees)
{
  // 0.2 px of noise on a facade 6-15 m away seen at 45 degrees: the window's fit
  // keeps the normal within a few degrees (a 3D fit of the points would turn with
  // the depth noise along the lines of sight).
  const StereoCalibration c = calibration();
  const Eigen::Vector3d n = Eigen::Vector3d(-1.0, 0.0, 1.0).normalized();
  const double d = -6.0 * std::sqrt(0.5);
  const cv::Mat disparity = renderPlane(c, n, d, 0.2, 2);
  const Points points = planePoints(c, n, d);
  Points normals;
  estimateDisparityNormals(disparity, c, points, DisparityNormalParams{}, normals);
  std::size_t defined = 0, within5 = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (normals[i].allFinite()) {
      ++defined;
      within5 += angleDeg(normals[i], n) < 5.0 ? 1 : 0;
    }
  ASSERT_GT(defined, 20u);
  EXPECT_GE(within5, defined * 95 / 100);
  // One point at a time, the same normals to the bit (NaN where there is none).
  const planar_grid::DisparityNormalEstimator estimator(disparity, c,
                                                        DisparityNormalParams{});
  for (std::size_t i = 0; i < points.size(); ++i) {
    const Eigen::Vector3f one = estimator.compute(points[i]);
    if (normals[i].allFinite())
      EXPECT_EQ(one, normals[i]) << i;
    else
      EXPECT_FALSE(one.allFinite()) << i;
  }
}

TEST(DisparityNormals, ObjectInFrontDoesNotTiltTheWall)
{
  // A fronto-parallel wall at 10 m with a post 4 m from the camera covering the left
  // half of each window: the pixels far from the wall's disparity are left out.
  const StereoCalibration c = calibration();
  cv::Mat disparity = renderPlane(c, Eigen::Vector3d(0, 0, -1), 10.0, 0.0, 3);
  const double wall = c.focal_length_px * c.baseline_m / 10.0;
  const double post = c.focal_length_px * c.baseline_m / 4.0;
  for (int v = 0; v < c.height; ++v)
    for (int u = 600; u < 700; ++u)
      disparity.at<float>(v, u) = static_cast<float>(post);
  Points points{Eigen::Vector3f(
    static_cast<float>((703 - c.cx_px) * 10.0 / c.focal_length_px), 0.0f, 10.0f)};
  Points normals;
  estimateDisparityNormals(disparity, c, points, DisparityNormalParams{}, normals);
  ASSERT_TRUE(normals[0].allFinite());
  EXPECT_LT(angleDeg(normals[0], Eigen::Vector3d(0, 0, 1)), 0.05);
  ASSERT_GT(post - wall, 0.2 * wall);
}

TEST(DisparityNormals, WindowCutByTheImageBorderStillFits)
{
  // A wall 10 m ahead fills the image; points 1 px inside the middle of each border:
  // their window (at least 4 px a side) loses the rows or columns beyond the border
  // and fits the rest, two thirds of it.
  const StereoCalibration c = calibration();
  const cv::Mat disparity = renderPlane(c, Eigen::Vector3d(0, 0, -1), 10.0, 0.0, 4);
  const auto at = [&c](double u, double v) {
    return Eigen::Vector3f(static_cast<float>((u - c.cx_px) * 10.0 / c.focal_length_px),
                           static_cast<float>((v - c.cy_px) * 10.0 / c.focal_length_px),
                           10.0f);
  };
  const Points points{at(c.width / 2, 1), at(c.width / 2, c.height - 2),
                      at(1, c.height / 2), at(c.width - 2, c.height / 2)};
  Points normals;
  estimateDisparityNormals(disparity, c, points, DisparityNormalParams{}, normals);
  for (std::size_t i = 0; i < points.size(); ++i) {
    ASSERT_TRUE(normals[i].allFinite()) << i;
    EXPECT_LT(angleDeg(normals[i], Eigen::Vector3d(0, 0, 1)), 0.05) << i;
  }
}

TEST(DisparityNormals, UndefinedWhereThereIsNothingToFit)
{
  const StereoCalibration c = calibration();
  cv::Mat disparity(c.height, c.width, CV_32FC1,
                    cv::Scalar(std::numeric_limits<float>::quiet_NaN()));
  const Points points{
    Eigen::Vector3f(0, 0, 10), Eigen::Vector3f(0, 0, -10), Eigen::Vector3f(100, 0, 1),
    Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN())};
  Points normals;
  estimateDisparityNormals(disparity, c, points, DisparityNormalParams{}, normals);
  ASSERT_EQ(normals.size(), points.size());
  for (const auto& n : normals)
    EXPECT_FALSE(n.allFinite());
}

TEST(DisparityNormals, BadInputIsAnError)
{
  const StereoCalibration c = calibration();
  const Points points{Eigen::Vector3f(0, 0, 10)};
  Points normals;
  EXPECT_THROW(estimateDisparityNormals(cv::Mat(10, 10, CV_8UC1), c, points,
                                        DisparityNormalParams{}, normals),
               planar_grid::Exception);
  StereoCalibration no_baseline = c;
  no_baseline.baseline_m = 0.0;
  const cv::Mat disparity(10, 10, CV_32FC1, cv::Scalar(10.0f));
  EXPECT_THROW(estimateDisparityNormals(disparity, no_baseline, points,
                                        DisparityNormalParams{}, normals),
               planar_grid::Exception);
  DisparityNormalParams bad;
  bad.window_radius_m = 0.0;
  EXPECT_THROW(estimateDisparityNormals(disparity, c, points, bad, normals),
               planar_grid::Exception);
  // The estimator of one point at a time checks the same, once.
  EXPECT_THROW(planar_grid::DisparityNormalEstimator(cv::Mat(10, 10, CV_8UC1), c,
                                                     DisparityNormalParams{}),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::DisparityNormalEstimator(disparity, c, bad),
               planar_grid::Exception);
  bad = DisparityNormalParams{};
  bad.min_window_radius_px = 10;
  bad.max_window_radius_px = 5;
  EXPECT_THROW(estimateDisparityNormals(disparity, c, points, bad, normals),
               planar_grid::Exception);
  bad = DisparityNormalParams{};
  bad.min_valid_fraction = 0.0;
  EXPECT_THROW(estimateDisparityNormals(disparity, c, points, bad, normals),
               planar_grid::Exception);
}

} // namespace
