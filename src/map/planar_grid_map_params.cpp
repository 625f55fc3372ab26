// SPDX-License-Identifier: BSD-3-Clause
// The declaration of every PlanarGridMap parameter: the map_integration stage, the
// stage reference and the Python keyword arguments are made from it.
#include <planar_grid/map/planar_grid_map.h>

namespace planar_grid {

namespace {

using Params = PlanarGridMap::Params;

ParamDeclarations<Params>
makeParamDeclarations()
{
  namespace space = explicit_space_grid_ranges;
  namespace surface = surface_layer_ranges;
  const auto space_state_name = [](SpaceState state) {
    return toString(state);
  };
  const auto merge_rule_name = [](SurfaceMergeRule rule) {
    return toString(rule);
  };
  return {
    declareReal<Params>(
      "resolution_m", [](auto& p) -> auto& { return p.resolution_m; },
      surface::RESOLUTION, "m", "Minimum cell size of both layers (the paper's 0.1 m).")
      .scalesWithCellSize(),
    declareReal<Params>(
      "max_range_m", [](auto& p) -> auto& { return p.space.max_range_m; },
      space::MAX_RANGE, "m", "Depth up to which a view marks space."),
    declareReal<Params>(
      "surface_margin_m", [](auto& p) -> auto& { return p.space.surface_margin_m; },
      space::SURFACE_MARGIN, "m",
      "Half-thickness of the measured surface; 0: half a voxel diagonal."),
    declareChoice<Params>(
      "prior", [](auto& p) -> auto& { return p.space.prior; }, {"unknown", "free"},
      space_state_name, spaceStateFromString,
      "State of space never inside a view (the paper: free)."),
    declareReal<Params>(
      "thickness_m", [](auto& p) -> auto& { return p.surface.thickness_m; },
      surface::THICKNESS, "m",
      "Extrusion of the map's planar cuboids behind their face.")
      .scalesWithCellSize(),
    declareReal<Params>(
      "plane_merge_angle_rad",
      [](auto& p) -> auto& { return p.surface.plane_merge_angle_rad; },
      surface::PLANE_MERGE_ANGLE, "rad",
      "Largest normal angle between one plane's views."),
    declareReal<Params>(
      "plane_merge_distance_m",
      [](auto& p) -> auto& { return p.surface.plane_merge_distance_m; },
      surface::PLANE_MERGE_DISTANCE, "m",
      "Largest RMS distance of a view's faces (and of the plane's evidence) to the "
      "least-squares plane of both."),
    declareInteger<Params>(
      "close_gaps_cells", [](auto& p) -> auto& { return p.surface.close_gaps_cells; },
      surface::CLOSE_GAPS, "cells",
      "Gaps of up to this many cells between observed cells of a plane's row or column "
      "are filled before the merge; 0: none."),
    declareChoice<Params>(
      "merge_rule", [](auto& p) -> auto& { return p.surface.merge_rule; },
      {"paper", "min_rectangles", "density"}, merge_rule_name,
      surfaceMergeRuleFromString,
      "Cover of a plane's cells: the paper's runs stacked by equal extent (Fig. 6b), "
      "the fewest exact rectangles, or rectangles grown while at least cover_density "
      "of their cells are the plane's (the paper's D_T applied to the merge)."),
    declareReal<Params>(
      "cover_density", [](auto& p) -> auto& { return p.surface.cover_density; },
      surface::COVER_DENSITY, "share",
      "merge_rule density: smallest share of a rectangle's cells observed on the "
      "plane."),
    declareReal<Params>(
      "occupancy_thres", [](auto& p) -> auto& { return p.surface.occupancy_thres; },
      surface::OCCUPANCY_THRES, "probability", "Cells at or above it are occupied."),
    declareReal<Params>(
      "feature_distance_m",
      [](auto& p) -> auto& { return p.surface.feature_distance_m; },
      surface::FEATURE_DISTANCE, "m",
      "A feature counts for a plane cell within this distance."),
    declareFlag<Params>(
      "clear_non_planar", [](auto& p) -> auto& { return p.clear_non_planar; },
      "Remove the non-planar cells a later view sees through (more than half of their "
      "voxels observed free), as OctoMap's misses clear a voxel hit before."),
    declareReal<Params>(
      "non_planar_min_occupied",
      [](auto& p) -> auto& { return p.non_planar_min_occupied; },
      planar_grid_map_ranges::NON_PLANAR_MIN_OCCUPIED, "share",
      "clear_non_planar: also remove a non-planar cell in a view when the space layer "
      "holds fewer than this share of its voxels occupied (free, or behind the surface "
      "from every view); 0: only the free rule."),
    declareFlag<Params>(
      "merge_non_planar", [](auto& p) -> auto& { return p.merge_non_planar; },
      "After each depth image, merge two touching non-planar cells in the view into "
      "their bounding box when the space layer holds at least non_planar_min_occupied "
      "of its voxels occupied and at most half free (off when that share is 0)."),
    declareFlag<Params>(
      "clear_planar", [](auto& p) -> auto& { return p.clear_planar; },
      "Remove the planes' raster cells a later view sees through (the voxel of the "
      "cell and the one behind it observed free): a car that drove away, a door that "
      "opened."),
    declareFlag<Params>(
      "planes_replace_non_planar",
      [](auto& p) -> auto& { return p.planes_replace_non_planar; },
      "Remove the non-planar cells lying on a map plane (centre and footprint within "
      "half a cell of its planar cuboids): the plane represents that surface."),
    declareFlag<Params>(
      "skip_isolated_non_planar",
      [](auto& p) -> auto& { return p.surface.skip_isolated_non_planar; },
      "Leave out of the cuboids a non-planar cell of one voxel that no other cell "
      "touches (none within one cell of its centre): a speckle of stereo noise, as "
      "PCL's RadiusOutlierRemoval drops a lone point. It stays stored, so a neighbour "
      "seen later brings it back."),
    declareInteger<Params>(
      "min_plane_cells", [](auto& p) -> auto& { return p.surface.min_plane_cells; },
      surface::MIN_PLANE_CELLS, "cells",
      "A map plane of fewer observed cells that a frame did not see goes, each of its "
      "cells becoming a non-planar box of one cell: a plane of a cell or two at the "
      "map's cell size is more often a fragment of clutter than a surface, and its "
      "record outweighs its cells. 0: planes are never demoted."),
    declareFlag<Params>(
      "planes_absorb_overlapping",
      [](auto& p) -> auto& { return p.planes_absorb_overlapping; },
      "Move a map plane's rectangles lying on a plane with more evidence (every cell's "
      "face within half a cell of its planar cuboids, or within absorb_distance_m "
      "along the normal of a parallel one) to that plane: a surface found as planes a "
      "few degrees or decimetres apart is covered once."),
    declareReal<Params>(
      "absorb_distance_m", [](auto& p) -> auto& { return p.surface.absorb_distance_m; },
      surface::ABSORB_DISTANCE, "m",
      "planes_absorb_overlapping: largest distance along a stronger parallel plane's "
      "normal at which a plane's cells are that surface seen at another depth (about "
      "twice eq. 4's depth error bound); also the largest gap at which two parallel "
      "planes of comparable evidence, one stacked over the other, merge into one."),
    declareReal<Params>(
      "terrain_plane_tile_m",
      [](auto& p) -> auto& { return p.surface.terrain_plane_tile_m; },
      surface::TERRAIN_PLANE_TILE, "m",
      "Side of the square tiles of the world's x, y plane that bound a level map plane "
      "(normal within 0.3 rad of z): > 0, a level plane joins and merges only with "
      "level planes of its tile and no two level planes absorb each other's cells, so "
      "the terrain stays planar per tile. Left out, it takes ground_removal's "
      "terrain_plane_tile_m. 0: level planes are unbounded."),
    declareReal<Params>(
      "terrain_cover_density",
      [](auto& p) -> auto& { return p.surface.terrain_cover_density; },
      surface::TERRAIN_COVER_DENSITY, "",
      "With terrain_plane_tile_m > 0 and merge_rule density, the cover_density of the "
      "level planes: a road or a floor, seen sparsely, leaves many unobserved cells in "
      "its tiles that a loose cover spans and marks occupied (1: observed cells "
      "only)."),
  };
}

} // namespace

const ParamDeclarations<PlanarGridMap::Params>&
PlanarGridMap::getParamDeclarations()
{
  static const ParamDeclarations<Params> table = makeParamDeclarations();
  return table;
}

} // namespace planar_grid
