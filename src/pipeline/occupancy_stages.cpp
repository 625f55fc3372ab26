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

class KLOccupancyFilterStage : public Stage {
public:
  /** The range error of eq. 4 by sensor; AUTO follows the frame's features. */
  enum class ErrorModel {
    AUTO,   // stereo for stereo input; depth camera for key features of a cloud's
            // image; range sensor for point features (no descriptors)
    STEREO, // the paper's: the frame's stereo calibration and disparity_error_px
    DEPTH_QUADRATIC, // dz = k z^2 (depth_error_coefficient_per_m)
    RANGE            // dr = range_error_m
  };

  /** The filter's parameters, the frame-to-frame matching and the motion model from
   * the stage's parameters (see klOccupancyFilterInfo()). */
  explicit KLOccupancyFilterStage(const ParamValues& v) :
      matcher_(matchingParams(v)), search_radius_px_(v.getDouble("search_radius_px")),
      max_hamming_distance_(v.getInt("max_hamming_distance_bits")),
      motion_model_(motionParams(v)),
      use_motion_likelihood_(v.getBool("use_motion_likelihood"))
  {
    const std::string& model = v.getChoice("range_error_model");
    error_model_ = model == "stereo"            ? ErrorModel::STEREO
                   : model == "depth_quadratic" ? ErrorModel::DEPTH_QUADRATIC
                   : model == "range"           ? ErrorModel::RANGE
                                                : ErrorModel::AUTO;
    filter_.setUpdateRule(occupancyUpdateRuleFromString(v.getChoice("update_rule")));
    filter_.setDisparityError(v.getDouble("disparity_error_px"));
    filter_.setDepthErrorCoefficient(v.getDouble("depth_error_coefficient_per_m"));
    filter_.setRangeError(v.getDouble("range_error_m"));
    filter_.setAssociationRadius(v.getDouble("association_radius_m"));
    filter_.setNeighbourhoodSize(v.getDouble("neighbourhood_size_m"));
    filter_.setClampingThresMin(v.getDouble("clamping_thres_min"));
    filter_.setClampingThresMax(v.getDouble("clamping_thres_max"));
    filter_.setOccupancyThres(v.getDouble("occupancy_thres"));
    filter_.setKLOffset(v.getDouble("kl_offset_nats"));
    filter_.setProbHit(v.getDouble("prob_hit"));
    filter_.setProbMiss(v.getDouble("prob_miss"));
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    const bool stereo = !frame.left.empty();
    const bool descriptors =
      frame.features.descriptors.rows > 0
      && static_cast<std::size_t>(frame.features.descriptors.rows)
           == frame.features.size();
    RangeErrorModel model = RangeErrorModel::STEREO;
    switch (error_model_) {
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
      if (search_radius_px_ > 0.0 && frame.has_pose && has_previous_pose_
          && frame.calibration.focal_length_px > 0.0)
        matcher_.matchDescriptorsProjected(
          previous_, frame.features, frame.world_T_camera.inverse() * previous_pose_,
          frame.calibration, search_radius_px_, matches_);
      else
        matcher_.matchDescriptors(previous_, frame.features, matches_);
      // Binary descriptors: a pair farther apart than max_hamming_distance_bits is no
      // match, whatever the ratio test says (a search window may hold one candidate).
      if (max_hamming_distance_ > 0 && frame.features.descriptors.depth() == CV_8U)
        matches_.erase(std::remove_if(matches_.begin(), matches_.end(),
                                      [this](const cv::DMatch& m) {
                                        return m.distance > static_cast<float>(
                                                 max_hamming_distance_);
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
    if (use_motion_likelihood_ && frame.has_pose && has_previous_pose_) {
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
    v.set("update_rule", toString(filter_.getUpdateRule()));
    v.set("range_error_model",
          std::string(error_model_ == ErrorModel::STEREO            ? "stereo"
                      : error_model_ == ErrorModel::DEPTH_QUADRATIC ? "depth_quadratic"
                      : error_model_ == ErrorModel::RANGE           ? "range"
                                                                    : "auto"));
    v.set("disparity_error_px", filter_.getDisparityError());
    v.set("depth_error_coefficient_per_m", filter_.getDepthErrorCoefficient());
    v.set("range_error_m", filter_.getRangeError());
    v.set("association_radius_m", filter_.getAssociationRadius());
    v.set("neighbourhood_size_m", filter_.getNeighbourhoodSize());
    v.set("clamping_thres_min", filter_.getClampingThresMin());
    v.set("clamping_thres_max", filter_.getClampingThresMax());
    v.set("occupancy_thres", filter_.getOccupancyThres());
    v.set("kl_offset_nats", filter_.getKLOffset());
    v.set("prob_hit", filter_.getProbHit());
    v.set("prob_miss", filter_.getProbMiss());
    v.set("match_ratio", matcher_.getParams().ratio);
    v.set("search_radius_px", search_radius_px_);
    v.set("max_hamming_distance_bits", max_hamming_distance_);
    v.set("use_motion_likelihood", use_motion_likelihood_);
    v.set("sigma_translation_m", motion_model_.getParams().sigma_translation_m);
    v.set("sigma_rotation_rad", motion_model_.getParams().sigma_rotation_rad);
  }

private:
  static StereoOdometry::Params matchingParams(const ParamValues& v)
  {
    StereoOdometry::Params matching;
    matching.ratio = v.getDouble("match_ratio");
    return matching;
  }

  static ConstantVelocityMotionModel::Params motionParams(const ParamValues& v)
  {
    ConstantVelocityMotionModel::Params motion;
    motion.sigma_translation_m = v.getDouble("sigma_translation_m");
    motion.sigma_rotation_rad = v.getDouble("sigma_rotation_rad");
    return motion;
  }

  ErrorModel error_model_{ErrorModel::AUTO};
  RangeErrorModel model_{RangeErrorModel::STEREO};
  KLDivergenceOccupancyFilter<pcl::PointXYZ> filter_;
  StereoOdometry matcher_;
  double search_radius_px_;
  int max_hamming_distance_;
  ConstantVelocityMotionModel motion_model_;
  bool use_motion_likelihood_;
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
  const KLDivergenceOccupancyFilter<pcl::PointXYZ> d;
  const ConstantVelocityMotionModel::Params md;
  namespace ranges = kl_divergence_occupancy_filter_ranges;
  info.params = {
    ParamSpec::choice("update_rule", toString(d.getUpdateRule()),
                      {"kl_divergence", "log_odds"},
                      "Update of a re-observed feature: eqs. 5-10 or OctoMap's "
                      "log-odds."),
    ParamSpec::choice("range_error_model", "auto",
                      {"auto", "stereo", "depth_quadratic", "range"},
                      "dr of eq. 4: stereo = the paper's (r_bar / z) z^2 / (B f) dd "
                      "with the frame's calibration; depth_quadratic = (r_bar / z) k "
                      "z^2 (a depth camera); range = range_error_m (a LiDAR); auto = "
                      "stereo for stereo input, depth_quadratic for key features of a "
                      "cloud's image, range for point features."),
    ParamSpec::real("disparity_error_px", d.getDisparityError(),
                    ranges::DISPARITY_ERROR, "px", "dd of eq. 4 (stereo)."),
    ParamSpec::real("depth_error_coefficient_per_m", d.getDepthErrorCoefficient(),
                    ranges::DEPTH_ERROR_COEFFICIENT, "1/m",
                    "k of dz = k z^2 (depth_quadratic); the default is 4 cm at 5 m, "
                    "the Kinect's (Khoshelham and Elberink 2012)."),
    ParamSpec::real("range_error_m", d.getRangeError(), ranges::RANGE_ERROR, "m",
                    "dr of eq. 4 (range): the sensor's range standard deviation."),
    ParamSpec::real("association_radius_m", 0.1, ranges::ASSOCIATION_RADIUS, "m",
                    "Features without descriptors: a feature continues the nearest "
                    "track within this distance in the world (the pipeline's value; "
                    "the class defaults to "
                      + formatParamNumber(d.getAssociationRadius()) + " m)."),
    ParamSpec::real("neighbourhood_size_m", d.getNeighbourhoodSize(),
                    ranges::NEIGHBOURHOOD_SIZE, "m",
                    "Cell over which r_bar of eq. 4 is averaged."),
    ParamSpec::real("clamping_thres_min", d.getClampingThresMin(),
                    ranges::CLAMPING_THRES_MIN, "probability",
                    "Lower clamp of the probability."),
    ParamSpec::real("clamping_thres_max", d.getClampingThresMax(),
                    ranges::CLAMPING_THRES_MAX, "probability",
                    "Upper clamp of the probability."),
    ParamSpec::real("occupancy_thres", d.getOccupancyThres(), ranges::OCCUPANCY_THRES,
                    "probability",
                    "A feature is occupied when its probability reaches it."),
    ParamSpec::real("kl_offset_nats", d.getKLOffset(), ranges::KL_OFFSET, "nats",
                    "A of eq. 10."),
    ParamSpec::real("prob_hit", d.getProbHit(), ranges::PROB_HIT, "probability",
                    "Log-odds rule: a hit (q >= 0.5)."),
    ParamSpec::real("prob_miss", d.getProbMiss(), ranges::PROB_MISS, "probability",
                    "Log-odds rule: a miss (q < 0.5)."),
    ParamSpec::real("match_ratio", StereoOdometry::Params().ratio,
                    stereo_odometry_ranges::RATIO, "",
                    "Lowe's ratio of the frame-to-frame descriptor matching."),
    ParamSpec::real("search_radius_px", 20.0, 0.0, 10000.0, "px",
                    "Frames with poses and a pinhole calibration: a previous feature "
                    "is matched only to the features within this distance of its "
                    "projection by the motion between the two poses (guided "
                    "matching); 0: to every feature of the frame."),
    ParamSpec::integer("max_hamming_distance_bits", 64, 0, 256, "bits",
                       "Binary descriptors (ORB): a pair of features farther apart "
                       "than this many bits is no match; 0: no limit."),
    ParamSpec::flag("use_motion_likelihood", false,
                    "m of eq. 9 from the poses' motion against a constant-velocity "
                    "model (for estimated poses); false: m = 1 (given poses)."),
    ParamSpec::real("sigma_translation_m", md.sigma_translation_m,
                    constant_velocity_motion_model_ranges::SIGMA_TRANSLATION, "m",
                    "Q_k of eq. 9: standard deviation of each translation component."),
    ParamSpec::real("sigma_rotation_rad", md.sigma_rotation_rad,
                    constant_velocity_motion_model_ranges::SIGMA_ROTATION, "rad",
                    "Q_k of eq. 9: standard deviation of each rotation component."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<KLOccupancyFilterStage>(v);
  };
  return info;
}
} // namespace stages
} // namespace planar_grid
