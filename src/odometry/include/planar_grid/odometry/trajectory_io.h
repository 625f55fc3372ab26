// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <map>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Camera poses world_T_camera, one per frame: a camera-frame point p (x right,
 * y down, z forward, metres) is at world_T_camera * p in the world frame. The readers
 * below return them in the z-up world (WorldConvention::Z_UP), whatever convention the
 * file is written in. \ingroup odometry */
using Trajectory =
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>;

/** \brief Reads a Karlsruhe `insdata.txt` (one line per frame:
 * timestamp_ns lat_deg lon_deg alt_m x_m y_m z_m roll pitch yaw) into camera poses.
 *
 * Only the metric positions (x, y, z; z up) are used: the angle columns are not
 * trustworthy (the yaw jumps by about 2 rad at frame 97), so the heading is taken from
 * the track. For each frame it is the direction from the nearest earlier to the nearest
 * later frame whose horizontal chord to it is at least \a heading_baseline_m (central
 * difference); at the ends of the track, where one of them does not exist, the frame
 * itself takes its place (one-sided difference). The camera looks level along the
 * heading: its x axis points right, y down (world -z), z forward; its origin is the
 * INS position. The world frame is the local x, y, z frame shifted so that frame 0 is
 * at the origin; z is up. Blank lines are skipped.
 * \param[in] path the insdata.txt file
 * \param[in] heading_baseline_m the shortest horizontal chord used to estimate the
 *            heading, metres (> 0)
 * \return one pose per non-blank line, in file order
 * \throws planar_grid::IOError naming file:line when the file is missing or empty, a
 *         line has fewer than 7 numbers or a token that is not a finite number, or the
 *         track never moves \a heading_baseline_m away from a frame
 * \throws planar_grid::Exception when \a heading_baseline_m is not positive
 * \ingroup odometry */
Trajectory loadKarlsruheInsData(const std::string& path,
                                double heading_baseline_m = 1.0);

/** \brief The conventions of the world frames that pose files and PCD headers are
 * written in. The map's world is Z_UP; each reader converts to it.
 * \ingroup odometry */
enum class WorldConvention {
  /** x forward, y left, z up (ROS REP-103): Karlsruhe insdata, EuRoC's Vicon world,
   * the visual odometry's world and the map. */
  Z_UP,
  /** x right, y down, z forward: a camera's optical frame. KITTI's world is the first
   * camera's frame, so KITTI poses files are written in it. */
  OPTICAL,
  /** x right, y up, z backward: the world of VTK and of PCL's visualizer. PCL's depth
   * camera grabbers write the VIEWPOINT of an optical-frame cloud in it (a level
   * camera has the orientation w = 0, x = 1: a half turn about x). */
  Y_UP
};

/** \brief z_up_world_T_world: the rotation that takes coordinates in a world written in
 * \a convention to the z-up world, where a level camera looking along +x has the
 * orientation with columns (-y, -z, +x). Its entries are 0 and +-1, so converting and
 * converting back is exact. \param[in] convention the world's convention
 * \return the rotation (no translation) \ingroup odometry */
Eigen::Isometry3d zUpWorldFrom(WorldConvention convention);

/** \brief Reads a KITTI poses file: one line per frame, 12 numbers, the row-major 3x4
 * matrix world_T_camera in KITTI's world, the first camera's optical frame (x right,
 * y down, z forward; WorldConvention::OPTICAL). The poses are returned in the z-up
 * world: zUpWorldFrom(OPTICAL) * world_T_camera, so the first camera of a KITTI
 * sequence is level at the origin, looking along +x. Blank lines are skipped.
 * \param[in] path the poses file
 * \return one pose per non-blank line, z-up world (empty for an empty file)
 * \throws planar_grid::IOError naming the file when it is missing, and file:line when a
 *         line does not hold exactly 12 finite numbers or its 3x3 part is not a proper
 *         rotation (orthonormal to 1e-4, determinant > 0)
 * \ingroup odometry */
Trajectory loadKittiPoses(const std::string& path);

/** \brief Body poses by image index, world_T_body. \ingroup odometry */
using IndexedPoses =
  std::map<int,
           Eigen::Isometry3d,
           std::less<int>,
           Eigen::aligned_allocator<std::pair<const int, Eigen::Isometry3d>>>;

/** \brief Reads the EuRoC ground-truth body poses of a set of image pairs
 * (euroc_v1_01_pairs/gt_body_poses.txt): one line per image,
 * `image timestamp_ns qw qx qy qz x_m y_m z_m`, the pose world_T_body (Vicon world
 * frame, z up) of the image with that index. Blank lines and lines starting with '#'
 * are skipped; the timestamp is not used. The camera pose follows from the body pose
 * and the camera's T_BS (StereoCameraModel::body_T_left).
 * \param[in] path the poses file
 * \return world_T_body by image index (empty for a file without poses)
 * \throws planar_grid::IOError naming the file when it is missing, and file:line when
 *         a line does not hold exactly 9 finite numbers, its image index is not a
 *         non-negative integer or repeats an earlier line's, or its quaternion is zero
 *         or not of unit norm (to 1e-3)
 * \ingroup odometry */
IndexedPoses loadEurocBodyPoses(const std::string& path);

/** \brief Writes a KITTI poses file (12 numbers per line, 17 significant digits),
 * atomically (see planar_grid::writeTextFileAtomically()). The z-up world poses are
 * written in KITTI's optical world convention (zUpWorldFrom(OPTICAL)^-1 * pose), so
 * that loadKittiPoses() gives back exactly the same doubles and the file compares
 * directly with KITTI ground truth.
 * \param[in] path the poses file
 * \param[in] trajectory the poses world_T_camera, z-up world
 * \throws planar_grid::IOError when it cannot be written (an existing file is left as
 *         it was)
 * \throws planar_grid::Exception when a pose is not finite
 * \ingroup odometry */
void saveKittiPoses(const std::string& path, const Trajectory& trajectory);

/** \brief The pose stored in a PCD file's VIEWPOINT field (sensor origin and
 * orientation, pcl::PointCloud::sensor_origin_ / sensor_orientation_) as written:
 * world_T_sensor in the PCD's own world, whose convention the header does not say
 * (see isDefaultPCDViewpoint() and WorldConvention::Y_UP). Only the header is read
 * (pcl::PCDReader::readHeader), not the points. PCD stores the viewpoint in single
 * precision, so the pose is exact to about 1e-7 relative.
 * \param[in] path the PCD file
 * \return world_T_sensor (identity for the default VIEWPOINT 0 0 0 1 0 0 0)
 * \throws planar_grid::IOError when the file is missing, its header cannot be parsed,
 *         or the VIEWPOINT is not finite or has a zero quaternion
 * \ingroup odometry */
Eigen::Isometry3d loadPCDViewpoint(const std::string& path);

/** \brief Whether a VIEWPOINT (loadPCDViewpoint()) is one that PCL writes without
 * measuring a pose: the origin at zero and either the identity orientation (the
 * default of pcl::PointCloud) or the constant half turn about x (w = 0, x = 1) that
 * PCL's depth camera grabbers give every optical-frame cloud. Such a viewpoint fixes
 * neither the motion between frames nor the up direction (a camera is rarely exactly
 * level). Both are compared to within 1e-6.
 * \param[in] sensor_pose the VIEWPOINT as world_T_sensor
 * \return true for those two constant poses
 * \ingroup odometry */
bool isDefaultPCDViewpoint(const Eigen::Isometry3d& sensor_pose);

} // namespace planar_grid
