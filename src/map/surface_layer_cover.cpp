// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's cover: each map plane's raster closed over gaps, its cells'
// occupancy, the rectangles of the merge rule (planar_grid/surface/rectangle_merge.h)
// and their cuboids.
#include <planar_grid/map/surface_layer.h>
#include <planar_grid/surface/rectangle_merge.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

namespace {

/** \brief A plane's cells for its cover: the raster's cells and those the gap
 * closing adds, sorted by key, each with its feature count and occupancy (the
 * features' mean; NaN for a featureless or filled cell). */
struct CoverCells {
  std::vector<std::uint64_t> keys;
  std::vector<float> value;
  std::vector<std::uint32_t> count;
};

/** \brief The cells of \a raster and those closeRasterGaps() fills, with their
 * evidence. */
CoverCells
coverCells(const Raster& raster, int close_gaps_cells)
{
  // the raster's cells, sorted, with their evidence
  std::vector<std::uint64_t> observed;
  std::vector<float> sums;
  std::vector<std::uint16_t> counts;
  raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t features) {
    observed.push_back(key);
    sums.push_back(sum);
    counts.push_back(features);
  });
  const std::vector<std::uint64_t> filled = closeRasterGaps(observed, close_gaps_cells);
  const std::size_t n = observed.size() + filled.size();
  CoverCells cells;
  cells.keys.reserve(n);
  cells.value.reserve(n);
  cells.count.reserve(n);
  for (std::size_t a = 0, b = 0; a < observed.size() || b < filled.size();) {
    if (b == filled.size() || (a < observed.size() && observed[a] < filled[b])) {
      cells.keys.push_back(observed[a]);
      const std::uint32_t features = counts[a];
      cells.count.push_back(features);
      cells.value.push_back(
        features > 0 ? static_cast<float>(static_cast<double>(sums[a]) / features)
                     : std::numeric_limits<float>::quiet_NaN());
      ++a;
    } else {
      cells.keys.push_back(filled[b++]);
      cells.count.push_back(0);
      cells.value.push_back(std::numeric_limits<float>::quiet_NaN());
    }
  }
  return cells;
}

/** \brief The 8 neighbours of each of the sorted cells \a keys (row below, same row,
 * row above; by column), -1 when absent, by one sweep over the rows with a pointer
 * into the row below and the row above. */
std::vector<std::array<std::ptrdiff_t, 8>>
cellNeighbours(const std::vector<std::uint64_t>& keys)
{
  const std::size_t n = keys.size();
  std::vector<std::array<std::ptrdiff_t, 8>> neighbours(n);
  for (std::size_t start = 0; start < n;) {
    const std::int64_t j = rasterCellJ(keys[start]);
    std::size_t end = start;
    while (end < n && rasterCellJ(keys[end]) == j)
      ++end;
    // rows j - 1 and j + 1: [lo, hi) ranges, empty when absent
    std::size_t below_lo = start, below_hi = start, above_lo = end, above_hi = end;
    if (start > 0 && rasterCellJ(keys[start - 1]) == j - 1) {
      below_hi = start;
      below_lo = start - 1;
      while (below_lo > 0 && rasterCellJ(keys[below_lo - 1]) == j - 1)
        --below_lo;
    }
    if (end < n && rasterCellJ(keys[end]) == j + 1) {
      above_hi = end;
      while (above_hi < n && rasterCellJ(keys[above_hi]) == j + 1)
        ++above_hi;
    }
    std::size_t pb = below_lo, pa = above_lo;
    for (std::size_t k = start; k < end; ++k) {
      const std::int64_t i = rasterCellI(keys[k]);
      const auto find3 = [&](std::size_t& p, std::size_t hi, std::ptrdiff_t* out) {
        while (p < hi && rasterCellI(keys[p]) < i - 1)
          ++p;
        for (std::int64_t di = -1; di <= 1; ++di) {
          std::ptrdiff_t found = -1;
          for (std::size_t q = p; q < hi && q <= p + 2; ++q)
            if (rasterCellI(keys[q]) == i + di)
              found = static_cast<std::ptrdiff_t>(q);
          out[di + 1] = found;
        }
      };
      std::array<std::ptrdiff_t, 8>& nb = neighbours[k];
      find3(pb, below_hi, nb.data());
      nb[3] = (k > start && rasterCellI(keys[k - 1]) == i - 1)
                ? static_cast<std::ptrdiff_t>(k - 1)
                : -1;
      nb[4] = (k + 1 < end && rasterCellI(keys[k + 1]) == i + 1)
                ? static_cast<std::ptrdiff_t>(k + 1)
                : -1;
      find3(pa, above_hi, nb.data() + 5);
    }
    start = end;
  }
  return neighbours;
}

/** \brief Occupancy of the cells without a value (paper, end of III-F): featureless
 * and filled cells take the mean of their valued 8-neighbours, layer by layer
 * outward; unreachable cells 0.5. \a keys: the sorted cells, \a count: their
 * feature counts. */
void
propagateOccupancy(const std::vector<std::uint64_t>& keys,
                   const std::vector<std::uint32_t>& count,
                   std::vector<float>& value)
{
  const std::size_t n = keys.size();
  std::size_t valued_cells = 0;
  for (std::size_t k = 0; k < n; ++k)
    valued_cells += count[k] > 0 ? 1 : 0;
  // neighbours only matter when valued and featureless cells coexist
  if (valued_cells > 0 && valued_cells < n) {
    const std::vector<std::array<std::ptrdiff_t, 8>> neighbours = cellNeighbours(keys);
    std::vector<std::size_t> layer, next;
    for (std::size_t k = 0; k < n; ++k)
      if (std::isnan(value[k]))
        for (const auto nb : neighbours[k])
          if (nb >= 0 && !std::isnan(value[static_cast<std::size_t>(nb)])) {
            layer.push_back(k);
            break;
          }
    std::vector<float> layer_values;
    std::vector<std::uint8_t> queued(n, 0);
    for (const auto k : layer)
      queued[k] = 1;
    while (!layer.empty()) {
      layer_values.assign(layer.size(), 0.0f);
      for (std::size_t l = 0; l < layer.size(); ++l) {
        double sum = 0.0;
        int valued = 0;
        for (const auto nb : neighbours[layer[l]])
          if (nb >= 0 && !std::isnan(value[static_cast<std::size_t>(nb)])) {
            sum += value[static_cast<std::size_t>(nb)];
            ++valued;
          }
        layer_values[l] = static_cast<float>(sum / valued);
      }
      for (std::size_t l = 0; l < layer.size(); ++l)
        value[layer[l]] = layer_values[l];
      next.clear();
      for (const auto k : layer)
        for (const auto nb : neighbours[k])
          if (nb >= 0 && std::isnan(value[static_cast<std::size_t>(nb)])
              && queued[static_cast<std::size_t>(nb)] == 0) {
            queued[static_cast<std::size_t>(nb)] = 1;
            next.push_back(static_cast<std::size_t>(nb));
          }
      std::swap(layer, next);
    }
  }
  for (auto& v : value)
    if (std::isnan(v))
      v = 0.5f;
}

/** \brief The plane's rectangles from the cover: each rectangle's mean probability
 * and feature count over the cells it holds. */
void
coverRectangles(const std::vector<RasterRectangle>& cover,
                const CoverCells& cells,
                MapPlane& plane)
{
  const std::vector<std::uint64_t>& keys = cells.keys;
  const std::size_t n = keys.size();
  plane.rects.reserve(cover.size());
  for (const RasterRectangle& rect : cover) {
    double sum = 0.0;
    std::uint64_t features = 0, held = 0;
    for (std::int64_t j = rect.j0; j < rect.j1; ++j) {
      auto k = static_cast<std::size_t>(
        std::lower_bound(keys.begin(), keys.end(),
                         rasterCellKey(rect.i0, static_cast<std::int32_t>(j)))
        - keys.begin());
      // the DENSITY cover may hold unobserved cells: only the raster's count
      for (; k < n && rasterCellJ(keys[k]) == j && rasterCellI(keys[k]) < rect.i1;
           ++k) {
        sum += cells.value[k];
        features += cells.count[k];
        ++held;
      }
    }
    plane.rects.push_back(
      RasterRect{rect.i0, rect.i1, rect.j0, rect.j1,
                 static_cast<float>(held > 0 ? sum / static_cast<double>(held) : 0.5),
                 static_cast<std::uint32_t>(std::min<std::uint64_t>(
                   features, std::numeric_limits<std::uint32_t>::max()))});
  }
}

/** \brief Rebuilds the cover of one plane: the gap closing, the occupancy per cell
 * (features' mean, else the propagated neighbours' mean, else 0.5), then the cover of
 * Params::merge_rule over cells of one occupancy class, with each rectangle's mean
 * probability and feature count, sorted by first row, then first column. */
void
rebuildPlane(MapPlane& plane, const SurfaceLayer::Params& params)
{
  std::vector<RasterRect>().swap(plane.rects);
  plane.dirty = false;
  plane.tidy_pending = true;
  if (plane.raster.empty())
    return;
  CoverCells cells = coverCells(plane.raster, params.close_gaps_cells);
  propagateOccupancy(cells.keys, cells.count, cells.value);
  const std::size_t n = cells.keys.size();
  std::vector<std::uint8_t> cls(n);
  for (std::size_t k = 0; k < n; ++k)
    cls[k] = cells.value[k] >= params.occupancy_thres ? 1 : 0;
  // With terrain tiles, the level planes (road, pavement, floor) take their own
  // density: their rasters hold many unobserved cells that a loose cover would span.
  const bool level_tile =
    params.terrain_plane_tile_m > 0.0 && isLevel(plane.normal.z());
  std::vector<RasterRectangle> cover = mergeRasterRectangles(
    cells.keys, cls, params.merge_rule,
    level_tile ? params.terrain_cover_density : params.cover_density);
  std::sort(cover.begin(), cover.end(),
            [](const RasterRectangle& a, const RasterRectangle& b) {
              return a.j0 != b.j0 ? a.j0 < b.j0 : a.i0 < b.i0;
            });
  coverRectangles(cover, cells, plane);
}

} // namespace

namespace surface_layer_detail {

PlanarCuboid
rectCuboid(const MapPlane& plane,
           const RasterFrame& frame,
           const FacePlacement& placement,
           const RasterRect& rect,
           int plane_id,
           double r,
           float thickness)
{
  // In double: corrupt (but accepted) raster keys near the int range must not
  // overflow.
  const double u_mid = 0.5 * (static_cast<double>(rect.i0) + rect.i1) * r;
  const double v_mid = 0.5 * (static_cast<double>(rect.j0) + rect.j1) * r;
  const Eigen::Vector3f on_frame = frame.origin
                                   + frame.u_axis * static_cast<float>(u_mid)
                                   + frame.v_axis * static_cast<float>(v_mid);
  const Eigen::Vector3f on_plane =
    on_frame - plane.normal * (plane.normal.dot(on_frame) + plane.d);
  PlanarCuboid c;
  c.normal = plane.normal;
  c.horizontal_axis = placement.place_u;
  c.width_m = static_cast<float>((static_cast<double>(rect.i1) - rect.i0) * r
                                 * placement.scale_u);
  c.height_m = static_cast<float>((static_cast<double>(rect.j1) - rect.j0) * r
                                  * placement.scale_v);
  c.thickness_m = thickness;
  c.centre = on_plane - plane.normal * (0.5f * thickness);
  c.plane_id = plane_id;
  c.point_count = rect.point_count;
  c.is_planar = true;
  c.probability = rect.probability;
  return c;
}

} // namespace surface_layer_detail

/** \brief Rebuilds the covers of the planes changed since; caller holds the mutex. */
void
SurfaceLayer::Impl::ensureCovers(const Params& params)
{
  for (auto& plane : planes)
    if (plane.dirty)
      rebuildPlane(plane, params);
}

/** \brief Appends every plane's rectangles, then the non-planar cells but the isolated
 * ones (ensureIsolated()); caller holds the mutex. */
void
SurfaceLayer::Impl::buildCuboids(const Params& params, PlanarCuboids& out)
{
  ensureCovers(params);
  std::size_t total = non_planar.size();
  for (const auto& plane : planes)
    total += plane.rects.size();
  out.reserve(out.size() + total);
  buildPlanarCuboids(params, out);
  ensureIsolated(params);
  std::size_t next_isolated = 0;
  for (std::size_t k = 0; k < non_planar.size(); ++k) {
    if (next_isolated < isolated.size() && isolated[next_isolated] == k) {
      ++next_isolated;
      continue;
    }
    const NonPlanarCell& cell = non_planar[k];
    PlanarCuboid c = nonPlanarCuboid(cell);
    c.probability = cell.feature_count > 0
                      ? static_cast<float>(cell.probability_sum / cell.feature_count)
                      : 0.5f;
    c.point_count = cell.feature_count;
    out.push_back(c);
  }
}

void
SurfaceLayer::Impl::buildPlanarCuboids(const Params& params, PlanarCuboids& out)
{
  ensureCovers(params);
  const auto thickness = static_cast<float>(params.thickness_m);
  for (std::size_t p = 0; p < planes.size(); ++p) {
    const MapPlane& plane = planes[p];
    if (plane.rects.empty())
      continue;
    const RasterFrame frame = plane.frame();
    const FacePlacement placement(frame, plane.normal);
    for (const RasterRect& rect : plane.rects)
      out.push_back(rectCuboid(plane, frame, placement, rect, static_cast<int>(p),
                               params.resolution_m, thickness));
  }
}

} // namespace planar_grid
