// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/segmentation/terrain_removal.h>

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>
#include <planar_grid/segmentation/impl/terrain_removal.hpp>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_TerrainRemoval(T) \
  template class planar_grid::TerrainRemoval<T>;
PLANAR_GRID_INSTANTIATE(TerrainRemoval, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
