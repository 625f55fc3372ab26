// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_estimator.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/imgproc.hpp>

#include <limits>
#include <string>

#include "grey_image.h"

namespace planar_grid {

namespace {

/** \brief SGBM's smoothness penalties for one grey channel: OpenCV's recommended
 * 8 * block^2 and 32 * block^2 unless set. */
int
effectiveP1(const DisparityEstimator::Params& params)
{
  return params.p1 > 0 ? params.p1 : 8 * params.block_size_px * params.block_size_px;
}

int
effectiveP2(const DisparityEstimator::Params& params)
{
  return params.p2 > 0 ? params.p2 : 32 * params.block_size_px * params.block_size_px;
}

void
validateParams(const DisparityEstimator::Params& params)
{
  const std::string prefix = "DisparityEstimator: ";
  if (params.num_disparities_px <= 0 || params.num_disparities_px % 16 != 0)
    throw Exception(prefix
                    + "num_disparities_px must be a positive multiple of 16, got "
                    + std::to_string(params.num_disparities_px));
  if (params.block_size_px < 1 || params.block_size_px > 11
      || params.block_size_px % 2 == 0)
    throw Exception(prefix + "block_size_px must be odd and in [1, 11], got "
                    + std::to_string(params.block_size_px));
  if (params.p1 < 0 || params.p2 < 0)
    throw Exception(prefix + "p1 and p2 must be >= 0 (0 = OpenCV's default)");
  if (effectiveP2(params) <= effectiveP1(params))
    throw Exception(prefix + "p2 (" + std::to_string(effectiveP2(params))
                    + ") must be greater than p1 ("
                    + std::to_string(effectiveP1(params)) + ")");
  if (params.uniqueness_ratio_percent < 0 || params.uniqueness_ratio_percent > 100)
    throw Exception(prefix + "uniqueness_ratio_percent must be in [0, 100], got "
                    + std::to_string(params.uniqueness_ratio_percent));
  if (params.pre_filter_cap < 1 || params.pre_filter_cap > 63)
    throw Exception(prefix + "pre_filter_cap must be in [1, 63], got "
                    + std::to_string(params.pre_filter_cap));
  if (params.speckle_window_size_px < 0 || params.speckle_range_px < 0)
    throw Exception(prefix
                    + "speckle_window_size_px and speckle_range_px must be >= 0");
}

} // namespace

DisparityEstimator::DisparityEstimator() : DisparityEstimator(Params()) {}

DisparityEstimator::DisparityEstimator(const Params& params) : params_(params)
{
  validateParams(params_);
  sgbm_ = cv::StereoSGBM::create(
    params_.min_disparity_px, params_.num_disparities_px, params_.block_size_px,
    effectiveP1(params_), effectiveP2(params_), params_.disp12_max_diff_px,
    params_.pre_filter_cap, params_.uniqueness_ratio_percent,
    params_.speckle_window_size_px, params_.speckle_range_px,
    params_.full_dp ? cv::StereoSGBM::MODE_HH : cv::StereoSGBM::MODE_SGBM);
}

DisparityEstimator::~DisparityEstimator() = default;
DisparityEstimator::DisparityEstimator(DisparityEstimator&&) noexcept = default;
DisparityEstimator&
DisparityEstimator::operator=(DisparityEstimator&&) noexcept = default;

void
DisparityEstimator::compute(const cv::Mat& left,
                            const cv::Mat& right,
                            cv::Mat& disparity) const
{
  if (left.empty() || right.empty())
    throw Exception("DisparityEstimator::compute: empty input image");
  if (left.size() != right.size())
    throw Exception("DisparityEstimator::compute: the left and right images differ in "
                    "size");
  if (left.type() != right.type())
    throw Exception("DisparityEstimator::compute: the left and right images differ in "
                    "type");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3)
    throw Exception("DisparityEstimator::compute: images must be CV_8UC1 or CV_8UC3");

  cv::Mat fixed_point; // CV_16S, disparity * 16
  sgbm_->compute(detail::toGrey(left), detail::toGrey(right), fixed_point);

  // SGBM marks failures with (min_disparity - 1) * 16; anything below the search range
  // is invalid.
  const int min_valid = params_.min_disparity_px * 16;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  disparity.create(fixed_point.size(), CV_32FC1);
  for (int v = 0; v < fixed_point.rows; ++v) {
    const short* in = fixed_point.ptr<short>(v);
    float* out = disparity.ptr<float>(v);
    for (int u = 0; u < fixed_point.cols; ++u)
      out[u] = in[u] < min_valid ? nan : static_cast<float>(in[u]) / 16.0f;
  }
}

} // namespace planar_grid
