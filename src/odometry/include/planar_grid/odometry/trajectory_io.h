// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <string>
#include <vector>

namespace planar_grid {

/** \brief Camera poses world_T_camera, one per frame: a camera-frame point p (x right,
  * y down, z forward, metres) is at world_T_camera * p in the world frame. \ingroup odometry */
using Trajectory = std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>;

/** \brief Reads a Karlsruhe `insdata.txt` (one line per frame:
  * timestamp_ns lat_deg lon_deg alt_m x_m y_m z_m roll pitch yaw) into camera poses.
  *
  * Only the metric positions (x, y, z; z up) are used: the angle columns are not
  * trustworthy (the yaw jumps by about 2 rad at frame 97), so the heading is taken from
  * the track (central difference over neighbours at least \a heading_baseline_m apart), and
  * the camera looks level along it. The world frame is the local x, y, z frame shifted so
  * that frame 0 is at the origin; z is up.
  * \param[in] path the insdata.txt file
  * \param[in] heading_baseline_m the shortest chord used to estimate the heading, metres
  * \return one pose per line
  * \throws planar_grid::IOError naming file:line when the file is missing, a line has
  *         fewer than 7 numbers, or the track never moves */
Trajectory
loadKarlsruheInsData(const std::string& path, double heading_baseline_m = 1.0);

/** \brief Reads a KITTI poses file: one line per frame, 12 numbers, the row-major 3x4
  * matrix world_T_camera. \throws planar_grid::IOError naming file:line on malformed lines. */
Trajectory
loadKittiPoses(const std::string& path);

/** \brief Writes a KITTI poses file (12 numbers per line, full precision), atomically.
  * \throws planar_grid::IOError when it cannot be written */
void
saveKittiPoses(const std::string& path, const Trajectory& trajectory);

/** \brief The pose stored in a PCD file's VIEWPOINT field (sensor origin and
  * orientation, pcl::PointCloud::sensor_origin_ / sensor_orientation_) as world_T_sensor.
  * \throws planar_grid::IOError when the file cannot be read */
Eigen::Isometry3d
loadPCDViewpoint(const std::string& path);

} // namespace planar_grid
