// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/stereo_pair_check.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include <cmath>
#include <vector>

namespace planar_grid {

StereoPairOrder
countStereoPairOrder(const cv::Mat& left, const cv::Mat& right)
{
  StereoPairOrder order;
  const cv::Ptr<cv::ORB> orb = cv::ORB::create(1000);
  std::vector<cv::KeyPoint> left_points, right_points;
  cv::Mat left_descriptors, right_descriptors;
  orb->detectAndCompute(left, cv::noArray(), left_points, left_descriptors);
  orb->detectAndCompute(right, cv::noArray(), right_points, right_descriptors);
  if (left_descriptors.empty() || right_descriptors.empty())
    return order;
  std::vector<cv::DMatch> matches;
  cv::BFMatcher(cv::NORM_HAMMING, true)
    .match(left_descriptors, right_descriptors, matches);
  for (const cv::DMatch& m : matches) {
    const cv::Point2f& l = left_points[static_cast<std::size_t>(m.queryIdx)].pt;
    const cv::Point2f& r = right_points[static_cast<std::size_t>(m.trainIdx)].pt;
    if (std::abs(l.y - r.y) > 1.0f)
      continue;
    const float disparity = l.x - r.x;
    if (disparity > 0.5f)
      ++order.positive;
    else if (disparity < -0.5f)
      ++order.negative;
    else
      ++order.zero;
  }
  return order;
}

void
checkStereoPairOrder(const cv::Mat& left,
                     const cv::Mat& right,
                     const std::string& left_path,
                     const std::string& right_path,
                     const std::string& remedy)
{
  // Two uniform images (a lens cap, darkness) are equal without being one image.
  double lowest = 0.0, highest = 0.0;
  cv::minMaxLoc(left, &lowest, &highest);
  if (highest > lowest && left.size() == right.size() && left.type() == right.type()
      && cv::norm(left, right, cv::NORM_INF) == 0.0)
    throw IOError(right_path + ": the right image is the left image (" + left_path
                  + ") pixel for pixel: no disparity, no depth (do the left and "
                    "right inputs name the same images?)");
  const StereoPairOrder order = countStereoPairOrder(left, right);
  const std::size_t nonzero = order.positive + order.negative;
  if (nonzero >= 40 && order.negative * 4 > nonzero * 3)
    throw IOError(left_path + ": the left and right images look swapped: "
                  + std::to_string(order.negative) + " of the "
                  + std::to_string(nonzero)
                  + " features matched on the same row lie further right in the left "
                    "image than in the right one ("
                  + right_path + "); " + remedy);
}

} // namespace planar_grid
