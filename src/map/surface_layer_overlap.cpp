// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's overlapping planes: a map plane's rectangles that lie on a
// plane with more evidence move to that plane.
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <mutex>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

namespace {

/** \brief True when the axis-aligned bounds of \a a and \a b, each grown by \a grow
 * (meters), intersect. */
bool
boundsMeet(const PlanarCuboid& a, const PlanarCuboid& b, float grow)
{
  Eigen::Vector3f a_lo, a_hi, b_lo, b_hi;
  cuboidBounds(a, a_lo, a_hi);
  cuboidBounds(b, b_lo, b_hi);
  return ((a_lo.array() - grow) <= (b_hi.array() + grow)).all()
         && ((b_lo.array() - grow) <= (a_hi.array() + grow)).all();
}

/** \brief True when \a point lies in \a c grown by \a lateral (meters) along its face
 * axes and by \a along (meters) along its normal. */
bool
holds(const PlanarCuboid& c, const Eigen::Vector3f& point, float lateral, float along)
{
  const Eigen::Vector3f d = point - c.centre;
  return std::abs(d.dot(c.horizontal_axis)) <= 0.5f * c.width_m + lateral
         && std::abs(d.dot(c.verticalAxis())) <= 0.5f * c.height_m + lateral
         && std::abs(d.dot(c.normal)) <= 0.5f * c.thickness_m + along;
}

/** \brief The surface layer's planes. */
using MapPlanes = std::vector<MapPlane, Eigen::aligned_allocator<MapPlane>>;

/** \brief A cell of a plane's raster moving to a stronger plane. */
struct CellMove {
  std::uint64_t key;
  std::uint32_t to;
  Eigen::Vector3f face; // the cell's face centre
  std::int32_t i, j;    // the cell in its plane's raster
};

/** \brief The distances of one absorption, meters (and the parallel test's cosine). */
struct AbsorbRule {
  double r;
  float half_cell;
  /** \brief Along the normal of a parallel plane: one surface seen at another depth. */
  float along_parallel;
  float cos_parallel;
  /** \brief Bin edge of the candidate sweep (8 cells). */
  float bin;
  float thickness;
};

using CuboidPairs = std::vector<std::pair<std::uint32_t, std::uint32_t>>;

/** \brief Candidate pairs (rectangle x, cuboid y of a stronger plane) whose bounds,
 * grown by half a cell or absorb_distance_m, meet and one of whose planes changed:
 * one sweep over the bins (8 cells) that a changed plane's cuboid meets, the cuboids
 * spanning too many bins paired with all. Sorted by rectangle, then its candidates'
 * planes strongest first (then index). Two level planes' cuboids are never paired. */
template <typename Stronger>
CuboidPairs
candidatePairs(const PlanarCuboids& planar,
               const std::vector<bool>& changed,
               const std::vector<bool>& level,
               const Stronger& stronger,
               const AbsorbRule& rule)
{
  std::vector<BinEntry> bins;
  std::vector<std::uint32_t> large;
  binCuboidsNearHot(
    planar, rule.along_parallel, rule.bin,
    [&](std::size_t k) {
      return changed[static_cast<std::size_t>(planar[k].plane_id)];
    },
    bins, large);
  CuboidPairs pairs;
  const auto pair = [&](std::uint32_t x, std::uint32_t y) {
    const auto a = static_cast<std::size_t>(planar[x].plane_id);
    const auto b = static_cast<std::size_t>(planar[y].plane_id);
    if (a != b && (changed[a] || changed[b]) && stronger(b, a)
        && !(level[a] && level[b])
        && boundsMeet(planar[x], planar[y], rule.along_parallel))
      pairs.emplace_back(x, y);
  };
  // (a bin without a cuboid of a changed plane has no pair; two level planes' cuboids
  // pair with the bin's other planes' only). Two cuboids share every bin of the
  // overlap of their bin ranges: the pair is taken in the first of them only (its
  // indices the larger of the two lower bin indices per axis), not once per shared
  // bin.
  std::vector<Eigen::Vector3d> low_bin(planar.size());
  for (const BinEntry& entry : bins) {
    Eigen::Vector3d last;
    binRange(planar[entry.index], rule.along_parallel, rule.bin, low_bin[entry.index],
             last);
  }
  const auto firstShared = [&](std::uint32_t x, std::uint32_t y, std::uint64_t key) {
    const Eigen::Vector3d first = low_bin[x].cwiseMax(low_bin[y]);
    return binKey(static_cast<std::int64_t>(first.x()),
                  static_cast<std::int64_t>(first.y()),
                  static_cast<std::int64_t>(first.z()))
           == key;
  };
  std::vector<std::uint32_t> not_level;
  for (std::size_t s = 0; s < bins.size();) {
    std::size_t e = s;
    bool any_changed = false;
    not_level.clear();
    for (; e < bins.size() && bins[e].key() == bins[s].key(); ++e) {
      const auto p = static_cast<std::size_t>(planar[bins[e].index].plane_id);
      any_changed = any_changed || changed[p];
      if (!level[p])
        not_level.push_back(bins[e].index);
    }
    const std::uint64_t key = bins[s].key();
    for (std::size_t x = s; any_changed && x < e; ++x) {
      const std::uint32_t i = bins[x].index;
      if (level[static_cast<std::size_t>(planar[i].plane_id)]) {
        for (const std::uint32_t y : not_level)
          if (firstShared(i, y, key))
            pair(i, y);
        continue;
      }
      for (std::size_t y = s; y < e; ++y)
        if (firstShared(i, bins[y].index, key))
          pair(i, bins[y].index);
    }
    s = e;
  }
  for (const auto l : large)
    for (std::uint32_t k = 0; k < planar.size(); ++k) {
      pair(l, k);
      pair(k, l);
    }
  std::sort(pairs.begin(), pairs.end(), [&](const auto& p, const auto& q) {
    if (p.first != q.first)
      return p.first < q.first;
    const auto pp = static_cast<std::size_t>(planar[p.second].plane_id);
    const auto qp = static_cast<std::size_t>(planar[q.second].plane_id);
    if (pp != qp)
      return stronger(pp, qp);
    return p.second < q.second;
  });
  pairs.erase(std::unique(pairs.begin(), pairs.end()), pairs.end());
  return pairs;
}

/** \brief One rectangle of a plane against the cuboids of its candidate planes: which
 * of its observed cells lie wholly on a stronger plane (the cell's face centre and
 * corners within half a cell of one stronger plane's cuboids, or within
 * absorb_distance_m along the normal of a parallel one). */
class RectangleLanding {
public:
  /** \brief Where an observed cell lands: the plane (-1 for none), its face centre,
   * and whether the plane is parallel. */
  struct Landing {
    int plane;
    Eigen::Vector3f face;
    bool parallel;
  };

  RectangleLanding(const MapPlanes& planes,
                   const PlanarCuboids& planar,
                   const PlanarCuboid& rect_cuboid,
                   const RasterRect& rect,
                   const std::vector<std::uint32_t>& candidates,
                   const AbsorbRule& rule) :
      planes_(planes),
      planar_(planar), rect_cuboid_(rect_cuboid), rect_(rect), candidates_(candidates),
      rule_(rule), plane_(planes[static_cast<std::size_t>(rect_cuboid.plane_id)]),
      frame_(plane_.frame()), placement_(frame_, plane_.normal)
  {}

  /** \brief Parallel and facing the same way (the map's normals point toward the
   * sensors that saw the plane): the two faces of a thin wall stay apart. */
  bool parallelTo(int b) const
  {
    return planes_[static_cast<std::size_t>(b)].normal.dot(plane_.normal)
           >= rule_.cos_parallel;
  }

  bool anyParallel() const
  {
    return std::any_of(candidates_.begin(), candidates_.end(), [&](std::uint32_t e) {
      return parallelTo(planar_[e].plane_id);
    });
  }

  bool observed(std::int32_t i, std::int32_t j) const
  {
    return plane_.raster.contains(rasterCellKey(i, j));
  }

  /** \brief The first (strongest) candidate plane whose cuboids hold the face centre
   * and four face corners of cell (i, j). */
  Landing lyingOn(std::int32_t i, std::int32_t j) const
  {
    const PlanarCuboid cell =
      rectCuboid(plane_, frame_, placement_, RasterRect{i, i + 1, j, j + 1, 0.5f, 0},
                 rect_cuboid_.plane_id, rule_.r, rule_.thickness);
    const Eigen::Vector3f face = cell.faceCentre();
    const Eigen::Vector3f du = 0.5f * cell.width_m * cell.horizontal_axis;
    const Eigen::Vector3f dv = 0.5f * cell.height_m * cell.verticalAxis();
    const std::array<Eigen::Vector3f, 5> points = {face, face - du - dv, face + du - dv,
                                                   face + du + dv, face - du + dv};
    for (std::size_t c = 0; c < candidates_.size();) {
      const int b = planar_[candidates_[c]].plane_id;
      std::size_t end = c;
      while (end < candidates_.size() && planar_[candidates_[end]].plane_id == b)
        ++end;
      const bool parallel = parallelTo(b);
      const auto held = [&](const Eigen::Vector3f& q) {
        for (std::size_t e = c; e < end; ++e)
          if (holds(planar_[candidates_[e]], q, rule_.half_cell,
                    parallel ? rule_.along_parallel : rule_.half_cell))
            return true;
        return false;
      };
      if (std::all_of(points.begin(), points.end(), held))
        return {b, face, parallel};
      c = end;
    }
    return {-1, face, false};
  }

  /** \brief The bounds of the rectangle's observed cells, [i0, i1) x [j0, j1); false
   * when it has none. */
  bool observedBounds(std::int32_t& i0,
                      std::int32_t& i1,
                      std::int32_t& j0,
                      std::int32_t& j1) const
  {
    const auto lineObserved = [&](bool row, std::int32_t at) {
      return anyOnLine(row, at, row ? rect_.i0 : rect_.j0, row ? rect_.i1 : rect_.j1,
                       [&](std::int32_t i, std::int32_t j) { return observed(i, j); });
    };
    j0 = rect_.j0;
    j1 = rect_.j1;
    while (j0 < j1 && !lineObserved(true, j0))
      ++j0;
    if (j0 == j1)
      return false;
    while (!lineObserved(true, j1 - 1))
      --j1;
    i0 = rect_.i0;
    i1 = rect_.i1;
    while (!lineObserved(false, i0))
      ++i0;
    while (!lineObserved(false, i1 - 1))
      --i1;
    return true;
  }

  /** \brief Whether every observed cell of row (\a row) or column \a at, from \a from
   * to \a to (exclusive), lands on a stronger plane. */
  bool lineMoves(bool row, std::int32_t at, std::int32_t from, std::int32_t to) const
  {
    return !anyOnLine(row, at, from, to, [&](std::int32_t i, std::int32_t j) {
      return observed(i, j) && lyingOn(i, j).plane < 0;
    });
  }

private:
  /** \brief Whether \a pred(i, j) holds for a cell of row \a at (row) or column \a at
   * from \a from to \a to (exclusive). */
  template <typename Pred>
  static bool anyOnLine(bool row,
                        std::int32_t at,
                        std::int32_t from,
                        std::int32_t to,
                        const Pred& pred)
  {
    for (std::int32_t t = from; t < to; ++t)
      if (row ? pred(t, at) : pred(at, t))
        return true;
    return false;
  }

  const MapPlanes& planes_;
  const PlanarCuboids& planar_;
  const PlanarCuboid& rect_cuboid_;
  const RasterRect& rect_;
  const std::vector<std::uint32_t>& candidates_;
  const AbsorbRule& rule_;
  const MapPlane& plane_;
  const RasterFrame frame_;
  const FacePlacement placement_;
};

/** \brief The observed cells of one rectangle that move to stronger planes, appended
 * to \a moves: those lying wholly on one when the rest of the rectangle stays one
 * rectangle, or, all moving to parallel planes, when they are every observed cell
 * within their own bounds. \a rect_moves is scratch. */
void
rectangleMoves(const RectangleLanding& landing,
               std::vector<CellMove>& rect_moves,
               std::vector<CellMove>& moves)
{
  std::int32_t oi0 = 0, oi1 = 0, oj0 = 0, oj1 = 0;
  if (!landing.observedBounds(oi0, oi1, oj0, oj1))
    return;
  // The observed cells that move lie outside the bounds of those that stay, so if any
  // moves, every observed cell of the first or last observed row or column does: test
  // those four lines first (up to the first cell that stays). Cells moving to
  // parallel planes may also be a rectangle inside: see below.
  if (!landing.anyParallel() && !landing.lineMoves(true, oj0, oi0, oi1)
      && !landing.lineMoves(true, oj1 - 1, oi0, oi1)
      && !landing.lineMoves(false, oi0, oj0, oj1)
      && !landing.lineMoves(false, oi1 - 1, oj0, oj1))
    return;
  rect_moves.clear();
  bool all_parallel = true;
  // the bounds of the observed cells that stay
  std::int32_t ki0 = oi1, ki1 = oi0, kj0 = oj1, kj1 = oj0;
  for (std::int32_t j = oj0; j < oj1; ++j)
    for (std::int32_t i = oi0; i < oi1; ++i) {
      if (!landing.observed(i, j))
        continue;
      const RectangleLanding::Landing l = landing.lyingOn(i, j);
      if (l.plane >= 0) {
        all_parallel = all_parallel && l.parallel;
        rect_moves.push_back(CellMove{
          rasterCellKey(i, j), static_cast<std::uint32_t>(l.plane), l.face, i, j});
      } else {
        ki0 = std::min(ki0, i);
        ki1 = std::max(ki1, i + 1);
        kj0 = std::min(kj0, j);
        kj1 = std::max(kj1, j + 1);
      }
    }
  // The cells move when the rest of the rectangle stays one rectangle: none of them
  // lies within the bounds of the cells that stay (a whole rectangle, or full rows or
  // columns at its ends).
  const bool rest_is_rectangle =
    std::none_of(rect_moves.begin(), rect_moves.end(), [&](const CellMove& mv) {
      return mv.i >= ki0 && mv.i < ki1 && mv.j >= kj0 && mv.j < kj1;
    });
  // Cells moving to parallel planes, where two views of one surface overlap, also
  // move when they are every observed cell within their own bounds: the overlap of
  // two rectangles is one rectangle, and what stays is at most four.
  bool inner_rectangle = false;
  if (!rest_is_rectangle && all_parallel && !rect_moves.empty()) {
    std::int32_t mi0 = oi1, mi1 = oi0, mj0 = oj1, mj1 = oj0;
    for (const CellMove& mv : rect_moves) {
      mi0 = std::min(mi0, mv.i);
      mi1 = std::max(mi1, mv.i + 1);
      mj0 = std::min(mj0, mv.j);
      mj1 = std::max(mj1, mv.j + 1);
    }
    std::size_t inside = 0;
    for (std::int32_t j = mj0; j < mj1; ++j)
      for (std::int32_t i = mi0; i < mi1; ++i)
        inside += landing.observed(i, j) ? 1 : 0;
    inner_rectangle = inside == rect_moves.size();
  }
  if (rest_is_rectangle || inner_rectangle)
    moves.insert(moves.end(), rect_moves.begin(), rect_moves.end());
}

/** \brief Moves plane \a a's cells in \a moves (sorted here by key): their evidence
 * to the cell of the stronger plane's raster that holds their face centre (observed
 * there too); they leave their plane. Marks the planes changed in \a next_changed;
 * returns the count of cells moved. */
std::size_t
applyMoves(MapPlanes& planes,
           std::size_t a,
           std::vector<CellMove>& moves,
           double inv_r,
           std::vector<bool>& next_changed)
{
  std::sort(moves.begin(), moves.end(),
            [](const CellMove& x, const CellMove& y) { return x.key < y.key; });
  MapPlane& src = planes[a];
  std::vector<std::uint64_t> keep_keys;
  std::vector<float> keep_sums;
  std::vector<std::uint16_t> keep_counts;
  std::vector<std::pair<std::uint32_t, CellEvidence>> out; // (to plane, evidence)
  std::size_t m = 0;
  src.raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t count) {
    while (m < moves.size() && moves[m].key < key)
      ++m;
    if (m < moves.size() && moves[m].key == key) {
      const MapPlane& dst = planes[moves[m].to];
      const Eigen::Vector2d f = dst.frame().toRaster(moves[m].face, inv_r);
      std::int64_t ci = 0, cj = 0;
      if (cellIndex(f.x(), ci) && cellIndex(f.y(), cj)) {
        out.emplace_back(moves[m].to,
                         CellEvidence{rasterCellKey(static_cast<std::int32_t>(ci),
                                                    static_cast<std::int32_t>(cj)),
                                      sum, count});
        return;
      }
    }
    keep_keys.push_back(key);
    keep_sums.push_back(sum);
    keep_counts.push_back(count);
  });
  if (out.empty())
    return 0;
  src.raster.assign(keep_keys, keep_sums, keep_counts);
  src.dirty = true;
  next_changed[a] = true;
  std::stable_sort(out.begin(), out.end(),
                   [](const auto& x, const auto& y) { return x.first < y.first; });
  for (std::size_t s = 0; s < out.size();) {
    const std::uint32_t to = out[s].first;
    std::vector<std::uint64_t> keys;
    std::vector<CellEvidence> evidence;
    for (; s < out.size() && out[s].first == to; ++s) {
      keys.push_back(out[s].second.key);
      if (out[s].second.count > 0)
        evidence.push_back(out[s].second);
    }
    MapPlane& dst = planes[to];
    dst.raster.insert(keys);
    dst.raster.addEvidence(evidence);
    dst.dirty = true;
    next_changed[to] = true;
  }
  return out.size();
}

} // namespace

std::size_t
SurfaceLayer::absorbOverlappingPlaneCells()
{
  Impl& impl = *impl_;
  if (impl.planes.size() < 2)
    return 0;
  AbsorbRule rule;
  rule.r = params_.resolution_m;
  rule.half_cell = static_cast<float>(0.5 * rule.r);
  rule.along_parallel =
    std::max(rule.half_cell, static_cast<float>(params_.absorb_distance_m));
  rule.cos_parallel = static_cast<float>(std::cos(params_.plane_merge_angle_rad));
  rule.bin = static_cast<float>(8.0 * rule.r);
  rule.thickness = static_cast<float>(params_.thickness_m);
  // The planes changed since the covers were last built (this frame's): only a
  // rectangle of such a plane, or one near such a plane, can have come to lie on
  // another plane. Moving cells changes planes too, so the test repeats for the
  // planes that moves changed until no cell moves (cells only move to planes with
  // more evidence, so this ends).
  std::vector<bool> changed(impl.planes.size());
  {
    std::lock_guard<std::mutex> lock(impl.mutex);
    bool any = false;
    for (std::size_t p = 0; p < impl.planes.size(); ++p) {
      changed[p] = impl.planes[p].dirty;
      any = any || changed[p];
    }
    if (!any)
      return 0;
  }
  // Plane b has more evidence than plane a (the lower index on a tie).
  const auto stronger = [&impl](std::size_t b, std::size_t a) {
    const double wa = impl.planes[a].moments.weight;
    const double wb = impl.planes[b].moments.weight;
    return wb > wa || (wb == wa && b < a);
  };
  // With terrain tiles, two level planes (normals within LEVEL_MAX_ANGLE_RAD of the
  // world z axis: road and pavement, floor and step) are not one surface seen at two
  // depths: the step between them (a curb, a stair) is real, so neither absorbs the
  // other.
  std::vector<bool> level(impl.planes.size(), false);
  for (std::size_t p = 0; p < impl.planes.size() && params_.terrain_plane_tile_m > 0.0;
       ++p)
    level[p] = isLevel(impl.planes[p].normal.z());
  std::vector<bool> emptied(impl.planes.size(), false);
  std::size_t total = 0;
  for (;;) {
    PlanarCuboids planar;
    {
      std::lock_guard<std::mutex> lock(impl.mutex);
      impl.buildPlanarCuboids(params_, planar);
    }
    if (planar.size() < 2)
      break;
    // planar[] holds each plane's rectangles in order: cuboid k is rectangle
    // rect_index[k] of its plane
    std::vector<std::size_t> rect_index(planar.size(), 0);
    for (std::size_t k = 1; k < planar.size(); ++k)
      if (planar[k].plane_id == planar[k - 1].plane_id)
        rect_index[k] = rect_index[k - 1] + 1;
    const CuboidPairs pairs = candidatePairs(planar, changed, level, stronger, rule);

    // 1. Per plane, the observed cells of its rectangles that lie wholly on stronger
    //    planes, and those planes.
    std::vector<std::vector<CellMove>> moves(impl.planes.size());
    std::vector<std::uint32_t> candidates;
    std::vector<CellMove> rect_moves;
    for (std::size_t s = 0; s < pairs.size();) {
      const std::size_t k = pairs[s].first;
      candidates.clear();
      for (; s < pairs.size() && pairs[s].first == k; ++s)
        candidates.push_back(pairs[s].second);
      const auto a = static_cast<std::size_t>(planar[k].plane_id);
      const RectangleLanding landing(impl.planes, planar, planar[k],
                                     impl.planes[a].rects[rect_index[k]], candidates,
                                     rule);
      rectangleMoves(landing, rect_moves, moves[a]);
    }

    // 2. The cells move.
    std::size_t moved = 0;
    std::vector<bool> next_changed(impl.planes.size(), false);
    for (std::size_t a = 0; a < impl.planes.size(); ++a) {
      if (moves[a].empty())
        continue;
      const std::size_t n =
        applyMoves(impl.planes, a, moves[a], 1.0 / rule.r, next_changed);
      if (n == 0)
        continue;
      moved += n;
      emptied[a] = impl.planes[a].raster.empty();
    }
    if (moved == 0)
      break;
    total += moved;
    changed.swap(next_changed);
  }
  if (total == 0)
    return 0;

  // 3. A plane left without cells goes (its evidence is what the stronger planes
  //    hold now).
  for (std::size_t a = impl.planes.size(); a-- > 0;)
    if (emptied[a] && impl.planes[a].raster.empty()) {
      impl.planes.erase(impl.planes.begin() + static_cast<std::ptrdiff_t>(a));
      impl.tidy_all = true;
    }
  impl.invalidate();
  return total;
}

} // namespace planar_grid
