// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/filters/fast_voxel_grid.h>

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_voxel_grid.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_FastVoxelGrid(T) \
  template class planar_grid::FastVoxelGrid<T>;
PLANAR_GRID_INSTANTIATE(FastVoxelGrid, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
