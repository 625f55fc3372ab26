// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/stereo_calibration.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <sstream>

namespace planar_grid {

void
StereoCalibration::validate(const std::string& source) const
{
  std::ostringstream problem;
  if (!std::isfinite(focal_length_px) || focal_length_px <= 0.0)
    problem << "focal length must be a positive number of pixels, got "
            << focal_length_px;
  else if (!std::isfinite(baseline_m) || baseline_m <= 0.0)
    problem << "baseline must be a positive number of metres, got " << baseline_m;
  else if (baseline_m < MIN_BASELINE_M || baseline_m > MAX_BASELINE_M)
    problem << "the baseline is " << baseline_m << " m, outside [" << MIN_BASELINE_M
            << ", " << MAX_BASELINE_M
            << "] m for a stereo rig (a wrong unit or a corrupt value)";
  else if (!std::isfinite(cx_px) || !std::isfinite(cy_px))
    problem << "principal point must be finite, got (" << cx_px << ", " << cy_px << ")";
  else if (width < 0 || height < 0)
    problem << "image size must not be negative, got " << width << "x" << height;
  if (!problem.str().empty())
    throw IOError(source + ": invalid stereo calibration: " + problem.str());
}

std::string
StereoCalibration::principalPointWarning(int width_px,
                                         int height_px,
                                         const std::string& source) const
{
  if (width_px <= 0 || height_px <= 0)
    return {};
  const double off_x = std::abs(cx_px - 0.5 * width_px) / width_px;
  const double off_y = std::abs(cy_px - 0.5 * height_px) / height_px;
  if (!(off_x > MAX_PRINCIPAL_POINT_OFFSET || off_y > MAX_PRINCIPAL_POINT_OFFSET))
    return {};
  std::ostringstream text;
  text.precision(4);
  text << source << ": the principal point (" << cx_px << ", " << cy_px << ") px lies "
       << std::lround(100.0 * std::max(off_x, off_y)) << " % of the image's "
       << (off_y > off_x ? "height" : "width") << " from the centre of the " << width_px
       << "x" << height_px
       << " px images; rectification keeps it near the centre: is it the calibration "
          "of these images (not of another crop, e.g. P1 rather than P1_roi)?";
  return text.str();
}

double
StereoCalibration::depthFromDisparity(double disparity_px) const
{
  if (disparity_px <= 0.0)
    return std::numeric_limits<double>::infinity();
  return focal_length_px * baseline_m / disparity_px;
}

double
StereoCalibration::depthError(double depth_m, double disparity_error_px) const
{
  return depth_m * depth_m / (baseline_m * focal_length_px) * disparity_error_px;
}

} // namespace planar_grid
