// SPDX-License-Identifier: BSD-3-Clause
// FastStatisticalOutlierRemoval's template body: compiled into planar_grid_filters for
// the point types of PLANAR_GRID_POINT_TYPES, and included by
// fast_statistical_outlier_removal.h for any other point type when PCL_NO_PRECOMPILE is
// defined (as PCL's own impl/*.hpp). The neighbour search itself is not a template.
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <string>
#include <vector>

namespace planar_grid {
namespace detail {

/** \brief The mean distance of each queried point to its \a mean_k nearest other
 * points, exactly as a kd-tree over all the points finds them.
 * \param[in] xyz the points, x, y, z packed (3 n floats, finite), meters
 * \param[in] queried n flags: the points whose mean distance is wanted
 * \param[in] mean_k the number of neighbours (>= 1)
 * \param[out] mean_distance n values, meters; 0 for the points not queried, and for
 * every point when there are no more than mean_k + 1 points
 * Defined in planar_grid_filters (nanoflann's kd-tree and a cell search). */
void meanNeighbourDistances(const std::vector<float>& xyz,
                            const std::vector<char>& queried,
                            int mean_k,
                            std::vector<float>& mean_distance);

} // namespace detail

template <typename PointT>
void
FastStatisticalOutlierRemoval<PointT>::applyFilter(pcl::Indices& indices)
{
  if (!fast_statistical_outlier_removal_ranges::MEAN_K.contains(params_.mean_k))
    throw Exception(
      "FastStatisticalOutlierRemoval: "
      + paramRangeMessage("mean_k", fast_statistical_outlier_removal_ranges::MEAN_K)
      + ", got " + std::to_string(params_.mean_k));
  if (!std::isfinite(params_.stddev_mul_thresh))
    throw Exception(
      "FastStatisticalOutlierRemoval: stddev_mul_thresh must be finite, got "
      + std::to_string(params_.stddev_mul_thresh));
  const auto& cloud = *this->input_;
  const pcl::Indices& input_indices = *this->indices_;
  // Every finite point of the cloud is searched, as by PCL's searcher; packed in
  // cloud order, so that the answers are those of the cloud itself.
  constexpr std::uint32_t NOT_FINITE = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> packed_of(cloud.size(), NOT_FINITE);
  std::vector<float> xyz;
  xyz.reserve(3 * cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const PointT& p = cloud[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    packed_of[i] = static_cast<std::uint32_t>(xyz.size() / 3);
    xyz.insert(xyz.end(), {p.x, p.y, p.z});
  }
  const std::size_t n_packed = xyz.size() / 3;

  std::vector<char> queried(n_packed, 0);
  for (const auto index : input_indices)
    if (packed_of[static_cast<std::size_t>(index)] != NOT_FINITE)
      queried[packed_of[static_cast<std::size_t>(index)]] = 1;
  std::vector<float> mean_distance;
  detail::meanNeighbourDistances(xyz, queried, params_.mean_k, mean_distance);

  std::vector<float> distances(input_indices.size(), 0.0f);
  int valid_distances = 0;
  for (std::size_t i = 0; i < input_indices.size(); ++i) {
    const std::uint32_t j = packed_of[static_cast<std::size_t>(input_indices[i])];
    if (j == NOT_FINITE)
      continue;
    distances[i] = mean_distance[j];
    ++valid_distances;
  }

  // The mean and standard deviation of the mean distances, with PCL's formulas (the
  // non-finite points add 0 to the sums but do not count).
  double sum = 0.0, sq_sum = 0.0;
  for (const float d : distances) {
    sum += d;
    sq_sum += d * d;
  }
  const double mean = sum / static_cast<double>(valid_distances);
  const double variance = (sq_sum - sum * sum / static_cast<double>(valid_distances))
                          / (static_cast<double>(valid_distances) - 1.0);
  const double threshold = mean + params_.stddev_mul_thresh * std::sqrt(variance);

  indices.clear();
  indices.reserve(input_indices.size());
  auto& removed = *this->removed_indices_;
  removed.clear();
  for (std::size_t i = 0; i < input_indices.size(); ++i) {
    const bool outlier = distances[i] > threshold;
    if (outlier != this->negative_) {
      if (this->extract_removed_indices_)
        removed.push_back(input_indices[i]);
      continue;
    }
    indices.push_back(input_indices[i]);
  }
}

} // namespace planar_grid
