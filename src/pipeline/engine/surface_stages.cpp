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
  explicit PlanarCuboidApproximationStage(
    const PlanarCuboidApproximationParams& params) :
      approximation_(params)
  {}

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
    reportParams(planarCuboidApproximationParamDeclarations(),
                 approximation_.getParams(), v);
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
    const double inv = 1.0 / approximation_.getMinCellSize();
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
  info.params = paramSpecs(planarCuboidApproximationParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    PlanarCuboidApproximationParams params;
    assignParams(planarCuboidApproximationParamDeclarations(), v, params);
    return std::make_unique<PlanarCuboidApproximationStage>(params);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
