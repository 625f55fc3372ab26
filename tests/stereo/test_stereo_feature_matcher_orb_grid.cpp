// SPDX-License-Identifier: BSD-3-Clause
// The ORB_GRID front end of StereoFeatureMatcher: grid-bucketed FAST corners, upright
// ORB descriptors, sub-pixel disparities.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <gtest/gtest.h>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <iostream>
#include <string>
#include <vector>

#include "../test_constants.h"

namespace {

using planar_grid::FeatureType;
using planar_grid::StereoCalibration;
using planar_grid::StereoFeatureMatcher;
using planar_grid::StereoFeatures;

using planar_grid_test::KARLSRUHE_DIR;

StereoFeatureMatcher::Params
gridParams()
{
  StereoFeatureMatcher::Params params;
  params.feature_type = FeatureType::ORB_GRID;
  return params;
}

/** \brief Karlsruhe frame 10 (1344x372, grey) and its calibration. */
class StereoFeatureMatcherORBGrid : public ::testing::Test {
protected:
  void SetUp() override
  {
    left_ = cv::imread(KARLSRUHE_DIR + "/left/I1_000010.png", cv::IMREAD_GRAYSCALE);
    right_ = cv::imread(KARLSRUHE_DIR + "/right/I2_000010.png", cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(left_.empty());
    ASSERT_FALSE(right_.empty());
    calibration_ =
      planar_grid::loadStereoCalibration(planar_grid::CalibrationFormat::KARLSRUHE,
                                         KARLSRUHE_DIR + "/calib.txt")
        .calibration;
  }

  /** \brief A right image in which every scene point has disparity exactly \a shift_px
   * (right(x, y) = left(x + shift_px, y), bilinear; blank where x + shift_px leaves the
   * image), so the true disparity of every match is known, fractional shifts included.
   */
  cv::Mat shiftedLeft(double shift_px) const
  {
    cv::Mat shifted;
    const cv::Matx23d to_left(1.0, 0.0, shift_px, 0.0, 1.0, 0.0);
    cv::warpAffine(left_, shifted, to_left, left_.size(),
                   cv::INTER_LINEAR | cv::WARP_INVERSE_MAP, cv::BORDER_CONSTANT,
                   cv::Scalar(0));
    return shifted;
  }

  cv::Mat left_, right_;
  StereoCalibration calibration_;
};

// Known truth: right = left shifted by a fractional number of pixels. Integer key
// points alone would be off by up to 0.5 px (the fractional part); the refinement must
// bring the disparities within 0.2 px. Matches near the blank band the shift leaves at
// the right image's right edge (within the refinement window plus the search of it)
// are excluded: their windows hold blank pixels. Measured (shift 7.3 / 20.5 / 31.75):
// 1129 / 1062 / 1154 matches, median error 0.032 / 0.012 / 0.045 px; 9-10 matches
// (1 %) beyond 0.2 px: half of them descriptor mismatches on repeated facade texture
// (5-46 px off, as plain ORB's), the others 0.2-0.74 px on windows with little
// texture across the row. Bounds: >= 97 % of the checked disparities within 0.2 px,
// median within 0.05 px, > 800 matches.
TEST_F(StereoFeatureMatcherORBGrid, SubPixelDisparityOfKnownFractionalShift)
{
  auto params = gridParams();
  // The largest range the matcher takes: 7.3 px is 50 m away at this baseline.
  params.max_range_m = planar_grid::stereo_feature_matcher_ranges::MAX_RANGE.max;
  for (const double shift_px : {7.3, 20.5, 31.75}) {
    StereoFeatures features;
    StereoFeatureMatcher(params).match(left_, shiftedLeft(shift_px), calibration_,
                                       features);
    ASSERT_EQ(features.disparities.size(), features.size());
    EXPECT_GT(features.size(), 800u) << "shift " << shift_px;
    std::vector<double> errors;
    const double blank_from =
      left_.cols - shift_px - params.subpixel_window_px - params.subpixel_search_px;
    std::size_t within = 0;
    for (std::size_t i = 0; i < features.size(); ++i) {
      if (features.keypoints_right[i].pt.x > blank_from)
        continue;
      const double error = std::abs(features.disparities[i] - shift_px);
      within += error <= 0.2 ? 1 : 0;
      // The right key point sits on the left key point's row (rectified pair).
      EXPECT_EQ(features.keypoints_right[i].pt.y, features.keypoints_left[i].pt.y);
      errors.push_back(error);
    }
    ASSERT_FALSE(errors.empty());
    EXPECT_GE(static_cast<double>(within), 0.97 * static_cast<double>(errors.size()))
      << "shift " << shift_px;
    std::nth_element(errors.begin(),
                     errors.begin() + static_cast<std::ptrdiff_t>(errors.size() / 2),
                     errors.end());
    const double median = errors[errors.size() / 2];
    std::cout << "[ shift " << shift_px << " ] orb_grid: " << features.size()
              << " matches, " << within << " of " << errors.size()
              << " within 0.2 px, median |d - shift| " << median << " px\n";
    EXPECT_LT(median, 0.05) << "shift " << shift_px;
  }
}

// Synthetic rectified pair with known disparity: smoothed uniform noise (seeded) and
// its copy shifted by 5.4 px (bilinear). Every match whose integer key points are the
// true pair (within 1 px) must have its refined disparity within 0.2 px of 5.4 (integer
// key points alone are 0.4-0.6 px off). Descriptor mismatches (measured: 1 of 1393, 56
// px off) are not the refinement's; at most 1 % of the matches may be such.
TEST(StereoFeatureMatcherORBGridSynthetic, RefinedDisparitiesWithinAFifthOfAPixel)
{
  cv::Mat noise(240, 400, CV_8UC1);
  cv::RNG rng(7);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat left;
  cv::GaussianBlur(noise, left, cv::Size(0, 0), 1.2);
  const double shift_px = 5.4;
  cv::Mat right;
  cv::warpAffine(left, right, cv::Matx23d(1.0, 0.0, shift_px, 0.0, 1.0, 0.0),
                 left.size(), cv::INTER_LINEAR | cv::WARP_INVERSE_MAP,
                 cv::BORDER_REFLECT_101);
  StereoCalibration calibration;
  calibration.focal_length_px = 500.0;
  calibration.baseline_m = 0.5;
  calibration.cx_px = 200.0;
  calibration.cy_px = 120.0;
  auto params = gridParams();
  params.max_range_m = planar_grid::stereo_feature_matcher_ranges::MAX_RANGE.max;
  StereoFeatures features;
  StereoFeatureMatcher(params).match(left, right, calibration, features);
  // 13 x 8 cells of 32 px, all textured: hundreds of matches.
  EXPECT_GT(features.size(), 300u);
  std::size_t checked = 0, mismatched = 0;
  for (std::size_t i = 0; i < features.size(); ++i) {
    if (features.keypoints_left[i].pt.x > 400.0 - 16.0 - shift_px)
      continue; // the reflected border band is not the shifted scene
    if (std::abs(features.disparities[i] - shift_px) > 1.0) {
      ++mismatched;
      continue;
    }
    ++checked;
    EXPECT_NEAR(features.disparities[i], shift_px, 0.2)
      << "at " << features.keypoints_left[i].pt;
  }
  std::cout << "[ synthetic 5.4 px ] orb_grid: " << features.size() << " matches, "
            << checked << " checked to 0.2 px, " << mismatched << " mismatches\n";
  EXPECT_LE(mismatched, features.size() / 100);
}

// Real pair, frame 10: depths agree with SGBM's at the same pixel (SGBM is independent:
// dense, block-based, smoothness prior). Measured: 525 matches at the default 2000
// key points, median relative depth difference 0.67 % over 480 features with an SGBM
// value (SIFT 1.35 %, plain ORB 3.55 % in test_stereo_feature_matcher.cpp: the
// sub-pixel refinement removes ORB's quantisation). Bounds: > 400 matches, median < 1.5
// %.
TEST_F(StereoFeatureMatcherORBGrid, RealPairAgreesWithSGBM)
{
  cv::Mat disparity;
  planar_grid::DisparityEstimator().compute(left_, right_, disparity);
  const auto params = gridParams();
  StereoFeatures features;
  StereoFeatureMatcher(params).match(left_, right_, calibration_, features);
  ASSERT_EQ(features.points.size(), features.size());
  ASSERT_EQ(static_cast<std::size_t>(features.descriptors.rows), features.size());
  EXPECT_EQ(features.descriptors.type(), CV_8U);
  EXPECT_EQ(features.descriptors.cols, 32); // 256-bit ORB descriptors
  std::vector<double> differences;
  for (std::size_t i = 0; i < features.size(); ++i) {
    const cv::Point2f& pl = features.keypoints_left[i].pt;
    const cv::Point2f& pr = features.keypoints_right[i].pt;
    EXPECT_EQ(pl.y, pr.y);
    EXPECT_FLOAT_EQ(features.disparities[i], pl.x - pr.x);
    EXPECT_GT(features.disparities[i], 0.0f);
    const double z =
      calibration_.focal_length_px * calibration_.baseline_m / features.disparities[i];
    EXPECT_NEAR(features.points[i].z, z, 1e-4 * z);
    const float d = disparity.at<float>(static_cast<int>(std::lround(pl.y)),
                                        static_cast<int>(std::lround(pl.x)));
    if (d > 0.0f) {
      const double z_sgbm = calibration_.depthFromDisparity(d);
      differences.push_back(std::abs(features.points[i].z - z_sgbm) / z_sgbm);
    }
  }
  ASSERT_GT(differences.size(), features.size() / 2);
  std::nth_element(differences.begin(),
                   differences.begin()
                     + static_cast<std::ptrdiff_t>(differences.size() / 2),
                   differences.end());
  const double median = differences[differences.size() / 2];
  std::cout << "[ Karlsruhe 10 ] orb_grid: " << features.size()
            << " matches; median |dz|/z vs SGBM " << median << " over "
            << differences.size() << " features\n";
  EXPECT_GT(features.size(), 400u);
  EXPECT_LT(median, 0.015);
}

/** \brief Uniform noise (grey levels 0-255, fixed seed) smoothed by a 3x3 box: corners
 * everywhere, so every grid cell holds many FAST corners. */
cv::Mat
texturedImage(int width, int height)
{
  cv::Mat noise(height, width, CV_8UC1);
  cv::RNG rng(42);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::Mat image;
  cv::blur(noise, image, cv::Size(3, 3));
  return image;
}

// Even coverage: on a textured 330x250 image with 32 px cells (11 x 8 cells, the last
// column 10 px and the last row 26 px wide) every cell gets exactly max_per_cell
// corners (each holds far more FAST corners), and they are the cell's strongest ones
// (brute-force check against cv::FAST over the whole image).
TEST(GridFastKeypoints, EveryCellOfATexturedImageHasKeypoints)
{
  const cv::Mat image = texturedImage(330, 250);
  const int bucket = 32, per_cell = 5, threshold = 10;
  std::vector<cv::KeyPoint> keypoints;
  planar_grid::detectGridFastKeypoints(image, bucket, per_cell, threshold, 0,
                                       keypoints);
  std::vector<cv::KeyPoint> all;
  cv::FAST(image, all, threshold, true);
  const int cols = 11, rows = 8;
  ASSERT_EQ(keypoints.size(), static_cast<std::size_t>(cols * rows * per_cell));
  std::vector<int> count(static_cast<std::size_t>(cols * rows), 0);
  std::vector<float> weakest_kept(count.size(), 1e9f);
  for (const cv::KeyPoint& k : keypoints) {
    const int cell =
      static_cast<int>(k.pt.y) / bucket * cols + static_cast<int>(k.pt.x) / bucket;
    ++count[static_cast<std::size_t>(cell)];
    weakest_kept[static_cast<std::size_t>(cell)] =
      std::min(weakest_kept[static_cast<std::size_t>(cell)], k.response);
    EXPECT_EQ(k.octave, 0);
    EXPECT_EQ(k.angle, 0.0f);
    EXPECT_EQ(k.size, 31.0f);
  }
  for (std::size_t cell = 0; cell < count.size(); ++cell)
    EXPECT_EQ(count[cell], per_cell) << "cell " << cell;
  // No dropped corner is stronger than the weakest kept one of its cell.
  std::vector<int> stronger(count.size(), 0);
  for (const cv::KeyPoint& k : all) {
    const int cell =
      static_cast<int>(k.pt.y) / bucket * cols + static_cast<int>(k.pt.x) / bucket;
    if (k.response > weakest_kept[static_cast<std::size_t>(cell)])
      ++stronger[static_cast<std::size_t>(cell)];
  }
  for (std::size_t cell = 0; cell < count.size(); ++cell)
    EXPECT_LE(stronger[cell], per_cell) << "cell " << cell;
}

// The border margin: no corner closer than border_px to an edge.
TEST(GridFastKeypoints, BorderIsRespected)
{
  const cv::Mat image = texturedImage(200, 120);
  std::vector<cv::KeyPoint> keypoints;
  planar_grid::detectGridFastKeypoints(image, 16, 100, 10, 16, keypoints);
  ASSERT_FALSE(keypoints.empty());
  for (const cv::KeyPoint& k : keypoints) {
    EXPECT_GE(k.pt.x, 16.0f);
    EXPECT_GE(k.pt.y, 16.0f);
    EXPECT_LT(k.pt.x, 200.0f - 16.0f);
    EXPECT_LT(k.pt.y, 120.0f - 16.0f);
  }
}

// The detector runs cv::FAST on the image less a margin of border_px - 4 px: the same
// key points, bit for bit and in the same order, as cv::FAST over the whole image, its
// corners within border_px of an edge dropped, then each cell's strongest (a stable
// sort by response) kept. Checked on both Karlsruhe frame 10 images, for borders at,
// below and above the 4 px the margin leaves, and on an image narrower than two
// borders.
TEST_F(StereoFeatureMatcherORBGrid, KeypointsEqualThoseOfFASTOverTheWholeImage)
{
  const auto reference = [](const cv::Mat& grey, int bucket, int per_cell, int border) {
    std::vector<cv::KeyPoint> all;
    cv::FAST(grey, all, 10, true);
    const int cols = (grey.cols + bucket - 1) / bucket;
    const int rows = (grey.rows + bucket - 1) / bucket;
    std::vector<std::vector<cv::KeyPoint>> cells(static_cast<std::size_t>(cols * rows));
    for (const cv::KeyPoint& k : all) {
      const int x = static_cast<int>(k.pt.x), y = static_cast<int>(k.pt.y);
      if (x < border || y < border || x >= grey.cols - border
          || y >= grey.rows - border)
        continue;
      cells[static_cast<std::size_t>(y / bucket * cols + x / bucket)].push_back(k);
    }
    std::vector<cv::KeyPoint> kept;
    for (auto& cell : cells) {
      std::stable_sort(cell.begin(), cell.end(),
                       [](const cv::KeyPoint& a, const cv::KeyPoint& b) {
                         return a.response > b.response;
                       });
      for (std::size_t i = 0; i < cell.size() && i < static_cast<std::size_t>(per_cell);
           ++i)
        kept.push_back(cell[i]);
    }
    return kept;
  };
  cv::Mat narrow_left = left_(cv::Rect(0, 0, 40, 372));
  for (const cv::Mat* image : {&left_, &right_, &narrow_left})
    for (const int border : {0, 3, 4, 5, 16, 25}) {
      std::vector<cv::KeyPoint> keypoints;
      planar_grid::detectGridFastKeypoints(*image, 32, 8, 10, border, keypoints);
      const std::vector<cv::KeyPoint> expected = reference(*image, 32, 8, border);
      ASSERT_EQ(keypoints.size(), expected.size()) << "border " << border;
      for (std::size_t i = 0; i < expected.size(); ++i) {
        EXPECT_EQ(keypoints[i].pt, expected[i].pt) << "border " << border << ", " << i;
        EXPECT_EQ(keypoints[i].response, expected[i].response);
      }
    }
}

// Degenerate input: blank images have no corners and give no features; an empty image
// gives no corners.
TEST(GridFastKeypoints, BlankAndEmptyImagesGiveNothing)
{
  std::vector<cv::KeyPoint> keypoints(3);
  planar_grid::detectGridFastKeypoints(cv::Mat(), 32, 5, 10, 0, keypoints);
  EXPECT_TRUE(keypoints.empty());
  const cv::Mat blank(200, 300, CV_8UC1, cv::Scalar(100));
  planar_grid::detectGridFastKeypoints(blank, 32, 5, 10, 0, keypoints);
  EXPECT_TRUE(keypoints.empty());

  StereoCalibration calibration;
  calibration.focal_length_px = 500.0;
  calibration.baseline_m = 0.5;
  StereoFeatures features;
  StereoFeatureMatcher(gridParams()).match(blank, blank, calibration, features);
  EXPECT_EQ(features.size(), 0u);
  EXPECT_EQ(features.descriptors.rows, 0);
}

TEST(StereoFeatureMatcherORBGridParams, BadParametersThrow)
{
  const auto expectThrow = [](auto mutate) {
    auto params = gridParams();
    mutate(params);
    EXPECT_THROW(StereoFeatureMatcher{params}, planar_grid::Exception);
  };
  using Params = StereoFeatureMatcher::Params;
  expectThrow([](Params& p) { p.bucket_size_px = 7; });
  expectThrow([](Params& p) { p.bucket_size_px = 1025; });
  expectThrow([](Params& p) { p.fast_threshold = 0; });
  expectThrow([](Params& p) { p.fast_threshold = 256; });
  expectThrow([](Params& p) { p.subpixel_window_px = 8; }); // even
  expectThrow([](Params& p) { p.subpixel_window_px = 1; });
  expectThrow([](Params& p) { p.subpixel_window_px = 33; });
  expectThrow([](Params& p) { p.subpixel_search_px = 0; });
  expectThrow([](Params& p) { p.subpixel_search_px = 9; });
  EXPECT_NO_THROW(StereoFeatureMatcher{gridParams()});

  std::vector<cv::KeyPoint> keypoints;
  const cv::Mat colour(50, 50, CV_8UC3, cv::Scalar(1, 2, 3));
  EXPECT_THROW(planar_grid::detectGridFastKeypoints(colour, 32, 5, 10, 0, keypoints),
               planar_grid::Exception);
  const cv::Mat grey(50, 50, CV_8UC1, cv::Scalar(1));
  EXPECT_THROW(planar_grid::detectGridFastKeypoints(grey, 0, 5, 10, 0, keypoints),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::detectGridFastKeypoints(grey, 32, 0, 10, 0, keypoints),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::detectGridFastKeypoints(grey, 32, 5, 0, 0, keypoints),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::detectGridFastKeypoints(grey, 32, 5, 10, -1, keypoints),
               planar_grid::Exception);

  EXPECT_EQ(planar_grid::featureTypeFromString("orb_grid"), FeatureType::ORB_GRID);
  EXPECT_THROW(planar_grid::featureTypeFromString("fast"), planar_grid::Exception);
}

} // namespace
