// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/filters/depth_error_filter.h>

namespace planar_grid {

const ParamDeclarations<DepthErrorFilterParams>&
depthErrorFilterParamDeclarations()
{
  using P = DepthErrorFilterParams;
  namespace ranges = depth_error_filter_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "disparity_error_px", [](auto& p) -> auto& { return p.disparity_error_px; },
      ranges::DISPARITY_ERROR, "px", "Delta d of eq. 4 (the paper's 0.5 px)."),
    declareReal<P>(
      "max_depth_error_m", [](auto& p) -> auto& { return p.max_depth_error_m; },
      ranges::MAX_DEPTH_ERROR, "m",
      "Largest depth error Delta z of a point that is kept."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/depth_error_filter.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_DepthErrorFilter(T) \
  template class planar_grid::DepthErrorFilter<T>;
PLANAR_GRID_INSTANTIATE(DepthErrorFilter, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
