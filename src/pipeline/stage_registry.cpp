// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stages.h"

namespace planar_grid {

const std::vector<StageInfo>&
stageRegistry()
{
  // Built once, in pipeline order.
  static const std::vector<StageInfo> registry{
    // clang-format off
    stages::stereoDisparityInfo(),
    stages::featureMatchingInfo(),
    stages::klOccupancyFilterInfo(),
    stages::visualOdometryInfo(),
    stages::depthErrorFilterInfo(),
    stages::voxelGridInfo(),
    stages::statisticalOutlierRemovalInfo(),
    stages::transformToWorldInfo(),
    stages::multiPlaneSegmentationInfo(),
    stages::groundRemovalInfo(),
    stages::planarCuboidApproximationInfo(),
    stages::mapIntegrationInfo(),
    stages::accumulateInfo(),
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
  std::size_t n = 0;
  for (const auto& p : cloud.points)
    n += std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z);
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

void
requirePoints(const Frame& frame, const char* stage_type)
{
  if (!frame.cloud || countValidPoints(*frame.cloud) == 0)
    throw Exception(std::string("stage '") + stage_type
                    + "' received 0 points in frame " + frame.name + " ("
                    + std::to_string(frame.sequence_number)
                    + "); check the earlier stages' parameters and the input");
}

} // namespace stages
} // namespace planar_grid
