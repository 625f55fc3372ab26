// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/odometry/floor_alignment.h>

#include <pcl/common/transforms.h>

#include <gtest/gtest.h>

#include <cmath>

#include "../test_constants.h"
#include "synthetic_room.h"

namespace {

using planar_grid_test::PI;

/** \brief world_T_camera of a camera 1.2 m above the floor at (0.5, -0.3), looking
 * along +x, pitched 20 deg down and rolled 5 deg (optical frame: x right, y down, z
 * forward). */
Eigen::Isometry3d
tiltedCamera()
{
  Eigen::Matrix3d level;
  level.col(0) = -Eigen::Vector3d::UnitY();
  level.col(1) = -Eigen::Vector3d::UnitZ();
  level.col(2) = Eigen::Vector3d::UnitX();
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = level
                  * Eigen::AngleAxisd(-20.0 * PI / 180.0, Eigen::Vector3d::UnitX())
                  * Eigen::AngleAxisd(5.0 * PI / 180.0, Eigen::Vector3d::UnitZ());
  pose.translation() = Eigen::Vector3d(0.5, -0.3, 1.2);
  return pose;
}

} // namespace

TEST(FloorAlignment, FloorOfATiltedCameraIsFoundAndLevelled)
{
  // The room in the camera's optical frame; the prior up is the camera's -y, 21 deg
  // from the true up. The table top (0.45 m below the camera) is higher than the floor
  // and the ceiling is absent; the floor must win.
  const Eigen::Isometry3d world_T_camera = tiltedCamera();
  const auto room = planar_grid_test::syntheticRoom();
  pcl::PointCloud<pcl::PointXYZ> camera_cloud;
  pcl::transformPointCloud(room, camera_cloud,
                           world_T_camera.inverse().cast<float>().matrix());
  Eigen::Vector4f floor;
  std::size_t inliers = 0;
  ASSERT_TRUE(planar_grid::estimateFloorPlane(
    camera_cloud, Eigen::Vector3f::Zero(), -Eigen::Vector3f::UnitY(),
    planar_grid::FloorEstimationParams(), floor, inliers));
  // The true up in the camera frame, and the camera 1.2 m above the floor; the fit is
  // on 3 mm noise over 24 m^2: within 0.1 deg and 5 mm.
  const Eigen::Vector3d true_up = world_T_camera.rotation().transpose().col(2);
  EXPECT_LT(std::acos(std::min(1.0, floor.head<3>().cast<double>().dot(true_up))),
            0.1 * PI / 180.0);
  EXPECT_NEAR(floor[3], 1.2, 0.005);
  // 6 x 4 m of floor (the synthetic floor has no hole under the table) at 5 cm voxels:
  // about 120 x 80 = 9600 points.
  EXPECT_GT(inliers, 8000u);

  // Levelled: the floor at z = 0 and horizontal, the camera at 1.2 m, looking along +x
  // of its new world (its forward direction projected on the floor).
  const Eigen::Isometry3d level =
    planar_grid::levelSensorPose(floor, Eigen::Vector3d::UnitZ());
  pcl::PointCloud<pcl::PointXYZ> levelled;
  pcl::transformPointCloud(camera_cloud, levelled, level.cast<float>().matrix());
  EXPECT_NEAR(level.translation().z(), 1.2, 0.005);
  const Eigen::Vector3d forward = level.rotation().col(2);
  EXPECT_NEAR(std::atan2(forward.y(), forward.x()), 0.0, 1e-9);
  const Eigen::Vector4f levelled_floor(0.0f, 0.0f, 1.0f, 0.0f);
  std::size_t near_zero = 0;
  for (const auto& p : levelled.points)
    near_zero += std::abs(p.z) < 0.02f;
  EXPECT_GT(near_zero, 0.9 * 151 * 101); // the floor grid: 151 x 101 samples
  EXPECT_LT(planar_grid::planeTiltFromHorizontal(levelled_floor), 1e-12);
}

TEST(FloorAlignment, NoFloorIsReported)
{
  // Only the walls of the room (points above 0.1 m) and a sensor at 1.2 m: no plane
  // faces up below the sensor.
  pcl::PointCloud<pcl::PointXYZ> walls;
  for (const auto& p : planar_grid_test::syntheticRoom().points)
    if (p.z > 0.1f && std::abs(p.z - 0.75f) > 0.05f)
      walls.push_back(p);
  Eigen::Vector4f floor(1.0f, 2.0f, 3.0f, 4.0f);
  std::size_t inliers = 7;
  EXPECT_FALSE(planar_grid::estimateFloorPlane(
    walls, Eigen::Vector3f(0.0f, 0.0f, 1.2f), Eigen::Vector3f::UnitZ(),
    planar_grid::FloorEstimationParams(), floor, inliers));
  EXPECT_EQ(floor, Eigen::Vector4f(1.0f, 2.0f, 3.0f, 4.0f));
  EXPECT_EQ(inliers, 7u);
  // Empty and zero-prior inputs fail the same way.
  EXPECT_FALSE(planar_grid::estimateFloorPlane(
    pcl::PointCloud<pcl::PointXYZ>(), Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitZ(),
    planar_grid::FloorEstimationParams(), floor, inliers));
  EXPECT_FALSE(planar_grid::estimateFloorPlane(
    planar_grid_test::syntheticRoom(), Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero(),
    planar_grid::FloorEstimationParams(), floor, inliers));
}
