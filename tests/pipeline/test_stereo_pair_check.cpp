// SPDX-License-Identifier: BSD-3-Clause
// The stereo pair order check on every real stereo dataset of ../shared/data: each
// pair in its order passes with a clear majority of positive disparities, each pair
// swapped is refused, one image given twice is refused; and the stereo input refuses a
// swapped sequence before the first frame.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stereo_pair_check.h>
#include <planar_grid/stereo/calibration_io.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <string>
#include <vector>

#include "../test_constants.h"

namespace {

using planar_grid_test::DATA;

struct Pair {
  std::string left, right;
  /** The EuRoC calibration pair for the raw EuRoC images ("" for rectified ones). */
  std::string calibration_left, calibration_right;
};

std::vector<Pair>
realPairs()
{
  const std::string euroc = DATA + "/euroc_v1_01_pairs/";
  return {
    {DATA + "/karlsruhe_2010_03_09_drive_0023/left/I1_000000.png",
     DATA + "/karlsruhe_2010_03_09_drive_0023/right/I2_000000.png", "", ""},
    {DATA + "/karlsruhe_2010_03_09_drive_0023/left/I1_000095.png",
     DATA + "/karlsruhe_2010_03_09_drive_0023/right/I2_000095.png", "", ""},
    {DATA + "/kitti_odometry_snippet_2/image_l/000000.png",
     DATA + "/kitti_odometry_snippet_2/image_r/000000.png", "", ""},
    {DATA + "/rtabmap_stereo_rect/left/50.jpg",
     DATA + "/rtabmap_stereo_rect/right/50.jpg", "", ""},
    {DATA + "/middlebury_aloe/aloeL.jpg", DATA + "/middlebury_aloe/aloeR.jpg", "", ""},
    {euroc + "left_img_0.png", euroc + "right_img_0.png", euroc + "sensorLeft.yaml",
     euroc + "sensorRight.yaml"}};
}

/** The pair as the stereo input sees it: grey, rectified where the calibration says. */
void
loadPair(const Pair& pair, cv::Mat& left, cv::Mat& right)
{
  left = cv::imread(pair.left, cv::IMREAD_GRAYSCALE);
  right = cv::imread(pair.right, cv::IMREAD_GRAYSCALE);
  ASSERT_FALSE(left.empty()) << pair.left;
  ASSERT_FALSE(right.empty()) << pair.right;
  if (!pair.calibration_left.empty()) {
    const auto model =
      planar_grid::loadStereoCalibration(planar_grid::CalibrationFormat::EUROC,
                                         pair.calibration_left, pair.calibration_right);
    cv::Mat l, r;
    model.rectifier.rectify(left, right, l, r);
    left = l;
    right = r;
  }
}

std::string
errorOf(const cv::Mat& left, const cv::Mat& right)
{
  try {
    planar_grid::checkStereoPairOrder(left, right, "L.png", "R.png");
  } catch (const planar_grid::IOError& e) {
    return e.what();
  }
  return "";
}

TEST(StereoPairCheck, EveryRealPairPassesAndItsSwapIsRefused)
{
  for (const Pair& pair : realPairs()) {
    cv::Mat left, right;
    loadPair(pair, left, right);
    const auto order = planar_grid::countStereoPairOrder(left, right);
    const auto swapped = planar_grid::countStereoPairOrder(right, left);
    // In order, the matches are nearly all at positive disparity; swapped, negative.
    EXPECT_GE(order.positive, 100u) << pair.left;
    EXPECT_LT(order.negative * 10, order.positive) << pair.left;
    EXPECT_GE(swapped.negative, 100u) << pair.left;
    EXPECT_LT(swapped.positive * 10, swapped.negative) << pair.left;
    EXPECT_EQ(errorOf(left, right), "") << pair.left;
    const std::string what = errorOf(right, left);
    EXPECT_NE(what.find("L.png: the left and right images look swapped"),
              std::string::npos)
      << pair.left << ": " << what;
    const std::string twice = errorOf(left, left.clone());
    EXPECT_NE(twice.find("R.png: the right image is the left image (L.png)"),
              std::string::npos)
      << pair.left << ": " << twice;
  }
  // Too little texture to tell: no verdict, no error.
  const cv::Mat flat(64, 96, CV_8UC1, cv::Scalar(128));
  cv::Mat shifted = flat.clone();
  shifted.at<std::uint8_t>(3, 3) = 0;
  EXPECT_EQ(errorOf(flat, shifted), "");
}

TEST(StereoPairCheck, SwappedSequenceIsRefusedBeforeTheFirstFrame)
{
  const std::string karlsruhe = DATA + "/karlsruhe_2010_03_09_drive_0023";
  const auto yaml = [&karlsruhe](const std::string& left, const std::string& right) {
    return "input:\n  type: stereo_sequence\n  left_images: " + karlsruhe + left
           + "\n  right_images: " + karlsruhe + right
           + "\n  frame_count: 2\n  calibration: {format: karlsruhe, file: " + karlsruhe
           + "/calib.txt}\npipeline:\n  - type: stereo_disparity\n";
  };
  const std::string left = "/left/I1_%06d.png", right = "/right/I2_%06d.png";
  EXPECT_NO_THROW(planar_grid::PipelineRunner(
    planar_grid::parsePipelineConfig(yaml(left, right), "t.yaml", "/")));
  try {
    planar_grid::PipelineRunner runner(
      planar_grid::parsePipelineConfig(yaml(right, left), "t.yaml", "/"));
    ADD_FAILURE() << "a swapped sequence was accepted";
  } catch (const planar_grid::IOError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("I2_000000.png: the left and right images look swapped"),
              std::string::npos)
      << what;
  }
}

} // namespace
