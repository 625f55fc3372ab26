// SPDX-License-Identifier: BSD-3-Clause
// Planar raster cells removed one by one: SurfaceLayer::removePlaneCells() (the map's
// clearing of the cells a view sees through, PlanarGridMap::clearPlanarCells()) and the
// rule they share with the rolling window (SurfaceLayer::removeOutside()), and the
// small planes a frame did not see turned into non-planar boxes (Params::
// min_plane_cells).
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <cstdint>
#include <utility>
#include <vector>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

std::pair<std::size_t, std::size_t>
SurfaceLayer::Impl::removePlaneCellsIf(
  const std::function<bool(const Eigen::Vector3f&, const Eigen::Vector3f&)>& remove,
  double resolution_m)
{
  std::size_t cells = 0;
  std::vector<std::uint64_t> keep_keys;
  std::vector<float> keep_sums;
  std::vector<std::uint16_t> keep_counts;
  for (MapPlane& plane : planes) {
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
        frame.cellCentre(rasterCellI(key), rasterCellJ(key), resolution_m);
      if (remove(on_frame - n * (n.dot(on_frame) + d), n)) {
        ++dropped;
        return;
      }
      keep_keys.push_back(key);
      keep_sums.push_back(sum);
      keep_counts.push_back(count);
    });
    if (dropped == 0)
      continue;
    cells += dropped;
    plane.raster.assign(keep_keys, keep_sums, keep_counts);
    // assign() keeps the evidence array's capacity: the memory follows the content.
    plane.raster.evidence_records.shrink_to_fit();
    std::vector<RasterRect>().swap(plane.rects);
    plane.dirty = true;
  }
  if (cells == 0)
    return {0, 0};
  // the planes that keep cells keep their fits (moments)
  return {cells, erasePlanesWithoutCells()};
}

std::size_t
SurfaceLayer::Impl::erasePlanesWithoutCells()
{
  const std::size_t before = planes.size();
  planes.erase(std::remove_if(planes.begin(), planes.end(),
                              [](const MapPlane& p) { return p.raster.empty(); }),
               planes.end());
  const std::size_t removed = before - planes.size();
  if (removed > 0) {
    tidy_all = true;
    planes.shrink_to_fit();
  }
  return removed;
}

std::size_t
SurfaceLayer::Impl::demoteSmallPlanes(const std::vector<int>& touched,
                                      const Params& params,
                                      std::size_t min_cells)
{
  if (min_cells == 0)
    return 0;
  const auto thickness = static_cast<float>(params.thickness_m);
  std::vector<PlanarCuboid> boxes;
  std::vector<std::pair<std::uint32_t, float>> evidence;
  for (std::size_t p = 0; p < planes.size(); ++p) {
    MapPlane& plane = planes[p];
    if (plane.raster.size() >= min_cells
        || std::binary_search(touched.begin(), touched.end(), static_cast<int>(p)))
      continue;
    const RasterFrame frame = plane.frame();
    const FacePlacement placement(frame, plane.normal);
    plane.raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t count) {
      const std::int32_t i = rasterCellI(key);
      const std::int32_t j = rasterCellJ(key);
      const RasterRect cell{
        i, i + 1, j, j + 1, count > 0 ? sum / static_cast<float>(count) : 0.5f, count};
      PlanarCuboid box =
        rectCuboid(plane, frame, placement, cell, -1, params.resolution_m, thickness);
      box.is_planar = false;
      boxes.push_back(box);
      evidence.emplace_back(count, sum);
    });
    plane.raster = Raster();
  }
  if (boxes.empty())
    return 0;
  const std::size_t removed = erasePlanesWithoutCells();
  std::vector<std::uint32_t> added;
  replaceNonPlanar(boxes, params, added);
  for (std::size_t k = 0; k < added.size(); ++k) {
    NonPlanarCell& cell = non_planar[added[k]];
    cell.feature_count = evidence[k].first;
    cell.probability_sum = evidence[k].second;
  }
  return removed;
}

std::size_t
SurfaceLayer::removePlaneCells(
  const std::function<bool(const Eigen::Vector3f&, const Eigen::Vector3f&)>& remove)
{
  Impl& impl = *impl_;
  std::lock_guard<std::mutex> lock(impl.mutex);
  const std::size_t cells = impl.removePlaneCellsIf(remove, params_.resolution_m).first;
  if (cells > 0)
    impl.invalidate();
  return cells;
}

} // namespace planar_grid
