// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/map/surface_layer.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>

#include <vector>

namespace planar_grid {

/** \brief One frame's measurements as PlanarGridMap::integrate() takes them: what the
 * surface layer merges (cuboids, plane models, feature occupancies), where the sensor
 * was, and one measurement of the explicit space layer (a depth image or a scan of
 * rays), plus the frame's place in its recording and the rolling window.
 *
 * The pointers are not owned: each must stay valid during the call. A null pointer is
 * an empty input, except that exactly one of depth and rays must be set. All poses
 * and points are in meters. \ingroup map */
struct MapFrame {
  /** \brief The frame's cuboids, world frame (PlanarCuboid::plane_id indexes
   * \a planes); null: none. */
  const PlanarCuboids* cuboids{nullptr};
  /** \brief The frame's plane models [a, b, c, d], world frame (unit normal, d in
   * meters), one per plane id; null: none. */
  const PlaneModels* planes{nullptr};
  /** \brief Feature points, world frame, meters; null: none. */
  const pcl::PointCloud<pcl::PointXYZ>* features{nullptr};
  /** \brief Occupancy probability in [0, 1] of each feature point, as many as
   * \a features; null: none. */
  const std::vector<float>* probabilities{nullptr};
  /** \brief The sensor's pose: rigid transform from the sensor frame (for a depth
   * image its camera frame: x right, y down, z forward) to the world frame,
   * translation in meters; finite. */
  Eigen::Isometry3d world_T_sensor{Eigen::Isometry3d::Identity()};
  /** \brief The space measurement of a pinhole sensor: the depth image of the camera
   * at world_T_sensor (depths in meters along its optical axis). Set exactly one of
   * depth and rays. */
  const DepthImage* depth{nullptr};
  /** \brief The space measurement of a scan: the end points of rays from the sensor
   * origin (world_T_sensor's translation), world frame, meters, for any field of view
   * (a 360 degree LiDAR scan). Set exactly one of depth and rays. */
  const pcl::PointCloud<pcl::PointXYZ>* rays{nullptr};
  /** \brief The frame's order key (PlanarGridMap::noteObservationOrder()): any finite
   * number that grows with the time of the frames, e.g. its index in the recording. */
  double observation_order{0.0};
  /** \brief The rolling window's half-size, meters (finite, >= 0): after the frame the
   * map keeps only the box of this half-size around the sensor in x and y (world z up;
   * every height) and drops the rest of both layers (PlanarGridMap::removeOutside()).
   * 0: off, the map grows with the run. */
  double window_half_size_m{0.0};
};

} // namespace planar_grid
