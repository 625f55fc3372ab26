// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/stage.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stages.h"

namespace planar_grid {

namespace {

/** \a info with its role and data flow declared: front end or mapping stage, what it
 * needs, what it produces, and whether it may be listed more than once. */
StageInfo
declare(StageInfo info,
        StageRole role,
        std::vector<StageData> needs,
        std::vector<StageData> produces,
        bool repeatable = false)
{
  info.role = role;
  info.needs = std::move(needs);
  info.produces = std::move(produces);
  info.repeatable = repeatable;
  return info;
}

} // namespace

std::string
stageDataName(StageData data)
{
  switch (data) {
    case StageData::STEREO_IMAGES:
      return "stereo images";
    case StageData::CLOUD:
      return "a point cloud";
    case StageData::DISPARITY:
      return "a disparity image";
    case StageData::FEATURES:
      return "key features";
    case StageData::FEATURE_OCCUPANCY:
      return "feature occupancy probabilities";
    case StageData::POSES:
      return "camera poses";
    case StageData::WORLD_FRAME:
      return "a world-frame cloud";
    case StageData::PLANES:
      return "planes";
    case StageData::CUBOIDS:
      return "cuboids";
    case StageData::MAP:
      return "a map";
    case StageData::WORLD_CLOUD:
      return "an accumulated world cloud";
  }
  return "?";
}

std::string
stageDataNames(const std::vector<StageData>& data)
{
  std::string list;
  for (const auto d : data)
    list += (list.empty() ? "" : ", ") + stageDataName(d);
  return list.empty() ? std::string("nothing") : list;
}

const std::vector<StageInfo>&
stageRegistry()
{
  using D = StageData;
  using R = StageRole;
  // Built once, in pipeline order, each with its role and the data it needs and
  // produces: the loader checks a pipeline's order against these before the first
  // frame. Only the filters of the working cloud may be listed twice (e.g. a coarse
  // and a fine voxel_grid); a second map_integration or segmentation would overwrite
  // the first one's result. cloud_features is a mapping stage: it reads the working
  // cloud, which the filters before it shape at the map's cell size.
  static const std::vector<StageInfo> registry{
    // clang-format off
    declare(stages::stereoDisparityInfo(), R::FRONT_END, {D::STEREO_IMAGES}, {D::CLOUD, D::DISPARITY}),
    declare(stages::featureMatchingInfo(), R::FRONT_END, {D::STEREO_IMAGES}, {D::FEATURES}),
    declare(stages::cloudFeaturesInfo(), R::MAPPING, {D::CLOUD}, {D::FEATURES}),
    declare(stages::klOccupancyFilterInfo(), R::FRONT_END, {D::FEATURES}, {D::FEATURE_OCCUPANCY}),
    declare(stages::visualOdometryInfo(), R::FRONT_END, {D::STEREO_IMAGES, D::FEATURES}, {D::POSES}),
    declare(stages::depthErrorFilterInfo(), R::MAPPING, {D::STEREO_IMAGES, D::CLOUD}, {}, true),
    declare(stages::voxelGridInfo(), R::MAPPING, {D::CLOUD}, {}, true),
    declare(stages::statisticalOutlierRemovalInfo(), R::MAPPING, {D::CLOUD}, {}, true),
    declare(stages::transformToWorldInfo(), R::MAPPING, {D::CLOUD, D::POSES}, {D::WORLD_FRAME}),
    declare(stages::multiPlaneSegmentationInfo(), R::MAPPING, {D::CLOUD}, {D::PLANES}),
    declare(stages::groundRemovalInfo(), R::MAPPING, {D::PLANES}, {}),
    declare(stages::planarCuboidApproximationInfo(), R::MAPPING, {D::CLOUD, D::PLANES}, {D::CUBOIDS}),
    declare(stages::rangeAdaptiveCellsInfo(), R::MAPPING, {D::CUBOIDS}, {}),
    declare(stages::mapIntegrationInfo(), R::MAPPING, {D::POSES, D::WORLD_FRAME, D::CUBOIDS}, {D::MAP}),
    declare(stages::accumulateInfo(), R::MAPPING, {D::WORLD_FRAME}, {D::WORLD_CLOUD}),
    // clang-format on
  };
  return registry;
}

const StageInfo*
findStage(const std::string& type)
{
  for (const auto& info : stageRegistry())
    if (info.type == type)
      return &info;
  return nullptr;
}

std::vector<StageNeed>
stageNeeds(const StageInfo& info, const ParamValues& params)
{
  std::vector<StageNeed> needs;
  for (const StageData d : info.needs)
    needs.push_back({d, "", ""});
  if (info.type == "multi_plane_segmentation"
      && params.getChoice("sample") == "features")
    needs.push_back({StageData::FEATURES, "sample", "cloud"});
  if (info.type == "stereo_disparity"
      && params.getChoice("frame_selection") == "keyframes")
    needs.push_back({StageData::POSES, "frame_selection", "every_n_frames"});
  return needs;
}

std::string
knownStageTypes()
{
  std::string list;
  for (const auto& info : stageRegistry())
    list += (list.empty() ? "" : ", ") + info.type;
  return list;
}

namespace stages {

std::size_t
countValidPoints(const pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  if (cloud.is_dense)
    return cloud.size();
  // Branch-free: v - v is 0 for a finite v and NaN for an infinite or NaN one, and a
  // sum with a NaN is NaN.
  std::size_t n = 0;
  for (const auto& p : cloud.points)
    n += ((p.x - p.x) + (p.y - p.y) + (p.z - p.z)) == 0.0f ? 1 : 0;
  return n;
}

Eigen::Vector3f
upAxis(const Frame& frame)
{
  return frame.cloud_in_world_frame ? Eigen::Vector3f::UnitZ()
                                    : Eigen::Vector3f(0.0f, -1.0f, 0.0f);
}

Eigen::Vector3f
sensorOrigin(const Frame& frame)
{
  if (frame.cloud_in_world_frame)
    return frame.world_T_camera.translation().cast<float>();
  return Eigen::Vector3f::Zero();
}

Eigen::Affine3f
cameraTCloud(const Frame& frame)
{
  if (frame.cloud_in_world_frame)
    return frame.world_T_camera.inverse().cast<float>();
  return Eigen::Affine3f::Identity();
}

std::size_t
removePoints(Frame& frame, const std::vector<std::uint8_t>& remove)
{
  auto& cloud = *frame.cloud;
  std::size_t removed = 0;
  if (cloud.isOrganized()) {
    const float nan = std::numeric_limits<float>::quiet_NaN();
    for (std::size_t i = 0; i < cloud.size(); ++i)
      if (remove[i]) {
        cloud[i].x = cloud[i].y = cloud[i].z = nan;
        ++removed;
      }
    cloud.is_dense = false;
    return removed;
  }
  std::vector<int> new_index(cloud.size(), -1);
  Frame::Cloud::Ptr out(new Frame::Cloud);
  out->header = cloud.header;
  out->sensor_origin_ = cloud.sensor_origin_;
  out->sensor_orientation_ = cloud.sensor_orientation_;
  out->reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (remove[i]) {
      ++removed;
      continue;
    }
    new_index[i] = static_cast<int>(out->size());
    out->push_back(cloud[i]);
  }
  out->is_dense = cloud.is_dense;
  for (auto& plane : frame.planes) {
    auto& indices = plane.inliers.indices;
    for (auto& i : indices)
      i = new_index[static_cast<std::size_t>(i)];
    indices.erase(std::remove(indices.begin(), indices.end(), -1), indices.end());
  }
  frame.cloud = out;
  return removed;
}

bool
hasPoints(Frame& frame, const char* stage_type)
{
  // One finite point is enough: most clouds answer at their first points, where a
  // count would read all of them.
  const auto finite = [](const pcl::PointXYZI& p) {
    return std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
  };
  if (frame.cloud && !frame.cloud->empty()
      && (frame.cloud->is_dense
          || std::any_of(frame.cloud->begin(), frame.cloud->end(), finite)))
    return true;
  if (frame.no_points_stage.empty()) {
    frame.no_points_stage = stage_type;
    PCL_WARN("[planar_grid::PipelineRunner] frame %s (%zu): no points reached stage "
             "'%s'; the frame adds nothing to the map (check the input and the "
             "earlier stages' parameters)\n",
             frame.name.c_str(), frame.sequence_number, stage_type);
  }
  return false;
}

} // namespace stages
} // namespace planar_grid
