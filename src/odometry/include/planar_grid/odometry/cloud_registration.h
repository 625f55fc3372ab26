// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <cstddef>

namespace planar_grid {

/** \brief Options of registerCloud(), with their defaults. \ingroup odometry */
struct CloudRegistrationParams {
  /** \brief Voxel edge both clouds are downsampled to (pcl::VoxelGrid), metres (> 0).
   */
  double leaf_size_m{0.05};
  /** \brief Largest correspondence distance of the coarse GICP pass, metres (> 0); a
   * fine pass follows at a quarter of it. */
  double max_correspondence_distance_m{0.5};
  /** \brief Most GICP iterations per pass, >= 1. */
  int max_iterations{100};
  /** \brief A source point whose nearest target point is this close is in the overlap;
   * the residual is taken over those, metres (> 0). */
  double inlier_distance_m{0.1};
  /** \brief Where GICP from the initial guess leaves less than feature_guess_overlap
   * of the source in the overlap, also try an initial guess from matched FPFH features
   * (pcl::FPFHEstimation, pcl::SampleConsensusPrerejective) and keep whichever result
   * has the larger overlap. */
  bool feature_initial_guess{true};
  /** \brief The overlap below which the feature guess is tried, in [0, 1]. */
  double feature_guess_overlap{0.6};
  /** \brief Voxel edge of the feature guess's clouds, metres (> 0); coarser than
   * leaf_size_m keeps pcl::SampleConsensusPrerejective fast. */
  double feature_leaf_size_m{0.1};
  /** \brief Radius of the normals of the feature guess, metres (> 0). */
  double normal_radius_m{0.25};
  /** \brief Radius of the FPFH features, metres (> normal_radius_m). */
  double feature_radius_m{0.5};
  /** \brief Iterations of pcl::SampleConsensusPrerejective, >= 1. */
  int feature_max_iterations{5000};
  /** \brief Seed of the feature guesses' random sampling (std::srand, which
   * pcl::SampleConsensusPrerejective draws from, and the RANSAC of the image feature
   * guess). */
  unsigned seed{0};
  /** \brief Where both clouds come with key features of their images (the overload
   * of registerCloud() with features), start GICP from the motion of the matched
   * features first (descriptor matching with Lowe's ratio and a mutual check, a RANSAC
   * rigid fit refined on its inliers: StereoOdometry without a calibration); the
   * initial guess and the FPFH guess are tried only when that leaves less than
   * feature_guess_overlap of the source in the overlap. */
  bool image_feature_guess{true};
  /** \brief RANSAC inlier threshold of the image feature guess: largest 3D distance of
   * a matched pair after the motion, metres (> 0). */
  double image_feature_distance_m{0.05};
  /** \brief Fewest RANSAC inliers for an image feature guess, >= 3. */
  int image_feature_min_inliers{20};
};

/** \brief What registerCloud() found. \ingroup odometry */
struct CloudRegistrationResult {
  /** \brief target_T_source: a source point p is at target_T_source * p in the target's
   * frame. */
  Eigen::Isometry3d target_T_source{Eigen::Isometry3d::Identity()};
  /** \brief Root mean square point-to-plane distance of the overlapping source points
   * to the target's surface (target normals), metres. */
  double residual_m{0.0};
  /** \brief Fraction of the downsampled source points in the overlap, in [0, 1]. */
  double overlap{0.0};
  /** \brief Whether GICP reported convergence. */
  bool converged{false};
  /** \brief Whether the kept result started from the FPFH feature guess. */
  bool feature_guess_used{false};
  /** \brief Whether the kept result started from the image feature guess. */
  bool image_feature_guess_used{false};
  /** \brief RANSAC inliers of the image feature guess (0 when it did not run or
   * failed). */
  std::size_t image_feature_inliers{0};
  /** \brief Whether the image features' motion was kept without GICP's refinement:
   * GICP moved it along a direction the clouds' geometry does not fix (a plane, a
   * corridor), so that fewer than 80 % as many matched features lie within
   * image_feature_distance_m of each other after the refined motion as after the
   * features' own. */
  bool image_feature_motion_kept{false};
};

/** \brief Registers \a source onto \a target: pcl::GeneralizedIterativeClosestPoint
 * (plane-to-plane ICP) on both clouds downsampled by pcl::VoxelGrid, a coarse pass and
 * a fine one, from \a initial_guess and, with feature_initial_guess where that leaves
 * too little overlap, also from the pose of FPFH features matched by
 * pcl::SampleConsensusPrerejective; the result with the larger overlap is kept. The
 * residual is measured against the target's normals (pcl::NormalEstimation, radius 3
 * leaf sizes).
 * \param[in] source the cloud to move, metres; NaN points are ignored
 * \param[in] target the fixed cloud, metres; NaN points are ignored
 * \param[in] initial_guess target_T_source to start from (identity when the frames are
 *            close)
 * \param[in] params the options
 * \return the transform with its residual and overlap; for a cloud with fewer than 10
 *         points the initial guess with overlap 0 and a PCL_WARN
 * \ingroup odometry */
CloudRegistrationResult registerCloud(const pcl::PointCloud<pcl::PointXYZ>& source,
                                      const pcl::PointCloud<pcl::PointXYZ>& target,
                                      const Eigen::Isometry3d& initial_guess,
                                      const CloudRegistrationParams& params);

/** \brief As registerCloud() without features, starting first from the motion of the
 * key features of the two clouds' images where both have some (see
 * CloudRegistrationParams::image_feature_guess): the features are matched by
 * descriptor (cv::BFMatcher, Lowe's ratio 0.8, mutual check) and their motion is fitted
 * by RANSAC on 3D point triples (pcl::SampleConsensusModelRegistration) and refined on
 * the inliers (pcl::registration::TransformationEstimationSVD), as the stereo
 * odometry's eq. 8; GICP refines it on the clouds. Without features on either side,
 * or with fewer than image_feature_min_inliers inliers, it is registerCloud().
 * \param[in] source the cloud to move, metres; NaN points are ignored
 * \param[in] target the fixed cloud, metres; NaN points are ignored
 * \param[in] initial_guess target_T_source to try when the feature guess fails
 * \param[in] params the options
 * \param[in] source_features 3D key features of the source, in its frame (metres), with
 *            descriptors (computeCloudImageFeatures())
 * \param[in] target_features the same for the target
 * \return as registerCloud()
 * \throws planar_grid::Exception when image_feature_distance_m is not > 0 or
 * image_feature_min_inliers is below 3 (checked when both clouds have features)
 * \ingroup odometry */
CloudRegistrationResult registerCloud(const pcl::PointCloud<pcl::PointXYZ>& source,
                                      const pcl::PointCloud<pcl::PointXYZ>& target,
                                      const Eigen::Isometry3d& initial_guess,
                                      const CloudRegistrationParams& params,
                                      const StereoFeatures& source_features,
                                      const StereoFeatures& target_features);

/** \brief The grey image of an organized cloud: one 8-bit pixel per point (row-major,
 * width x height), from the intensity field (a colour cloud's grey,
 * pcl::PointXYZRGBtoXYZI). Intensities outside [0, 255] (a scanner's own scale) are
 * stretched to it; non-finite ones are 0.
 * \param[in] cloud the cloud
 * \return CV_8UC1 image; empty when the cloud is not organized or its intensity is the
 * same everywhere (bare x y z: no image)
 * \ingroup odometry */
cv::Mat cloudIntensityImage(const pcl::PointCloud<pcl::PointXYZI>& cloud);

/** \brief Key features of an organized cloud's own image, lifted to 3D through the
 * cloud: key points are detected and described on \a grey (orb_grid: FAST corners
 * bucketed over a grid with upright ORB descriptors, detectGridFastKeypoints(); orb;
 * sift) and each takes the cloud's point at its pixel. Key points on a pixel without a
 * finite point, or beyond params.max_range_m from the sensor, are dropped.
 * \param[in] cloud the organized cloud (the sensor's frame unless camera_T_cloud says
 *            otherwise), metres
 * \param[in] grey its image, cloudIntensityImage()
 * \param[in] params feature_type, max_features, bucket_size_px, fast_threshold and
 *            max_range_m (metres) are used
 * \param[in] camera_T_cloud takes the cloud's points into the sensor (camera) frame
 * \param[out] features replaced by the features: points (sensor frame, metres),
 *             keypoints_left (px) and descriptors, one row per point
 * \ingroup odometry */
void computeCloudImageFeatures(const pcl::PointCloud<pcl::PointXYZI>& cloud,
                               const cv::Mat& grey,
                               const StereoFeatureMatcher::Params& params,
                               const Eigen::Affine3f& camera_T_cloud,
                               StereoFeatures& features);

} // namespace planar_grid
