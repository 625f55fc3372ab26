// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

#include <cstddef>
#include <limits>
#include <memory>

namespace octomap {
class OcTree;
} // namespace octomap

namespace planar_grid {

/** \brief Ground truth of the mapping error: a dense point sampling of the true
 * surfaces (world frame, meters), searched with pcl::search::KdTree. The sampling
 * should be denser than the tolerance used with it (a sample between truth points is
 * up to half their spacing farther from the sampling than from the surface).
 * \ingroup eval */
class GroundTruthSurface {
public:
  using Ptr = std::shared_ptr<GroundTruthSurface>;
  using ConstPtr = std::shared_ptr<const GroundTruthSurface>;
  using PointCloud = pcl::PointCloud<pcl::PointXYZ>;
  using PointCloudConstPtr = PointCloud::ConstPtr;

  /** \brief Builds the k-d tree over the finite points of \a surface_points.
   * \param[in] surface_points the truth points, meters
   * \throws planar_grid::Exception when the pointer is null or holds no finite
   * point */
  explicit GroundTruthSurface(pcl::PointCloud<pcl::PointXYZ>::ConstPtr surface_points);
  GroundTruthSurface(const GroundTruthSurface&) = delete;
  GroundTruthSurface& operator=(const GroundTruthSurface&) = delete;
  /** \brief Moves (defined in the .cpp, where Impl is complete). */
  GroundTruthSurface(GroundTruthSurface&&) noexcept;
  /** \brief Move assignment (defined in the .cpp). */
  GroundTruthSurface& operator=(GroundTruthSurface&&) noexcept;
  ~GroundTruthSurface();

  /** \brief Distance from \a point to the nearest truth point, meters (+inf for a
   * non-finite point). Safe to call from several threads. */
  [[nodiscard]] float distance(const Eigen::Vector3f& point) const;
  /** \brief Number of truth points (the finite ones). */
  [[nodiscard]] std::size_t size() const;

private:
  struct Impl;
  /** \brief The k-d tree (pimpl keeps pcl_search out of this header). */
  std::unique_ptr<Impl> impl_;
};

/** \brief Counts of the mapping error of one method (paper Sec. IV-B, Fig. 13).
 * \ingroup eval */
struct MappingError {
  /** \brief Occupied samples counted, in units of voxels of edge resolution_m. */
  std::size_t samples{0};
  /** \brief Samples farther than tolerance_m from the truth. */
  std::size_t erroneous{0};
  /** \brief Cells (voxels, leaves, boxes, cuboids) with at least one sample counted:
   * with a region, the method's cells in it (the paper's local cell count, Sec. IV-B);
   * without, every occupied cell evaluated. */
  std::size_t cells{0};
};

/** \brief Optional region of interest of the mapping error ("the occupied grid in a
 * small range near the robot", Sec. IV-B): a sample counts only when it lies inside
 * the axis-aligned box [min_m, max_m] and, when max_distance_m > 0, within
 * max_distance_m of centre_m. The default contains everything. Samples outside are
 * neither counted nor checked; a cell straddling the border counts its inside samples.
 * \ingroup eval */
struct MappingErrorRegion {
  /** \brief Minimum corner of the box, meters (default -inf). */
  Eigen::Vector3f min_m{
    Eigen::Vector3f::Constant(-std::numeric_limits<float>::infinity())};
  /** \brief Maximum corner of the box, meters (default +inf). */
  Eigen::Vector3f max_m{
    Eigen::Vector3f::Constant(std::numeric_limits<float>::infinity())};
  /** \brief Centre of the ball, meters (e.g. the robot's position). */
  Eigen::Vector3f centre_m{Eigen::Vector3f::Zero()};
  /** \brief Radius of the ball, meters; <= 0: no ball. */
  double max_distance_m{-1.0};

  /** \brief Whether \a point (meters) is inside the region. */
  [[nodiscard]] bool contains(const Eigen::Vector3f& point) const
  {
    if ((point.array() < min_m.array()).any() || (point.array() > max_m.array()).any())
      return false;
    return max_distance_m <= 0.0
           || static_cast<double>((point - centre_m).squaredNorm())
                <= max_distance_m * max_distance_m;
  }
};

/** \brief Mapping error of SG: one sample per occupied voxel
 * (StandardVoxelGrid::isOccupied), at its centre.
 * \param[in] grid the standard voxel grid
 * \param[in] truth the ground truth
 * \param[in] tolerance_m a sample farther than this from the truth is erroneous,
 * meters, >= 0
 * \return samples = occupied voxels, erroneous = those farther than tolerance_m
 * \throws planar_grid::Exception for tolerance_m < 0 or NaN
 * \ingroup eval */
MappingError evaluateVoxels(const StandardVoxelGrid& grid,
                            const GroundTruthSurface& truth,
                            double tolerance_m);
/** \brief evaluateVoxels() counting only the samples inside \a region. */
MappingError evaluateVoxels(const StandardVoxelGrid& grid,
                            const GroundTruthSurface& truth,
                            double tolerance_m,
                            const MappingErrorRegion& region);

/** \brief Mapping error of RA: the occupied boxes only, each sampled at the centres of
 * its size.x() size.y() size.z() voxels of edge resolution_m.
 * \param[in] boxes RA's boxes
 * \param[in] resolution_m voxel edge of the grid the boxes came from, meters, > 0
 * \param[in] truth the ground truth
 * \param[in] tolerance_m meters, >= 0
 * \throws planar_grid::Exception for resolution_m <= 0 or tolerance_m < 0
 * \ingroup eval */
MappingError evaluateBoxes(const AxisAlignedBoxes& boxes,
                           double resolution_m,
                           const GroundTruthSurface& truth,
                           double tolerance_m);
/** \brief evaluateBoxes() counting only the samples inside \a region. */
MappingError evaluateBoxes(const AxisAlignedBoxes& boxes,
                           double resolution_m,
                           const GroundTruthSurface& truth,
                           double tolerance_m,
                           const MappingErrorRegion& region);

/** \brief Mapping error of PG: the cuboids with probability >= occupancy_thres, each
 * sampled on a lattice in its own frame (horizontal_axis, verticalAxis() = normal x
 * horizontal_axis, normal): n = max(1, ceil(extent / resolution_m - 1e-3)) samples
 * per axis (the 1e-3 absorbs float extents such as 0.3f = 0.30000001 m that are
 * meant as whole cells), at the centres of the n equal sub-intervals of the extent;
 * so an extent that is a multiple of resolution_m gives extent / resolution_m samples
 * of step resolution_m, and a thin cuboid one sample across.
 * \param[in] cuboids PG's cuboids (world frame)
 * \param[in] occupancy_thres probability in [0, 1]
 * \param[in] resolution_m sample step, meters, > 0
 * \param[in] truth the ground truth
 * \param[in] tolerance_m meters, >= 0
 * \throws planar_grid::Exception for resolution_m <= 0, tolerance_m < 0 or an
 * occupancy_thres outside [0, 1]
 * \note a cuboid with non-finite fields or more than 1e9 samples is skipped with a
 * PCL_WARN
 * \ingroup eval */
MappingError evaluateCuboids(const PlanarCuboids& cuboids,
                             double occupancy_thres,
                             double resolution_m,
                             const GroundTruthSurface& truth,
                             double tolerance_m);
/** \brief evaluateCuboids() counting only the samples inside \a region. */
MappingError evaluateCuboids(const PlanarCuboids& cuboids,
                             double occupancy_thres,
                             double resolution_m,
                             const GroundTruthSurface& truth,
                             double tolerance_m,
                             const MappingErrorRegion& region);

/** \brief Mapping error of OG: the occupied leaves of an OctoMap tree
 * (tree.isNodeOccupied); a leaf at depth d of a tree of depth D (16) is expanded into
 * (2^(D - d))^3 samples at the centres of its voxels of the tree's resolution.
 * \param[in] tree the octree
 * \param[in] truth the ground truth
 * \param[in] tolerance_m meters, >= 0
 * \throws planar_grid::Exception for tolerance_m < 0
 * \ingroup eval */
MappingError evaluateOcTree(const octomap::OcTree& tree,
                            const GroundTruthSurface& truth,
                            double tolerance_m);
/** \brief evaluateOcTree() counting only the samples inside \a region. */
MappingError evaluateOcTree(const octomap::OcTree& tree,
                            const GroundTruthSurface& truth,
                            double tolerance_m,
                            const MappingErrorRegion& region);

} // namespace planar_grid
