// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

namespace planar_grid {
namespace detail {

/** \brief pcl::GeneralizedIterativeClosestPoint of \a source onto \a target from \a
 * guess (transformation epsilon 1e-8). \param[in] max_correspondence_distance_m largest
 * correspondence distance, metres (> 0) \param[in] max_iterations most iterations, >= 1
 * \param[out] converged whether PCL reports convergence
 * \return the 4x4 target_T_source transform (metres)
 */
Eigen::Matrix4f
alignGeneralizedICP(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& source,
                    const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& target,
                    const Eigen::Matrix4f& guess,
                    double max_correspondence_distance_m,
                    int max_iterations,
                    bool& converged);

/** \brief pcl::SampleConsensusPrerejective on FPFH correspondences (3 samples, 5
 * nearest features, similarity 0.9, inlier fraction 0.25), with std::rand seeded by \a
 * seed so that the result is reproducible. \param[in] max_iterations RANSAC iterations,
 * >= 1 \param[in] max_correspondence_distance_m inlier distance, metres (> 0)
 * \param[out] transform the 4x4 target_T_source transform found
 * \return whether the alignment converged
 */
bool alignFeatureCorrespondences(
  const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& source,
  const pcl::PointCloud<pcl::FPFHSignature33>::ConstPtr& source_features,
  const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& target,
  const pcl::PointCloud<pcl::FPFHSignature33>::ConstPtr& target_features,
  int max_iterations,
  double max_correspondence_distance_m,
  unsigned seed,
  Eigen::Matrix4f& transform);

} // namespace detail
} // namespace planar_grid
