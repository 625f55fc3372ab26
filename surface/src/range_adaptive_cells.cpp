// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>
#include <planar_grid/surface/range_adaptive_cells.h>

#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

namespace planar_grid {

const ParamDeclarations<RangeAdaptiveCellsParams>&
rangeAdaptiveCellsParamDeclarations()
{
  using P = RangeAdaptiveCellsParams;
  namespace ranges = range_adaptive_cells_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "min_cell_size_m", [](auto& p) -> auto& { return p.min_cell_size_m; },
      ranges::MIN_CELL_SIZE, "m", "The minimum cell; level l's cells are 2^l times it.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "min_points_per_cell", [](auto& p) -> auto& { return p.min_points_per_cell; },
      ranges::MIN_POINTS_PER_CELL, "",
      "Cells with fewer far points are dropped (the far points are not thinned by "
      "voxel_grid or statistical_outlier_removal)."),
    declareReal<P>(
      "terrain_height_m", [](auto& p) -> auto& { return p.terrain_height_m; },
      ranges::TERRAIN_HEIGHT, "m",
      "Far points this close above their column's lowest point are terrain."),
    declareReal<P>(
      "terrain_cell_m", [](auto& p) -> auto& { return p.terrain_cell_m; },
      ranges::TERRAIN_CELL, "m", "Side of the terrain columns, in the ground plane."),
    declareReal<P>(
      "terrain_max_rise_m", [](auto& p) -> auto& { return p.terrain_max_rise_m; },
      ranges::TERRAIN_MAX_RISE, "m",
      "Highest terrain above the ground plane: a column whose lowest point is higher "
      "(a crown or a wall whose foot is hidden) keeps its points above this plus "
      "terrain_height_m."),
    declareFlag<P>(
      "fit_to_points", [](auto& p) -> auto& { return p.fit_to_points; },
      "Each cell is the box of its points, rounded out to min_cell_size_m inside its "
      "lattice cell, instead of the whole lattice cell: the part of a far wall in a "
      "cell is a slab as thick as its points' depth spread, not the whole cell."),
  };
  return table;
}

void
RangeAdaptiveCells::setParams(const Params& params)
{
  const std::string bad = checkDeclaredRanges(getParamDeclarations(), params);
  if (!bad.empty())
    throw Exception("RangeAdaptiveCells: " + bad);
  params_ = params;
}

void
RangeAdaptiveCells::setUpAxis(const Eigen::Vector3f& up_axis)
{
  if (!up_axis.allFinite() || !(up_axis.norm() > 0.0f))
    throw Exception("RangeAdaptiveCells: the up axis must be finite and not zero");
  up_ = up_axis.normalized();
}

std::size_t
RangeAdaptiveCells::compute(const Points& points,
                            const std::vector<std::uint8_t>& levels,
                            std::vector<std::uint8_t>& is_terrain,
                            PlanarCuboids& cells)
{
  if (levels.size() != points.size())
    throw Exception("RangeAdaptiveCells: " + std::to_string(points.size())
                    + " points but " + std::to_string(levels.size()) + " levels");
  if (std::any_of(levels.begin(), levels.end(),
                  [](std::uint8_t level) { return level >= 16; }))
    throw Exception("RangeAdaptiveCells: a level must be below 16");
  // The axes of the non-planar cells of PlanarCuboidApproximation: e1 horizontal, up,
  // e2.
  PlanarCuboidApproximation<pcl::PointXYZ> axes;
  axes.setUpAxis(up_);
  const Eigen::Vector3f e1 = axes.getHorizontalReference();
  const Eigen::Vector3f e2 = up_.cross(e1);
  relative_.resize(points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    relative_[i] = points[i] - origin_;
  is_terrain.assign(points.size(), 0);
  if (has_ground_)
    markTerrain(e1, e2, is_terrain);
  // The points the cells are made of, in order.
  kept_levels_.clear();
  std::size_t kept = 0;
  for (std::size_t i = 0; i < points.size(); ++i)
    if (!is_terrain[i]) {
      relative_[kept++] = relative_[i];
      kept_levels_.push_back(levels[i]);
    }
  relative_.resize(kept);
  return makeCells(e1, e2, cells);
}

void
RangeAdaptiveCells::markTerrain(const Eigen::Vector3f& e1,
                                const Eigen::Vector3f& e2,
                                std::vector<std::uint8_t>& is_terrain)
{
  const Eigen::Vector4f& g = ground_;
  const std::size_t n = relative_.size();
  const float origin_height = g.head<3>().dot(origin_) + g[3];
  heights_.resize(n);
  for (std::size_t i = 0; i < n; ++i)
    heights_[i] = g.head<3>().dot(relative_[i]) + origin_height;
  const double inv = 1.0 / params_.terrain_cell_m;
  columns_.resize(n);
  for (std::size_t i = 0; i < n; ++i) {
    const auto x = static_cast<std::int64_t>(std::floor(e1.dot(relative_[i]) * inv));
    const auto y = static_cast<std::int64_t>(std::floor(e2.dot(relative_[i]) * inv));
    columns_[i] = (static_cast<std::uint64_t>(x + (1 << 30)) << 32)
                  | static_cast<std::uint64_t>(y + (1 << 30));
  }
  column_low_.clear();
  for (std::size_t i = 0; i < n; ++i) {
    const auto it = column_low_.emplace(columns_[i], heights_[i]).first;
    it->second = std::min(it->second, heights_[i]);
  }
  const auto max_rise = static_cast<float>(params_.terrain_max_rise_m);
  const auto band = static_cast<float>(params_.terrain_height_m);
  for (std::size_t i = 0; i < n; ++i) {
    const float base = std::min(column_low_[columns_[i]], max_rise);
    is_terrain[i] = heights_[i] <= base + band ? 1 : 0;
  }
}

std::size_t
RangeAdaptiveCells::makeCells(const Eigen::Vector3f& e1,
                              const Eigen::Vector3f& e2,
                              PlanarCuboids& cells)
{
  const Eigen::Vector3f& up = up_;
  const double min_cell = params_.min_cell_size_m;
  keys_.clear();
  for (std::size_t i = 0; i < relative_.size(); ++i) {
    const std::uint8_t level = kept_levels_[i];
    const double inv = 1.0 / (min_cell * std::ldexp(1.0, level));
    const auto q = [&](float c) {
      // +-2^19 cells: far beyond eq. 4's reach at any level
      const auto k = static_cast<std::int64_t>(std::floor(c * inv));
      return static_cast<std::uint64_t>(
        std::clamp<std::int64_t>(k, -(1 << 19), (1 << 19) - 1) + (1 << 19));
    };
    keys_.emplace_back((static_cast<std::uint64_t>(level) << 60)
                         | (q(e1.dot(relative_[i])) << 40)
                         | (q(up.dot(relative_[i])) << 20) | q(e2.dot(relative_[i])),
                       static_cast<std::uint32_t>(i));
  }
  std::sort(keys_.begin(), keys_.end());
  const Eigen::Matrix3f axes_t =
    (Eigen::Matrix3f() << e1.transpose(), up.transpose(), e2.transpose()).finished();
  const auto min_points = static_cast<std::size_t>(params_.min_points_per_cell);
  std::size_t made = 0;
  for (std::size_t a = 0; a < keys_.size();) {
    std::size_t b = a;
    while (b < keys_.size() && keys_[b].first == keys_[a].first)
      ++b;
    if (b - a >= min_points) {
      const std::uint64_t key = keys_[a].first;
      const auto level = static_cast<int>(key >> 60);
      const double cell = min_cell * std::ldexp(1.0, level);
      Eigen::Vector3d lo, hi; // the box in (e1, up, e2), relative to the sensor
      for (int d = 0; d < 3; ++d) {
        const auto k =
          static_cast<std::int64_t>((key >> (40 - 20 * d)) & 0xFFFFF) - (1 << 19);
        lo[d] = static_cast<double>(k) * cell;
        hi[d] = lo[d] + cell;
      }
      if (params_.fit_to_points && level > 0)
        fitToPoints(axes_t, a, b, cell, lo, hi);
      const Eigen::Vector3d mid = 0.5 * (lo + hi), size = hi - lo;
      PlanarCuboid c;
      c.normal = -e2;
      c.horizontal_axis = e1; // vertical = -e2 x e1 = up
      c.width_m = static_cast<float>(size[0]);
      c.height_m = static_cast<float>(size[1]);
      c.thickness_m = static_cast<float>(size[2]);
      c.centre = origin_ + axes_t.transpose() * mid.cast<float>();
      c.plane_id = -1;
      c.is_planar = false;
      c.point_count = b - a;
      cells.push_back(c);
      ++made;
    }
    a = b;
  }
  return made;
}

void
RangeAdaptiveCells::fitToPoints(const Eigen::Matrix3f& axes_t,
                                std::size_t a,
                                std::size_t b,
                                double cell,
                                Eigen::Vector3d& lo,
                                Eigen::Vector3d& hi) const
{
  Eigen::Vector3f p_min = Eigen::Vector3f::Constant(std::numeric_limits<float>::max()),
                  p_max = -p_min;
  for (std::size_t j = a; j < b; ++j) {
    const Eigen::Vector3f p = axes_t * relative_[keys_[j].second];
    p_min = p_min.cwiseMin(p);
    p_max = p_max.cwiseMax(p);
  }
  const double r = params_.min_cell_size_m;
  for (int d = 0; d < 3; ++d) {
    // sub-cells of r inside the lattice cell: [lo + r i, lo + r (i + 1))
    const auto n = static_cast<int>(std::lround(cell / r));
    const auto sub = [&](float c) {
      return std::clamp(static_cast<int>(std::floor((c - lo[d]) / r)), 0, n - 1);
    };
    const int first = sub(p_min[d]), last = sub(p_max[d]);
    hi[d] = lo[d] + r * (last + 1);
    lo[d] += r * first;
  }
}

} // namespace planar_grid
