// SPDX-License-Identifier: BSD-3-Clause
// range_adaptive_cells: the points beyond depth_error_filter's bound mapped at coarser
// cells, the cell size following eq. 4's depth error, instead of dropped
// (planar_grid::RangeAdaptiveCells).
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/range_adaptive_cells.h>

#include <algorithm>
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class RangeAdaptiveCellsStage : public Stage {
public:
  explicit RangeAdaptiveCellsStage(const RangeAdaptiveCells::Params& p) : cells_(p) {}

  void getParameters(ParamValues& v) const override
  {
    reportParams(RangeAdaptiveCells::getParamDeclarations(), cells_.getParams(), v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    far_points_ = terrain_points_ = made_ = 0;
    if (!frame.far_cloud || frame.far_cloud->empty())
      return;
    const Frame::Cloud::ConstPtr far_cloud = frame.far_cloud; // kept alive below
    const auto& far = *far_cloud;
    if (frame.far_levels.size() != far.size())
      throw Exception("stage 'range_adaptive_cells': frame " + frame.name + " has "
                      + std::to_string(far.size()) + " far points but "
                      + std::to_string(frame.far_levels.size()) + " levels");
    far_points_ = far.size();

    // The points in the frame of the cells (the working cloud's).
    const Eigen::Affine3f cloud_T_camera = cameraTCloud(frame).inverse();
    points_.resize(far.size());
    for (std::size_t i = 0; i < far.size(); ++i)
      points_[i] = cloud_T_camera * far[i].getVector3fMap();
    cells_.setUpAxis(upAxis(frame));
    cells_.setSensorOrigin(sensorOrigin(frame));
    if (frame.has_ground)
      cells_.setGroundPlane(frame.ground_coefficients);
    else
      cells_.clearGroundPlane();
    made_ = cells_.compute(points_, frame.far_levels, terrain_, frame.cuboids);
    terrain_points_ = static_cast<std::size_t>(
      std::count(terrain_.begin(), terrain_.end(), std::uint8_t{1}));
    if (terrain_points_ > 0)
      keepNonTerrain(frame, far);
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("far_points", static_cast<double>(far_points_));
    values.emplace_back("far_terrain_points", static_cast<double>(terrain_points_));
    values.emplace_back("far_cells", static_cast<double>(made_));
  }

private:
  /** \brief The frame keeps the far points the cells are made of (a new cloud: the old
   * one may be shared with copies of the frame). */
  void keepNonTerrain(Frame& frame, const Frame::Cloud& far) const
  {
    auto kept = std::make_shared<Frame::Cloud>();
    std::vector<std::uint8_t> kept_levels;
    kept->reserve(far.size() - terrain_points_);
    kept_levels.reserve(far.size() - terrain_points_);
    for (std::size_t i = 0; i < far.size(); ++i)
      if (!terrain_[i]) {
        kept->push_back(far[i]);
        kept_levels.push_back(frame.far_levels[i]);
      }
    frame.far_cloud = std::move(kept);
    frame.far_levels = std::move(kept_levels);
  }

  RangeAdaptiveCells cells_;
  RangeAdaptiveCells::Points points_;
  std::vector<std::uint8_t> terrain_;
  std::size_t far_points_{0};
  std::size_t terrain_points_{0};
  std::size_t made_{0};
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
  info.params = paramSpecs(RangeAdaptiveCells::getParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    RangeAdaptiveCells::Params p;
    assignParams(RangeAdaptiveCells::getParamDeclarations(), v, p);
    return std::make_unique<RangeAdaptiveCellsStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
