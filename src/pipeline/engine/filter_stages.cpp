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
// 4 bytes per point per listed filter stage). The voxel grid and the depth error filter
// are the exceptions: they take the whole dense cloud of each frame, whose index list
// and buffers (up to 28 bytes per pixel) would otherwise be allocated, and their fresh
// pages faulted in, for every frame. They drop the input cloud after each frame and
// the buffers after the last.
class VoxelGridStage : public Stage {
public:
  explicit VoxelGridStage(const FastVoxelGridParams& params) : params_(params) {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(fastVoxelGridParamDeclarations(), params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "voxel_grid"))
      return;
    if (!filter_) {
      filter_ = std::make_unique<FastVoxelGrid<pcl::PointXYZI>>();
      filter_->setParams(params_);
    }
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter_->setInputCloud(frame.cloud);
    filter_->filter(*out);
    filter_->setInputCloud(Frame::Cloud::ConstPtr());
    frame.cloud = out;
  }

  void finish(PipelineState& /*state*/) override { filter_.reset(); }

private:
  FastVoxelGridParams params_;
  std::unique_ptr<FastVoxelGrid<pcl::PointXYZI>> filter_;
};

class StatisticalOutlierRemovalStage : public Stage {
public:
  explicit StatisticalOutlierRemovalStage(
    const FastStatisticalOutlierRemovalParams& params) :
      params_(params)
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(fastStatisticalOutlierRemovalParamDeclarations(), params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "statistical_outlier_removal"))
      return;
    FastStatisticalOutlierRemoval<pcl::PointXYZI> filter;
    filter.setParams(params_);
    Frame::Cloud::Ptr out(new Frame::Cloud);
    filter.setInputCloud(frame.cloud);
    filter.filter(*out);
    frame.cloud = out;
  }

private:
  FastStatisticalOutlierRemovalParams params_;
};

/** depth_error_filter's own parameters beside DepthErrorFilter's: the second bound and
 * the far levels kept for range_adaptive_cells. */
struct DepthErrorStageParams {
  double max_plane_depth_error_m{0.0};
  int far_levels{0};
};

const ParamDeclarations<DepthErrorStageParams>&
depthErrorStageParamDeclarations()
{
  using P = DepthErrorStageParams;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "max_plane_depth_error_m",
      [](auto& p) -> auto& { return p.max_plane_depth_error_m; },
      ParamRange::closed(0.0, 100.0), "m",
      "Largest depth error Delta z of a point that may still join a plane (needs "
      "multi_plane_segmentation later in the pipeline); at or below max_depth_error_m "
      "(0, the default): none."),
    declareInteger<P>(
      "far_levels", [](auto& p) -> auto& { return p.far_levels; },
      ParamRange::closed(0, 4), "",
      "Range-adaptive cells: the dropped points whose depth error is within "
      "max_depth_error_m x 2^far_levels are kept aside for range_adaptive_cells, which "
      "maps level l (error within max_depth_error_m x 2^l) at cells 2^l times its "
      "minimum; 0 (the default): dropped. With max_plane_depth_error_m, the points "
      "between the two bounds are kept aside too, and multi_plane_segmentation takes "
      "out the ones a plane takes."),
  };
  return table;
}

class DepthErrorFilterStage : public Stage {
public:
  DepthErrorFilterStage(const DepthErrorFilterParams& params,
                        const DepthErrorStageParams& stage_params) :
      params_(params),
      stage_params_(stage_params),
      max_plane_depth_error_m_(
        std::max(params.max_depth_error_m, stage_params.max_plane_depth_error_m))
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(depthErrorFilterParamDeclarations(), params_, v);
    reportParams(depthErrorStageParamDeclarations(), stage_params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (!hasPoints(frame, "depth_error_filter"))
      return;
    const double error_at_1m =
      frame.calibration.depthError(1.0, params_.disparity_error_px);
    if (!(std::isfinite(error_at_1m) && error_at_1m > 0.0))
      throw Exception("stage 'depth_error_filter' needs a stereo calibration (frame "
                      + frame.name + " has none)");
    // The finite points beyond each bound (eq. 4), by DepthErrorFilter. The filter,
    // its index list and the masks stay with the stage from frame to frame (dense
    // clouds of one size: nothing is allocated again); the filter drops the cloud
    // after the frame.
    if (!filter_)
      filter_ = std::make_unique<DepthErrorFilter<Frame::Cloud::PointType>>();
    DepthErrorFilter<Frame::Cloud::PointType>& filter = *filter_;
    filter.setParams(params_);
    filter.setCalibration(frame.calibration);
    filter.setCameraTransform(cameraTCloud(frame));
    filter.setInputCloud(frame.cloud);
    filter.setNegative(true);
    const auto beyondBound = [&](double max_depth_error_m, float& max_depth,
                                 std::vector<std::uint8_t>& mask) {
      filter.setMaxDepthError(max_depth_error_m);
      max_depth = static_cast<float>(filter.getMaxDepth());
      filter.filter(beyond_indices_);
      mask.assign(frame.cloud->size(), 0);
      for (const auto index : beyond_indices_)
        mask[static_cast<std::size_t>(index)] = 1;
    };
    // The points between the two bounds stay, for the planes alone.
    beyondBound(params_.max_depth_error_m, max_depth_m_, beyond_);
    const std::vector<std::uint8_t>& beyond = beyond_;
    // With one bound the points beyond it are the far ones: no second pass.
    const bool two_bounds = max_plane_depth_error_m_ > params_.max_depth_error_m;
    if (two_bounds)
      beyondBound(max_plane_depth_error_m_, max_plane_depth_m_, beyond_plane_bound_);
    else
      max_plane_depth_m_ = max_depth_m_;
    filter.setInputCloud(Frame::Cloud::ConstPtr());
    const std::vector<std::uint8_t>& far = two_bounds ? beyond_plane_bound_ : beyond;
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
    if (stage_params_.far_levels > 0)
      keepFarPoints(frame, beyond, error_at_1m);
    removed_ = removePoints(frame, far);
    if (max_plane_depth > max_depth)
      frame.inlier_only_depth_m = std::min(frame.inlier_only_depth_m, max_depth);
  }

  void finish(PipelineState& /*state*/) override
  {
    filter_.reset();
    beyond_indices_ = pcl::Indices();
    beyond_ = std::vector<std::uint8_t>();
    beyond_plane_bound_ = std::vector<std::uint8_t>();
  }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("max_depth_m", static_cast<double>(max_depth_m_));
    values.emplace_back("far_points", static_cast<double>(removed_));
    if (stage_params_.far_levels > 0)
      values.emplace_back("far_points_kept", static_cast<double>(kept_far_));
    if (max_plane_depth_error_m_ > params_.max_depth_error_m) {
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
    std::vector<float> level_depth(static_cast<std::size_t>(stage_params_.far_levels)
                                   + 1);
    for (int l = 0; l <= stage_params_.far_levels; ++l)
      level_depth[static_cast<std::size_t>(l)] = static_cast<float>(
        std::sqrt(params_.max_depth_error_m * std::ldexp(1.0, l) / error_at_1m));
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

  DepthErrorFilterParams params_;
  DepthErrorStageParams stage_params_;
  /** The plane bound, raised to max_depth_error_m. */
  double max_plane_depth_error_m_;
  /** The filter, the indices it returns and the masks of the points beyond each bound,
   * kept from one frame to the next. */
  std::unique_ptr<DepthErrorFilter<Frame::Cloud::PointType>> filter_;
  pcl::Indices beyond_indices_;
  std::vector<std::uint8_t> beyond_, beyond_plane_bound_;
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
  info.params = paramSpecs(depthErrorFilterParamDeclarations());
  const auto stage_params = paramSpecs(depthErrorStageParamDeclarations());
  info.params.insert(info.params.end(), stage_params.begin(), stage_params.end());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    DepthErrorFilterParams params;
    assignParams(depthErrorFilterParamDeclarations(), v, params);
    DepthErrorStageParams stage_params;
    assignParams(depthErrorStageParamDeclarations(), v, stage_params);
    return std::make_unique<DepthErrorFilterStage>(params, stage_params);
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
  info.params = paramSpecs(fastVoxelGridParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    FastVoxelGridParams params;
    assignParams(fastVoxelGridParamDeclarations(), v, params);
    return std::make_unique<VoxelGridStage>(params);
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
  info.params = paramSpecs(fastStatisticalOutlierRemovalParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    FastStatisticalOutlierRemovalParams params;
    assignParams(fastStatisticalOutlierRemovalParamDeclarations(), v, params);
    return std::make_unique<StatisticalOutlierRemovalStage>(params);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
