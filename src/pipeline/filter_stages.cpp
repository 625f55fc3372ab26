// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/depth_error_filter.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/fast_voxel_grid.h>

#include <pcl/common/point_tests.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <memory>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

// The PCL filters are made for each frame: a filter kept in the stage keeps, until the
// next frame, its input cloud and the index list PCLBase makes for it (one cloud and
// 4 bytes per point per listed filter stage).
class VoxelGridStage : public Stage {
public:
  VoxelGridStage(double leaf_size_m, int min_points_per_voxel) :
      leaf_size_m_(static_cast<float>(leaf_size_m)),
      min_points_per_voxel_(static_cast<unsigned int>(min_points_per_voxel))
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    v.set("leaf_size_m", static_cast<double>(leaf_size_m_));
    v.set("min_points_per_voxel", static_cast<int>(min_points_per_voxel_));
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "voxel_grid"))
      return;
    FastVoxelGrid<pcl::PointXYZI> filter;
    filter.setLeafSize(leaf_size_m_, leaf_size_m_, leaf_size_m_);
    filter.setMinimumPointsNumberPerVoxel(min_points_per_voxel_);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter.setInputCloud(frame.cloud);
    filter.filter(*out);
    frame.cloud = out;
  }

private:
  float leaf_size_m_;
  unsigned int min_points_per_voxel_;
};

class StatisticalOutlierRemovalStage : public Stage {
public:
  StatisticalOutlierRemovalStage(int mean_k, double stddev_mul_thresh) :
      mean_k_(mean_k), stddev_mul_thresh_(stddev_mul_thresh)
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    v.set("mean_k", mean_k_);
    v.set("stddev_mul_thresh", stddev_mul_thresh_);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "statistical_outlier_removal"))
      return;
    FastStatisticalOutlierRemoval<pcl::PointXYZI> filter;
    filter.setMeanK(mean_k_);
    filter.setStddevMulThresh(stddev_mul_thresh_);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter.setInputCloud(frame.cloud);
    filter.filter(*out);
    frame.cloud = out;
  }

private:
  int mean_k_;
  double stddev_mul_thresh_;
};

class DepthErrorFilterStage : public Stage {
public:
  DepthErrorFilterStage(double disparity_error_px,
                        double max_depth_error_m,
                        double max_plane_depth_error_m,
                        int far_levels) :
      disparity_error_px_(disparity_error_px),
      max_depth_error_m_(max_depth_error_m),
      max_plane_depth_error_m_(std::max(max_depth_error_m, max_plane_depth_error_m)),
      far_levels_(far_levels)
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    // max_plane_depth_error_m is held raised to max_depth_error_m, so it is not
    // read back.
    v.set("disparity_error_px", disparity_error_px_);
    v.set("max_depth_error_m", max_depth_error_m_);
    v.set("far_levels", far_levels_);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "depth_error_filter"))
      return;
    const double error_at_1m = frame.calibration.depthError(1.0, disparity_error_px_);
    if (!(std::isfinite(error_at_1m) && error_at_1m > 0.0))
      throw Exception("stage 'depth_error_filter' needs a stereo calibration (frame "
                      + frame.name + " has none)");
    // The finite points beyond each bound (eq. 4), by DepthErrorFilter.
    DepthErrorFilter<Frame::Cloud::PointType> filter;
    filter.setCalibration(frame.calibration);
    filter.setDisparityError(disparity_error_px_);
    filter.setCameraTransform(cameraTCloud(frame));
    filter.setInputCloud(frame.cloud);
    filter.setNegative(true);
    const auto beyondBound = [&](double max_depth_error_m, float& max_depth) {
      filter.setMaxDepthError(max_depth_error_m);
      max_depth = static_cast<float>(filter.getMaxDepth());
      pcl::Indices beyond;
      filter.filter(beyond);
      std::vector<std::uint8_t> mask(frame.cloud->size(), 0);
      for (const auto index : beyond)
        mask[static_cast<std::size_t>(index)] = 1;
      return mask;
    };
    // Per frame, not kept in the stage: the stage may be listed more than once.
    // The points between the two bounds stay, for the planes alone.
    const std::vector<std::uint8_t> beyond =
      beyondBound(max_depth_error_m_, max_depth_m_);
    // With one bound the points beyond it are the far ones: no second pass.
    const bool two_bounds = max_plane_depth_error_m_ > max_depth_error_m_;
    std::vector<std::uint8_t> beyond_plane_bound;
    if (two_bounds)
      beyond_plane_bound = beyondBound(max_plane_depth_error_m_, max_plane_depth_m_);
    else
      max_plane_depth_m_ = max_depth_m_;
    const std::vector<std::uint8_t>& far = two_bounds ? beyond_plane_bound : beyond;
    const float max_depth = max_depth_m_;
    const float max_plane_depth = max_plane_depth_m_;
    inlier_only_ = 0;
    if (two_bounds)
      for (std::size_t i = 0; i < far.size(); ++i)
        inlier_only_ += beyond[i] && !far[i];
    kept_far_ = 0;
    // Every point beyond the cell bound may make a far cell; the ones between the two
    // bounds also stay in the cloud, and multi_plane_segmentation takes out of the far
    // cloud those a plane takes.
    if (far_levels_ > 0)
      keepFarPoints(frame, beyond, error_at_1m);
    removed_ = removePoints(frame, far);
    if (max_plane_depth > max_depth)
      frame.inlier_only_depth_m = std::min(frame.inlier_only_depth_m, max_depth);
  }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("max_depth_m", static_cast<double>(max_depth_m_));
    values.emplace_back("far_points", static_cast<double>(removed_));
    if (far_levels_ > 0)
      values.emplace_back("far_points_kept", static_cast<double>(kept_far_));
    if (max_plane_depth_error_m_ > max_depth_error_m_) {
      values.emplace_back("max_plane_depth_m", static_cast<double>(max_plane_depth_m_));
      values.emplace_back("inlier_only_points", static_cast<double>(inlier_only_));
    }
  }

private:
  /** The points \a far marks whose depth error is within max_depth_error_m x
   * 2^far_levels, in the camera frame with their level, into the frame's far_cloud. */
  void
  keepFarPoints(Frame& frame, const std::vector<std::uint8_t>& far, double error_at_1m)
  {
    const auto& cloud = *frame.cloud;
    const Eigen::Affine3f camera_T_cloud = cameraTCloud(frame);
    auto out = std::make_shared<Frame::Cloud>();
    std::vector<std::uint8_t> levels;
    // Level l holds the depths whose error is in (max 2^(l-1), max 2^l]: depth bounds
    // sqrt(max 2^l / error at 1 m).
    std::vector<float> level_depth(static_cast<std::size_t>(far_levels_) + 1);
    for (int l = 0; l <= far_levels_; ++l)
      level_depth[static_cast<std::size_t>(l)] = static_cast<float>(
        std::sqrt(max_depth_error_m_ * std::ldexp(1.0, l) / error_at_1m));
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      if (!far[i])
        continue;
      pcl::PointXYZI p = cloud[i];
      p.getVector3fMap() = camera_T_cloud * cloud[i].getVector3fMap();
      if (!(p.z > level_depth[0]) || p.z > level_depth.back())
        continue;
      std::uint8_t level = 1;
      while (p.z > level_depth[level])
        ++level;
      out->push_back(p);
      levels.push_back(level);
    }
    kept_far_ = out->size();
    frame.far_cloud = std::move(out);
    frame.far_levels = std::move(levels);
  }

  double disparity_error_px_;
  double max_depth_error_m_;
  double max_plane_depth_error_m_;
  int far_levels_;
  std::size_t kept_far_{0};
  float max_depth_m_{0.0f};
  float max_plane_depth_m_{0.0f};
  std::size_t removed_{0};
  std::size_t inlier_only_{0};
};

} // namespace

StageInfo
depthErrorFilterInfo()
{
  StageInfo info;
  info.type = "depth_error_filter";
  info.description =
    "Drops the points whose stereo depth error (eq. 4: Delta z = z^2 Delta d / (B f), "
    "z the depth along the optical axis) exceeds max_depth_error_m, so that they make "
    "no planes or cells; the disparity image, which the map's free space is carved "
    "from, keeps them. With max_plane_depth_error_m above it, the points between the "
    "two bounds stay for multi_plane_segmentation alone: they may join the planes the "
    "nearer points and the key features make (eq. 11), and the ones no plane takes "
    "are dropped there, so that they make no non-planar cells. Needs stereo input (its "
    "calibration).";
  info.params = {
    ParamSpec::real("disparity_error_px", 0.5,
                    depth_error_filter_ranges::DISPARITY_ERROR, "px",
                    "Delta d of eq. 4 (the paper's 0.5 px)."),
    ParamSpec::real("max_depth_error_m", 0.3,
                    depth_error_filter_ranges::MAX_DEPTH_ERROR, "m",
                    "Largest depth error Delta z of a point that is kept."),
    ParamSpec::real("max_plane_depth_error_m", 0.0, 0.0, 100.0, "m",
                    "Largest depth error Delta z of a point that may still join a "
                    "plane (needs multi_plane_segmentation later in the pipeline); at "
                    "or below max_depth_error_m (0, the default): none."),
    ParamSpec::integer("far_levels", 0, 0, 4, "",
                       "Range-adaptive cells: the dropped points whose depth error is "
                       "within max_depth_error_m x 2^far_levels are kept aside for "
                       "range_adaptive_cells, which maps level l (error within "
                       "max_depth_error_m x 2^l) at cells 2^l times its minimum; 0 "
                       "(the default): dropped. With max_plane_depth_error_m, the "
                       "points between the two bounds are kept aside too, and "
                       "multi_plane_segmentation takes out the ones a plane takes."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<DepthErrorFilterStage>(
      v.getDouble("disparity_error_px"), v.getDouble("max_depth_error_m"),
      v.getDouble("max_plane_depth_error_m"), v.getInt("far_levels"));
  };
  return info;
}

StageInfo
voxelGridInfo()
{
  StageInfo info;
  info.type = "voxel_grid";
  info.description =
    "One centroid per occupied voxel of the working cloud: pcl::VoxelGrid's output "
    "(FastVoxelGrid).";
  info.params = {
    ParamSpec::real("leaf_size_m", 0.05, 0.001, 10.0, "m",
                    "Voxel edge length (the pipeline's value; the filter class has "
                    "none that fits a stereo cloud).")
      .scalesWithCellSize(),
    ParamSpec::integer("min_points_per_voxel", 1, 1, 100000, "",
                       "Voxels with fewer points are dropped (1 keeps every voxel, as "
                       "the class's 0 does)."),
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
    "pcl::StatisticalOutlierRemoval's filter (FastStatisticalOutlierRemoval, the same "
    "points kept, nanoflann's kd-tree): drops points whose mean distance to their k "
    "nearest neighbours exceeds the global mean by more than stddev_mul_thresh "
    "standard deviations.";
  info.params = {
    ParamSpec::integer("mean_k", 20, fast_statistical_outlier_removal_ranges::MEAN_K,
                       "",
                       "Neighbours per point (the pipeline's value; the class keeps "
                       "pcl::StatisticalOutlierRemoval's 1)."),
    ParamSpec::real("stddev_mul_thresh", 2.0, 0.0, 100.0, "",
                    "Standard-deviation multiplier of the distance threshold (the "
                    "pipeline's value; the class keeps PCL's 0)."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<StatisticalOutlierRemovalStage>(
      v.getInt("mean_k"), v.getDouble("stddev_mul_thresh"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
