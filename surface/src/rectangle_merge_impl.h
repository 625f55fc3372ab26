// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of the rectangle merge: the cell components and the
// MIN_RECTANGLES and DENSITY covers.
#pragma once

#include <planar_grid/surface/rectangle_merge.h>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace planar_grid {
namespace detail {

/** \brief The 4-connected components of cells of one class: component c holds the
 * keys members[start[c]] .. members[start[c + 1] - 1], in key order; components are
 * numbered by their first cell. \a keys sorted by row, then column; \a cls the
 * class of each. */
struct CellComponents {
  std::vector<std::uint64_t> members;
  std::vector<std::size_t> start;
  std::size_t size() const { return start.size() - 1; }
  /** The cells of component \a c, in key order, into \a sub. */
  void cells(std::size_t c, std::vector<std::uint64_t>& sub) const
  {
    sub.assign(members.begin() + static_cast<std::ptrdiff_t>(start[c]),
               members.begin() + static_cast<std::ptrdiff_t>(start[c + 1]));
  }
};

/** \brief The components of the cells \a keys by class \a cls (CellComponents). */
CellComponents cellComponents(const std::vector<std::uint64_t>& keys,
                              const std::vector<std::uint8_t>& cls);

/** \brief Whether the dense grid of a component of \a cells cells in a \a w x \a h
 * bounding box is affordable (a 4-connected component of m cells spans at most
 * m x m cells: a long diagonal staircase would not be). */
bool denseGridAffordable(std::int64_t w, std::int64_t h, std::size_t cells);

/** \brief Bounding box [i_lo, i_lo + w) x [j_lo, j_lo + h) of \a sub (sorted). */
void cellBounds(const std::vector<std::uint64_t>& sub,
                std::int64_t& i_lo,
                std::int64_t& j_lo,
                std::int64_t& w,
                std::int64_t& h);

/** \brief The MIN_RECTANGLES cover: per 4-connected component of one class, the
 * fewest rectangles (fewestRectangles). */
std::vector<RasterRectangle> minRectangleCover(const std::vector<std::uint64_t>& keys,
                                               const std::vector<std::uint8_t>& cls);

/** \brief The DENSITY cover (RectangleMergeRule::DENSITY): per 4-connected component
 * of raster cells (either class), rectangles grown greedily on the component's
 * bounding box. A cell of the box is free (no raster cell), of class 0 or 1, or
 * blocked (a raster cell of another component, or one already covered). From each
 * uncovered cell in row-major order, a rectangle grows one column or row at a time on
 * the side whose new strip has the largest share of cells of the seed's class (more
 * of them on a tie; right, up, left, down on a further tie), while the strip holds
 * such a cell and no blocked cell and at least \a density of the rectangle's cells
 * are of the seed's class. */
std::vector<RasterRectangle> densityCover(const std::vector<std::uint64_t>& keys,
                                          const std::vector<std::uint8_t>& cls,
                                          double density);

} // namespace detail
} // namespace planar_grid
