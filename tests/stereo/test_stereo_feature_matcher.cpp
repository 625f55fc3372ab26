// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iostream>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "../test_constants.h"

namespace {

using planar_grid::FeatureType;
using planar_grid::StereoCalibration;
using planar_grid::StereoFeatureMatcher;
using planar_grid::StereoFeatures;

using planar_grid_test::KARLSRUHE_DIR;

/** \brief Karlsruhe frame 10 and its calibration, loaded once per test. */
class StereoFeatureMatcherKarlsruhe : public ::testing::Test {
protected:
  void SetUp() override
  {
    left_ = cv::imread(KARLSRUHE_DIR + "/left/I1_000010.png", cv::IMREAD_UNCHANGED);
    right_ = cv::imread(KARLSRUHE_DIR + "/right/I2_000010.png", cv::IMREAD_UNCHANGED);
    ASSERT_FALSE(left_.empty());
    ASSERT_FALSE(right_.empty());
    calibration_ =
      planar_grid::loadStereoCalibration(planar_grid::CalibrationFormat::KARLSRUHE,
                                         KARLSRUHE_DIR + "/calib.txt")
        .calibration;
  }

  /** \brief The left image shifted left by \a shift_px columns (blank on the right): a
   * right image in which every point has disparity exactly shift_px. */
  cv::Mat shiftedLeft(int shift_px) const
  {
    cv::Mat shifted = cv::Mat::zeros(left_.size(), left_.type());
    left_.colRange(shift_px, left_.cols)
      .copyTo(shifted.colRange(0, left_.cols - shift_px));
    return shifted;
  }

  static StereoFeatureMatcher::Params paramsFor(FeatureType type)
  {
    StereoFeatureMatcher::Params params;
    params.feature_type = type;
    return params;
  }

  /** \brief Checks the invariants every match obeys and the parallel arrays. */
  static void expectConsistent(const StereoFeatures& features,
                               const StereoFeatureMatcher::Params& params,
                               const StereoCalibration& calibration)
  {
    ASSERT_EQ(features.keypoints_right.size(), features.size());
    ASSERT_EQ(features.disparities.size(), features.size());
    ASSERT_EQ(features.points.size(), features.size());
    ASSERT_EQ(static_cast<std::size_t>(features.descriptors.rows), features.size());
    EXPECT_EQ(features.points.width, features.size());
    EXPECT_EQ(features.points.height, 1u);
    EXPECT_TRUE(features.points.is_dense);
    for (std::size_t i = 0; i < features.size(); ++i) {
      const cv::Point2f& pl = features.keypoints_left[i].pt;
      const cv::Point2f& pr = features.keypoints_right[i].pt;
      const float d = features.disparities[i];
      EXPECT_LE(std::abs(pl.y - pr.y), params.max_row_difference_px);
      EXPECT_FLOAT_EQ(d, pl.x - pr.x);
      EXPECT_GT(d, 0.0f);
      EXPECT_LE(d, params.max_disparity_px);
      const pcl::PointXYZ& p = features.points[i];
      const double z = calibration.focal_length_px * calibration.baseline_m / d;
      EXPECT_NEAR(p.z, z, 1e-4 * z);
      EXPECT_NEAR(p.x, (pl.x - calibration.cx_px) * z / calibration.focal_length_px,
                  1e-4 * z);
      EXPECT_NEAR(p.y, (pl.y - calibration.cy_px) * z / calibration.focal_length_px,
                  1e-4 * z);
      EXPECT_LE(std::sqrt(p.x * p.x + p.y * p.y + p.z * p.z),
                params.max_range_m + 1e-3);
    }
  }

  cv::Mat left_, right_;
  StereoCalibration calibration_;
};

// Known truth: the right image is the left one shifted by exactly 24 px, so every true
// match has disparity 24 and dy = 0. SIFT is shift-equivariant when the shift is a
// multiple of the octave's sampling step (2^octave px; 24 = 3 * 2^3, so octaves -1..3)
// and the descriptor window is not cut by the right image's new borders (x = 0, which
// is column 24 of the left image, and the blank band from x = width - 24); OpenCV's
// SIFT descriptor reaches 3 sigma * sqrt(2) * (4 + 1) / 2 = 2.65 * size from the key
// point, so "clear of the border" is 3 * size. Those matches must be within 0.5 px. The
// rest (octave >= 4, near a border) must be within one sampling step plus 0.5 px.
// Measured: 1987 matches; 1 border match off by 0.80 px and 3 octave-4 matches off by
// <= 1.24 px (step 16 px), all others < 0.5 px.
TEST_F(StereoFeatureMatcherKarlsruhe, SIFTRecoversKnownShift)
{
  const int shift_px = 24;
  const auto params = paramsFor(FeatureType::SIFT);
  StereoFeatures features;
  StereoFeatureMatcher(params).match(left_, shiftedLeft(shift_px), calibration_,
                                     features);
  expectConsistent(features, params, calibration_);
  // 2000 key points per image on identical content: most re-detected and matched;
  // measured 1987, bound 1500 (25 % lower).
  EXPECT_GT(features.size(), 1500u);
  ASSERT_EQ(features.descriptors.type(), CV_32F);
  std::size_t exact_checked = 0;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const cv::KeyPoint& kl = features.keypoints_left[i];
    const cv::KeyPoint& kr = features.keypoints_right[i];
    const int octave = static_cast<signed char>(kl.octave & 0xff);
    const double step_px = std::pow(2.0, octave);
    const float error =
      std::abs(features.disparities[i] - static_cast<float>(shift_px));
    EXPECT_LE(std::abs(kl.pt.y - kr.pt.y), 1.0f);
    const float margin_px = 3.0f * kr.size;
    const bool clear_of_border =
      kr.pt.x > margin_px
      && kr.pt.x < static_cast<float>(left_.cols - shift_px) - margin_px;
    if (octave <= 3 && clear_of_border) {
      ++exact_checked;
      EXPECT_LE(error, 0.5f) << "at " << kl.pt << " octave " << octave;
    } else {
      EXPECT_LE(error, step_px + 0.5) << "at " << kl.pt << " octave " << octave;
    }
  }
  std::cout << "[ shift 24 ] SIFT: " << features.size() << " matches, " << exact_checked
            << " checked to 0.5 px\n";
  EXPECT_GT(exact_checked, 1500u);
}

// ORB key points are integer positions on a pyramid level with scale 1.2^level, so a
// 24-px shift is exact only on levels 0 and 1 (24 / 1.2 = 20); those must be within
// 0.5 px. Higher levels are quantised to 1.2^level px. Measured: 1702 matches, levels 0
// and 1 (792 matches) all exact; 16 matches (0.9 %) beyond one level step + 0.5 px: ORB
// on repeated facade texture with the true partner not re-detected, which the ratio
// test cannot see. Bound: at most 2 % of matches beyond that step.
TEST_F(StereoFeatureMatcherKarlsruhe, ORBRecoversKnownShift)
{
  const int shift_px = 24;
  const auto params = paramsFor(FeatureType::ORB);
  StereoFeatures features;
  StereoFeatureMatcher(params).match(left_, shiftedLeft(shift_px), calibration_,
                                     features);
  expectConsistent(features, params, calibration_);
  // Measured 1702, bound 1200 (30 % lower).
  EXPECT_GT(features.size(), 1200u);
  ASSERT_EQ(features.descriptors.type(), CV_8U);
  std::size_t exact_checked = 0, beyond_step = 0;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const cv::KeyPoint& kl = features.keypoints_left[i];
    const float error =
      std::abs(features.disparities[i] - static_cast<float>(shift_px));
    EXPECT_LE(std::abs(kl.pt.y - features.keypoints_right[i].pt.y), 1.0f);
    if (kl.octave <= 1) {
      ++exact_checked;
      EXPECT_LE(error, 0.5f) << "at " << kl.pt << " level " << kl.octave;
    } else if (error > std::pow(1.2, kl.octave) + 0.5) {
      ++beyond_step;
    }
  }
  std::cout << "[ shift 24 ] ORB: " << features.size() << " matches, " << exact_checked
            << " checked to 0.5 px, " << beyond_step << " beyond one level step\n";
  EXPECT_GT(exact_checked, 600u); // measured 792
  EXPECT_LE(beyond_step, features.size() / 50);
}

/** \brief Median over features of |z_feature - z_sgbm| / z_sgbm where SGBM has a value
 * at the left key point's pixel; \a compared gets the number of such features. */
double
medianRelativeDepthDifference(const StereoFeatures& features,
                              const cv::Mat& disparity,
                              const StereoCalibration& calibration,
                              std::size_t& compared)
{
  std::vector<double> differences;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const cv::Point2f& p = features.keypoints_left[i].pt;
    const int u = static_cast<int>(std::lround(p.x));
    const int v = static_cast<int>(std::lround(p.y));
    if (u < 0 || v < 0 || u >= disparity.cols || v >= disparity.rows)
      continue;
    const float d = disparity.at<float>(v, u);
    if (!(d > 0.0f))
      continue;
    const double z_sgbm = calibration.depthFromDisparity(d);
    differences.push_back(std::abs(features.points[i].z - z_sgbm) / z_sgbm);
  }
  compared = differences.size();
  if (differences.empty())
    return std::numeric_limits<double>::infinity();
  const auto middle =
    differences.begin() + static_cast<std::ptrdiff_t>(differences.size() / 2);
  std::nth_element(differences.begin(), middle, differences.end());
  return *middle;
}

// Real pair, frame 10: the matches obey the epipolar and disparity constraints, and
// their depth agrees with SGBM's at the same pixel for most features. SGBM is
// independent (dense, block-based, smoothness prior), so agreement checks the matching
// and the triangulation. Measured (SIFT / ORB): 613 / 465 matches; median relative
// depth difference 1.35 % / 3.55 % over 520 / 414 features with an SGBM value. ORB is
// worse because its key points are integer positions on pyramid levels of scale
// 1.2^level (no sub-pixel refinement): at the typical 20 px disparity a 1 px error is 5
// % of the depth. Bounds: > 400 / > 300 matches, median difference < 2 % / < 5 % (a
// wrong baseline factor, a disparity sign error, or mismatches dominating give >> 10
// %).
TEST_F(StereoFeatureMatcherKarlsruhe, RealPairAgreesWithSGBM)
{
  cv::Mat disparity;
  planar_grid::DisparityEstimator().compute(left_, right_, disparity);
  for (const FeatureType type : {FeatureType::SIFT, FeatureType::ORB}) {
    const auto params = paramsFor(type);
    const StereoFeatureMatcher matcher(params);
    StereoFeatures features;
    const auto start = std::chrono::steady_clock::now();
    matcher.match(left_, right_, calibration_, features);
    const double elapsed_ms = std::chrono::duration<double, std::milli>(
                                std::chrono::steady_clock::now() - start)
                                .count();
    expectConsistent(features, params, calibration_);
    std::size_t compared = 0;
    const double median_difference =
      medianRelativeDepthDifference(features, disparity, calibration_, compared);
    const char* name = type == FeatureType::SIFT ? "SIFT" : "ORB";
    std::cout << "[ Karlsruhe 10 ] " << name << ": " << features.size()
              << " matches in " << elapsed_ms << " ms; median |dz|/z vs SGBM "
              << median_difference << " over " << compared << " features\n";
    EXPECT_GT(features.size(), type == FeatureType::SIFT ? 400u : 300u) << name;
    EXPECT_GT(compared, features.size() / 2) << name;
    EXPECT_LT(median_difference, type == FeatureType::SIFT ? 0.02 : 0.05) << name;
  }
}

/** \brief Brute-force reference of the matcher: every left key point against
 * every right key point, same constraints, ratio test and uniqueness rule. Returns the
 * (left index, right index) pairs before the range cut. */
std::vector<std::pair<int, int>>
bruteForceMatches(const std::vector<cv::KeyPoint>& keypoints_left,
                  const cv::Mat& descriptors_left,
                  const std::vector<cv::KeyPoint>& keypoints_right,
                  const cv::Mat& descriptors_right,
                  const StereoFeatureMatcher::Params& params)
{
  const int norm =
    params.feature_type == FeatureType::SIFT ? cv::NORM_L2 : cv::NORM_HAMMING;
  std::vector<int> match_of_left(keypoints_left.size(), -1);
  std::vector<double> owner_distance(keypoints_right.size(),
                                     std::numeric_limits<double>::infinity());
  std::vector<int> owner(keypoints_right.size(), -1);
  for (std::size_t i = 0; i < keypoints_left.size(); ++i) {
    double best = std::numeric_limits<double>::infinity(), second = best;
    int best_j = -1;
    for (std::size_t j = 0; j < keypoints_right.size(); ++j) {
      const double dy = keypoints_left[i].pt.y - keypoints_right[j].pt.y;
      const double d = keypoints_left[i].pt.x - keypoints_right[j].pt.x;
      if (std::abs(dy) > params.max_row_difference_px || !(d > 0.0)
          || d > params.max_disparity_px)
        continue;
      const double distance =
        cv::norm(descriptors_left.row(static_cast<int>(i)),
                 descriptors_right.row(static_cast<int>(j)), norm);
      if (distance < best) {
        second = best;
        best = distance;
        best_j = static_cast<int>(j);
      } else if (distance < second) {
        second = distance;
      }
    }
    if (best_j < 0 || !(best < params.ratio * second))
      continue;
    match_of_left[i] = best_j;
    if (best < owner_distance[static_cast<std::size_t>(best_j)]) {
      owner_distance[static_cast<std::size_t>(best_j)] = best;
      owner[static_cast<std::size_t>(best_j)] = static_cast<int>(i);
    }
  }
  std::vector<std::pair<int, int>> matches;
  for (std::size_t i = 0; i < keypoints_left.size(); ++i)
    if (match_of_left[i] >= 0
        && owner[static_cast<std::size_t>(match_of_left[i])] == static_cast<int>(i))
      matches.emplace_back(static_cast<int>(i), match_of_left[i]);
  return matches;
}

// Oracle: the row-bucketed matcher gives exactly the brute-force matches on the
// real pair (same detector run, so the same key points; the largest max_range_m so the
// range cut removes nothing). Compared by key point positions. SIFT and ORB; the
// descriptor distances tie-break identically (strict <), so the sets must be equal.
TEST_F(StereoFeatureMatcherKarlsruhe, BucketedMatchingEqualsBruteForce)
{
  for (const FeatureType type : {FeatureType::SIFT, FeatureType::ORB}) {
    auto params = paramsFor(type);
    params.max_range_m = planar_grid::stereo_feature_matcher_ranges::MAX_RANGE.max;
    StereoFeatures features;
    StereoFeatureMatcher(params).match(left_, right_, calibration_, features);

    cv::Ptr<cv::Feature2D> detector;
    if (type == FeatureType::SIFT)
      detector = cv::SIFT::create(params.max_features);
    else
      detector = cv::ORB::create(params.max_features);
    std::vector<cv::KeyPoint> keypoints_left, keypoints_right;
    cv::Mat descriptors_left, descriptors_right;
    detector->detectAndCompute(left_, cv::noArray(), keypoints_left, descriptors_left);
    detector->detectAndCompute(right_, cv::noArray(), keypoints_right,
                               descriptors_right);
    const auto expected = bruteForceMatches(keypoints_left, descriptors_left,
                                            keypoints_right, descriptors_right, params);

    ASSERT_EQ(features.size(), expected.size())
      << (type == FeatureType::SIFT ? "SIFT" : "ORB");
    for (std::size_t k = 0; k < expected.size(); ++k) {
      const cv::Point2f& el =
        keypoints_left[static_cast<std::size_t>(expected[k].first)].pt;
      const cv::Point2f& er =
        keypoints_right[static_cast<std::size_t>(expected[k].second)].pt;
      EXPECT_EQ(features.keypoints_left[k].pt, el);
      EXPECT_EQ(features.keypoints_right[k].pt, er);
      // Descriptor rows are copied for the kept matches.
      EXPECT_EQ(cv::norm(features.descriptors.row(static_cast<int>(k)),
                         descriptors_left.row(expected[k].first), cv::NORM_INF),
                0.0);
    }
  }
}

// Blank images have no key points: zero features, no crash.
TEST(StereoFeatureMatcher, BlankImagesGiveNoFeatures)
{
  StereoCalibration calibration;
  calibration.focal_length_px = 500.0;
  calibration.baseline_m = 0.5;
  const cv::Mat blank(200, 300, CV_8UC1, cv::Scalar(100));
  for (const FeatureType type : {FeatureType::SIFT, FeatureType::ORB}) {
    StereoFeatureMatcher::Params params;
    params.feature_type = type;
    StereoFeatures features;
    StereoFeatureMatcher(params).match(blank, blank, calibration, features);
    EXPECT_EQ(features.size(), 0u);
    EXPECT_TRUE(features.points.empty());
    EXPECT_EQ(features.descriptors.rows, 0);
  }
}

TEST(StereoFeatureMatcher, RejectsBadInput)
{
  StereoCalibration calibration;
  calibration.focal_length_px = 500.0;
  calibration.baseline_m = 0.5;
  const StereoFeatureMatcher matcher;
  StereoFeatures features;
  const cv::Mat image(200, 300, CV_8UC1, cv::Scalar(100));
  EXPECT_THROW(matcher.match(image, cv::Mat(200, 301, CV_8UC1), calibration, features),
               planar_grid::Exception);
  EXPECT_THROW(matcher.match(cv::Mat(), image, calibration, features),
               planar_grid::Exception);
  EXPECT_THROW(matcher.match(image, image, StereoCalibration(), features),
               planar_grid::Exception);

  StereoFeatureMatcher::Params params;
  params.ratio = 0.0;
  EXPECT_THROW(StereoFeatureMatcher{params}, planar_grid::Exception);
  params = StereoFeatureMatcher::Params();
  params.max_features = 0;
  EXPECT_THROW(StereoFeatureMatcher{params}, planar_grid::Exception);
  params = StereoFeatureMatcher::Params();
  params.max_disparity_px = -1.0;
  EXPECT_THROW(StereoFeatureMatcher{params}, planar_grid::Exception);

  EXPECT_EQ(planar_grid::featureTypeFromString("sift"), FeatureType::SIFT);
  EXPECT_EQ(planar_grid::featureTypeFromString("orb"), FeatureType::ORB);
  EXPECT_THROW(planar_grid::featureTypeFromString("surf"), planar_grid::Exception);
}

} // namespace
