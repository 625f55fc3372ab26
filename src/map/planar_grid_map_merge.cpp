// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::merge(): another recording's map joins this one, layer by layer.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <algorithm>
#include <cmath>
#include <string>

#include "map_merge_transform.h"

namespace planar_grid {

void
PlanarGridMap::noteObservationOrder(double order)
{
  if (!std::isfinite(order))
    throw Exception(
      "PlanarGridMap::noteObservationOrder: the order key must be finite");
  observation_span_.first = std::min(observation_span_.first, order);
  observation_span_.last = std::max(observation_span_.last, order);
}

void
PlanarGridMap::setObservationSpan(const ObservationSpan& span)
{
  if (!span.empty() && !(std::isfinite(span.first) && std::isfinite(span.last)))
    throw Exception("PlanarGridMap::setObservationSpan: the bounds must be finite");
  observation_span_ = span.empty() ? ObservationSpan() : span;
}

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
  // The newer map's observations win where one map's views all came after the
  // other's; spans that overlap (or are unknown) leave no newer map to follow.
  const ObservationSpan& mine = observation_span_;
  const ObservationSpan& theirs = other.observation_span_;
  auto order = ExplicitSpaceGrid::MergeOrder::UNORDERED;
  if (!mine.empty() && !theirs.empty()) {
    if (theirs.first > mine.last)
      order = ExplicitSpaceGrid::MergeOrder::OTHER_IS_NEWER;
    else if (mine.first > theirs.last)
      order = ExplicitSpaceGrid::MergeOrder::THIS_IS_NEWER;
  }
  space_.merge(other.space_, this_T_other, order);
  if (!theirs.empty()) {
    observation_span_.first = std::min(mine.first, theirs.first);
    observation_span_.last = std::max(mine.last, theirs.last);
  }
  // The tidying integrateSurface() does after a frame, for the planes that met.
  if (params_.planes_absorb_overlapping)
    surface_.absorbOverlappingPlaneCells();
  if (params_.planes_replace_non_planar)
    surface_.removeNonPlanarCellsOnPlanes();
}

} // namespace planar_grid
