// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <opencv2/core/utility.hpp>
#include <sched.h>

#include <algorithm>
#include <cmath>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** The CPUs this process may run on (its affinity mask, e.g. under taskset), at least
 * 1. */
int
allowedCpuCount()
{
  cpu_set_t cpus;
  CPU_ZERO(&cpus);
  if (sched_getaffinity(0, sizeof(cpus), &cpus) != 0)
    return 1;
  return std::max(1, CPU_COUNT(&cpus));
}

/** Dense frames: one in every_n_frames, [1, 1000]. */
constexpr ParamRange EVERY_N_FRAMES = ParamRange::closed(1, 1000);
/** Keyframe motion thresholds and the longest gap between two keyframes. */
constexpr ParamRange KEYFRAME_TRANSLATION = ParamRange::openMin(0.0, 1000.0);
constexpr ParamRange KEYFRAME_ROTATION = ParamRange::openMin(0.0, M_PI);
constexpr ParamRange KEYFRAME_MAX_GAP = ParamRange::closed(1, 100000);

/** Which frames get a dense disparity. */
struct DenseFrameSelection {
  /** true: keyframes by motion; false: one frame in every_n_frames. */
  bool keyframes{false};
  int every_n_frames{1};
  double keyframe_translation_m{1.0};
  double keyframe_rotation_rad{0.1};
  int keyframe_max_gap_frames{5};
};

/** The stage's own parameters beside DisparityEstimator's: the cloud's range and
 * which frames are dense. */
struct StereoDisparityStageParams {
  double max_range_m{40.0};
  DenseFrameSelection selection;
};

const ParamDeclarations<StereoDisparityStageParams>&
stereoDisparityStageParamDeclarations()
{
  using P = StereoDisparityStageParams;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "max_range_m", [](auto& p) -> auto& { return p.max_range_m; },
      point_cloud_from_disparity_ranges::MAX_RANGE, "m",
      "Points farther than this are invalid (stereo error grows as z^2)."),
    declareNamedChoice<P, bool>(
      "frame_selection", [](auto& p) -> auto& { return p.selection.keyframes; },
      {{"every_n_frames", false}, {"keyframes", true}},
      "Which frames are dense (get the disparity and the cloud): every_n_frames by "
      "position, or keyframes by the camera's motion since the last keyframe (needs "
      "the frame's pose when this stage runs: input poses, the live mapper's pose, or "
      "visual_odometry listed before it; a run's first frame is a keyframe). The "
      "other frames carry their key features alone (feature_matching, "
      "kl_occupancy_filter and visual_odometry run on every frame) and add no points, "
      "planes, cells or free space to the map."),
    declareInteger<P>(
      "every_n_frames", [](auto& p) -> auto& { return p.selection.every_n_frames; },
      EVERY_N_FRAMES, "frames",
      "frame_selection every_n_frames: the frames whose sequence number (0-based "
      "position in the input, or in the live mapper's calls) is a multiple of n are "
      "dense. 1 = every frame."),
    declareReal<P>(
      "keyframe_translation_m",
      [](auto& p) -> auto& { return p.selection.keyframe_translation_m; },
      KEYFRAME_TRANSLATION, "m",
      "frame_selection keyframes: a frame whose camera is this far from the last "
      "keyframe's is a keyframe."),
    declareReal<P>(
      "keyframe_rotation_rad",
      [](auto& p) -> auto& { return p.selection.keyframe_rotation_rad; },
      KEYFRAME_ROTATION, "rad",
      "frame_selection keyframes: a frame whose camera turned this much from the last "
      "keyframe's (angle of the relative rotation) is a keyframe."),
    declareInteger<P>(
      "keyframe_max_gap_frames",
      [](auto& p) -> auto& { return p.selection.keyframe_max_gap_frames; },
      KEYFRAME_MAX_GAP, "frames",
      "frame_selection keyframes: the frame this many frames after the last keyframe "
      "is a keyframe whatever the motion (a robot standing still still maps what "
      "moves); 1 = every frame."),
  };
  return table;
}

/** The estimator's parameters without its per-call thread switch: the stage sets
 * OpenCV's thread count once for the run instead. */
DisparityEstimator::Params
withoutThreadSwitch(DisparityEstimator::Params params)
{
  params.num_threads = 0;
  return params;
}

class StereoDisparityStage : public Stage {
public:
  StereoDisparityStage(const DisparityEstimator::Params& params,
                       const StereoDisparityStageParams& stage_params) :
      params_(params),
      stage_params_(stage_params), estimator_(withoutThreadSwitch(params)),
      num_threads_(params.num_threads), max_range_m_(stage_params.max_range_m),
      selection_(stage_params.selection)
  {}
  StereoDisparityStage(const StereoDisparityStage&) = delete;
  StereoDisparityStage& operator=(const StereoDisparityStage&) = delete;
  ~StereoDisparityStage() override { restoreThreads(); }

  // The keyframe choice carries the last keyframe's pose from frame to frame, in input
  // order, which the read-ahead keeps (it prepares one frame after the other).
  bool isFrameLocal() const override { return true; }

  // The read-ahead may have chosen keyframes beyond the frame a checkpoint is taken
  // at, so the keyframe state cannot be written for that frame.
  bool supportsCheckpoint() const override { return !selection_.keyframes; }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("dense_frames", frame.disparity.empty() ? 0.0 : 1.0);
  }

  // OpenCV's thread count is process-wide, and changing it while another thread is
  // inside cv::parallel_for_ (this stage runs beside the mapping stages when frames
  // overlap) can leave both spinning in the thread pool. So it is set once, on the
  // runner's thread before the first frame, and restored after the last.
  void start(PipelineState& /*state*/) override
  {
    has_keyframe_ = false;
    frames_since_keyframe_ = 0;
    restoreThreads();
    if (num_threads_ <= 0)
      return;
    // More threads than allowed CPUs gain nothing, and TBB prints a warning for each
    // worker it cannot start.
    const int wanted = std::min(num_threads_, allowedCpuCount());
    const int current = cv::getNumThreads();
    if (current != wanted) {
      previous_threads_ = current;
      cv::setNumThreads(wanted);
    }
  }

  void finish(PipelineState& /*state*/) override { restoreThreads(); }

  void getParameters(ParamValues& v) const override
  {
    // The configured parameters: the estimator holds them without the thread count.
    reportParams(DisparityEstimator::getParamDeclarations(), params_, v);
    reportParams(stereoDisparityStageParamDeclarations(), stage_params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    if (frame.left.empty() || frame.right.empty())
      throw Exception("stage 'stereo_disparity' needs a stereo pair; frame "
                      + frame.name + " has none");
    frame.cloud.reset(new Frame::Cloud);
    frame.cloud_in_world_frame = false;
    if (!isDense(frame)) {
      // A frame between two dense ones: no disparity and an empty cloud, so the dense
      // stages pass it on empty (without the warning of a frame whose points were lost)
      // and only its key features reach the map.
      frame.disparity.release();
      frame.no_points_stage = selection_.keyframes
                                ? "stereo_disparity (not a keyframe)"
                                : "stereo_disparity (every_n_frames)";
      return;
    }
    estimator_.compute(frame.left, frame.right, frame.disparity);
    disparityToPointCloud(frame.disparity, frame.left, frame.calibration, max_range_m_,
                          *frame.cloud);
  }

private:
  /** Whether \a frame gets a dense disparity: one in every_n_frames by position, or a
   * keyframe: the first frame, then each frame whose camera moved at least
   * keyframe_translation_m or turned at least keyframe_rotation_rad from the last
   * keyframe's, or that is keyframe_max_gap_frames after it. */
  bool isDense(const Frame& frame)
  {
    if (!selection_.keyframes)
      return frame.sequence_number % static_cast<std::size_t>(selection_.every_n_frames)
             == 0;
    if (!frame.has_pose)
      throw Exception("stage 'stereo_disparity' chooses keyframes by the camera's "
                      "motion, but frame "
                      + frame.name
                      + " has no pose when it runs: give the frames' poses, or list "
                        "visual_odometry before stereo_disparity");
    ++frames_since_keyframe_;
    bool keyframe =
      !has_keyframe_ || frames_since_keyframe_ >= selection_.keyframe_max_gap_frames;
    if (!keyframe) {
      const Eigen::Isometry3d motion =
        last_keyframe_world_T_camera_.inverse() * frame.world_T_camera;
      const double rotation_rad = Eigen::AngleAxisd(motion.rotation()).angle();
      keyframe = motion.translation().norm() >= selection_.keyframe_translation_m
                 || std::abs(rotation_rad) >= selection_.keyframe_rotation_rad;
    }
    if (keyframe) {
      has_keyframe_ = true;
      frames_since_keyframe_ = 0;
      last_keyframe_world_T_camera_ = frame.world_T_camera;
    }
    return keyframe;
  }

  void restoreThreads()
  {
    if (previous_threads_ > 0)
      cv::setNumThreads(previous_threads_);
    previous_threads_ = 0;
  }

  DisparityEstimator::Params params_;
  StereoDisparityStageParams stage_params_;
  DisparityEstimator estimator_;
  int num_threads_;
  int previous_threads_{0};
  double max_range_m_;
  DenseFrameSelection selection_;
  bool has_keyframe_{false};
  int frames_since_keyframe_{0};
  Eigen::Isometry3d last_keyframe_world_T_camera_{Eigen::Isometry3d::Identity()};
};

class FeatureMatchingStage : public Stage {
public:
  explicit FeatureMatchingStage(const StereoFeatureMatcher::Params& params) :
      matcher_(params)
  {}

  bool isFrameLocal() const override { return true; }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    matcher_.match(frame.left, frame.right, frame.calibration, frame.features);
  }

  bool countsCloudPoints() const override { return false; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(StereoFeatureMatcher::getParamDeclarations(), matcher_.getParams(), v);
  }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("features", static_cast<double>(frame.features.size()));
  }

private:
  StereoFeatureMatcher matcher_;
};

} // namespace

StageInfo
stereoDisparityInfo()
{
  StageInfo info;
  info.type = "stereo_disparity";
  info.description =
    "Dense disparity with an OpenCV matcher (StereoSGBM in one of its modes, or "
    "StereoBM), optionally at half resolution, reprojected to an organized cloud in "
    "the left camera frame (x right, y down, z forward; NaN = invalid).";
  info.needs_stereo = true;
  info.params = paramSpecs(DisparityEstimator::getParamDeclarations());
  const auto stage_params = paramSpecs(stereoDisparityStageParamDeclarations());
  info.params.insert(info.params.end(), stage_params.begin(), stage_params.end());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    DisparityEstimator::Params p;
    assignParams(DisparityEstimator::getParamDeclarations(), v, p);
    StereoDisparityStageParams stage_params;
    assignParams(stereoDisparityStageParamDeclarations(), v, stage_params);
    return std::make_unique<StereoDisparityStage>(p, stage_params);
  };
  return info;
}

StageInfo
featureMatchingInfo()
{
  StageInfo info;
  info.type = "feature_matching";
  info.description =
    "Key feature points (SIFT, ORB, or orb_grid: FAST corners bucketed over a grid, "
    "upright ORB descriptors and sub-pixel disparities; the paper's SURF is not in "
    "Debian's OpenCV) matched left to right along the epipolar row with Lowe's ratio "
    "test and triangulated to 3D.";
  info.needs_stereo = true;
  info.params = paramSpecs(StereoFeatureMatcher::getParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    StereoFeatureMatcher::Params p;
    assignParams(StereoFeatureMatcher::getParamDeclarations(), v, p);
    return std::make_unique<FeatureMatchingStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
