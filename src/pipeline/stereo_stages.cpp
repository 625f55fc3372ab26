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
                       double max_range_m,
                       const DenseFrameSelection& selection) :
      estimator_(withoutThreadSwitch(params)),
      num_threads_(params.num_threads), max_range_m_(max_range_m), selection_(selection)
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
    const DisparityEstimator::Params& p = estimator_.getParams();
    v.set("algorithm", toString(p.algorithm));
    v.set("downscale", p.downscale);
    v.set("row_downscale", p.row_downscale);
    v.set("num_threads", num_threads_);
    v.set("min_disparity_px", p.min_disparity_px);
    v.set("num_disparities_px", p.num_disparities_px);
    v.set("block_size_px", p.block_size_px);
    v.set("p1", p.p1);
    v.set("p2", p.p2);
    v.set("disp12_max_diff_px", p.disp12_max_diff_px);
    v.set("pre_filter_cap", p.pre_filter_cap);
    v.set("uniqueness_ratio_percent", p.uniqueness_ratio_percent);
    v.set("speckle_window_size_px", p.speckle_window_size_px);
    v.set("speckle_range_px", p.speckle_range_px);
    v.set("full_dp", p.full_dp);
    v.set("bm_pre_filter", toString(p.bm_pre_filter));
    v.set("bm_pre_filter_cap", p.bm_pre_filter_cap);
    v.set("bm_pre_filter_size_px", p.bm_pre_filter_size_px);
    v.set("bm_texture_threshold", p.bm_texture_threshold);
    v.set("max_range_m", max_range_m_);
    v.set("frame_selection", selection_.keyframes ? std::string("keyframes")
                                                  : std::string("every_n_frames"));
    v.set("every_n_frames", selection_.every_n_frames);
    v.set("keyframe_translation_m", selection_.keyframe_translation_m);
    v.set("keyframe_rotation_rad", selection_.keyframe_rotation_rad);
    v.set("keyframe_max_gap_frames", selection_.keyframe_max_gap_frames);
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
  const DisparityEstimator::Params d;
  const DenseFrameSelection dense;
  namespace ranges = disparity_estimator_ranges;
  info.params = {
    ParamSpec::choice("algorithm", toString(d.algorithm),
                      {"sgbm", "sgbm_3way", "sgbm_hh", "sgbm_hh4", "block_matching"},
                      "OpenCV matcher: StereoSGBM 5-path (single-threaded), 3-way "
                      "(parallel), 8-path, 4-path, or StereoBM (local SAD, parallel)."),
    ParamSpec::integer("downscale", d.downscale, ranges::DOWNSCALE, "",
                       "Image scale divisor: 2 matches half-resolution images; the "
                       "output stays full resolution, in full-resolution px."),
    ParamSpec::integer("row_downscale", d.row_downscale, ranges::ROW_DOWNSCALE, "",
                       "Row divisor (with downscale 1): 2 matches the images at half "
                       "their rows and full width, so disparities keep their 1/16 px "
                       "step at half the matching cost; the output stays full size."),
    ParamSpec::integer("num_threads", d.num_threads, ranges::NUM_THREADS, "",
                       "OpenCV threads for the whole run (OpenCV's setting is "
                       "process-wide: every stage's OpenCV calls use it), set before "
                       "the first frame and restored after the last; speed only, "
                       "never the result; 0 = leave OpenCV's setting."),
    ParamSpec::integer("min_disparity_px", d.min_disparity_px, ranges::MIN_DISPARITY,
                       "px", "Smallest disparity searched; a multiple of downscale."),
    ParamSpec::integer("num_disparities_px", d.num_disparities_px,
                       ranges::NUM_DISPARITIES, "px",
                       "Number of disparities searched; a multiple of 16 * downscale."),
    ParamSpec::integer("block_size_px", d.block_size_px, ranges::BLOCK_SIZE, "px",
                       "Matched block side in matched-image px; odd, 1..11 for the "
                       "SGBM modes, 5..21 for block_matching."),
    ParamSpec::integer(
      "p1", d.p1, ranges::P1, "",
      "SGBM penalty for 1 px disparity changes; 0 = 8*channels*block^2."),
    ParamSpec::integer("p2", d.p2, ranges::P2, "",
                       "SGBM penalty for larger changes; 0 = 32*channels*block^2."),
    ParamSpec::integer("disp12_max_diff_px", d.disp12_max_diff_px,
                       ranges::DISP12_MAX_DIFF, "px",
                       "Left-right consistency tolerance; -1 disables the check."),
    ParamSpec::integer("pre_filter_cap", d.pre_filter_cap, ranges::PRE_FILTER_CAP, "",
                       "SGBM modes: clip of the x-derivative pre-filter."),
    ParamSpec::integer("uniqueness_ratio_percent", d.uniqueness_ratio_percent,
                       ranges::UNIQUENESS_RATIO, "percent",
                       "Margin by which the best cost must win."),
    ParamSpec::integer("speckle_window_size_px", d.speckle_window_size_px,
                       ranges::SPECKLE_WINDOW_SIZE, "px",
                       "Largest speckle region removed as noise; 0 disables."),
    ParamSpec::integer("speckle_range_px", d.speckle_range_px, ranges::SPECKLE_RANGE,
                       "px", "Largest disparity variation inside a speckle component."),
    ParamSpec::flag("full_dp", d.full_dp,
                    "Legacy: true = algorithm sgbm_hh (only with algorithm sgbm)."),
    ParamSpec::choice("bm_pre_filter", toString(d.bm_pre_filter),
                      {"xsobel", "normalized_response"},
                      "block_matching: pre-filter of both images."),
    ParamSpec::integer("bm_pre_filter_cap", d.bm_pre_filter_cap,
                       ranges::BM_PRE_FILTER_CAP, "",
                       "block_matching: clip of the pre-filter output (above 31 "
                       "OpenCV 4.6's StereoBM is not repeatable)."),
    ParamSpec::integer("bm_pre_filter_size_px", d.bm_pre_filter_size_px,
                       ranges::BM_PRE_FILTER_SIZE, "px",
                       "block_matching: normalized_response window side; odd."),
    ParamSpec::integer("bm_texture_threshold", d.bm_texture_threshold,
                       ranges::BM_TEXTURE_THRESHOLD, "",
                       "block_matching: blocks with less pre-filtered texture (sum of "
                       "absolute values) are invalid; 0 disables."),
    ParamSpec::real(
      "max_range_m", 40.0, point_cloud_from_disparity_ranges::MAX_RANGE, "m",
      "Points farther than this are invalid (stereo error grows as z^2)."),
    ParamSpec::choice(
      "frame_selection", "every_n_frames", {"every_n_frames", "keyframes"},
      "Which frames are dense (get the disparity and the cloud): every_n_frames by "
      "position, or keyframes by the camera's motion since the last keyframe (needs "
      "the frame's pose when this stage runs: input poses, the live mapper's pose, or "
      "visual_odometry listed before it; a run's first frame is a keyframe). The "
      "other frames carry their key features alone (feature_matching, "
      "kl_occupancy_filter and visual_odometry run on every frame) and add no points, "
      "planes, cells or free space to the map."),
    ParamSpec::integer(
      "every_n_frames", dense.every_n_frames, EVERY_N_FRAMES, "frames",
      "frame_selection every_n_frames: the frames whose sequence number (0-based "
      "position in the input, or in the live mapper's calls) is a multiple of n are "
      "dense. 1 = every frame."),
    ParamSpec::real("keyframe_translation_m", dense.keyframe_translation_m,
                    KEYFRAME_TRANSLATION, "m",
                    "frame_selection keyframes: a frame whose camera is this far from "
                    "the last keyframe's is a keyframe."),
    ParamSpec::real("keyframe_rotation_rad", dense.keyframe_rotation_rad,
                    KEYFRAME_ROTATION, "rad",
                    "frame_selection keyframes: a frame whose camera turned this much "
                    "from the last keyframe's (angle of the relative rotation) is a "
                    "keyframe."),
    ParamSpec::integer("keyframe_max_gap_frames", dense.keyframe_max_gap_frames,
                       KEYFRAME_MAX_GAP, "frames",
                       "frame_selection keyframes: the frame this many frames after "
                       "the last keyframe is a keyframe whatever the motion (a robot "
                       "standing still still maps what moves); 1 = every frame."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    DisparityEstimator::Params p;
    p.algorithm = disparityAlgorithmFromString(v.getChoice("algorithm"));
    p.downscale = v.getInt("downscale");
    p.row_downscale = v.getInt("row_downscale");
    p.num_threads = v.getInt("num_threads");
    p.min_disparity_px = v.getInt("min_disparity_px");
    p.num_disparities_px = v.getInt("num_disparities_px");
    p.block_size_px = v.getInt("block_size_px");
    p.p1 = v.getInt("p1");
    p.p2 = v.getInt("p2");
    p.disp12_max_diff_px = v.getInt("disp12_max_diff_px");
    p.pre_filter_cap = v.getInt("pre_filter_cap");
    p.uniqueness_ratio_percent = v.getInt("uniqueness_ratio_percent");
    p.speckle_window_size_px = v.getInt("speckle_window_size_px");
    p.speckle_range_px = v.getInt("speckle_range_px");
    p.full_dp = v.getBool("full_dp");
    p.bm_pre_filter = blockMatchingPreFilterFromString(v.getChoice("bm_pre_filter"));
    p.bm_pre_filter_cap = v.getInt("bm_pre_filter_cap");
    p.bm_pre_filter_size_px = v.getInt("bm_pre_filter_size_px");
    p.bm_texture_threshold = v.getInt("bm_texture_threshold");
    DenseFrameSelection selection;
    selection.keyframes = v.getChoice("frame_selection") == "keyframes";
    selection.every_n_frames = v.getInt("every_n_frames");
    selection.keyframe_translation_m = v.getDouble("keyframe_translation_m");
    selection.keyframe_rotation_rad = v.getDouble("keyframe_rotation_rad");
    selection.keyframe_max_gap_frames = v.getInt("keyframe_max_gap_frames");
    return std::make_unique<StereoDisparityStage>(p, v.getDouble("max_range_m"),
                                                  selection);
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
