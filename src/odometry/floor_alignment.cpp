// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/odometry/floor_alignment.h>

#include <pcl/console/print.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/extract_indices.h>
#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/search/kdtree.h>
#include <pcl/segmentation/sac_segmentation.h>

#include <algorithm>
#include <cmath>
#include <vector>

namespace planar_grid {

bool
estimateFloorPlane(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                   const Eigen::Vector3f& sensor_origin,
                   const Eigen::Vector3f& up_prior,
                   const FloorEstimationParams& params,
                   Eigen::Vector4f& model_coefficients,
                   std::size_t& inliers)
{
  using Cloud = pcl::PointCloud<pcl::PointXYZ>;
  if (!(up_prior.norm() > 0.0f)) {
    PCL_WARN("[planar_grid::estimateFloorPlane] The prior up direction is zero.\n");
    return false;
  }
  const Eigen::Vector3f up = up_prior.normalized();
  Cloud::Ptr finite(new Cloud);
  pcl::Indices kept;
  pcl::removeNaNFromPointCloud(cloud, *finite, kept);
  Cloud::Ptr remaining(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  const auto leaf = static_cast<float>(params.leaf_size_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.setInputCloud(finite);
  grid.filter(*remaining);
  const std::size_t total = remaining->size();
  const auto min_inliers =
    std::max<std::size_t>(3, static_cast<std::size_t>(params.min_inlier_fraction
                                                      * static_cast<double>(total)));
  if (total < min_inliers || total < 3) {
    PCL_WARN("[planar_grid::estimateFloorPlane] Only %zu points; no floor.\n", total);
    return false;
  }
  // Only points on surfaces that face up (or down) within the angle: without walls,
  // RANSAC cannot take a slanted cut through them for a plane.
  {
    pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
    estimation.setInputCloud(remaining);
    estimation.setSearchMethod(
      pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
    estimation.setRadiusSearch(3.0 * params.leaf_size_m);
    pcl::PointCloud<pcl::Normal> normals;
    estimation.compute(normals);
    const auto cos_eps = static_cast<float>(std::cos(params.eps_angle_rad));
    Cloud::Ptr facing_up(new Cloud);
    for (std::size_t i = 0; i < remaining->size(); ++i) {
      const Eigen::Vector3f n = normals[i].getNormalVector3fMap();
      if (std::isfinite(n.x()) && std::abs(n.dot(up)) >= cos_eps)
        facing_up->push_back((*remaining)[i]);
    }
    remaining = facing_up;
  }

  struct Candidate {
    Eigen::Vector4f coefficients;
    std::size_t inliers;
    float sensor_height;
  };
  std::vector<Candidate> candidates;
  pcl::SACSegmentation<pcl::PointXYZ> segmentation;
  segmentation.setModelType(pcl::SACMODEL_PERPENDICULAR_PLANE);
  segmentation.setMethodType(pcl::SAC_RANSAC);
  segmentation.setAxis(up);
  segmentation.setEpsAngle(params.eps_angle_rad);
  segmentation.setDistanceThreshold(params.distance_threshold_m);
  segmentation.setMaxIterations(params.max_iterations);
  segmentation.setOptimizeCoefficients(true);
  for (int k = 0; k < params.max_planes && remaining->size() >= min_inliers; ++k) {
    pcl::PointIndices::Ptr plane(new pcl::PointIndices);
    pcl::ModelCoefficients coefficients;
    segmentation.setInputCloud(remaining);
    segmentation.segment(*plane, coefficients);
    if (plane->indices.size() < min_inliers || coefficients.values.size() != 4)
      break;
    Eigen::Vector4f c(coefficients.values.data());
    c /= c.head<3>().norm();
    if (c.head<3>().dot(up) < 0.0f)
      c = -c;
    // The least-squares refit may leave the angular window; such a plane is a wall
    // or a slope, not the floor.
    const float height = c.head<3>().dot(sensor_origin) + c[3];
    if (c.head<3>().dot(up) >= std::cos(params.eps_angle_rad)
        && height >= params.min_sensor_height_m)
      candidates.push_back({c, plane->indices.size(), height});
    pcl::ExtractIndices<pcl::PointXYZ> extract;
    extract.setInputCloud(remaining);
    extract.setIndices(plane);
    extract.setNegative(true);
    Cloud::Ptr rest(new Cloud);
    extract.filter(*rest);
    remaining = rest;
  }
  if (candidates.empty()) {
    PCL_WARN("[planar_grid::estimateFloorPlane] No plane within %g rad of the up "
             "direction lies %g m or more below the sensor.\n",
             params.eps_angle_rad, params.min_sensor_height_m);
    return false;
  }
  std::size_t largest = 0;
  for (const auto& c : candidates)
    largest = std::max(largest, c.inliers);
  const Candidate* floor = nullptr;
  for (const auto& c : candidates)
    if (4 * c.inliers >= largest
        && (floor == nullptr || c.sensor_height > floor->sensor_height))
      floor = &c;
  model_coefficients = floor->coefficients;
  inliers = floor->inliers;
  return true;
}

Eigen::Isometry3d
levelSensorPose(const Eigen::Vector4f& floor_coefficients,
                const Eigen::Vector3d& forward)
{
  const Eigen::Vector3d up = floor_coefficients.head<3>().cast<double>().normalized();
  const Eigen::Vector3d x = (forward - up * up.dot(forward)).normalized();
  const Eigen::Vector3d y = up.cross(x);
  // The rows of world_R_sensor are the world axes in the sensor frame.
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear().row(0) = x.transpose();
  pose.linear().row(1) = y.transpose();
  pose.linear().row(2) = up.transpose();
  // The sensor (the sensor frame's origin) is its height above the floor up.
  const double height =
    static_cast<double>(floor_coefficients[3]) / floor_coefficients.head<3>().norm();
  pose.translation() = Eigen::Vector3d(0.0, 0.0, height);
  return pose;
}

double
planeTiltFromHorizontal(const Eigen::Vector4f& model_coefficients)
{
  const Eigen::Vector3d n = model_coefficients.head<3>().cast<double>().normalized();
  return std::acos(std::min(1.0, std::abs(n.z())));
}

} // namespace planar_grid
