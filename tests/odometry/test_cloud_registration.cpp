// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/odometry/cloud_registration.h>

#include <pcl/common/transforms.h>

#include <gtest/gtest.h>

#include <cmath>

#include "synthetic_room.h"

namespace {

constexpr double PI = 3.14159265358979323846;

/** \brief Angle of the rotation between two poses, radians. */
double
rotationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b)
{
  return Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle();
}

/** \brief A known target_T_source: yaw, a little roll, and a translation. */
Eigen::Isometry3d
knownMotion(double yaw_rad, const Eigen::Vector3d& translation_m)
{
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())
                * Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitX()))
                 .toRotationMatrix();
  t.translation() = translation_m;
  return t;
}

} // namespace

TEST(CloudRegistration, SmallMotionIsRecoveredByGICP)
{
  // The room seen from a sensor moved by a known transform: the source is the room in
  // the moved sensor's frame, so target_T_source is that transform.
  const auto target = planar_grid_test::syntheticRoom();
  const Eigen::Isometry3d truth = knownMotion(0.2, Eigen::Vector3d(0.3, -0.2, 0.05));
  pcl::PointCloud<pcl::PointXYZ> source;
  pcl::transformPointCloud(target, source, truth.inverse().cast<float>().matrix());

  planar_grid::CloudRegistrationParams params;
  const auto result =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  // 0.2 rad and 0.36 m are within GICP's reach from the identity, so no feature guess
  // is needed; the answer is exact up to the 3 mm noise and the 5 cm voxels: 0.2 deg
  // and 1 cm.
  EXPECT_FALSE(result.feature_guess_used);
  EXPECT_LT(rotationError(result.target_T_source, truth), 0.2 * PI / 180.0);
  EXPECT_LT((result.target_T_source.translation() - truth.translation()).norm(), 0.01);
  // Same room, all of it seen: nearly every point overlaps, and the residual is the
  // noise (3 mm), not a misalignment.
  EXPECT_GT(result.overlap, 0.95);
  EXPECT_LT(result.residual_m, 0.01);
  EXPECT_TRUE(result.converged);
}

TEST(CloudRegistration, LargeMotionNeedsTheFeatureGuess)
{
  // 1.2 rad (69 deg) and 1.5 m: GICP from the identity falls into a wrong minimum;
  // the FPFH + SampleConsensusPrerejective guess brings it home.
  const auto target = planar_grid_test::syntheticRoom();
  const Eigen::Isometry3d truth = knownMotion(1.2, Eigen::Vector3d(1.0, 1.1, 0.0));
  pcl::PointCloud<pcl::PointXYZ> source;
  pcl::transformPointCloud(target, source, truth.inverse().cast<float>().matrix());

  planar_grid::CloudRegistrationParams params;
  params.seed = 3;
  const auto result =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  EXPECT_TRUE(result.feature_guess_used);
  EXPECT_LT(rotationError(result.target_T_source, truth), 0.2 * PI / 180.0);
  EXPECT_LT((result.target_T_source.translation() - truth.translation()).norm(), 0.01);
  EXPECT_GT(result.overlap, 0.95);
  EXPECT_LT(result.residual_m, 0.01);

  // Without the guess the same pair is not registered: the overlap stays low.
  params.feature_initial_guess = false;
  const auto plain =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  EXPECT_LT(plain.overlap, result.overlap);
}

TEST(CloudRegistration, DegenerateInputGivesTheGuess)
{
  const auto room = planar_grid_test::syntheticRoom();
  const pcl::PointCloud<pcl::PointXYZ> empty;
  const Eigen::Isometry3d guess(Eigen::Translation3d(1.0, 2.0, 3.0));
  for (const auto* pair : {&empty, &room}) {
    const auto result =
      planar_grid::registerCloud(*pair, pair == &empty ? room : empty, guess,
                                 planar_grid::CloudRegistrationParams());
    EXPECT_TRUE(result.target_T_source.isApprox(guess));
    EXPECT_EQ(result.overlap, 0.0);
  }
  // All-NaN points count as none.
  pcl::PointCloud<pcl::PointXYZ> nan_cloud;
  nan_cloud.resize(50, pcl::PointXYZ(NAN, NAN, NAN));
  nan_cloud.is_dense = false;
  const auto result = planar_grid::registerCloud(
    nan_cloud, room, guess, planar_grid::CloudRegistrationParams());
  EXPECT_EQ(result.overlap, 0.0);
}
