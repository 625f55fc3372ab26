// SPDX-License-Identifier: BSD-3-Clause
// The DENSITY rule of the rectangle merge: rectangles grown per component while at
// least a given share of their cells is of the seed's class, small ones absorbed.
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

/** States of a cell of the DENSITY cover's grid: no raster cell, a cell of class 0 or
 * 1 of the component, or blocked (another component's cell, or covered). */
enum : std::uint8_t { FREE = 0, CLASS_0 = 1, CLASS_1 = 2, BLOCKED = 3 };

/** A rectangle [x0, x1) x [y0, y1) of a component's grid and the class it was grown
 * for (CLASS_0 or CLASS_1; BLOCKED once absorbed into a neighbour). */
struct LocalRect {
  std::int64_t x0, x1, y0, y1;
  std::uint8_t of;
};

/** \brief Second step of the DENSITY cover: the greedy growth leaves small rectangles
 * where an earlier rectangle blocked a strip (the corners of a staircase, a cell or
 * two sticking out of an edge). Smallest first, each rectangle S joins the largest
 * edge neighbour R for which the bounding box U of both holds only cells outside the
 * raster and rectangles that lie wholly inside U, with at least \a density of U's
 * cells of R's class: U replaces R and the rectangles inside it. So the cover keeps
 * its invariants (every raster cell in exactly one rectangle, each rectangle at
 * \a density) with fewer rectangles.
 *
 * \a cls_grid is the component's grid before covering (\a W columns), \a label the
 * rectangle of each grid cell (index into \a rects, -1 for none); absorbed
 * rectangles get of = BLOCKED. */
void
absorbSmallRectangles(const std::vector<std::uint8_t>& cls_grid,
                      std::vector<std::int32_t>& label,
                      std::size_t W,
                      double density,
                      std::vector<LocalRect>& rects)
{
  if (rects.size() < 2)
    return;
  const auto area = [](const LocalRect& r) {
    return (r.x1 - r.x0) * (r.y1 - r.y0);
  };
  std::vector<std::int32_t> order(rects.size());
  for (std::size_t k = 0; k < order.size(); ++k)
    order[k] = static_cast<std::int32_t>(k);
  std::stable_sort(order.begin(), order.end(), [&](std::int32_t a, std::int32_t b) {
    return area(rects[static_cast<std::size_t>(a)])
           < area(rects[static_cast<std::size_t>(b)]);
  });
  const auto H = static_cast<std::int64_t>(label.size() / W);
  const auto W64 = static_cast<std::int64_t>(W);
  const auto cell = [W](std::int64_t x, std::int64_t y) {
    return static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x);
  };
  std::vector<std::int32_t> neighbours, inside;
  // Repeated until no rectangle joins another: a join can open one for a rectangle
  // tried before it.
  for (bool joined = true; joined;) {
    joined = false;
    for (const std::int32_t s : order) {
      const LocalRect& S = rects[static_cast<std::size_t>(s)];
      if (S.of == BLOCKED)
        continue;
      neighbours.clear();
      const auto look = [&](std::int64_t x, std::int64_t y) {
        if (x < 0 || y < 0 || x >= W64 || y >= H)
          return;
        const std::int32_t n = label[cell(x, y)];
        if (n >= 0 && n != s)
          neighbours.push_back(n);
      };
      for (std::int64_t x = S.x0; x < S.x1; ++x) {
        look(x, S.y0 - 1);
        look(x, S.y1);
      }
      for (std::int64_t y = S.y0; y < S.y1; ++y) {
        look(S.x0 - 1, y);
        look(S.x1, y);
      }
      std::sort(neighbours.begin(), neighbours.end());
      neighbours.erase(std::unique(neighbours.begin(), neighbours.end()),
                       neighbours.end());
      std::stable_sort(neighbours.begin(), neighbours.end(),
                       [&](std::int32_t a, std::int32_t b) {
                         return area(rects[static_cast<std::size_t>(a)])
                                > area(rects[static_cast<std::size_t>(b)]);
                       });
      for (const std::int32_t n : neighbours) {
        LocalRect& R = rects[static_cast<std::size_t>(n)];
        const LocalRect U{std::min(R.x0, S.x0), std::max(R.x1, S.x1),
                          std::min(R.y0, S.y0), std::max(R.y1, S.y1), R.of};
        std::int64_t members = 0;
        bool fits = true;
        inside.clear();
        for (std::int64_t y = U.y0; y < U.y1 && fits; ++y)
          for (std::int64_t x = U.x0; x < U.x1; ++x) {
            const std::int32_t l = label[cell(x, y)];
            if (l < 0 && cls_grid[cell(x, y)] != FREE) {
              fits = false;
              break;
            }
            if (l >= 0 && l != n && l != s) {
              const LocalRect& T = rects[static_cast<std::size_t>(l)];
              if (T.x0 < U.x0 || T.x1 > U.x1 || T.y0 < U.y0 || T.y1 > U.y1) {
                fits = false;
                break;
              }
              inside.push_back(l);
            }
            members += cls_grid[cell(x, y)] == R.of ? 1 : 0;
          }
        if (!fits
            || static_cast<double>(members) < density * static_cast<double>(area(U)))
          continue;
        for (std::int64_t y = U.y0; y < U.y1; ++y)
          for (std::int64_t x = U.x0; x < U.x1; ++x)
            label[cell(x, y)] = n;
        R = U;
        rects[static_cast<std::size_t>(s)].of = BLOCKED;
        for (const std::int32_t l : inside)
          rects[static_cast<std::size_t>(l)].of = BLOCKED;
        joined = true;
        break;
      }
    }
  }
}

} // namespace

namespace detail {

std::vector<RasterRectangle>
densityCover(const std::vector<std::uint64_t>& keys,
             const std::vector<std::uint8_t>& cls,
             double density)
{
  const CellComponents components =
    cellComponents(keys, std::vector<std::uint8_t>(keys.size(), 0));
  std::vector<RasterRectangle> rects;
  std::vector<std::uint64_t> sub;
  std::vector<std::uint8_t> grid, cls_grid;
  std::vector<std::int32_t> label;
  std::vector<LocalRect> local;
  // Cells outside the raster covered so far: a later component's box may hold them.
  std::set<std::uint64_t> covered_outside;
  for (std::size_t c = 0; c < components.size(); ++c) {
    components.cells(c, sub);
    std::int64_t i_lo, j_lo, w, h;
    cellBounds(sub, i_lo, j_lo, w, h);
    if (!denseGridAffordable(w, h, sub.size())) {
      const std::vector<RasterRectangle> part = minRectangleCover(sub, [&] {
        std::vector<std::uint8_t> sub_cls(sub.size());
        for (std::size_t k = 0; k < sub.size(); ++k)
          sub_cls[k] = cls[static_cast<std::size_t>(
            std::lower_bound(keys.begin(), keys.end(), sub[k]) - keys.begin())];
        return sub_cls;
      }());
      rects.insert(rects.end(), part.begin(), part.end());
      continue;
    }
    const auto W = static_cast<std::size_t>(w);
    grid.assign(W * static_cast<std::size_t>(h), FREE);
    // Every raster cell in the box is blocked, then the component's own take their
    // class.
    for (std::int64_t y = 0; y < h; ++y) {
      const auto j = static_cast<std::int32_t>(j_lo + y);
      auto it = std::lower_bound(keys.begin(), keys.end(),
                                 rasterCellKey(static_cast<std::int32_t>(i_lo), j));
      for (; it != keys.end() && rasterCellJ(*it) == j && rasterCellI(*it) < i_lo + w;
           ++it)
        grid[static_cast<std::size_t>(y) * W
             + static_cast<std::size_t>(rasterCellI(*it) - i_lo)] = BLOCKED;
      // cells outside the raster that an earlier component's rectangle covers
      for (auto c = covered_outside.lower_bound(
             rasterCellKey(static_cast<std::int32_t>(i_lo), j));
           c != covered_outside.end() && rasterCellJ(*c) == j
           && rasterCellI(*c) < i_lo + w;
           ++c)
        grid[static_cast<std::size_t>(y) * W
             + static_cast<std::size_t>(rasterCellI(*c) - i_lo)] = BLOCKED;
    }
    for (const auto key : sub) {
      const auto k = static_cast<std::size_t>(
        std::lower_bound(keys.begin(), keys.end(), key) - keys.begin());
      grid[static_cast<std::size_t>(rasterCellJ(key) - j_lo) * W
           + static_cast<std::size_t>(rasterCellI(key) - i_lo)] =
        cls[k] != 0 ? CLASS_1 : CLASS_0;
    }
    const auto at = [&](std::int64_t x, std::int64_t y) -> std::uint8_t& {
      return grid[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)];
    };
    cls_grid = grid;
    label.assign(grid.size(), -1);
    local.clear();
    // Cells of class \a of in the strip x in [x0, x1), y in [y0, y1); -1 if it holds
    // a blocked cell.
    const auto strip = [&](std::uint8_t of, std::int64_t x0, std::int64_t x1,
                           std::int64_t y0, std::int64_t y1) -> std::int64_t {
      std::int64_t members = 0;
      for (std::int64_t y = y0; y < y1; ++y)
        for (std::int64_t x = x0; x < x1; ++x) {
          const std::uint8_t g = at(x, y);
          if (g == BLOCKED)
            return -1;
          members += g == of ? 1 : 0;
        }
      return members;
    };
    for (std::int64_t sy = 0; sy < h; ++sy)
      for (std::int64_t sx = 0; sx < w; ++sx) {
        const std::uint8_t of = at(sx, sy);
        if (of != CLASS_0 && of != CLASS_1)
          continue;
        std::int64_t x0 = sx, x1 = sx + 1, y0 = sy, y1 = sy + 1, members = 1;
        for (;;) {
          // right, up, left, down
          const std::int64_t len_u = y1 - y0, len_v = x1 - x0;
          const std::int64_t got[4] = {x1 < w ? strip(of, x1, x1 + 1, y0, y1) : -1,
                                       y1 < h ? strip(of, x0, x1, y1, y1 + 1) : -1,
                                       x0 > 0 ? strip(of, x0 - 1, x0, y0, y1) : -1,
                                       y0 > 0 ? strip(of, x0, x1, y0 - 1, y0) : -1};
          const std::int64_t len[4] = {len_u, len_v, len_u, len_v};
          const double area = static_cast<double>((x1 - x0) * (y1 - y0));
          int best = -1;
          for (int side = 0; side < 4; ++side) {
            if (got[side] <= 0
                || static_cast<double>(members + got[side])
                     < density * (area + static_cast<double>(len[side])))
              continue;
            if (best < 0 || got[side] * len[best] > got[best] * len[side]
                || (got[side] * len[best] == got[best] * len[side]
                    && got[side] > got[best]))
              best = side;
          }
          if (best < 0)
            break;
          members += got[best];
          if (best == 0)
            ++x1;
          else if (best == 1)
            ++y1;
          else if (best == 2)
            --x0;
          else
            --y0;
        }
        for (std::int64_t y = y0; y < y1; ++y)
          for (std::int64_t x = x0; x < x1; ++x) {
            at(x, y) = BLOCKED;
            label[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)] =
              static_cast<std::int32_t>(local.size());
          }
        local.push_back(LocalRect{x0, x1, y0, y1, of});
      }
    absorbSmallRectangles(cls_grid, label, W, density, local);
    for (const LocalRect& lr : local) {
      if (lr.of == BLOCKED)
        continue;
      for (std::int64_t y = lr.y0; y < lr.y1; ++y)
        for (std::int64_t x = lr.x0; x < lr.x1; ++x)
          if (cls_grid[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)]
              == FREE)
            covered_outside.insert(rasterCellKey(static_cast<std::int32_t>(i_lo + x),
                                                 static_cast<std::int32_t>(j_lo + y)));
      rects.push_back(RasterRectangle{static_cast<std::int32_t>(i_lo + lr.x0),
                                      static_cast<std::int32_t>(i_lo + lr.x1),
                                      static_cast<std::int32_t>(j_lo + lr.y0),
                                      static_cast<std::int32_t>(j_lo + lr.y1)});
    }
  }
  return rects;
}

} // namespace detail
} // namespace planar_grid
