// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>

#include <pcl/point_types.h>

#include <cmath>
#include <cstdint>
#include <nanoflann.hpp>
#include <vector>

namespace planar_grid {

namespace {

/** nanoflann's view of the finite points of a cloud (x, y, z). */
template <typename PointT> struct CloudAdaptor {
  const pcl::PointCloud<PointT>& cloud;
  const std::vector<std::uint32_t>& finite;

  std::size_t kdtree_get_point_count() const { return finite.size(); }
  float kdtree_get_pt(std::size_t i, std::size_t dim) const
  {
    const PointT& p = cloud[finite[i]];
    return dim == 0 ? p.x : (dim == 1 ? p.y : p.z);
  }
  template <typename BoundingBox> bool kdtree_get_bbox(BoundingBox&) const
  {
    return false;
  }
};

} // namespace

template <typename PointT>
void
FastStatisticalOutlierRemoval<PointT>::applyFilter(pcl::Indices& indices)
{
  if (mean_k_ < 1)
    throw Exception("FastStatisticalOutlierRemoval: mean_k must be >= 1, got "
                    + std::to_string(mean_k_));
  const auto& cloud = *this->input_;
  const pcl::Indices& input_indices = *this->indices_;
  std::vector<std::uint32_t> finite;
  finite.reserve(cloud.size());
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (std::isfinite(cloud[i].x) && std::isfinite(cloud[i].y)
        && std::isfinite(cloud[i].z))
      finite.push_back(static_cast<std::uint32_t>(i));

  using Adaptor = CloudAdaptor<PointT>;
  using Tree =
    nanoflann::KDTreeSingleIndexAdaptor<nanoflann::L2_Simple_Adaptor<float, Adaptor>,
                                        Adaptor, 3, std::uint32_t>;
  const Adaptor adaptor{cloud, finite};
  const Tree tree(3, adaptor, nanoflann::KDTreeSingleIndexAdaptorParams(10));

  // One more neighbour than mean_k: the query point is its own nearest neighbour.
  const auto k = static_cast<std::size_t>(mean_k_) + 1;
  std::vector<std::uint32_t> nn_indices(k);
  std::vector<float> nn_dists(k);
  std::vector<float> distances(input_indices.size(), 0.0f);
  int valid_distances = 0;
  for (std::size_t i = 0; i < input_indices.size(); ++i) {
    const PointT& p = cloud[input_indices[i]];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const float query[3] = {p.x, p.y, p.z};
    nanoflann::KNNResultSet<float, std::uint32_t> result(k);
    result.init(nn_indices.data(), nn_dists.data());
    tree.findNeighbors(result, query, nanoflann::SearchParams());
    const std::size_t found = result.size();
    if (found == 0)
      continue;
    double dist_sum = 0.0;
    for (std::size_t j = 1; j < found; ++j)
      dist_sum += std::sqrt(nn_dists[j]);
    distances[i] = static_cast<float>(dist_sum / mean_k_);
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
  const double threshold = mean + std_mul_ * std::sqrt(variance);

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

template class planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ>;
template class planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZI>;
template class planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZRGB>;
