// SPDX-License-Identifier: BSD-3-Clause
// SurfaceLayer::removeOutside(): the rolling window of a long run. The planes' raster
// cells and the non-planar cells outside a box go, with the storage they held.
#include <planar_grid/map/surface_layer.h>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

SurfaceLayer::WindowRemoval
SurfaceLayer::removeOutside(const Eigen::AlignedBox3f& keep)
{
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  const double r = params_.resolution_m;
  // An empty box (or a NaN bound: every comparison fails) holds no point.
  const auto inside = [&keep](const Eigen::Vector3f& p) {
    return (p.array() >= keep.min().array()).all()
           && (p.array() <= keep.max().array()).all();
  };
  WindowRemoval removed;

  // The planes' raster cells, by the centre of the cell on its refined plane (where
  // its cuboid's face lies).
  std::vector<std::uint64_t> keys;
  std::vector<float> sums;
  std::vector<std::uint16_t> counts;
  for (MapPlane& plane : impl.planes) {
    const RasterFrame frame = plane.frame();
    const Eigen::Vector3f n = plane.normal;
    const float d = plane.d;
    keys.clear();
    sums.clear();
    counts.clear();
    std::size_t outside = 0;
    plane.raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t count) {
      const Eigen::Vector3f on_frame =
        frame.cellCentre(rasterCellI(key), rasterCellJ(key), r);
      if (!inside(on_frame - n * (n.dot(on_frame) + d))) {
        ++outside;
        return;
      }
      keys.push_back(key);
      sums.push_back(sum);
      counts.push_back(count);
    });
    if (outside == 0)
      continue;
    removed.plane_cells += outside;
    plane.raster.assign(keys, sums, counts);
    // assign() keeps the evidence arrays' capacity: the memory follows the content.
    plane.raster.probability_sums.shrink_to_fit();
    plane.raster.feature_counts.shrink_to_fit();
    std::vector<RasterRect>().swap(plane.rects);
    plane.dirty = true;
  }
  if (removed.plane_cells > 0) {
    // A plane left without cells goes (later planes' indices shift down); the planes
    // that keep cells keep their fits (moments).
    const std::size_t before = impl.planes.size();
    impl.planes.erase(
      std::remove_if(impl.planes.begin(), impl.planes.end(),
                     [](const MapPlane& p) { return p.raster.empty(); }),
      impl.planes.end());
    removed.planes = before - impl.planes.size();
    if (removed.planes > 0) {
      impl.planes.shrink_to_fit();
      impl.updatePlaneModels();
      impl.plane_models.shrink_to_fit();
    }
  }

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
