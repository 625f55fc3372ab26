// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::removeOutside(): the rolling window of a long run, in both layers.
#include <planar_grid/map/planar_grid_map.h>

namespace planar_grid {

MapWindowRemoval
PlanarGridMap::removeOutside(const Eigen::AlignedBox3f& keep)
{
  invalidateQueryCache();
  MapWindowRemoval removed;
  const ExplicitSpaceGrid::WindowRemoval space = space_.removeOutside(keep);
  removed.space_blocks = space.blocks;
  removed.space_voxels = space.voxels;
  const SurfaceLayer::WindowRemoval surface = surface_.removeOutside(keep);
  removed.plane_cells = surface.plane_cells;
  removed.planes = surface.planes;
  removed.non_planar_cells = surface.non_planar_cells;
  return removed;
}

} // namespace planar_grid
