// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>

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
  /** \brief Seed of the feature guess's random sampling (std::srand, which
   * pcl::SampleConsensusPrerejective draws from). */
  unsigned seed{0};
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

} // namespace planar_grid
