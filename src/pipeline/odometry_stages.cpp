// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class VisualOdometryStage : public Stage {
public:
  VisualOdometryStage(const StereoOdometry::Params& params,
                      bool reprojection_refinement,
                      double initial_height_m,
                      double initial_pitch_rad) :
      odometry_(params, ConstantVelocityMotionModel::Params()),
      reprojection_refinement_(reprojection_refinement),
      initial_height_m_(initial_height_m), initial_pitch_rad_(initial_pitch_rad)
  {
    // The first camera, level along world +x at initial_height_m above the world origin
    // and pitched down by initial_pitch_rad: camera x right = -y, y down = -z, z
    // forward = +x (world z up), then the pitch about the camera's x axis.
    Eigen::Matrix3d level;
    level.col(0) = -Eigen::Vector3d::UnitY();
    level.col(1) = -Eigen::Vector3d::UnitZ();
    level.col(2) = Eigen::Vector3d::UnitX();
    world_T_first_.linear() =
      level * Eigen::AngleAxisd(-initial_pitch_rad, Eigen::Vector3d::UnitX()).matrix();
    world_T_first_.translation() = Eigen::Vector3d(0.0, 0.0, initial_height_m);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (frame.features.size() == 0 && odometry_.getTrajectory().empty())
      throw Exception(
        "stage 'visual_odometry' needs the 'feature_matching' stage before "
        "it (frame "
        + frame.name + " has no features)");
    if (reprojection_refinement_ && !calibration_set_) {
      odometry_.setCalibration(frame.calibration);
      calibration_set_ = true;
    }
    last_ = odometry_.addFrame(frame.features);
    frame.world_T_camera = world_T_first_ * odometry_.getTrajectory().back();
    frame.has_pose = true;
  }

  bool countsCloudPoints() const override { return false; }

  void getParameters(ParamValues& v) const override
  {
    const StereoOdometry::Params& p = odometry_.getStereoOdometry().getParams();
    v.set("ratio", p.ratio);
    v.set("distance_threshold_m", p.distance_threshold_m);
    v.set("reprojection_threshold_px", p.reprojection_threshold_px);
    v.set("max_iterations", p.max_iterations);
    v.set("min_inliers", p.min_inliers);
    v.set("reprojection_refinement", reprojection_refinement_);
    v.set("epipolar_refinement", p.epipolar_refinement);
    v.set("epipolar_threshold_px", p.epipolar_threshold_px);
    v.set("seed", static_cast<int>(p.seed));
    v.set("estimate_disparity_offset", p.estimate_disparity_offset);
    v.set("disparity_offset_px", p.disparity_offset_px);
    v.set("disparity_offset_sigma_px", p.disparity_offset_sigma_px);
    v.set("disparity_offset_memory", p.disparity_offset_memory);
    v.set("initial_height_m", initial_height_m_);
    v.set("initial_pitch_rad", initial_pitch_rad_);
  }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("correspondences", static_cast<double>(last_.correspondences));
    values.emplace_back("inliers", static_cast<double>(last_.inliers));
    // A frame whose motion was invalid takes the constant-velocity prediction (eq. 9).
    values.emplace_back("flagged", last_.valid ? 0.0 : 1.0);
  }

  /** The odometry's run state (VisualOdometry::serializeState(): the previous frame's
   * features, the trajectory, the per-frame results, the flagged frames and the motion
   * model). The last result (the counters) is the odometry's last one; the
   * calibration is set again from the next frame, and the first camera's pose follows
   * from the parameters. */
  void saveState(std::vector<std::uint8_t>& bytes) const override
  {
    odometry_.serializeState(bytes);
  }

  void loadState(const std::uint8_t* data, std::size_t size) override
  {
    odometry_.deserializeState(data, size);
    last_ =
      odometry_.getResults().empty() ? OdometryResult() : odometry_.getResults().back();
  }

private:
  VisualOdometry odometry_;
  bool reprojection_refinement_;
  double initial_height_m_;
  double initial_pitch_rad_;
  bool calibration_set_{false};
  Eigen::Isometry3d world_T_first_{Eigen::Isometry3d::Identity()};
  OdometryResult last_;
};

} // namespace

StageInfo
visualOdometryInfo()
{
  StageInfo info;
  info.type = "visual_odometry";
  info.description =
    "Frame-to-frame camera motion (paper eq. 8) from the matched 3D key features: "
    "descriptor matching (ratio + mutual check), RANSAC with PCL's registration model, "
    "SVD and stereo reprojection refinement, rotation from the left images' epipolar "
    "geometry; frames with too few inliers take the "
    "constant-velocity prediction (eq. 9) and are counted as flagged. Sets the poses "
    "when input.poses.format is odometry; the world frame has z up with its origin "
    "initial_height_m below the first camera.";
  info.needs_stereo = true;
  const StereoOdometry::Params d;
  namespace ranges = stereo_odometry_ranges;
  info.params = {
    ParamSpec::real("ratio", d.ratio, ranges::RATIO, "", "Lowe's ratio test."),
    ParamSpec::real("distance_threshold_m", d.distance_threshold_m,
                    ranges::DISTANCE_THRESHOLD, "m",
                    "RANSAC inlier threshold between matched 3D features."),
    ParamSpec::real("reprojection_threshold_px", d.reprojection_threshold_px,
                    ranges::REPROJECTION_THRESHOLD, "px",
                    "Inlier threshold of the reprojection refinement."),
    ParamSpec::integer("max_iterations", d.max_iterations, ranges::MAX_ITERATIONS, "",
                       "Most RANSAC iterations."),
    ParamSpec::integer("min_inliers", d.min_inliers, ranges::MIN_INLIERS, "",
                       "Fewest inliers for a valid motion; else the frame is flagged."),
    ParamSpec::flag("reprojection_refinement", true,
                    "Refine the motion on the stereo reprojection error."),
    ParamSpec::flag("epipolar_refinement", d.epipolar_refinement,
                    "Then take the rotation from the epipolar geometry of the left "
                    "images (free of disparity errors) and refit the translation; "
                    "needs reprojection_refinement."),
    ParamSpec::real("epipolar_threshold_px", d.epipolar_threshold_px,
                    ranges::EPIPOLAR_THRESHOLD, "px",
                    "Huber threshold of the Sampson distance."),
    ParamSpec::integer("seed", static_cast<int>(d.seed), 0, 2147483647, "",
                       "RANSAC seed (reproducible runs)."),
    ParamSpec::flag("estimate_disparity_offset", d.estimate_disparity_offset,
                    "Estimate the features' disparity offset (true = measured + "
                    "offset) with the motion; needs reprojection_refinement."),
    ParamSpec::real("disparity_offset_px", d.disparity_offset_px,
                    ranges::DISPARITY_OFFSET, "px",
                    "The offset's prior mean at the first frame pair, or the offset "
                    "used when it is not estimated."),
    ParamSpec::real("disparity_offset_sigma_px", d.disparity_offset_sigma_px,
                    ranges::DISPARITY_OFFSET_SIGMA, "px",
                    "Standard deviation of the offset's first prior."),
    ParamSpec::real("disparity_offset_memory", d.disparity_offset_memory,
                    ranges::DISPARITY_OFFSET_MEMORY, "",
                    "Share of the offset's information carried to the next frame "
                    "pair: 1 = one offset for the run, 0 = each pair on its own."),
    ParamSpec::real("initial_height_m", 0.0, 0.0, 10.0, "m",
                    "Height of the first camera above the world origin (the road)."),
    ParamSpec::real("initial_pitch_rad", 0.0, -1.5, 1.5, "rad",
                    "Downward pitch of the first camera from level (> 0 down)."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    StereoOdometry::Params p;
    p.ratio = v.getDouble("ratio");
    p.distance_threshold_m = v.getDouble("distance_threshold_m");
    p.reprojection_threshold_px = v.getDouble("reprojection_threshold_px");
    p.max_iterations = v.getInt("max_iterations");
    p.min_inliers = v.getInt("min_inliers");
    p.epipolar_refinement = v.getBool("epipolar_refinement");
    p.epipolar_threshold_px = v.getDouble("epipolar_threshold_px");
    p.seed = static_cast<unsigned>(v.getInt("seed"));
    p.estimate_disparity_offset = v.getBool("estimate_disparity_offset");
    p.disparity_offset_px = v.getDouble("disparity_offset_px");
    p.disparity_offset_sigma_px = v.getDouble("disparity_offset_sigma_px");
    p.disparity_offset_memory = v.getDouble("disparity_offset_memory");
    return std::make_unique<VisualOdometryStage>(
      p, v.getBool("reprojection_refinement"), v.getDouble("initial_height_m"),
      v.getDouble("initial_pitch_rad"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
