// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <cmath>
#include <unordered_set>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class PlanarCuboidApproximationStage : public Stage {
public:
  explicit PlanarCuboidApproximationStage(const ParamValues& v) :
      min_cell_size_m_(v.getDouble("min_cell_size_m"))
  {
    approximation_.setMinCellSize(min_cell_size_m_);
    approximation_.setDensityThreshold(v.getDouble("density_threshold"));
    approximation_.setNonPlanarDensityThreshold(
      v.getDouble("non_planar_density_threshold"));
    approximation_.setMinWidth(v.getDouble("min_width_m"));
    approximation_.setMinHeight(v.getDouble("min_height_m"));
    approximation_.setThickness(v.getDouble("thickness_m"));
    approximation_.setMinPointsPerCell(v.getInt("min_points_per_cell"));
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    // The terrain removal may leave nothing (an open road): no cells then.
    if (frame.has_ground && frame.cloud && countValidPoints(*frame.cloud) == 0) {
      frame.cuboids.clear();
      voxels_ = 0;
      return;
    }
    if (!hasPoints(frame, "planar_cuboid_approximation")) {
      frame.cuboids.clear();
      voxels_ = 0;
      return;
    }
    if (std::isfinite(frame.inlier_only_depth_m))
      throw Exception("stage 'planar_cuboid_approximation': depth_error_filter's "
                      "max_plane_depth_error_m needs multi_plane_segmentation before "
                      "it (frame "
                      + frame.name + ")");
    approximation_.setInputCloud(frame.cloud);
    approximation_.setPlanes(frame.planes);
    approximation_.setUpAxis(upAxis(frame));
    approximation_.setSensorOrigin(sensorOrigin(frame));
    approximation_.approximate(frame.cuboids);
    voxels_ = countOccupiedVoxels(*frame.cloud);
  }

  bool countsCloudPoints() const override { return false; }

  void getParameters(ParamValues& v) const override
  {
    const auto& a = approximation_;
    v.set("min_cell_size_m", a.getMinCellSize());
    v.set("density_threshold", a.getDensityThreshold());
    v.set("non_planar_density_threshold", a.getNonPlanarDensityThreshold());
    v.set("min_width_m", a.getMinWidth());
    v.set("min_height_m", a.getMinHeight());
    v.set("thickness_m", a.getThickness());
    v.set("min_points_per_cell", a.getMinPointsPerCell());
  }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    std::size_t planar = 0;
    for (const auto& c : frame.cuboids)
      planar += c.is_planar;
    values.emplace_back("cuboids", static_cast<double>(frame.cuboids.size()));
    values.emplace_back("planar_cuboids", static_cast<double>(planar));
    // The standard grid on the same points, for the paper's combination efficiency
    // eta = 1 - N_cuboids / N_voxels (Sec. IV-B).
    values.emplace_back("voxels", static_cast<double>(voxels_));
  }

private:
  /** Occupied voxels of edge min_cell_size_m (the standard grid, SG) on the points. */
  std::size_t countOccupiedVoxels(const Frame::Cloud& cloud)
  {
    keys_.clear();
    const double inv = 1.0 / min_cell_size_m_;
    for (const auto& p : cloud.points) {
      if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
        continue;
      const auto ix = static_cast<std::int64_t>(std::floor(p.x * inv));
      const auto iy = static_cast<std::int64_t>(std::floor(p.y * inv));
      const auto iz = static_cast<std::int64_t>(std::floor(p.z * inv));
      // 21 bits per axis: +-1e6 cells, +-100 km at 0.1 m.
      keys_.insert(((ix & 0x1FFFFF) << 42) | ((iy & 0x1FFFFF) << 21) | (iz & 0x1FFFFF));
    }
    return keys_.size();
  }

  PlanarCuboidApproximation<pcl::PointXYZI> approximation_;
  double min_cell_size_m_;
  std::unordered_set<std::int64_t> keys_;
  std::size_t voxels_{0};
};

} // namespace

StageInfo
planarCuboidApproximationInfo()
{
  StageInfo info;
  info.type = "planar_cuboid_approximation";
  info.description =
    "planar_grid::PlanarCuboidApproximation (paper Sec. III-F, Figs. 6-8): each "
    "plane's "
    "inliers are split into four about the centre while the split density D < D_T and "
    "the unit is wider than W_T and higher than H_T, merged horizontally then "
    "vertically "
    "into the largest rectangles and extruded behind the surface; the rest is split "
    "the "
    "same way, never merged. Reports the occupied voxels at the same size (SG).";
  // The defaults are the class's, except where a row says otherwise.
  const PlanarCuboidApproximation<pcl::PointXYZI> d;
  namespace ranges = planar_cuboid_approximation_ranges;
  info.params = {
    ParamSpec::real(
      "min_cell_size_m", d.getMinCellSize(), ranges::MIN_CELL_SIZE, "m",
      "Smallest cell side and raster resolution (the paper's minimum grid).")
      .scalesWithCellSize(),
    ParamSpec::real("density_threshold", d.getDensityThreshold(),
                    ranges::DENSITY_THRESHOLD, "",
                    "D_T: a unit whose occupied-area fraction D is below it is split."),
    ParamSpec::real("non_planar_density_threshold", 0.25,
                    ranges::NON_PLANAR_DENSITY_THRESHOLD, "",
                    "Occupied share of its 3D lattice a non-planar box (Fig. 7) must "
                    "reach before it stops splitting (0: density_threshold). The "
                    "pipeline's value; the class defaults to 0."),
    ParamSpec::real("min_width_m", d.getMinWidth(), ranges::MIN_WIDTH, "m",
                    "W_T: a unit is split only while wider than this.")
      .scalesWithCellSize(),
    ParamSpec::real("min_height_m", d.getMinHeight(), ranges::MIN_HEIGHT, "m",
                    "H_T: a unit is split only while higher than this.")
      .scalesWithCellSize(),
    ParamSpec::real("thickness_m", d.getThickness(), ranges::THICKNESS, "m",
                    "Extrusion behind the surface along the normal.")
      .scalesWithCellSize(),
    ParamSpec::integer("min_points_per_cell", d.getMinPointsPerCell(),
                       ranges::MIN_POINTS_PER_CELL, "",
                       "Cells with fewer points are dropped."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<PlanarCuboidApproximationStage>(v);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
