// SPDX-License-Identifier: BSD-3-Clause
#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class VoxelGridStage : public Stage {
public:
  VoxelGridStage(double leaf_size_m, int min_points_per_voxel)
  {
    const auto leaf = static_cast<float>(leaf_size_m);
    filter_.setLeafSize(leaf, leaf, leaf);
    filter_.setMinimumPointsNumberPerVoxel(
      static_cast<unsigned int>(min_points_per_voxel));
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    requirePoints(frame, "voxel_grid");
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter_.setInputCloud(frame.cloud);
    filter_.filter(*out);
    frame.cloud = out;
  }

private:
  pcl::VoxelGrid<pcl::PointXYZI> filter_;
};

class StatisticalOutlierRemovalStage : public Stage {
public:
  StatisticalOutlierRemovalStage(int mean_k, double stddev_mul_thresh)
  {
    filter_.setMeanK(mean_k);
    filter_.setStddevMulThresh(stddev_mul_thresh);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    requirePoints(frame, "statistical_outlier_removal");
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter_.setInputCloud(frame.cloud);
    filter_.filter(*out);
    frame.cloud = out;
  }

private:
  pcl::StatisticalOutlierRemoval<pcl::PointXYZI> filter_;
};

} // namespace

StageInfo
voxelGridInfo()
{
  StageInfo info;
  info.type = "voxel_grid";
  info.description =
    "pcl::VoxelGrid: one centroid per occupied voxel of the working cloud.";
  info.params = {
    ParamSpec::real("leaf_size_m", 0.05, 0.001, 10.0, "m", "Voxel edge length.")
      .scalesWithCellSize(),
    ParamSpec::integer("min_points_per_voxel", 1, 1, 100000, "",
                       "Voxels with fewer points are dropped."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<VoxelGridStage>(v.getDouble("leaf_size_m"),
                                            v.getInt("min_points_per_voxel"));
  };
  return info;
}

StageInfo
statisticalOutlierRemovalInfo()
{
  StageInfo info;
  info.type = "statistical_outlier_removal";
  info.description =
    "pcl::StatisticalOutlierRemoval: drops points whose mean distance to their k "
    "nearest "
    "neighbours exceeds the global mean by more than stddev_mul_thresh standard "
    "deviations.";
  info.params = {
    ParamSpec::integer("mean_k", 20, 1, 1000, "", "Neighbours per point."),
    ParamSpec::real("stddev_mul_thresh", 2.0, 0.0, 100.0, "",
                    "Standard-deviation multiplier of the distance threshold."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<StatisticalOutlierRemovalStage>(
      v.getInt("mean_k"), v.getDouble("stddev_mul_thresh"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
