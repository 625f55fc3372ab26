// SPDX-License-Identifier: BSD-3-Clause
// The /tf chains of a bag without a bag: TransformTable on messages built here, with
// poses whose products and interpolations are known; and RosBagFile on a file that is
// no bag.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/ros_bag/ros_bag_file.h>
#include <planar_grid/ros_bag/ros_messages.h>
#include <planar_grid/ros_bag/transform_table.h>

#include <gtest/gtest.h>

#include <cmath>
#include <string>

namespace {

/** A message holding one transform parent -> child at \a stamp (s). */
tf2_msgs::TFMessage
message(const Eigen::Isometry3d& parent_T_child,
        const std::string& parent,
        const std::string& child,
        double stamp)
{
  tf2_msgs::TFMessage m;
  m.transforms.push_back(planar_grid::ros_messages::transformStamped(
    parent_T_child, parent, child, ros::Time(stamp)));
  return m;
}

Eigen::Isometry3d
translation(double x, double y, double z)
{
  return Eigen::Isometry3d(Eigen::Translation3d(x, y, z));
}

} // namespace

TEST(TransformTable, ChainsAStaticAndAMovingTransform)
{
  // map -> odom moves from x = 0 m at 10 s to x = 2 m at 12 s; odom -> camera is
  // static, z = 1 m. At 11 s: x = 1 m (halfway), z = 1 m.
  planar_grid::TransformTable table;
  table.add(message(translation(2, 0, 0), "map", "odom", 12.0), false, "test");
  table.add(message(translation(0, 0, 0), "map", "odom", 10.0), false, "test");
  table.add(message(translation(0, 0, 1), "odom", "camera", 0.0), true, "test");
  table.sort();
  const Eigen::Isometry3d pose = table.lookup("map", "camera", 11.0, 0.0, "test");
  EXPECT_NEAR(pose.translation().x(), 1.0, 1e-12);
  EXPECT_NEAR(pose.translation().y(), 0.0, 1e-12);
  EXPECT_NEAR(pose.translation().z(), 1.0, 1e-12);
}

TEST(TransformTable, SlerpsTheRotation)
{
  // 0 rad at 0 s, pi/2 rad about z at 1 s: pi/4 rad at 0.5 s.
  planar_grid::TransformTable table;
  Eigen::Isometry3d turned = Eigen::Isometry3d::Identity();
  turned.linear() = Eigen::AngleAxisd(M_PI / 2, Eigen::Vector3d::UnitZ()).matrix();
  table.add(message(Eigen::Isometry3d::Identity(), "map", "camera", 0.0), false,
            "test");
  table.add(message(turned, "map", "camera", 1.0), false, "test");
  table.sort();
  const Eigen::AngleAxisd half(
    table.lookup("map", "camera", 0.5, 0.0, "test").linear());
  EXPECT_NEAR(half.angle(), M_PI / 4, 1e-9);
  EXPECT_NEAR(half.axis().z(), 1.0, 1e-9);
}

TEST(TransformTable, TakesTheNearestSampleWithinTheTolerance)
{
  planar_grid::TransformTable table;
  table.add(message(translation(1, 0, 0), "map", "camera", 5.0), false, "test");
  table.add(message(translation(3, 0, 0), "map", "camera", 6.0), false, "test");
  table.sort();
  // 0.05 s after the last sample, within 0.1 s: the last sample.
  EXPECT_NEAR(table.lookup("map", "camera", 6.05, 0.1, "test").translation().x(), 3.0,
              1e-12);
  // 0.5 s before the first, beyond 0.1 s.
  EXPECT_THROW(static_cast<void>(table.lookup("map", "camera", 4.5, 0.1, "test")),
               planar_grid::IOError);
}

TEST(TransformTable, RefusesAMissingChainAndASecondParent)
{
  planar_grid::TransformTable empty;
  EXPECT_THROW(static_cast<void>(empty.lookup("map", "camera", 0.0, 0.0, "test")),
               planar_grid::IOError);

  planar_grid::TransformTable table;
  table.add(message(translation(0, 0, 0), "map", "camera", 0.0), false, "test");
  EXPECT_THROW(
    table.add(message(translation(0, 0, 0), "odom", "camera", 1.0), false, "test"),
    planar_grid::IOError);
  table.sort();
  EXPECT_THROW(static_cast<void>(table.lookup("world", "camera", 0.0, 0.0, "test")),
               planar_grid::IOError);
}

TEST(RosBagFile, RefusesAFileThatIsNoBag)
{
  EXPECT_THROW(planar_grid::RosBagFile(std::string(PLANAR_GRID_SOURCE_DIR)
                                       + "/tests/ros_bag/test_transform_table.cpp"),
               planar_grid::IOError);
  EXPECT_THROW(planar_grid::RosBagFile("/nonexistent/no.bag"), planar_grid::IOError);
}
