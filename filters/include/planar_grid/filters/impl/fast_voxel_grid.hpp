// SPDX-License-Identifier: BSD-3-Clause
// FastVoxelGrid's template body: compiled into planar_grid_filters for the point types
// of PLANAR_GRID_POINT_TYPES, and included by fast_voxel_grid.h for any other point
// type when PCL_NO_PRECOMPILE is defined (as PCL's own impl/*.hpp).
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_voxel_grid.h>

#include <pcl/common/centroid.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>

#include <algorithm>
#include <boost/sort/spreadsort/integer_sort.hpp>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {

namespace detail {

/** \brief Leaf coordinates of this magnitude and more (2^23) are integers already in
 * single precision; below it, the differences of two voxel coordinates are exact. */
constexpr float EXACT_LIMIT = 8388608.0f;

/** \brief static_cast<int>(std::floor(v)) for |v| < 2^23, without the call to floorf
 * (x86-64 before SSE4.1 has no rounding instruction). */
inline int
floorToInt(float v)
{
  const int t = static_cast<int>(v); // truncation towards zero
  return t - (static_cast<float>(t) > v ? 1 : 0);
}

} // namespace detail

template <typename PointT>
void
FastVoxelGrid<PointT>::applyFilter(PointCloud& output)
{
  for (int d = 0; d < 3; ++d)
    if (!(leaf_size_[d] > 0.0f) || !std::isfinite(leaf_size_[d]))
      throw Exception("FastVoxelGrid: the voxel edge along " + std::string(1, "xyz"[d])
                      + " must be finite and > 0, got " + std::to_string(leaf_size_[d])
                      + " m");
  const PointCloud& cloud = *this->input_;
  const pcl::Indices& indices = *this->indices_;
  output.height = 1;
  output.is_dense = true;

  // One pass over the points: the bounding box of the finite ones (as
  // pcl::getMinMax3D) and their voxels, in index order. The buffers grow to the
  // largest cloud and are never shrunk: each element is written before it is read.
  const Eigen::Array4f inv = inverse_leaf_size_;
  if (voxels_.size() < indices.size())
    voxels_.resize(indices.size());
  detail::PointVoxel* const voxels = voxels_.data();
  std::size_t n = 0;
  Eigen::Array4f min_p = Eigen::Array4f::Constant(std::numeric_limits<float>::max());
  Eigen::Array4f max_p = Eigen::Array4f::Constant(std::numeric_limits<float>::lowest());
  const bool dense = cloud.is_dense;
  bool exact = true;
  for (const auto index : indices) {
    const PointT& p = cloud[static_cast<std::size_t>(index)];
    if (!dense && !pcl::isXYZFinite(p))
      continue;
    const Eigen::Array4f a = p.getArray4fMap();
    min_p = min_p.min(a);
    max_p = max_p.max(a);
    const float sx = p.x * inv[0], sy = p.y * inv[1], sz = p.z * inv[2];
    // Voxels are taken here only within the exact range, where they fit an int;
    // beyond it the grid is too large or the second pass below takes them.
    const bool in_range = std::abs(sx) < detail::EXACT_LIMIT
                          && std::abs(sy) < detail::EXACT_LIMIT
                          && std::abs(sz) < detail::EXACT_LIMIT;
    exact = exact && in_range;
    voxels[n++] =
      in_range
        ? detail::PointVoxel{detail::floorToInt(sx), detail::floorToInt(sy),
                             detail::floorToInt(sz), static_cast<unsigned int>(index)}
        : detail::PointVoxel{0, 0, 0, static_cast<unsigned int>(index)};
  }
  if (n == 0) {
    output.clear();
    output.width = 0;
    return;
  }

  // The grid over the bounding box, as pcl::VoxelGrid sizes and checks it: too large
  // when its voxel count or a voxel coordinate exceeds the int range. The extents are
  // compared one product at a time, so that no product overflows (pcl::VoxelGrid
  // multiplies all three at once in int64, which overflows for huge extents; where it
  // does not, both decide alike).
  constexpr auto INT_RANGE = static_cast<std::int64_t>(std::numeric_limits<int>::max());
  constexpr auto INT_RANGE_F = static_cast<float>(INT_RANGE); // 2^31
  float lowest[3], highest[3]; // the bounding box's first and last voxels
  bool too_large = false;
  std::int64_t voxel_count = 1;
  for (int d = 0; d < 3 && !too_large; ++d) {
    const float extent = (max_p[d] - min_p[d]) * inv[d];
    lowest[d] = std::floor(min_p[d] * inv[d]);
    highest[d] = std::floor(max_p[d] * inv[d]);
    // Not NaN, and below 2^31 (so voxel_count stays below 2^31 * 2^32). The voxel
    // coordinates themselves must fit an int too (pcl::VoxelGrid's cast is undefined
    // beyond).
    too_large = !(extent < INT_RANGE_F) || !(lowest[d] >= -INT_RANGE_F)
                || !(highest[d] < INT_RANGE_F);
    if (!too_large) {
      voxel_count *= static_cast<std::int64_t>(extent) + 1;
      too_large = voxel_count > INT_RANGE;
    }
  }
  if (too_large) {
    PCL_WARN("[pcl::%s::applyFilter] Leaf size is too small for the input dataset. "
             "Integer indices would overflow.\n",
             this->getClassName().c_str());
    output = cloud;
    return;
  }
  int min_b[3], max_b[3];
  for (int d = 0; d < 3; ++d) {
    min_b[d] = static_cast<int>(lowest[d]);
    max_b[d] = static_cast<int>(highest[d]);
  }
  const std::int64_t mul_y = max_b[0] - min_b[0] + 1;
  const std::int64_t mul_z = mul_y * (max_b[1] - min_b[1] + 1);

  // The linear voxel index of every finite point, in index order (pcl::VoxelGrid's
  // int arithmetic, modulo 2^32), then sorted by it. pcl::VoxelGrid subtracts the
  // bounding box's first voxel in single precision, which equals the integer
  // difference below 2^23 (rounding is monotone, so that voxel is the floor of the
  // smallest point's coordinate); beyond, the voxels are taken again its way.
  if (entries_.size() < n)
    entries_.resize(n);
  detail::VoxelEntry* const entries = entries_.data();
  if (exact)
    for (std::size_t j = 0; j < n; ++j) {
      const detail::PointVoxel& v = voxels[j];
      entries[j] = {static_cast<unsigned int>((v.x - min_b[0])
                                              + (v.y - min_b[1]) * mul_y
                                              + (v.z - min_b[2]) * mul_z),
                    v.cloud_point_index};
    }
  else
    for (std::size_t j = 0; j < n; ++j) {
      const PointT& p = cloud[voxels[j].cloud_point_index];
      const auto i0 = static_cast<std::int64_t>(std::floor(p.x * inv[0])
                                                - static_cast<float>(min_b[0]));
      const auto i1 = static_cast<std::int64_t>(std::floor(p.y * inv[1])
                                                - static_cast<float>(min_b[1]));
      const auto i2 = static_cast<std::int64_t>(std::floor(p.z * inv[2])
                                                - static_cast<float>(min_b[2]));
      entries[j] = {static_cast<unsigned int>(i0 + i1 * mul_y + i2 * mul_z),
                    voxels[j].cloud_point_index};
    }
  boost::sort::spreadsort::integer_sort(
    entries, entries + n,
    [](const detail::VoxelEntry& e, unsigned offset) { return e.idx >> offset; });

  // The runs of one voxel index with enough points, then their centroids.
  std::vector<std::pair<unsigned int, unsigned int>>& runs = runs_;
  runs.clear();
  for (std::size_t b = 0; b < n;) {
    std::size_t e = b + 1;
    while (e < n && entries[e].idx == entries[b].idx)
      ++e;
    if (e - b >= getMinimumPointsNumberPerVoxel())
      runs.emplace_back(static_cast<unsigned int>(b), static_cast<unsigned int>(e));
    b = e;
  }
  output.resize(runs.size());
  for (std::size_t r = 0; r < runs.size(); ++r) {
    pcl::CentroidPoint<PointT> centroid;
    for (unsigned int i = runs[r].first; i < runs[r].second; ++i)
      centroid.add(cloud[entries[i].cloud_point_index]);
    centroid.get(output[r]);
  }
  output.width = static_cast<std::uint32_t>(output.size());
}

} // namespace planar_grid
