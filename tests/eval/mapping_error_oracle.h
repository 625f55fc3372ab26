// SPDX-License-Identifier: BSD-3-Clause
// The brute-force oracles of the completeness and planar-share tests. They are the
// reference, not code under test: the sanitizer build compiles them optimised and
// uninstrumented (tests/eval/CMakeLists.txt).
#pragma once

#include <planar_grid/eval/mapping_error.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

#include <vector>

namespace planar_grid {
namespace test {

/** \brief A solid box for the oracle: centre, orthonormal axes, half extents. */
struct OracleBox {
  Eigen::Vector3d centre;
  Eigen::Matrix3d axes; // columns
  Eigen::Vector3d half;
};

/** \brief Euclidean distance (m) from \a p to the solid box, through its closest point
 * (the clamp of \a p into the box). */
double oracleDistance(const OracleBox& box, const Eigen::Vector3d& p);

/** \brief The voxel \a index of edge \a r (m) as a box. */
OracleBox oracleVoxel(const VoxelIndex& index, double r);

/** \brief The cuboid \a c as a box. */
OracleBox oracleCuboid(const PlanarCuboid& c);

/** \brief The oracle's truth voxels: floor(p / r) of every point, and for each the
 * ground flag by brute force over all of them (lowest centre of its 1 m column). */
struct OracleTruth {
  std::vector<VoxelIndex> voxels;
  std::vector<bool> ground;
};

/** \brief The truth voxels of \a points at edge \a r (m). */
OracleTruth oracleTruth(const pcl::PointCloud<pcl::PointXYZ>& points, double r);

/** \brief Brute-force completeness: truth voxels (in the region, non-ground ones only
 * with \a nonground_only) whose centre is within \a tolerance_m of one of \a boxes. */
Completeness oracleCompleteness(const OracleTruth& truth,
                                double r,
                                const std::vector<OracleBox>& boxes,
                                double tolerance_m,
                                const MappingErrorRegion& region = {},
                                bool nonground_only = false);

/** \brief The occupied cuboids (probability >= 0.5; planar ones only with \a
 * planar_only) as boxes. */
std::vector<OracleBox> oracleCuboids(const PlanarCuboids& cuboids, bool planar_only);

/** \brief Brute-force plane precision: the face samples of the occupied planar
 * cuboids (probability >= 0.5) on the lattice of evaluatePlanePrecision(), each
 * precise when the points of \a truth within max(2 r, PLANE_PRECISION_MIN_RADIUS_M)
 * of it (a linear scan) number >= 5 and, in that radius or the first of its doublings
 * up to PLANE_PRECISION_MAX_RADIUS_M where they do, the squared singular values
 * s0 <= s1 <= s2 of their centred matrix satisfy s0 <
 * PLANE_PRECISION_MAX_EIGENVALUE_RATIO s1 and s1 > 1e-6 s2, and the singular vector
 * of s0 is within 20 degrees of the cuboid's normal (either sign); the imprecise area
 * by cause as evaluatePlanePrecision() gives it. */
PlanePrecision oraclePlanePrecision(const pcl::PointCloud<pcl::PointXYZ>& truth,
                                    const PlanarCuboids& cuboids,
                                    double r,
                                    const MappingErrorRegion& region = {});

} // namespace test
} // namespace planar_grid
