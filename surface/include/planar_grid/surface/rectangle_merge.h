// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief How a raster of cells is covered by rectangles (the merge of the paper's
 * Fig. 6b and two covers with fewer rectangles). \ingroup surface */
enum class RectangleMergeRule : std::uint8_t {
  /** The paper's rule (Fig. 6b): maximal runs of one class along the raster's
   * horizontal axis i, then runs with exactly equal extent [i0, i1) and class in
   * consecutive rows stacked along j. Where consecutive rows differ by one cell it
   * leaves slivers. */
  PAPER = 0,
  /** The fewest rectangles: per 4-connected component of one class, a minimum
   * partition into rectangles (the classical construction for rectilinear polygons
   * with holes: cut a largest set of non-crossing chords between facing reflex
   * corners, found by bipartite matching, then one cut per remaining reflex corner).
   * Never more rectangles than PAPER, fewer where the paper's exact equal-extent
   * stacking leaves slivers (ragged borders, bumps, holes). A component whose
   * bounding box exceeds 8 times its cells plus 4096 (a long diagonal staircase,
   * where the dense grid of the construction would cost too much) keeps the paper's
   * cover. */
  MIN_RECTANGLES = 1,
  /** The paper's density threshold D_T (Fig. 8: a unit is kept whole when at least
   * D_T of it is occupied) applied to the merge: per 4-connected component of the
   * raster (either class), rectangles grown greedily from the first uncovered cell
   * (rows first, then columns) one row or column at a time, each step taking the side
   * whose new strip holds the largest share of cells of the first cell's class, as
   * long as at least cover_density of the rectangle's cells are of that class and the
   * strip holds no cell of another component or of an earlier rectangle (of this or
   * an earlier component). Then, smallest first, a rectangle joins an edge neighbour
   * when the bounding box of the two holds no cell of another component, cuts no
   * third rectangle (those inside it join too) and has at least cover_density of its
   * cells of the neighbour's class, until no two rectangles can be one. Every cell
   * of the raster lies in exactly one rectangle; a rectangle may also cover, in all
   * up to 1 - cover_density of its area, cells not in the raster (ragged borders,
   * notches) and cells of the other class (the paper merges the split units by
   * geometry), so a facade whose rows end a cell or two apart, or whose occupancy is
   * speckled, is a few large rectangles instead of one sliver per row or speckle.
   * cover_density 1 gives exact rectangles of one class. A component
   * whose bounding box exceeds 8 times its cells plus 4096 keeps the MIN_RECTANGLES
   * cover. */
  DENSITY = 2
};

/** \brief "paper", "min_rectangles" or "density". \ingroup surface */
std::string toString(RectangleMergeRule rule);

/** \brief Parses "paper", "min_rectangles" or "density".
 * \throws planar_grid::Exception for any other name \ingroup surface */
RectangleMergeRule rectangleMergeRuleFromString(const std::string& name);

/** \brief A rectangle of raster cells [i0, i1) x [j0, j1) (i the column along the
 * raster's horizontal axis, j the row). \ingroup surface */
struct RasterRectangle {
  /** First column, in cells. */
  std::int32_t i0;
  /** One past the last column, in cells. */
  std::int32_t i1;
  /** First row, in cells. */
  std::int32_t j0;
  /** One past the last row, in cells. */
  std::int32_t j1;
};

/** \brief Largest |i| or |j| of a raster cell accepted by the raster functions, in
 * cells (2e9: the int32 range of RasterRectangle and rasterCellKey() with a margin, so
 * that an index plus one, a neighbour or one past the last cell, never overflows).
 * Callers that turn coordinates into raster indices reject, or skip, a cell beyond
 * it. \ingroup surface */
inline constexpr double MAX_CELL_INDEX = 2.0e9;

/** \brief Key of raster cell (i, j) of a sparse raster: keys order the cells by row
 * j, then column i (both signed). \ingroup surface */
inline std::uint64_t
rasterCellKey(std::int32_t i, std::int32_t j)
{
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(j) ^ 0x80000000u) << 32)
         | static_cast<std::uint64_t>(static_cast<std::uint32_t>(i) ^ 0x80000000u);
}

/** \brief Column i of a rasterCellKey(). \ingroup surface */
inline std::int32_t
rasterCellI(std::uint64_t key)
{
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key & 0xffffffffu)
                                   ^ 0x80000000u);
}

/** \brief Row j of a rasterCellKey(). \ingroup surface */
inline std::int32_t
rasterCellJ(std::uint64_t key)
{
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key >> 32) ^ 0x80000000u);
}

/** \brief The cells that close the gaps of a sparse raster: every run of at most
 * \a max_gap cells not in the raster between two raster cells of one row or of one
 * column (the union of the morphological closings with a horizontal and a vertical
 * segment of max_gap + 1 cells; a gap open on one side, like a ragged border, is not
 * filled).
 * \param[in] keys the raster's cells (rasterCellKey()), sorted, unique
 * \param[in] max_gap widest gap closed, in cells (<= 0: none)
 * \return the filling cells, sorted, unique, disjoint from \a keys */
std::vector<std::uint64_t> closeRasterGaps(const std::vector<std::uint64_t>& keys,
                                           int max_gap);

/** \brief Covers a sparse raster of two-class cells with rectangles by \a rule (the
 * paper's Fig. 6b, or a cover with fewer rectangles).
 *
 * PAPER and MIN_RECTANGLES give a partition of the raster's cells into rectangles
 * of one class; DENSITY covers every raster cell by exactly one rectangle, which may
 * also hold cells outside the raster and of the other class (see
 * RectangleMergeRule). PAPER lists the rectangles in the order the rows create them
 * (by first row, then first column); the other rules by component (numbered by its
 * first cell), then as built: callers that need an order sort them.
 * \param[in] keys the raster's cells (rasterCellKey()), sorted, unique; |i|, |j| at
 * most MAX_CELL_INDEX
 * \param[in] classes one class per key, 0 or 1
 * \param[in] rule the merge
 * \param[in] cover_density with DENSITY, the smallest share of a rectangle's cells of
 * its first cell's class, in [0.5, 1]; ignored by the other rules
 * \return the rectangles, in raster cells
 * \throws planar_grid::Exception when \a classes and \a keys differ in size or
 * \a cover_density is out of range (DENSITY) */
std::vector<RasterRectangle>
mergeRasterRectangles(const std::vector<std::uint64_t>& keys,
                      const std::vector<std::uint8_t>& classes,
                      RectangleMergeRule rule,
                      double cover_density = 1.0);

} // namespace planar_grid
