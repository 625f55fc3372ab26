// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** The stage's own parameters beside StereoOdometry's: the refinement switch the
 * VisualOdometry takes, and the first camera's pose in the world. */
struct OdometryStageParams {
  bool reprojection_refinement{true};
  double initial_height_m{0.0};
  double initial_pitch_rad{0.0};
};

const ParamDeclarations<OdometryStageParams>&
odometryStageParamDeclarations()
{
  using P = OdometryStageParams;
  static const ParamDeclarations<P> table = {
    declareFlag<P>(
      "reprojection_refinement",
      [](auto& p) -> auto& { return p.reprojection_refinement; },
      "Refine the motion on the stereo reprojection error."),
    declareReal<P>(
      "initial_height_m", [](auto& p) -> auto& { return p.initial_height_m; },
      ParamRange::closed(0.0, 10.0), "m",
      "Height of the first camera above the world origin (the road)."),
    declareReal<P>(
      "initial_pitch_rad", [](auto& p) -> auto& { return p.initial_pitch_rad; },
      ParamRange::closed(-1.5, 1.5), "rad",
      "Downward pitch of the first camera from level (> 0 down)."),
  };
  return table;
}

class VisualOdometryStage : public Stage {
public:
  VisualOdometryStage(const StereoOdometry::Params& params,
                      const OdometryStageParams& stage_params) :
      odometry_(params, ConstantVelocityMotionModel::Params()),
      stage_params_(stage_params),
      reprojection_refinement_(stage_params.reprojection_refinement)
  {
    const double initial_height_m = stage_params.initial_height_m;
    const double initial_pitch_rad = stage_params.initial_pitch_rad;
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
    reportParams(StereoOdometry::getParamDeclarations(),
                 odometry_.getStereoOdometry().getParams(), v);
    reportParams(odometryStageParamDeclarations(), stage_params_, v);
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
  OdometryStageParams stage_params_;
  bool reprojection_refinement_;
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
  // StereoOdometry's keys, the refinement switch after min_inliers, the first
  // camera's pose last.
  info.params = paramSpecs(StereoOdometry::getParamDeclarations());
  const auto local = paramSpecs(odometryStageParamDeclarations());
  insertParamSpec(info.params, "min_inliers", local.front());
  info.params.insert(info.params.end(), local.begin() + 1, local.end());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    StereoOdometry::Params p;
    assignParams(StereoOdometry::getParamDeclarations(), v, p);
    OdometryStageParams stage_params;
    assignParams(odometryStageParamDeclarations(), v, stage_params);
    return std::make_unique<VisualOdometryStage>(p, stage_params);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
