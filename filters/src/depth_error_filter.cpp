// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/filters/depth_error_filter.h>

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/depth_error_filter.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_DepthErrorFilter(T) \
  template class planar_grid::DepthErrorFilter<T>;
PLANAR_GRID_INSTANTIATE(DepthErrorFilter, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
