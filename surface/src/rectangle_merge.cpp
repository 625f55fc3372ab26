// SPDX-License-Identifier: BSD-3-Clause
// The rectangle merge of a plane's raster cells: gap closing, the paper's cover and the
// MIN_RECTANGLES cover (minimum partition per component), and the rule names.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/rectangle_merge.h>

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

constexpr std::uint32_t NONE = std::numeric_limits<std::uint32_t>::max();

/** \brief One component's cells in their box of w x h cells, and the cuts between
 * them: cut_right[c] separates cell c = (x, y) from (x + 1, y); cut_up[c] from
 * (x, y + 1). */
struct PartitionGrid {
  std::int64_t w, h;
  std::size_t W, H;
  std::vector<std::uint8_t> inside, cut_right, cut_up;

  PartitionGrid(const std::vector<std::uint64_t>& keys,
                std::int64_t i_lo,
                std::int64_t j_lo,
                std::int64_t w_cells,
                std::int64_t h_cells) :
      w(w_cells),
      h(h_cells), W(static_cast<std::size_t>(w_cells)),
      H(static_cast<std::size_t>(h_cells)), inside(W * H, 0), cut_right(W * H, 0),
      cut_up(W * H, 0)
  {
    for (const auto key : keys)
      inside[static_cast<std::size_t>(rasterCellJ(key) - j_lo) * W
             + static_cast<std::size_t>(rasterCellI(key) - i_lo)] = 1;
  }

  bool in(std::int64_t x, std::int64_t y) const
  {
    return x >= 0 && y >= 0 && x < w && y < h
           && inside[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)]
                != 0;
  }

  std::size_t cell(std::int64_t x, std::int64_t y) const
  {
    return static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x);
  }

  /** \brief Of the cells sharing grid point (x, y), x in [0, w], y in [0, h] (the
   * cells (x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y)), how many are inside. */
  int countIn(std::int64_t x, std::int64_t y) const
  {
    return (in(x - 1, y - 1) ? 1 : 0) + (in(x, y - 1) ? 1 : 0) + (in(x - 1, y) ? 1 : 0)
           + (in(x, y) ? 1 : 0);
  }

  /** \brief Whether a vertical cut meets grid point (x, y). */
  bool verticalCutAt(std::int64_t x, std::int64_t y) const
  {
    return (in(x - 1, y) && in(x, y) && cut_right[cell(x - 1, y)] != 0)
           || (in(x - 1, y - 1) && in(x, y - 1) && cut_right[cell(x - 1, y - 1)] != 0);
  }

  /** \brief Whether any cut meets grid point (x, y). */
  bool touchesCut(std::int64_t x, std::int64_t y) const
  {
    return verticalCutAt(x, y)
           || (in(x - 1, y - 1) && in(x - 1, y) && cut_up[cell(x - 1, y - 1)] != 0)
           || (in(x, y - 1) && in(x, y) && cut_up[cell(x, y - 1)] != 0);
  }
};

/** \brief A reflex (concave) corner: a grid point with 3 of its 4 cells inside. */
struct Reflex {
  std::int64_t x, y;
  int dx, dy; // directions of its horizontal and vertical extensions
};

/** \brief A chord: a grid-line segment through the interior joining two reflex
 * corners that face each other. */
struct Chord {
  std::int64_t fixed, lo, hi; // y (x) of the line, x (y) range of the points
  std::int32_t a, b;          // its reflex corners
};

/** \brief The reflex corners of the component. */
std::vector<Reflex>
reflexCorners(const PartitionGrid& g)
{
  std::vector<Reflex> reflex;
  for (std::int64_t y = 0; y <= g.h; ++y)
    for (std::int64_t x = 0; x <= g.w; ++x)
      if (g.countIn(x, y) == 3) {
        const bool west_out = !g.in(x - 1, y - 1) || !g.in(x - 1, y);
        const bool south_out = !g.in(x - 1, y - 1) || !g.in(x, y - 1);
        reflex.push_back(Reflex{x, y, west_out ? 1 : -1, south_out ? 1 : -1});
      }
  return reflex;
}

/** \brief The horizontal and vertical chords: from each reflex corner extending +x
 * (+y), a walk through interior points to the first boundary point; a chord when
 * that is a reflex corner extending the other way. */
void
findChords(const PartitionGrid& g,
           const std::vector<Reflex>& reflex,
           std::vector<Chord>& horizontal,
           std::vector<Chord>& vertical)
{
  // a point's reflex index, -1 otherwise
  std::vector<std::int32_t> reflex_at((g.W + 1) * (g.H + 1), -1);
  for (std::size_t k = 0; k < reflex.size(); ++k)
    reflex_at[static_cast<std::size_t>(reflex[k].y) * (g.W + 1)
              + static_cast<std::size_t>(reflex[k].x)] = static_cast<std::int32_t>(k);
  const auto reflexAt = [&](std::int64_t x, std::int64_t y) {
    return reflex_at[static_cast<std::size_t>(y) * (g.W + 1)
                     + static_cast<std::size_t>(x)];
  };
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    const Reflex& p = reflex[k];
    if (p.dx == 1) {
      std::int64_t x = p.x + 1;
      while (x <= g.w && g.in(x - 1, p.y - 1) && g.in(x - 1, p.y)
             && g.countIn(x, p.y) == 4)
        ++x;
      if (x <= g.w && g.in(x - 1, p.y - 1) && g.in(x - 1, p.y) && reflexAt(x, p.y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(x, p.y))].dx == -1)
        horizontal.push_back(
          Chord{p.y, p.x, x, static_cast<std::int32_t>(k), reflexAt(x, p.y)});
    }
    if (p.dy == 1) {
      std::int64_t y = p.y + 1;
      while (y <= g.h && g.in(p.x - 1, y - 1) && g.in(p.x, y - 1)
             && g.countIn(p.x, y) == 4)
        ++y;
      if (y <= g.h && g.in(p.x - 1, y - 1) && g.in(p.x, y - 1) && reflexAt(p.x, y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(p.x, y))].dy == -1)
        vertical.push_back(
          Chord{p.x, p.y, y, static_cast<std::int32_t>(k), reflexAt(p.x, y)});
    }
  }
}

/** \brief A largest set of pairwise non-intersecting chords: the bipartite
 * intersection graph (touching counts: a shared corner can take only one chord), a
 * maximum matching (augmenting paths, iterative), and Koenig's theorem: Z = the
 * vertices reachable from unmatched horizontal chords by alternating paths; the set
 * is (horizontal in Z) + (vertical not in Z). Sets \a take_h and \a take_v. */
void
independentChords(const std::vector<Chord>& horizontal,
                  const std::vector<Chord>& vertical,
                  std::vector<std::uint8_t>& take_h,
                  std::vector<std::uint8_t>& take_v)
{
  std::vector<std::vector<std::uint32_t>> adjacent(horizontal.size());
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    for (std::size_t b = 0; b < vertical.size(); ++b)
      if (vertical[b].fixed >= horizontal[a].lo && vertical[b].fixed <= horizontal[a].hi
          && horizontal[a].fixed >= vertical[b].lo
          && horizontal[a].fixed <= vertical[b].hi)
        adjacent[a].push_back(static_cast<std::uint32_t>(b));
  std::vector<std::uint32_t> match_h(horizontal.size(), NONE),
    match_v(vertical.size(), NONE);
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
  std::vector<std::uint8_t> z_h(horizontal.size(), 0), z_v(vertical.size(), 0);
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
  take_h = z_h;
  take_v.assign(vertical.size(), 0);
  for (std::size_t b = 0; b < vertical.size(); ++b)
    take_v[b] = z_v[b] == 0 ? 1 : 0;
}

/** \brief Cuts the chords taken, then every reflex corner not yet resolved
 * horizontally to the boundary or the first cut (a cut touching a reflex corner lies
 * on one of its extensions: it is resolved). */
void
cutCorners(const std::vector<Reflex>& reflex,
           const std::vector<Chord>& horizontal,
           const std::vector<Chord>& vertical,
           const std::vector<std::uint8_t>& take_h,
           const std::vector<std::uint8_t>& take_v,
           PartitionGrid& g)
{
  std::vector<std::uint8_t> resolved(reflex.size(), 0);
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    if (take_h[a] != 0) {
      const Chord& c = horizontal[a];
      for (std::int64_t x = c.lo; x < c.hi; ++x)
        g.cut_up[g.cell(x, c.fixed - 1)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  for (std::size_t b = 0; b < vertical.size(); ++b)
    if (take_v[b] != 0) {
      const Chord& c = vertical[b];
      for (std::int64_t y = c.lo; y < c.hi; ++y)
        g.cut_right[g.cell(c.fixed - 1, y)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    if (resolved[k] != 0 || g.touchesCut(reflex[k].x, reflex[k].y))
      continue;
    const Reflex& p = reflex[k];
    for (std::int64_t x = p.x;;) {
      const std::int64_t column = p.dx == 1 ? x : x - 1;
      if (!g.in(column, p.y - 1) || !g.in(column, p.y)
          || g.cut_up[g.cell(column, p.y - 1)] != 0)
        break;
      g.cut_up[g.cell(column, p.y - 1)] = 1;
      x += p.dx;
      if (g.countIn(x, p.y) != 4 || g.verticalCutAt(x, p.y))
        break;
    }
  }
}

/** \brief The regions between the cuts, as rectangles offset by (i_lo, j_lo); empty
 * when a region is not a rectangle. */
std::vector<RasterRectangle>
regionsBetweenCuts(const PartitionGrid& g, std::int64_t i_lo, std::int64_t j_lo)
{
  std::vector<std::uint32_t> region(g.W * g.H, NONE);
  std::vector<RasterRectangle> rects;
  std::vector<std::size_t> queue;
  for (std::int64_t y0 = 0; y0 < g.h; ++y0)
    for (std::int64_t x0 = 0; x0 < g.w; ++x0) {
      if (!g.in(x0, y0) || region[g.cell(x0, y0)] != NONE)
        continue;
      const auto id = static_cast<std::uint32_t>(rects.size());
      std::int64_t x_min = x0, x_max = x0, y_min = y0, y_max = y0;
      std::size_t cells = 0;
      queue.assign(1, g.cell(x0, y0));
      region[g.cell(x0, y0)] = id;
      for (std::size_t q = 0; q < queue.size(); ++q) {
        const auto x = static_cast<std::int64_t>(queue[q] % g.W);
        const auto y = static_cast<std::int64_t>(queue[q] / g.W);
        ++cells;
        x_min = std::min(x_min, x);
        x_max = std::max(x_max, x);
        y_min = std::min(y_min, y);
        y_max = std::max(y_max, y);
        const auto visit = [&](std::int64_t nx, std::int64_t ny, bool blocked) {
          if (!blocked && g.in(nx, ny) && region[g.cell(nx, ny)] == NONE) {
            region[g.cell(nx, ny)] = id;
            queue.push_back(g.cell(nx, ny));
          }
        };
        visit(x + 1, y, x + 1 < g.w && g.cut_right[g.cell(x, y)] != 0);
        visit(x - 1, y, x > 0 && g.cut_right[g.cell(x - 1, y)] != 0);
        visit(x, y + 1, y + 1 < g.h && g.cut_up[g.cell(x, y)] != 0);
        visit(x, y - 1, y > 0 && g.cut_up[g.cell(x, y - 1)] != 0);
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
  PartitionGrid grid(keys, i_lo, j_lo, w, h);
  const std::vector<Reflex> reflex = reflexCorners(grid);
  std::vector<Chord> horizontal, vertical;
  findChords(grid, reflex, horizontal, vertical);
  std::vector<std::uint8_t> take_h, take_v;
  independentChords(horizontal, vertical, take_h, take_v);
  cutCorners(reflex, horizontal, vertical, take_h, take_v, grid);
  return regionsBetweenCuts(grid, i_lo, j_lo);
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
