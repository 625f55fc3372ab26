// SPDX-License-Identifier: BSD-3-Clause
// The motion of one stereo frame pair (paper eq. 8): RANSAC over the 3D
// correspondences, least-squares, and the disparity offset. The descriptor matching is
// in stereo_odometry_matching.cpp, the reprojection and epipolar refinement in
// stereo_odometry_refinement.cpp; the frame sequence around it (motion model,
// trajectory, checkpoint state) is in visual_odometry.cpp.
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

#include "stereo_odometry_impl.h"

namespace planar_grid {

namespace {

using detail::OffsetEstimate;
using detail::refineEpipolar;
using detail::refineReprojection;
using detail::reprojectionResiduals;
using detail::StereoKeypoints;
using detail::triangulate;

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

/** \brief Matched points of two frames: source the current frame's, target the
 * previous frame's (the registration model estimates target = T * source, which is
 * previous_T_current, eq. 8), and their key points when both frames have them. */
struct Correspondences {
  std::shared_ptr<Cloud> source{std::make_shared<Cloud>()};
  std::shared_ptr<Cloud> target{std::make_shared<Cloud>()};
  /** \brief Previous left, previous right, current left, current right. */
  std::vector<StereoKeypoints> keypoints;
};

/** \brief The finite 3D points of \a matches (query: previous, train: current). */
Correspondences
correspondencesOf(const StereoFeatures& previous,
                  const StereoFeatures& current,
                  const std::vector<cv::DMatch>& matches)
{
  Correspondences corr;
  corr.source->reserve(matches.size());
  corr.target->reserve(matches.size());
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
    corr.target->push_back(p);
    corr.source->push_back(c);
    if (query < previous.keypoints_left.size()
        && query < previous.keypoints_right.size()
        && train < current.keypoints_left.size()
        && train < current.keypoints_right.size())
      corr.keypoints.push_back(
        {&previous.keypoints_left[query], &previous.keypoints_right[query],
         &current.keypoints_left[train], &current.keypoints_right[train]});
  }
  return corr;
}

/** \brief RANSAC on the correspondences (thresholds scaled with the depth error),
 * then least squares on the inliers, the inliers of the refined motion re-selected and
 * refined once more. False when RANSAC finds no motion. */
bool
ransacMotion(const Correspondences& corr,
             const StereoOdometry::Params& params,
             Eigen::Matrix4d& transform,
             pcl::Indices& inliers)
{
  const Cloud& source = *corr.source;
  const Cloud& target = *corr.target;
  const std::size_t correspondences = source.size();
  // Per-correspondence threshold scale: the stereo depth error grows with z^2.
  std::vector<float> scales(correspondences, 1.0f);
  std::vector<float> weights(correspondences, 1.0f);
  if (params.reference_depth_m > 0.0) {
    for (std::size_t i = 0; i < correspondences; ++i) {
      const double depth = std::max(source[i].z, target[i].z);
      const double ratio = std::max(1.0, depth / params.reference_depth_m);
      scales[i] = static_cast<float>(ratio * ratio);
      weights[i] = 1.0f / (scales[i] * scales[i]);
    }
  }
  auto model = std::make_shared<ScaledRegistrationModel>(corr.source, corr.target,
                                                         scales, params.seed);
  pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model, params.distance_threshold_m);
  ransac.setMaxIterations(params.max_iterations);
  ransac.setProbability(params.probability);
  if (!ransac.computeModel())
    return false;
  ransac.getInliers(inliers);
  pcl::registration::TransformationEstimationSVD<pcl::PointXYZ, pcl::PointXYZ, double>
    svd;
  transform = Eigen::Matrix4d::Identity();
  for (int pass = 0; pass < 2 && inliers.size() >= 3; ++pass) {
    if (params.reference_depth_m > 0.0)
      transform = weightedRigidTransform(source, target, inliers, weights);
    else
      svd.estimateRigidTransformation(source, inliers, target, inliers, transform);
    pcl::Indices refined;
    model->selectWithinDistance(toCoefficients(transform), params.distance_threshold_m,
                                refined);
    if (refined.size() < 3)
      break;
    inliers.swap(refined);
  }
  return true;
}

/** \brief The refinement of a RANSAC motion on the key points: the stereo
 * reprojection error (twice, re-selecting the inliers), then the rotation from the
 * left images' epipolar geometry with the translation (and the disparity offset) from
 * the stereo reprojection, kept when it stays close to the first. */
class ReprojectionRefinement {
public:
  ReprojectionRefinement(const StereoOdometry::Params& params,
                         const StereoCalibration& calibration,
                         const std::vector<StereoKeypoints>& keypoints,
                         const OffsetEstimate& prior) :
      params_(params),
      calibration_(calibration), keypoints_(keypoints), prior_(prior)
  {}

  /** \brief Refines \a motion, \a inliers and \a offset in place; returns whether the
   * epipolar refinement was kept. */
  bool
  refine(Eigen::Isometry3d& motion, pcl::Indices& inliers, OffsetEstimate& offset) const
  {
    const bool estimate_offset = params_.estimate_disparity_offset;
    for (int round = 0; round < 2; ++round) {
      motion = refineReprojection(motion, calibration_, keypoints_, inliers, false,
                                  estimate_offset, prior_, offset);
      pcl::Indices selected = selectInliers(motion, offset.offset_px);
      if (selected.size() < 3)
        break;
      inliers.swap(selected);
    }
    if (!params_.epipolar_refinement || inliers.size() < 5
        || motion.translation().norm() < params_.epipolar_min_translation_m)
      return false;
    Eigen::Matrix3d rotation = motion.linear();
    Eigen::Vector3d direction = motion.translation().normalized();
    refineEpipolar(rotation, direction, calibration_, keypoints_, inliers,
                   params_.epipolar_threshold_px);
    const double rotation_change =
      Eigen::AngleAxisd(rotation * motion.linear().transpose()).angle();
    const double direction_cosine = direction.dot(motion.translation().normalized());
    if (!rotation.allFinite() || !direction.allFinite()
        || rotation_change > params_.epipolar_max_rotation_change_rad
        || direction_cosine < std::cos(15.0 * M_PI / 180.0))
      return false;
    Eigen::Isometry3d epipolar = motion;
    epipolar.linear() = rotation;
    OffsetEstimate epipolar_offset = offset;
    epipolar = refineReprojection(epipolar, calibration_, keypoints_, inliers, true,
                                  estimate_offset, prior_, epipolar_offset);
    pcl::Indices selected = selectInliers(epipolar, epipolar_offset.offset_px);
    if (selected.size() < 3)
      return false;
    motion = epipolar;
    offset = epipolar_offset;
    inliers.swap(selected);
    return true;
  }

private:
  /** \brief The correspondences whose largest stereo reprojection error under
   * \a motion is below reprojection_threshold_px. */
  pcl::Indices selectInliers(const Eigen::Isometry3d& motion, double offset_px) const
  {
    pcl::Indices selected;
    for (std::size_t i = 0; i < keypoints_.size(); ++i) {
      Eigen::Matrix<double, 8, 1> residuals;
      if (reprojectionResiduals(motion, calibration_, offset_px, keypoints_[i],
                                residuals)
          && residuals.cwiseAbs().maxCoeff() < params_.reprojection_threshold_px)
        selected.push_back(static_cast<pcl::index_t>(i));
    }
    return selected;
  }

  const StereoOdometry::Params& params_;
  const StereoCalibration& calibration_;
  const std::vector<StereoKeypoints>& keypoints_;
  const OffsetEstimate prior_;
};

} // namespace

StereoOdometry::StereoOdometry(const Params& params) : params_(params)
{
  namespace ranges = stereo_odometry_ranges;
  // The first value outside its declared range is reported.
  std::string error;
  const auto check = [&error](const char* name, double value, const ParamRange& range,
                              const char* unit) {
    if (error.empty() && !range.contains(value))
      error =
        paramRangeMessage(name, range, unit) + ", got " + formatParamNumber(value);
  };
  check("ratio", params.ratio, ranges::RATIO, "");
  check("max_descriptor_distance", params.max_descriptor_distance,
        ranges::MAX_DESCRIPTOR_DISTANCE, "");
  check("distance_threshold_m", params.distance_threshold_m, ranges::DISTANCE_THRESHOLD,
        "m");
  check("reference_depth_m", params.reference_depth_m, ranges::REFERENCE_DEPTH, "m");
  check("reprojection_threshold_px", params.reprojection_threshold_px,
        ranges::REPROJECTION_THRESHOLD, "px");
  check("epipolar_threshold_px", params.epipolar_threshold_px,
        ranges::EPIPOLAR_THRESHOLD, "px");
  check("epipolar_max_rotation_change_rad", params.epipolar_max_rotation_change_rad,
        ranges::EPIPOLAR_MAX_ROTATION_CHANGE, "rad");
  check("epipolar_min_translation_m", params.epipolar_min_translation_m,
        ranges::EPIPOLAR_MIN_TRANSLATION, "m");
  check("disparity_offset_px", params.disparity_offset_px, ranges::DISPARITY_OFFSET,
        "px");
  check("disparity_offset_sigma_px", params.disparity_offset_sigma_px,
        ranges::DISPARITY_OFFSET_SIGMA, "px");
  check("disparity_offset_memory", params.disparity_offset_memory,
        ranges::DISPARITY_OFFSET_MEMORY, "");
  check("max_iterations", params.max_iterations, ranges::MAX_ITERATIONS, "");
  check("probability", params.probability, ranges::PROBABILITY, "");
  check("min_inliers", params.min_inliers, ranges::MIN_INLIERS, "");
  if (!error.empty())
    throw Exception("StereoOdometry: " + error);
}

StereoOdometry::StereoOdometry() : StereoOdometry(Params()) {}

void
StereoOdometry::setCalibration(const StereoCalibration& calibration)
{
  calibration.validate("StereoOdometry::setCalibration");
  calibration_ = calibration;
  has_calibration_ = true;
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
  Correspondences corr = correspondencesOf(previous, current, matches);
  Cloud& source = *corr.source;
  Cloud& target = *corr.target;
  const std::size_t correspondences = source.size();
  const bool use_keypoints =
    has_calibration_ && corr.keypoints.size() == correspondences;
  // With a disparity offset the 3D points of the RANSAC are triangulated again from
  // their key points with it.
  if (use_keypoints && disparity_offset_px != 0.0) {
    for (std::size_t i = 0; i < correspondences; ++i) {
      const StereoKeypoints& k = corr.keypoints[i];
      Eigen::Vector3d p, c;
      if (triangulate(*k[0], *k[1], calibration_, disparity_offset_px, p)
          && triangulate(*k[2], *k[3], calibration_, disparity_offset_px, c)) {
        target[i].getVector3fMap() = p.cast<float>();
        source[i].getVector3fMap() = c.cast<float>();
      }
    }
  }

  if (correspondences < 3)
    return invalidResult(correspondences, 0,
                         "Only " + std::to_string(correspondences)
                           + " correspondences; a rigid motion needs at least 3.");
  if (isColinear(source) || isColinear(target))
    return invalidResult(correspondences, 0,
                         "The " + std::to_string(correspondences)
                           + " matched points lie on one line; the motion is not "
                             "observable.");
  Eigen::Matrix4d transform;
  pcl::Indices inliers;
  if (!ransacMotion(corr, params_, transform, inliers))
    return invalidResult(correspondences, 0,
                         "RANSAC found no motion among "
                           + std::to_string(correspondences) + " correspondences.");

  bool epipolar_refined = false;
  // The disparity offset's prior, and its estimate once refined.
  const OffsetEstimate prior{disparity_offset_px, disparity_offset_information};
  OffsetEstimate offset = prior;
  if (has_calibration_ && inliers.size() >= 3) {
    if (!use_keypoints) {
      PCL_WARN("[planar_grid::StereoOdometry::estimate] Key points missing; the "
               "reprojection refinement is skipped.\n");
    } else {
      Eigen::Isometry3d motion(transform);
      const ReprojectionRefinement refinement(params_, calibration_, corr.keypoints,
                                              prior);
      epipolar_refined = refinement.refine(motion, inliers, offset);
      transform = motion.matrix();
    }
  }

  if (inliers.size() < static_cast<std::size_t>(params_.min_inliers))
    return invalidResult(correspondences, inliers.size(),
                         "Only " + std::to_string(inliers.size()) + " of "
                           + std::to_string(correspondences)
                           + " correspondences are inliers; min_inliers is "
                           + std::to_string(params_.min_inliers) + ".");
  Cloud inlier_cloud(source, inliers);
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

const ParamDeclarations<StereoOdometry::Params>&
StereoOdometry::getParamDeclarations()
{
  using P = StereoOdometry::Params;
  namespace ranges = stereo_odometry_ranges;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "ratio", [](auto& p) -> auto& { return p.ratio; }, ranges::RATIO, "",
      "Lowe's ratio test."),
    declareReal<P>(
      "distance_threshold_m", [](auto& p) -> auto& { return p.distance_threshold_m; },
      ranges::DISTANCE_THRESHOLD, "m",
      "RANSAC inlier threshold between matched 3D features."),
    declareReal<P>(
      "reprojection_threshold_px",
      [](auto& p) -> auto& { return p.reprojection_threshold_px; },
      ranges::REPROJECTION_THRESHOLD, "px",
      "Inlier threshold of the reprojection refinement."),
    declareInteger<P>(
      "max_iterations", [](auto& p) -> auto& { return p.max_iterations; },
      ranges::MAX_ITERATIONS, "", "Most RANSAC iterations."),
    declareInteger<P>(
      "min_inliers", [](auto& p) -> auto& { return p.min_inliers; },
      ranges::MIN_INLIERS, "",
      "Fewest inliers for a valid motion; else the frame is flagged."),
    declareFlag<P>(
      "epipolar_refinement", [](auto& p) -> auto& { return p.epipolar_refinement; },
      "Then take the rotation from the epipolar geometry of the left images (free of "
      "disparity errors) and refit the translation; needs reprojection_refinement."),
    declareReal<P>(
      "epipolar_threshold_px", [](auto& p) -> auto& { return p.epipolar_threshold_px; },
      ranges::EPIPOLAR_THRESHOLD, "px", "Huber threshold of the Sampson distance."),
    declareInteger<P>(
      "seed", [](auto& p) -> auto& { return p.seed; },
      ParamRange::closed(0, 2147483647), "", "RANSAC seed (reproducible runs)."),
    declareFlag<P>(
      "estimate_disparity_offset",
      [](auto& p) -> auto& { return p.estimate_disparity_offset; },
      "Estimate the features' disparity offset (true = measured + offset) with the "
      "motion; needs reprojection_refinement."),
    declareReal<P>(
      "disparity_offset_px", [](auto& p) -> auto& { return p.disparity_offset_px; },
      ranges::DISPARITY_OFFSET, "px",
      "The offset's prior mean at the first frame pair, or the offset used when it is "
      "not estimated."),
    declareReal<P>(
      "disparity_offset_sigma_px",
      [](auto& p) -> auto& { return p.disparity_offset_sigma_px; },
      ranges::DISPARITY_OFFSET_SIGMA, "px",
      "Standard deviation of the offset's first prior."),
    declareReal<P>(
      "disparity_offset_memory",
      [](auto& p) -> auto& { return p.disparity_offset_memory; },
      ranges::DISPARITY_OFFSET_MEMORY, "",
      "Share of the offset's information carried to the next frame pair: 1 = one "
      "offset for the run, 0 = each pair on its own."),
  };
  return table;
}

} // namespace planar_grid
