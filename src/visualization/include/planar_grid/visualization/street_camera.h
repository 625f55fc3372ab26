// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/visualization/scene_renderer.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <cstddef>
#include <vector>

namespace planar_grid {

/** \brief How streetCamera() places a camera that looks along the street from above
 * and behind one pose of a trajectory, as a person standing on a roof behind the
 * vehicle would: the pose is at the bottom edge of the image (centre column), the
 * street ahead of it up to \a look_ahead_m at the top edge. \ingroup visualization */
struct StreetCameraParameters {
  /** \brief Which pose the camera follows, as a fraction of the trajectory, in [0, 1]:
   * pose index round(pose_fraction * (n - 1)) of n poses (0: the first, 1: the last).
   */
  double pose_fraction{1.0 / 3.0};
  /** \brief Downward pitch of the viewing direction below the horizontal, radians
   * (0.5 rad = 28.6 deg); in (v / 2, pi / 2 - v / 2) for the vertical view angle v,
   * so that the top edge of the image still looks down and the bottom edge still
   * looks forwards. */
  double pitch_rad{0.5};
  /** \brief Distance ahead of the pose along the direction of travel whose point at
   * the pose's height is on the top edge of the image, metres, > 0. */
  double look_ahead_m{40.0};
  /** \brief Vertical field of view, degrees, in (0, 180). The default is wide (45 deg)
   * so that the camera stays close behind the pose (4.7 m above it and 3.8 m behind
   * with the other defaults) and the facades along the street are seen less
   * obliquely than from further back. */
  double view_angle_deg{45.0};
  /** \brief The world's up direction (any length > 0): +z for a z-up world, -y for a
   * KITTI world (the first camera's frame). */
  Eigen::Vector3d world_up{0.0, 0.0, 1.0};
  /** \brief The shortest horizontal chord along the trajectory that gives the direction
   * of travel, metres, > 0 (shorter chords are dominated by position noise). */
  double travel_baseline_m{5.0};
};

/** \brief Camera poses world_T_camera (the same type as planar_grid::Trajectory of the
 * odometry module, which the visualization headers do not include).
 * \ingroup visualization */
using PoseVector =
  std::vector<Eigen::Isometry3d, Eigen::aligned_allocator<Eigen::Isometry3d>>;

/** \brief The camera above and behind \a position looking along \a direction_of_travel
 * with the downward pitch of \a parameters.
 *
 * With u the unit world_up, d the unit horizontal part of the direction of travel,
 * pitch p and vertical view angle v, the camera is at position - b d + h u with
 * h / tan(p + v/2) = b (the bottom edge of the image looks at the pose) and
 * h / tan(p - v/2) = b + look_ahead_m (the top edge looks at the point look_ahead_m
 * ahead, at the pose's height). The focal point is where the optical axis meets the
 * pose's height; view_up is orthogonal to the viewing direction, in the vertical plane
 * through d. pose_fraction and travel_baseline_m are not used here.
 * \param[in] position the followed pose's position, world frame, metres
 * \param[in] direction_of_travel any vector with a horizontal part (length > 0)
 * \param[in] parameters pitch, look-ahead, view angle and world up
 * \return the camera (view_angle_deg from \a parameters)
 * \throws planar_grid::Exception when a parameter is out of its documented range, a
 *         vector is not finite, or \a direction_of_travel is (nearly) vertical */
CameraParameters streetCamera(const Eigen::Vector3d& position,
                              const Eigen::Vector3d& direction_of_travel,
                              const StreetCameraParameters& parameters);

/** \brief The index of the pose a street camera follows: round(pose_fraction *
 * (n_poses - 1)).
 * \param[in] n_poses the number of poses, > 0
 * \param[in] pose_fraction in [0, 1]
 * \return an index in [0, n_poses)
 * \throws planar_grid::Exception when n_poses is 0 or the fraction is outside [0, 1] */
std::size_t streetCameraPoseIndex(std::size_t n_poses, double pose_fraction);

/** \brief The direction of travel at pose \a index of \a trajectory, horizontal (unit,
 * orthogonal to \a world_up): towards the first later pose at least \a baseline_m away
 * horizontally; near the end of the trajectory, from the last earlier pose that far
 * away; when the vehicle never moved that far, the camera's optical axis (its z axis),
 * or its image-up axis (-y) when the optical axis is vertical.
 * \param[in] trajectory camera poses world_T_camera (x right, y down, z forward)
 * \param[in] index the pose, < trajectory.size()
 * \param[in] world_up the world's up direction (length > 0)
 * \param[in] baseline_m the shortest horizontal chord, metres, > 0
 * \return the unit horizontal direction of travel
 * \throws planar_grid::Exception when \a index is out of range, \a world_up is zero or
 *         not finite, or \a baseline_m is not positive */
Eigen::Vector3d travelDirection(const PoseVector& trajectory,
                                std::size_t index,
                                const Eigen::Vector3d& world_up,
                                double baseline_m);

/** \brief The street camera of a trajectory: streetCamera() at the pose
 * streetCameraPoseIndex() picks, looking along travelDirection() there.
 * \param[in] trajectory camera poses world_T_camera, world frame, metres; not empty
 * \param[in] parameters all of them
 * \return the camera
 * \throws planar_grid::Exception when the trajectory is empty or a parameter is out of
 *         its range */
CameraParameters streetCamera(const PoseVector& trajectory,
                              const StreetCameraParameters& parameters);

} // namespace planar_grid
