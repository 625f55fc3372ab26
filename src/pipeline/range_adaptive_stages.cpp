// SPDX-License-Identifier: BSD-3-Clause
// range_adaptive_cells: the points beyond depth_error_filter's bound mapped at coarser
// cells, the cell size following eq. 4's depth error, instead of dropped.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/point_types.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** The stage's parameters (no library class takes them). */
struct RangeAdaptiveCellsParams {
  double min_cell_size_m{0.1};
  int min_points_per_cell{10};
  double terrain_height_m{0.3};
  double terrain_cell_m{1.0};
  double terrain_max_rise_m{1.0};
  bool fit_to_points{true};
};

const ParamDeclarations<RangeAdaptiveCellsParams>&
rangeAdaptiveCellsParamDeclarations()
{
  using P = RangeAdaptiveCellsParams;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "min_cell_size_m", [](auto& p) -> auto& { return p.min_cell_size_m; },
      ParamRange::closed(0.01, 10.0), "m",
      "The minimum cell; level l's cells are 2^l times it.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "min_points_per_cell", [](auto& p) -> auto& { return p.min_points_per_cell; },
      ParamRange::closed(1, 1000000), "",
      "Cells with fewer far points are dropped (the far points are not thinned by "
      "voxel_grid or statistical_outlier_removal)."),
    declareReal<P>(
      "terrain_height_m", [](auto& p) -> auto& { return p.terrain_height_m; },
      ParamRange::closed(0.0, 10.0), "m",
      "Far points this close above their column's lowest point are terrain."),
    declareReal<P>(
      "terrain_cell_m", [](auto& p) -> auto& { return p.terrain_cell_m; },
      ParamRange::closed(0.05, 100.0), "m",
      "Side of the terrain columns, in the ground plane."),
    declareReal<P>(
      "terrain_max_rise_m", [](auto& p) -> auto& { return p.terrain_max_rise_m; },
      ParamRange::closed(0.0, 100.0), "m",
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

class RangeAdaptiveCellsStage : public Stage {
public:
  explicit RangeAdaptiveCellsStage(const RangeAdaptiveCellsParams& p) :
      params_(p), min_cell_size_m_(p.min_cell_size_m),
      min_points_per_cell_(static_cast<std::size_t>(p.min_points_per_cell)),
      terrain_height_m_(static_cast<float>(p.terrain_height_m)),
      terrain_cell_m_(p.terrain_cell_m),
      terrain_max_rise_m_(static_cast<float>(p.terrain_max_rise_m)),
      fit_to_points_(p.fit_to_points)
  {}

  void getParameters(ParamValues& v) const override
  {
    reportParams(rangeAdaptiveCellsParamDeclarations(), params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    far_points_ = terrain_points_ = cells_ = 0;
    if (!frame.far_cloud || frame.far_cloud->empty())
      return;
    const Frame::Cloud::ConstPtr far_cloud = frame.far_cloud; // kept alive below
    const auto& far = *far_cloud;
    if (frame.far_levels.size() != far.size())
      throw Exception("stage 'range_adaptive_cells': frame " + frame.name + " has "
                      + std::to_string(far.size()) + " far points but "
                      + std::to_string(frame.far_levels.size()) + " levels");
    far_points_ = far.size();

    // The points in the frame of the cells (the working cloud's), and the axes of
    // the non-planar cells of planar_cuboid_approximation: e1 horizontal, up, e2.
    const Eigen::Affine3f cloud_T_camera = cameraTCloud(frame).inverse();
    const Eigen::Vector3f up = upAxis(frame).normalized();
    PlanarCuboidApproximation<pcl::PointXYZI> axes;
    axes.setUpAxis(up);
    const Eigen::Vector3f e1 = axes.getHorizontalReference();
    const Eigen::Vector3f e2 = up.cross(e1);
    const Eigen::Vector3f origin = sensorOrigin(frame);
    points_.resize(far.size());
    for (std::size_t i = 0; i < far.size(); ++i)
      points_[i] = cloud_T_camera * far[i].getVector3fMap() - origin;
    terrain_.assign(far.size(), 0);
    if (frame.has_ground)
      markTerrain(frame.ground_coefficients, origin, e1, e2);
    if (terrain_points_ > 0)
      keepNonTerrain(frame, far);
    makeCells(frame, e1, up, e2, origin);
  }

private:
  /** \brief Terrain: a point at most terrain_height above the lowest far point of its
   * column (terrain_cell_m wide) of the ground plane \a g, or above terrain_max_rise
   * where that column's lowest point is higher (its foot unseen), is road, verge or
   * lawn. */
  void markTerrain(const Eigen::Vector4f& g,
                   const Eigen::Vector3f& origin,
                   const Eigen::Vector3f& e1,
                   const Eigen::Vector3f& e2)
  {
    const std::size_t n = points_.size();
    const float origin_height = g.head<3>().dot(origin) + g[3];
    heights_.resize(n);
    for (std::size_t i = 0; i < n; ++i)
      heights_[i] = g.head<3>().dot(points_[i]) + origin_height;
    const double inv = 1.0 / terrain_cell_m_;
    columns_.resize(n);
    for (std::size_t i = 0; i < n; ++i) {
      const auto x = static_cast<std::int64_t>(std::floor(e1.dot(points_[i]) * inv));
      const auto y = static_cast<std::int64_t>(std::floor(e2.dot(points_[i]) * inv));
      columns_[i] = (static_cast<std::uint64_t>(x + (1 << 30)) << 32)
                    | static_cast<std::uint64_t>(y + (1 << 30));
    }
    column_low_.clear();
    for (std::size_t i = 0; i < n; ++i) {
      const auto it = column_low_.emplace(columns_[i], heights_[i]).first;
      it->second = std::min(it->second, heights_[i]);
    }
    for (std::size_t i = 0; i < n; ++i) {
      const float base = std::min(column_low_[columns_[i]], terrain_max_rise_m_);
      terrain_[i] = heights_[i] <= base + terrain_height_m_ ? 1 : 0;
      terrain_points_ += terrain_[i];
    }
  }

  /** \brief The frame keeps the far points the cells are made of (a new cloud: the old
   * one may be shared with copies of the frame); points_ keeps the same ones, in
   * order. */
  void keepNonTerrain(Frame& frame, const Frame::Cloud& far)
  {
    auto kept = std::make_shared<Frame::Cloud>();
    std::vector<std::uint8_t> kept_levels;
    kept->reserve(far.size() - terrain_points_);
    kept_levels.reserve(far.size() - terrain_points_);
    for (std::size_t i = 0; i < far.size(); ++i)
      if (!terrain_[i]) {
        points_[kept->size()] = points_[i];
        kept->push_back(far[i]);
        kept_levels.push_back(frame.far_levels[i]);
      }
    points_.resize(kept->size());
    frame.far_cloud = std::move(kept);
    frame.far_levels = std::move(kept_levels);
  }

  /** \brief Cells: a lattice of edge min_cell_size x 2^level per level, anchored at
   * the sensor's position (cells of one frame never straddle the lattice of another
   * level); a cell with at least min_points_per_cell points is one non-planar box:
   * the whole lattice cell, or with fit_to_points the bounds of its points rounded
   * out to min_cell_size (inside the lattice cell, at least min_cell_size a side). */
  void makeCells(Frame& frame,
                 const Eigen::Vector3f& e1,
                 const Eigen::Vector3f& up,
                 const Eigen::Vector3f& e2,
                 const Eigen::Vector3f& origin)
  {
    keys_.clear();
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const std::uint8_t level = frame.far_levels[i];
      const double inv = 1.0 / (min_cell_size_m_ * std::ldexp(1.0, level));
      const auto q = [&](float c) {
        // +-2^19 cells: far beyond eq. 4's reach at any level
        const auto k = static_cast<std::int64_t>(std::floor(c * inv));
        return static_cast<std::uint64_t>(
          std::clamp<std::int64_t>(k, -(1 << 19), (1 << 19) - 1) + (1 << 19));
      };
      keys_.emplace_back((static_cast<std::uint64_t>(level) << 60)
                           | (q(e1.dot(points_[i])) << 40)
                           | (q(up.dot(points_[i])) << 20) | q(e2.dot(points_[i])),
                         static_cast<std::uint32_t>(i));
    }
    std::sort(keys_.begin(), keys_.end());
    const Eigen::Matrix3f axes_t =
      (Eigen::Matrix3f() << e1.transpose(), up.transpose(), e2.transpose()).finished();
    for (std::size_t a = 0; a < keys_.size();) {
      std::size_t b = a;
      while (b < keys_.size() && keys_[b].first == keys_[a].first)
        ++b;
      if (b - a >= min_points_per_cell_) {
        const std::uint64_t key = keys_[a].first;
        const auto level = static_cast<int>(key >> 60);
        const double cell = min_cell_size_m_ * std::ldexp(1.0, level);
        Eigen::Vector3d lo, hi; // the box in (e1, up, e2), relative to the sensor
        for (int d = 0; d < 3; ++d) {
          const auto k =
            static_cast<std::int64_t>((key >> (40 - 20 * d)) & 0xFFFFF) - (1 << 19);
          lo[d] = static_cast<double>(k) * cell;
          hi[d] = lo[d] + cell;
        }
        if (fit_to_points_ && level > 0)
          fitToPoints(axes_t, a, b, cell, lo, hi);
        const Eigen::Vector3d mid = 0.5 * (lo + hi), size = hi - lo;
        PlanarCuboid c;
        c.normal = -e2;
        c.horizontal_axis = e1; // vertical = -e2 x e1 = up
        c.width_m = static_cast<float>(size[0]);
        c.height_m = static_cast<float>(size[1]);
        c.thickness_m = static_cast<float>(size[2]);
        c.centre = origin + axes_t.transpose() * mid.cast<float>();
        c.plane_id = -1;
        c.is_planar = false;
        c.point_count = b - a;
        frame.cuboids.push_back(c);
        ++cells_;
      }
      a = b;
    }
  }

  /** \brief The lattice cell [lo, hi) shrunk to the bounds of its points keys_[a..b)
   * rounded out to sub-cells of min_cell_size (in the cell's axes \a axes_t). */
  void fitToPoints(const Eigen::Matrix3f& axes_t,
                   std::size_t a,
                   std::size_t b,
                   double cell,
                   Eigen::Vector3d& lo,
                   Eigen::Vector3d& hi) const
  {
    Eigen::Vector3f p_min =
                      Eigen::Vector3f::Constant(std::numeric_limits<float>::max()),
                    p_max = -p_min;
    for (std::size_t j = a; j < b; ++j) {
      const Eigen::Vector3f p = axes_t * points_[keys_[j].second];
      p_min = p_min.cwiseMin(p);
      p_max = p_max.cwiseMax(p);
    }
    const double r = min_cell_size_m_;
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

public:
  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("far_points", static_cast<double>(far_points_));
    values.emplace_back("far_terrain_points", static_cast<double>(terrain_points_));
    values.emplace_back("far_cells", static_cast<double>(cells_));
  }

private:
  RangeAdaptiveCellsParams params_;
  double min_cell_size_m_;
  std::size_t min_points_per_cell_;
  float terrain_height_m_;
  double terrain_cell_m_;
  float terrain_max_rise_m_;
  bool fit_to_points_;
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> points_;
  std::vector<float> heights_;
  std::vector<std::uint8_t> terrain_;
  std::vector<std::uint64_t> columns_;
  std::unordered_map<std::uint64_t, float> column_low_;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> keys_;
  std::size_t far_points_{0};
  std::size_t terrain_points_{0};
  std::size_t cells_{0};
};

} // namespace

StageInfo
rangeAdaptiveCellsInfo()
{
  StageInfo info;
  info.type = "range_adaptive_cells";
  info.description =
    "Maps the points depth_error_filter keeps beyond its bound (its far_levels) as "
    "non-planar cells whose size follows eq. 4's depth error: level l (error within "
    "max_depth_error_m x 2^l) at min_cell_size_m x 2^l, so that far structures are "
    "coarse cells instead of nothing. With a ground plane (ground_removal), the far "
    "terrain goes: points within terrain_height_m above the lowest far point of their "
    "column. Appends to the frame's cells; put it after planar_cuboid_approximation.";
  info.params = paramSpecs(rangeAdaptiveCellsParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    RangeAdaptiveCellsParams p;
    assignParams(rangeAdaptiveCellsParamDeclarations(), v, p);
    return std::make_unique<RangeAdaptiveCellsStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
