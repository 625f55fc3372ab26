// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/trajectory_metrics.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <string>

namespace planar_grid {

namespace {

void
checkSizes(const Trajectory& estimated, const Trajectory& ground_truth)
{
  if (estimated.size() != ground_truth.size() || estimated.size() < 3)
    throw Exception("trajectory metrics: need the same number (>= 3) of estimated and "
                    "ground-truth poses, got "
                    + std::to_string(estimated.size()) + " and "
                    + std::to_string(ground_truth.size()));
}

} // namespace

Eigen::Isometry3d
alignPositions(const Trajectory& estimated, const Trajectory& ground_truth)
{
  checkSizes(estimated, ground_truth);
  Eigen::Matrix3Xd source(3, estimated.size());
  Eigen::Matrix3Xd destination(3, ground_truth.size());
  for (std::size_t i = 0; i < estimated.size(); ++i) {
    source.col(static_cast<Eigen::Index>(i)) = estimated[i].translation();
    destination.col(static_cast<Eigen::Index>(i)) = ground_truth[i].translation();
  }
  Eigen::Isometry3d gt_T_est;
  gt_T_est.matrix() = Eigen::umeyama(source, destination, false);
  return gt_T_est;
}

double
absoluteTrajectoryError(const Trajectory& estimated, const Trajectory& ground_truth)
{
  const Eigen::Isometry3d gt_T_est = alignPositions(estimated, ground_truth);
  double sum = 0.0;
  for (std::size_t i = 0; i < estimated.size(); ++i)
    sum += (gt_T_est * estimated[i].translation() - ground_truth[i].translation())
             .squaredNorm();
  return std::sqrt(sum / static_cast<double>(estimated.size()));
}

std::vector<RelativeTranslationError>
relativeTranslationError(const Trajectory& estimated,
                         const Trajectory& ground_truth,
                         const std::vector<double>& segment_lengths_m)
{
  const Eigen::Matrix3d rotation = alignPositions(estimated, ground_truth).linear();
  // Ground-truth path length from frame 0 to each frame.
  std::vector<double> distance(ground_truth.size(), 0.0);
  for (std::size_t k = 1; k < ground_truth.size(); ++k)
    distance[k] =
      distance[k - 1]
      + (ground_truth[k].translation() - ground_truth[k - 1].translation()).norm();

  std::vector<RelativeTranslationError> errors;
  for (const double length : segment_lengths_m) {
    if (!(length > 0.0))
      throw Exception("relativeTranslationError: segment lengths must be > 0, got "
                      + std::to_string(length));
    RelativeTranslationError error;
    error.segment_length_m = length;
    double sum = 0.0;
    std::size_t j = 0;
    for (std::size_t i = 0; i < ground_truth.size(); ++i) {
      j = std::max(j, i);
      while (j < ground_truth.size() && distance[j] - distance[i] < length)
        ++j;
      if (j >= ground_truth.size())
        break; // later start frames have even less path left
      const Eigen::Vector3d estimated_step =
        rotation * (estimated[j].translation() - estimated[i].translation());
      const Eigen::Vector3d true_step =
        ground_truth[j].translation() - ground_truth[i].translation();
      sum += (estimated_step - true_step).norm() / length;
      ++error.segments;
    }
    if (error.segments > 0)
      error.mean_error_percent = 100.0 * sum / static_cast<double>(error.segments);
    errors.push_back(error);
  }
  return errors;
}

double
meanRelativeTranslationError(const std::vector<RelativeTranslationError>& errors)
{
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& error : errors) {
    sum += error.mean_error_percent * static_cast<double>(error.segments);
    count += error.segments;
  }
  return count > 0 ? sum / static_cast<double>(count) : 0.0;
}

Trajectory
withReferenceStepLengths(const Trajectory& estimated, const Trajectory& reference)
{
  checkSizes(estimated, reference);
  Trajectory result{estimated.front()};
  for (std::size_t k = 1; k < estimated.size(); ++k) {
    const Eigen::Vector3d step =
      estimated[k].translation() - estimated[k - 1].translation();
    const double length =
      (reference[k].translation() - reference[k - 1].translation()).norm();
    Eigen::Isometry3d pose = estimated[k];
    pose.translation() = result.back().translation();
    if (step.norm() > 0.0)
      pose.translation() += step.normalized() * length;
    result.push_back(pose);
  }
  return result;
}

Trajectory
offsetAlongTrack(const Trajectory& trajectory, double forward_m, double left_m)
{
  if (trajectory.size() < 2)
    throw Exception("offsetAlongTrack: need at least 2 poses, got "
                    + std::to_string(trajectory.size()));
  Trajectory result = trajectory;
  for (std::size_t k = 0; k < trajectory.size(); ++k) {
    const std::size_t before = k == 0 ? 0 : k - 1;
    const std::size_t after = k + 1 < trajectory.size() ? k + 1 : k;
    Eigen::Vector3d forward =
      trajectory[after].translation() - trajectory[before].translation();
    forward.z() = 0.0;
    if (!(forward.norm() > 0.0))
      continue; // standing still: the direction of travel is not defined
    forward.normalize();
    const Eigen::Vector3d left(-forward.y(), forward.x(), 0.0);
    result[k].translation() += forward_m * forward + left_m * left;
  }
  return result;
}

} // namespace planar_grid
