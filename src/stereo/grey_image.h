// SPDX-License-Identifier: BSD-3-Clause
// Internal to planar_grid_stereo: not installed.
#pragma once

#include <opencv2/core/mat.hpp>
#include <opencv2/imgproc.hpp>

namespace planar_grid {
namespace detail {

/** \brief The grey version of a CV_8UC1 / CV_8UC3 (BGR) image; shared, not copied, when
 * it is already grey. */
inline cv::Mat
toGrey(const cv::Mat& image)
{
  if (image.channels() == 1)
    return image;
  cv::Mat grey;
  cv::cvtColor(image, grey, cv::COLOR_BGR2GRAY);
  return grey;
}

} // namespace detail
} // namespace planar_grid
