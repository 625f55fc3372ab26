// SPDX-License-Identifier: BSD-3-Clause
// The refinements of a stereo motion estimate: Gauss-Newton on the stereo reprojection
// error (with the disparity offset as an optional unknown) and on the epipolar
// (Sampson) error of the left key points.
#include <Eigen/Cholesky>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

#include "stereo_odometry_impl.h"

namespace planar_grid {
namespace detail {

bool
triangulate(const cv::KeyPoint& left,
            const cv::KeyPoint& right,
            const StereoCalibration& calibration,
            double offset_px,
            Eigen::Vector3d& point)
{
  const double disparity =
    static_cast<double>(left.pt.x) - static_cast<double>(right.pt.x) + offset_px;
  if (!(disparity >= 0.1))
    return false;
  const double scale = calibration.baseline_m / disparity;
  point = Eigen::Vector3d((left.pt.x - calibration.cx_px) * scale,
                          (left.pt.y - calibration.cy_px) * scale,
                          calibration.focal_length_px * scale);
  return true;
}

bool
reprojectionResiduals(const Eigen::Isometry3d& previous_T_current,
                      const StereoCalibration& calibration,
                      double offset_px,
                      const StereoKeypoints& keypoints,
                      Eigen::Matrix<double, 8, 1>& residuals)
{
  Eigen::Vector3d previous_point, current_point;
  if (!triangulate(*keypoints[0], *keypoints[1], calibration, offset_px, previous_point)
      || !triangulate(*keypoints[2], *keypoints[3], calibration, offset_px,
                      current_point))
    return false;
  const Eigen::Vector3d in_current = previous_T_current.inverse() * previous_point;
  const Eigen::Vector3d in_previous = previous_T_current * current_point;
  if (in_current.z() < 0.1 || in_previous.z() < 0.1)
    return false;
  const double f = calibration.focal_length_px;
  const auto project = [&](const Eigen::Vector3d& p, const cv::KeyPoint* left,
                           const cv::KeyPoint* right, int offset) {
    const double v = f * p.y() / p.z() + calibration.cy_px;
    residuals[offset] = f * p.x() / p.z() + calibration.cx_px - left->pt.x;
    residuals[offset + 1] = v - left->pt.y;
    residuals[offset + 2] = f * (p.x() - calibration.baseline_m) / p.z()
                            + calibration.cx_px + offset_px - right->pt.x;
    residuals[offset + 3] = v - right->pt.y;
  };
  project(in_current, keypoints[2], keypoints[3], 0);
  project(in_previous, keypoints[0], keypoints[1], 4);
  return true;
}

namespace {

/** \brief A small motion exp(delta) applied on the left: rotation vector delta[0..2]
 * (radians), translation delta[3..5] (metres). */
Eigen::Isometry3d
perturbation(const Eigen::Matrix<double, 6, 1>& delta)
{
  Eigen::Isometry3d result = Eigen::Isometry3d::Identity();
  const double angle = delta.head<3>().norm();
  if (angle > 0.0)
    result.linear() =
      Eigen::AngleAxisd(angle, delta.head<3>() / angle).toRotationMatrix();
  result.translation() = delta.tail<3>();
  return result;
}

} // namespace

Eigen::Isometry3d
refineReprojection(Eigen::Isometry3d motion,
                   const StereoCalibration& calibration,
                   const std::vector<StereoKeypoints>& keypoints,
                   const pcl::Indices& inliers,
                   bool rotation_fixed,
                   bool estimate_offset,
                   const OffsetEstimate& prior,
                   OffsetEstimate& offset)
{
  using Matrix7d = Eigen::Matrix<double, 7, 7>;
  using Vector7d = Eigen::Matrix<double, 7, 1>;
  const double step = 1e-6;
  // Unknowns: rotation vector (0-2), translation (3-5), disparity offset (6). With the
  // rotation fixed only the translation columns of the Jacobian are needed.
  const int first_column = rotation_fixed ? 3 : 0;
  const int last_column = estimate_offset ? 7 : 6;
  for (int iteration = 0; iteration < 10; ++iteration) {
    // The motions one numerical step away in each direction, shared by every
    // correspondence of this iteration.
    std::array<Eigen::Isometry3d, 12> perturbed;
    for (int k = first_column; k < 6; ++k) {
      Eigen::Matrix<double, 6, 1> delta = Eigen::Matrix<double, 6, 1>::Zero();
      delta[k] = step;
      perturbed[static_cast<std::size_t>(2 * k)] = perturbation(delta) * motion;
      perturbed[static_cast<std::size_t>(2 * k + 1)] = perturbation(-delta) * motion;
    }
    Matrix7d hessian = Matrix7d::Zero();
    Vector7d gradient = Vector7d::Zero();
    std::size_t used = 0;
    for (const auto index : inliers) {
      const StereoKeypoints& points = keypoints[static_cast<std::size_t>(index)];
      Eigen::Matrix<double, 8, 1> residuals, plus, minus;
      if (!reprojectionResiduals(motion, calibration, offset.offset_px, points,
                                 residuals))
        continue;
      Eigen::Matrix<double, 8, 7> jacobian = Eigen::Matrix<double, 8, 7>::Zero();
      bool ok = true;
      for (int k = first_column; k < last_column && ok; ++k) {
        if (k < 6)
          ok = reprojectionResiduals(perturbed[static_cast<std::size_t>(2 * k)],
                                     calibration, offset.offset_px, points, plus)
               && reprojectionResiduals(perturbed[static_cast<std::size_t>(2 * k + 1)],
                                        calibration, offset.offset_px, points, minus);
        else
          ok = reprojectionResiduals(motion, calibration, offset.offset_px + step,
                                     points, plus)
               && reprojectionResiduals(motion, calibration, offset.offset_px - step,
                                        points, minus);
        jacobian.col(k) = (plus - minus) / (2.0 * step);
      }
      if (!ok)
        continue;
      for (int m = 0; m < 8; ++m) {
        const double magnitude = std::abs(residuals[m]);
        const double weight = magnitude <= 1.0 ? 1.0 : 1.0 / magnitude;
        hessian += weight * jacobian.row(m).transpose() * jacobian.row(m);
        gradient += weight * jacobian.row(m).transpose() * residuals[m];
      }
      ++used;
    }
    if (used < 3)
      break;
    if (estimate_offset) {
      // The data's information on the offset once the motion is free (Schur
      // complement), plus the prior's.
      const int n = 6 - first_column;
      const Eigen::MatrixXd motion_block =
        hessian.block(first_column, first_column, n, n);
      const Eigen::VectorXd cross = hessian.block(first_column, 6, n, 1);
      const double data_information =
        hessian(6, 6) - cross.dot(motion_block.ldlt().solve(cross));
      offset.information = prior.information + std::max(0.0, data_information);
      hessian(6, 6) += prior.information;
      gradient[6] += prior.information * (offset.offset_px - prior.offset_px);
    }
    const int n = last_column - first_column;
    Vector7d delta = Vector7d::Zero();
    delta.segment(first_column, n) = -hessian.block(first_column, first_column, n, n)
                                        .ldlt()
                                        .solve(gradient.segment(first_column, n));
    if (!delta.allFinite())
      break;
    motion = perturbation(delta.head<6>()) * motion;
    offset.offset_px += delta[6];
    if (delta.norm() < 1e-10)
      break;
  }
  return motion;
}

namespace {

/** \brief The cross-product matrix [v]x (so that [v]x w = v x w). */
Eigen::Matrix3d
skew(const Eigen::Vector3d& v)
{
  Eigen::Matrix3d result;
  result << 0.0, -v.z(), v.y(), v.z(), 0.0, -v.x(), -v.y(), v.x(), 0.0;
  return result;
}

/** \brief Viewing ray (x / z, y / z, 1) of a key point in the rectified camera. */
Eigen::Vector3d
viewingRay(const cv::KeyPoint& keypoint, const StereoCalibration& calibration)
{
  return {(keypoint.pt.x - calibration.cx_px) / calibration.focal_length_px,
          (keypoint.pt.y - calibration.cy_px) / calibration.focal_length_px, 1.0};
}

/** \brief Signed Sampson distance, pixels, of one pair of left-image rays from the
 * epipolar constraint x_prev^T E x_cur = 0 with E = [direction]x rotation, i.e. of the
 * motion previous_T_current = [rotation | s direction] for any scale s > 0. */
double
sampsonDistance(const Eigen::Matrix3d& rotation,
                const Eigen::Vector3d& direction,
                const Eigen::Vector3d& previous_ray,
                const Eigen::Vector3d& current_ray,
                double focal_length_px)
{
  const Eigen::Matrix3d essential = skew(direction) * rotation;
  const Eigen::Vector3d line_previous = essential * current_ray;
  const Eigen::Vector3d line_current = essential.transpose() * previous_ray;
  const double norm =
    line_previous.head<2>().squaredNorm() + line_current.head<2>().squaredNorm();
  if (!(norm > 0.0))
    return 0.0;
  return focal_length_px * previous_ray.dot(line_previous) / std::sqrt(norm);
}

/** \brief The rotation and unit translation direction after a 5-vector step: rotation
 * vector delta[0..2] applied on the left (radians), direction moved by delta[3] and
 * delta[4] along two unit vectors orthogonal to it. */
void
applyEpipolarStep(const Eigen::Matrix<double, 5, 1>& delta,
                  const Eigen::Matrix3d& rotation,
                  const Eigen::Vector3d& direction,
                  Eigen::Matrix3d& new_rotation,
                  Eigen::Vector3d& new_direction)
{
  const Eigen::Vector3d axis =
    std::abs(direction.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
  const Eigen::Vector3d first = direction.cross(axis).normalized();
  const Eigen::Vector3d second = direction.cross(first).normalized();
  Eigen::Matrix<double, 6, 1> rotation_step = Eigen::Matrix<double, 6, 1>::Zero();
  rotation_step.head<3>() = delta.head<3>();
  new_rotation = perturbation(rotation_step).linear() * rotation;
  new_direction = (direction + delta[3] * first + delta[4] * second).normalized();
}

} // namespace

void
refineEpipolar(Eigen::Matrix3d& rotation,
               Eigen::Vector3d& direction,
               const StereoCalibration& calibration,
               const std::vector<StereoKeypoints>& keypoints,
               const pcl::Indices& inliers,
               double threshold_px)
{
  std::vector<Eigen::Vector3d> previous_rays, current_rays;
  std::vector<double> sizes;
  for (const auto index : inliers) {
    const StereoKeypoints& points = keypoints[static_cast<std::size_t>(index)];
    previous_rays.push_back(viewingRay(*points[0], calibration));
    current_rays.push_back(viewingRay(*points[2], calibration));
    sizes.push_back(std::max(points[0]->size, points[2]->size));
  }
  std::vector<double> sorted = sizes;
  std::nth_element(sorted.begin(), sorted.begin() + sorted.size() / 2, sorted.end());
  const double median_size = sorted[sorted.size() / 2];
  std::vector<double> weights(sizes.size(), 1.0);
  if (median_size > 0.0)
    for (std::size_t i = 0; i < sizes.size(); ++i)
      if (sizes[i] > 0.0)
        weights[i] = (median_size / sizes[i]) * (median_size / sizes[i]);

  const double f = calibration.focal_length_px;
  const double step = 1e-6;
  for (int iteration = 0; iteration < 10; ++iteration) {
    // The rotations and directions one numerical step away in each of the 5
    // directions, shared by every correspondence of this iteration.
    std::array<Eigen::Matrix3d, 10> rotations;
    std::array<Eigen::Vector3d, 10> directions;
    for (int k = 0; k < 5; ++k) {
      Eigen::Matrix<double, 5, 1> delta = Eigen::Matrix<double, 5, 1>::Zero();
      delta[k] = step;
      const auto plus = static_cast<std::size_t>(2 * k);
      applyEpipolarStep(delta, rotation, direction, rotations[plus], directions[plus]);
      applyEpipolarStep(-delta, rotation, direction, rotations[plus + 1],
                        directions[plus + 1]);
    }
    Eigen::Matrix<double, 5, 5> hessian = Eigen::Matrix<double, 5, 5>::Zero();
    Eigen::Matrix<double, 5, 1> gradient = Eigen::Matrix<double, 5, 1>::Zero();
    for (std::size_t i = 0; i < previous_rays.size(); ++i) {
      const double residual =
        sampsonDistance(rotation, direction, previous_rays[i], current_rays[i], f);
      Eigen::Matrix<double, 1, 5> jacobian;
      for (int k = 0; k < 5; ++k) {
        const auto plus = static_cast<std::size_t>(2 * k);
        jacobian[k] = (sampsonDistance(rotations[plus], directions[plus],
                                       previous_rays[i], current_rays[i], f)
                       - sampsonDistance(rotations[plus + 1], directions[plus + 1],
                                         previous_rays[i], current_rays[i], f))
                      / (2.0 * step);
      }
      // Huber weight on the residual scaled to unit key point size.
      const double magnitude = std::abs(residual) * std::sqrt(weights[i]);
      const double weight =
        weights[i] * (magnitude <= threshold_px ? 1.0 : threshold_px / magnitude);
      hessian += weight * jacobian.transpose() * jacobian;
      gradient += weight * jacobian.transpose() * residual;
    }
    const Eigen::Matrix<double, 5, 1> delta = -hessian.ldlt().solve(gradient);
    if (!delta.allFinite())
      break;
    Eigen::Matrix3d new_rotation;
    Eigen::Vector3d new_direction;
    applyEpipolarStep(delta, rotation, direction, new_rotation, new_direction);
    rotation = new_rotation;
    direction = new_direction;
    if (delta.norm() < 1e-10)
      break;
  }
}

} // namespace detail
} // namespace planar_grid
