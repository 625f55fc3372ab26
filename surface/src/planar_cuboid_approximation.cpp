// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/surface/planar_cuboid_approximation.h>

namespace planar_grid {

const ParamDeclarations<PlanarCuboidApproximationParams>&
planarCuboidApproximationParamDeclarations()
{
  using P = PlanarCuboidApproximationParams;
  namespace ranges = planar_cuboid_approximation_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "min_cell_size_m", [](auto& p) -> auto& { return p.min_cell_size_m; },
      ranges::MIN_CELL_SIZE, "m",
      "Smallest cell side and raster resolution (the paper's minimum grid).")
      .scalesWithCellSize(),
    declareReal<P>(
      "density_threshold", [](auto& p) -> auto& { return p.density_threshold; },
      ranges::DENSITY_THRESHOLD, "",
      "D_T: a unit whose occupied-area fraction D is below it is split."),
    declareReal<P>(
      "non_planar_density_threshold",
      [](auto& p) -> auto& { return p.non_planar_density_threshold; },
      ranges::NON_PLANAR_DENSITY_THRESHOLD, "",
      "Occupied share of its 3D lattice a non-planar box (Fig. 7) must reach before it "
      "stops splitting (0: density_threshold)."),
    declareReal<P>(
      "min_width_m", [](auto& p) -> auto& { return p.min_width_m; }, ranges::MIN_WIDTH,
      "m", "W_T: a unit is split only while wider than this.")
      .scalesWithCellSize(),
    declareReal<P>(
      "min_height_m", [](auto& p) -> auto& { return p.min_height_m; },
      ranges::MIN_HEIGHT, "m", "H_T: a unit is split only while higher than this.")
      .scalesWithCellSize(),
    declareReal<P>(
      "thickness_m", [](auto& p) -> auto& { return p.thickness_m; }, ranges::THICKNESS,
      "m", "Extrusion behind the surface along the normal.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "min_points_per_cell", [](auto& p) -> auto& { return p.min_points_per_cell; },
      ranges::MIN_POINTS_PER_CELL, "", "Cells with fewer points are dropped."),
  };
  return table;
}

} // namespace planar_grid

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>
#include <planar_grid/surface/impl/planar_cuboid_approximation.hpp>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
PLANAR_GRID_INSTANTIATE(PlanarCuboidApproximation, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
