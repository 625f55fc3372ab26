// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/core/stereo_calibration.h>
#include <planar_grid/pipeline/pinhole_view.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Everything one frame carries through the stages. \ingroup pipeline */
struct Frame {
  /** \brief The working cloud type (intensity = grey value for stereo input). */
  using Cloud = pcl::PointCloud<pcl::PointXYZI>;

  /** \brief Position in the run (0-based). */
  std::size_t sequence_number{0};
  /** \brief Index in the input's file names. */
  int file_index{0};
  /** \brief A name for messages (the left image or PCD file). */
  std::string name;

  /** \brief Rectified left image (stereo input only). */
  cv::Mat left;
  /** \brief Rectified right image (stereo input only). */
  cv::Mat right;
  /** \brief Rectified intrinsics (stereo input only). */
  StereoCalibration calibration;
  /** \brief Disparity in px, CV_32FC1, NaN = invalid (after stereo_disparity). */
  cv::Mat disparity;
  /** \brief Depth-image input (Mapper::integrateDepth()): the depth camera whose
   * pixels the organized `cloud` holds, row by row; width_px 0 for every other input.
   * map_integration's `auto` sensor model then clears free space through this camera
   * instead of casting a ray to every point. */
  PinholeView depth_camera;

  /** \brief The working cloud: in the camera frame (x right, y down, z forward, metres)
   * until transform_to_world, in the world frame after it. */
  Cloud::Ptr cloud;
  /** \brief True once `cloud` is in the world frame. */
  bool cloud_in_world_frame{false};
  /** \brief Point-cloud input only: the working cloud as transform_to_world left it
   * (world frame, meters), before segmentation and ground removal take points out:
   * every measured point, for the map's ray casting (stereo frames give their
   * disparity image instead). Empty before transform_to_world. */
  Cloud::ConstPtr measured_cloud;

  /** \brief Points of `cloud` deeper than this along the camera's optical axis (metres)
   * may only join planes: depth_error_filter keeps them between its two bounds,
   * multi_plane_segmentation lets them extend its planes and drops the ones no plane
   * takes (then resets this to infinity). Infinity: every point may make cells. */
  float inlier_only_depth_m{std::numeric_limits<float>::infinity()};

  /** \brief Points beyond depth_error_filter's bounds that it keeps for
   * range_adaptive_cells (its far_levels > 0): camera frame (x right, y down, z
   * forward, metres), finite. Null or empty: none. Shared by frame copies and never
   * changed in place: multi_plane_segmentation replaces it by the points no plane
   * takes (when depth_error_filter also keeps them in `cloud` for the planes), and
   * range_adaptive_cells by the points it maps (the terrain taken out). */
  Cloud::ConstPtr far_cloud;
  /** \brief The level of each far_cloud point, 1..far_levels: its depth error (eq. 4)
   * is within max_depth_error_m x 2^level, so it is mapped at cells 2^level times the
   * minimum. */
  std::vector<std::uint8_t> far_levels;

  /** \brief Matched 3D key feature points in the camera frame (after feature_matching).
   */
  StereoFeatures features;
  /** \brief Occupancy probability of each feature, in [0, 1] (after
   * kl_occupancy_filter; empty before). */
  std::vector<float> feature_probabilities;
  /** \brief Track id of each feature across frames (after kl_occupancy_filter). */
  std::vector<std::int64_t> feature_track_ids;

  /** \brief Planes of the working cloud, their inliers index `cloud` (after
   * multi_plane_segmentation; ground_removal takes the ground out). */
  PlanarSegments planes;
  /** \brief The frame's cells (after planar_cuboid_approximation), in the cloud's
   * frame; plane_id indexes `planes` (-1 for non-planar cells). */
  PlanarCuboids cuboids;
  /** \brief The ground plane [a, b, c, d] in the cloud's frame, when ground_removal
   * found one; its points are no longer in `cloud`. */
  Eigen::Vector4f ground_coefficients{Eigen::Vector4f::Zero()};
  /** \brief True when ground_coefficients holds a ground plane. */
  bool has_ground{false};

  /** \brief world_T_camera when the input gives poses. */
  Eigen::Isometry3d world_T_camera{Eigen::Isometry3d::Identity()};
  /** \brief True when world_T_camera holds the frame's pose. */
  bool has_pose{false};
  /** \brief The first stage that found no valid point in the cloud (the frame then
   * adds nothing to the map); empty while the frame has points. */
  std::string no_points_stage;

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace planar_grid
