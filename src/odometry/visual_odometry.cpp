// SPDX-License-Identifier: BSD-3-Clause
// The frame sequence around StereoOdometry: the constant-velocity motion model that
// stands in for a failed estimate, the trajectory and the disparity offset carried from
// one frame pair to the next (VisualOdometry), and its checkpoint state. The motion of
// one frame pair is estimated in stereo_odometry.cpp.
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {

ConstantVelocityMotionModel::ConstantVelocityMotionModel(const Params& params) :
    params_(params)
{
  namespace ranges = constant_velocity_motion_model_ranges;
  if (!ranges::SIGMA_TRANSLATION.contains(params.sigma_translation_m))
    throw Exception(
      "ConstantVelocityMotionModel: "
      + paramRangeMessage("sigma_translation_m", ranges::SIGMA_TRANSLATION, "m"));
  if (!ranges::SIGMA_ROTATION.contains(params.sigma_rotation_rad))
    throw Exception(
      "ConstantVelocityMotionModel: "
      + paramRangeMessage("sigma_rotation_rad", ranges::SIGMA_ROTATION, "rad"));
}

ConstantVelocityMotionModel::ConstantVelocityMotionModel() :
    ConstantVelocityMotionModel(Params())
{}

void
ConstantVelocityMotionModel::addMotion(const Eigen::Isometry3d& previous_T_current)
{
  last_motion_ = previous_T_current;
  has_motion_ = true;
}

void
ConstantVelocityMotionModel::reset()
{
  last_motion_ = Eigen::Isometry3d::Identity();
  has_motion_ = false;
}

Eigen::Isometry3d
ConstantVelocityMotionModel::predict(const Eigen::Isometry3d& world_T_current) const
{
  return world_T_current * last_motion_;
}

Eigen::Matrix<double, 6, 6>
ConstantVelocityMotionModel::getCovariance() const
{
  Eigen::Matrix<double, 6, 1> diagonal;
  const double t2 = params_.sigma_translation_m * params_.sigma_translation_m;
  const double r2 = params_.sigma_rotation_rad * params_.sigma_rotation_rad;
  diagonal << t2, t2, t2, r2, r2, r2;
  return diagonal.asDiagonal();
}

double
ConstantVelocityMotionModel::mahalanobisSquared(
  const Eigen::Isometry3d& measured_motion) const
{
  const Eigen::Isometry3d error = last_motion_.inverse() * measured_motion;
  const Eigen::AngleAxisd rotation(error.linear());
  const Eigen::Vector3d rotation_vector = rotation.angle() * rotation.axis();
  return error.translation().squaredNorm()
           / (params_.sigma_translation_m * params_.sigma_translation_m)
         + rotation_vector.squaredNorm()
             / (params_.sigma_rotation_rad * params_.sigma_rotation_rad);
}

double
ConstantVelocityMotionModel::motionLikelihood(
  const Eigen::Isometry3d& measured_motion) const
{
  return std::exp(-0.5 * mahalanobisSquared(measured_motion));
}

VisualOdometry::VisualOdometry(
  const StereoOdometry::Params& odometry_params,
  const ConstantVelocityMotionModel::Params& motion_params) :
    odometry_(odometry_params),
    motion_model_(motion_params),
    disparity_offset_px_(odometry_params.disparity_offset_px),
    disparity_offset_information_(1.0
                                  / (odometry_params.disparity_offset_sigma_px
                                     * odometry_params.disparity_offset_sigma_px))
{}

VisualOdometry::VisualOdometry() :
    VisualOdometry(StereoOdometry::Params(), ConstantVelocityMotionModel::Params())
{}

const OdometryResult&
VisualOdometry::addFrame(const StereoFeatures& features)
{
  if (trajectory_.empty()) {
    OdometryResult first;
    first.valid = true;
    trajectory_.push_back(Eigen::Isometry3d::Identity());
    results_.push_back(first);
  } else {
    OdometryResult result = odometry_.estimate(
      previous_, features, disparity_offset_px_, disparity_offset_information_);
    Eigen::Isometry3d motion = result.previous_T_current;
    if (result.valid) {
      motion_model_.addMotion(motion);
      // The posterior of the disparity offset is the next pair's prior.
      if (std::isfinite(result.disparity_offset_px)
          && std::isfinite(result.disparity_offset_information)) {
        const double sigma = odometry_.getParams().disparity_offset_sigma_px;
        disparity_offset_px_ = result.disparity_offset_px;
        disparity_offset_information_ =
          std::max(odometry_.getParams().disparity_offset_memory
                     * result.disparity_offset_information,
                   1.0 / (sigma * sigma));
      }
    } else {
      result.disparity_offset_px = disparity_offset_px_;
      result.disparity_offset_information = disparity_offset_information_;
      motion = motion_model_.getPredictedMotion();
      flagged_frames_.push_back(trajectory_.size());
      PCL_WARN("[planar_grid::VisualOdometry::addFrame] Frame %zu: %s The "
               "constant-velocity prediction takes its place.\n",
               trajectory_.size(), result.reason.c_str());
    }
    trajectory_.push_back(trajectory_.back() * motion);
    results_.push_back(result);
  }
  previous_ = features;
  return results_.back();
}

namespace {

/** "PGVO", little-endian. */
constexpr std::uint32_t VO_STATE_MAGIC = 0x4f564750u;
constexpr std::uint32_t VO_STATE_VERSION = 2u;

} // namespace

void
VisualOdometry::serializeState(std::vector<std::uint8_t>& bytes) const
{
  ByteWriter w(bytes);
  w.put(VO_STATE_MAGIC);
  w.put(VO_STATE_VERSION);
  putStereoFeatures(w, previous_);
  w.put(static_cast<std::uint64_t>(trajectory_.size()));
  for (std::size_t i = 0; i < trajectory_.size(); ++i) {
    const OdometryResult& result = results_[i];
    putPose(w, trajectory_[i]);
    putPose(w, result.previous_T_current);
    w.put(static_cast<std::uint64_t>(result.inliers));
    w.put(static_cast<std::uint64_t>(result.correspondences));
    w.put(static_cast<std::uint8_t>(result.epipolar_refined));
    w.put(static_cast<std::uint8_t>(result.valid));
    w.put(result.disparity_offset_px);
    w.put(result.disparity_offset_information);
    w.putString(result.reason);
  }
  const std::vector<std::uint64_t> flagged(flagged_frames_.begin(),
                                           flagged_frames_.end());
  w.putVector(flagged);
  w.put(static_cast<std::uint8_t>(motion_model_.hasMotion()));
  putPose(w, motion_model_.getPredictedMotion());
  w.put(disparity_offset_px_);
  w.put(disparity_offset_information_);
}

void
VisualOdometry::deserializeState(const std::uint8_t* data, std::size_t size)
{
  ByteReader r(data, size, "visual odometry state");
  if (r.get<std::uint32_t>() != VO_STATE_MAGIC)
    r.fail("not a visual odometry section (magic)");
  if (r.get<std::uint32_t>() != VO_STATE_VERSION)
    r.fail("unsupported version");
  StereoFeatures previous;
  getStereoFeatures(r, previous);
  // Each frame holds at least two poses, two counts, two flags, the disparity offset
  // and its information and a reason length.
  constexpr std::size_t FRAME_BYTES = 2 * 12 * 8 + 2 * 8 + 2 + 2 * 8 + 8;
  const std::size_t n = r.getCount(FRAME_BYTES, "frame");
  Trajectory trajectory;
  std::vector<OdometryResult, Eigen::aligned_allocator<OdometryResult>> results;
  trajectory.reserve(n);
  results.reserve(n);
  for (std::size_t i = 0; i < n; ++i) {
    trajectory.push_back(getPose(r));
    OdometryResult result;
    result.previous_T_current = getPose(r);
    result.inliers = static_cast<std::size_t>(r.get<std::uint64_t>());
    result.correspondences = static_cast<std::size_t>(r.get<std::uint64_t>());
    result.epipolar_refined = r.get<std::uint8_t>() != 0;
    result.valid = r.get<std::uint8_t>() != 0;
    result.disparity_offset_px = r.get<double>();
    result.disparity_offset_information = r.get<double>();
    if (!std::isfinite(result.disparity_offset_px)
        || !(result.disparity_offset_information >= 0.0)
        || !std::isfinite(result.disparity_offset_information))
      r.fail("frame " + std::to_string(i) + ": invalid disparity offset");
    result.reason = r.getString("reason");
    results.push_back(std::move(result));
  }
  std::vector<std::uint64_t> flagged;
  r.getVector(flagged, "flagged frame");
  for (std::size_t k = 0; k < flagged.size(); ++k)
    if (flagged[k] == 0 || flagged[k] >= n || (k > 0 && flagged[k] <= flagged[k - 1]))
      r.fail("flagged frame " + std::to_string(flagged[k]) + " out of range or order");
  const bool has_motion = r.get<std::uint8_t>() != 0;
  const Eigen::Isometry3d motion = getPose(r);
  const double disparity_offset_px = r.get<double>();
  const double disparity_offset_information = r.get<double>();
  if (!std::isfinite(disparity_offset_px) || !(disparity_offset_information >= 0.0)
      || !std::isfinite(disparity_offset_information))
    r.fail("invalid disparity offset");
  if (r.remaining() != 0)
    r.fail(std::to_string(r.remaining()) + " bytes of trailing data");

  // Everything is read and checked; only now is the object changed.
  previous_ = std::move(previous);
  trajectory_ = std::move(trajectory);
  results_ = std::move(results);
  flagged_frames_.assign(flagged.begin(), flagged.end());
  motion_model_.reset();
  if (has_motion)
    motion_model_.addMotion(motion);
  disparity_offset_px_ = disparity_offset_px;
  disparity_offset_information_ = disparity_offset_information;
}

} // namespace planar_grid
