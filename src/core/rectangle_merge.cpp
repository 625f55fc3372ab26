// SPDX-License-Identifier: BSD-3-Clause
// The rectangle merge of a plane's raster cells: gap closing, the paper's cover and the
// MIN_RECTANGLES cover (minimum partition per component), and the rule names.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/rectangle_merge.h>

#include <algorithm>
#include <cstddef>
#include <limits>
#include <set>
#include <utility>

#include "rectangle_merge_impl.h"

namespace planar_grid {

namespace {

/** \brief Cells inside a gap of at most \a max_gap cells between two observed cells
 * of one row or one column (closeRasterGaps()); \a keys sorted
 * by row, then column. The result is sorted, unique and disjoint from \a keys. */
std::vector<std::uint64_t>
closeGapsImpl(const std::vector<std::uint64_t>& keys, int max_gap)
{
  std::vector<std::uint64_t> filled;
  if (max_gap <= 0 || keys.size() < 2)
    return filled;
  // Rows: consecutive keys of one row.
  for (std::size_t k = 0; k + 1 < keys.size(); ++k) {
    const std::int32_t j = rasterCellJ(keys[k]);
    if (rasterCellJ(keys[k + 1]) != j)
      continue;
    const std::int64_t a = rasterCellI(keys[k]), b = rasterCellI(keys[k + 1]);
    if (b - a - 1 >= 1 && b - a - 1 <= max_gap)
      for (std::int64_t i = a + 1; i < b; ++i)
        filled.push_back(rasterCellKey(static_cast<std::int32_t>(i), j));
  }
  // Columns: the same on the transposed keys (column i, then row j).
  std::vector<std::uint64_t> transposed(keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k)
    transposed[k] = rasterCellKey(rasterCellJ(keys[k]), rasterCellI(keys[k]));
  std::sort(transposed.begin(), transposed.end());
  for (std::size_t k = 0; k + 1 < transposed.size(); ++k) {
    const std::int32_t i = rasterCellJ(transposed[k]);
    if (rasterCellJ(transposed[k + 1]) != i)
      continue;
    const std::int64_t a = rasterCellI(transposed[k]),
                       b = rasterCellI(transposed[k + 1]);
    if (b - a - 1 >= 1 && b - a - 1 <= max_gap)
      for (std::int64_t j = a + 1; j < b; ++j)
        filled.push_back(rasterCellKey(i, static_cast<std::int32_t>(j)));
  }
  std::sort(filled.begin(), filled.end());
  filled.erase(std::unique(filled.begin(), filled.end()), filled.end());
  return filled;
}

/** \brief The paper's merge (Fig. 6b): maximal runs of one class along u per row,
 * then runs with the same [i0, i1) and class in consecutive rows stacked into one
 * rectangle. \a keys sorted by row, then column; \a cls the class of each. */
std::vector<RasterRectangle>
paperCover(const std::vector<std::uint64_t>& keys, const std::vector<std::uint8_t>& cls)
{
  struct Run {
    std::int32_t i0, i1;
    std::uint8_t cls;
    std::size_t rect;
  };
  std::vector<RasterRectangle> rects;
  std::vector<Run> previous, current;
  std::int64_t previous_row = std::numeric_limits<std::int64_t>::min();
  const std::size_t n = keys.size();
  for (std::size_t k = 0; k < n;) {
    const std::int32_t j = rasterCellJ(keys[k]);
    if (static_cast<std::int64_t>(j) != previous_row + 1)
      previous.clear();
    current.clear();
    std::size_t p = 0;
    while (k < n && rasterCellJ(keys[k]) == j) {
      const std::uint8_t c = cls[k];
      const std::int32_t i0 = rasterCellI(keys[k]);
      std::int64_t i1 = static_cast<std::int64_t>(i0) + 1;
      std::size_t e = k + 1;
      while (e < n && rasterCellJ(keys[e]) == j && rasterCellI(keys[e]) == i1
             && cls[e] == c) {
        ++i1;
        ++e;
      }
      const auto end = static_cast<std::int32_t>(i1);
      while (p < previous.size() && previous[p].i0 < i0)
        ++p;
      std::size_t rect;
      if (p < previous.size() && previous[p].i0 == i0 && previous[p].i1 == end
          && previous[p].cls == c) {
        rect = previous[p].rect;
        rects[rect].j1 = j + 1;
      } else {
        rect = rects.size();
        rects.push_back(RasterRectangle{i0, end, j, j + 1});
      }
      current.push_back(Run{i0, end, c, rect});
      k = e;
    }
    std::swap(previous, current);
    previous_row = j;
  }
  return rects;
}

/** \brief A minimum partition into rectangles of one 4-connected component \a keys
 * (inside the box of w x h cells at (i_lo, j_lo)), by the classical construction for
 * rectilinear polygons with holes (Lipski et al. 1979; Ohtsuki 1982; Ferrari et al.
 * 1979): a reflex (concave) corner of the region is a grid point with 3 of its 4
 * cells in it; a chord joins two reflex corners facing each other along a grid line
 * through the region's interior; a largest set of pairwise non-intersecting chords
 * (the complement of a minimum vertex cover of the bipartite intersection graph of
 * horizontal and vertical chords, by Koenig's theorem from a maximum matching) is
 * cut, then every reflex corner not yet resolved is cut horizontally until the
 * boundary or a cut. That gives the fewest rectangles: reflex corners - chords + 1 -
 * holes. Returns an empty vector if a region is not a rectangle (not expected; the
 * caller then keeps the paper's cover). */
std::vector<RasterRectangle>
minimumPartition(const std::vector<std::uint64_t>& keys,
                 std::int64_t i_lo,
                 std::int64_t j_lo,
                 std::int64_t w,
                 std::int64_t h)
{
  const auto W = static_cast<std::size_t>(w);
  const auto H = static_cast<std::size_t>(h);
  std::vector<std::uint8_t> inside(W * H, 0);
  for (const auto key : keys)
    inside[static_cast<std::size_t>(rasterCellJ(key) - j_lo) * W
           + static_cast<std::size_t>(rasterCellI(key) - i_lo)] = 1;
  const auto in = [&](std::int64_t x, std::int64_t y) {
    return x >= 0 && y >= 0 && x < w && y < h
           && inside[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)]
                != 0;
  };
  // Cuts: cut_right[c] separates cell c = (x, y) from (x + 1, y); cut_up[c] from
  // (x, y + 1).
  std::vector<std::uint8_t> cut_right(W * H, 0), cut_up(W * H, 0);
  const auto cell = [W](std::int64_t x, std::int64_t y) {
    return static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x);
  };
  // Grid point (x, y), x in [0, w], y in [0, h], is the corner shared by the cells
  // (x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y).
  const auto count_in = [&](std::int64_t x, std::int64_t y) {
    return (in(x - 1, y - 1) ? 1 : 0) + (in(x, y - 1) ? 1 : 0) + (in(x - 1, y) ? 1 : 0)
           + (in(x, y) ? 1 : 0);
  };
  struct Reflex {
    std::int64_t x, y;
    int dx, dy; // directions of its horizontal and vertical extensions
  };
  std::vector<Reflex> reflex;
  for (std::int64_t y = 0; y <= h; ++y)
    for (std::int64_t x = 0; x <= w; ++x)
      if (count_in(x, y) == 3) {
        const bool west_out = !in(x - 1, y - 1) || !in(x - 1, y);
        const bool south_out = !in(x - 1, y - 1) || !in(x, y - 1);
        reflex.push_back(Reflex{x, y, west_out ? 1 : -1, south_out ? 1 : -1});
      }
  // a point's reflex index, -1 otherwise
  std::vector<std::int32_t> reflex_at((W + 1) * (H + 1), -1);
  for (std::size_t k = 0; k < reflex.size(); ++k)
    reflex_at[static_cast<std::size_t>(reflex[k].y) * (W + 1)
              + static_cast<std::size_t>(reflex[k].x)] = static_cast<std::int32_t>(k);
  const auto reflexAt = [&](std::int64_t x, std::int64_t y) {
    return reflex_at[static_cast<std::size_t>(y) * (W + 1)
                     + static_cast<std::size_t>(x)];
  };
  // Chords: from each reflex corner extending +x (+y), walk through interior points
  // to the first boundary point; a chord when that is a reflex corner.
  struct Chord {
    std::int64_t fixed, lo, hi; // y (x) of the line, x (y) range of the points
    std::int32_t a, b;          // its reflex corners
  };
  std::vector<Chord> horizontal, vertical;
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    const Reflex& p = reflex[k];
    if (p.dx == 1) {
      std::int64_t x = p.x + 1;
      while (x <= w && in(x - 1, p.y - 1) && in(x - 1, p.y) && count_in(x, p.y) == 4)
        ++x;
      if (x <= w && in(x - 1, p.y - 1) && in(x - 1, p.y) && reflexAt(x, p.y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(x, p.y))].dx == -1)
        horizontal.push_back(
          Chord{p.y, p.x, x, static_cast<std::int32_t>(k), reflexAt(x, p.y)});
    }
    if (p.dy == 1) {
      std::int64_t y = p.y + 1;
      while (y <= h && in(p.x - 1, y - 1) && in(p.x, y - 1) && count_in(p.x, y) == 4)
        ++y;
      if (y <= h && in(p.x - 1, y - 1) && in(p.x, y - 1) && reflexAt(p.x, y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(p.x, y))].dy == -1)
        vertical.push_back(
          Chord{p.x, p.y, y, static_cast<std::int32_t>(k), reflexAt(p.x, y)});
    }
  }
  // Bipartite intersection graph (touching counts: a shared corner can take only
  // one chord) and a maximum matching (augmenting paths, iterative).
  std::vector<std::vector<std::uint32_t>> adjacent(horizontal.size());
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    for (std::size_t b = 0; b < vertical.size(); ++b)
      if (vertical[b].fixed >= horizontal[a].lo && vertical[b].fixed <= horizontal[a].hi
          && horizontal[a].fixed >= vertical[b].lo
          && horizontal[a].fixed <= vertical[b].hi)
        adjacent[a].push_back(static_cast<std::uint32_t>(b));
  constexpr std::uint32_t NONE = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> match_h(horizontal.size(), NONE),
    match_v(vertical.size(), NONE);
  {
    std::vector<std::uint32_t> seen(vertical.size(), NONE);
    std::vector<std::pair<std::uint32_t, std::size_t>> stack; // (h, next edge)
    for (std::size_t root = 0; root < horizontal.size(); ++root) {
      stack.assign(1, {static_cast<std::uint32_t>(root), 0});
      bool found = false;
      while (!stack.empty() && !found) {
        auto& [a, next] = stack.back();
        if (next == adjacent[a].size()) {
          stack.pop_back();
          continue;
        }
        const std::uint32_t b = adjacent[a][next++];
        if (seen[b] == static_cast<std::uint32_t>(root))
          continue;
        seen[b] = static_cast<std::uint32_t>(root);
        if (match_v[b] == NONE) {
          // augment along the stack: each h on it takes the v it went through
          std::uint32_t v = b;
          for (auto it = stack.rbegin(); it != stack.rend(); ++it) {
            const std::uint32_t u = it->first;
            const std::uint32_t previous = match_h[u];
            match_h[u] = v;
            match_v[v] = u;
            v = previous;
          }
          found = true;
        } else {
          stack.push_back({match_v[b], 0});
        }
      }
    }
  }
  // Koenig: Z = vertices reachable from unmatched horizontal chords by alternating
  // paths; the largest independent set is (horizontal in Z) + (vertical not in Z).
  std::vector<std::uint8_t> z_h(horizontal.size(), 0), z_v(vertical.size(), 0);
  {
    std::vector<std::uint32_t> queue;
    for (std::size_t a = 0; a < horizontal.size(); ++a)
      if (match_h[a] == NONE) {
        z_h[a] = 1;
        queue.push_back(static_cast<std::uint32_t>(a));
      }
    for (std::size_t q = 0; q < queue.size(); ++q)
      for (const auto b : adjacent[queue[q]])
        if (z_v[b] == 0) {
          z_v[b] = 1;
          const std::uint32_t a = match_v[b];
          if (a != NONE && z_h[a] == 0) {
            z_h[a] = 1;
            queue.push_back(a);
          }
        }
  }
  std::vector<std::uint8_t> resolved(reflex.size(), 0);
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    if (z_h[a] != 0) {
      const Chord& c = horizontal[a];
      for (std::int64_t x = c.lo; x < c.hi; ++x)
        cut_up[cell(x, c.fixed - 1)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  for (std::size_t b = 0; b < vertical.size(); ++b)
    if (z_v[b] == 0) {
      const Chord& c = vertical[b];
      for (std::int64_t y = c.lo; y < c.hi; ++y)
        cut_right[cell(c.fixed - 1, y)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  // Every other reflex corner: a horizontal cut to the boundary or the first cut.
  // (A cut touching a reflex corner lies on one of its extensions: it is resolved.)
  const auto verticalCutAt = [&](std::int64_t x, std::int64_t y) {
    return (in(x - 1, y) && in(x, y) && cut_right[cell(x - 1, y)] != 0)
           || (in(x - 1, y - 1) && in(x, y - 1) && cut_right[cell(x - 1, y - 1)] != 0);
  };
  const auto touchesCut = [&](std::int64_t x, std::int64_t y) {
    return verticalCutAt(x, y)
           || (in(x - 1, y - 1) && in(x - 1, y) && cut_up[cell(x - 1, y - 1)] != 0)
           || (in(x, y - 1) && in(x, y) && cut_up[cell(x, y - 1)] != 0);
  };
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    if (resolved[k] != 0 || touchesCut(reflex[k].x, reflex[k].y))
      continue;
    const Reflex& p = reflex[k];
    for (std::int64_t x = p.x;;) {
      const std::int64_t column = p.dx == 1 ? x : x - 1;
      if (!in(column, p.y - 1) || !in(column, p.y)
          || cut_up[cell(column, p.y - 1)] != 0)
        break;
      cut_up[cell(column, p.y - 1)] = 1;
      x += p.dx;
      if (count_in(x, p.y) != 4 || verticalCutAt(x, p.y))
        break;
    }
  }
  // The regions between cuts; each must be a rectangle.
  std::vector<std::uint32_t> region(W * H, NONE);
  std::vector<RasterRectangle> rects;
  std::vector<std::size_t> queue;
  for (std::int64_t y0 = 0; y0 < h; ++y0)
    for (std::int64_t x0 = 0; x0 < w; ++x0) {
      if (!in(x0, y0) || region[cell(x0, y0)] != NONE)
        continue;
      const auto id = static_cast<std::uint32_t>(rects.size());
      std::int64_t x_min = x0, x_max = x0, y_min = y0, y_max = y0;
      std::size_t cells = 0;
      queue.assign(1, cell(x0, y0));
      region[cell(x0, y0)] = id;
      for (std::size_t q = 0; q < queue.size(); ++q) {
        const auto x = static_cast<std::int64_t>(queue[q] % W);
        const auto y = static_cast<std::int64_t>(queue[q] / W);
        ++cells;
        x_min = std::min(x_min, x);
        x_max = std::max(x_max, x);
        y_min = std::min(y_min, y);
        y_max = std::max(y_max, y);
        const auto visit = [&](std::int64_t nx, std::int64_t ny, bool blocked) {
          if (!blocked && in(nx, ny) && region[cell(nx, ny)] == NONE) {
            region[cell(nx, ny)] = id;
            queue.push_back(cell(nx, ny));
          }
        };
        visit(x + 1, y, x + 1 < w && cut_right[cell(x, y)] != 0);
        visit(x - 1, y, x > 0 && cut_right[cell(x - 1, y)] != 0);
        visit(x, y + 1, y + 1 < h && cut_up[cell(x, y)] != 0);
        visit(x, y - 1, y > 0 && cut_up[cell(x, y - 1)] != 0);
      }
      if (static_cast<std::int64_t>(cells) != (x_max - x_min + 1) * (y_max - y_min + 1))
        return {};
      rects.push_back(RasterRectangle{static_cast<std::int32_t>(i_lo + x_min),
                                      static_cast<std::int32_t>(i_lo + x_max + 1),
                                      static_cast<std::int32_t>(j_lo + y_min),
                                      static_cast<std::int32_t>(j_lo + y_max + 1)});
    }
  return rects;
}

} // namespace

namespace detail {

CellComponents
cellComponents(const std::vector<std::uint64_t>& keys,
               const std::vector<std::uint8_t>& cls)
{
  const std::size_t n = keys.size();
  std::vector<std::uint32_t> parent(n);
  for (std::size_t k = 0; k < n; ++k)
    parent[k] = static_cast<std::uint32_t>(k);
  const auto root = [&parent](std::uint32_t k) {
    while (parent[k] != k) {
      parent[k] = parent[parent[k]];
      k = parent[k];
    }
    return k;
  };
  const auto unite = [&](std::size_t a, std::size_t b) {
    const std::uint32_t ra = root(static_cast<std::uint32_t>(a));
    const std::uint32_t rb = root(static_cast<std::uint32_t>(b));
    if (ra != rb)
      parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  for (std::size_t k = 0; k < n; ++k) {
    const std::int32_t i = rasterCellI(keys[k]), j = rasterCellJ(keys[k]);
    if (k + 1 < n && rasterCellJ(keys[k + 1]) == j
        && static_cast<std::int64_t>(rasterCellI(keys[k + 1]))
             == static_cast<std::int64_t>(i) + 1
        && cls[k + 1] == cls[k])
      unite(k, k + 1);
    if (static_cast<std::int64_t>(j) + 1 > MAX_CELL_INDEX)
      continue;
    const std::uint64_t up = rasterCellKey(i, j + 1);
    const auto it = std::lower_bound(keys.begin() + static_cast<std::ptrdiff_t>(k) + 1,
                                     keys.end(), up);
    if (it != keys.end() && *it == up
        && cls[static_cast<std::size_t>(it - keys.begin())] == cls[k])
      unite(k, static_cast<std::size_t>(it - keys.begin()));
  }
  // Components numbered by their first cell; members in key order.
  std::vector<std::uint32_t> component(n);
  std::vector<std::uint32_t> id_of_root(n, std::numeric_limits<std::uint32_t>::max());
  std::vector<std::size_t> sizes;
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t rt = root(static_cast<std::uint32_t>(k));
    if (id_of_root[rt] == std::numeric_limits<std::uint32_t>::max()) {
      id_of_root[rt] = static_cast<std::uint32_t>(sizes.size());
      sizes.push_back(0);
    }
    component[k] = id_of_root[rt];
    ++sizes[component[k]];
  }
  std::vector<std::size_t> start(sizes.size() + 1, 0);
  for (std::size_t c = 0; c < sizes.size(); ++c)
    start[c + 1] = start[c] + sizes[c];
  CellComponents out;
  out.members.resize(n);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < n; ++k)
      out.members[fill[component[k]]++] = keys[k];
  }
  out.start = std::move(start);
  return out;
}

bool
denseGridAffordable(std::int64_t w, std::int64_t h, std::size_t cells)
{
  return static_cast<double>(w) * static_cast<double>(h)
         <= 8.0 * static_cast<double>(cells) + 4096.0;
}

void
cellBounds(const std::vector<std::uint64_t>& sub,
           std::int64_t& i_lo,
           std::int64_t& j_lo,
           std::int64_t& w,
           std::int64_t& h)
{
  i_lo = rasterCellI(sub.front());
  std::int64_t i_hi = i_lo;
  for (const auto key : sub) {
    i_lo = std::min<std::int64_t>(i_lo, rasterCellI(key));
    i_hi = std::max<std::int64_t>(i_hi, rasterCellI(key));
  }
  j_lo = rasterCellJ(sub.front());
  w = i_hi - i_lo + 1;
  h = rasterCellJ(sub.back()) - j_lo + 1;
}

namespace {

/** \brief The MIN_RECTANGLES cover of one component \a sub: the minimum partition,
 * or the paper's cover when that is as small (always when it is one rectangle) or
 * when the component's bounding box is much larger than its cells. */
std::vector<RasterRectangle>
fewestRectangles(const std::vector<std::uint64_t>& sub)
{
  const std::vector<std::uint8_t> one_class(sub.size(), 0);
  std::vector<RasterRectangle> paper = paperCover(sub, one_class);
  if (paper.size() > 1) {
    std::int64_t i_lo, j_lo, w, h;
    cellBounds(sub, i_lo, j_lo, w, h);
    if (denseGridAffordable(w, h, sub.size())) {
      std::vector<RasterRectangle> fewest = minimumPartition(sub, i_lo, j_lo, w, h);
      if (!fewest.empty() && fewest.size() < paper.size())
        paper.swap(fewest);
    }
  }
  return paper;
}

} // namespace

std::vector<RasterRectangle>
minRectangleCover(const std::vector<std::uint64_t>& keys,
                  const std::vector<std::uint8_t>& cls)
{
  const CellComponents components = cellComponents(keys, cls);
  std::vector<RasterRectangle> rects;
  std::vector<std::uint64_t> sub;
  for (std::size_t c = 0; c < components.size(); ++c) {
    components.cells(c, sub);
    const std::vector<RasterRectangle> part = fewestRectangles(sub);
    rects.insert(rects.end(), part.begin(), part.end());
  }
  return rects;
}

} // namespace detail

namespace {

using detail::densityCover;
using detail::minRectangleCover;

} // namespace

std::vector<std::uint64_t>
closeRasterGaps(const std::vector<std::uint64_t>& keys, int max_gap)
{
  return closeGapsImpl(keys, max_gap);
}

std::vector<RasterRectangle>
mergeRasterRectangles(const std::vector<std::uint64_t>& keys,
                      const std::vector<std::uint8_t>& classes,
                      RectangleMergeRule rule,
                      double cover_density)
{
  if (classes.size() != keys.size())
    throw Exception("mergeRasterRectangles: " + std::to_string(classes.size())
                    + " classes for " + std::to_string(keys.size()) + " cells");
  switch (rule) {
    case RectangleMergeRule::PAPER:
      return paperCover(keys, classes);
    case RectangleMergeRule::MIN_RECTANGLES:
      return minRectangleCover(keys, classes);
    case RectangleMergeRule::DENSITY:
      if (!(cover_density >= 0.5 && cover_density <= 1.0))
        throw Exception("mergeRasterRectangles: cover_density "
                        + std::to_string(cover_density) + " outside [0.5, 1]");
      return densityCover(keys, classes, cover_density);
  }
  throw Exception("mergeRasterRectangles: unknown rule "
                  + std::to_string(static_cast<int>(rule)));
}

std::string
toString(RectangleMergeRule rule)
{
  switch (rule) {
    case RectangleMergeRule::PAPER:
      return "paper";
    case RectangleMergeRule::MIN_RECTANGLES:
      return "min_rectangles";
    case RectangleMergeRule::DENSITY:
      return "density";
  }
  return "unknown";
}

RectangleMergeRule
rectangleMergeRuleFromString(const std::string& name)
{
  if (name == "paper")
    return RectangleMergeRule::PAPER;
  if (name == "min_rectangles")
    return RectangleMergeRule::MIN_RECTANGLES;
  if (name == "density")
    return RectangleMergeRule::DENSITY;
  throw Exception("Unknown surface merge rule '" + name
                  + "' (expected paper, min_rectangles or density)");
}

} // namespace planar_grid
