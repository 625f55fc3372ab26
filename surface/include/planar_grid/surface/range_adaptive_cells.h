// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/core/planar_cuboid.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <unordered_map>
#include <utility>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each RangeAdaptiveCells parameter. \ingroup surface */
namespace range_adaptive_cells_ranges {
/** \brief The minimum cell: [0.01, 10] meters. */
inline constexpr ParamRange MIN_CELL_SIZE = ParamRange::closed(0.01, 10.0);
/** \brief Fewest points of a cell: [1, 1000000]. */
inline constexpr ParamRange MIN_POINTS_PER_CELL = ParamRange::closed(1, 1000000);
/** \brief Terrain band above a column's lowest point: [0, 10] meters. */
inline constexpr ParamRange TERRAIN_HEIGHT = ParamRange::closed(0.0, 10.0);
/** \brief Side of the terrain columns: [0.05, 100] meters. */
inline constexpr ParamRange TERRAIN_CELL = ParamRange::closed(0.05, 100.0);
/** \brief Highest terrain above the ground plane: [0, 100] meters. */
inline constexpr ParamRange TERRAIN_MAX_RISE = ParamRange::closed(0.0, 100.0);
} // namespace range_adaptive_cells_ranges

/** \brief RangeAdaptiveCells' parameters, named by their keys (the pipeline's
 * range_adaptive_cells stage keys, with its defaults). \ingroup surface */
struct RangeAdaptiveCellsParams {
  /** \brief The minimum cell, meters; level l's cells are 2^l times it. */
  double min_cell_size_m{0.1};
  /** \brief Fewest points of a cell. */
  int min_points_per_cell{10};
  /** \brief Terrain band above a column's lowest point, meters. */
  double terrain_height_m{0.3};
  /** \brief Side of the terrain columns in the ground plane, meters. */
  double terrain_cell_m{1.0};
  /** \brief Highest terrain above the ground plane, meters. */
  double terrain_max_rise_m{1.0};
  /** \brief Whether a cell is the box of its points (rounded out to min_cell_size_m)
   * rather than its whole lattice cell. */
  bool fit_to_points{true};
};

/** \brief The one declaration of each RangeAdaptiveCellsParams member (key with unit,
 * range, meaning). \ingroup surface */
const ParamDeclarations<RangeAdaptiveCellsParams>&
rangeAdaptiveCellsParamDeclarations();

/** \brief Non-planar cells whose size follows the stereo range error: points beyond
 * the depth at which eq. 4's error exceeds the map's bound are not dropped but mapped
 * at coarser cells, level l (error within the bound x 2^l, e.g. DepthErrorFilter's
 * far levels) at min_cell_size_m x 2^l. Not in the paper, which drops them.
 *
 * The cells of a level form a lattice anchored at the sensor origin, with axes (e1,
 * up, e2): up the up axis, e1 its horizontal reference (that of
 * PlanarCuboidApproximation's non-planar boxes), e2 = up x e1. A lattice cell with at
 * least min_points_per_cell points is one non-planar cuboid: the whole lattice cell,
 * or with fit_to_points (from level 1) the bounds of its points rounded out to
 * min_cell_size_m, inside the lattice cell.
 *
 * With a ground plane set, the far terrain goes first: a point at most
 * terrain_height_m above the lowest point of its column (terrain_cell_m a side, in
 * the ground plane), or above terrain_max_rise_m where that column's lowest point is
 * higher (its foot unseen: a crown, a wall), is road, verge or lawn, and makes no
 * cell. \ingroup surface */
class RangeAdaptiveCells {
public:
  /** \brief The parameters (RangeAdaptiveCellsParams). */
  using Params = RangeAdaptiveCellsParams;
  /** \brief Points, meters. */
  using Points =
    std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>;

  /** \brief Each parameter's one declaration: the range_adaptive_cells stage and its
   * reference are made from it. */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return rangeAdaptiveCellsParamDeclarations();
  }

  RangeAdaptiveCells() = default;
  /** \brief With \a params. \throws planar_grid::Exception for a value out of its
   * declared range */
  explicit RangeAdaptiveCells(const Params& params) { setParams(params); }

  /** \brief Sets the parameters. \throws planar_grid::Exception for a value out of
   * its declared range (the parameters then stay as they were) */
  void setParams(const Params& params);
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Sets the up axis, non-zero (normalised; default (0, 0, 1); (0, -1, 0) in
   * a camera frame). \throws planar_grid::Exception for a zero or non-finite axis */
  void setUpAxis(const Eigen::Vector3f& up_axis);
  /** \brief The up axis, unit length. */
  const Eigen::Vector3f& getUpAxis() const { return up_; }

  /** \brief Sets the sensor origin the lattices are anchored at, meters (default 0).
   */
  void setSensorOrigin(const Eigen::Vector3f& origin) { origin_ = origin; }
  /** \brief The sensor origin, meters. */
  const Eigen::Vector3f& getSensorOrigin() const { return origin_; }

  /** \brief Sets the ground plane [a, b, c, d] (unit normal up, d meters: a point's
   * height is n . p + d) that the terrain test measures heights from. */
  void setGroundPlane(const Eigen::Vector4f& ground)
  {
    ground_ = ground;
    has_ground_ = true;
  }
  /** \brief No ground plane: no terrain test (the default). */
  void clearGroundPlane() { has_ground_ = false; }

  /** \brief Builds the cells of \a points.
   * \param[in] points the far points, meters, in the frame of the up axis and the
   * sensor origin
   * \param[in] levels each point's level l >= 0 (as many as points; its cells are
   * min_cell_size_m x 2^l, l < 16)
   * \param[out] is_terrain one flag per point: 1 for the terrain (none without a
   * ground plane)
   * \param[out] cells the cells are appended: non-planar cuboids (plane_id -1,
   * normal -e2, horizontal axis e1, point_count their points), in the order of
   * (level, e1, up, e2) lattice key
   * \return the number of cells appended
   * \throws planar_grid::Exception when levels and points differ in size or a level
   * is 16 or more */
  std::size_t compute(const Points& points,
                      const std::vector<std::uint8_t>& levels,
                      std::vector<std::uint8_t>& is_terrain,
                      PlanarCuboids& cells);

private:
  void markTerrain(const Eigen::Vector3f& e1,
                   const Eigen::Vector3f& e2,
                   std::vector<std::uint8_t>& is_terrain);
  std::size_t
  makeCells(const Eigen::Vector3f& e1, const Eigen::Vector3f& e2, PlanarCuboids& cells);
  void fitToPoints(const Eigen::Matrix3f& axes_t,
                   std::size_t a,
                   std::size_t b,
                   double cell,
                   Eigen::Vector3d& lo,
                   Eigen::Vector3d& hi) const;

  Params params_;
  Eigen::Vector3f up_{0.0f, 0.0f, 1.0f};
  Eigen::Vector3f origin_{Eigen::Vector3f::Zero()};
  Eigen::Vector4f ground_{Eigen::Vector4f::Zero()};
  bool has_ground_{false};
  // Per call, kept between calls to reuse their memory.
  Points relative_;
  std::vector<std::uint8_t> kept_levels_;
  std::vector<float> heights_;
  std::vector<std::uint64_t> columns_;
  std::unordered_map<std::uint64_t, float> column_low_;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys_;
};

} // namespace planar_grid
