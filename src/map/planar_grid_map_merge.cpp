// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::merge(): another recording's map joins this one, layer by layer.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <string>

#include "map_merge_transform.h"

namespace planar_grid {

void
PlanarGridMap::merge(const PlanarGridMap& other, const Eigen::Isometry3d& this_T_other)
{
  if (&other == this)
    throw Exception("PlanarGridMap::merge: a map cannot be merged into itself");
  map_merge::checkRigid(this_T_other, "PlanarGridMap::merge");
  // Every check before the first change: the surface layer checks its parameters
  // before it changes anything, and the space layer's (resolution, prior) are
  // checked here, so that a refused merge leaves the map as it was.
  const std::string differences =
    map_merge::difference("resolution_m", params_.resolution_m,
                          other.params_.resolution_m, "m")
    + map_merge::difference("prior", toString(params_.space.prior),
                            toString(other.params_.space.prior), "");
  if (!differences.empty())
    throw Exception("PlanarGridMap::merge: the maps' parameters must be equal, but "
                    + differences);
  invalidateQueryCache();
  try {
    surface_.merge(other.surface_, this_T_other);
  } catch (const Exception& e) {
    throw Exception(std::string("PlanarGridMap::merge: ") + e.what());
  }
  space_.merge(other.space_, this_T_other);
  // The tidying integrateSurface() does after a frame, for the planes that met.
  if (params_.planes_absorb_overlapping)
    surface_.absorbOverlappingPlaneCells();
  if (params_.planes_replace_non_planar)
    surface_.removeNonPlanarCellsOnPlanes();
}

} // namespace planar_grid
