// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/map/plane_registry.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>

namespace planar_grid {

template <typename PointT>
int
PlaneRegistry::addPlane(const pcl::PointCloud<PointT>& cloud,
                        const pcl::ModelCoefficients& model_coefficients,
                        const pcl::PointIndices& inliers)
{
  if (model_coefficients.values.size() != 4) {
    PCL_WARN("[planar_grid::PlaneRegistry::addPlane] A plane with %zu coefficients "
             "instead of 4.\n",
             model_coefficients.values.size());
    return -1;
  }
  for (const auto i : inliers.indices)
    if (i < 0 || static_cast<std::size_t>(i) >= cloud.size()) {
      PCL_WARN("[planar_grid::PlaneRegistry::addPlane] Inlier index %d outside the "
               "cloud of %zu points.\n",
               i, cloud.size());
      return -1;
    }
  const int id = associate(Eigen::Vector4f(model_coefficients.values.data()),
                           inliers.indices.size());
  if (id < 0)
    return -1;
  for (const auto i : inliers.indices)
    appendInlier(cloud[static_cast<std::size_t>(i)], static_cast<std::uint32_t>(id));
  return id;
}

template <typename PointT>
void
PlaneRegistry::addPlanes(const pcl::PointCloud<PointT>& cloud,
                         const std::vector<pcl::ModelCoefficients>& model_coefficients,
                         const std::vector<pcl::PointIndices>& inliers,
                         std::vector<int>& plane_ids)
{
  plane_ids.clear();
  if (model_coefficients.size() != inliers.size()) {
    PCL_ERROR("[planar_grid::PlaneRegistry::addPlanes] %zu model_coefficients but %zu "
              "inliers.\n",
              model_coefficients.size(), inliers.size());
    return;
  }
  plane_ids.reserve(model_coefficients.size());
  for (std::size_t k = 0; k < model_coefficients.size(); ++k)
    plane_ids.push_back(addPlane(cloud, model_coefficients[k], inliers[k]));
}

template <typename PointT>
void
cropToWindowXY(pcl::PointCloud<PointT>& cloud,
               const Eigen::Vector3d& sensor_origin,
               double window_half_size_m)
{
  const double r = window_half_size_m;
  const auto outside = [&](const PointT& p) {
    return !(std::abs(p.x - sensor_origin.x()) <= r
             && std::abs(p.y - sensor_origin.y()) <= r);
  };
  auto& points = cloud.points;
  points.erase(std::remove_if(points.begin(), points.end(), outside), points.end());
  cloud.width = static_cast<std::uint32_t>(points.size());
  cloud.height = 1;
}

} // namespace planar_grid
