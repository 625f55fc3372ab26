// SPDX-License-Identifier: BSD-3-Clause
// Shared by the stereo tests and bench_disparity: Middlebury-style error rates of a
// disparity image against 8-bit ground truth (docs/STEREO.md).
#pragma once

#include <opencv2/core/mat.hpp>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <vector>

namespace planar_grid {
namespace test {

/** \brief Errors of a disparity image over the pixels with known ground truth. */
struct DisparityErrors {
  /** \brief Pixels with ground truth (GT value > 0). */
  std::size_t known{0};
  /** \brief Of those, pixels where the estimate is not NaN. */
  std::size_t valid{0};
  /** \brief valid / known, in [0, 1]. */
  double density{0.0};
  /** \brief Fraction of the valid pixels whose error exceeds 1 px, in [0, 1]. */
  double bad1{0.0};
  /** \brief Fraction of the valid pixels whose error exceeds 2 px, in [0, 1]. */
  double bad2{0.0};
  /** \brief Mean absolute error (end-point error along the row) over the valid pixels,
   * px. */
  double epe_px{0.0};
  /** \brief Median of estimate / GT over the valid pixels (1 when the scales agree). */
  double median_ratio{0.0};
};

/** \brief Compares \a disparity (CV_32FC1, px, NaN = invalid) with \a truth (CV_8UC1,
 * px, 0 = unknown) of the same size. Only pixels with GT and an estimate count toward
 * bad1, bad2 and the EPE; the density says how many those are. */
inline DisparityErrors
compareWithGroundTruth(const cv::Mat& disparity, const cv::Mat& truth)
{
  DisparityErrors errors;
  std::size_t bad1 = 0, bad2 = 0;
  double error_sum = 0.0;
  std::vector<double> ratios;
  for (int v = 0; v < truth.rows; ++v)
    for (int u = 0; u < truth.cols; ++u) {
      const int gt = truth.at<std::uint8_t>(v, u);
      if (gt == 0)
        continue;
      ++errors.known;
      const float d = disparity.at<float>(v, u);
      if (std::isnan(d))
        continue;
      ++errors.valid;
      const double error = std::abs(static_cast<double>(d) - gt);
      error_sum += error;
      bad1 += error > 1.0;
      bad2 += error > 2.0;
      ratios.push_back(static_cast<double>(d) / gt);
    }
  if (errors.known > 0)
    errors.density =
      static_cast<double>(errors.valid) / static_cast<double>(errors.known);
  if (errors.valid == 0)
    return errors;
  const auto valid = static_cast<double>(errors.valid);
  errors.bad1 = static_cast<double>(bad1) / valid;
  errors.bad2 = static_cast<double>(bad2) / valid;
  errors.epe_px = error_sum / valid;
  const auto middle = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), middle, ratios.end());
  errors.median_ratio = *middle;
  return errors;
}

} // namespace test
} // namespace planar_grid
