// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/filters/fast_voxel_grid.h>

namespace planar_grid {

const ParamDeclarations<FastVoxelGridParams>&
fastVoxelGridParamDeclarations()
{
  using P = FastVoxelGridParams;
  namespace ranges = fast_voxel_grid_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "leaf_size_m", [](auto& p) -> auto& { return p.leaf_size_m; }, ranges::LEAF_SIZE,
      "m", "Voxel edge length.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "min_points_per_voxel", [](auto& p) -> auto& { return p.min_points_per_voxel; },
      ranges::MIN_POINTS_PER_VOXEL, "",
      "Voxels with fewer points are dropped (1 keeps every voxel)."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_voxel_grid.hpp>
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_FastVoxelGrid(T) \
  template class planar_grid::FastVoxelGrid<T>;
PLANAR_GRID_INSTANTIATE(FastVoxelGrid, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
