// SPDX-License-Identifier: BSD-3-Clause
// The occupancy of the features (kl_occupancy_filter, paper Sec. III-D/E): the
// KLDivergenceOccupancyFilter along feature tracks matched from frame to frame with the
// visual odometry's descriptor matching and motion model.
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include <pcl/common/transforms.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** The range error of eq. 4 by sensor; AUTO follows the frame's features. */
enum class ErrorModel {
  AUTO,   // stereo for stereo input; depth camera for key features of a cloud's
          // image; range sensor for point features (no descriptors)
  STEREO, // the paper's: the frame's stereo calibration and disparity_error_px
  DEPTH_QUADRATIC, // dz = k z^2 (depth_error_coefficient_per_m)
  RANGE            // dr = range_error_m
};

/** The stage's own parameters beside the filter's: the sensor model it picks per
 * frame, the frame-to-frame matching and the motion model. */
struct KLStageParams {
  ErrorModel range_error_model{ErrorModel::AUTO};
  double match_ratio{StereoOdometry::Params().ratio};
  double search_radius_px{20.0};
  int max_hamming_distance_bits{64};
  bool use_motion_likelihood{false};
  double sigma_translation_m{ConstantVelocityMotionModel::Params().sigma_translation_m};
  double sigma_rotation_rad{ConstantVelocityMotionModel::Params().sigma_rotation_rad};
};

const ParamDeclarations<KLStageParams>&
klStageParamDeclarations()
{
  using P = KLStageParams;
  static const ParamDeclarations<P> table = {
    declareNamedChoice<P, ErrorModel>(
      "range_error_model", [](auto& p) -> auto& { return p.range_error_model; },
      {{"auto", ErrorModel::AUTO},
       {"stereo", ErrorModel::STEREO},
       {"depth_quadratic", ErrorModel::DEPTH_QUADRATIC},
       {"range", ErrorModel::RANGE}},
      "dr of eq. 4: stereo = the paper's (r_bar / z) z^2 / (B f) dd with the frame's "
      "calibration; depth_quadratic = (r_bar / z) k z^2 (a depth camera); range = "
      "range_error_m (a LiDAR); auto = stereo for stereo input, depth_quadratic for "
      "key features of a cloud's image, range for point features."),
    declareReal<P>(
      "match_ratio", [](auto& p) -> auto& { return p.match_ratio; },
      stereo_odometry_ranges::RATIO, "",
      "Lowe's ratio of the frame-to-frame descriptor matching."),
    declareReal<P>(
      "search_radius_px", [](auto& p) -> auto& { return p.search_radius_px; },
      ParamRange::closed(0.0, 10000.0), "px",
      "Frames with poses and a pinhole calibration: a previous feature is matched only "
      "to the features within this distance of its projection by the motion between "
      "the two poses (guided matching); 0: to every feature of the frame."),
    declareInteger<P>(
      "max_hamming_distance_bits",
      [](auto& p) -> auto& { return p.max_hamming_distance_bits; },
      ParamRange::closed(0, 256), "bits",
      "Binary descriptors (ORB): a pair of features farther apart than this many bits "
      "is no match; 0: no limit."),
    declareFlag<P>(
      "use_motion_likelihood", [](auto& p) -> auto& { return p.use_motion_likelihood; },
      "m of eq. 9 from the poses' motion against a constant-velocity model (for "
      "estimated poses); false: m = 1 (given poses)."),
    declareReal<P>(
      "sigma_translation_m", [](auto& p) -> auto& { return p.sigma_translation_m; },
      constant_velocity_motion_model_ranges::SIGMA_TRANSLATION, "m",
      "Q_k of eq. 9: standard deviation of each translation component."),
    declareReal<P>(
      "sigma_rotation_rad", [](auto& p) -> auto& { return p.sigma_rotation_rad; },
      constant_velocity_motion_model_ranges::SIGMA_ROTATION, "rad",
      "Q_k of eq. 9: standard deviation of each rotation component."),
  };
  return table;
}

class KLOccupancyFilterStage : public Stage {
public:
  /** The filter's parameters, and the stage's: the sensor model, the frame-to-frame
   * matching and the motion model (see klOccupancyFilterInfo()). */
  KLOccupancyFilterStage(const KLDivergenceOccupancyFilterParams& params,
                         const KLStageParams& stage_params) :
      stage_params_(stage_params),
      matcher_(matchingParams(stage_params)), motion_model_(motionParams(stage_params))
  {
    filter_.setParams(params);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    const bool stereo = !frame.left.empty();
    const bool descriptors =
      frame.features.descriptors.rows > 0
      && static_cast<std::size_t>(frame.features.descriptors.rows)
           == frame.features.size();
    RangeErrorModel model = RangeErrorModel::STEREO;
    switch (stage_params_.range_error_model) {
      case ErrorModel::AUTO:
        model = stereo        ? RangeErrorModel::STEREO
                : descriptors ? RangeErrorModel::DEPTH_QUADRATIC
                              : RangeErrorModel::RANGE;
        break;
      case ErrorModel::STEREO:
        if (!stereo)
          throw Exception("stage 'kl_occupancy_filter': range_error_model stereo "
                          "needs a stereo calibration; frame "
                          + frame.name + " has none");
        break;
      case ErrorModel::DEPTH_QUADRATIC:
        model = RangeErrorModel::DEPTH_QUADRATIC;
        break;
      case ErrorModel::RANGE:
        model = RangeErrorModel::RANGE;
        break;
    }
    model_ = model;
    frame.feature_probabilities.clear();
    frame.feature_track_ids.clear();
    kept_ = 0;
    reobserved_ = 0;
    motion_likelihood_ = 1.0;
    const std::size_t n = frame.features.size();
    if (n == 0 || frame.features.points.size() != n) {
      // Nothing matched in this frame (e.g. a blank image): the tracks wait.
      previous_ = StereoFeatures();
      previous_ids_.clear();
      return;
    }
    // Track ids: a feature whose descriptor matches one of the previous frame's (ratio
    // test + mutual check, as the odometry) continues that feature's track. Features
    // without descriptors (the points of a scan) are associated by position instead,
    // in the world frame (the filter's association radius).
    std::vector<std::int64_t> ids(n, -1);
    if (descriptors && previous_.size() > 0) {
      matches_.clear();
      // With both frames' poses (given, or estimated by an earlier stage) and a
      // pinhole calibration, a previous feature is searched only near where the motion
      // projects it; otherwise among all the frame's features.
      if (stage_params_.search_radius_px > 0.0 && frame.has_pose && has_previous_pose_
          && frame.calibration.focal_length_px > 0.0)
        matcher_.matchDescriptorsProjected(
          previous_, frame.features, frame.world_T_camera.inverse() * previous_pose_,
          frame.calibration, stage_params_.search_radius_px, matches_);
      else
        matcher_.matchDescriptors(previous_, frame.features, matches_);
      // Binary descriptors: a pair farther apart than
      // max_hamming_distance_bits is no match, whatever the ratio
      // test says (a search window may hold one candidate).
      if (stage_params_.max_hamming_distance_bits > 0
          && frame.features.descriptors.depth() == CV_8U)
        matches_.erase(
          std::remove_if(matches_.begin(), matches_.end(),
                         [this](const cv::DMatch& m) {
                           return m.distance > static_cast<float>(
                                    stage_params_.max_hamming_distance_bits);
                         }),
          matches_.end());
      for (const auto& m : matches_) {
        ids[static_cast<std::size_t>(m.trainIdx)] =
          previous_ids_[static_cast<std::size_t>(m.queryIdx)];
        ++reobserved_;
      }
    }
    for (auto& id : ids)
      if (id < 0)
        id = next_track_id_++;

    // m of eq. 9: the likelihood of this frame's motion under the motion model, when
    // the poses are estimated; 1 when they are given (GPS/INS, files).
    if (stage_params_.use_motion_likelihood && frame.has_pose && has_previous_pose_) {
      const Eigen::Isometry3d motion = previous_pose_.inverse() * frame.world_T_camera;
      motion_likelihood_ = motion_model_.motionLikelihood(motion);
      motion_model_.addMotion(motion);
    }
    has_previous_pose_ = frame.has_pose;
    previous_pose_ = frame.world_T_camera;

    pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
    if (descriptors || !frame.has_pose) {
      *cloud = frame.features.points;
    } else {
      // In the world frame with the camera pose as the sensor pose: the filter takes
      // eq. 4 in the sensor frame and associates the points across frames in the
      // world.
      pcl::transformPointCloud(frame.features.points, *cloud,
                               frame.world_T_camera.cast<float>().matrix());
      cloud->sensor_origin_.head<3>() =
        frame.world_T_camera.translation().cast<float>();
      cloud->sensor_origin_[3] = 1.0f;
      cloud->sensor_orientation_ =
        Eigen::Quaternionf(frame.world_T_camera.rotation().cast<float>());
    }
    filter_.setRangeErrorModel(model);
    if (model == RangeErrorModel::STEREO)
      filter_.setStereoParameters(frame.calibration.focal_length_px,
                                  frame.calibration.baseline_m);
    filter_.setInputCloud(cloud);
    if (descriptors)
      filter_.setTrackIds(ids);
    else
      filter_.setTrackIds({});
    filter_.setMotionLikelihood(motion_likelihood_);
    // Tracks made by position association are numbered from 0 up, so the ones that
    // existed before this frame are those below the current count.
    const auto first_new_id = static_cast<std::int64_t>(filter_.getTrackCount());
    pcl::Indices kept;
    filter_.filter(kept);
    kept_ = kept.size();
    frame.feature_probabilities = filter_.getProbabilities();
    frame.feature_track_ids = descriptors ? ids : filter_.getAssignedTrackIds();
    probability_sum_ = 0.0;
    for (const float p : frame.feature_probabilities)
      probability_sum_ += p;
    if (descriptors) {
      // Ids continue only from the previous frame's features: a track this frame did
      // not observe is never referenced again.
      filter_.retainTracks(ids);
      previous_ = frame.features;
      previous_ids_ = std::move(ids);
    } else {
      // Re-observed by position: the filter's tracks are the memory.
      for (const auto id : frame.feature_track_ids)
        reobserved_ += id >= 0 && id < first_new_id ? 1 : 0;
      previous_ = StereoFeatures();
      previous_ids_.clear();
    }
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    const double n = static_cast<double>(frame.features.size());
    values.emplace_back("features", n);
    values.emplace_back("reobserved", static_cast<double>(reobserved_));
    values.emplace_back("occupied", static_cast<double>(kept_));
    values.emplace_back("mean_probability", n > 0 ? probability_sum_ / n : 0.0);
    values.emplace_back("motion_likelihood", motion_likelihood_);
    // 0 stereo, 1 depth camera, 2 range sensor: the range error eq. 4 used.
    values.emplace_back("range_error_model", static_cast<double>(model_));
  }

  /** The tracks, the previous frame's features and ids, the previous pose and the
   * motion model's last motion. */
  void saveState(std::vector<std::uint8_t>& bytes) const override
  {
    ByteWriter w(bytes);
    std::vector<std::uint8_t> tracks;
    filter_.serializeTracks(tracks);
    w.putVector(tracks);
    putStereoFeatures(w, previous_);
    w.putVector(previous_ids_);
    w.put(next_track_id_);
    w.put(static_cast<std::uint8_t>(has_previous_pose_));
    putPose(w, previous_pose_);
    w.put(static_cast<std::uint8_t>(motion_model_.hasMotion()));
    putPose(w, motion_model_.getPredictedMotion());
  }

  void loadState(const std::uint8_t* data, std::size_t size) override
  {
    ByteReader r(data, size, "checkpoint: kl_occupancy_filter state");
    std::size_t tracks_size = 0;
    const std::uint8_t* tracks = r.getBytes(tracks_size, "track section");
    StereoFeatures previous;
    getStereoFeatures(r, previous);
    std::vector<std::int64_t> ids;
    r.getVector(ids, "track id");
    if (ids.size() != previous.size())
      r.fail("track ids and features of different lengths");
    const auto next_id = r.get<std::int64_t>();
    const bool has_previous_pose = r.get<std::uint8_t>() != 0;
    const Eigen::Isometry3d previous_pose = getPose(r);
    const bool has_motion = r.get<std::uint8_t>() != 0;
    const Eigen::Isometry3d motion = getPose(r);
    if (r.remaining() != 0)
      r.fail(std::to_string(r.remaining()) + " bytes of trailing data");
    filter_.deserializeTracks(tracks, tracks_size);
    previous_ = std::move(previous);
    previous_ids_ = std::move(ids);
    next_track_id_ = next_id;
    has_previous_pose_ = has_previous_pose;
    previous_pose_ = previous_pose;
    motion_model_.reset();
    if (has_motion)
      motion_model_.addMotion(motion);
  }

  void getParameters(ParamValues& v) const override
  {
    reportParams(klDivergenceOccupancyFilterParamDeclarations(), filter_.getParams(),
                 v);
    reportParams(klStageParamDeclarations(), stage_params_, v);
  }

private:
  static StereoOdometry::Params matchingParams(const KLStageParams& p)
  {
    StereoOdometry::Params matching;
    matching.ratio = p.match_ratio;
    return matching;
  }

  static ConstantVelocityMotionModel::Params motionParams(const KLStageParams& p)
  {
    ConstantVelocityMotionModel::Params motion;
    motion.sigma_translation_m = p.sigma_translation_m;
    motion.sigma_rotation_rad = p.sigma_rotation_rad;
    return motion;
  }

  KLStageParams stage_params_;
  RangeErrorModel model_{RangeErrorModel::STEREO};
  KLDivergenceOccupancyFilter<pcl::PointXYZ> filter_;
  StereoOdometry matcher_;
  ConstantVelocityMotionModel motion_model_;
  StereoFeatures previous_;
  std::vector<std::int64_t> previous_ids_;
  std::vector<cv::DMatch> matches_;
  std::int64_t next_track_id_{0};
  Eigen::Isometry3d previous_pose_{Eigen::Isometry3d::Identity()};
  bool has_previous_pose_{false};
  std::size_t kept_{0};
  std::size_t reobserved_{0};
  double probability_sum_{0.0};
  double motion_likelihood_{1.0};
};

} // namespace

StageInfo
klOccupancyFilterInfo()
{
  StageInfo info;
  info.type = "kl_occupancy_filter";
  info.description =
    "planar_grid::KLDivergenceOccupancyFilter (paper Sec. III-D/E): each 3D key "
    "feature gets the sampled-Gaussian occupancy of eq. 4 over its sensor's range "
    "error (stereo, depth camera or range sensor); features matched again in later "
    "frames (descriptor matching, ratio test and mutual check, one track per feature, "
    "searched near the feature's projection by the poses' motion when the frames have "
    "poses; "
    "features without descriptors by position in the world) are updated with the "
    "Kullback-Leibler rule (eqs. 5-10) or OctoMap's log-odds rule. Needs "
    "feature_matching (stereo) or cloud_features (point clouds) before it.";
  // The filter's table with the stage's sensor model after the update rule and its
  // matching and motion keys last.
  info.params = paramSpecs(klDivergenceOccupancyFilterParamDeclarations());
  const auto local = paramSpecs(klStageParamDeclarations());
  insertParamSpec(info.params, "update_rule", local.front());
  info.params.insert(info.params.end(), local.begin() + 1, local.end());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    KLDivergenceOccupancyFilterParams params;
    assignParams(klDivergenceOccupancyFilterParamDeclarations(), v, params);
    KLStageParams stage_params;
    assignParams(klStageParamDeclarations(), v, stage_params);
    return std::make_unique<KLOccupancyFilterStage>(params, stage_params);
  };
  return info;
}
} // namespace stages
} // namespace planar_grid
