// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_normals.h>

#include <Eigen/Dense>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace planar_grid {

DisparityNormalEstimator::DisparityNormalEstimator(
  const cv::Mat& disparity,
  const StereoCalibration& calibration,
  const DisparityNormalParams& params) :
    disparity_(disparity),
    calibration_(calibration), params_(params)
{
  namespace ranges = disparity_normals_ranges;
  if (!disparity.empty() && disparity.type() != CV_32FC1)
    throw Exception("estimateDisparityNormals: the disparity must be CV_32FC1");
  const double f = calibration.focal_length_px;
  const double fb = f * calibration.baseline_m;
  if (!(f > 0.0) || !(fb > 0.0) || !std::isfinite(fb))
    throw Exception("estimateDisparityNormals: the calibration needs a positive focal "
                    "length and baseline");
  if (!ranges::WINDOW_RADIUS.contains(params.window_radius_m))
    throw Exception(paramRangeMessage("window_radius_m", ranges::WINDOW_RADIUS, "m"));
  if (!ranges::WINDOW_RADIUS_PX.contains(params.min_window_radius_px)
      || !ranges::WINDOW_RADIUS_PX.contains(params.max_window_radius_px)
      || params.min_window_radius_px > params.max_window_radius_px)
    throw Exception("estimateDisparityNormals: min_window_radius_px and "
                    "max_window_radius_px must be in [1, 200] px, the first no larger "
                    "than the second");
  if (!ranges::MIN_VALID_FRACTION.contains(params.min_valid_fraction))
    throw Exception(
      paramRangeMessage("min_valid_fraction", ranges::MIN_VALID_FRACTION, ""));
}

Eigen::Vector3f
DisparityNormalEstimator::compute(const Eigen::Vector3f& p) const
{
  const Eigen::Vector3f none =
    Eigen::Vector3f::Constant(std::numeric_limits<float>::quiet_NaN());
  if (disparity_.empty())
    return none;
  const double f = calibration_.focal_length_px;
  const double fb = f * calibration_.baseline_m;
  // Wide windows are read at a stride: about 2 x HALF_SAMPLES + 1 pixels a side.
  constexpr int HALF_SAMPLES = 7;
  if (!p.allFinite() || !(p.z() > 0.0f))
    return none;
  const double u = f * p.x() / p.z() + calibration_.cx_px;
  const double v = f * p.y() / p.z() + calibration_.cy_px;
  const long ui = std::lround(u), vi = std::lround(v);
  if (ui < 0 || vi < 0 || ui >= disparity_.cols || vi >= disparity_.rows)
    return none;
  const double own = fb / p.z();
  const double gate = std::max(2.0, 0.2 * own);
  const int r = static_cast<int>(
    std::clamp<double>(std::round(f * params_.window_radius_m / p.z()),
                       params_.min_window_radius_px, params_.max_window_radius_px));
  const int stride = std::max(1, (r + HALF_SAMPLES - 1) / HALF_SAMPLES);
  const int half = r / stride;
  const double min_count =
    std::max(3.0, params_.min_valid_fraction * (2 * half + 1) * (2 * half + 1));
  // Least squares of d = a du + b dv + c0 over the window, du and dv relative to
  // (ui, vi): the normal equations' sums. Those of the pixel offsets alone are sums
  // of integers, kept exactly in integers; those with the disparity in double.
  std::int64_t n = 0, su = 0, sv = 0, suu = 0, suv = 0, svv = 0;
  double sd = 0, sud = 0, svd = 0;
  // the window's columns inside the image
  const long col_first = ui + static_cast<long>(-half) * stride;
  int i_first = -half, i_last = half;
  if (col_first < 0)
    i_first += static_cast<int>((-col_first + stride - 1) / stride);
  const long col_last = ui + static_cast<long>(half) * stride;
  if (col_last >= disparity_.cols)
    i_last -= static_cast<int>((col_last - disparity_.cols + stride) / stride);
  for (int j = -half; j <= half; ++j) {
    const long row = vi + static_cast<long>(j) * stride;
    if (row < 0 || row >= disparity_.rows)
      continue;
    const float* line = disparity_.ptr<float>(static_cast<int>(row));
    const std::int64_t dv_int = row - vi;
    const auto dv = static_cast<double>(dv_int);
    std::int64_t row_n = 0, row_su = 0, row_suu = 0;
    // Without a branch: a pixel that does not take part adds 0 to every sum, which
    // leaves each sum as it was (none of them is ever -0), so the sums are those of
    // the taking part pixels alone, in the same order.
    for (int i = i_first; i <= i_last; ++i) {
      const long col = ui + static_cast<long>(i) * stride;
      const double d = line[col];
      const bool takes_part = d > 0.0 && !(std::abs(d - own) > gate);
      const std::int64_t du_int = col - ui;
      const auto du = static_cast<double>(du_int);
      const double e = takes_part ? d - own : 0.0; // centred: better conditioned sums
      const std::int64_t m = takes_part ? 1 : 0;
      row_n += m;
      row_su += m * du_int;
      row_suu += m * du_int * du_int;
      sd += e;
      sud += du * e;
      svd += dv * e;
    }
    n += row_n;
    su += row_su;
    sv += row_n * dv_int;
    suu += row_suu;
    suv += row_su * dv_int;
    svv += row_n * dv_int * dv_int;
  }
  if (static_cast<double>(n) < min_count)
    return none;
  Eigen::Matrix3d normal_matrix;
  normal_matrix << static_cast<double>(suu), static_cast<double>(suv),
    static_cast<double>(su), static_cast<double>(suv), static_cast<double>(svv),
    static_cast<double>(sv), static_cast<double>(su), static_cast<double>(sv),
    static_cast<double>(n);
  const Eigen::Vector3d rhs(sud, svd, sd);
  // The sums of the pixel offsets are exact integers: the samples are collinear (no
  // plane fits them) exactly when the determinant of their normal matrix is zero.
  // It is computed exactly: with at most 15 x 15 samples of offsets |du|, |dv| <= 200
  // px, every sum is below 2^24 and every product of three below 2^62.
  const std::int64_t det =
    suu * (svv * n - sv * sv) - suv * (suv * n - sv * su) + su * (suv * sv - svv * su);
  if (det == 0)
    return none;
  const Eigen::LDLT<Eigen::Matrix3d> ldlt(normal_matrix);
  if (ldlt.info() != Eigen::Success)
    return none;
  const Eigen::Vector3d abc = ldlt.solve(rhs);
  const double a = abc[0], b = abc[1];
  // Disparity at pixel (0, 0): c = own + c0 - a ui - b vi.
  const double c =
    own + abc[2] - a * static_cast<double>(ui) - b * static_cast<double>(vi);
  Eigen::Vector3d normal(a * f, b * f,
                         c + a * calibration_.cx_px + b * calibration_.cy_px);
  const double length = normal.norm();
  if (!(length > 0.0) || !std::isfinite(length))
    return none;
  normal /= length;
  // Toward the camera: the point's line of sight p meets the normal at n . p < 0.
  if (normal.dot(p.cast<double>()) > 0.0)
    normal = -normal;
  return normal.cast<float>();
}

void
estimateDisparityNormals(
  const cv::Mat& disparity,
  const StereoCalibration& calibration,
  const std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>&
    points_camera,
  const DisparityNormalParams& params,
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>& normals)
{
  const DisparityNormalEstimator estimator(disparity, calibration, params);
  normals.resize(points_camera.size());
  for (std::size_t k = 0; k < points_camera.size(); ++k)
    normals[k] = estimator.compute(points_camera[k]);
}

} // namespace planar_grid
