// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/trajectory_io.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "../test_constants.h"

namespace {

namespace fs = std::filesystem;

using planar_grid_test::PI;

/** \brief The real Karlsruhe GPS/INS file (112 frames, data README). */
std::string
karlsruheInsData()
{
  return std::string(PLANAR_GRID_DATA_DIR)
         + "/karlsruhe_2010_03_09_drive_0023/insdata.txt";
}

/** \brief Heading (yaw about world +z, radians) of a camera's optical axis. */
double
cameraYaw(const Eigen::Isometry3d& world_T_camera)
{
  const Eigen::Vector3d forward = world_T_camera.linear().col(2);
  return std::atan2(forward.y(), forward.x());
}

/** \brief b - a wrapped to (-pi, pi]. */
double
yawChange(double a_rad, double b_rad)
{
  return std::remainder(b_rad - a_rad, 2.0 * PI);
}

/** \brief True when \a what contains \a part; gtest prints both on failure. */
::testing::AssertionResult
contains(const std::string& what, const std::string& part)
{
  if (what.find(part) != std::string::npos)
    return ::testing::AssertionSuccess();
  return ::testing::AssertionFailure()
         << "'" << what << "' does not contain '" << part << "'";
}

/** \brief The real trajectory, loaded once per test (a fixture, so that no test sees
 * another's changes). */
class TrajectoryIOKarlsruhe : public ::testing::Test {
protected:
  void SetUp() override
  {
    trajectory_ = planar_grid::loadKarlsruheInsData(karlsruheInsData());
  }
  /** \brief The camera poses read from insdata.txt. */
  planar_grid::Trajectory trajectory_;
};

/** \brief A fresh, empty folder per test, removed afterwards. */
class TrajectoryIOFiles : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_test_odometry_" + std::string(info->name()) + "_"
              + std::to_string(static_cast<long>(::getpid())));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override
  {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  /** \brief Writes \a content to dir_/name and returns the path. */
  std::string writeFile(const std::string& name, const std::string& content) const
  {
    const fs::path path = dir_ / name;
    std::ofstream out(path, std::ios::binary);
    out << content;
    return path.string();
  }
  /** \brief Message of the IOError \a load throws; fails the test when it does not. */
  template <typename Load> static std::string ioErrorOf(Load load)
  {
    try {
      load();
    } catch (const planar_grid::IOError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no planar_grid::IOError thrown";
    return {};
  }

  /** \brief The test's own folder. */
  fs::path dir_;
};

} // namespace

// ---------------------------------------------------------------- Karlsruhe, real data

TEST_F(TrajectoryIOKarlsruhe, OnePosePerFrame)
{
  // insdata.txt has one line per stereo pair: I1_000000 ... I1_000111 (data README).
  EXPECT_EQ(trajectory_.size(), 112u);
}

TEST_F(TrajectoryIOKarlsruhe, PositionsAreTheFileShiftedToFrameZero)
{
  ASSERT_EQ(trajectory_.size(), 112u);
  // Frame 0 is subtracted from itself: exactly zero.
  EXPECT_EQ(trajectory_.front().translation(), Eigen::Vector3d::Zero());
  // Last line minus first line, columns x_m y_m z_m, by hand from the file:
  // (-4837.6686264576 + 4913.8186204098, -1235.7055799915 + 1208.8158587134,
  //  116.3671340942 - 115.8571701050). Tolerance 1e-9 m: a double subtraction of
  // numbers near 5000 is exact to ~1e-12 m.
  const Eigen::Vector3d last(76.1499939522, -26.8897212781, 0.5099639892);
  EXPECT_NEAR(trajectory_.back().translation().x(), last.x(), 1e-9);
  EXPECT_NEAR(trajectory_.back().translation().y(), last.y(), 1e-9);
  EXPECT_NEAR(trajectory_.back().translation().z(), last.z(), 1e-9);
}

TEST_F(TrajectoryIOKarlsruhe, PathLengthMatchesTheDataReadme)
{
  double length_m = 0.0;
  for (std::size_t i = 1; i < trajectory_.size(); ++i)
    length_m +=
      (trajectory_[i].translation() - trajectory_[i - 1].translation()).norm();
  // The data README gives 93.7 m (rounded to 0.1 m). +-0.5 m (0.5 %) allows for the
  // rounding yet catches wrong columns (lat/lon degrees would give ~0.001 m) or a
  // dropped line (the median step is 0.74 m).
  EXPECT_NEAR(length_m, 93.7, 0.5);
}

TEST_F(TrajectoryIOKarlsruhe, RotationsAreProperAndLevel)
{
  // The rotations are built from cos/sin and exact unit axes: orthonormal to a few
  // ulp, so 1e-12 is generous.
  for (std::size_t i = 0; i < trajectory_.size(); ++i) {
    const Eigen::Matrix3d r = trajectory_[i].linear();
    EXPECT_LT((r.transpose() * r - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff(),
              1e-12)
      << "frame " << i;
    EXPECT_NEAR(r.determinant(), 1.0, 1e-12) << "frame " << i;
    // Camera y (down) is world -z: the camera is level (z up).
    const Eigen::Vector3d down = r * Eigen::Vector3d::UnitY();
    EXPECT_LT((down - Eigen::Vector3d(0.0, 0.0, -1.0)).norm(), 1e-12) << "frame " << i;
    // The homogeneous bottom row is exactly 0 0 0 1 (an isometry).
    EXPECT_EQ(trajectory_[i].matrix().row(3), Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0));
  }
}

TEST_F(TrajectoryIOKarlsruhe, CameraLooksAlongTheTrack)
{
  ASSERT_EQ(trajectory_.size(), 112u);
  // The first 60 frames drive a straight street heading about -5 degrees (x east-ish).
  // The camera's z axis must point along the motion, its x axis to the right of it.
  const Eigen::Vector3d motion =
    (trajectory_[10].translation() - trajectory_[0].translation()).normalized();
  const Eigen::Matrix3d r = trajectory_[5].linear();
  // cos(angle) > 0.99 (angle < 8 degrees) between optical axis and motion: the
  // heading baseline is 1 m, so the frame-5 heading and the 0..10 chord agree closely.
  EXPECT_GT(r.col(2).dot(motion), 0.99);
  // Right = down x forward: with z up, the right of the motion (x, y) is (y, -x).
  const Eigen::Vector3d right_of_motion(motion.y(), -motion.x(), 0.0);
  EXPECT_GT(r.col(0).dot(right_of_motion.normalized()), 0.99);
}

TEST_F(TrajectoryIOKarlsruhe, NinetyDegreeRightTurnNearTheEnd)
{
  ASSERT_EQ(trajectory_.size(), 112u);
  const double before_rad = cameraYaw(trajectory_[60]);
  const double after_rad = cameraYaw(trajectory_.back());
  const double turn_rad = yawChange(before_rad, after_rad);
  // The README: a 90 degree right turn near the end. Measured: -88.3 degrees between
  // frame 60 and frame 111. A right turn with z up is a negative yaw change; 75..105
  // degrees allows for the street corner not being square and GPS noise.
  EXPECT_LT(turn_rad, -75.0 * PI / 180.0);
  EXPECT_GT(turn_rad, -105.0 * PI / 180.0);

  // Where the turn is: the frame at which half of it is done. Measured: frame 80.
  // Before frame 56 the street is straight (heading within 3 degrees of frame 0).
  std::size_t half_frame = 0;
  for (std::size_t i = 60; i < trajectory_.size(); ++i)
    if (yawChange(before_rad, cameraYaw(trajectory_[i])) < 0.5 * turn_rad) {
      half_frame = i;
      break;
    }
  EXPECT_GE(half_frame, 75u);
  EXPECT_LE(half_frame, 85u);
  for (std::size_t i = 0; i < 56; ++i)
    EXPECT_LT(std::abs(yawChange(cameraYaw(trajectory_[0]), cameraYaw(trajectory_[i]))),
              3.0 * PI / 180.0)
      << "frame " << i;
}

TEST_F(TrajectoryIOKarlsruhe, HeadingIsSmoothThroughTheYawColumnJump)
{
  // The file's yaw column jumps by about 2 rad at frame 97; the track does not. The
  // largest step of the track heading is 0.05 rad (in the turn, ~3 degrees per frame at
  // 9.4 Hz); 0.2 rad would be a 30 degree/frame swing no car makes at this speed.
  for (std::size_t i = 1; i < trajectory_.size(); ++i)
    EXPECT_LT(
      std::abs(yawChange(cameraYaw(trajectory_[i - 1]), cameraYaw(trajectory_[i]))),
      0.2)
      << "between frames " << i - 1 << " and " << i;
}

TEST_F(TrajectoryIOKarlsruhe, LongerBaselineGivesSameTurn)
{
  // The heading estimate must not depend much on its baseline on a smooth track.
  const planar_grid::Trajectory smooth =
    planar_grid::loadKarlsruheInsData(karlsruheInsData(), 3.0);
  ASSERT_EQ(smooth.size(), trajectory_.size());
  // Tolerance 0.1 rad (~6 degrees): the 3 m chord cuts the corner, the 1 m one less.
  for (std::size_t i = 0; i < smooth.size(); ++i)
    EXPECT_LT(std::abs(yawChange(cameraYaw(trajectory_[i]), cameraYaw(smooth[i]))), 0.1)
      << "frame " << i;
}

// ---------------------------------------------------------------- Karlsruhe, synthetic

TEST_F(TrajectoryIOFiles, InsDataStraightNorthTrack)
{
  // Three frames 2 m apart along +y: heading +90 degrees at every frame (central in the
  // middle, one-sided at the ends). Camera z -> +y, x (right) -> +x, y -> -z.
  const std::string path = writeFile("ins.txt", "0 0 0 0 10 20 5 0 0 0\n"
                                                "1 0 0 0 10 22 5 0 0 3\n"
                                                "2 0 0 0 10 24 5 0 0 -3\n");
  const planar_grid::Trajectory trajectory = planar_grid::loadKarlsruheInsData(path);
  ASSERT_EQ(trajectory.size(), 3u);
  Eigen::Matrix3d expected;
  expected.col(0) = Eigen::Vector3d::UnitX();
  expected.col(1) = -Eigen::Vector3d::UnitZ();
  expected.col(2) = Eigen::Vector3d::UnitY();
  for (std::size_t i = 0; i < 3; ++i) {
    // cos/sin of pi/2 are exact to ~1e-16: 1e-12 is generous.
    EXPECT_TRUE(trajectory[i].linear().isApprox(expected, 1e-12)) << "frame " << i;
    // Positions minus frame 0 (10, 20, 5): small integers, exact.
    EXPECT_EQ(trajectory[i].translation(),
              Eigen::Vector3d(0.0, 2.0 * static_cast<double>(i), 0.0))
      << "frame " << i;
  }
}

TEST_F(TrajectoryIOFiles, InsDataEastTrackRightIsMinusY)
{
  // Forward +x_world: right = down x forward = (0,0,-1) x (1,0,0) = (0,-1,0).
  const std::string path = writeFile("ins.txt", "0 0 0 0 0 0 0 0 0 0\n"
                                                "\n"
                                                "1 0 0 0 5 0 0 0 0 0\n");
  const planar_grid::Trajectory trajectory = planar_grid::loadKarlsruheInsData(path);
  ASSERT_EQ(trajectory.size(), 2u); // the blank line is skipped
  for (const auto& pose : trajectory) {
    EXPECT_TRUE(pose.linear().col(0).isApprox(-Eigen::Vector3d::UnitY(), 1e-12));
    EXPECT_TRUE(pose.linear().col(2).isApprox(Eigen::Vector3d::UnitX(), 1e-12));
  }
}

TEST_F(TrajectoryIOFiles, InsDataErrorsNameFileAndLine)
{
  const std::string missing = (dir_ / "missing.txt").string();
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKarlsruheInsData(missing); }), missing));

  const std::string empty = writeFile("empty.txt", "");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKarlsruheInsData(empty); }), empty));

  const std::string short_line = writeFile("short.txt", "0 0 0 0 0 0 0 0 0 0\n"
                                                        "1 0 0 0 5 0\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKarlsruheInsData(short_line); }),
             short_line + ":2:"));

  const std::string not_number = writeFile("word.txt", "0 0 0 0 0 0 0 0 0 0\n"
                                                       "1 0 0 0 5 0 0\n"
                                                       "2 0 0 0 x 0 0 0 0 0\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKarlsruheInsData(not_number); }),
             not_number + ":3:"));

  // A track that stays within the 1 m heading baseline: no heading can be estimated.
  const std::string parked = writeFile("parked.txt", "0 0 0 0 1 1 1 0 0 0\n"
                                                     "1 0 0 0 1.1 1 1 0 0 0\n"
                                                     "2 0 0 0 1.2 1 1 0 0 0\n");
  EXPECT_TRUE(contains(ioErrorOf([&] { planar_grid::loadKarlsruheInsData(parked); }),
                       parked + ":"));

  EXPECT_THROW(planar_grid::loadKarlsruheInsData(karlsruheInsData(), 0.0),
               planar_grid::Exception);
}

// ---------------------------------------------------------------- KITTI poses

TEST_F(TrajectoryIOFiles, KittiRoundTripIsExact)
{
  planar_grid::Trajectory trajectory =
    planar_grid::loadKarlsruheInsData(karlsruheInsData());
  // Plus a pose with a general 3D rotation and awkward decimals.
  Eigen::Isometry3d tilted = Eigen::Isometry3d::Identity();
  tilted.linear() =
    Eigen::AngleAxisd(0.3141592653589793, Eigen::Vector3d(1.0, 2.0, 3.0).normalized())
      .toRotationMatrix();
  tilted.translation() = Eigen::Vector3d(1.0 / 3.0, -2.0e-7, 12345.678901234567);
  trajectory.push_back(tilted);

  const std::string path = (dir_ / "poses.txt").string();
  planar_grid::saveKittiPoses(path, trajectory);
  const planar_grid::Trajectory loaded = planar_grid::loadKittiPoses(path);
  ASSERT_EQ(loaded.size(), trajectory.size());
  // 17 significant digits make the text round trip of every double exact, so any
  // difference is a bug; 1e-12 (m or unitless) is far below the ~1e-6 a 6-digit writer
  // would lose and far above rounding noise (there is none).
  for (std::size_t i = 0; i < loaded.size(); ++i)
    EXPECT_LT((loaded[i].matrix() - trajectory[i].matrix()).cwiseAbs().maxCoeff(),
              1e-12)
      << "frame " << i;
  // Saved atomically: only the poses file in the folder, no temporary left.
  EXPECT_EQ(std::distance(fs::directory_iterator(dir_), fs::directory_iterator()), 1);

  // Mutating one pose is seen after the round trip.
  trajectory[3].translation().x() += 1e-6;
  planar_grid::saveKittiPoses(path, trajectory);
  EXPECT_GT((planar_grid::loadKittiPoses(path)[3].matrix() - loaded[3].matrix())
              .cwiseAbs()
              .maxCoeff(),
            5e-7);
}

TEST_F(TrajectoryIOFiles, KittiReadsTwelveNumbersRowMajor)
{
  const std::string path = writeFile("poses.txt", "1 0 0 1.5 0 1 0 -2 0 0 1 3\n"
                                                  "\n"
                                                  "0 -1 0 4 1 0 0 5 0 0 1 6\n");
  const planar_grid::Trajectory loaded = planar_grid::loadKittiPoses(path);
  ASSERT_EQ(loaded.size(), 2u); // the blank line is skipped
  // Back in KITTI's own world (the reader gives the z-up world) the numbers are the
  // file's, exactly: the conversion is a signed permutation.
  const Eigen::Isometry3d optical_T_z_up =
    planar_grid::zUpWorldFrom(planar_grid::WorldConvention::OPTICAL).inverse();
  const Eigen::Isometry3d first = optical_T_z_up * loaded[0];
  const Eigen::Isometry3d second = optical_T_z_up * loaded[1];
  EXPECT_EQ(first.translation(), Eigen::Vector3d(1.5, -2.0, 3.0));
  EXPECT_EQ(second.translation(), Eigen::Vector3d(4.0, 5.0, 6.0));
  // Row-major: the second line's first row is (0 -1 0 | 4).
  EXPECT_EQ(second.linear()(0, 1), -1.0);
  EXPECT_EQ(second.linear()(1, 0), 1.0);
  EXPECT_TRUE(planar_grid::loadKittiPoses(writeFile("empty.txt", "")).empty());
}

TEST_F(TrajectoryIOFiles, KittiWorldBecomesZUp)
{
  // KITTI's world is the first camera's optical frame: the identity is a level camera,
  // and (0, -1.65, 10) is 10 m ahead of it and 1.65 m higher (y points down).
  const std::string path =
    writeFile("poses.txt", "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 -1.65 0 0 1 10\n");
  const planar_grid::Trajectory loaded = planar_grid::loadKittiPoses(path);
  ASSERT_EQ(loaded.size(), 2u);
  // In the z-up world the first camera looks along +x, its x axis (right) is -y and
  // its y axis (down) is -z. Exact: the entries are 0 and +-1.
  EXPECT_EQ(loaded[0].linear().col(0), Eigen::Vector3d(0.0, -1.0, 0.0));
  EXPECT_EQ(loaded[0].linear().col(1), Eigen::Vector3d(0.0, 0.0, -1.0));
  EXPECT_EQ(loaded[0].linear().col(2), Eigen::Vector3d(1.0, 0.0, 0.0));
  EXPECT_EQ(loaded[0].translation(), Eigen::Vector3d::Zero());
  EXPECT_EQ(loaded[1].translation(), Eigen::Vector3d(10.0, 0.0, 1.65));
  // The ground below the first camera (1.65 m down its y axis) is at z = -1.65.
  EXPECT_EQ(loaded[0] * Eigen::Vector3d(0.0, 1.65, 0.0), Eigen::Vector3d(0, 0, -1.65));
}

TEST(TrajectoryIOConventions, EveryConventionIsAProperRotationToZUp)
{
  using planar_grid::WorldConvention;
  EXPECT_TRUE(planar_grid::zUpWorldFrom(WorldConvention::Z_UP).matrix().isIdentity());
  for (const auto convention : {WorldConvention::OPTICAL, WorldConvention::Y_UP}) {
    const Eigen::Matrix3d r = planar_grid::zUpWorldFrom(convention).linear();
    EXPECT_TRUE((r.transpose() * r).isIdentity(0.0));
    EXPECT_EQ(r.determinant(), 1.0);
  }
  // The y-up world's up (+y) is z-up's up, its backward (+z) is z-up's -x.
  const Eigen::Isometry3d y_up = planar_grid::zUpWorldFrom(WorldConvention::Y_UP);
  EXPECT_EQ(y_up * Eigen::Vector3d::UnitY(), Eigen::Vector3d::UnitZ());
  EXPECT_EQ(y_up * Eigen::Vector3d::UnitZ(), -Eigen::Vector3d::UnitX());
  // PCL's grabber VIEWPOINT (a half turn about x) in the y-up world is a level camera
  // looking along +x, exactly as a level optical camera in KITTI's world.
  const Eigen::Matrix3d grabber = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  EXPECT_EQ(y_up.linear() * grabber,
            planar_grid::zUpWorldFrom(WorldConvention::OPTICAL).linear());
}

TEST(TrajectoryIOConventions, DefaultPCDViewpoints)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  EXPECT_TRUE(planar_grid::isDefaultPCDViewpoint(pose));
  pose.linear() = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  EXPECT_TRUE(planar_grid::isDefaultPCDViewpoint(pose));
  // Moved 1 mm, or turned 0.01 rad: a measured pose.
  pose.translation().x() = 1e-3;
  EXPECT_FALSE(planar_grid::isDefaultPCDViewpoint(pose));
  pose = Eigen::Isometry3d(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ()));
  EXPECT_FALSE(planar_grid::isDefaultPCDViewpoint(pose));
}

TEST_F(TrajectoryIOFiles, KittiMalformedLineNamesFileAndLine)
{
  const std::string identity = "1 0 0 0 0 1 0 0 0 0 1 0\n";
  const std::string eleven =
    writeFile("eleven.txt", identity + identity + "1 0 0 0 0 1 0 0 0 0 1\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKittiPoses(eleven); }), eleven + ":3:"));

  const std::string thirteen =
    writeFile("thirteen.txt", "1 0 0 0 0 1 0 0 0 0 1 0 7\n" + identity);
  EXPECT_TRUE(contains(ioErrorOf([&] { planar_grid::loadKittiPoses(thirteen); }),
                       thirteen + ":1:"));

  const std::string word =
    writeFile("word.txt", identity + "1 0 0 0 0 one 0 0 0 0 1 0\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKittiPoses(word); }), word + ":2:"));

  // A reflection (det -1) is not a pose.
  const std::string mirror = writeFile("mirror.txt", "-1 0 0 0 0 1 0 0 0 0 1 0\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKittiPoses(mirror); }), mirror + ":1:"));

  const std::string missing = (dir_ / "missing.txt").string();
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadKittiPoses(missing); }), missing));
}

TEST_F(TrajectoryIOFiles, KittiSaveToMissingFolderThrows)
{
  const planar_grid::Trajectory trajectory(1, Eigen::Isometry3d::Identity());
  const std::string path = (dir_ / "no_such_folder" / "poses.txt").string();
  EXPECT_THROW(planar_grid::saveKittiPoses(path, trajectory), planar_grid::IOError);
}

// ---------------------------------------------------------------- EuRoC body poses

// The real file (data README): pair 2's line is
// "2 1403715400762142976 0.3394 -0.672895 -0.492724 -0.435018 -0.662997
// -0.495046 1.3473".
TEST(TrajectoryIOEuroc, ReadsTheRealGroundTruth)
{
  const planar_grid::IndexedPoses poses = planar_grid::loadEurocBodyPoses(
    std::string(PLANAR_GRID_DATA_DIR) + "/euroc_v1_01_pairs/gt_body_poses.txt");
  ASSERT_EQ(poses.size(), 4u);
  for (int index = 0; index < 4; ++index)
    ASSERT_EQ(poses.count(index), 1u) << index;
  const Eigen::Isometry3d& pose = poses.at(2);
  EXPECT_NEAR(pose.translation().x(), -0.662997, 1e-9);
  EXPECT_NEAR(pose.translation().y(), -0.495046, 1e-9);
  EXPECT_NEAR(pose.translation().z(), 1.347300, 1e-9);
  const Eigen::Matrix3d rotation = pose.linear();
  EXPECT_LT((rotation * rotation.transpose() - Eigen::Matrix3d::Identity())
              .cwiseAbs()
              .maxCoeff(),
            1e-12);
  EXPECT_NEAR(rotation.determinant(), 1.0, 1e-12);
  // The rotation is the file's quaternion (w first), normalized.
  const Eigen::Quaterniond q =
    Eigen::Quaterniond(0.3394, -0.672895, -0.492724, -0.435018).normalized();
  EXPECT_LT((rotation - q.toRotationMatrix()).cwiseAbs().maxCoeff(), 1e-12);
}

TEST_F(TrajectoryIOFiles, EurocBodyPosesSkipCommentsAndBlankLines)
{
  const std::string path =
    writeFile("gt.txt", "# image timestamp_ns qw qx qy qz x y z\n"
                        "\n"
                        "7 100 1 0 0 0 1 2 3\n"
                        "  # indented comment\n"
                        "3 200 0 0 0 1 -1 -2 -3\n");
  const planar_grid::IndexedPoses poses = planar_grid::loadEurocBodyPoses(path);
  ASSERT_EQ(poses.size(), 2u);
  EXPECT_TRUE(poses.at(7).linear().isIdentity(1e-15));
  EXPECT_TRUE(poses.at(7).translation().isApprox(Eigen::Vector3d(1, 2, 3)));
  // q = (0, 0, 0, 1): half a turn about z.
  EXPECT_NEAR(poses.at(3).linear()(0, 0), -1.0, 1e-15);
  EXPECT_NEAR(poses.at(3).linear()(1, 1), -1.0, 1e-15);
  EXPECT_NEAR(poses.at(3).linear()(2, 2), 1.0, 1e-15);
  EXPECT_TRUE(planar_grid::loadEurocBodyPoses(writeFile("empty.txt", "")).empty());
}

TEST_F(TrajectoryIOFiles, EurocBodyPosesMalformedLineNamesFileAndLine)
{
  const std::string good = "0 100 1 0 0 0 0 0 0\n";
  const auto expectError = [&](const std::string& name, const std::string& content,
                               const std::string& location, const std::string& detail) {
    const std::string path = writeFile(name, content);
    const std::string what = ioErrorOf([&] { planar_grid::loadEurocBodyPoses(path); });
    EXPECT_TRUE(contains(what, path + location)) << name;
    EXPECT_TRUE(contains(what, detail)) << name;
  };
  expectError("eight.txt", good + "1 100 1 0 0 0 0 0\n", ":2:", "expected 9 numbers");
  expectError("ten.txt", "0 100 1 0 0 0 0 0 0 5\n", ":1:", "expected 9 numbers");
  expectError("word.txt", good + "1 100 1 0 zero 0 0 0 0\n", ":2:", "expected numbers");
  expectError("inf.txt", "0 100 1 0 0 0 inf 0 0\n", ":1:", "");
  expectError("huge.txt", "0 100 1 0 0 0 1e999 0 0\n", ":1:", "");
  expectError("zero_q.txt", good + "# c\n1 100 0 0 0 0 0 0 0\n",
              ":3:", "zero quaternion");
  expectError("half_q.txt", "0 100 0.5 0 0 0 0 0 0\n", ":1:", "unit norm");
  expectError("duplicate.txt", good + "1 100 1 0 0 0 0 0 0\n" + good,
              ":3:", "image index 0 appears twice");
  expectError("negative.txt", "-1 100 1 0 0 0 0 0 0\n", ":1:", "non-negative integer");
  expectError("fraction.txt", "1.5 100 1 0 0 0 0 0 0\n", ":1:", "non-negative integer");

  const std::string missing = (dir_ / "missing.txt").string();
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadEurocBodyPoses(missing); }), missing));
}

// ---------------------------------------------------------------- PCD viewpoint

TEST_F(TrajectoryIOFiles, PCDViewpointRoundTrip)
{
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));
  cloud.push_back(pcl::PointXYZ(-1.0f, 0.5f, 4.0f));
  // Values with few digits are stored exactly; the quaternion is a general rotation.
  cloud.sensor_origin_ = Eigen::Vector4f(1.5f, -2.25f, 0.75f, 0.0f);
  const Eigen::Quaterniond rotation(
    Eigen::AngleAxisd(0.7, Eigen::Vector3d(1.0, -2.0, 0.5).normalized()));
  cloud.sensor_orientation_ = rotation.cast<float>();
  const std::string path = (dir_ / "tiny.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileBinary(path, cloud), 0);

  const Eigen::Isometry3d pose = planar_grid::loadPCDViewpoint(path);
  // 1.5, -2.25, 0.75 are exact in float and in PCL's 6-digit header text.
  EXPECT_EQ(pose.translation(), Eigen::Vector3d(1.5, -2.25, 0.75));
  // PCL writes the VIEWPOINT with 6 significant digits: each quaternion component is
  // off by <= 5e-7, so the rotation matrix entries by ~2e-6. 1e-5 bounds that.
  EXPECT_LT((pose.linear() - rotation.toRotationMatrix()).cwiseAbs().maxCoeff(), 1e-5);
  // The result is a proper rotation even though the stored quaternion is rounded.
  EXPECT_NEAR(pose.linear().determinant(), 1.0, 1e-12);
}

TEST_F(TrajectoryIOFiles, PCDViewpointErrors)
{
  const std::string missing = (dir_ / "missing.pcd").string();
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadPCDViewpoint(missing); }), missing));
  const std::string garbage = writeFile("garbage.pcd", "this is not a point cloud\n");
  EXPECT_TRUE(
    contains(ioErrorOf([&] { planar_grid::loadPCDViewpoint(garbage); }), garbage));
}

TEST(TrajectoryIOPCDViewpoint, RealOfficeCloudViewpoint)
{
  // office1.pcd's header reads "VIEWPOINT 0 0 0 0 1 0 0": origin (0, 0, 0) and the
  // quaternion (w, x, y, z) = (0, 1, 0, 0), a half turn about x, i.e. the rotation
  // diag(1, -1, -1). Small integers: exact, so 1e-12 only absorbs the float -> double
  // conversion (which is exact too).
  const std::string path =
    std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/office1.pcd";
  // Start from a different pose so that the checks below see what was loaded.
  Eigen::Isometry3d pose(Eigen::Translation3d(1.0, 2.0, 3.0));
  ASSERT_NO_THROW(pose = planar_grid::loadPCDViewpoint(path));
  EXPECT_LT(pose.translation().norm(), 1e-12);
  const Eigen::Matrix3d half_turn_about_x =
    Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  EXPECT_LT((pose.linear() - half_turn_about_x).cwiseAbs().maxCoeff(), 1e-12)
    << pose.matrix();
}
