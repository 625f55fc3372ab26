// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>

#include <cstddef>

namespace planar_grid {

/** \brief Options of estimateFloorPlane(), with their defaults. \ingroup odometry */
struct FloorEstimationParams {
  /** \brief Voxel edge the cloud is downsampled to first (pcl::VoxelGrid), metres
   * (> 0). */
  double leaf_size_m{0.05};
  /** \brief RANSAC inlier distance of a plane, metres (> 0). */
  double distance_threshold_m{0.03};
  /** \brief Largest angle between the floor's normal and the prior up direction,
   * radians, in (0, pi/2). */
  double eps_angle_rad{0.6};
  /** \brief The sensor must be at least this high above the floor, metres (>= 0):
   * tables and the ceiling are not taken for the floor. */
  double min_sensor_height_m{0.3};
  /** \brief A floor candidate needs at least this fraction of the downsampled points,
   * in (0, 1). */
  double min_inlier_fraction{0.02};
  /** \brief Most horizontal planes examined (each one's inliers are removed before the
   * next is sought), >= 1. */
  int max_planes{6};
  /** \brief RANSAC iterations per plane, >= 1. */
  int max_iterations{1000};
};

/** \brief Finds the floor (or the ground) of a scene: the plane roughly perpendicular
 * to the prior up direction that lies at least min_sensor_height_m below the sensor,
 * the lowest of the large ones (a candidate with at least a quarter of the inliers of
 * the largest candidate; a table top is higher, the ceiling is above the sensor). The
 * cloud is downsampled by pcl::VoxelGrid, only the points whose normal
 * (pcl::NormalEstimation, radius 3 leaf sizes) is within eps_angle_rad of the prior up
 * direction are kept, and planes come from pcl::SACSegmentation with
 * pcl::SACMODEL_PERPENDICULAR_PLANE (deterministic RANSAC, least-squares refit on the
 * inliers).
 * \param[in] cloud the points, any frame, metres; NaN points are ignored
 * \param[in] sensor_origin the sensor's position in the cloud's frame, metres
 * \param[in] up_prior the approximate up direction in the cloud's frame (non-zero)
 * \param[in] params the options
 * \param[out] model_coefficients the floor [a, b, c, d] with unit normal (a, b, c)
 *             pointing up (towards the sensor): a point's height above the floor is
 *             a x + b y + c z + d
 * \param[out] inliers the number of downsampled points on the floor
 * \return true when a floor was found; false (outputs untouched, a PCL_WARN) when the
 *         cloud has too few points or no plane qualifies
 * \ingroup odometry */
bool estimateFloorPlane(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                        const Eigen::Vector3f& sensor_origin,
                        const Eigen::Vector3f& up_prior,
                        const FloorEstimationParams& params,
                        Eigen::Vector4f& model_coefficients,
                        std::size_t& inliers);

/** \brief world_T_sensor of a sensor levelled on its floor: the world's z axis is the
 * floor normal, its x axis the sensor's \a forward direction projected on the floor,
 * and its origin on the floor below the sensor (so the floor is at z = 0).
 * \param[in] floor_coefficients the floor [a, b, c, d] in the sensor frame, unit normal
 *            pointing up (estimateFloorPlane())
 * \param[in] forward the sensor's forward direction in its own frame (z for a camera's
 *            optical frame, x for a LiDAR); must not be parallel to the normal
 * \return the pose (z-up world, metres)
 * \ingroup odometry */
Eigen::Isometry3d levelSensorPose(const Eigen::Vector4f& floor_coefficients,
                                  const Eigen::Vector3d& forward);

/** \brief The tilt of a plane from the horizontal of the z-up world, radians: the angle
 * between its normal and +-z, in [0, pi/2].
 * \param[in] model_coefficients the plane [a, b, c, d] (the normal need not be unit)
 * \ingroup odometry */
double planeTiltFromHorizontal(const Eigen::Vector4f& model_coefficients);

} // namespace planar_grid
