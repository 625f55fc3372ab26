// SPDX-License-Identifier: BSD-3-Clause
// The brute-force oracle of the planner queries' tests: distances and overlaps against
// every obstacle box, in double precision. It is the reference, not code under test:
// the sanitizer build compiles it optimised and uninstrumented
// (tests/map/CMakeLists.txt).
#pragma once

#include <Eigen/Core>

#include <utility>
#include <vector>

namespace planar_grid {
namespace test {

/** \brief An oriented box: the columns of \a axes are its unit axes, \a half its half
 * extents along them (m). */
struct OracleBox {
  Eigen::Matrix3d axes;
  Eigen::Vector3d centre;
  Eigen::Vector3d half;
};

/** \brief Distance (m) from \a p to box \a b, 0 inside; \a grad the unit gradient
 * outside, zero inside. */
double
oracleDistance(const OracleBox& b, const Eigen::Vector3d& p, Eigen::Vector3d& grad);

/** \brief The smallest distance (m) from \a p to any of \a boxes, at most \a cap; every
 * box closer than the running smallest plus \a tolerance is appended to \a near as
 * (distance, gradient). */
double oracleNearest(const std::vector<OracleBox>& boxes,
                     const Eigen::Vector3d& p,
                     double cap,
                     double tolerance,
                     std::vector<std::pair<double, Eigen::Vector3d>>& near);

/** \brief The smallest separation (m) of the box (rotation \a ra, centre \a ca, half
 * extents \a ha) from \a boxes by separating axes over the corners' projections: > 0
 * apart, <= 0 overlapping; +infinity when every box's bounding box is farther than \a
 * skip (m) from the body's. */
double oracleBoxMargin(const std::vector<OracleBox>& boxes,
                       const Eigen::Matrix3d& ra,
                       const Eigen::Vector3d& ca,
                       const Eigen::Vector3d& ha,
                       double skip);

/** \brief The smallest distance (m) from the sphere (centre \a c, radius \a radius) to
 * \a boxes, negative overlapping; +infinity as oracleBoxMargin(). */
double oracleSphereMargin(const std::vector<OracleBox>& boxes,
                          const Eigen::Vector3d& c,
                          double radius,
                          double skip);

} // namespace test
} // namespace planar_grid
