// SPDX-License-Identifier: BSD-3-Clause
#pragma once

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
OccupancyUpdateRule
occupancyUpdateRuleFromString(const std::string& name);

/** \brief The name occupancyUpdateRuleFromString() accepts for \a rule. */
std::string
toString(OccupancyUpdateRule rule);

/** \brief Eq. 4 of the paper, unclamped: the sampled Gaussian occupancy of one feature.
 *
 * dz = z^2 / (B f) dd, dr = (r_bar / z) dz, p = exp(-0.5 ((r - r_bar) / dr)^2).
 * \param[in] range_m r = |X - sensor_origin|, meters (> 0)
 * \param[in] mean_range_m r_bar, the mean range of the neighbourhood, meters
 * \param[in] depth_m z, the depth along the optical axis, meters (> 0)
 * \param[in] focal_length_px f, pixels (> 0)
 * \param[in] baseline_m B, meters (> 0)
 * \param[in] disparity_error_px dd, pixels (> 0)
 * \return the probability in [0, 1] (1 when r == r_bar)
 * \ingroup filters */
double
rangeOccupancyProbability(double range_m,
                          double mean_range_m,
                          double depth_m,
                          double focal_length_px,
                          double baseline_m,
                          double disparity_error_px);

/** \brief The Kullback-Leibler divergence of two Bernoulli distributions (eq. 6):
 * D = p ln(p / q) + (1 - p) ln((1 - p) / (1 - q)), in nats.
 * \param[in] p the stored probability, in (0, 1)
 * \param[in] q the new probability, in (0, 1)
 * \return D >= 0, in nats \ingroup filters */
double
bernoulliKLDivergence(double p, double q);

/** \brief One KL update (eqs. 5-10): E = |D| + A when p <= 0.5 and q <= 0.5, else |D|;
 * returns exp(-E) (not clamped).
 * \param[in] p the stored probability, in (0, 1)
 * \param[in] q the new observation's probability (p_new m), in (0, 1)
 * \param[in] offset_nats A, nats (>= 0; the paper's 1.07)
 * \return the updated probability in (0, 1] \ingroup filters */
double
klDivergenceUpdate(double p, double q, double offset_nats);

/** \brief Occupancy probability of stereo key feature points (paper Sec. III-D, eq. 4)
 * updated across frames with the Kullback-Leibler rule (Sec. III-E, eqs. 5-10), as a
 * pcl::FilterIndices: filter() keeps the features whose track probability reaches the
 * occupancy threshold (or, with setNegative(true), removes them).
 *
 * Each call of filter() on a new input integrates the input as one frame:
 * - the sensor pose is the input cloud's sensor_origin_ / sensor_orientation_ (camera
 *   frame: x right, y down, z forward), so the features may be given in the camera
 *   frame (identity pose) or in the world frame with the camera pose set, as PCL
 *   clouds carry it;
 * - a feature whose track is new gets eq. 4: r = |X - sensor_origin|, z its depth, r_bar
 *   the mean range of the frame's features in the same neighbourhood cell (a cube of
 *   edge neighbourhood_size_m in the sensor frame), clamped to [prob_min, prob_max];
 * - a feature whose track was seen before gets q = p_new m with p_new eq. 4 in this
 *   frame and m the motion likelihood (setMotionLikelihood(), eq. 9), and its
 *   probability becomes klDivergenceUpdate(p, q, A) (or the log-odds rule), clamped;
 * - tracks not seen in the frame keep their probability.
 * Tracks are given by setTrackIds() (one id per input point, e.g. from descriptor
 * matching); without ids a feature joins the nearest stored track within
 * association_radius_m in the input's coordinates (pcl::search::KdTree), else starts a
 * new one. Calling filter() again on the same input (cloud, indices, ids and motion
 * likelihood unchanged) only re-selects; it does not update twice.
 *
 * Empty input or input without valid points gives empty output and a PCL_WARN; a
 * non-finite point gets probability 0 and is never kept; invalid parameters or stereo
 * parameters not set give empty output and a PCL_ERROR (S24).
 * \ingroup filters */
template <typename PointT>
class KLDivergenceOccupancyFilter : public pcl::FilterIndices<PointT> {
protected:
  using PointCloud = typename pcl::FilterIndices<PointT>::PointCloud;
  using pcl::FilterIndices<PointT>::filter_name_;
  using pcl::FilterIndices<PointT>::input_;
  using pcl::FilterIndices<PointT>::indices_;
  using pcl::FilterIndices<PointT>::negative_;
  using pcl::FilterIndices<PointT>::extract_removed_indices_;
  using pcl::FilterIndices<PointT>::removed_indices_;

public:
  using Ptr = std::shared_ptr<KLDivergenceOccupancyFilter<PointT>>;
  using ConstPtr = std::shared_ptr<const KLDivergenceOccupancyFilter<PointT>>;
  using PointCloudPtr = typename PointCloud::Ptr;
  using PointCloudConstPtr = typename PointCloud::ConstPtr;

  /** \brief Parameters with their defaults and valid ranges. */
  struct Params {
    /** dd of eq. 4: disparity error, pixels; > 0. */
    double disparity_error_px{0.5};
    /** Edge of the neighbourhood cell over which r_bar is averaged, meters; > 0. */
    double neighbourhood_size_m{0.5};
    /** Lower clamp of the probability (OctoMap's clamping_thres_min); in (0, 0.5). */
    double clamping_thres_min{0.1192};
    /** Upper clamp of the probability (OctoMap's clamping_thres_max); in (0.5, 1). */
    double clamping_thres_max{0.971};
    /** A feature is kept when its probability >= occupancy_thres; in [0, 1]. */
    double occupancy_thres{0.5};
    /** A of eq. 10, nats; >= 0. exp(-1.07) = 0.343. */
    double kl_offset_nats{1.07};
    /** The update rule of a re-observed track. */
    OccupancyUpdateRule update_rule{OccupancyUpdateRule::KL_DIVERGENCE};
    /** Log-odds rule: probability of a hit (q >= 0.5), in (0.5, 1); OctoMap's 0.7. */
    double prob_hit{0.7};
    /** Log-odds rule: probability of a miss (q < 0.5), in (0, 0.5); OctoMap's 0.4. */
    double prob_miss{0.4};
    /** Association without track ids: largest distance to a stored track, in the
     * input's units (meters); > 0. */
    double association_radius_m{0.2};
  };

  /** \brief Empty filter with the default Params; stereo parameters must be set. */
  KLDivergenceOccupancyFilter();
  ~KLDivergenceOccupancyFilter() override = default;

  /** \brief Sets the parameters; they are validated when filter() starts (S23). */
  void setParams(const Params& params) { params_ = params; markInputChanged(); }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Sets the rectified stereo rig of eq. 4.
   * \param[in] focal_length_px f, pixels (> 0)
   * \param[in] baseline_m B, meters (> 0) */
  void setStereoParameters(double focal_length_px, double baseline_m);

  /** \brief Sets the input cloud (one frame of features); marks a new frame. */
  void setInputCloud(const PointCloudConstPtr& cloud) override;

  /** \brief Sets one track id per point of the input cloud (not per index), >= 0; the
   * same id in a later frame is the same feature observed again. An id of -1 marks a
   * feature that belongs to no track (it gets eq. 4 and is not stored). An empty
   * vector selects association by position. A size other than the input's gives
   * empty output and a PCL_ERROR. */
  void setTrackIds(const std::vector<std::int64_t>& track_ids);

  /** \brief Sets m of eq. 9 for this frame: the likelihood of the estimated motion
   * under the motion model, exp(-0.5 Mahalanobis^2), in (0, 1]; 1 when the poses are
   * given. Applies to the next update only. */
  void setMotionLikelihood(double motion_likelihood);

  /** \brief Forgets every track. */
  void reset();

  /** \brief The probability of each input point after the last update (size of the
   * input cloud; 0 for points outside the indices or non-finite). */
  const std::vector<float>&
  getProbabilities() const
  {
    return probabilities_;
  }

  /** \brief The track id of each input point after the last update (size of the input
   * cloud; -1 for points outside the indices, non-finite or without a track). */
  const std::vector<std::int64_t>&
  getAssignedTrackIds() const
  {
    return assigned_track_ids_;
  }

  /** \brief Looks up a track's probability.
   * \param[in] track_id the id
   * \param[out] probability its probability, in [0, 1]
   * \return false when the track is unknown */
  bool getTrackProbability(std::int64_t track_id, float& probability) const;

  /** \brief Number of tracks stored. */
  std::size_t getTrackCount() const { return tracks_.size(); }

  /** \brief Memory held by the tracks, bytes (estimate from the containers' sizes). */
  std::size_t getMemoryBytes() const;

protected:
  /** \brief Integrates the input when new (see the class brief), then selects. */
  void applyFilter(pcl::Indices& indices) override;

  /** \brief One stored feature track. */
  struct Track {
    /** \brief Probability in [clamping_thres_min, clamping_thres_max]. */
    float probability{0.5f};
    /** \brief Last observed position, in the input's coordinates. */
    Eigen::Vector3f position{Eigen::Vector3f::Zero()};
    /** \brief Number of observations. */
    std::uint32_t observations{0};
    /** \brief Frame of the last observation (count of updates so far). */
    std::uint32_t last_frame{0};
  };

  /** \brief Marks the input as not yet integrated. */
  void markInputChanged() { input_integrated_ = false; }

  /** \brief The parameters. */
  Params params_;
  /** \brief f, pixels (0 until set). */
  double focal_length_px_{0.0};
  /** \brief B, meters (0 until set). */
  double baseline_m_{0.0};
  /** \brief Per-point track ids of the input (empty: association by position). */
  std::vector<std::int64_t> track_ids_;
  /** \brief m of eq. 9 for the next update. */
  double motion_likelihood_{1.0};
  /** \brief Tracks by id. */
  std::unordered_map<std::int64_t, Track> tracks_;
  /** \brief Next id for tracks created by association. */
  std::int64_t next_track_id_{0};
  /** \brief Number of updates so far. */
  std::uint32_t frame_count_{0};
  /** \brief Whether the current input was integrated already. */
  bool input_integrated_{false};
  /** \brief Per-point probabilities of the last update. */
  std::vector<float> probabilities_;
  /** \brief Per-point track ids of the last update. */
  std::vector<std::int64_t> assigned_track_ids_;

public:
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/kl_divergence_occupancy_filter.hpp>
#endif
