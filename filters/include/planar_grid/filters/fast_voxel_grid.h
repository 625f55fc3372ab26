// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>

#include <pcl/filters/filter.h>
#include <pcl/point_cloud.h>

#include <Eigen/Core>

#include <utility>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each FastVoxelGridParams member, declared once for the
 * voxel_grid stage (the filter itself, as pcl::VoxelGrid, takes any positive leaf).
 * \ingroup filters */
namespace fast_voxel_grid_ranges {
/** \brief Voxel edge, meters: [0.001, 10]. */
inline constexpr ParamRange LEAF_SIZE = ParamRange::closed(0.001, 10.0);
/** \brief Fewest points of a voxel that gives a point: [1, 100000]. */
inline constexpr ParamRange MIN_POINTS_PER_VOXEL = ParamRange::closed(1, 100000);
} // namespace fast_voxel_grid_ranges

/** \brief FastVoxelGrid's parameters for a cubic voxel; their declarations are
 * fastVoxelGridParamDeclarations(). The defaults are the pipeline's voxel_grid
 * stage's. \ingroup filters */
struct FastVoxelGridParams {
  /** \brief Voxel edge along x, y and z, meters (0.05: a stereo cloud at the map's
   * 0.1 m cells). */
  double leaf_size_m{0.05};
  /** \brief Voxels with fewer points give none (1 keeps every voxel, as 0 does). */
  int min_points_per_voxel{1};
};

/** \brief The one declaration of each FastVoxelGridParams member (key with unit,
 * range, meaning). \ingroup filters */
const ParamDeclarations<FastVoxelGridParams>& fastVoxelGridParamDeclarations();

namespace detail {

/** \brief A point's linear voxel index and its index in the cloud: the element
 * pcl::VoxelGrid sorts, with its order (the voxel index alone). */
struct VoxelEntry {
  /** \brief Uninitialized: a buffer of entries grows without being zero-filled (each
   * entry is written before it is read). */
  VoxelEntry() {}
  /** \brief The entry of the point \a point_index in voxel \a voxel_index. */
  VoxelEntry(unsigned int voxel_index, unsigned int point_index) :
      idx(voxel_index), cloud_point_index(point_index)
  {}

  /** \brief Linear voxel index. */
  unsigned int idx;
  /** \brief Index of the point in the cloud. */
  unsigned int cloud_point_index;

  /** \brief pcl::VoxelGrid's order: by voxel index alone. */
  bool operator<(const VoxelEntry& other) const { return idx < other.idx; }
};

/** \brief A finite point's voxel, integer coordinates in leaves from the origin, and
 * its index in the cloud. */
struct PointVoxel {
  /** \brief Uninitialized, as VoxelEntry. */
  PointVoxel() {}
  /** \brief The point \a point_index in the voxel (\a voxel_x, \a voxel_y,
   * \a voxel_z). */
  PointVoxel(int voxel_x, int voxel_y, int voxel_z, unsigned int point_index) :
      x(voxel_x), y(voxel_y), z(voxel_z), cloud_point_index(point_index)
  {}

  /** \brief Voxel x coordinate, in leaves from the origin. */
  int x;
  /** \brief Voxel y coordinate, in leaves from the origin. */
  int y;
  /** \brief Voxel z coordinate, in leaves from the origin. */
  int z;
  /** \brief Index of the point in the cloud. */
  unsigned int cloud_point_index;
};

} // namespace detail

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
 * without finite points gives an empty output. The working buffers stay with the
 * filter from one filter() call to the next (releaseBuffers() frees them), so that a
 * filter kept for a stream of clouds allocates nothing after the largest one. Timings
 * on the main job in docs/BENCHMARKS.md.
 * Precompiled for the point types of PLANAR_GRID_POINT_TYPES; any other type is
 * instantiated from the impl/ header when PCL_NO_PRECOMPILE is defined, as with PCL.
 * \ingroup filters */
template <typename PointT> class FastVoxelGrid : public pcl::Filter<PointT> {
public:
  /** \brief The filtered cloud type, pcl::PointCloud<PointT>. */
  using PointCloud = typename pcl::Filter<PointT>::PointCloud;

  /** \brief The parameters of a cubic voxel (FastVoxelGridParams). */
  using Params = FastVoxelGridParams;

  /** \brief Each parameter's one declaration: the voxel_grid stage and its reference
   * are made from it. \return fastVoxelGridParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return fastVoxelGridParamDeclarations();
  }

  /** \brief A filter with the default Params (0.05 m voxels, every voxel kept). */
  FastVoxelGrid()
  {
    this->filter_name_ = "FastVoxelGrid";
    setParams(Params{});
  }

  /** \brief Sets a cubic voxel of params.leaf_size_m and the minimum point count. */
  void setParams(const Params& params)
  {
    const auto leaf = static_cast<float>(params.leaf_size_m);
    setLeafSize(leaf, leaf, leaf);
    params_ = params;
  }
  /** \brief The parameters as set (after setLeafSize(), leaf_size_m is the edge along
   * x). */
  const Params& getParams() const { return params_; }

  /** \brief The voxel edges along x, y and z, meters (finite and > 0, else filter()
   * throws planar_grid::Exception; 0.05 by default, the pipeline's). */
  void setLeafSize(float lx, float ly, float lz)
  {
    leaf_size_ = Eigen::Array4f(lx, ly, lz, 1.0f);
    inverse_leaf_size_ = Eigen::Array4f::Ones() / leaf_size_;
    params_.leaf_size_m = static_cast<double>(lx);
  }
  /** \brief The voxel edges, meters. */
  Eigen::Vector3f getLeafSize() const { return leaf_size_.head<3>().matrix(); }

  /** \brief Voxels with fewer points than this give no point (1 by default; 0 and 1
   * keep every voxel). */
  void setMinimumPointsNumberPerVoxel(unsigned int min_points_per_voxel)
  {
    params_.min_points_per_voxel = static_cast<int>(min_points_per_voxel);
  }
  /** \brief The minimum number of points per voxel. */
  unsigned int getMinimumPointsNumberPerVoxel() const
  {
    return static_cast<unsigned int>(params_.min_points_per_voxel);
  }

  /** \brief Frees the working buffers that filter() keeps for the next cloud (their
   * size follows the largest cloud filtered). */
  void releaseBuffers()
  {
    voxels_ = std::vector<detail::PointVoxel>();
    entries_ = std::vector<detail::VoxelEntry>();
    runs_ = std::vector<std::pair<unsigned int, unsigned int>>();
  }

protected:
  /** \brief The centroids of the occupied voxels of the input (its indices, when
   * set). When the bounding box has more voxels than a 32-bit index holds, the output
   * is a copy of the input, as for pcl::VoxelGrid (which warns; so does this).
   * \throws planar_grid::Exception for a voxel edge that is not finite and > 0 */
  void applyFilter(PointCloud& output) override;

private:
  /** \brief The voxel edges, meters (set by the constructor). */
  Eigen::Array4f leaf_size_{Eigen::Array4f::Ones()};
  /** \brief Their inverses, 1/m. */
  Eigen::Array4f inverse_leaf_size_{Eigen::Array4f::Ones()};
  /** \brief The parameters as set. */
  Params params_;
  /** \brief Working buffers of applyFilter(), kept between calls: the voxel of every
   * finite point, the sorted index entries, the runs of one voxel. Never shrunk, so
   * that they are neither reallocated nor zero-filled again for a cloud no larger
   * than one before. */
  std::vector<detail::PointVoxel> voxels_;
  std::vector<detail::VoxelEntry> entries_;
  std::vector<std::pair<unsigned int, unsigned int>> runs_;
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/filters/impl/fast_voxel_grid.hpp>
#endif
