// SPDX-License-Identifier: BSD-3-Clause
// SurfaceLayer::removePlaneCells(): planar raster cells removed one by one (the map's
// clearing of the cells a view sees through, PlanarGridMap::clearPlanarCells()).
#include <planar_grid/map/surface_layer.h>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

std::size_t
SurfaceLayer::removePlaneCells(
  const std::function<bool(const Eigen::Vector3f&, const Eigen::Vector3f&)>& remove)
{
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  const double r = params_.resolution_m;
  std::size_t removed = 0;
  bool emptied = false;
  std::vector<std::uint64_t> keep_keys;
  std::vector<float> keep_sums;
  std::vector<std::uint16_t> keep_counts;
  for (MapPlane& plane : impl.planes) {
    const RasterFrame frame = plane.frame();
    const Eigen::Vector3f n = plane.normal;
    const float d = plane.d;
    keep_keys.clear();
    keep_sums.clear();
    keep_counts.clear();
    std::size_t dropped = 0;
    plane.raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t count) {
      // The cell's centre on the frame's plane, projected on the refined plane (where
      // its cuboid's face lies).
      const Eigen::Vector3f on_frame =
        frame.cellCentre(rasterCellI(key), rasterCellJ(key), r);
      const Eigen::Vector3f centre = on_frame - n * (n.dot(on_frame) + d);
      if (remove(centre, n)) {
        ++dropped;
        return;
      }
      keep_keys.push_back(key);
      keep_sums.push_back(sum);
      keep_counts.push_back(count);
    });
    if (dropped == 0)
      continue;
    removed += dropped;
    plane.raster.assign(keep_keys, keep_sums, keep_counts);
    plane.dirty = true;
    emptied = emptied || plane.raster.empty();
  }
  if (removed == 0)
    return 0;
  // A plane left without cells goes; its moments went with the cells' evidence.
  if (emptied) {
    impl.planes.erase(
      std::remove_if(impl.planes.begin(), impl.planes.end(),
                     [](const MapPlane& p) { return p.raster.empty(); }),
      impl.planes.end());
    impl.updatePlaneModels();
  }
  impl.invalidate();
  return removed;
}

} // namespace planar_grid
