// SPDX-License-Identifier: BSD-3-Clause
// The template bodies of SACMultiPlaneSegmentation's tests of a hypothesis (the normal
// agreement, the sensor plane, visibility, shell and cluster tests), the merge of
// near-duplicate planes and their description (eqs. 2-3); included at the end of
// sac_multi_plane_segmentation.hpp, whose constants they use.
#pragma once

#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp>

#include <pcl/common/centroid.h>
#include <pcl/common/eigen.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace planar_grid {

template <typename PointT>
bool
SACMultiPlaneSegmentation<PointT>::passesNormalAgreement(detail::DensePoints& dense,
                                                         const Eigen::Vector4f& plane,
                                                         float d_t)
{
  // Over the eq. 11 support by distance alone, the points with a normal that agree
  // against all those with a normal: points without one (too few neighbours to
  // tell) are no evidence either way. The normal test then leaves the mask on the
  // plane's inliers.
  const std::size_t support = dense.selectInliersByDistance(plane, d_t);
  const std::size_t known = support - dense.countSelectedWithoutNormal();
  const std::size_t disagreeing = dense.deselectOffNormal(plane);
  const std::size_t agreeing = known - disagreeing;
  if (known == 0
      || static_cast<double>(agreeing)
           >= params_.min_normal_agreement * static_cast<double>(known)) {
    counts_.normal_removed += disagreeing;
    return true;
  }
  PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane whose support scatters in "
            "normal (%zu of %zu agree).\n",
            getClassName().c_str(), agreeing, known);
  // The support that disagrees would only give the same plane again: it leaves the
  // search (it stays for the non-planar cells); the points that agree or have no
  // normal stay for the planes they may lie on.
  dense.selectInliersByDistance(plane, d_t);
  dense.deselectOffNormal(plane, /*keep_off_normal=*/true);
  dense.removeSelected();
  return false;
}

template <typename PointT>
bool
SACMultiPlaneSegmentation<PointT>::passesPlaneTests(detail::DensePoints& dense,
                                                    const detail::DensePoints& all,
                                                    const Eigen::Vector4f& plane,
                                                    const Eigen::Vector3f& origin,
                                                    float d_t,
                                                    std::size_t& count)
{
  if (static_cast<int>(supportCount(dense, count)) < params_.min_inliers) {
    PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane with %zu < %d inliers.\n",
              getClassName().c_str(), count, params_.min_inliers);
    return false;
  }
  if (params_.min_sensor_distance_m > 0.0) {
    const std::size_t removed = detail::removeSensorPlane(
      dense, plane, origin, static_cast<float>(params_.min_sensor_distance_m));
    if (removed > 0) {
      PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane passing within %g m of "
                "the sensor (%zu inliers).\n",
                getClassName().c_str(), params_.min_sensor_distance_m, removed);
      counts_.sensor_plane_removed += removed;
      ++counts_.sensor_plane_rejected;
      return false;
    }
  }
  if (params_.max_visibility_conflict_ratio > 0.0) {
    const std::size_t removed = detail::removeVisibilityConflicts(
      dense, all, d_t, plane, origin, static_cast<float>(params_.visibility_margin_m),
      static_cast<float>(params_.visibility_cell_m),
      params_.max_visibility_conflict_ratio);
    counts_.visibility_removed += removed;
    count -= removed;
    if (static_cast<int>(supportCount(dense, count)) < params_.min_inliers) {
      PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane with visibility "
                "conflicts at %zu of its inliers (%zu left).\n",
                getClassName().c_str(), removed, count);
      ++counts_.visibility_rejected;
      return false;
    }
  }
  if (params_.max_shell_ratio > 0.0) {
    const std::size_t removed = detail::removeShellCells(
      dense, all, d_t, plane, static_cast<float>(params_.shell_width_m),
      static_cast<float>(params_.visibility_cell_m), params_.max_shell_ratio);
    counts_.shell_removed += removed;
    count -= removed;
    if (static_cast<int>(supportCount(dense, count)) < params_.min_inliers) {
      PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane with points beyond its "
                "threshold at %zu of its inliers (%zu left).\n",
                getClassName().c_str(), removed, count);
      ++counts_.shell_rejected;
      return false;
    }
  }
  // Terrain (DensePoints::isTerrain(): level, far enough below the sensor, nothing
  // under it) is spared, as by the normal test: the layers of a noisy road fall apart
  // into clusters, and the terrain removal takes them out whole. Asked only when the
  // test runs: the floor test passes over the frame's points.
  if (params_.min_cluster_size > 0 && !dense.isTerrain(plane)) {
    const std::size_t removed = detail::removeSmallClusters(
      dense, plane, static_cast<float>(params_.cluster_cell_m),
      static_cast<std::size_t>(params_.min_cluster_size));
    counts_.cluster_removed += removed;
    count -= removed;
    if (static_cast<int>(supportCount(dense, count)) < params_.min_inliers) {
      PCL_DEBUG("[planar_grid::%s::segment] Dropped a plane whose footprint falls "
                "apart into clusters of < %d inliers (%zu left).\n",
                getClassName().c_str(), params_.min_cluster_size, count);
      ++counts_.cluster_rejected;
      // The fragments would give the same plane again: they leave the search.
      dense.selectInliers(plane, d_t);
      dense.removeSelected();
      return false;
    }
  }
  return true;
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::mergeDuplicatePlanes(
  PlanarSegments& planes,
  const Eigen::Vector3f& origin) const
{
  const double cos_eps = std::cos(params_.merge_angle_rad);
  bool merged = true;
  while (merged) {
    merged = false;
    for (std::size_t i = 0; i < planes.size() && !merged; ++i) {
      for (std::size_t j = i + 1; j < planes.size() && !merged; ++j) {
        const auto& ci = planes[i].model_coefficients.values;
        const auto& cj = planes[j].model_coefficients.values;
        const double dot = ci[0] * cj[0] + ci[1] * cj[1] + ci[2] * cj[2];
        const double d_j = dot < 0.0 ? -cj[3] : cj[3];
        if (std::abs(dot) < cos_eps || std::abs(ci[3] - d_j) > params_.merge_distance_m)
          continue;
        PlanarSegment& a = planes[i];
        PlanarSegment& b = planes[j];
        auto& ind = a.inliers.indices;
        ind.insert(ind.end(), b.inliers.indices.begin(), b.inliers.indices.end());
        Eigen::Vector4f refit, centroid;
        if (params_.optimize_coefficients
            && detail::fitPlanePCA(*input_, ind, refit, centroid)) {
          detail::orientTowards(refit, origin);
          a.model_coefficients.values.assign(refit.data(), refit.data() + 4);
        } else if (b.inliers.indices.size() > ind.size() - b.inliers.indices.size()) {
          a.model_coefficients.values = b.model_coefficients.values;
        }
        a.sample_inliers += b.sample_inliers;
        planes.erase(planes.begin() + static_cast<std::ptrdiff_t>(j));
        merged = true;
      }
    }
  }
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::describePlanes(PlanarSegments& planes,
                                                  const Eigen::Vector3f& up) const
{
  for (auto& segment : planes) {
    auto& ind = segment.inliers.indices;
    std::sort(ind.begin(), ind.end());
    pcl::compute3DCentroid(*input_, ind, segment.centroid);
    segment.centroid[3] = 1.0f;
    const auto& c = segment.model_coefficients.values;
    const Eigen::Vector3f normal(c[0], c[1], c[2]);
    // Eq. 2 with the up axis in place of z: c_i = n . up (|n| = 1).
    const double c_up = std::max(-1.0f, std::min(1.0f, normal.dot(up)));
    segment.tilt_rad = std::acos(c_up);
    // Eq. 3: theta for c > 0, theta - pi for c < 0, pi/2 for a vertical plane.
    if (c_up > 0.0)
      segment.normalized_tilt_rad = segment.tilt_rad;
    else if (c_up < 0.0)
      segment.normalized_tilt_rad = segment.tilt_rad - M_PI;
    else
      segment.normalized_tilt_rad = M_PI / 2.0;
    segment.model_coefficients.header = input_->header;
    segment.inliers.header = input_->header;
  }
  std::stable_sort(planes.begin(), planes.end(),
                   [](const PlanarSegment& l, const PlanarSegment& r) {
                     return l.inliers.indices.size() > r.inliers.indices.size();
                   });
}

} // namespace planar_grid
