// SPDX-License-Identifier: BSD-3-Clause
// The plane precision of a map's planar cells: samples of their faces, and whether the
// truth around each is a surface of the cell's orientation.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>

#include <pcl/console/print.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>

#include "mapping_error_impl.h"

namespace planar_grid {

namespace {

/** \brief Smallest ratio of the middle to the largest eigenvalue of a neighbourhood's
 * covariance for its points to span a surface rather than a line. */
constexpr double MIN_MIDDLE_EIGENVALUE_RATIO = 1e-6;

/** \brief What the truth around a face sample is. */
enum class TruthSurface { NONE, NOT_A_SURFACE, SURFACE };

/** \brief The unit PCA normal of the truth points \a indices (the eigenvector of the
 * smallest eigenvalue of their covariance) with SURFACE; NONE when they are too few,
 * NOT_A_SURFACE when they do not form a surface (on a line, or the smallest eigenvalue
 * not clearly below the middle one). */
TruthSurface
surfaceNormal(const GroundTruthSurface::PointCloud& points,
              const pcl::Indices& indices,
              Eigen::Vector3d& normal)
{
  if (indices.size() < PLANE_PRECISION_MIN_POINTS)
    return TruthSurface::NONE;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto i : indices)
    mean += points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>();
  mean /= static_cast<double>(indices.size());
  Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
  for (const auto i : indices) {
    const Eigen::Vector3d d =
      points[static_cast<std::size_t>(i)].getVector3fMap().cast<double>() - mean;
    covariance += d * d.transpose();
  }
  covariance /= static_cast<double>(indices.size());
  // Eigen sorts the eigenvalues of a self-adjoint matrix in increasing order.
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() != Eigen::Success)
    return TruthSurface::NOT_A_SURFACE;
  const Eigen::Vector3d& eigenvalues = solver.eigenvalues();
  // Points on a line leave the two smaller eigenvalues at rounding noise, whose ratio
  // means nothing: the middle one must be a real spread next to the largest.
  if (!(eigenvalues(1) > MIN_MIDDLE_EIGENVALUE_RATIO * eigenvalues(2))
      || !(eigenvalues(0) < PLANE_PRECISION_MAX_EIGENVALUE_RATIO * eigenvalues(1)))
    return TruthSurface::NOT_A_SURFACE;
  normal = solver.eigenvectors().col(0);
  return TruthSurface::SURFACE;
}

} // namespace

PlanePrecision
evaluatePlanePrecision(const PlanarCuboids& cuboids,
                       double occupancy_thres,
                       double resolution_m,
                       const GroundTruthSurface& truth,
                       const MappingErrorRegion& region)
{
  detail::checkResolution(resolution_m);
  if (!(occupancy_thres >= 0.0 && occupancy_thres <= 1.0))
    throw Exception("evaluatePlanePrecision: occupancy_thres must be a probability in "
                    "[0, 1], got "
                    + std::to_string(occupancy_thres));
  const double radius_m = std::max(2.0 * resolution_m, PLANE_PRECISION_MIN_RADIUS_M);
  const double max_radius_m = std::max(radius_m, PLANE_PRECISION_MAX_RADIUS_M);
  const double min_cos = std::cos(PLANE_PRECISION_MAX_ANGLE_DEG * M_PI / 180.0);
  const GroundTruthSurface::PointCloudConstPtr points = truth.getPoints();
  PlanePrecision precision;
  pcl::Indices indices;
  std::size_t skipped = 0;
  for (const auto& c : cuboids) {
    if (!c.is_planar || !(static_cast<double>(c.probability) >= occupancy_thres))
      continue;
    const std::int64_t nu = detail::samplesAlong(c.width_m, resolution_m);
    const std::int64_t nv = detail::samplesAlong(c.height_m, resolution_m);
    if (nu == 0 || nv == 0 || !c.centre.allFinite() || !c.normal.allFinite()
        || !c.horizontal_axis.allFinite() || !std::isfinite(c.thickness_m)
        || static_cast<double>(nu) * static_cast<double>(nv) > 1e9) {
      ++skipped;
      continue;
    }
    const Eigen::Vector3d u = c.horizontal_axis.cast<double>();
    const Eigen::Vector3d v = c.verticalAxis().cast<double>();
    const Eigen::Vector3d face_centre = c.faceCentre().cast<double>();
    const Eigen::Vector3d cell_normal = c.normal.cast<double>().normalized();
    const double w = c.width_m, h = c.height_m;
    const double sample_area_m2 =
      w * h / (static_cast<double>(nu) * static_cast<double>(nv));
    for (std::int64_t j = 0; j < nv; ++j) {
      const double ov = detail::sampleOffset(j, nv, h);
      for (std::int64_t i = 0; i < nu; ++i) {
        const double ou = detail::sampleOffset(i, nu, w);
        const Eigen::Vector3f sample = (face_centre + ou * u + ov * v).cast<float>();
        if (!region.contains(sample))
          continue;
        ++precision.samples;
        precision.face_area_m2 += sample_area_m2;
        // A stereo reference is as thick as its depth noise: where its points do not
        // form a surface in the first neighbourhood, wider ones (doubling) are asked
        // before the sample is called not a surface.
        Eigen::Vector3d normal;
        truth.radiusSearch(sample, radius_m, indices);
        TruthSurface found = surfaceNormal(*points, indices, normal);
        for (double wider_m = 2.0 * radius_m;
             found == TruthSurface::NOT_A_SURFACE && wider_m <= max_radius_m;
             wider_m *= 2.0) {
          truth.radiusSearch(sample, wider_m, indices);
          found = surfaceNormal(*points, indices, normal);
        }
        switch (found) {
          case TruthSurface::NONE:
            precision.no_truth_area_m2 += sample_area_m2;
            break;
          case TruthSurface::NOT_A_SURFACE:
            precision.not_surface_area_m2 += sample_area_m2;
            break;
          case TruthSurface::SURFACE:
            if (std::abs(normal.dot(cell_normal)) >= min_cos) {
              ++precision.precise_samples;
              precision.precise_area_m2 += sample_area_m2;
            } else {
              precision.misoriented_area_m2 += sample_area_m2;
            }
            break;
        }
      }
    }
  }
  if (skipped > 0)
    PCL_WARN("[planar_grid::evaluatePlanePrecision] %zu planar cuboids with non-finite "
             "fields or more than 1e9 face samples skipped.\n",
             skipped);
  return precision;
}

} // namespace planar_grid
