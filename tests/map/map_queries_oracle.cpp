// SPDX-License-Identifier: BSD-3-Clause
#include "map_queries_oracle.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <limits>

namespace planar_grid {
namespace test {

double
oracleDistance(const OracleBox& b, const Eigen::Vector3d& p, Eigen::Vector3d& grad)
{
  const Eigen::Vector3d q = b.axes.transpose() * (p - b.centre);
  const Eigen::Vector3d closest = q.cwiseMax(-b.half).cwiseMin(b.half);
  const Eigen::Vector3d e = q - closest;
  const double d = e.norm();
  grad = d > 0.0 ? Eigen::Vector3d(b.axes * e / d) : Eigen::Vector3d::Zero();
  return d;
}

double
oracleNearest(const std::vector<OracleBox>& boxes,
              const Eigen::Vector3d& p,
              double cap,
              double tolerance,
              std::vector<std::pair<double, Eigen::Vector3d>>& near)
{
  double best = cap;
  for (const auto& b : boxes) {
    Eigen::Vector3d g;
    const double d = oracleDistance(b, p, g);
    if (d < best + tolerance)
      near.emplace_back(d, g);
    best = std::min(best, d);
  }
  return best;
}

namespace {

// Separating axes from the corners' projections (a formulation apart from the one in
// the library, which works in the frame of the body). Returns the largest gap over the
// axes: > 0 separated, <= 0 overlapping.
double
oracleGap(const Eigen::Matrix3d& ra,
          const Eigen::Vector3d& ca,
          const Eigen::Vector3d& ha,
          const OracleBox& b)
{
  std::vector<Eigen::Vector3d> axes;
  for (int i = 0; i < 3; ++i) {
    axes.push_back(ra.col(i));
    axes.push_back(b.axes.col(i));
  }
  for (int i = 0; i < 3; ++i)
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d c = ra.col(i).cross(b.axes.col(j));
      if (c.norm() > 1e-9)
        axes.push_back(c.normalized());
    }
  const auto corners = [](const Eigen::Matrix3d& r, const Eigen::Vector3d& c,
                          const Eigen::Vector3d& h) {
    std::vector<Eigen::Vector3d> out;
    for (int k = 0; k < 8; ++k)
      out.push_back(c
                    + r
                        * Eigen::Vector3d((k & 1) ? h.x() : -h.x(),
                                          (k & 2) ? h.y() : -h.y(),
                                          (k & 4) ? h.z() : -h.z()));
    return out;
  };
  const auto pa = corners(ra, ca, ha), pb = corners(b.axes, b.centre, b.half);
  double gap = -std::numeric_limits<double>::infinity();
  for (const auto& axis : axes) {
    double amin = 1e30, amax = -1e30, bmin = 1e30, bmax = -1e30;
    for (const auto& p : pa) {
      amin = std::min(amin, p.dot(axis));
      amax = std::max(amax, p.dot(axis));
    }
    for (const auto& p : pb) {
      bmin = std::min(bmin, p.dot(axis));
      bmax = std::max(bmax, p.dot(axis));
    }
    gap = std::max(gap, std::max(bmin - amax, amin - bmax));
  }
  return gap;
}

/** Bounding boxes apart by more than \a skip: the bodies are apart too. */
bool
apart(const OracleBox& b,
      const Eigen::Vector3d& c,
      const Eigen::Vector3d& reach,
      double skip)
{
  const Eigen::Vector3d b_reach = b.axes.cwiseAbs() * b.half;
  return ((c - b.centre).cwiseAbs() - reach - b_reach).maxCoeff() > skip;
}

} // namespace

double
oracleBoxMargin(const std::vector<OracleBox>& boxes,
                const Eigen::Matrix3d& ra,
                const Eigen::Vector3d& ca,
                const Eigen::Vector3d& ha,
                double skip)
{
  const Eigen::Vector3d reach = ra.cwiseAbs() * ha;
  double margin = std::numeric_limits<double>::infinity();
  for (const auto& b : boxes)
    if (!apart(b, ca, reach, skip))
      margin = std::min(margin, oracleGap(ra, ca, ha, b));
  return margin;
}

double
oracleSphereMargin(const std::vector<OracleBox>& boxes,
                   const Eigen::Vector3d& c,
                   double radius,
                   double skip)
{
  const Eigen::Vector3d reach = Eigen::Vector3d::Constant(radius);
  double margin = std::numeric_limits<double>::infinity();
  for (const auto& b : boxes)
    if (!apart(b, c, reach, skip)) {
      Eigen::Vector3d g;
      margin = std::min(margin, oracleDistance(b, c, g) - radius);
    }
  return margin;
}

} // namespace test
} // namespace planar_grid
