// SPDX-License-Identifier: BSD-3-Clause
// The planes SACMultiPlaneSegmentation finds (PlanarSegment, PlanarSegments) and the
// ground candidate test on them.
#pragma once

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/pcl_macros.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <vector>

namespace planar_grid {

/** \brief One plane found by SACMultiPlaneSegmentation, on the pattern of
 * pcl::PlanarRegion. \ingroup segmentation */
struct PlanarSegment {
  /** \brief [a, b, c, d] of eq. 1 with (a, b, c) a unit normal and d in meters; the
   * normal points toward the input cloud's sensor origin (a o_x + b o_y + c o_z + d
   * >= 0; for the default origin (0,0,0) this is d >= 0). */
  pcl::ModelCoefficients model_coefficients;
  /** \brief Dense inliers: indices into the input cloud of the points whose eq. 11
   * distance to the plane is <= the distance threshold (and that no earlier plane
   * took), sorted ascending. A plane merged from near-duplicates holds the union of
   * their inliers, each within d_T of one of the merged planes but not necessarily of
   * the refitted one. */
  pcl::PointIndices inliers;
  /** \brief Centroid of the dense inliers (x, y, z, 1), in meters. */
  Eigen::Vector4f centroid{Eigen::Vector4f::Zero()};
  /** \brief theta of eq. 2: angle between the normal and the up axis, in radians,
   * in [0, pi]. 0 for a floor, pi/2 for a wall. */
  double tilt_rad{0.0};
  /** \brief The normalised tilt of eq. 3, in radians, in (-pi/2, pi/2]: theta when
   * c > 0, theta - pi when c < 0, pi/2 for a vertical plane (c == 0), where c is the
   * normal's component along the up axis. */
  double normalized_tilt_rad{0.0};
  /** \brief Number of sample-cloud points on the plane: the sample consensus inliers,
   * or, when the dense hypothesis was kept, the remaining sample points within the
   * sample distance threshold of the plane. */
  std::size_t sample_inliers{0};

  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief A vector of PlanarSegment with Eigen's aligned allocator (its
 * fixed-size vectorizable members need it in std::vector). */
using PlanarSegments =
  std::vector<PlanarSegment, Eigen::aligned_allocator<PlanarSegment>>;

/** \brief True when the segment is a ground candidate: its normal is within eps_angle
 * of the up axis (either direction). \ingroup segmentation
 * \param[in] segment a plane from SACMultiPlaneSegmentation
 * \param[in] up_axis the up direction (need not be unit length; zero gives false)
 * \param[in] eps_angle_rad the largest angle between the normal and the up axis, in
 * radians, in [0, pi/2] \return whether the plane is near-horizontal */
inline bool
isGroundCandidate(const PlanarSegment& segment,
                  const Eigen::Vector3f& up_axis,
                  double eps_angle_rad)
{
  const auto& c = segment.model_coefficients.values;
  const float up_norm = up_axis.norm();
  if (c.size() != 4 || !(up_norm > 0.0f))
    return false;
  const Eigen::Vector3f normal(c[0], c[1], c[2]);
  const double n_norm = normal.norm();
  if (!(n_norm > 0.0))
    return false;
  const double cos_angle = std::abs(normal.dot(up_axis)) / (n_norm * up_norm);
  return std::acos(std::min(1.0, cos_angle)) <= eps_angle_rad;
}

} // namespace planar_grid
