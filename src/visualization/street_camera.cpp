// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/street_camera.h>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>

namespace planar_grid {

namespace {

constexpr double PI = 3.14159265358979323846;

/** \brief Horizontal directions shorter than this (relative to their input) count as
 * vertical. */
constexpr double MIN_HORIZONTAL_FRACTION = 1e-6;

/** \brief \a up as a unit vector; throws when it is zero or not finite. */
Eigen::Vector3d
unitUp(const Eigen::Vector3d& up, const char* where)
{
  if (!up.allFinite() || !(up.norm() > 0.0))
    throw Exception(std::string("[planar_grid::") + where
                    + "] world_up must be finite and non-zero");
  return up.normalized();
}

/** \brief The part of \a v orthogonal to the unit vector \a up. */
Eigen::Vector3d
horizontal(const Eigen::Vector3d& v, const Eigen::Vector3d& up)
{
  return v - v.dot(up) * up;
}

} // namespace

CameraParameters
streetCamera(const Eigen::Vector3d& position,
             const Eigen::Vector3d& direction_of_travel,
             const StreetCameraParameters& parameters)
{
  const double view_rad = parameters.view_angle_deg * PI / 180.0;
  if (!(parameters.view_angle_deg > 0.0 && parameters.view_angle_deg < 180.0))
    throw Exception("[planar_grid::streetCamera] view_angle_deg must be in (0, 180), "
                    "got "
                    + std::to_string(parameters.view_angle_deg));
  const double pitch = parameters.pitch_rad;
  if (!(pitch > 0.5 * view_rad && pitch < 0.5 * PI - 0.5 * view_rad)) {
    std::ostringstream msg;
    msg << "[planar_grid::streetCamera] pitch_rad must be in (" << 0.5 * view_rad
        << ", " << 0.5 * PI - 0.5 * view_rad << ") for a view angle of "
        << parameters.view_angle_deg
        << " deg (the top edge of the image must look down, the bottom edge forwards), "
           "got "
        << pitch;
    throw Exception(msg.str());
  }
  if (!(parameters.look_ahead_m > 0.0) || !std::isfinite(parameters.look_ahead_m))
    throw Exception("[planar_grid::streetCamera] look_ahead_m must be > 0, got "
                    + std::to_string(parameters.look_ahead_m));
  if (!position.allFinite() || !direction_of_travel.allFinite())
    throw Exception("[planar_grid::streetCamera] position and direction_of_travel "
                    "must be finite");
  const Eigen::Vector3d up = unitUp(parameters.world_up, "streetCamera");
  const Eigen::Vector3d flat = horizontal(direction_of_travel, up);
  if (!(flat.norm() > MIN_HORIZONTAL_FRACTION * direction_of_travel.norm()))
    throw Exception("[planar_grid::streetCamera] direction_of_travel has no horizontal "
                    "part (it is zero or parallel to world_up)");
  const Eigen::Vector3d forward = flat.normalized();

  // The rays of the image's bottom and top edges (centre column) leave the camera at
  // pitch + v/2 and pitch - v/2 below the horizontal. From a height h above the pose,
  // they meet the pose's height h / tan(angle) ahead of the camera: at the pose
  // (distance back b) and look_ahead_m beyond it.
  const double cot_top = 1.0 / std::tan(pitch - 0.5 * view_rad);
  const double cot_bottom = 1.0 / std::tan(pitch + 0.5 * view_rad);
  const double height = parameters.look_ahead_m / (cot_top - cot_bottom);
  const double back = height * cot_bottom;

  const Eigen::Vector3d view_direction =
    std::cos(pitch) * forward - std::sin(pitch) * up;
  CameraParameters camera;
  camera.position = position - back * forward + height * up;
  // The optical axis reaches the pose's height after height / sin(pitch).
  camera.focal_point = camera.position + (height / std::sin(pitch)) * view_direction;
  camera.view_up = std::sin(pitch) * forward + std::cos(pitch) * up;
  camera.view_angle_deg = parameters.view_angle_deg;
  return camera;
}

std::size_t
streetCameraPoseIndex(std::size_t n_poses, double pose_fraction)
{
  if (n_poses == 0)
    throw Exception("[planar_grid::streetCameraPoseIndex] the trajectory is empty: a "
                    "street camera follows one of its poses");
  if (!(pose_fraction >= 0.0 && pose_fraction <= 1.0))
    throw Exception("[planar_grid::streetCameraPoseIndex] pose_fraction must be in "
                    "[0, 1], got "
                    + std::to_string(pose_fraction));
  const double index = std::round(pose_fraction * static_cast<double>(n_poses - 1));
  return std::min(static_cast<std::size_t>(index), n_poses - 1);
}

Eigen::Vector3d
travelDirection(const PoseVector& trajectory,
                std::size_t index,
                const Eigen::Vector3d& world_up,
                double baseline_m)
{
  if (index >= trajectory.size())
    throw Exception("[planar_grid::travelDirection] pose index " + std::to_string(index)
                    + " is out of range (the trajectory has "
                    + std::to_string(trajectory.size()) + " poses)");
  if (!(baseline_m > 0.0))
    throw Exception("[planar_grid::travelDirection] baseline_m must be > 0, got "
                    + std::to_string(baseline_m));
  const Eigen::Vector3d up = unitUp(world_up, "travelDirection");
  const Eigen::Vector3d here = trajectory[index].translation();
  for (std::size_t j = index + 1; j < trajectory.size(); ++j) {
    const Eigen::Vector3d chord = horizontal(trajectory[j].translation() - here, up);
    if (chord.allFinite() && chord.norm() >= baseline_m)
      return chord.normalized();
  }
  for (std::size_t j = index; j-- > 0;) {
    const Eigen::Vector3d chord = horizontal(here - trajectory[j].translation(), up);
    if (chord.allFinite() && chord.norm() >= baseline_m)
      return chord.normalized();
  }
  // The vehicle stood (nearly) still: the way the camera looks, or, for a camera
  // looking straight down, the way the top of its image points.
  const Eigen::Matrix3d rotation = trajectory[index].linear();
  for (const Eigen::Vector3d& axis :
       {Eigen::Vector3d(rotation.col(2)), Eigen::Vector3d(-rotation.col(1))}) {
    const Eigen::Vector3d flat = horizontal(axis, up);
    if (flat.allFinite() && flat.norm() > 1e-3)
      return flat.normalized();
  }
  // Only for a pose whose rotation is not a rotation: any horizontal direction.
  return horizontal(std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX()
                                           : Eigen::Vector3d::UnitY(),
                    up)
    .normalized();
}

CameraParameters
streetCamera(const PoseVector& trajectory, const StreetCameraParameters& parameters)
{
  const std::size_t index =
    streetCameraPoseIndex(trajectory.size(), parameters.pose_fraction);
  const Eigen::Vector3d forward = travelDirection(
    trajectory, index, parameters.world_up, parameters.travel_baseline_m);
  return streetCamera(trajectory[index].translation(), forward, parameters);
}

} // namespace planar_grid
