// SPDX-License-Identifier: BSD-3-Clause
#include "mapping_error_oracle.h"

#include <Eigen/SVD>

#include <algorithm>
#include <cmath>
#include <set>
#include <tuple>

namespace planar_grid {
namespace test {

double
oracleDistance(const OracleBox& box, const Eigen::Vector3d& p)
{
  Eigen::Vector3d closest = box.centre;
  for (int k = 0; k < 3; ++k) {
    const double along = (p - box.centre).dot(box.axes.col(k));
    closest += std::clamp(along, -box.half[k], box.half[k]) * box.axes.col(k);
  }
  return (p - closest).norm();
}

OracleBox
oracleVoxel(const VoxelIndex& index, double r)
{
  return {(index.cast<double>().array() + 0.5).matrix() * r,
          Eigen::Matrix3d::Identity(), Eigen::Vector3d::Constant(0.5 * r)};
}

OracleBox
oracleCuboid(const PlanarCuboid& c)
{
  OracleBox box;
  box.centre = c.centre.cast<double>();
  box.axes.col(0) = c.horizontal_axis.cast<double>();
  box.axes.col(1) = c.verticalAxis().cast<double>();
  box.axes.col(2) = c.normal.cast<double>();
  box.half = 0.5 * Eigen::Vector3d(c.width_m, c.height_m, c.thickness_m);
  return box;
}

OracleTruth
oracleTruth(const pcl::PointCloud<pcl::PointXYZ>& points, double r)
{
  std::set<std::tuple<int, int, int>> unique;
  for (const auto& p : points.points)
    unique.emplace(static_cast<int>(std::floor(static_cast<double>(p.x) / r)),
                   static_cast<int>(std::floor(static_cast<double>(p.y) / r)),
                   static_cast<int>(std::floor(static_cast<double>(p.z) / r)));
  OracleTruth out;
  for (const auto& [x, y, z] : unique)
    out.voxels.emplace_back(x, y, z);
  const auto centre = [r](const VoxelIndex& v) {
    return Eigen::Vector3d((v.cast<double>().array() + 0.5).matrix() * r);
  };
  for (const VoxelIndex& v : out.voxels) {
    const Eigen::Vector3d c = centre(v);
    double lowest = c.z();
    for (const VoxelIndex& w : out.voxels) {
      const Eigen::Vector3d d = centre(w);
      if (std::floor(d.x()) == std::floor(c.x())
          && std::floor(d.y()) == std::floor(c.y()))
        lowest = std::min(lowest, d.z());
    }
    out.ground.push_back(c.z() - lowest <= 0.3 + 1e-6);
  }
  return out;
}

Completeness
oracleCompleteness(const OracleTruth& truth,
                   double r,
                   const std::vector<OracleBox>& boxes,
                   double tolerance_m,
                   const MappingErrorRegion& region,
                   bool nonground_only)
{
  Completeness out;
  for (std::size_t i = 0; i < truth.voxels.size(); ++i) {
    const Eigen::Vector3d c =
      (truth.voxels[i].cast<double>().array() + 0.5).matrix() * r;
    if ((nonground_only && truth.ground[i]) || !region.contains(c.cast<float>()))
      continue;
    ++out.truth_voxels;
    for (const auto& box : boxes)
      if (oracleDistance(box, c) <= tolerance_m) {
        ++out.covered;
        break;
      }
  }
  return out;
}

std::vector<OracleBox>
oracleCuboids(const PlanarCuboids& cuboids, bool planar_only)
{
  std::vector<OracleBox> out;
  for (const auto& c : cuboids)
    if (c.probability >= 0.5f && (!planar_only || c.is_planar))
      out.push_back(oracleCuboid(c));
  return out;
}

PlanePrecision
oraclePlanePrecision(const pcl::PointCloud<pcl::PointXYZ>& truth,
                     const PlanarCuboids& cuboids,
                     double r,
                     const MappingErrorRegion& region)
{
  const double first_radius =
    std::max(2.0 * r, planar_grid::PLANE_PRECISION_MIN_RADIUS_M);
  const double max_radius = planar_grid::PLANE_PRECISION_MAX_RADIUS_M;
  const double min_cos = std::cos(20.0 * M_PI / 180.0);
  PlanePrecision out;
  for (const auto& c : cuboids) {
    if (!c.is_planar || c.probability < 0.5f)
      continue;
    const int nu = std::max(1, static_cast<int>(std::ceil(c.width_m / r - 1e-3)));
    const int nv = std::max(1, static_cast<int>(std::ceil(c.height_m / r - 1e-3)));
    const double area = static_cast<double>(c.width_m) * c.height_m / (nu * nv);
    const Eigen::Vector3d face =
      c.centre.cast<double>()
      + 0.5 * static_cast<double>(c.thickness_m) * c.normal.cast<double>();
    for (int j = 0; j < nv; ++j)
      for (int i = 0; i < nu; ++i) {
        const Eigen::Vector3f sample =
          (face + ((i + 0.5) / nu - 0.5) * c.width_m * c.horizontal_axis.cast<double>()
           + ((j + 0.5) / nv - 0.5) * c.height_m * c.verticalAxis().cast<double>())
            .cast<float>();
        if (!region.contains(sample))
          continue;
        ++out.samples;
        out.face_area_m2 += area;
        // 0: no truth, 1: not a surface, 2: a surface (normal set)
        int found = 1;
        Eigen::Vector3d normal = Eigen::Vector3d::Zero();
        for (double radius = first_radius;
             found == 1 && radius <= std::max(first_radius, max_radius);
             radius *= 2.0) {
          std::vector<Eigen::Vector3d> near;
          for (const auto& p : truth.points)
            if ((p.getVector3fMap().cast<double>() - sample.cast<double>())
                  .squaredNorm()
                <= radius * radius)
              near.push_back(p.getVector3fMap().cast<double>());
          if (near.size() < 5) {
            // only the first neighbourhood decides that there is no truth
            found = radius == first_radius ? 0 : 1;
            break;
          }
          Eigen::MatrixXd centred(static_cast<Eigen::Index>(near.size()), 3);
          Eigen::Vector3d mean = Eigen::Vector3d::Zero();
          for (const auto& p : near)
            mean += p / static_cast<double>(near.size());
          for (std::size_t k = 0; k < near.size(); ++k)
            centred.row(static_cast<Eigen::Index>(k)) = (near[k] - mean).transpose();
          // Singular values come in decreasing order: s(0) >= s(1) >= s(2).
          const Eigen::JacobiSVD<Eigen::MatrixXd> svd(centred, Eigen::ComputeThinV);
          const Eigen::Vector3d s = svd.singularValues();
          if (s(1) * s(1) > 1e-6 * s(0) * s(0)
              && s(2) * s(2)
                   < planar_grid::PLANE_PRECISION_MAX_EIGENVALUE_RATIO * s(1) * s(1)) {
            found = 2;
            normal = svd.matrixV().col(2);
          }
        }
        if (found == 0) {
          out.no_truth_area_m2 += area;
        } else if (found == 1) {
          out.not_surface_area_m2 += area;
        } else if (std::abs(normal.dot(c.normal.cast<double>().normalized()))
                   >= min_cos) {
          ++out.precise_samples;
          out.precise_area_m2 += area;
        } else {
          out.misoriented_area_m2 += area;
        }
      }
  }
  return out;
}

} // namespace test
} // namespace planar_grid
