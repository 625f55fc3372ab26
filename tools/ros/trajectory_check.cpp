// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_trajectory_check: the errors of estimated camera trajectories against a
// ground truth, with the project's odometry metrics (trajectory_metrics.h, as
// planar_grid_odometry_eval computes them; docs/ODOMETRY.md), for the ROS node's stereo
// test (test_ros_node.py --stereo-odometry, docs/ROS.md).
//   planar_grid_trajectory_check --ground-truth POSES.txt
//                                (--kitti NAME=FILE | --tum NAME=FILE)...
// POSES.txt and --kitti files: KITTI poses, one row-major 3x4 world_T_camera a line in
// the optical world (planar_grid_pipeline's trajectory.txt, KITTI's poses.txt);
// --tum files: "stamp x y z qx qy qz qw" a line, world_T_camera in a z-up world (what
// the node publishes on /tf and ~odometry; stamp in seconds, unused). Each trajectory
// must have the ground truth's number of poses. Prints one JSON object: per NAME its
// frames, RTE over all segments of 10-50 m (percent) and per length, ATE RMSE (m), its
// path length and the ground truth's (m), and its largest position (m) and rotation
// (rad) difference from the first trajectory given, both in the z-up world.
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/odometry/trajectory_metrics.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <iostream>
#include <sstream>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

namespace {

/** A TUM trajectory file's poses (z-up world, meters), in file order; blank lines and
 * lines starting with '#' are skipped.
 * \throws std::runtime_error naming file:line for a line that is not 8 finite numbers
 * or a quaternion far from unit norm */
planar_grid::Trajectory
loadTumPoses(const std::string& path)
{
  std::ifstream in(path);
  if (!in)
    throw std::runtime_error("cannot open " + path);
  planar_grid::Trajectory poses;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    if (line.empty() || line[0] == '#')
      continue;
    std::istringstream fields(line);
    double stamp_s = 0.0;
    Eigen::Vector3d t;
    double qx = 0.0, qy = 0.0, qz = 0.0, qw = 0.0;
    std::string rest;
    if (!(fields >> stamp_s >> t.x() >> t.y() >> t.z() >> qx >> qy >> qz >> qw)
        || (fields >> rest) || !t.allFinite())
      throw std::runtime_error(path + ":" + std::to_string(number)
                               + ": expected 8 numbers: stamp x y z qx qy qz qw");
    const Eigen::Quaterniond q(qw, qx, qy, qz);
    if (!(std::abs(q.norm() - 1.0) < 1e-3))
      throw std::runtime_error(path + ":" + std::to_string(number)
                               + ": the quaternion is not of unit norm");
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() = q.normalized().toRotationMatrix();
    pose.translation() = t;
    poses.push_back(pose);
  }
  return poses;
}

/** The length of the path through \a poses' positions, meters. */
double
pathLength(const planar_grid::Trajectory& poses)
{
  double length = 0.0;
  for (std::size_t i = 1; i < poses.size(); ++i)
    length += (poses[i].translation() - poses[i - 1].translation()).norm();
  return length;
}

/** "NAME=FILE" split at the first '='. \throws std::runtime_error without one */
std::pair<std::string, std::string>
namedFile(const std::string& text)
{
  const auto at = text.find('=');
  if (at == std::string::npos || at == 0 || at + 1 == text.size())
    throw std::runtime_error("expected NAME=FILE, got '" + text + "'");
  return {text.substr(0, at), text.substr(at + 1)};
}

} // namespace

int
main(int argc, char** argv)
{
  try {
    std::string ground_truth_path;
    std::vector<std::pair<std::string, planar_grid::Trajectory>> estimated;
    for (int i = 1; i + 1 < argc; i += 2) {
      const std::string key = argv[i];
      if (key == "--ground-truth")
        ground_truth_path = argv[i + 1];
      else if (key == "--kitti" || key == "--tum") {
        const auto [name, path] = namedFile(argv[i + 1]);
        estimated.emplace_back(name, key == "--kitti"
                                       ? planar_grid::loadKittiPoses(path)
                                       : loadTumPoses(path));
      } else
        throw std::runtime_error("unknown option " + key);
    }
    if (argc % 2 == 0 || ground_truth_path.empty() || estimated.empty()) {
      std::cerr << "usage: planar_grid_trajectory_check --ground-truth POSES.txt "
                   "(--kitti NAME=FILE | --tum NAME=FILE)...\n";
      return 2;
    }
    const planar_grid::Trajectory ground_truth =
      planar_grid::loadKittiPoses(ground_truth_path);
    // The segment lengths of planar_grid_odometry_eval and docs/ODOMETRY.md.
    const std::vector<double> lengths_m{10.0, 20.0, 30.0, 40.0, 50.0};
    nlohmann::json result;
    const planar_grid::Trajectory& first = estimated.front().second;
    for (const auto& [name, poses] : estimated) {
      if (poses.size() != ground_truth.size())
        throw std::runtime_error(name + " has " + std::to_string(poses.size())
                                 + " poses, the ground truth "
                                 + std::to_string(ground_truth.size()));
      const auto rte =
        planar_grid::relativeTranslationError(poses, ground_truth, lengths_m);
      nlohmann::json j;
      j["frames"] = poses.size();
      j["rte_percent"] = planar_grid::meanRelativeTranslationError(rte);
      for (const auto& segment : rte)
        j["rte_by_length"].push_back({{"length_m", segment.segment_length_m},
                                      {"segments", segment.segments},
                                      {"percent", segment.mean_error_percent}});
      j["ate_m"] = planar_grid::absoluteTrajectoryError(poses, ground_truth);
      j["path_length_m"] = pathLength(poses);
      j["path_length_ground_truth_m"] = pathLength(ground_truth);
      double position_m = 0.0, rotation_rad = 0.0;
      for (std::size_t i = 0; i < poses.size(); ++i) {
        position_m = std::max(position_m,
                              (poses[i].translation() - first[i].translation()).norm());
        rotation_rad = std::max(
          rotation_rad,
          Eigen::AngleAxisd(first[i].linear().transpose() * poses[i].linear()).angle());
      }
      j["max_position_difference_m"] = position_m;
      j["max_rotation_difference_rad"] = rotation_rad;
      result[name] = j;
    }
    std::cout << result.dump(2) << "\n";
  } catch (const std::exception& e) {
    std::cerr << "planar_grid_trajectory_check: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
