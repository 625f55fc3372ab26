// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>

#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class TransformToWorldStage : public Stage {
public:
  void process(Frame& frame, PipelineState& /*state*/) override
  {
    requirePoints(frame, "transform_to_world");
    if (!frame.has_pose)
      throw Exception("stage 'transform_to_world': frame " + frame.name
                      + " has no pose");
    if (frame.cloud_in_world_frame)
      throw Exception("stage 'transform_to_world': the cloud of frame " + frame.name
                      + " is already in the world frame (stage listed twice?)");
    Frame::Cloud::Ptr out(new Frame::Cloud);
    pcl::transformPointCloud(*frame.cloud, *out,
                             frame.world_T_camera.cast<float>().matrix());
    // Keep the sensor pose with the cloud (S33).
    out->sensor_origin_ << frame.world_T_camera.translation().cast<float>(), 1.0f;
    out->sensor_orientation_ =
      Eigen::Quaternionf(frame.world_T_camera.rotation().cast<float>());
    frame.cloud = out;
    frame.cloud_in_world_frame = true;
  }
};

class AccumulateStage : public Stage {
public:
  AccumulateStage(double leaf_size_m, int downsample_every_n_frames) :
      leaf_size_m_(leaf_size_m), every_(downsample_every_n_frames)
  {}

  void process(Frame& frame, PipelineState& state) override
  {
    requirePoints(frame, "accumulate");
    if (!frame.cloud_in_world_frame)
      throw Exception("stage 'accumulate' needs world-frame clouds: put "
                      "'transform_to_world' before it");
    auto& world = *state.world_cloud;
    world.reserve(world.size() + frame.cloud->size());
    for (const auto& p : frame.cloud->points)
      if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
        world.push_back(p);
    if (++frames_since_downsample_ >= every_)
      downsample(state);
  }

  void finish(PipelineState& state) override
  {
    if (frames_since_downsample_ > 0)
      downsample(state);
  }

  bool countsCloudPoints() const override { return true; }

private:
  void downsample(PipelineState& state)
  {
    frames_since_downsample_ = 0;
    if (leaf_size_m_ <= 0.0 || state.world_cloud->empty())
      return;
    pcl::VoxelGrid<pcl::PointXYZI> grid;
    const auto leaf = static_cast<float>(leaf_size_m_);
    grid.setLeafSize(leaf, leaf, leaf);
    grid.setInputCloud(state.world_cloud);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    grid.filter(*out);
    state.world_cloud = out;
  }

  double leaf_size_m_;
  int every_;
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
                     "(pcl::VoxelGrid) every few frames so memory stays bounded by the "
                     "scene, not the run.";
  info.params = {
    ParamSpec::real("leaf_size_m", 0.1, 0.0, 10.0, "m",
                    "Voxel edge of the accumulated cloud; 0 keeps every point."),
    ParamSpec::integer("downsample_every_n_frames", 5, 1, 100000, "",
                       "How often the accumulated cloud is downsampled."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<AccumulateStage>(v.getDouble("leaf_size_m"),
                                             v.getInt("downsample_every_n_frames"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
