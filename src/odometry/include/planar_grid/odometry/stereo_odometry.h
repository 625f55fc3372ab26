// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/memory.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each StereoOdometry::Params member, declared once: the
 * StereoOdometry constructor tests the values against them and the pipeline's
 * visual_odometry (and kl_occupancy_filter's match_ratio) stage table takes them as
 * its ranges. \ingroup odometry */
namespace stereo_odometry_ranges {
/** \brief Lowe's ratio: (0, 1]. */
inline constexpr ParamRange RATIO = ParamRange::openMin(0.0, 1.0);
/** \brief Largest descriptor distance of a match: [0, inf) (L2 or Hamming bits). */
inline constexpr ParamRange MAX_DESCRIPTOR_DISTANCE =
  ParamRange::openMax(0.0, ParamRange::UNBOUNDED);
/** \brief RANSAC inlier threshold: (0, 10] metres. */
inline constexpr ParamRange DISTANCE_THRESHOLD = ParamRange::openMin(0.0, 10.0);
/** \brief Depth scaling of the threshold: [0, inf) metres. */
inline constexpr ParamRange REFERENCE_DEPTH =
  ParamRange::openMax(0.0, ParamRange::UNBOUNDED);
/** \brief Reprojection inlier threshold: (0, 100] pixels. */
inline constexpr ParamRange REPROJECTION_THRESHOLD = ParamRange::openMin(0.0, 100.0);
/** \brief Huber threshold of the Sampson distance: (0, 100] pixels. */
inline constexpr ParamRange EPIPOLAR_THRESHOLD = ParamRange::openMin(0.0, 100.0);
/** \brief Largest rotation change of the epipolar refinement: (0, inf) radians. */
inline constexpr ParamRange EPIPOLAR_MAX_ROTATION_CHANGE =
  ParamRange::open(0.0, ParamRange::UNBOUNDED);
/** \brief Shortest translation of the epipolar refinement: [0, inf) metres. */
inline constexpr ParamRange EPIPOLAR_MIN_TRANSLATION =
  ParamRange::openMax(0.0, ParamRange::UNBOUNDED);
/** \brief Disparity offset: [-20, 20] pixels. */
inline constexpr ParamRange DISPARITY_OFFSET = ParamRange::closed(-20.0, 20.0);
/** \brief Standard deviation of the disparity offset's first prior: (0, 100] pixels. */
inline constexpr ParamRange DISPARITY_OFFSET_SIGMA = ParamRange::openMin(0.0, 100.0);
/** \brief Share of the offset's information carried on: [0, 1]. */
inline constexpr ParamRange DISPARITY_OFFSET_MEMORY = ParamRange::closed(0.0, 1.0);
/** \brief Most RANSAC iterations: [1, 1000000]. */
inline constexpr ParamRange MAX_ITERATIONS = ParamRange::closed(1, 1000000);
/** \brief RANSAC probability: (0, 1). */
inline constexpr ParamRange PROBABILITY = ParamRange::open(0.0, 1.0);
/** \brief Fewest inliers of a valid motion: [3, 100000]. */
inline constexpr ParamRange MIN_INLIERS = ParamRange::closed(3, 100000);
} // namespace stereo_odometry_ranges

/** \brief The valid range of each ConstantVelocityMotionModel::Params member, declared
 * once: the constructor tests the values against them and the pipeline's
 * kl_occupancy_filter stage table takes them as its ranges. \ingroup odometry */
namespace constant_velocity_motion_model_ranges {
/** \brief Standard deviation of each translation component: (0, 100] metres. */
inline constexpr ParamRange SIGMA_TRANSLATION = ParamRange::openMin(0.0, 100.0);
/** \brief Standard deviation of each rotation-vector component: (0, 10] radians. */
inline constexpr ParamRange SIGMA_ROTATION = ParamRange::openMin(0.0, 10.0);
} // namespace constant_velocity_motion_model_ranges

/** \brief Result of one frame-to-frame motion estimate (paper eq. 8).
 * \ingroup odometry */
struct OdometryResult {
  /** \brief Camera motion [R|T] of eq. 8: a point seen at x_cur in the current camera
   * frame is at x_prev = R x_cur + T in the previous one, so this is also the pose of
   * the current camera in the previous camera's frame (metres). Identity when invalid.
   */
  Eigen::Isometry3d previous_T_current{Eigen::Isometry3d::Identity()};
  /** \brief Correspondences within the RANSAC distance threshold of the final motion.
   */
  std::size_t inliers{0};
  /** \brief Descriptor matches that passed the ratio and mutual checks. */
  std::size_t correspondences{0};
  /** \brief True when the rotation comes from the epipolar refinement (see
   * StereoOdometry::Params::epipolar_refinement); false when it was off, skipped
   * (translation too short) or rejected by its guards. */
  bool epipolar_refined{false};
  /** \brief The disparity offset the motion was estimated with, pixels: the true
   * disparity is the measured one plus this (see
   * StereoOdometry::Params::estimate_disparity_offset). The prior's value when the
   * reprojection refinement did not run. */
  double disparity_offset_px{0.0};
  /** \brief Information (1 / variance, px^-2, for reprojection residuals of 1 px
   * standard deviation) of disparity_offset_px: the prior's plus this frame pair's. */
  double disparity_offset_information{0.0};
  /** \brief False when the motion could not be estimated (see reason). */
  bool valid{false};
  /** \brief Why the estimate is invalid; empty when valid. */
  std::string reason;

  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief Frame-to-frame stereo visual odometry (paper eq. 8): matches the descriptors
 * of the 3D key features of two frames (cv::BFMatcher, L2 for SIFT, Hamming for ORB,
 * Lowe's ratio test and a mutual check), estimates the rigid motion with RANSAC
 * (pcl::SampleConsensusModelRegistration + pcl::RandomSampleConsensus) and refines it
 * on the inliers with pcl::registration::TransformationEstimationSVD.
 *
 * Degenerate input never passes silently: fewer than 3 correspondences, matched points
 * on one line (or a single point), a RANSAC failure or fewer than min_inliers inliers
 * give OdometryResult::valid = false with a reason and a PCL_WARN.
 * \ingroup odometry */
class StereoOdometry {
public:
  /** \brief Shared pointer to a StereoOdometry. */
  using Ptr = std::shared_ptr<StereoOdometry>;
  /** \brief Shared pointer to a const StereoOdometry. */
  using ConstPtr = std::shared_ptr<const StereoOdometry>;

  /** \brief Parameters, with their valid ranges. */
  struct Params {
    /** Lowe's ratio: best / second-best descriptor distance must be below it; in
     * stereo_odometry_ranges::RATIO. */
    double ratio{0.8};
    /** Keep a match only when it is also the best match in the other direction. */
    bool mutual_check{true};
    /** Largest descriptor distance of a match (L2 for SIFT, Hamming bits for ORB);
     * 0 disables the check; in stereo_odometry_ranges::MAX_DESCRIPTOR_DISTANCE. */
    double max_descriptor_distance{0.0};
    /** RANSAC inlier threshold: largest 3D distance between a previous point and the
     * transformed current point (for points nearer than reference_depth_m), metres;
     * in stereo_odometry_ranges::DISTANCE_THRESHOLD. */
    double distance_threshold_m{0.1};
    /** Depth scaling of the threshold, metres; in
     * stereo_odometry_ranges::REFERENCE_DEPTH. When > 0, correspondence i's distance is
     * divided by s_i = max(1, z_i / reference_depth_m)^2 (z_i the larger of its two
     * depths; the stereo depth error grows with z^2) before the comparison with
     * distance_threshold_m, and the least-squares refinement weights it by 1 / s_i^2
     * (weighted SVD). When 0, one threshold holds for all depths and the refinement is
     * pcl::registration::TransformationEstimationSVD. */
    double reference_depth_m{0.0};
    /** Largest stereo reprojection error of an inlier in the refinement that runs
     * when a calibration is set (setCalibration()), pixels; in
     * stereo_odometry_ranges::REPROJECTION_THRESHOLD. */
    double reprojection_threshold_px{2.0};
    /** Re-estimate the rotation from the epipolar geometry of the two left images
     * after the stereo refinement (needs a calibration, setCalibration()): the
     * rotation and the translation direction minimise the Sampson distance of the
     * inliers' left key points (Gauss-Newton, Huber weights of
     * epipolar_threshold_px, each key point weighted by (median size / size)^2),
     * then the translation is re-fitted to the stereo reprojection error with that
     * rotation held fixed. The epipolar constraint does not involve the disparity,
     * so a disparity error (calibration, rectification, sub-pixel bias) cannot leak
     * into the rotation the way it does through the triangulated points. Skipped when
     * the stereo translation is shorter than epipolar_min_translation_m (the
     * epipolar geometry degenerates); the stereo motion is kept when the refined
     * rotation differs from it by more than epipolar_max_rotation_change_rad or the
     * translation direction by more than 15 degrees. */
    bool epipolar_refinement{true};
    /** Huber threshold of the Sampson distance in the epipolar refinement, pixels;
     * in stereo_odometry_ranges::EPIPOLAR_THRESHOLD. */
    double epipolar_threshold_px{0.5};
    /** Largest rotation change the epipolar refinement may make to the stereo
     * rotation, radians; in stereo_odometry_ranges::EPIPOLAR_MAX_ROTATION_CHANGE. */
    double epipolar_max_rotation_change_rad{0.02};
    /** Shortest stereo translation for which the epipolar refinement runs, metres;
     * in stereo_odometry_ranges::EPIPOLAR_MIN_TRANSLATION. */
    double epipolar_min_translation_m{0.05};
    /** Estimate a disparity offset together with the motion in the reprojection
     * refinement (needs a calibration, setCalibration()): the true disparity is
     * taken as the measured one plus an offset (the difference of the two rectified
     * cameras' principal point columns, which a rectification error shifts; the
     * negative of Middlebury's doffs), the points are triangulated with it and the
     * right-image projections carry it. Points triangulated from disparities that
     * are short by the offset are too far by about z offset / d (8 % at 20 px for
     * +1.5 px), and a motion fitted to such fixed points is too long by the same
     * factor; the offset is observable from two frames because the left-image motion
     * of a point follows its true inverse depth (d + offset) / (f B), whatever the
     * disparity says. The offset is a seventh Gauss-Newton unknown with the Gaussian
     * prior disparity_offset_px +- disparity_offset_sigma_px (estimate()), which
     * VisualOdometry replaces frame by frame by the previous pair's posterior (see
     * disparity_offset_memory). Off: the offset stays at disparity_offset_px. */
    bool estimate_disparity_offset{true};
    /** Disparity offset of the features, pixels (true disparity = measured +
     * offset): the prior mean of the estimate, or the offset used when it is not
     * estimated; in stereo_odometry_ranges::DISPARITY_OFFSET. */
    double disparity_offset_px{0.0};
    /** Standard deviation of the disparity offset's prior at the first frame pair,
     * pixels, for reprojection residuals of 1 px standard deviation; in
     * stereo_odometry_ranges::DISPARITY_OFFSET_SIGMA. */
    double disparity_offset_sigma_px{1.0};
    /** Share of the disparity offset's information that VisualOdometry carries from
     * one frame pair to the next as its prior; in
     * stereo_odometry_ranges::DISPARITY_OFFSET_MEMORY. 1 averages over the whole run (a
     * constant offset), smaller values follow an offset that changes, over about 1 / (1
     * - memory) frame pairs; the prior never gets weaker than disparity_offset_sigma_px
     * around the last estimate. The default, 0.8 (about 5 frame pairs), is a compromise
     * between the KITTI snippet, whose offset is constant (1 is best there), and
     * Karlsruhe, whose per-pair estimates change with the speed (0 is best there;
     * docs/ODOMETRY.md). */
    double disparity_offset_memory{0.8};
    /** Most RANSAC iterations; in stereo_odometry_ranges::MAX_ITERATIONS. */
    int max_iterations{2000};
    /** RANSAC probability of drawing one outlier-free sample; in
     * stereo_odometry_ranges::PROBABILITY. */
    double probability{0.99};
    /** Fewest inliers for a valid motion; in stereo_odometry_ranges::MIN_INLIERS. */
    int min_inliers{20};
    /** Seed of the RANSAC sampler: the same input and seed give the same motion.
     */
    unsigned seed{12345u};
  };

  /** \brief The one declaration (key with unit, range, meaning) of each Params member
   * that the visual_odometry stage sets, in the order documented; the stage, its
   * reference and the defaults (the members' initializers) are made from it. */
  static const ParamDeclarations<Params>& getParamDeclarations();

  /** \brief Throws planar_grid::Exception for out-of-range parameters. */
  explicit StereoOdometry(const Params& params);
  /** \brief Uses the default Params. */
  StereoOdometry();

  /** \brief Sets the rectified stereo calibration of the features. From then on
   * estimate() refines the RANSAC motion by minimising the stereo reprojection error
   * (Gauss-Newton, Huber weights of 1 px): each previous point is projected into the
   * current left and right images and each current point into the previous ones,
   * against the matched key points. The inliers are then the correspondences whose
   * largest reprojection error is below reprojection_threshold_px. When
   * Params::epipolar_refinement is set, the rotation is then re-estimated from the
   * epipolar geometry of the left images. Without a calibration only the 3D
   * refinement runs.
   * \param[in] calibration the calibration the features were triangulated with
   * \throws planar_grid::Exception when it is not valid */
  void setCalibration(const StereoCalibration& calibration);

  /** \brief Estimates the camera motion between two frames (eq. 8).
   * \param[in] previous the features of the earlier frame (camera frame, metres)
   * \param[in] current the features of the later frame
   * \return the motion previous_T_current, inlier and correspondence counts; valid =
   * false with a reason (and a PCL_WARN) when it cannot be estimated */
  OdometryResult estimate(const StereoFeatures& previous,
                          const StereoFeatures& current) const;

  /** \brief As estimate(previous, current), with the prior of the disparity offset
   * given instead of taken from the parameters (VisualOdometry passes the previous
   * frame pair's posterior).
   * \param[in] previous the features of the earlier frame (camera frame, metres)
   * \param[in] current the features of the later frame
   * \param[in] disparity_offset_px the prior mean of the disparity offset, pixels
   * (the offset used when Params::estimate_disparity_offset is off)
   * \param[in] disparity_offset_information the prior's information, px^-2 (>= 0)
   * \return as estimate(previous, current); disparity_offset_px and
   * disparity_offset_information hold the posterior */
  OdometryResult estimate(const StereoFeatures& previous,
                          const StereoFeatures& current,
                          double disparity_offset_px,
                          double disparity_offset_information) const;

  /** \brief Matches the descriptors of two frames: k = 2 nearest neighbours with
   * cv::BFMatcher, Lowe's ratio test, optional maximum distance and mutual check.
   * \param[in] previous the earlier frame's features (queryIdx of the matches)
   * \param[in] current the later frame's features (trainIdx of the matches)
   * \param[out] matches the accepted matches (empty when either frame has no
   * descriptors or their types differ; then a PCL_WARN is printed) */
  void matchDescriptors(const StereoFeatures& previous,
                        const StereoFeatures& current,
                        std::vector<cv::DMatch>& matches) const;

  /** \brief Guided matching of two frames whose relative pose is known (given poses,
   * or a motion model's prediction): each previous feature is projected into the
   * current left image, and only the current features whose left key points lie within
   * \a search_radius_px of the projection are its candidates. Among them the same
   * tests as matchDescriptors() apply: Lowe's ratio (best against second-best
   * candidate), the optional maximum distance and the mutual check (the current
   * feature's best candidate, over the previous features whose projections lie within
   * the radius of it, is the same previous feature). The cost is O(N) in the number of
   * features for a bounded key point density, against matchDescriptors()' O(N^2).
   * \param[in] previous the earlier frame's features (queryIdx of the matches), with
   * 3D points in its camera frame (metres)
   * \param[in] current the later frame's features (trainIdx of the matches)
   * \param[in] current_T_previous the motion from the previous camera frame to the
   * current one
   * \param[in] calibration the rectified calibration of the current frame (focal
   * length and principal point, pixels)
   * \param[in] search_radius_px the radius of the search window, pixels (> 0)
   * \param[out] matches the accepted matches, sorted by queryIdx (empty when either
   * frame has no descriptors, their types differ (with a PCL_WARN), the radius is not
   * > 0 or the calibration has no focal length) */
  void matchDescriptorsProjected(const StereoFeatures& previous,
                                 const StereoFeatures& current,
                                 const Eigen::Isometry3d& current_T_previous,
                                 const StereoCalibration& calibration,
                                 double search_radius_px,
                                 std::vector<cv::DMatch>& matches) const;

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

private:
  /** \brief The parameters (validated in the constructor). */
  Params params_;
  /** \brief The calibration for the reprojection refinement (valid if
   * has_calibration_).
   */
  StereoCalibration calibration_;
  /** \brief Whether setCalibration() was called. */
  bool has_calibration_{false};
};

/** \brief Constant-velocity motion model of the camera (paper eq. 9): the next motion
 * is predicted to equal the last one, m_k, with Gaussian error of covariance Q_k =
 * diag(sigma_translation_m^2 x 3, sigma_rotation_rad^2 x 3) over the 6-vector
 * (translation, rotation vector) of predicted^-1 * measured. Before any motion is added
 * the prediction is the identity (standing still). \ingroup odometry */
class ConstantVelocityMotionModel {
public:
  /** \brief Standard deviations of the motion error per frame. */
  struct Params {
    /** Standard deviation of each translation component, metres; in
     * constant_velocity_motion_model_ranges::SIGMA_TRANSLATION. */
    double sigma_translation_m{0.1};
    /** Standard deviation of each rotation-vector component, radians; in
     * constant_velocity_motion_model_ranges::SIGMA_ROTATION. */
    double sigma_rotation_rad{0.02};
  };

  /** \brief Throws planar_grid::Exception for sigmas outside their ranges. */
  explicit ConstantVelocityMotionModel(const Params& params);
  /** \brief Uses the default Params. */
  ConstantVelocityMotionModel();

  /** \brief Records the latest frame-to-frame motion previous_T_current (metres). */
  void addMotion(const Eigen::Isometry3d& previous_T_current);

  /** \brief Forgets the motion: the prediction becomes the identity again. */
  void reset();

  /** \brief True once a motion was added. */
  bool hasMotion() const { return has_motion_; }

  /** \brief The predicted next motion m_k (eq. 9): the last motion added, or the
   * identity. */
  const Eigen::Isometry3d& getPredictedMotion() const { return last_motion_; }

  /** \brief Predicts the next camera pose (eq. 9): world_T_current * m_k.
   * \param[in] world_T_current the current camera pose
   * \return the predicted world_T_next */
  Eigen::Isometry3d predict(const Eigen::Isometry3d& world_T_current) const;

  /** \brief Q_k: the 6x6 diagonal covariance of the motion error (translation in m^2,
   * then rotation vector in rad^2). */
  Eigen::Matrix<double, 6, 6> getCovariance() const;

  /** \brief Squared Mahalanobis distance of a measured motion from the prediction:
   * d^2 = e^T Q_k^-1 e with e = (t, r) of m_k^-1 * measured (t in metres, r the
   * rotation vector in radians). 0 for the prediction itself. \param[in]
   * measured_motion a measured previous_T_current \return d^2 (dimensionless, >= 0) */
  double mahalanobisSquared(const Eigen::Isometry3d& measured_motion) const;

  /** \brief Unnormalised Gaussian likelihood exp(-d^2 / 2) of a measured motion
   * (eq. 9), in (0, 1]; 1 for the prediction itself. \param[in] measured_motion a
   * measured previous_T_current */
  double motionLikelihood(const Eigen::Isometry3d& measured_motion) const;

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  PCL_MAKE_ALIGNED_OPERATOR_NEW

private:
  /** \brief The standard deviations. */
  Params params_;
  /** \brief The last motion added (identity before any). */
  Eigen::Isometry3d last_motion_{Eigen::Isometry3d::Identity()};
  /** \brief Whether a motion was added since construction or reset(). */
  bool has_motion_{false};
};

/** \brief Chains frame-to-frame motions (eq. 8) into camera poses world_T_camera; the
 * first frame is the world origin. When a frame's motion is invalid, the
 * constant-velocity prediction (eq. 9) takes its place, the frame index is recorded as
 * flagged (getFlaggedFrames()) and a PCL_WARN names it; it is never dropped silently.
 * \ingroup odometry */
class VisualOdometry {
public:
  /** \brief Shared pointer to a VisualOdometry. */
  using Ptr = std::shared_ptr<VisualOdometry>;
  /** \brief Shared pointer to a const VisualOdometry. */
  using ConstPtr = std::shared_ptr<const VisualOdometry>;

  /** \brief Throws planar_grid::Exception for invalid parameters. */
  VisualOdometry(const StereoOdometry::Params& odometry_params,
                 const ConstantVelocityMotionModel::Params& motion_params);
  /** \brief Uses the default parameters. */
  VisualOdometry();

  /** \brief Adds the next frame: estimates its motion from the previous frame and
   * appends its pose to the trajectory. \param[in] features the frame's features
   * \return the frame's odometry result (for the first frame: valid, identity, no
   * correspondences) */
  const OdometryResult& addFrame(const StereoFeatures& features);

  /** \brief Enables the reprojection refinement (StereoOdometry::setCalibration()).
   * \param[in] calibration the calibration the features were triangulated with */
  void setCalibration(const StereoCalibration& calibration)
  {
    odometry_.setCalibration(calibration);
  }

  /** \brief Camera poses world_T_camera, one per frame added (metres). */
  const Trajectory& getTrajectory() const { return trajectory_; }

  /** \brief One result per frame added (index 0: the first frame). */
  const std::vector<OdometryResult, Eigen::aligned_allocator<OdometryResult>>&
  getResults() const
  {
    return results_;
  }

  /** \brief Indices of the frames whose motion was invalid and replaced by the
   * prediction. */
  const std::vector<std::size_t>& getFlaggedFrames() const { return flagged_frames_; }

  /** \brief The motion model (its last motion is the prediction for the next frame).
   */
  const ConstantVelocityMotionModel& getMotionModel() const { return motion_model_; }

  /** \brief The frame-to-frame motion estimator (its parameters: getParams()). */
  const StereoOdometry& getStereoOdometry() const { return odometry_; }

  /** \brief The disparity offset estimated so far, pixels (true disparity = measured
   * + offset; StereoOdometry::Params::estimate_disparity_offset): the last valid frame
   * pair's posterior, the prior of the next one. Params::disparity_offset_px before
   * any. */
  double getDisparityOffset() const { return disparity_offset_px_; }

  /** \brief The information of getDisparityOffset(), px^-2. */
  double getDisparityOffsetInformation() const { return disparity_offset_information_; }

  /** \brief Appends the run state (for pipeline checkpoints): everything that the
   * next addFrame() calls and the getters depend on. A little-endian section of u32
   * magic "PGVO", u32 version 2; the previous frame's features (putStereoFeatures());
   * u64 frame count, then per frame its pose world_T_camera and its result (the motion
   * previous_T_current, each as the 3x4 f64 of putPose(), metres; u64 inliers, u64
   * correspondences, u8 epipolar_refined, u8 valid, f64 disparity_offset_px, f64
   * disparity_offset_information, the reason as u64 length and characters); the
   * flagged frame indices as u64 byte count and u64 values; the motion model's u8
   * has_motion and last motion (putPose()); the disparity offset and its information
   * (f64 px, f64 px^-2). The parameters and the
   * calibration (constructor, setCalibration()) are not included; the RANSAC seed is a
   * parameter and does not change from frame to frame, so no sampler state is needed.
   * \param[out] bytes appended to */
  void serializeState(std::vector<std::uint8_t>& bytes) const;

  /** \brief Replaces the run state by serializeState()'s output (exactly \a size
   * bytes): the next addFrame() continues as the odometry that wrote it would.
   * \throws planar_grid::IOError on truncated, trailing or invalid data (bad magic or
   * version, non-finite poses, inconsistent features, a flagged index out of range or
   * out of order); the object is then unchanged */
  void deserializeState(const std::uint8_t* data, std::size_t size);

private:
  /** \brief The frame-to-frame estimator. */
  StereoOdometry odometry_;
  /** \brief The constant-velocity model that bridges invalid frames. */
  ConstantVelocityMotionModel motion_model_;
  /** \brief The previous frame's features. */
  StereoFeatures previous_;
  /** \brief Poses world_T_camera. */
  Trajectory trajectory_;
  /** \brief One result per frame. */
  std::vector<OdometryResult, Eigen::aligned_allocator<OdometryResult>> results_;
  /** \brief Frames whose motion was predicted. */
  std::vector<std::size_t> flagged_frames_;
  /** \brief The disparity offset so far (the next frame pair's prior), pixels. */
  double disparity_offset_px_{0.0};
  /** \brief Its information, px^-2. */
  double disparity_offset_information_{0.0};
};

} // namespace planar_grid
