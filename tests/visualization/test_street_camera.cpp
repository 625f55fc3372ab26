// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/visualization/street_camera.h>

#include <gtest/gtest.h>

#include <cmath>

#include "../test_constants.h"

namespace {

using planar_grid::CameraParameters;
using planar_grid::PoseVector;
using planar_grid::StreetCameraParameters;

using planar_grid_test::PI;

/** \brief Angle of \a v below the horizontal plane of \a up (radians, > 0 downwards).
 */
double
depression(const Eigen::Vector3d& v, const Eigen::Vector3d& up)
{
  const double vertical = v.dot(up);
  const double horizontal = (v - vertical * up).norm();
  return std::atan2(-vertical, horizontal);
}

/** \brief A camera pose of a z-up world at \a position looking level along the unit
 * horizontal \a forward: camera x right, y down (world -z), z forward. */
Eigen::Isometry3d
levelPose(const Eigen::Vector3d& position, const Eigen::Vector3d& forward)
{
  Eigen::Matrix3d r;
  r.col(2) = forward;
  r.col(1) = -Eigen::Vector3d::UnitZ();
  r.col(0) = r.col(1).cross(r.col(2));
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = r;
  pose.translation() = position;
  return pose;
}

/** \brief \a n poses 0.75 m apart (the Karlsruhe median step) from \a start along the
 * unit horizontal \a forward, at 1.5 m above z = 0. */
PoseVector
straightTrack(std::size_t n,
              const Eigen::Vector3d& start,
              const Eigen::Vector3d& forward)
{
  PoseVector poses;
  for (std::size_t k = 0; k < n; ++k)
    poses.push_back(
      levelPose(start + 0.75 * static_cast<double>(k) * forward, forward));
  return poses;
}

} // namespace

TEST(StreetCamera, SitsBehindAndAboveThePoseAndFramesTheStreetAhead)
{
  // Pose at (10, 5, 1.5), travelling +x in a z-up world: pitch p = 0.45 rad, view
  // angle v = 30 deg, 40 m ahead.
  const Eigen::Vector3d pose(10.0, 5.0, 1.5), forward = Eigen::Vector3d::UnitX();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  StreetCameraParameters parameters;
  parameters.pitch_rad = 0.45;
  parameters.view_angle_deg = 30.0;
  parameters.look_ahead_m = 40.0;
  const CameraParameters camera = planar_grid::streetCamera(pose, forward, parameters);
  const double v = parameters.view_angle_deg * PI / 180.0;

  // Behind (-x) and above the pose, in the vertical plane through it along the travel.
  EXPECT_LT(camera.position.x(), pose.x() - 1.0);
  EXPECT_GT(camera.position.z(), pose.z() + 1.0);
  EXPECT_NEAR(camera.position.y(), pose.y(), 1e-9);
  // Looking forwards (+x) and down by the pitch.
  const Eigen::Vector3d view = camera.focal_point - camera.position;
  EXPECT_GT(view.x(), 0.0);
  EXPECT_NEAR(view.y(), 0.0, 1e-9);
  EXPECT_NEAR(depression(view, up), parameters.pitch_rad, 1e-9);
  // The focal point is on the optical axis at the pose's height, ahead of the pose.
  EXPECT_NEAR(camera.focal_point.z(), pose.z(), 1e-9);
  EXPECT_GT(camera.focal_point.x(), pose.x());
  // The image's bottom edge (p + v/2 below the horizontal) looks at the pose, the top
  // edge (p - v/2) at the point 40 m ahead at the pose's height.
  EXPECT_NEAR(depression(pose - camera.position, up), parameters.pitch_rad + 0.5 * v,
              1e-9);
  const Eigen::Vector3d ahead = pose + parameters.look_ahead_m * forward;
  EXPECT_NEAR(depression(ahead - camera.position, up), parameters.pitch_rad - 0.5 * v,
              1e-9);
  // Here h = 40 / (cot(0.1882) - cot(0.7118)) = 40 / (5.2506 - 1.1592)
  // = 9.777 m above the pose and b = h cot(0.7118) = 11.333 m behind it.
  EXPECT_NEAR(camera.position.z() - pose.z(), 9.777, 0.001);
  EXPECT_NEAR(pose.x() - camera.position.x(), 11.333, 0.001);
  // view_up: unit, orthogonal to the view, pointing up (the image is not upside down).
  EXPECT_NEAR(camera.view_up.norm(), 1.0, 1e-12);
  EXPECT_NEAR(camera.view_up.dot(view.normalized()), 0.0, 1e-12);
  EXPECT_GT(camera.view_up.z(), 0.0);
  EXPECT_DOUBLE_EQ(camera.view_angle_deg, parameters.view_angle_deg);
}

TEST(StreetCamera, LooksFurtherAheadFromFurtherBackAndHigher)
{
  const Eigen::Vector3d pose(0.0, 0.0, 0.0), forward(0.0, 1.0, 0.0);
  StreetCameraParameters near_view;
  near_view.look_ahead_m = 20.0;
  StreetCameraParameters far_view;
  far_view.look_ahead_m = 40.0;
  const auto a = planar_grid::streetCamera(pose, forward, near_view);
  const auto b = planar_grid::streetCamera(pose, forward, far_view);
  // The placement scales with the look-ahead: twice as far back and twice as high.
  EXPECT_NEAR(b.position.y(), 2.0 * a.position.y(), 1e-9);
  EXPECT_NEAR(b.position.z(), 2.0 * a.position.z(), 1e-9);
  EXPECT_LT(a.position.y(), 0.0) << "behind the pose, travelling +y";
}

TEST(StreetCamera, FollowsTheTrajectoryAlongItsDirectionOfTravel)
{
  // 120 poses along a heading of 30 degrees; the default fraction 1/3 picks pose
  // round(119 / 3) = 40.
  const Eigen::Vector3d heading(std::cos(PI / 6.0), std::sin(PI / 6.0), 0.0);
  const PoseVector track = straightTrack(120, Eigen::Vector3d(3.0, -2.0, 1.5), heading);
  const StreetCameraParameters parameters;
  EXPECT_EQ(planar_grid::streetCameraPoseIndex(track.size(), parameters.pose_fraction),
            40u);
  const CameraParameters camera = planar_grid::streetCamera(track, parameters);
  const CameraParameters expected =
    planar_grid::streetCamera(track[40].translation(), heading, parameters);
  EXPECT_LT((camera.position - expected.position).norm(), 1e-9);
  EXPECT_LT((camera.focal_point - expected.focal_point).norm(), 1e-9);
  // The horizontal view is the heading; the camera is behind pose 40 along it.
  Eigen::Vector3d flat = camera.focal_point - camera.position;
  flat.z() = 0.0;
  EXPECT_LT((flat.normalized() - heading).norm(), 1e-9);
  EXPECT_GT((track[40].translation() - camera.position).dot(heading), 1.0);
}

TEST(StreetCamera, DirectionOfTravelAtTheEndsAndWhenStandingStill)
{
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  // A track along +x that turns right (to -y) after 20 poses: at the last pose, the
  // direction comes from the last earlier pose 5 m away, which is on the -y leg.
  PoseVector track =
    straightTrack(20, Eigen::Vector3d::Zero(), Eigen::Vector3d::UnitX());
  const Eigen::Vector3d corner = track.back().translation();
  for (int k = 1; k <= 20; ++k)
    track.push_back(levelPose(corner - 0.75 * k * Eigen::Vector3d::UnitY(),
                              -Eigen::Vector3d::UnitY()));
  EXPECT_LT((planar_grid::travelDirection(track, track.size() - 1, up, 5.0)
             + Eigen::Vector3d::UnitY())
              .norm(),
            1e-9);
  EXPECT_LT(
    (planar_grid::travelDirection(track, 0, up, 5.0) - Eigen::Vector3d::UnitX()).norm(),
    1e-9);

  // Standing still: the camera's optical axis, here world +y.
  PoseVector still(5,
                   levelPose(Eigen::Vector3d(1.0, 2.0, 1.5), Eigen::Vector3d::UnitY()));
  EXPECT_LT(
    (planar_grid::travelDirection(still, 2, up, 5.0) - Eigen::Vector3d::UnitY()).norm(),
    1e-9);
  // A camera looking straight down (z = world -z) with the top of its image (-y) along
  // world -x: the direction is -x.
  Eigen::Isometry3d down = Eigen::Isometry3d::Identity();
  down.linear().col(2) = -Eigen::Vector3d::UnitZ();
  down.linear().col(1) = Eigen::Vector3d::UnitX();
  down.linear().col(0) = down.linear().col(1).cross(down.linear().col(2));
  EXPECT_LT((planar_grid::travelDirection(PoseVector(1, down), 0, up, 5.0)
             + Eigen::Vector3d::UnitX())
              .norm(),
            1e-9);
}

TEST(StreetCamera, KittiWorldWithYDown)
{
  // The KITTI world is the first camera's frame: x right, y down, z forward. Driving
  // along +z, "above" is -y.
  PoseVector track;
  for (int k = 0; k < 30; ++k) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.translation() = Eigen::Vector3d(0.0, 0.0, 1.0 * k);
    track.push_back(pose);
  }
  StreetCameraParameters parameters;
  parameters.world_up = Eigen::Vector3d(0.0, -1.0, 0.0);
  const auto camera = planar_grid::streetCamera(track, parameters);
  const Eigen::Vector3d pose = track[10].translation(); // round(29 / 3)
  EXPECT_LT(camera.position.y(), pose.y() - 1.0) << "above";
  EXPECT_LT(camera.position.z(), pose.z() - 1.0) << "behind";
  EXPECT_GT(camera.focal_point.z(), camera.position.z()) << "looking forwards";
  EXPECT_LT(camera.view_up.y(), 0.0);
}

TEST(StreetCamera, PoseIndex)
{
  // 112 Karlsruhe frames: a third of the way is pose round(111 / 3) = 37.
  EXPECT_EQ(planar_grid::streetCameraPoseIndex(112, 1.0 / 3.0), 37u);
  EXPECT_EQ(planar_grid::streetCameraPoseIndex(112, 0.0), 0u);
  EXPECT_EQ(planar_grid::streetCameraPoseIndex(112, 1.0), 111u);
  EXPECT_EQ(planar_grid::streetCameraPoseIndex(1, 0.5), 0u);
  EXPECT_THROW(planar_grid::streetCameraPoseIndex(0, 0.5), planar_grid::Exception);
  EXPECT_THROW(planar_grid::streetCameraPoseIndex(10, -0.1), planar_grid::Exception);
  EXPECT_THROW(planar_grid::streetCameraPoseIndex(10, 1.1), planar_grid::Exception);
  EXPECT_THROW(planar_grid::streetCameraPoseIndex(10, std::nan("")),
               planar_grid::Exception);
}

TEST(StreetCamera, InvalidParametersThrow)
{
  const Eigen::Vector3d pose(0.0, 0.0, 1.5), forward = Eigen::Vector3d::UnitX();
  const auto throws = [&](const StreetCameraParameters& p,
                          const Eigen::Vector3d& direction) {
    EXPECT_THROW(planar_grid::streetCamera(pose, direction, p), planar_grid::Exception);
  };
  StreetCameraParameters p;
  p.view_angle_deg = 30.0;
  p.pitch_rad = 0.2; // below half the 30 degree view angle (0.2618 rad)
  throws(p, forward);
  p.pitch_rad = 1.35; // above pi/2 - 0.2618 = 1.309 rad
  throws(p, forward);
  p.pitch_rad = 1.3; // inside: no throw
  EXPECT_NO_THROW(planar_grid::streetCamera(pose, forward, p));
  p = StreetCameraParameters();
  p.look_ahead_m = 0.0;
  throws(p, forward);
  p = StreetCameraParameters();
  p.view_angle_deg = 180.0;
  throws(p, forward);
  p = StreetCameraParameters();
  p.world_up = Eigen::Vector3d::Zero();
  throws(p, forward);
  p = StreetCameraParameters();
  throws(p, Eigen::Vector3d::UnitZ()); // travelling straight up: no horizontal part
  throws(p, Eigen::Vector3d::Zero());
  throws(p, Eigen::Vector3d(std::nan(""), 0.0, 0.0));
  EXPECT_THROW(planar_grid::streetCamera(PoseVector(), p), planar_grid::Exception);
  const PoseVector one(1, Eigen::Isometry3d::Identity());
  EXPECT_THROW(planar_grid::travelDirection(one, 1, Eigen::Vector3d::UnitZ(), 5.0),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::travelDirection(one, 0, Eigen::Vector3d::UnitZ(), 0.0),
               planar_grid::Exception);
}

TEST(StreetCamera, DefaultsAreThoseOfThePipelineConfiguration)
{
  // output.street_view documents the same defaults (the pipeline library does not link
  // the visualization one, so they are written twice).
  const StreetCameraParameters camera;
  const planar_grid::StreetViewConfig config;
  EXPECT_DOUBLE_EQ(camera.pose_fraction, config.pose_fraction);
  EXPECT_DOUBLE_EQ(camera.pitch_rad, config.pitch_rad);
  EXPECT_DOUBLE_EQ(camera.look_ahead_m, config.look_ahead_m);
  EXPECT_DOUBLE_EQ(camera.view_angle_deg, config.view_angle_deg);
  EXPECT_EQ(camera.world_up, Eigen::Vector3d(config.up.data()));
  EXPECT_FALSE(config.fixed);
}
