// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/segmentation/terrain_removal.h>

namespace planar_grid {

const ParamDeclarations<TerrainRemovalParams>&
terrainRemovalParamDeclarations()
{
  using P = TerrainRemovalParams;
  namespace ranges = terrain_removal_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "eps_angle_rad", [](auto& p) -> auto& { return p.eps_angle_rad; }, ranges::ANGLE,
      "rad", "Largest angle between the ground normal and the up axis."),
    declareReal<P>(
      "min_sensor_height_m", [](auto& p) -> auto& { return p.min_sensor_height_m; },
      ranges::MIN_SENSOR_HEIGHT, "m",
      "The sensor must be at least this high above the ground plane."),
    declareReal<P>(
      "terrain_max_slope_rad", [](auto& p) -> auto& { return p.terrain_max_slope_rad; },
      ranges::ANGLE, "rad",
      "Largest angle between a terrain plane's normal and the up axis (0: the ground "
      "plane is the only terrain plane)."),
    declareReal<P>(
      "terrain_max_step_m", [](auto& p) -> auto& { return p.terrain_max_step_m; },
      ranges::HEIGHT, "m",
      "Largest step from a terrain plane up to the next (a curb)."),
    declareReal<P>(
      "terrain_height_m", [](auto& p) -> auto& { return p.terrain_height_m; },
      ranges::HEIGHT, "m",
      "Points in no plane up to this height above the terrain are terrain, and a "
      "terrain plane's inliers higher above it than this stay (0: no loose point is "
      "terrain, every inlier is)."),
    declareReal<P>(
      "terrain_cell_m", [](auto& p) -> auto& { return p.terrain_cell_m; },
      ranges::TERRAIN_CELL, "m", "Cell of the terrain height map."),
    declareReal<P>(
      "terrain_plane_tile_m", [](auto& p) -> auto& { return p.terrain_plane_tile_m; },
      ranges::PLANE_TILE, "m",
      "The ground as planar cells: > 0 keeps the terrain planes and the inliers lying "
      "on them, split into square tiles of this side in the world's x, y plane and "
      "each tile's plane refitted to its inliers, so that the approximation makes them "
      "planar cells (the map's terrain cuboids: road, pavement, floor) and a sagging "
      "road is planar per tile; map_integration's terrain_plane_tile_m takes this "
      "value. Only the loose terrain points go. 0: the paper's rule, all terrain "
      "goes."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>
#include <planar_grid/segmentation/impl/terrain_removal.hpp>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
#define PLANAR_GRID_INSTANTIATE_TerrainRemoval(T) \
  template class planar_grid::TerrainRemoval<T>;
PLANAR_GRID_INSTANTIATE(TerrainRemoval, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
