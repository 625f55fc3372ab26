// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>

#include <pcl/filters/filter_indices.h>
#include <pcl/pcl_macros.h>
#include <pcl/point_cloud.h>

#include <Eigen/Core>

#include <cstdint>
#include <memory>
#include <string>
#include <unordered_map>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each KLDivergenceOccupancyFilter parameter, declared once:
 * checkParameters() tests the values against them and the pipeline's
 * kl_occupancy_filter stage table takes them as its ranges. \ingroup filters */
namespace kl_divergence_occupancy_filter_ranges {
/** \brief Delta d of eq. 4: (0, 10] pixels. */
inline constexpr ParamRange DISPARITY_ERROR = ParamRange::openMin(0.0, 10.0);
/** \brief Edge of the neighbourhood cell of r_bar: (0, 100] meters. */
inline constexpr ParamRange NEIGHBOURHOOD_SIZE = ParamRange::openMin(0.0, 100.0);
/** \brief Lower clamp of the probability: (0, 0.5). */
inline constexpr ParamRange CLAMPING_THRES_MIN = ParamRange::open(0.0, 0.5);
/** \brief Upper clamp of the probability: (0.5, 1). */
inline constexpr ParamRange CLAMPING_THRES_MAX = ParamRange::open(0.5, 1.0);
/** \brief Occupancy threshold, a probability: [0, 1]. */
inline constexpr ParamRange OCCUPANCY_THRES = ParamRange::closed(0.0, 1.0);
/** \brief A of eq. 10: [0, 10] nats. */
inline constexpr ParamRange KL_OFFSET = ParamRange::closed(0.0, 10.0);
/** \brief Log-odds rule, probability of a hit: (0.5, 1). */
inline constexpr ParamRange PROB_HIT = ParamRange::open(0.5, 1.0);
/** \brief Log-odds rule, probability of a miss: (0, 0.5). */
inline constexpr ParamRange PROB_MISS = ParamRange::open(0.0, 0.5);
/** \brief Association radius without track ids: (0, 10] meters. */
inline constexpr ParamRange ASSOCIATION_RADIUS = ParamRange::openMin(0.0, 10.0);
/** \brief DEPTH_QUADRATIC: k of Delta z = k z^2, (0, 1] 1/m. */
inline constexpr ParamRange DEPTH_ERROR_COEFFICIENT = ParamRange::openMin(0.0, 1.0);
/** \brief RANGE: Delta r, (0, 10] meters. */
inline constexpr ParamRange RANGE_ERROR = ParamRange::openMin(0.0, 10.0);
/** \brief m of eq. 9, a likelihood: [0, 1]. */
inline constexpr ParamRange MOTION_LIKELIHOOD = ParamRange::closed(0.0, 1.0);
} // namespace kl_divergence_occupancy_filter_ranges

/** \brief How a feature track's occupancy probability is updated when it is observed
 * again. \ingroup filters */
enum class OccupancyUpdateRule {
  /** \brief The paper's Kullback-Leibler rule (eqs. 5-10). */
  KL_DIVERGENCE,
  /** \brief OctoMap's log-odds update: log_odds += log_odds(prob_hit) when the new
   * observation's probability q >= 0.5, else += log_odds(prob_miss), clamped. */
  LOG_ODDS
};

/** \brief Parses "kl_divergence" or "log_odds".
 * \throws planar_grid::Exception for any other name \ingroup filters */
OccupancyUpdateRule occupancyUpdateRuleFromString(const std::string& name);

/** \brief The name occupancyUpdateRuleFromString() accepts for \a rule. */
std::string toString(OccupancyUpdateRule rule);

/** \brief The range error Delta r of eq. 4, by sensor. \ingroup filters */
enum class RangeErrorModel {
  /** \brief The paper's stereo camera: Delta z = z^2 / (B f) Delta d and
   * Delta r = (r_bar / z) Delta z (the stereo parameters and disparity_error_px). */
  STEREO,
  /** \brief A depth camera (RGB-D, structured light or time of flight): Delta z =
   * k z^2 with k = depth_error_coefficient_per_m, and Delta r = (r_bar / z) Delta z,
   * the stereo form with k in place of Delta d / (B f). */
  DEPTH_QUADRATIC,
  /** \brief A range sensor (LiDAR): Delta r = range_error_m, the same at every range
   * and in every direction (a 360 degree scan: no optical axis is needed). */
  RANGE
};

/** \brief Parses "stereo", "depth_quadratic" or "range".
 * \throws planar_grid::Exception for any other name \ingroup filters */
RangeErrorModel rangeErrorModelFromString(const std::string& name);

/** \brief The name rangeErrorModelFromString() accepts for \a model. */
std::string toString(RangeErrorModel model);

/** \brief The probability guard of the KL rule: bernoulliKLDivergence() moves q into
 * [KL_PROBABILITY_EPS, 1 - KL_PROBABILITY_EPS] before taking logarithms, so that q = 0
 * (a motion likelihood m that underflowed) or q = 1 gives a large but finite
 * divergence instead of inf / NaN. \ingroup filters */
constexpr double KL_PROBABILITY_EPS = 1e-9;

/** \brief Eq. 4 of the paper, unclamped: the sampled Gaussian occupancy of one feature.
 *
 * dz = z^2 / (B f) dd, dr = (r_bar / z) dz, p = exp(-0.5 ((r - r_bar) / dr)^2).
 * \param[in] range_m r = |X - sensor_origin|, meters (> 0)
 * \param[in] mean_range_m r_bar, the mean range of the neighbourhood, meters
 * \param[in] depth_m z, the depth along the optical axis, meters (> 0)
 * \param[in] focal_length_px f, pixels (> 0)
 * \param[in] baseline_m B, meters (> 0)
 * \param[in] disparity_error_px dd, pixels (> 0)
 * \return the probability in [0, 1]: 1 when r == r_bar (a feature alone in its
 * neighbourhood), 0 when an argument is non-finite or out of its range
 * \ingroup filters */
double rangeOccupancyProbability(double range_m,
                                 double mean_range_m,
                                 double depth_m,
                                 double focal_length_px,
                                 double baseline_m,
                                 double disparity_error_px);

/** \brief Eq. 4 of the paper for a given range error, unclamped: the sampled Gaussian
 * p = exp(-0.5 ((r - r_bar) / Delta r)^2), for any sensor's Delta r.
 * \param[in] range_m r, meters
 * \param[in] mean_range_m r_bar, the mean range of the neighbourhood, meters
 * \param[in] range_error_m Delta r, meters (> 0)
 * \return the probability in [0, 1]: 1 when r == r_bar, 0 when an argument is
 * non-finite or Delta r <= 0 \ingroup filters */
double
sampledGaussianOccupancy(double range_m, double mean_range_m, double range_error_m);

/** \brief The Kullback-Leibler divergence of two Bernoulli distributions (eqs. 5-6
 * read for one feature with the two outcomes occupied / free):
 * D = p ln(p / q) + (1 - p) ln((1 - p) / (1 - q)), in nats.
 * \param[in] p the stored probability, in [0, 1] (0 ln 0 is taken as 0)
 * \param[in] q the new probability, in [0, 1]; moved into
 * [KL_PROBABILITY_EPS, 1 - KL_PROBABILITY_EPS] before the logarithms
 * \return D >= 0 (up to rounding), in nats; NaN when p or q is NaN \ingroup filters */
double bernoulliKLDivergence(double p, double q);

/** \brief One KL update (eq. 10): E = |D| + A when p <= 0.5 and q <= 0.5, else |D|,
 * with D = bernoulliKLDivergence(p, q); returns exp(-E) (not clamped). \param[in] p the
 * stored probability, in [0, 1] \param[in] q the new observation's probability (p_new
 * m, eq. 7), in [0, 1] \param[in] offset_nats A, nats (>= 0; the paper's 1.07) \return
 * the updated probability in (0, 1]; <= exp(-A) when p <= 0.5 and q <= 0.5
 * \ingroup filters */
double klDivergenceUpdate(double p, double q, double offset_nats);

/** \brief KLDivergenceOccupancyFilter's parameters with their defaults and valid
 * ranges (checked when filter() starts); their declarations are
 * klDivergenceOccupancyFilterParamDeclarations(), except range_error_model, which a
 * caller chooses per sensor (the kl_occupancy_filter stage per frame). The defaults
 * are the pipeline's. \ingroup filters */
struct KLDivergenceOccupancyFilterParams {
  /** dd of eq. 4: disparity error, pixels; in
   * kl_divergence_occupancy_filter_ranges::DISPARITY_ERROR. The paper's 0.5. */
  double disparity_error_px{0.5};
  /** Edge of the neighbourhood cell over which r_bar is averaged, meters; in
   * kl_divergence_occupancy_filter_ranges::NEIGHBOURHOOD_SIZE. */
  double neighbourhood_size_m{0.5};
  /** Lower clamp of the probability (OctoMap's clamping_thres_min); in
   * kl_divergence_occupancy_filter_ranges::CLAMPING_THRES_MIN.
   * 0.1192 = log-odds -2. */
  double clamping_thres_min{0.1192};
  /** Upper clamp of the probability (OctoMap's clamping_thres_max); in
   * kl_divergence_occupancy_filter_ranges::CLAMPING_THRES_MAX.
   * 0.971 = log-odds 3.5. */
  double clamping_thres_max{0.971};
  /** A feature is kept when its probability >= occupancy_thres; in
   * kl_divergence_occupancy_filter_ranges::OCCUPANCY_THRES. 0.5 = log-odds 0. */
  double occupancy_thres{0.5};
  /** A of eq. 10, nats; in kl_divergence_occupancy_filter_ranges::KL_OFFSET.
   * exp(-1.07) = 0.343. */
  double kl_offset_nats{1.07};
  /** The update rule of a re-observed track. */
  OccupancyUpdateRule update_rule{OccupancyUpdateRule::KL_DIVERGENCE};
  /** Log-odds rule: probability of a hit (q >= 0.5), in
   * kl_divergence_occupancy_filter_ranges::PROB_HIT; OctoMap's 0.7 =
   * log-odds 0.847. */
  double prob_hit{0.7};
  /** Log-odds rule: probability of a miss (q < 0.5), in
   * kl_divergence_occupancy_filter_ranges::PROB_MISS; OctoMap's 0.4 =
   * log-odds -0.405. */
  double prob_miss{0.4};
  /** Association without track ids: largest distance to a stored track, in the
   * input's units (meters); in
   * kl_divergence_occupancy_filter_ranges::ASSOCIATION_RADIUS. The pipeline's 0.1 m
   * (features without descriptors, associated in the world frame). */
  double association_radius_m{0.1};
  /** The sensor model of eq. 4's range error. */
  RangeErrorModel range_error_model{RangeErrorModel::STEREO};
  /** DEPTH_QUADRATIC: k of Delta z = k z^2, 1/m; in
   * kl_divergence_occupancy_filter_ranges::DEPTH_ERROR_COEFFICIENT. 0.0016 / m is 4
   * cm at 5 m, the Kinect's random depth error measured by Khoshelham and Elberink
   * (Sensors 12(2), 2012). */
  double depth_error_coefficient_per_m{0.0016};
  /** RANGE: Delta r, meters; in kl_divergence_occupancy_filter_ranges::RANGE_ERROR.
   * 0.03 m is the +-3 cm range accuracy of common 16-32 beam 3D LiDARs. */
  double range_error_m{0.03};
};

/** \brief The one declaration of each KLDivergenceOccupancyFilterParams member but
 * range_error_model (key with unit, range, meaning), in the order documented.
 * \ingroup filters */
const ParamDeclarations<KLDivergenceOccupancyFilterParams>&
klDivergenceOccupancyFilterParamDeclarations();

/** \brief Occupancy probability of stereo key feature points (paper Sec. III-D, eq. 4)
 * updated across frames with the Kullback-Leibler rule (Sec. III-E, eqs. 5-10), as a
 * pcl::FilterIndices: filter() keeps the features whose track probability reaches the
 * occupancy threshold (or, with setNegative(true), removes them).
 *
 * Eq. 4's range error Delta r is the paper's stereo model by default;
 * setRangeErrorModel() selects a depth camera's (Delta z = k z^2) or a range sensor's
 * (constant Delta r) instead, for features of RGB-D or LiDAR clouds (RangeErrorModel).
 *
 * Each call of filter() on a new input integrates the input as one frame:
 * - the sensor pose is the input cloud's sensor_origin_ / sensor_orientation_ (camera
 *   frame: x right, y down, z forward), so the features may be given in the camera
 *   frame (identity pose) or in the world frame with the camera pose set, as PCL
 *   clouds carry it;
 * - every valid feature gets p_new of eq. 4: r = |X - sensor_origin|, z its depth in
 *   the sensor frame, r_bar the mean range of the frame's valid features in the same
 *   neighbourhood cell (a cube of edge neighbourhood_size_m, axis-aligned in the
 *   sensor frame), clamped to [clamping_thres_min, clamping_thres_max] (with the RANGE
 *   model z is not used: any point at r > 0 is valid, whatever its direction);
 * - a feature whose track is new (or that has no track) takes p_new;
 * - a feature whose track was seen before gets q = p_new m with m the motion
 *   likelihood (setMotionLikelihood(), eq. 9), and its probability becomes
 *   klDivergenceUpdate(p, q, A) (or the log-odds rule), clamped;
 * - tracks not seen in the frame keep their probability; a track id that occurs twice
 *   in one frame is updated once (by its first occurrence).
 * Tracks are given by setTrackIds() (one id per input point, e.g. from descriptor
 * matching); without ids a feature joins the nearest stored track within
 * association_radius_m in the input's coordinates (a spatial hash of cubes of that
 * edge, searched over the 27 cubes around the feature) that no earlier feature of the
 * same frame took, else starts a new one. Association by position is meaningful for
 * world-frame input (or a still camera). Calling filter() again on the same input
 * (same cloud and indices pointers, ids and motion likelihood not set again) only
 * re-selects, with the current occupancy_thres and setNegative(); it does not update
 * twice. setParams() does not start a new frame.
 *
 * Internally each track stores its log-odds, as OctoMap does (probabilities only at
 * the interface, where a user reads and sets them): the KL rule converts to a
 * probability, updates and converts back, the log-odds rule adds log_odds(prob_hit) or
 * log_odds(prob_miss). The cost per frame is O(N) in the number of input features
 * (hash tables for the neighbourhood cells, the tracks and the association cubes; the
 * per-point work buffers are reused across frames).
 *
 * Degenerate input: no input cloud leaves the output untouched (pcl::Filter returns
 * before applyFilter()); an empty cloud or empty indices give empty output and a
 * PCL_WARN; a non-finite point or one at depth z <= 0 in the sensor frame is invalid:
 * probability 0, no track, never kept (also with setNegative(true); it goes to the
 * removed indices), and input without valid points gives empty output and a PCL_WARN;
 * invalid parameters, stereo parameters not set (STEREO model), a motion likelihood
 * outside [0, 1]
 * or track ids of the wrong size give empty output and a PCL_ERROR, and the tracks
 * are left unchanged, as PCL filters report bad input.
 * \ingroup filters */
template <typename PointT>
class KLDivergenceOccupancyFilter : public pcl::FilterIndices<PointT> {
protected:
  /** \brief The input cloud type. */
  using PointCloud = typename pcl::FilterIndices<PointT>::PointCloud;
  using pcl::FilterIndices<PointT>::filter_name_;
  using pcl::FilterIndices<PointT>::input_;
  using pcl::FilterIndices<PointT>::indices_;
  using pcl::FilterIndices<PointT>::negative_;
  using pcl::FilterIndices<PointT>::extract_removed_indices_;
  using pcl::FilterIndices<PointT>::removed_indices_;

public:
  /** \brief Shared pointer to a filter. */
  using Ptr = std::shared_ptr<KLDivergenceOccupancyFilter<PointT>>;
  /** \brief Shared pointer to a const filter. */
  using ConstPtr = std::shared_ptr<const KLDivergenceOccupancyFilter<PointT>>;
  /** \brief Shared pointer to an input cloud. */
  using PointCloudPtr = typename PointCloud::Ptr;
  /** \brief Shared pointer to a const input cloud. */
  using PointCloudConstPtr = typename PointCloud::ConstPtr;

  /** \brief Parameters with their defaults and valid ranges (checked when filter()
   * starts): KLDivergenceOccupancyFilterParams. */
  using Params = KLDivergenceOccupancyFilterParams;

  /** \brief Each parameter's one declaration (key, range, unit, meaning): the
   * kl_occupancy_filter stage and its reference are made from it.
   * \return klDivergenceOccupancyFilterParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return klDivergenceOccupancyFilterParamDeclarations();
  }

  /** \brief Empty filter with the default Params; stereo parameters must be set.
   * \param[in] extract_removed_indices whether filter() also records the removed
   * indices (getRemovedIndices()), as PCL's filters take it */
  explicit KLDivergenceOccupancyFilter(bool extract_removed_indices = false);
  ~KLDivergenceOccupancyFilter() override = default;

  /** \brief Sets all the parameters at once (each also has its own setter below);
   * they are validated when filter() starts. They apply from the next update on; this
   * does not start a new frame (filtering the same input again re-selects with the new
   * occupancy_thres). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Sets Delta d of eq. 4 (STEREO range error model). Like every setter below,
   * the value is validated when filter() starts (an invalid one gives empty output and
   * a PCL_ERROR) and applies from the next update on.
   * \param[in] disparity_error_px the disparity error, pixels, in
   * kl_divergence_occupancy_filter_ranges::DISPARITY_ERROR (default 0.5, the paper's)
   */
  void setDisparityError(double disparity_error_px)
  {
    params_.disparity_error_px = disparity_error_px;
  }
  /** \brief Returns Delta d of eq. 4, pixels. */
  double getDisparityError() const { return params_.disparity_error_px; }

  /** \brief Sets the edge of the neighbourhood cell over which eq. 4's mean range
   * r_bar is taken (a cube, axis-aligned in the sensor frame).
   * \param[in] neighbourhood_size_m the edge, meters, in
   * kl_divergence_occupancy_filter_ranges::NEIGHBOURHOOD_SIZE (default 0.5) */
  void setNeighbourhoodSize(double neighbourhood_size_m)
  {
    params_.neighbourhood_size_m = neighbourhood_size_m;
  }
  /** \brief Returns the neighbourhood cell's edge, meters. */
  double getNeighbourhoodSize() const { return params_.neighbourhood_size_m; }

  /** \brief Sets the lower clamp of a probability (OctoMap's clamping_thres_min).
   * \param[in] probability in kl_divergence_occupancy_filter_ranges::CLAMPING_THRES_MIN
   * (default 0.1192, log-odds -2) */
  void setClampingThresMin(double probability)
  {
    params_.clamping_thres_min = probability;
  }
  /** \brief Returns the lower clamp, a probability. */
  double getClampingThresMin() const { return params_.clamping_thres_min; }
  /** \brief Returns the lower clamp in log-odds (default -2). */
  double getClampingThresMinLogOdds() const;

  /** \brief Sets the upper clamp of a probability (OctoMap's clamping_thres_max).
   * \param[in] probability in kl_divergence_occupancy_filter_ranges::CLAMPING_THRES_MAX
   * (default 0.971, log-odds 3.51) */
  void setClampingThresMax(double probability)
  {
    params_.clamping_thres_max = probability;
  }
  /** \brief Returns the upper clamp, a probability. */
  double getClampingThresMax() const { return params_.clamping_thres_max; }
  /** \brief Returns the upper clamp in log-odds (default 3.51). */
  double getClampingThresMaxLogOdds() const;

  /** \brief Sets the probability a feature must reach to be kept by filter().
   * \param[in] probability in kl_divergence_occupancy_filter_ranges::OCCUPANCY_THRES
   * (default 0.5, log-odds 0) */
  void setOccupancyThres(double probability) { params_.occupancy_thres = probability; }
  /** \brief Returns the occupancy threshold, a probability. */
  double getOccupancyThres() const { return params_.occupancy_thres; }
  /** \brief Returns the occupancy threshold in log-odds (default 0; -inf / +inf for a
   * threshold of 0 / 1). */
  double getOccupancyThresLogOdds() const;

  /** \brief Sets A of eq. 10, added to the divergence when both the stored and the new
   * probability are <= 0.5.
   * \param[in] kl_offset_nats A, nats, in
   * kl_divergence_occupancy_filter_ranges::KL_OFFSET (default 1.07: exp(-1.07) = 0.343)
   */
  void setKLOffset(double kl_offset_nats) { params_.kl_offset_nats = kl_offset_nats; }
  /** \brief Returns A of eq. 10, nats. */
  double getKLOffset() const { return params_.kl_offset_nats; }

  /** \brief Sets the update of a re-observed track.
   * \param[in] update_rule KL_DIVERGENCE (eqs. 5-10, default) or LOG_ODDS */
  void setUpdateRule(OccupancyUpdateRule update_rule)
  {
    params_.update_rule = update_rule;
  }
  /** \brief Returns the update rule. */
  OccupancyUpdateRule getUpdateRule() const { return params_.update_rule; }

  /** \brief Sets the log-odds rule's probability of a hit (new q >= 0.5).
   * \param[in] probability in kl_divergence_occupancy_filter_ranges::PROB_HIT (default
   * 0.7, OctoMap's: log-odds 0.847) */
  void setProbHit(double probability) { params_.prob_hit = probability; }
  /** \brief Returns the probability of a hit. */
  double getProbHit() const { return params_.prob_hit; }
  /** \brief Returns the probability of a hit in log-odds (default 0.847). */
  double getProbHitLogOdds() const;

  /** \brief Sets the log-odds rule's probability of a miss (new q < 0.5).
   * \param[in] probability in kl_divergence_occupancy_filter_ranges::PROB_MISS (default
   * 0.4, OctoMap's: log-odds -0.405) */
  void setProbMiss(double probability) { params_.prob_miss = probability; }
  /** \brief Returns the probability of a miss. */
  double getProbMiss() const { return params_.prob_miss; }
  /** \brief Returns the probability of a miss in log-odds (default -0.405). */
  double getProbMissLogOdds() const;

  /** \brief Sets the largest distance from a feature to the stored track it joins,
   * for association by position (no track ids).
   * \param[in] association_radius_m in the input's units (meters), in
   * kl_divergence_occupancy_filter_ranges::ASSOCIATION_RADIUS (default 0.1) */
  void setAssociationRadius(double association_radius_m)
  {
    params_.association_radius_m = association_radius_m;
  }
  /** \brief Returns the association radius, meters. */
  double getAssociationRadius() const { return params_.association_radius_m; }

  /** \brief Sets the sensor model of eq. 4's range error.
   * \param[in] model STEREO (default), DEPTH_QUADRATIC or RANGE */
  void setRangeErrorModel(RangeErrorModel model) { params_.range_error_model = model; }
  /** \brief Returns the range error model. */
  RangeErrorModel getRangeErrorModel() const { return params_.range_error_model; }

  /** \brief Sets k of the DEPTH_QUADRATIC model's Delta z = k z^2.
   * \param[in] coefficient_per_m k, 1/m, in
   * kl_divergence_occupancy_filter_ranges::DEPTH_ERROR_COEFFICIENT (default 0.0016: 4
   * cm at 5 m) */
  void setDepthErrorCoefficient(double coefficient_per_m)
  {
    params_.depth_error_coefficient_per_m = coefficient_per_m;
  }
  /** \brief Returns k of Delta z = k z^2, 1/m. */
  double getDepthErrorCoefficient() const
  {
    return params_.depth_error_coefficient_per_m;
  }

  /** \brief Sets the RANGE model's Delta r, the same at every range.
   * \param[in] range_error_m Delta r, meters, in
   * kl_divergence_occupancy_filter_ranges::RANGE_ERROR (default 0.03) */
  void setRangeError(double range_error_m) { params_.range_error_m = range_error_m; }
  /** \brief Returns the RANGE model's Delta r, meters. */
  double getRangeError() const { return params_.range_error_m; }

  /** \brief Sets the rectified stereo rig of eq. 4 (validated when filter() starts;
   * needed by the STEREO range error model only).
   * \param[in] focal_length_px f, pixels (> 0)
   * \param[in] baseline_m B, meters (> 0) */
  void setStereoParameters(double focal_length_px, double baseline_m);
  /** \brief f of setStereoParameters(), pixels (0 when not set). */
  double getFocalLength() const { return focal_length_px_; }
  /** \brief B of setStereoParameters(), meters (0 when not set). */
  double getBaseline() const { return baseline_m_; }

  /** \brief Sets the input cloud (one frame of features); marks a new frame.
   * \param[in] cloud the features, in the camera frame or in the world frame with
   * sensor_origin_ / sensor_orientation_ holding the camera pose (meters) */
  void setInputCloud(const PointCloudConstPtr& cloud) override;

  /** \brief Sets one track id per point of the input cloud (not per index), >= 0; the
   * same id in a later frame is the same feature observed again. A negative id (-1)
   * marks a feature that belongs to no track (it gets eq. 4 and is not stored). An
   * empty vector selects association by position. A size other than the input's gives
   * empty output and a PCL_ERROR. Marks a new frame.
   * \param[in] track_ids the ids, parallel to the input cloud */
  void setTrackIds(const std::vector<std::int64_t>& track_ids);

  /** \brief Sets m of eq. 9 for this frame: the likelihood of the estimated motion
   * under the motion model, exp(-0.5 Mahalanobis^2), in [0, 1]; 1 when the poses are
   * given. Applies to the next update only (then it returns to 1). Marks a new frame.
   * \param[in] motion_likelihood m, in
   * kl_divergence_occupancy_filter_ranges::MOTION_LIKELIHOOD */
  void setMotionLikelihood(double motion_likelihood);

  /** \brief Forgets every track (and the frame count); the next filter() integrates
   * its input as a first frame. */
  void reset();

  /** \brief The probability of each input point after the last update (size of the
   * input cloud; 0 for points outside the indices, invalid or after a failure), in
   * [0, 1]. */
  const std::vector<float>& getProbabilities() const { return probabilities_; }

  /** \brief The track id of each input point after the last update (size of the input
   * cloud; -1 for points outside the indices, invalid or without a track). */
  const std::vector<std::int64_t>& getAssignedTrackIds() const
  {
    return assigned_track_ids_;
  }

  /** \brief Looks up a track's probability.
   * \param[in] track_id the id
   * \param[out] probability its probability, in [clamping_thres_min,
   * clamping_thres_max]; unchanged when the track is unknown
   * \return false when the track is unknown */
  bool getTrackProbability(std::int64_t track_id, float& probability) const;

  /** \brief Number of tracks stored. */
  std::size_t getTrackCount() const { return tracks_.size(); }

  /** \brief The id the next track made by position association gets: above every id
   * seen, also after retainTracks(). */
  std::int64_t getNextTrackId() const { return next_track_id_; }

  /** \brief Keeps the tracks whose ids are in \a track_ids and forgets the others.
   * Where the caller's track ids continue only from one frame to the next (a
   * frame-to-frame descriptor matcher, as the pipeline's stage), the tracks not among
   * the last frame's ids are never referenced again, and forgetting them after each
   * frame keeps a long run's memory bounded without changing any probability. Ids are
   * not reused (getNextTrackId()).
   * \param[in] track_ids the ids kept (ids without a track are ignored)
   * \return the number of tracks removed */
  std::size_t retainTracks(const std::vector<std::int64_t>& track_ids);

  /** \brief Appends the state carried across frames (for pipeline checkpoints): a
   * little-endian section of u32 magic "PGKT", u32 version 1, u32 frame count, i64 next
   * id, u64 tracks, then per track (sorted by id) i64 id, f32 log-odds, f32 position
   * x, y, z (meters), u32 observations, u32 last frame. Parameters, stereo parameters
   * and per-frame outputs are not included.
   * \param[out] bytes appended to */
  void serializeTracks(std::vector<std::uint8_t>& bytes) const;

  /** \brief Replaces the tracks by serializeTracks()' output (exactly \a size bytes);
   * the next filter() continues as the filter that wrote them would.
   * \throws planar_grid::IOError on truncated, trailing or invalid data (non-finite
   * values, a duplicate id); the tracks are then unchanged */
  void deserializeTracks(const std::uint8_t* data, std::size_t size);

  /** \brief Memory held by the tracks, the association hash and the work buffers,
   * bytes (estimate from the containers' sizes and bucket counts). */
  std::size_t getMemoryBytes() const;

protected:
  /** \brief Integrates the input when new (see the class brief), then selects. */
  void applyFilter(pcl::Indices& indices) override;

  /** \brief One stored feature track. */
  struct Track {
    /** \brief Log-odds of the probability, within the clamping thresholds' log-odds. */
    float log_odds{0.0f};
    /** \brief Last observed position, in the input's coordinates (meters). */
    Eigen::Vector3f position{Eigen::Vector3f::Zero()};
    /** \brief Number of observations. */
    std::uint32_t observations{0};
    /** \brief Frame of the last observation (1 for the first integrated frame). */
    std::uint32_t last_frame{0};
  };

  /** \brief One neighbourhood cell of the frame in the open-addressing table. */
  struct CellSum {
    /** \brief Packed cell coordinates. */
    std::uint64_t key{0};
    /** \brief Sum of the ranges of the cell's features, meters. */
    double range_sum_m{0.0};
    /** \brief Number of features in the cell (0: slot empty). */
    std::uint32_t count{0};
  };

  /** \brief Checks the parameters, stereo parameters, motion likelihood and track ids
   * against the input. \return nullptr when valid, else what is wrong */
  const char* checkParameters() const;

  /** \brief Computes eq. 4 for the indexed points and updates the tracks (one frame).
   * \return the number of valid points */
  std::size_t integrate();

  /** \brief Pass 1 of integrate(): the range, depth and neighbourhood cell of every
   * valid indexed point, and the cells' range sums. \return the number of valid
   * points */
  std::size_t sumNeighbourhoodRanges();

  /** \brief Eq. 4 for indexed point \a k (valid), by the range error model, clamped
   * to [clamping_thres_min, clamping_thres_max]. */
  double featureProbability(std::size_t k) const;

  /** \brief The constants of a frame's track updates: the clamping bounds as
   * probabilities and log-odds, and the log-odds rule's steps. */
  struct TrackUpdate {
    /** \brief clamping_thres_min, probability. */
    double p_min;
    /** \brief clamping_thres_max, probability. */
    double p_max;
    /** \brief clamping_thres_min as log-odds. */
    double log_odds_min;
    /** \brief clamping_thres_max as log-odds. */
    double log_odds_max;
    /** \brief The log-odds rule's step for a hit (prob_hit as log-odds). */
    double log_odds_hit;
    /** \brief The log-odds rule's step for a miss (prob_miss as log-odds). */
    double log_odds_miss;
  };

  /** \brief The track of point \a index (new, or updated by eqs. 5-10 once a frame)
   * with the new observation \a p_new at \a position; sets the point's probability
   * and track id. \a by_position: associate by position, not by the given ids. */
  void updateTrack(std::size_t index,
                   double p_new,
                   const Eigen::Vector3f& position,
                   bool by_position,
                   const TrackUpdate& update);

  /** \brief Finds the nearest stored track within association_radius_m of \a position
   * not yet observed in this frame. \return its id, or -1 */
  std::int64_t associate(const Eigen::Vector3f& position) const;

  /** \brief Packed key of the association cube of \a position. */
  std::uint64_t associationKey(const Eigen::Vector3f& position) const;

  /** \brief Rebuilds the association hash from all tracks. */
  void rebuildAssociationCells();

  /** \brief Moves track \a id from association cube \a old_key to \a new_key. */
  void moveAssociation(std::int64_t id, std::uint64_t old_key, std::uint64_t new_key);

  /** \brief Marks the input as not yet integrated. */
  void markInputChanged() { input_integrated_ = false; }

  /** \brief Clears the per-point outputs to the input's size (zeros / -1). */
  void resetOutputs();

  /** \brief The parameters. */
  Params params_;
  /** \brief f, pixels (0 until set). */
  double focal_length_px_{0.0};
  /** \brief B, meters (0 until set). */
  double baseline_m_{0.0};
  /** \brief Per-point track ids of the input (empty: association by position). */
  std::vector<std::int64_t> track_ids_;
  /** \brief m of eq. 9 for the next update, in [0, 1]. */
  double motion_likelihood_{1.0};
  /** \brief Tracks by id. */
  std::unordered_map<std::int64_t, Track> tracks_;
  /** \brief Association by position: ids of the tracks in each cube of edge
   * association_radius_m (valid when association_cells_valid_). */
  std::unordered_map<std::uint64_t, std::vector<std::int64_t>> association_cells_;
  /** \brief Whether association_cells_ matches the tracks' positions. */
  bool association_cells_valid_{false};
  /** \brief The cube edge association_cells_ was built with, meters. */
  double association_cell_size_m_{0.0};
  /** \brief Next id for tracks created by association (above every id seen). */
  std::int64_t next_track_id_{0};
  /** \brief Number of integrated frames so far. */
  std::uint32_t frame_count_{0};
  /** \brief Whether the current input was integrated already. */
  bool input_integrated_{false};
  /** \brief The input cloud integrated last. */
  PointCloudConstPtr integrated_input_;
  /** \brief The indices integrated last. */
  pcl::IndicesConstPtr integrated_indices_;
  /** \brief Per-point probabilities of the last update. */
  std::vector<float> probabilities_;
  /** \brief Per-point track ids of the last update. */
  std::vector<std::int64_t> assigned_track_ids_;
  /** \brief Work buffer: open-addressing table of the frame's neighbourhood cells. */
  std::vector<CellSum> cells_;
  /** \brief Work buffer: range (meters) of each indexed point. */
  std::vector<double> ranges_m_;
  /** \brief Work buffer: depth (meters) of each indexed point (its range with the
   * RANGE model), <= 0 when invalid. */
  std::vector<double> depths_m_;
  /** \brief Work buffer: slot in cells_ of each indexed point. */
  std::vector<std::uint32_t> cell_slots_;

public:
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/kl_divergence_occupancy_filter.hpp>
#endif
