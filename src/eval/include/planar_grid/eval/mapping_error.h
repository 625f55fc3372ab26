// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>
#include <pcl/types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <vector>

namespace octomap {
class OcTree;
} // namespace octomap

namespace planar_grid {

class PlanarGridMap;

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
  /** \brief The truth points within \a radius_m of \a point (pcl::search::KdTree's
   * radiusSearch). Safe to call from several threads.
   * \param[in] point the query, meters
   * \param[in] radius_m meters, > 0
   * \param[out] indices into getPoints() of the points found (cleared first; none for a
   * non-finite point or radius_m <= 0)
   * \return the number of points found */
  std::size_t radiusSearch(const Eigen::Vector3f& point,
                           double radius_m,
                           pcl::Indices& indices) const;
  /** \brief Number of truth points (the finite ones). */
  [[nodiscard]] std::size_t size() const;
  /** \brief The truth points (the finite ones of the constructor's cloud), meters. */
  [[nodiscard]] PointCloudConstPtr getPoints() const;

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

  /** \brief The method's own error erroneous / samples in [0, 1]: the share of its own
   * occupied volume (in samples) that lies off the truth, which a method cannot lower
   * by mapping less, unlike the paper's e = erroneous / SG's cells; NaN without
   * samples. */
  [[nodiscard]] double ownError() const
  {
    return samples > 0 ? static_cast<double>(erroneous) / static_cast<double>(samples)
                       : std::numeric_limits<double>::quiet_NaN();
  }
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

/** \brief Largest angle between a planar cell's normal and the normal of the truth
 * surface at a face sample for the sample to count as precise, degrees
 * (evaluatePlanePrecision()): wider than the scatter of PCA normals of stereo
 * reference points over a cell's neighbourhood, narrower than the angle of a cell
 * fitted across two surfaces (a wall and the floor meet at 90 degrees).
 * \ingroup eval */
constexpr double PLANE_PRECISION_MAX_ANGLE_DEG = 20.0;
/** \brief Fewest truth points in a face sample's neighbourhood for a normal
 * (evaluatePlanePrecision()). \ingroup eval */
constexpr std::size_t PLANE_PRECISION_MIN_POINTS = 5;
/** \brief Largest ratio of the smallest to the middle eigenvalue of the covariance of
 * a face sample's truth points for them to form a surface (evaluatePlanePrecision()):
 * above it the points spread in three directions (a corner, clutter) and give no
 * normal. A stereo reference is a surface as thick as its depth noise: a flat wall
 * whose points scatter with a standard deviation of 0.1 / 0.15 / 0.2 m across it
 * reads about 0.3 / 0.5 / 0.6 over a 0.4 m neighbourhood, 0.1 / 0.2 / 0.3 over 0.8 m
 * (hence PLANE_PRECISION_MAX_RADIUS_M). \ingroup eval */
constexpr double PLANE_PRECISION_MAX_EIGENVALUE_RATIO = 0.5;
/** \brief Smallest radius of a face sample's neighbourhood, meters; the radius is the
 * larger of this and 2 resolution_m (evaluatePlanePrecision()): wide enough that a
 * stereo reference's surface, as thick as its depth noise, still has a normal.
 * \ingroup eval */
constexpr double PLANE_PRECISION_MIN_RADIUS_M = 0.4;
/** \brief Largest radius of a face sample's neighbourhood, meters
 * (evaluatePlanePrecision()): where the truth points of the first neighbourhood hold
 * enough points but do not form a surface, the radius doubles up to this bound before
 * the sample is called not a surface, so that a reference as thick as its depth noise
 * (the multi-view stereo references scatter 0.1-0.2 m across a wall) still shows a
 * wall, while clutter, a corner or a canopy stays no surface at every radius and a
 * cell across a wall meets the wall's normal. \ingroup eval */
constexpr double PLANE_PRECISION_MAX_RADIUS_M = 1.6;

/** \brief Plane precision of PG's planar cells: their face area and the part of it
 * where the truth is a surface of the cell's orientation. \ingroup eval */
struct PlanePrecision {
  /** \brief Face area of the occupied planar cuboids counted, square meters (with a
   * region, the area of the face samples in it). */
  double face_area_m2{0.0};
  /** \brief Of it, the area of the precise face samples, square meters. */
  double precise_area_m2{0.0};
  /** \brief Face samples counted and precise ones. */
  std::size_t samples{0};
  std::size_t precise_samples{0};
  /** \brief Of the imprecise face area, square meters: the part with fewer than
   * PLANE_PRECISION_MIN_POINTS truth points around it (a cell in space the truth
   * does not hold), the part whose truth points do not form a surface (a corner,
   * clutter, a line) and the part whose truth surface is tilted more than
   * PLANE_PRECISION_MAX_ANGLE_DEG from the cell. They sum to face_area_m2 -
   * precise_area_m2. */
  double no_truth_area_m2{0.0};
  double not_surface_area_m2{0.0};
  double misoriented_area_m2{0.0};

  /** \brief precise_area_m2 / face_area_m2 in [0, 1]; NaN without face area. */
  [[nodiscard]] double ratio() const
  {
    return face_area_m2 > 0.0 ? precise_area_m2 / face_area_m2
                              : std::numeric_limits<double>::quiet_NaN();
  }
};

/** \brief Plane precision of PG: the share of the face area of its occupied planar
 * cuboids (PlanarCuboid::is_planar, probability >= occupancy_thres) where the truth
 * points form a surface with the cuboid's normal.
 *
 * Each face (PlanarCuboid::face(), width_m x height_m at faceCentre()) is sampled as
 * evaluateCuboids() samples a cuboid across its face: n = max(1, ceil(extent /
 * resolution_m - 1e-3)) samples per in-plane axis at the centres of the n equal
 * sub-intervals, each weighing width_m height_m / (n_u n_v) square meters. A sample
 * is precise when the truth points within max(2 resolution_m,
 * PLANE_PRECISION_MIN_RADIUS_M) of it (GroundTruthSurface::radiusSearch()) number at
 * least PLANE_PRECISION_MIN_POINTS, their covariance's eigenvalues l0 <= l1 <= l2
 * satisfy l0 < PLANE_PRECISION_MAX_EIGENVALUE_RATIO l1 and l1 > 1e-6 l2 (a surface,
 * not a cloud or a line), and the eigenvector of l0 (the PCA normal) is within
 * PLANE_PRECISION_MAX_ANGLE_DEG of the cuboid's normal, either sign (|cos| >=
 * cos(angle)). Where the points are enough but no surface, the radius doubles up to
 * PLANE_PRECISION_MAX_RADIUS_M and the first neighbourhood that is a surface decides
 * (a thick reference); none: not a surface. A sample with too few truth points in the
 * first neighbourhood (a cell in empty space) is not precise.
 * \param[in] cuboids PG's cuboids (world frame); the non-planar and the unoccupied
 * ones are ignored
 * \param[in] occupancy_thres probability in [0, 1]
 * \param[in] resolution_m sample step and half the neighbourhood radius, meters, > 0
 * \param[in] truth the ground truth (or reference) points
 * \param[in] region only the face samples inside it are counted; default: all
 * \return the face area, its precise part and the sample counts (ratio(): NaN
 * without planar cells)
 * \throws planar_grid::Exception for resolution_m <= 0 or an occupancy_thres outside
 * [0, 1]
 * \note a cuboid with non-finite fields, a negative extent or more than 1e9 face
 * samples is skipped with a PCL_WARN
 * \ingroup eval */
PlanePrecision evaluatePlanePrecision(const PlanarCuboids& cuboids,
                                      double occupancy_thres,
                                      double resolution_m,
                                      const GroundTruthSurface& truth,
                                      const MappingErrorRegion& region = {});

/** \brief One camera view of the mapped range (TruthVoxels::addView()): where a frame
 * was seen from and what its image covers (camera frame x right, y down, z forward).
 * \ingroup eval */
struct RangeView {
  /** \brief The camera pose world_T_camera, meters. */
  Eigen::Isometry3d world_T_camera{Eigen::Isometry3d::Identity()};
  /** \brief Focal length, pixels; <= 0: no image bounds (every direction in front of
   * the camera is in the view, as for a point-cloud input). */
  double focal_length_px{0.0};
  /** \brief Principal point column and row, pixels. */
  double cx_px{0.0};
  double cy_px{0.0};
  /** \brief Image width and height, pixels; 0: no image bounds. */
  int width_px{0};
  int height_px{0};

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief The truth's occupied voxels at one cell size, for the completeness: the
 * truth points voxelized at resolution_m (a point p lies in the voxel of index
 * floor(p / resolution_m) per axis, the lattice of StandardVoxelGrid and OctoMap), one
 * entry per voxel holding a point, at its centre (index + 1/2) resolution_m.
 *
 * Each voxel is also classified as ground or not, independently of the pipeline's own
 * ground removal: the world's up axis is +z; the voxels are grouped into vertical
 * columns of GROUND_COLUMN_SIZE_M x GROUND_COLUMN_SIZE_M (x, y) by the voxel centre,
 * and a voxel is ground when its centre z is at most GROUND_HEIGHT_M above the lowest
 * voxel centre of its column. A column without a floor (a wall seen above nothing)
 * counts its lowest GROUND_HEIGHT_M as ground.
 *
 * Each voxel is also in the mapped range or not: by default every voxel is (no range);
 * after setMappedRange(max_depth_m) only the voxels whose centre lies in the view of a
 * camera given to addView() since (in front of it at a depth along its optical axis of
 * at most max_depth_m, and projecting inside its image): the space within which the
 * pipeline makes cells (depth_error_filter's bound of eq. 4). Occlusion is not taken
 * into account.
 *
 * Voxels are ordered by (z, y, x) index (deterministic). A truth point whose index is
 * outside [-(2^20 - 1), 2^20 - 1] per axis (StandardVoxelGrid::MAX_INDEX: 104.8 km at
 * 0.1 m) is left out with a PCL_WARN.
 * \ingroup eval */
class TruthVoxels {
public:
  /** \brief Edge of the (x, y) columns of the ground test, meters. */
  static constexpr double GROUND_COLUMN_SIZE_M = 1.0;
  /** \brief Height above the lowest truth voxel of its column up to which a truth
   * voxel is ground, meters (inclusive; a 1e-6 m margin absorbs the rounding of whole
   * multiples of the cell size such as 3 x 0.1 m). */
  static constexpr double GROUND_HEIGHT_M = 0.3;

  /** \brief Voxelizes the points of \a truth.
   * \param[in] truth the ground truth
   * \param[in] resolution_m voxel edge, meters, > 0
   * \throws planar_grid::Exception for resolution_m <= 0 or not finite */
  TruthVoxels(const GroundTruthSurface& truth, double resolution_m);

  /** \brief Voxel edge, meters. */
  [[nodiscard]] double getResolution() const { return resolution_m_; }
  /** \brief Number of truth voxels. */
  [[nodiscard]] std::size_t size() const { return indices_.size(); }
  /** \brief Number of ground voxels among them. */
  [[nodiscard]] std::size_t getGroundCount() const { return ground_count_; }
  /** \brief Index of voxel \a i (i < size()). */
  [[nodiscard]] const VoxelIndex& getIndex(std::size_t i) const { return indices_[i]; }
  /** \brief Centre of voxel \a i, meters. */
  [[nodiscard]] Eigen::Vector3f getCentre(std::size_t i) const;
  /** \brief Whether voxel \a i is ground (see the class description). */
  [[nodiscard]] bool isGround(std::size_t i) const { return ground_[i] != 0; }

  /** \brief Restricts the mapped range to the views added from now on: no voxel is in
   * range until addView() puts it there.
   * \param[in] max_depth_m largest depth along a view's optical axis, meters, > 0
   * (+inf: the image bounds alone)
   * \throws planar_grid::Exception for max_depth_m <= 0 or NaN */
  void setMappedRange(double max_depth_m);
  /** \brief Puts the voxels whose centre lies in \a view (within the depth of
   * setMappedRange()) in the mapped range; a no-op before setMappedRange(). */
  void addView(const RangeView& view);
  /** \brief Largest depth of the mapped range, meters (+inf without a range). */
  [[nodiscard]] double getMappedRange() const { return max_depth_m_; }
  /** \brief Whether voxel \a i is in the mapped range (every voxel without a range).
   */
  [[nodiscard]] bool isInRange(std::size_t i) const
  {
    return !has_range_ || in_range_[i] != 0;
  }

private:
  /** \brief Voxel edge, meters. */
  double resolution_m_;
  /** \brief The voxels' indices, sorted by (z, y, x). */
  std::vector<VoxelIndex> indices_;
  /** \brief 1 for a ground voxel, parallel to indices_. */
  std::vector<std::uint8_t> ground_;
  /** \brief Number of ground voxels. */
  std::size_t ground_count_{0};
  /** \brief Whether setMappedRange() was called. */
  bool has_range_{false};
  /** \brief Largest depth of the mapped range, meters. */
  double max_depth_m_{std::numeric_limits<double>::infinity()};
  /** \brief 1 for a voxel in the mapped range, parallel to indices_ (with a range). */
  std::vector<std::uint8_t> in_range_;
};

/** \brief Completeness of one method: how much of the truth its occupied cells cover.
 * A method cannot lower it by dropping data, as it can the mapping error.
 * \ingroup eval */
struct Completeness {
  /** \brief Truth voxels counted (TruthVoxels; with a region, those whose centre is in
   * it; for the planar share, the non-ground ones). */
  std::size_t truth_voxels{0};
  /** \brief Of them, those whose centre lies within the tolerance of an occupied cell.
   */
  std::size_t covered{0};
  /** \brief Of the truth voxels counted, the non-ground ones (TruthVoxels::isGround).
   */
  std::size_t nonground_voxels{0};
  /** \brief Of those, the covered ones: nonground_covered / nonground_voxels is how
   * much of the truth above the ground the cells reach; for cells made from the same
   * points as the planar cuboids, the bound of evaluatePlanarShare(). */
  std::size_t nonground_covered{0};
  /** \brief Of the non-ground truth voxels counted, those in the mapped range
   * (TruthVoxels::isInRange). */
  std::size_t range_nonground_voxels{0};
  /** \brief Of those, the covered ones. */
  std::size_t range_nonground_covered{0};

  /** \brief covered / truth_voxels in [0, 1]; NaN without truth voxels. */
  [[nodiscard]] double ratio() const
  {
    return truth_voxels > 0
             ? static_cast<double>(covered) / static_cast<double>(truth_voxels)
             : std::numeric_limits<double>::quiet_NaN();
  }
  /** \brief nonground_covered / nonground_voxels in [0, 1]; NaN without non-ground
   * truth voxels. */
  [[nodiscard]] double nongroundRatio() const
  {
    return nonground_voxels > 0 ? static_cast<double>(nonground_covered)
                                    / static_cast<double>(nonground_voxels)
                                : std::numeric_limits<double>::quiet_NaN();
  }
  /** \brief range_nonground_covered / range_nonground_voxels in [0, 1]; NaN without
   * non-ground truth voxels in the mapped range. */
  [[nodiscard]] double rangeNongroundRatio() const
  {
    return range_nonground_voxels > 0 ? static_cast<double>(range_nonground_covered)
                                          / static_cast<double>(range_nonground_voxels)
                                      : std::numeric_limits<double>::quiet_NaN();
  }
};

/** \brief Completeness of SG: the share of the truth voxels whose centre lies within
 * \a tolerance_m (Euclidean) of an occupied voxel (StandardVoxelGrid::isOccupied) taken
 * as a solid cube.
 *
 * A truth voxel of index k is covered when one of the voxels k + d is occupied (looked
 * up in the grid's hash map), for the offsets d whose cube is within tolerance_m of
 * the centre: resolution_m |max(|d| - 1/2, 0)| <= tolerance_m (componentwise; at
 * tolerance_m = resolution_m these are the 27 voxels sharing at least a corner with
 * the truth voxel; a voxel two steps away is 1.5 resolution_m away), nearest first.
 * Exact, since the truth voxels and SG share the lattice.
 * \param[in] grid the standard voxel grid
 * \param[in] truth the truth voxels, at the grid's resolution
 * \param[in] tolerance_m meters, >= 0
 * \param[in] region only the truth voxels whose centre is in it are counted (the
 * occupied cells count wherever they are); default: all
 * \throws planar_grid::Exception for tolerance_m < 0, NaN or above 16 resolution_m,
 * or a truth resolution other than the grid's
 * \ingroup eval */
Completeness evaluateCompleteness(const StandardVoxelGrid& grid,
                                  const TruthVoxels& truth,
                                  double tolerance_m,
                                  const MappingErrorRegion& region = {});

/** \brief Completeness of RA: as the StandardVoxelGrid overload, the occupied cells
 * being the voxels of the occupied boxes (a box is the union of its voxels), collected
 * in a hash set of voxel indices (those within reach of a counted truth voxel).
 * \param[in] boxes RA's boxes
 * \param[in] resolution_m voxel edge of the grid the boxes came from, meters, > 0;
 * the truth voxels' resolution
 * \param[in] truth the truth voxels
 * \param[in] tolerance_m meters, >= 0
 * \param[in] region only the truth voxels whose centre is in it are counted
 * \throws planar_grid::Exception for resolution_m <= 0, tolerance_m < 0 or above 16
 * resolution_m, or a truth resolution other than resolution_m
 * \ingroup eval */
Completeness evaluateCompleteness(const AxisAlignedBoxes& boxes,
                                  double resolution_m,
                                  const TruthVoxels& truth,
                                  double tolerance_m,
                                  const MappingErrorRegion& region = {});

/** \brief Completeness of OG: as the StandardVoxelGrid overload, the occupied cells
 * being the occupied leaves (tree.isNodeOccupied) of any depth, a leaf being the
 * union of its voxels of the tree's resolution, collected in a hash set of voxel
 * indices (the leaves in the box of voxels within reach of a counted truth voxel).
 * \param[in] tree the octree
 * \param[in] truth the truth voxels, at the tree's resolution
 * \param[in] tolerance_m meters, >= 0
 * \param[in] region only the truth voxels whose centre is in it are counted
 * \throws planar_grid::Exception for tolerance_m < 0 or above 16 resolution_m, or a
 * truth resolution other than the tree's
 * \ingroup eval */
Completeness evaluateCompleteness(const octomap::OcTree& tree,
                                  const TruthVoxels& truth,
                                  double tolerance_m,
                                  const MappingErrorRegion& region = {});

/** \brief Completeness of PG: the share of the truth voxels whose centre lies within
 * \a tolerance_m (Euclidean) of an occupied cuboid (probability >= occupancy_thres)
 * taken as a solid oriented box (the exact Euclidean distance from the centre to the
 * box, not to the cuboid's error samples: a thin or tilted cuboid covers what its
 * volume reaches).
 *
 * The cuboids are put in a hash of cubic buckets of edge 2 (resolution + tolerance_m)
 * (each in the buckets that its box grown by tolerance_m may reach); a truth voxel's
 * centre is tested against the cuboids of its bucket.
 * \param[in] cuboids PG's cuboids (world frame)
 * \param[in] occupancy_thres probability in [0, 1]
 * \param[in] truth the truth voxels (any resolution)
 * \param[in] tolerance_m meters, >= 0
 * \param[in] region only the truth voxels whose centre is in it are counted
 * \throws planar_grid::Exception for tolerance_m < 0 or an occupancy_thres outside
 * [0, 1]
 * \note a cuboid with non-finite fields or a negative extent is skipped with a
 * PCL_WARN
 * \ingroup eval */
Completeness evaluateCompleteness(const PlanarCuboids& cuboids,
                                  double occupancy_thres,
                                  const TruthVoxels& truth,
                                  double tolerance_m,
                                  const MappingErrorRegion& region = {});

/** \brief Completeness of PG's whole map, what a robot querying it
 * (PlanarGridMap::getState()) finds OCCUPIED: the share of the truth voxels whose
 * centre lies within \a tolerance_m (Euclidean) of an occupied cell of either layer,
 * each taken as a solid: the occupied cuboids (probability >= the surface layer's
 * occupancy_thres) as oriented boxes, as in the PlanarCuboids overload, and the space
 * layer's occupied voxels as cubes, those whose centre getState() reports OCCUPIED
 * (a voxel whose centre lies in a cuboid below the threshold reads FREE there and is
 * left out). The voxels share the truth's lattice: they are looked up as in the
 * StandardVoxelGrid overload, the cuboids' distances computed as in the PlanarCuboids
 * one, for the truth voxels no voxel covers.
 * \param[in] map PG's map
 * \param[in] truth the truth voxels, at the map's resolution_m
 * \param[in] tolerance_m meters, >= 0
 * \param[in] region only the truth voxels whose centre is in it are counted
 * \throws planar_grid::Exception for tolerance_m < 0 or above 16 resolution_m, or a
 * truth resolution other than the map's
 * \ingroup eval */
Completeness evaluateMapCompleteness(const PlanarGridMap& map,
                                     const TruthVoxels& truth,
                                     double tolerance_m,
                                     const MappingErrorRegion& region = {});

/** \brief Planar share of PG: the completeness of its occupied planar cuboids
 * (PlanarCuboid::is_planar, probability >= occupancy_thres) over the non-ground truth
 * voxels (TruthVoxels::isGround false): how much of the truth above the ground the
 * planar cells explain. Same distance test and arguments as the PlanarCuboids
 * overload of evaluateCompleteness().
 * \return truth_voxels = non-ground truth voxels (in the region), covered = those
 * within tolerance_m of an occupied planar cuboid; range_nonground_voxels and
 * range_nonground_covered the same within the mapped range (TruthVoxels::isInRange):
 * the planar share within the range the pipeline maps
 * \ingroup eval */
Completeness evaluatePlanarShare(const PlanarCuboids& cuboids,
                                 double occupancy_thres,
                                 const TruthVoxels& truth,
                                 double tolerance_m,
                                 const MappingErrorRegion& region = {});

} // namespace planar_grid
