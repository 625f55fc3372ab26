// SPDX-License-Identifier: BSD-3-Clause
// SurfaceLayer::removeOutside(): the rolling window of a long run. The planes' raster
// cells and the non-planar cells outside a box go, with the storage they held.
#include <planar_grid/map/surface_layer.h>

#include <tuple>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

SurfaceLayer::WindowRemoval
SurfaceLayer::removeOutside(const Eigen::AlignedBox3f& keep)
{
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  // An empty box (or a NaN bound: every comparison fails) holds no point.
  const auto inside = [&keep](const Eigen::Vector3f& p) {
    return (p.array() >= keep.min().array()).all()
           && (p.array() <= keep.max().array()).all();
  };
  WindowRemoval removed;

  // The planes' raster cells, by the centre of the cell on its refined plane (where
  // its cuboid's face lies).
  std::tie(removed.plane_cells, removed.planes) = impl.removePlaneCellsIf(
    [&inside](const Eigen::Vector3f& centre, const Eigen::Vector3f& /*normal*/) {
      return !inside(centre);
    },
    params_.resolution_m);

  // The non-planar cells, by their centres.
  std::size_t kept = 0;
  for (std::size_t k = 0; k < impl.non_planar.size(); ++k)
    if (inside(impl.non_planar[k].centre))
      impl.non_planar[kept++] = impl.non_planar[k];
  removed.non_planar_cells = impl.non_planar.size() - kept;
  if (removed.non_planar_cells > 0) {
    impl.non_planar.erase(impl.non_planar.begin() + static_cast<std::ptrdiff_t>(kept),
                          impl.non_planar.end());
    impl.non_planar.shrink_to_fit();
    impl.pruneAxes();
  }
  if (removed.plane_cells > 0 || removed.non_planar_cells > 0)
    impl.invalidate();
  return removed;
}

} // namespace planar_grid
