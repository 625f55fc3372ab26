// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/filters/filter.h>
#include <pcl/point_cloud.h>

#include <Eigen/Core>

namespace planar_grid {

/** \brief pcl::VoxelGrid's filter without its second pass over the cloud: the same
 * output cloud, point for point and bit for bit, for the same leaf size and minimum
 * point count.
 *
 * Each occupied voxel of the leaf size (meters per axis, the grid anchored at the
 * origin) gives one point, the centroid of its finite input points (every field
 * pcl::CentroidPoint averages, as pcl::VoxelGrid with downsample_all_data), in the
 * order of the voxels' linear indices over the cloud's bounding box. Voxels with fewer
 * than the minimum number of points give none. The output is unorganized and dense.
 *
 * The points are bucketed by the same linear voxel index, sorted by the same
 * boost::sort::spreadsort::integer_sort (whose order of the points within a voxel, and
 * so the single precision sums, depend only on the indices), and averaged with
 * pcl::CentroidPoint; the voxel indices come from the same single precision
 * arithmetic (exactly so, also far from the origin). What is saved against
 * pcl::VoxelGrid: the second pass over the input cloud (the voxels are found in the
 * bounding box pass and kept compact), the index entries' reallocation checks and
 * zero-filling, and the calls to floorf. Not supported (pcl::VoxelGrid has them): a
 * filter field and limits, the leaf layout, and centroids of x, y, z only. A cloud
 * without finite points gives an empty output. Timings on the main job in
 * docs/BENCHMARKS.md.
 * Precompiled for the point types of PLANAR_GRID_POINT_TYPES; any other type is
 * instantiated from the impl/ header when PCL_NO_PRECOMPILE is defined, as with PCL.
 * \ingroup filters */
template <typename PointT> class FastVoxelGrid : public pcl::Filter<PointT> {
public:
  /** \brief The filtered cloud type, pcl::PointCloud<PointT>. */
  using PointCloud = typename pcl::Filter<PointT>::PointCloud;

  FastVoxelGrid() { this->filter_name_ = "FastVoxelGrid"; }

  /** \brief The voxel edges along x, y and z, meters (> 0). */
  void setLeafSize(float lx, float ly, float lz)
  {
    leaf_size_ = Eigen::Array4f(lx, ly, lz, 1.0f);
    inverse_leaf_size_ = Eigen::Array4f::Ones() / leaf_size_;
  }
  /** \brief The voxel edges, meters. */
  Eigen::Vector3f getLeafSize() const { return leaf_size_.head<3>().matrix(); }

  /** \brief Voxels with fewer points than this give no point (0 by default). */
  void setMinimumPointsNumberPerVoxel(unsigned int min_points_per_voxel)
  {
    min_points_per_voxel_ = min_points_per_voxel;
  }
  /** \brief The minimum number of points per voxel. */
  unsigned int getMinimumPointsNumberPerVoxel() const { return min_points_per_voxel_; }

protected:
  /** \brief The centroids of the occupied voxels of the input (its indices, when
   * set). When the bounding box has more voxels than a 32-bit index holds, the output
   * is a copy of the input, as for pcl::VoxelGrid (which warns; so does this). */
  void applyFilter(PointCloud& output) override;

private:
  Eigen::Array4f leaf_size_{Eigen::Array4f::Ones()};
  Eigen::Array4f inverse_leaf_size_{Eigen::Array4f::Ones()};
  unsigned int min_points_per_voxel_{0};
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_voxel_grid.hpp>
#endif
