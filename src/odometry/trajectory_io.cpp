// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/odometry/trajectory_io.h>

#include <cmath>
#include <cstddef>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <sstream>
#include <string>
#include <vector>

namespace planar_grid {

namespace {

/** \brief "file:line: message", the location format of every IOError thrown here. */
std::string
where(const std::string& path, std::size_t line_number, const std::string& message)
{
  return path + ":" + std::to_string(line_number) + ": " + message;
}

/** \brief Every white-space separated number on \a line; IOError naming file:line
 * when a token is not a number or a number is not finite. */
std::vector<double>
parseNumbers(const std::string& path, std::size_t line_number, const std::string& line)
{
  std::istringstream stream(line);
  std::vector<double> numbers;
  double value = 0.0;
  while (stream >> value) {
    if (!std::isfinite(value))
      throw IOError(where(path, line_number, "non-finite number"));
    numbers.push_back(value);
  }
  // operator>> stops at the end of the line (eof set) or at a token that is not a
  // number (eof not set).
  if (!stream.eof())
    throw IOError(
      where(path, line_number,
            "expected numbers separated by white space, got '" + line + "'"));
  return numbers;
}

/** \brief Opens \a path for reading; IOError when it is missing or unreadable. */
std::ifstream
openForReading(const std::string& path)
{
  checkRegularFile(path);
  std::ifstream in(path);
  if (!in)
    throw IOError(path + ": cannot open for reading");
  return in;
}

/** \brief Reads the text file \a path line by line and calls
 * visit(line_number, numbers) with the numbers (parseNumbers()) of every line that is
 * not blank and, with \a skip_comments, does not start with '#'.
 * \return the number of lines read
 * \throws IOError for a missing or unreadable file, a read error or a token that is not
 * a finite number (file:line) */
template <typename Visit>
std::size_t
forEachNumberLine(const std::string& path, bool skip_comments, Visit visit)
{
  std::ifstream in = openForReading(path);
  std::string line;
  std::size_t line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    const std::size_t first = line.find_first_not_of(" \t\r\n\v\f");
    if (first == std::string::npos || (skip_comments && line[first] == '#'))
      continue;
    visit(line_number, parseNumbers(path, line_number, line));
  }
  if (in.bad())
    throw IOError(path + ": read error");
  return line_number;
}

/** \brief Heading (yaw about +z, radians) of the planar direction \a from -> \a to. */
double
headingOf(const Eigen::Vector3d& from, const Eigen::Vector3d& to)
{
  return std::atan2(to.y() - from.y(), to.x() - from.x());
}

/** \brief Horizontal (x, y) distance between two positions, metres. */
double
horizontalDistance(const Eigen::Vector3d& a, const Eigen::Vector3d& b)
{
  return (a.head<2>() - b.head<2>()).norm();
}

/** \brief Level camera pose at \a position looking along \a yaw_rad (about +z, world
 * z up): camera x right, y down (world -z), z forward. */
Eigen::Isometry3d
levelCameraPose(const Eigen::Vector3d& position, double yaw_rad)
{
  const Eigen::Vector3d forward(std::cos(yaw_rad), std::sin(yaw_rad), 0.0);
  const Eigen::Vector3d down(0.0, 0.0, -1.0);
  // right = down x forward: for forward = +x_world this is -y_world, i.e. to the right
  // of a vehicle driving along +x with z up.
  const Eigen::Vector3d right = down.cross(forward);
  Eigen::Matrix3d rotation;
  rotation.col(0) = right;
  rotation.col(1) = down;
  rotation.col(2) = forward;
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation;
  pose.translation() = position;
  return pose;
}

} // namespace

Trajectory
loadKarlsruheInsData(const std::string& path, double heading_baseline_m)
{
  if (!std::isfinite(heading_baseline_m) || heading_baseline_m <= 0.0)
    throw Exception(path
                    + ": heading_baseline_m must be a positive number of metres, got "
                    + std::to_string(heading_baseline_m));

  // Columns: timestamp_ns lat_deg lon_deg alt_m x_m y_m z_m roll pitch yaw.
  constexpr std::size_t MIN_COLUMNS = 7;
  constexpr std::size_t X_COLUMN = 4;

  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> positions;
  std::vector<std::size_t> line_numbers;
  const std::size_t line_number = forEachNumberLine(
    path, false, [&](std::size_t number, const std::vector<double>& numbers) {
      if (numbers.size() < MIN_COLUMNS)
        throw IOError(where(path, number,
                            "expected at least 7 numbers (timestamp_ns lat_deg lon_deg "
                            "alt_m x_m y_m z_m ...), got "
                              + std::to_string(numbers.size())));
      positions.emplace_back(numbers[X_COLUMN], numbers[X_COLUMN + 1],
                             numbers[X_COLUMN + 2]);
      line_numbers.push_back(number);
    });
  if (positions.empty())
    throw IOError(where(path, line_number, "no poses in the file"));

  // World frame: the local frame shifted so that frame 0 is at the origin.
  const Eigen::Vector3d first = positions.front();
  for (auto& position : positions)
    position -= first;

  const std::size_t count = positions.size();
  Trajectory trajectory;
  trajectory.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const Eigen::Vector3d& here = positions[i];
    // Nearest earlier and later frames whose horizontal chord to this one reaches the
    // baseline: short chords are dominated by GPS/INS noise.
    std::size_t earlier = i;
    bool has_earlier = false;
    for (std::size_t j = i; j-- > 0;)
      if (horizontalDistance(positions[j], here) >= heading_baseline_m) {
        earlier = j;
        has_earlier = true;
        break;
      }
    std::size_t later = i;
    bool has_later = false;
    for (std::size_t k = i + 1; k < count; ++k)
      if (horizontalDistance(positions[k], here) >= heading_baseline_m) {
        later = k;
        has_later = true;
        break;
      }
    if (!has_earlier && !has_later)
      throw IOError(where(path, line_numbers[i],
                          "the track never moves " + std::to_string(heading_baseline_m)
                            + " m away from this frame; cannot tell the heading"));
    // Central difference when both exist, one-sided at the ends of the track.
    const double yaw_rad = headingOf(positions[earlier], positions[later]);
    trajectory.push_back(levelCameraPose(here, yaw_rad));
  }
  return trajectory;
}

Eigen::Isometry3d
zUpWorldFrom(WorldConvention convention)
{
  Eigen::Matrix3d rotation = Eigen::Matrix3d::Identity();
  // Columns: where the convention's x, y and z axes point in the z-up world (x
  // forward, y left, z up).
  switch (convention) {
    case WorldConvention::Z_UP:
      break;
    case WorldConvention::OPTICAL: // right, down, forward
      rotation.col(0) = -Eigen::Vector3d::UnitY();
      rotation.col(1) = -Eigen::Vector3d::UnitZ();
      rotation.col(2) = Eigen::Vector3d::UnitX();
      break;
    case WorldConvention::Y_UP: // right, up, backward
      rotation.col(0) = -Eigen::Vector3d::UnitY();
      rotation.col(1) = Eigen::Vector3d::UnitZ();
      rotation.col(2) = -Eigen::Vector3d::UnitX();
      break;
  }
  Eigen::Isometry3d transform = Eigen::Isometry3d::Identity();
  transform.linear() = rotation;
  return transform;
}

Trajectory
loadKittiPoses(const std::string& path)
{
  const Eigen::Isometry3d z_up_T_optical = zUpWorldFrom(WorldConvention::OPTICAL);
  constexpr std::size_t KITTI_COLUMNS = 12;
  // KITTI files are often written with 6 significant digits, so the stored rotations
  // are orthonormal to about 1e-6; anything far off is not a rotation at all.
  constexpr double ORTHONORMALITY_TOLERANCE = 1e-4;

  Trajectory trajectory;
  forEachNumberLine(
    path, false, [&](std::size_t line_number, const std::vector<double>& numbers) {
      if (numbers.size() != KITTI_COLUMNS)
        throw IOError(where(path, line_number,
                            "expected 12 numbers (row-major 3x4 world_T_camera), got "
                              + std::to_string(numbers.size())));
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      for (int row = 0; row < 3; ++row)
        for (int col = 0; col < 4; ++col)
          pose.matrix()(row, col) = numbers[static_cast<std::size_t>(row * 4 + col)];
      const Eigen::Matrix3d rotation = pose.linear();
      if ((rotation.transpose() * rotation - Eigen::Matrix3d::Identity())
              .cwiseAbs()
              .maxCoeff()
            > ORTHONORMALITY_TOLERANCE
          || rotation.determinant() <= 0.0)
        throw IOError(
          where(path, line_number, "the 3x3 part is not a proper rotation matrix"));
      trajectory.push_back(z_up_T_optical * pose);
    });
  return trajectory;
}

IndexedPoses
loadEurocBodyPoses(const std::string& path)
{
  // Columns: image timestamp_ns qw qx qy qz x_m y_m z_m.
  constexpr std::size_t EUROC_COLUMNS = 9;
  // The file gives the quaternions to 6 digits; a norm far from 1 is a wrong column.
  constexpr double UNIT_NORM_TOLERANCE = 1e-3;
  constexpr double ZERO_NORM = 1e-9;

  IndexedPoses poses;
  forEachNumberLine(
    path, true, [&](std::size_t line_number, const std::vector<double>& numbers) {
      if (numbers.size() != EUROC_COLUMNS)
        throw IOError(where(path, line_number,
                            "expected 9 numbers (image timestamp_ns qw qx qy qz x_m "
                            "y_m z_m), got "
                              + std::to_string(numbers.size())));
      const double image = numbers[0];
      if (image < 0.0 || image > 1e9 || image != std::floor(image))
        throw IOError(
          where(path, line_number, "the image index must be a non-negative integer"));
      const int index = static_cast<int>(image);
      const Eigen::Quaterniond q(numbers[2], numbers[3], numbers[4], numbers[5]);
      if (q.norm() < ZERO_NORM)
        throw IOError(where(path, line_number, "zero quaternion"));
      if (std::abs(q.norm() - 1.0) > UNIT_NORM_TOLERANCE)
        throw IOError(
          where(path, line_number, "the quaternion (qw qx qy qz) is not of unit norm"));
      Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
      pose.linear() = q.normalized().toRotationMatrix();
      pose.translation() = Eigen::Vector3d(numbers[6], numbers[7], numbers[8]);
      if (!poses.emplace(index, pose).second)
        throw IOError(where(path, line_number,
                            "image index " + std::to_string(index) + " appears twice"));
    });
  return poses;
}

void
saveKittiPoses(const std::string& path, const Trajectory& trajectory)
{
  std::ostringstream out;
  // 17 significant digits: every double survives the text round trip exactly.
  out << std::setprecision(17);
  const Eigen::Isometry3d optical_T_z_up =
    zUpWorldFrom(WorldConvention::OPTICAL).inverse();
  for (std::size_t i = 0; i < trajectory.size(); ++i) {
    const Eigen::Matrix4d m = (optical_T_z_up * trajectory[i]).matrix();
    if (!m.topRows<3>().allFinite())
      throw Exception(path + ": pose " + std::to_string(i) + " is not finite");
    for (int row = 0; row < 3; ++row)
      for (int col = 0; col < 4; ++col)
        out << m(row, col) << (row == 2 && col == 3 ? '\n' : ' ');
  }
  writeTextFileAtomically(path, out.str());
}

Eigen::Isometry3d
loadPCDViewpoint(const std::string& path)
{
  // Only the header is used: the VIEWPOINT line holds the pose. The check refuses a
  // file that is not a PCD file and a VIEWPOINT that is not seven finite numbers
  // (which PCL's reader would take as the identity).
  const PCDFileInfo info = checkPCDFile(path);
  const Eigen::Quaternionf& orientation = info.sensor_orientation;
  if (!info.sensor_origin.head<3>().allFinite() || !orientation.coeffs().allFinite()
      || orientation.norm() < 1e-6)
    throw IOError(path + ": VIEWPOINT is not a valid pose");

  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = orientation.cast<double>().normalized().toRotationMatrix();
  pose.translation() = info.sensor_origin.head<3>().cast<double>();
  return pose;
}

bool
isDefaultPCDViewpoint(const Eigen::Isometry3d& sensor_pose)
{
  constexpr double TOLERANCE = 1e-6;
  if (sensor_pose.translation().norm() > TOLERANCE)
    return false;
  const Eigen::Matrix3d& rotation = sensor_pose.linear();
  const Eigen::Matrix3d grabber = Eigen::Vector3d(1.0, -1.0, -1.0).asDiagonal();
  return (rotation - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff() < TOLERANCE
         || (rotation - grabber).cwiseAbs().maxCoeff() < TOLERANCE;
}

} // namespace planar_grid
