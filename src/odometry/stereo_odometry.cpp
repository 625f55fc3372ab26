// SPDX-License-Identifier: BSD-3-Clause
// The motion of one stereo frame pair (paper eq. 8): descriptor matching, RANSAC over
// the 3D correspondences, least-squares, reprojection and epipolar refinement, and the
// disparity offset. The frame sequence around it (motion model, trajectory, checkpoint
// state) is in visual_odometry.cpp.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include <pcl/common/centroid.h>
#include <pcl/console/print.h>
#include <pcl/registration/transformation_estimation_svd.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_registration.h>

#include <Eigen/Eigenvalues>
#include <opencv2/core.hpp>
#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <sstream>
#include <utility>

namespace planar_grid {

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** \brief SampleConsensusModelRegistration whose sampler takes a seed, so that runs
 * are repeatable and the seed can still be varied (PCL's model only offers a fixed
 * seed or the time), and whose point-to-point distances are divided by a
 * per-correspondence scale (1 for a fixed threshold, larger for far points whose
 * stereo depth is less certain). Correspondence i is source point i and target
 * point i. */
class ScaledRegistrationModel
    : public pcl::SampleConsensusModelRegistration<pcl::PointXYZ> {
public:
  ScaledRegistrationModel(const Cloud::ConstPtr& source,
                          const Cloud::ConstPtr& target,
                          std::vector<float> scales,
                          unsigned seed) :
      pcl::SampleConsensusModelRegistration<pcl::PointXYZ>(source, false),
      source_(source), target_points_(target), scales_(std::move(scales))
  {
    rng_alg_.seed(seed);
    setInputTarget(target);
  }

  void getDistancesToModel(const Eigen::VectorXf& model_coefficients,
                           std::vector<double>& distances) const override
  {
    distances.resize(source_->size());
    const Eigen::Matrix4f transform = toMatrix(model_coefficients);
    for (std::size_t i = 0; i < source_->size(); ++i)
      distances[i] = scaledDistance(transform, i);
  }

  void selectWithinDistance(const Eigen::VectorXf& model_coefficients,
                            const double threshold,
                            pcl::Indices& inliers) override
  {
    inliers.clear();
    error_sqr_dists_.clear();
    if (model_coefficients.size() != 16)
      return;
    const Eigen::Matrix4f transform = toMatrix(model_coefficients);
    for (std::size_t i = 0; i < source_->size(); ++i) {
      const double distance = scaledDistance(transform, i);
      if (distance < threshold) {
        inliers.push_back(static_cast<pcl::index_t>(i));
        error_sqr_dists_.push_back(distance * distance);
      }
    }
  }

  std::size_t countWithinDistance(const Eigen::VectorXf& model_coefficients,
                                  const double threshold) const override
  {
    if (model_coefficients.size() != 16)
      return 0;
    const Eigen::Matrix4f transform = toMatrix(model_coefficients);
    std::size_t count = 0;
    for (std::size_t i = 0; i < source_->size(); ++i)
      if (scaledDistance(transform, i) < threshold)
        ++count;
    return count;
  }

private:
  static Eigen::Matrix4f toMatrix(const Eigen::VectorXf& coefficients)
  {
    Eigen::Matrix4f transform = Eigen::Matrix4f::Identity();
    if (coefficients.size() == 16)
      for (int row = 0; row < 4; ++row)
        transform.row(row) = coefficients.segment<4>(row * 4).transpose();
    return transform;
  }

  double scaledDistance(const Eigen::Matrix4f& transform, std::size_t i) const
  {
    const Eigen::Vector3f moved =
      transform.topLeftCorner<3, 3>() * (*source_)[i].getVector3fMap()
      + transform.topRightCorner<3, 1>();
    return static_cast<double>((moved - (*target_points_)[i].getVector3fMap()).norm()
                               / scales_[i]);
  }

  Cloud::ConstPtr source_;
  Cloud::ConstPtr target_points_;
  std::vector<float> scales_;
};

/** \brief Weighted least-squares rigid transform target = T * source over the given
 * correspondences (weighted Kabsch/Umeyama without scale, SVD). */
Eigen::Matrix4d
weightedRigidTransform(const Cloud& source,
                       const Cloud& target,
                       const pcl::Indices& indices,
                       const std::vector<float>& weights)
{
  double total = 0.0;
  Eigen::Vector3d source_mean = Eigen::Vector3d::Zero();
  Eigen::Vector3d target_mean = Eigen::Vector3d::Zero();
  for (const auto index : indices) {
    const auto i = static_cast<std::size_t>(index);
    const double w = weights[i];
    total += w;
    source_mean += w * source[i].getVector3fMap().cast<double>();
    target_mean += w * target[i].getVector3fMap().cast<double>();
  }
  source_mean /= total;
  target_mean /= total;
  Eigen::Matrix3d cross = Eigen::Matrix3d::Zero();
  for (const auto index : indices) {
    const auto i = static_cast<std::size_t>(index);
    cross += weights[i] * (target[i].getVector3fMap().cast<double>() - target_mean)
             * (source[i].getVector3fMap().cast<double>() - source_mean).transpose();
  }
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(cross, Eigen::ComputeFullU
                                                       | Eigen::ComputeFullV);
  Eigen::Matrix3d sign = Eigen::Matrix3d::Identity();
  if ((svd.matrixU() * svd.matrixV().transpose()).determinant() < 0.0)
    sign(2, 2) = -1.0;
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  transform.topLeftCorner<3, 3>() = svd.matrixU() * sign * svd.matrixV().transpose();
  transform.topRightCorner<3, 1>() =
    target_mean - transform.topLeftCorner<3, 3>() * source_mean;
  return transform;
}

/** \brief Points within 1 mm of one line (or fewer than 2 points): the rotation about
 * that line is not observable. */
bool
isColinear(const Cloud& cloud)
{
  if (cloud.size() < 2)
    return true;
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  Eigen::Vector4d centroid = Eigen::Vector4d::Zero();
  if (pcl::computeMeanAndCovarianceMatrix(cloud, covariance, centroid) < 2)
    return true;
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance,
                                                              Eigen::EigenvaluesOnly);
  const Eigen::Vector3d eigenvalues = solver.eigenvalues(); // ascending
  const double middle = std::max(eigenvalues[1], 0.0);
  return std::sqrt(middle) < 1e-3 || middle < 1e-10 * eigenvalues[2];
}

/** \brief The 16 row-major coefficients of a 4x4 transform, as the registration model
 * stores them. */
Eigen::VectorXf
toCoefficients(const Eigen::Matrix4d& transform)
{
  Eigen::VectorXf coefficients(16);
  for (int row = 0; row < 4; ++row)
    for (int col = 0; col < 4; ++col)
      coefficients[row * 4 + col] = static_cast<float>(transform(row, col));
  return coefficients;
}

/** \brief The key points of one correspondence: previous left, previous right,
 * current left, current right. */
using StereoKeypoints = std::array<const cv::KeyPoint*, 4>;

/** \brief The point of a left and a right key point in the rectified left camera
 * frame (metres), with \a offset_px added to their disparity u_left - u_right:
 * z = f B / (d + offset), x = (u_left - cx) z / f, y = (v_left - cy) z / f, as
 * StereoFeatureMatcher triangulates with no offset. False when the corrected
 * disparity is below 0.1 px. */
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

/** \brief Stereo reprojection residuals of one correspondence: the previous point
 * projected into the current left and right images and the current point into the
 * previous ones, minus the matched key points (8 values, pixels). Both points are
 * triangulated from their key points with the disparity offset \a offset_px (true
 * disparity = measured + offset), and the right projections carry the same offset
 * (a measured right column is the true one + offset), so that the offset acts as the
 * difference of the two rectified cameras' principal point columns. False when a
 * disparity is too small or a point falls behind a camera. */
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

/** \brief The disparity offset of a reprojection refinement: its value (px) and its
 * information (1 / variance, px^-2, for residuals of unit variance in pixels). */
struct OffsetEstimate {
  double offset_px{0.0};
  double information{0.0};
};

/** \brief Gauss-Newton on the stereo reprojection error of the given correspondences,
 * with Huber weights (1 px) and numerical derivatives; 10 iterations at most. With
 * rotation_fixed only the translation changes. \a offset holds the disparity offset
 * the refinement starts from. With \a estimate_offset the offset is a seventh unknown
 * with the Gaussian prior \a prior (its information is the prior's weight), and
 * \a offset receives the estimate and its information (the prior's plus the data's,
 * the Schur complement of the motion); without it \a offset is left as it is. */
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

/** \brief Gauss-Newton on the Sampson distances of the left key points of the given
 * correspondences over the rotation and the translation direction (5 degrees of
 * freedom; numerical derivatives; Huber weights of threshold_px; each
 * correspondence weighted by (median size / size)^2 with size the larger of its two
 * key point sizes, as the localisation error grows with the detection scale). 10
 * iterations at most. */
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

OdometryResult
invalidResult(std::size_t correspondences,
              std::size_t inliers,
              const std::string& reason)
{
  OdometryResult result;
  result.correspondences = correspondences;
  result.inliers = inliers;
  result.valid = false;
  result.reason = reason;
  PCL_WARN("[planar_grid::StereoOdometry::estimate] %s\n", reason.c_str());
  return result;
}

} // namespace

StereoOdometry::StereoOdometry(const Params& params) : params_(params)
{
  std::ostringstream error;
  if (!(params.ratio > 0.0 && params.ratio <= 1.0))
    error << "ratio must be in (0, 1], got " << params.ratio;
  else if (!(params.max_descriptor_distance >= 0.0))
    error << "max_descriptor_distance must be >= 0, got "
          << params.max_descriptor_distance;
  else if (!(params.distance_threshold_m > 0.0))
    error << "distance_threshold_m must be > 0, got " << params.distance_threshold_m;
  else if (!(params.reference_depth_m >= 0.0))
    error << "reference_depth_m must be >= 0, got " << params.reference_depth_m;
  else if (!(params.reprojection_threshold_px > 0.0))
    error << "reprojection_threshold_px must be > 0, got "
          << params.reprojection_threshold_px;
  else if (!(params.epipolar_threshold_px > 0.0))
    error << "epipolar_threshold_px must be > 0, got " << params.epipolar_threshold_px;
  else if (!(params.epipolar_max_rotation_change_rad > 0.0))
    error << "epipolar_max_rotation_change_rad must be > 0, got "
          << params.epipolar_max_rotation_change_rad;
  else if (!(params.epipolar_min_translation_m >= 0.0))
    error << "epipolar_min_translation_m must be >= 0, got "
          << params.epipolar_min_translation_m;
  else if (!(std::abs(params.disparity_offset_px) <= 20.0))
    error << "disparity_offset_px must be in [-20, 20], got "
          << params.disparity_offset_px;
  else if (!(params.disparity_offset_sigma_px > 0.0)
           || !std::isfinite(params.disparity_offset_sigma_px))
    error << "disparity_offset_sigma_px must be > 0, got "
          << params.disparity_offset_sigma_px;
  else if (!(params.disparity_offset_memory >= 0.0
             && params.disparity_offset_memory <= 1.0))
    error << "disparity_offset_memory must be in [0, 1], got "
          << params.disparity_offset_memory;
  else if (params.max_iterations < 1)
    error << "max_iterations must be >= 1, got " << params.max_iterations;
  else if (!(params.probability > 0.0 && params.probability < 1.0))
    error << "probability must be in (0, 1), got " << params.probability;
  else if (params.min_inliers < 3)
    error << "min_inliers must be >= 3, got " << params.min_inliers;
  if (!error.str().empty())
    throw Exception("StereoOdometry: " + error.str());
}

StereoOdometry::StereoOdometry() : StereoOdometry(Params()) {}

void
StereoOdometry::setCalibration(const StereoCalibration& calibration)
{
  calibration.validate("StereoOdometry::setCalibration");
  calibration_ = calibration;
  has_calibration_ = true;
}

namespace {

/** \brief True when the two frames' descriptors can be compared (same type and
 * length); otherwise warns, naming \a caller. Empty descriptors are not comparable
 * and not warned about. */
bool
comparableDescriptors(const cv::Mat& previous,
                      const cv::Mat& current,
                      const char* caller)
{
  if (previous.empty() || current.empty())
    return false;
  if (previous.type() == current.type() && previous.cols == current.cols)
    return true;
  PCL_WARN("[planar_grid::StereoOdometry::%s] The two frames' descriptors differ in "
           "type or length; no matches.\n",
           caller);
  return false;
}

/** \brief Lowe's ratio test and the distance bound on a previous feature's best match:
 * \a best and \a second are its best and second-best descriptor distances, \a second
 * infinite when it has a single candidate (which passes the ratio test). */
bool
passesRatioAndDistance(float best, float second, const StereoOdometry::Params& params)
{
  if (std::isfinite(second) && !(best < params.ratio * second))
    return false;
  return !(params.max_descriptor_distance > 0.0
           && best > params.max_descriptor_distance);
}

} // namespace

void
StereoOdometry::matchDescriptors(const StereoFeatures& previous,
                                 const StereoFeatures& current,
                                 std::vector<cv::DMatch>& matches) const
{
  matches.clear();
  if (!comparableDescriptors(previous.descriptors, current.descriptors,
                             "matchDescriptors"))
    return;
  const int norm =
    previous.descriptors.depth() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(previous.descriptors, current.descriptors, knn, 2);
  std::vector<cv::DMatch> reverse;
  if (params_.mutual_check)
    matcher.match(current.descriptors, previous.descriptors, reverse);

  for (const auto& candidates : knn) {
    if (candidates.empty())
      continue;
    const cv::DMatch& best = candidates[0];
    // A single candidate (the other frame has one feature) passes the ratio test.
    const float second = candidates.size() > 1 ? candidates[1].distance
                                               : std::numeric_limits<float>::infinity();
    if (!passesRatioAndDistance(best.distance, second, params_))
      continue;
    if (params_.mutual_check
        && (best.trainIdx >= static_cast<int>(reverse.size())
            || reverse[static_cast<std::size_t>(best.trainIdx)].trainIdx
                 != best.queryIdx))
      continue;
    matches.push_back(best);
  }
}

void
StereoOdometry::matchDescriptorsProjected(const StereoFeatures& previous,
                                          const StereoFeatures& current,
                                          const Eigen::Isometry3d& current_T_previous,
                                          const StereoCalibration& calibration,
                                          double search_radius_px,
                                          std::vector<cv::DMatch>& matches) const
{
  matches.clear();
  const cv::Mat& query = previous.descriptors;
  const cv::Mat& train = current.descriptors;
  if (!comparableDescriptors(query, train, "matchDescriptorsProjected"))
    return;
  if (!(search_radius_px > 0.0) || !(calibration.focal_length_px > 0.0))
    return;
  const std::size_t n_query =
    std::min(static_cast<std::size_t>(query.rows), previous.points.size());
  const std::size_t n_train =
    std::min(static_cast<std::size_t>(train.rows), current.keypoints_left.size());
  const bool hamming = query.depth() == CV_8U;
  const auto distance = [&](std::size_t i, std::size_t j) {
    if (hamming)
      return static_cast<float>(
        cv::hal::normHamming(query.ptr<uchar>(static_cast<int>(i)),
                             train.ptr<uchar>(static_cast<int>(j)), query.cols));
    return std::sqrt(cv::normL2Sqr<float, float>(query.ptr<float>(static_cast<int>(i)),
                                                 train.ptr<float>(static_cast<int>(j)),
                                                 query.cols));
  };

  // The current key points in square cells of edge search_radius_px (a counting sort,
  // so that each cell lists its features in ascending order): the features within the
  // radius of a projection are in the 3 x 3 cells around it.
  const double cell = search_radius_px;
  float max_u = 0.0f, max_v = 0.0f;
  for (std::size_t j = 0; j < n_train; ++j) {
    max_u = std::max(max_u, current.keypoints_left[j].pt.x);
    max_v = std::max(max_v, current.keypoints_left[j].pt.y);
  }
  const auto cellOf = [cell](double value) {
    return static_cast<long>(std::floor(value / cell));
  };
  const long cols = cellOf(std::max(0.0f, max_u)) + 1;
  const long rows = cellOf(std::max(0.0f, max_v)) + 1;
  std::vector<std::uint32_t> start(static_cast<std::size_t>(cols * rows) + 1, 0);
  std::vector<std::uint32_t> cell_of(n_train);
  for (std::size_t j = 0; j < n_train; ++j) {
    const cv::Point2f& pt = current.keypoints_left[j].pt;
    const long c = std::min(cols - 1, std::max(0L, cellOf(pt.x)));
    const long r = std::min(rows - 1, std::max(0L, cellOf(pt.y)));
    cell_of[j] = static_cast<std::uint32_t>(r * cols + c);
    ++start[cell_of[j] + 1];
  }
  for (std::size_t k = 1; k < start.size(); ++k)
    start[k] += start[k - 1];
  std::vector<std::uint32_t> sorted(n_train);
  {
    std::vector<std::uint32_t> next(start.begin(), start.end() - 1);
    for (std::size_t j = 0; j < n_train; ++j)
      sorted[next[cell_of[j]]++] = static_cast<std::uint32_t>(j);
  }

  // One pass over the (previous, current) pairs within the radius: each previous
  // feature's best and second-best candidate, and each current feature's best
  // previous feature (ties go to the lower index, as in a brute-force search).
  constexpr float NONE = std::numeric_limits<float>::max();
  std::vector<float> reverse_distance(n_train, NONE);
  std::vector<std::uint32_t> reverse_best(n_train, 0);
  struct Candidate {
    float best{NONE};
    float second{NONE};
    std::uint32_t train{0};
  };
  std::vector<Candidate> forward(n_query);
  const double radius_sq = search_radius_px * search_radius_px;
  const double f = calibration.focal_length_px;
  for (std::size_t i = 0; i < n_query; ++i) {
    const pcl::PointXYZ& p = previous.points[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d x = current_T_previous * Eigen::Vector3d(p.x, p.y, p.z);
    if (!(x.z() > 0.0))
      continue; // behind the current camera
    const double u = f * x.x() / x.z() + calibration.cx_px;
    const double v = f * x.y() / x.z() + calibration.cy_px;
    const long c0 = std::max(0L, cellOf(u - search_radius_px));
    const long c1 = std::min(cols - 1, cellOf(u + search_radius_px));
    const long r0 = std::max(0L, cellOf(v - search_radius_px));
    const long r1 = std::min(rows - 1, cellOf(v + search_radius_px));
    Candidate& candidate = forward[i];
    for (long r = r0; r <= r1; ++r)
      for (long c = c0; c <= c1; ++c) {
        const auto k = static_cast<std::size_t>(r * cols + c);
        for (std::uint32_t s = start[k]; s < start[k + 1]; ++s) {
          const std::uint32_t j = sorted[s];
          const cv::Point2f& pt = current.keypoints_left[j].pt;
          const double du = pt.x - u, dv = pt.y - v;
          if (du * du + dv * dv > radius_sq)
            continue;
          const float d = distance(i, j);
          if (d < candidate.best || (d == candidate.best && j < candidate.train)) {
            candidate.second = candidate.best;
            candidate.best = d;
            candidate.train = j;
          } else if (d < candidate.second) {
            candidate.second = d;
          }
          if (d < reverse_distance[j]) {
            reverse_distance[j] = d;
            reverse_best[j] = static_cast<std::uint32_t>(i);
          }
        }
      }
  }

  for (std::size_t i = 0; i < n_query; ++i) {
    const Candidate& candidate = forward[i];
    if (candidate.best == NONE)
      continue;
    // A single candidate passes the ratio test, as in matchDescriptors().
    const float second = candidate.second == NONE
                           ? std::numeric_limits<float>::infinity()
                           : candidate.second;
    if (!passesRatioAndDistance(candidate.best, second, params_))
      continue;
    if (params_.mutual_check && reverse_best[candidate.train] != i)
      continue;
    matches.emplace_back(static_cast<int>(i), static_cast<int>(candidate.train),
                         candidate.best);
  }
}

OdometryResult
StereoOdometry::estimate(const StereoFeatures& previous,
                         const StereoFeatures& current) const
{
  const double sigma = params_.disparity_offset_sigma_px;
  return estimate(previous, current, params_.disparity_offset_px,
                  1.0 / (sigma * sigma));
}

OdometryResult
StereoOdometry::estimate(const StereoFeatures& previous,
                         const StereoFeatures& current,
                         double disparity_offset_px,
                         double disparity_offset_information) const
{
  std::vector<cv::DMatch> matches;
  matchDescriptors(previous, current, matches);

  // Source: current points; target: previous points. The registration model estimates
  // target = T * source, which is previous_T_current (eq. 8).
  auto source = std::make_shared<Cloud>();
  auto target = std::make_shared<Cloud>();
  std::vector<StereoKeypoints> keypoints;
  source->reserve(matches.size());
  target->reserve(matches.size());
  for (const auto& match : matches) {
    const auto query = static_cast<std::size_t>(match.queryIdx);
    const auto train = static_cast<std::size_t>(match.trainIdx);
    if (query >= previous.points.size() || train >= current.points.size())
      continue;
    const pcl::PointXYZ& p = previous.points[query];
    const pcl::PointXYZ& c = current.points[train];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)
        || !std::isfinite(c.x) || !std::isfinite(c.y) || !std::isfinite(c.z))
      continue;
    target->push_back(p);
    source->push_back(c);
    if (query < previous.keypoints_left.size()
        && query < previous.keypoints_right.size()
        && train < current.keypoints_left.size()
        && train < current.keypoints_right.size())
      keypoints.push_back(
        {&previous.keypoints_left[query], &previous.keypoints_right[query],
         &current.keypoints_left[train], &current.keypoints_right[train]});
  }
  const std::size_t correspondences = source->size();
  const bool use_keypoints = has_calibration_ && keypoints.size() == correspondences;
  // With a disparity offset the 3D points of the RANSAC are triangulated again from
  // their key points with it.
  if (use_keypoints && disparity_offset_px != 0.0) {
    for (std::size_t i = 0; i < correspondences; ++i) {
      Eigen::Vector3d p, c;
      if (triangulate(*keypoints[i][0], *keypoints[i][1], calibration_,
                      disparity_offset_px, p)
          && triangulate(*keypoints[i][2], *keypoints[i][3], calibration_,
                         disparity_offset_px, c)) {
        (*target)[i].getVector3fMap() = p.cast<float>();
        (*source)[i].getVector3fMap() = c.cast<float>();
      }
    }
  }

  if (correspondences < 3)
    return invalidResult(correspondences, 0,
                         "Only " + std::to_string(correspondences)
                           + " correspondences; a rigid motion needs at least 3.");
  if (isColinear(*source) || isColinear(*target))
    return invalidResult(correspondences, 0,
                         "The " + std::to_string(correspondences)
                           + " matched points lie on one line; the motion is not "
                             "observable.");

  // Per-correspondence threshold scale: the stereo depth error grows with z^2.
  std::vector<float> scales(correspondences, 1.0f);
  std::vector<float> weights(correspondences, 1.0f);
  if (params_.reference_depth_m > 0.0) {
    for (std::size_t i = 0; i < correspondences; ++i) {
      const double depth = std::max((*source)[i].z, (*target)[i].z);
      const double ratio = std::max(1.0, depth / params_.reference_depth_m);
      scales[i] = static_cast<float>(ratio * ratio);
      weights[i] = 1.0f / (scales[i] * scales[i]);
    }
  }
  auto model =
    std::make_shared<ScaledRegistrationModel>(source, target, scales, params_.seed);
  pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model, params_.distance_threshold_m);
  ransac.setMaxIterations(params_.max_iterations);
  ransac.setProbability(params_.probability);
  if (!ransac.computeModel())
    return invalidResult(correspondences, 0,
                         "RANSAC found no motion among "
                           + std::to_string(correspondences) + " correspondences.");
  pcl::Indices inliers;
  ransac.getInliers(inliers);

  // Refine on the inliers (least squares, SVD), re-select the inliers of the refined
  // motion and refine once more.
  pcl::registration::TransformationEstimationSVD<pcl::PointXYZ, pcl::PointXYZ, double>
    svd;
  Eigen::Matrix4d transform = Eigen::Matrix4d::Identity();
  for (int pass = 0; pass < 2 && inliers.size() >= 3; ++pass) {
    if (params_.reference_depth_m > 0.0)
      transform = weightedRigidTransform(*source, *target, inliers, weights);
    else
      svd.estimateRigidTransformation(*source, inliers, *target, inliers, transform);
    pcl::Indices refined;
    model->selectWithinDistance(toCoefficients(transform), params_.distance_threshold_m,
                                refined);
    if (refined.size() < 3)
      break;
    inliers.swap(refined);
  }

  bool epipolar_refined = false;
  // The disparity offset's prior, and its estimate once refined.
  const OffsetEstimate prior{disparity_offset_px, disparity_offset_information};
  OffsetEstimate offset = prior;
  const bool estimate_offset = params_.estimate_disparity_offset;
  if (has_calibration_ && inliers.size() >= 3) {
    if (!use_keypoints) {
      PCL_WARN("[planar_grid::StereoOdometry::estimate] Key points missing; the "
               "reprojection refinement is skipped.\n");
    } else {
      // The correspondences whose largest stereo reprojection error under a motion is
      // below reprojection_threshold_px.
      const auto select_inliers = [&](const Eigen::Isometry3d& motion,
                                      double offset_px) {
        pcl::Indices selected;
        for (std::size_t i = 0; i < correspondences; ++i) {
          Eigen::Matrix<double, 8, 1> residuals;
          if (reprojectionResiduals(motion, calibration_, offset_px, keypoints[i],
                                    residuals)
              && residuals.cwiseAbs().maxCoeff() < params_.reprojection_threshold_px)
            selected.push_back(static_cast<pcl::index_t>(i));
        }
        return selected;
      };
      Eigen::Isometry3d motion(transform);
      for (int round = 0; round < 2; ++round) {
        motion = refineReprojection(motion, calibration_, keypoints, inliers, false,
                                    estimate_offset, prior, offset);
        pcl::Indices selected = select_inliers(motion, offset.offset_px);
        if (selected.size() < 3)
          break;
        inliers.swap(selected);
      }

      // Rotation from the epipolar geometry of the left images, translation (and the
      // disparity offset) from the stereo reprojection with that rotation.
      if (params_.epipolar_refinement && inliers.size() >= 5
          && motion.translation().norm() >= params_.epipolar_min_translation_m) {
        Eigen::Matrix3d rotation = motion.linear();
        Eigen::Vector3d direction = motion.translation().normalized();
        refineEpipolar(rotation, direction, calibration_, keypoints, inliers,
                       params_.epipolar_threshold_px);
        const double rotation_change =
          Eigen::AngleAxisd(rotation * motion.linear().transpose()).angle();
        const double direction_cosine =
          direction.dot(motion.translation().normalized());
        if (rotation.allFinite() && direction.allFinite()
            && rotation_change <= params_.epipolar_max_rotation_change_rad
            && direction_cosine >= std::cos(15.0 * M_PI / 180.0)) {
          Eigen::Isometry3d epipolar = motion;
          epipolar.linear() = rotation;
          OffsetEstimate epipolar_offset = offset;
          epipolar = refineReprojection(epipolar, calibration_, keypoints, inliers,
                                        true, estimate_offset, prior, epipolar_offset);
          pcl::Indices selected = select_inliers(epipolar, epipolar_offset.offset_px);
          if (selected.size() >= 3) {
            motion = epipolar;
            offset = epipolar_offset;
            inliers.swap(selected);
            epipolar_refined = true;
          }
        }
      }
      transform = motion.matrix();
    }
  }

  if (inliers.size() < static_cast<std::size_t>(params_.min_inliers))
    return invalidResult(correspondences, inliers.size(),
                         "Only " + std::to_string(inliers.size()) + " of "
                           + std::to_string(correspondences)
                           + " correspondences are inliers; min_inliers is "
                           + std::to_string(params_.min_inliers) + ".");
  Cloud inlier_cloud(*source, inliers);
  if (isColinear(inlier_cloud))
    return invalidResult(correspondences, inliers.size(),
                         "The " + std::to_string(inliers.size())
                           + " inliers lie on one line; the motion is not observable.");

  OdometryResult result;
  result.previous_T_current.matrix() = transform;
  // Re-orthonormalise the rotation (SVD gives it to double precision already).
  result.previous_T_current.linear() =
    Eigen::Quaterniond(transform.topLeftCorner<3, 3>()).normalized().toRotationMatrix();
  result.correspondences = correspondences;
  result.inliers = inliers.size();
  result.epipolar_refined = epipolar_refined;
  result.disparity_offset_px = offset.offset_px;
  result.disparity_offset_information = offset.information;
  result.valid = true;
  return result;
}

} // namespace planar_grid
