// SPDX-License-Identifier: BSD-3-Clause
// DepthErrorFilter's template body: compiled into planar_grid_filters for the point
// types of PLANAR_GRID_POINT_TYPES, and included by depth_error_filter.h for any other
// point type when PCL_NO_PRECOMPILE is defined (as PCL's own impl/*.hpp).
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/depth_error_filter.h>

#include <cmath>
#include <string>

namespace planar_grid {

template <typename PointT>
double
DepthErrorFilter<PointT>::getMaxDepth() const
{
  if (!depth_error_filter_ranges::DISPARITY_ERROR.contains(params_.disparity_error_px))
    throw Exception("DepthErrorFilter: "
                    + paramRangeMessage("disparity_error_px",
                                        depth_error_filter_ranges::DISPARITY_ERROR)
                    + ", got " + formatParamNumber(params_.disparity_error_px));
  if (!depth_error_filter_ranges::MAX_DEPTH_ERROR.contains(params_.max_depth_error_m))
    throw Exception("DepthErrorFilter: "
                    + paramRangeMessage("max_depth_error_m",
                                        depth_error_filter_ranges::MAX_DEPTH_ERROR)
                    + ", got " + formatParamNumber(params_.max_depth_error_m));
  // Eq. 4: Delta z = z^2 Delta d / (B f) <= max  <=>  z <= sqrt(max / Delta z(1 m)).
  const double error_at_1m = calibration_.depthError(1.0, params_.disparity_error_px);
  if (!(std::isfinite(error_at_1m) && error_at_1m > 0.0))
    throw Exception("DepthErrorFilter: the calibration's baseline_m and "
                    "focal_length_px must be finite and positive (got "
                    + formatParamNumber(calibration_.baseline_m) + " m and "
                    + formatParamNumber(calibration_.focal_length_px) + " px)");
  return std::sqrt(params_.max_depth_error_m / error_at_1m);
}

template <typename PointT>
void
DepthErrorFilter<PointT>::applyFilter(pcl::Indices& indices)
{
  const auto max_depth = static_cast<float>(getMaxDepth());
  // The depth along the optical axis: the third row of camera_T_cloud applied to p.
  const Eigen::RowVector4f row = camera_T_cloud_.matrix().row(2);
  const float r0 = row[0], r1 = row[1], r2 = row[2], r3 = row[3];
  const auto& cloud = *this->input_;
  const pcl::Indices& input_indices = *this->indices_;
  const bool negative = this->negative_;
  const bool extract_removed = this->extract_removed_indices_;
  indices.clear();
  auto& removed = *this->removed_indices_;
  removed.clear();
  for (const auto index : input_indices) {
    const PointT& p = cloud[static_cast<std::size_t>(index)];
    const float depth = r0 * p.x + r1 * p.y + r2 * p.z + r3;
    // A non-finite coordinate gives a non-finite depth (NaN, or +-inf).
    if (!std::isfinite(depth)) {
      if (extract_removed)
        removed.push_back(index);
      continue;
    }
    if ((depth > max_depth) == negative)
      indices.push_back(index);
    else if (extract_removed)
      removed.push_back(index);
  }
}

} // namespace planar_grid
