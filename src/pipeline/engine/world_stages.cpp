// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_voxel_grid.h>
#include <planar_grid/map/plane_registry.h>

#include <pcl/common/transforms.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <memory>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class TransformToWorldStage : public Stage {
public:
  bool isFrameLocal() const override { return true; }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    hasPoints(frame, "transform_to_world"); // an empty cloud moves as well
    if (!frame.has_pose)
      throw Exception("stage 'transform_to_world': frame " + frame.name
                      + " has no pose");
    if (frame.cloud_in_world_frame)
      throw Exception("stage 'transform_to_world': the cloud of frame " + frame.name
                      + " is already in the world frame (stage listed twice?)");
    Frame::Cloud::Ptr out(new Frame::Cloud);
    // PCL warns about an empty cloud's zero width; there is nothing to move.
    if (!frame.cloud->empty())
      pcl::transformPointCloud(*frame.cloud, *out,
                               frame.world_T_camera.cast<float>().matrix());
    // Keep the sensor pose with the cloud, where PCL clouds carry it.
    out->sensor_origin_ << frame.world_T_camera.translation().cast<float>(), 1.0f;
    out->sensor_orientation_ =
      Eigen::Quaternionf(frame.world_T_camera.rotation().cast<float>());
    frame.cloud = out;
    frame.cloud_in_world_frame = true;
    // The later stages take points out of the working cloud (in place when it is
    // organized): the map's ray casting keeps its own copy of what was measured.
    if (frame.disparity.empty())
      frame.measured_cloud.reset(new Frame::Cloud(*out));
  }
};

/** The accumulate stage's parameters: its voxel grid and window, and the run-wide
 * planes' (planesParams()). */
struct AccumulateParams {
  double leaf_size_m{PlaneRegistryParams{}.leaf_size_m};
  int downsample_every_n_frames{5};
  double plane_merge_angle_rad{PlaneRegistryParams{}.eps_angle_rad};
  double plane_merge_distance_m{PlaneRegistryParams{}.distance_threshold_m};
  double window_radius_m{0.0};
};

const ParamDeclarations<AccumulateParams>&
accumulateParamDeclarations()
{
  using P = AccumulateParams;
  namespace ranges = plane_registry_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "leaf_size_m", [](auto& p) -> auto& { return p.leaf_size_m; }, ranges::LEAF_SIZE,
      "m", "Voxel edge of the accumulated cloud; 0 keeps every point.")
      .scalesWithCellSize(),
    declareInteger<P>(
      "downsample_every_n_frames",
      [](auto& p) -> auto& { return p.downsample_every_n_frames; },
      ParamRange::closed(1, 100000), "",
      "How often the accumulated cloud is downsampled."),
    declareReal<P>(
      "plane_merge_angle_rad", [](auto& p) -> auto& { return p.plane_merge_angle_rad; },
      ranges::EPS_ANGLE, "rad",
      "A frame's plane joins a run-wide plane whose normal is this close..."),
    declareReal<P>(
      "plane_merge_distance_m",
      [](auto& p) -> auto& { return p.plane_merge_distance_m; },
      ranges::DISTANCE_THRESHOLD, "m",
      "... and whose offset d is this close; else it starts a new one (the pipeline's "
      "value, for this offset distance; PlaneAssociationCriteria's 0.15 m default is "
      "for its evidence distance)."),
    declareReal<P>(
      "window_radius_m", [](auto& p) -> auto& { return p.window_radius_m; },
      ParamRange::closed(0.0, 1e6), "m",
      "Rolling window of the accumulated clouds: at each downsampling only the points "
      "within window_radius_m of the sensor in x and y (world z up) are kept, as "
      "map_integration's window_radius_m keeps the map's; 0 keeps everything."),
  };
  return table;
}

class AccumulateStage : public Stage {
public:
  explicit AccumulateStage(const AccumulateParams& p) :
      params_(p), every_(p.downsample_every_n_frames),
      window_radius_m_(p.window_radius_m), planes_params_(planesParams(p))
  {}

  void getParameters(ParamValues& v) const override
  {
    reportParams(accumulateParamDeclarations(), params_, v);
  }

  void process(Frame& frame, PipelineState& state) override
  {
    if (!frame.cloud_in_world_frame)
      throw Exception("stage 'accumulate' needs world-frame clouds: put "
                      "'transform_to_world' before it");
    // All terrain (an open road) leaves no point, and is no warning. A frame without
    // points goes on: it counts towards the downsampling like any other.
    if (!(frame.has_ground && frame.cloud && countValidPoints(*frame.cloud) == 0))
      hasPoints(frame, "accumulate");
    auto& world = *state.world_cloud;
    // Grown geometrically, not to the exact size: an exact reserve would copy the
    // whole accumulated cloud on every frame.
    if (world.points.capacity() < world.size() + frame.cloud->size())
      world.reserve(std::max(world.size() + frame.cloud->size(), 2 * world.size()));
    for (const auto& p : frame.cloud->points)
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
        world.push_back(p);
    // The planes' inliers, labelled with the run-wide plane they belong to.
    PlaneRegistry& planes = registry(state);
    std::vector<int> run_wide_id(frame.planes.size(), -1);
    for (std::size_t k = 0; k < frame.planes.size(); ++k)
      run_wide_id[k] = planes.addPlane(*frame.cloud, frame.planes[k].model_coefficients,
                                       frame.planes[k].inliers);
    // The frame's cells, relabelled with the run-wide plane ids, unless a map merges
    // them across frames (map_integration).
    for (auto cuboid : state.map ? PlanarCuboids() : frame.cuboids) {
      const auto k = static_cast<std::size_t>(cuboid.plane_id);
      if (cuboid.plane_id >= 0)
        cuboid.plane_id = k < run_wide_id.size() ? run_wide_id[k] : -1;
      state.cuboids.push_back(cuboid);
    }
    if (++frames_since_downsample_ >= every_) {
      if (window_radius_m_ > 0.0)
        cropToWindow(frame.world_T_camera.translation(), state);
      downsample(state);
    }
  }

  void finish(PipelineState& state) override
  {
    if (frames_since_downsample_ > 0)
      downsample(state);
  }

  /** The frames since the last downsampling (the clouds are in PipelineState). */
  void saveState(std::vector<std::uint8_t>& bytes) const override
  {
    ByteWriter(bytes).put(static_cast<std::int32_t>(frames_since_downsample_));
  }

  void loadState(const std::uint8_t* data, std::size_t size) override
  {
    ByteReader r(data, size, "checkpoint: accumulate state");
    const auto frames = r.get<std::int32_t>();
    if (frames < 0 || r.remaining() != 0)
      r.fail("invalid state");
    frames_since_downsample_ = frames;
  }

private:
  /** The run-wide planes' parameters: the association's two tolerances and the
   * accumulated cloud's voxel edge. */
  static PlaneRegistryParams planesParams(const AccumulateParams& p)
  {
    PlaneRegistryParams params;
    params.eps_angle_rad = p.plane_merge_angle_rad;
    params.distance_threshold_m = p.plane_merge_distance_m;
    params.leaf_size_m = p.leaf_size_m;
    return params;
  }

  /** The state's run-wide planes with this stage's parameters: a state from a
   * checkpoint or from a caller holds the planes without them. */
  PlaneRegistry& registry(PipelineState& state) const
  {
    if (!state.planes)
      state.planes = std::make_shared<PlaneRegistry>(planes_params_);
    else
      state.planes->setParams(planes_params_);
    return *state.planes;
  }

  /** Drops the world cloud's and the planes' points outside the box of half-size
   * window_radius_m around the sensor in x and y (every height), the map_integration
   * stage's rolling window. */
  void cropToWindow(const Eigen::Vector3d& sensor, PipelineState& state) const
  {
    cropToWindowXY(*state.world_cloud, sensor, window_radius_m_);
    registry(state).cropToWindow(sensor, window_radius_m_);
  }

  void downsample(PipelineState& state)
  {
    frames_since_downsample_ = 0;
    if (params_.leaf_size_m <= 0.0 || state.world_cloud->empty())
      return;
    FastVoxelGrid<pcl::PointXYZI> grid;
    const auto leaf = static_cast<float>(params_.leaf_size_m);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.setInputCloud(state.world_cloud);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    grid.filter(*out);
    state.world_cloud = out;
    // Labels must not be averaged: the planes keep the point nearest each voxel's
    // centre.
    registry(state).downsample();
  }

  AccumulateParams params_;
  int every_;
  double window_radius_m_;
  PlaneRegistryParams planes_params_;
  int frames_since_downsample_{0};
};

} // namespace

StageInfo
transformToWorldInfo()
{
  StageInfo info;
  info.type = "transform_to_world";
  info.description =
    "Moves the working cloud from the camera frame to the world frame with the "
    "frame's "
    "pose (pcl::transformPointCloud); keeps the sensor origin and orientation.";
  info.needs_poses = true;
  info.create = [](const ParamValues&) -> std::unique_ptr<Stage> {
    return std::make_unique<TransformToWorldStage>();
  };
  return info;
}

StageInfo
accumulateInfo()
{
  StageInfo info;
  info.type = "accumulate";
  info.description = "Appends each world-frame cloud to the accumulated world cloud, "
                     "voxel-downsampled "
                     "(FastVoxelGrid, pcl::VoxelGrid's output) every few frames so "
                     "memory stays bounded by the "
                     "scene, not the run.";
  info.params = paramSpecs(accumulateParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    AccumulateParams p;
    assignParams(accumulateParamDeclarations(), v, p);
    return std::make_unique<AccumulateStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
