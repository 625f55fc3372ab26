// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/pcl_base.h>
#include <pcl/pcl_macros.h>
#include <pcl/point_cloud.h>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace pcl {
struct PolygonMesh;
} // namespace pcl

namespace planar_grid {

/** \brief The valid range of each PlanarCuboidApproximation parameter, declared once:
 * checkParameters() tests the values against them and the pipeline's
 * planar_cuboid_approximation stage table takes them as its ranges. \ingroup surface */
namespace planar_cuboid_approximation_ranges {
/** \brief Raster resolution and smallest unit side: (0, 10] meters. */
inline constexpr ParamRange MIN_CELL_SIZE = ParamRange::openMin(0.0, 10.0);
/** \brief D_T of Fig. 8, a share of the unit's area: (0, 1]. */
inline constexpr ParamRange DENSITY_THRESHOLD = ParamRange::openMin(0.0, 1.0);
/** \brief Occupied lattice share of a non-planar box: [0, 1] (0: D_T). */
inline constexpr ParamRange NON_PLANAR_DENSITY_THRESHOLD = ParamRange::closed(0.0, 1.0);
/** \brief W_T of Fig. 8: [0, 100] meters. */
inline constexpr ParamRange MIN_WIDTH = ParamRange::closed(0.0, 100.0);
/** \brief H_T of Fig. 8: [0, 100] meters. */
inline constexpr ParamRange MIN_HEIGHT = ParamRange::closed(0.0, 100.0);
/** \brief Smallest extrusion of a cuboid: (0, 10] meters. */
inline constexpr ParamRange THICKNESS = ParamRange::openMin(0.0, 10.0);
/** \brief Fewest points of an output cuboid: [1, 1000000]. */
inline constexpr ParamRange MIN_POINTS_PER_CELL = ParamRange::closed(1, 1000000);
} // namespace planar_cuboid_approximation_ranges

/** \brief PlanarCuboidApproximation's parameters, named by their keys; their ranges
 * are planar_cuboid_approximation_ranges' and their declarations
 * planarCuboidApproximationParamDeclarations(). The defaults are the pipeline's
 * planar_cuboid_approximation stage's; each setter documents its member.
 * \ingroup surface */
struct PlanarCuboidApproximationParams {
  /** \brief Raster resolution and smallest unit side, meters (the paper's 0.1). */
  double min_cell_size_m{0.1};
  /** \brief D_T of Fig. 8. */
  double density_threshold{0.9};
  /** \brief Occupied lattice share of a non-planar box (0: D_T). */
  double non_planar_density_threshold{0.25};
  /** \brief W_T of Fig. 8, meters. */
  double min_width_m{0.1};
  /** \brief H_T of Fig. 8, meters. */
  double min_height_m{0.1};
  /** \brief Smallest extrusion, meters. */
  double thickness_m{0.1};
  /** \brief Fewest points of an output cuboid. */
  int min_points_per_cell{3};
};

/** \brief The one declaration of each PlanarCuboidApproximationParams member (key
 * with unit, range, meaning), in the order documented. \ingroup surface */
const ParamDeclarations<PlanarCuboidApproximationParams>&
planarCuboidApproximationParamDeclarations();

/** \brief Grid approximation and combination of Sec. III-F (Figs. 6-8) of the paper
 * ("Efficient Planar Surface-Based 3D Mapping Method for Mobile Robots Using Stereo
 * Vision"): turns a ground-free cloud and its planes into oriented rectangular cuboids
 * (PlanarCuboid).
 *
 * Planar clusters (Fig. 6): the inliers of each plane are expressed in plane
 * coordinates (u along the plane's horizontal axis, v along its vertical axis) and
 * rastered at min_cell_size_m (a raster cell is occupied by >= 1 point). A quadtree
 * splits the unit, starting from the bounding square of 2^k raster cells at the
 * cluster's (u, v) minimum, into four equal parts about its centre while
 * D = S_PO / S_PA < D_T and W > W_T and H > H_T (Fig. 8, line 8), where S_PO is the
 * occupied raster area and S_PA the unit area; empty parts are dropped and a unit
 * stops splitting at one raster cell. The kept units are then merged exactly on the
 * raster: first horizontally (maximal runs of covered cells along u in each raster row:
 * equal heights), then vertically (runs with equal u-extent in consecutive rows: equal
 * widths), giving the largest rectangles of Fig. 6(b). Each rectangle is tightened to
 * the (u, v) extent of its inliers and extruded along the normal to the back
 * (Fig. 6(c)): the face is at the front-most inlier (toward the sensor) and the box
 * reaches at least thickness_m behind it and behind every inlier. Rectangles with
 * fewer than min_points_per_cell inliers are dropped and their points join the
 * non-planar remainder.
 *
 * Non-planar remainder (Fig. 7): the remaining finite points (within the indices) are
 * split the same way, in the up-aligned frame (e1 horizontal, up vertical, e2 = up x
 * e1 horizontal depth; see getHorizontalReference()): a quadtree on the (e1, up)
 * raster, then each leaf's points are cut along e2 wherever consecutive depths are more
 * than min_cell_size_m apart, so that no box spans free space between separate
 * surfaces. Every part with >= min_points_per_cell points is split further in 3D
 * (octree steps on a lattice of min_cell_size_m voxels anchored at the part's
 * minimum) until each box's share of occupied voxels reaches D_T (or
 * setNonPlanarDensityThreshold()) or the box is one voxel: a box never spans space its
 * points leave empty (noisy stereo spreads a surface's points over a depth range much
 * larger than a cell). Each box bounds its points (each extent at least min_cell_size_m
 * along e1 and up and thickness_m along e2, so it reaches at most half a cell beyond
 * them); these are never merged and may overlap slightly.
 *
 * With min_points_per_cell = 1 every finite input point within the indices lies in
 * some cuboid. The run time is linear in the number of points plus the raster area
 * (plus an O(n log n) depth sort of the non-planar points within each leaf).
 *
 * Empty or degenerate input (no input, empty cloud, only NaNs) or invalid parameters
 * give an empty output and a PCL_ERROR/PCL_WARN; planes with bad coefficients or no
 * usable inliers are skipped with a PCL_WARN (their points are treated as non-planar).
 * approximate() never throws for bad data.
 *
 * The planes come as the project's PlanarSegments (SACMultiPlaneSegmentation) or as
 * PCL's own parallel lists of pcl::ModelCoefficients and pcl::PointIndices, the
 * output of pcl::SACSegmentation or pcl::OrganizedMultiPlaneSegmentation. The cuboids
 * come as PlanarCuboids (approximate()) or as a pcl::PolygonMesh (reconstruct(), on
 * the convention of pcl::MeshConstruction::reconstruct). The class derives from
 * pcl::PCLBase, not pcl::PCLSurfaceBase, whose search method it has no use for.
 * \ingroup surface */
template <typename PointT>
class PlanarCuboidApproximation : public pcl::PCLBase<PointT> {
public:
  /** \brief Shared pointer to a PlanarCuboidApproximation. */
  using Ptr = std::shared_ptr<PlanarCuboidApproximation<PointT>>;
  /** \brief Shared pointer to a const PlanarCuboidApproximation. */
  using ConstPtr = std::shared_ptr<const PlanarCuboidApproximation<PointT>>;
  /** \brief The input cloud type. */
  using PointCloud = pcl::PointCloud<PointT>;
  /** \brief Shared pointer to an input cloud. */
  using PointCloudPtr = typename PointCloud::Ptr;
  /** \brief Shared pointer to a const input cloud. */
  using PointCloudConstPtr = typename PointCloud::ConstPtr;

  /** \brief The parameters (PlanarCuboidApproximationParams). */
  using Params = PlanarCuboidApproximationParams;

  /** \brief Each parameter's one declaration (key, range, unit, meaning): the
   * planar_cuboid_approximation stage and its reference are made from it.
   * \return planarCuboidApproximationParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return planarCuboidApproximationParamDeclarations();
  }

  /** \brief An approximation with the default parameters. */
  PlanarCuboidApproximation() = default;
  /** \brief An approximation with \a params (checked by approximate()). */
  explicit PlanarCuboidApproximation(const Params& params) : params_(params) {}
  ~PlanarCuboidApproximation() override = default;

  /** \brief Sets the parameters at once (checked by approximate()). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Sets the planes of the input cloud (e.g. from SACMultiPlaneSegmentation);
   * their inliers index the input cloud. A point in the inliers of several planes
   * goes to the first. An empty list (the default) makes every point non-planar.
   * \param[in] planes model_coefficients [a, b, c, d] (unit normal, d in meters) and
   * inliers per plane */
  void setPlanes(const PlanarSegments& planes) { planes_ = planes; }
  /** \brief Sets the planes of the input cloud as PCL's segmentations give them (e.g.
   * one pcl::SACSegmentation::segment() call per plane); their inliers index the
   * input cloud. A point in the inliers of several planes goes to the first.
   * \param[in] model_coefficients [a, b, c, d] per plane (normal (a, b, c), any
   * length and either sign, d in meters: normalised and turned toward the sensor)
   * \param[in] inliers indices into the input cloud per plane, parallel to
   * \a model_coefficients
   * \throws planar_grid::Exception when the two lists differ in size (the planes are
   * then left unchanged) */
  void setPlanes(const std::vector<pcl::ModelCoefficients>& model_coefficients,
                 const std::vector<pcl::PointIndices>& inliers);
  /** \brief Returns the planes. */
  const PlanarSegments& getPlanes() const { return planes_; }

  /** \brief Sets the up axis (the paper's z axis); it is normalised.
   * \param[in] axis non-zero (default (0, 0, 1); (0, -1, 0) for a camera frame) */
  void setUpAxis(const Eigen::Vector3f& axis) { up_axis_ = axis; }
  /** \brief Returns the up axis as set. */
  Eigen::Vector3f getUpAxis() const { return up_axis_; }

  /** \brief Sets the sensor origin that decides the front of each plane (the box is
   * extruded away from it). Unset, the input cloud's sensor_origin_ is used.
   * \param[in] origin in meters, in the cloud's frame */
  void setSensorOrigin(const Eigen::Vector3f& origin)
  {
    sensor_origin_ = origin;
    sensor_origin_set_ = true;
  }
  /** \brief Returns the sensor origin in meters (the cloud's when unset, or zero
   * without input). */
  Eigen::Vector3f getSensorOrigin() const
  {
    if (sensor_origin_set_ || !input_)
      return sensor_origin_;
    return input_->sensor_origin_.template head<3>();
  }

  /** \brief Sets the raster resolution, which is also the smallest unit side.
   * \param[in] min_cell_size_m in meters, in
   * planar_cuboid_approximation_ranges::MIN_CELL_SIZE (default 0.1) */
  void setMinCellSize(double min_cell_size_m)
  {
    params_.min_cell_size_m = min_cell_size_m;
  }
  /** \brief Returns the raster resolution, in meters. */
  double getMinCellSize() const { return params_.min_cell_size_m; }

  /** \brief Sets D_T of Fig. 8: a unit splits only while its split density
   * D = S_PO / S_PA (occupied raster area over unit area) is below it.
   * \param[in] density_threshold in
   * planar_cuboid_approximation_ranges::DENSITY_THRESHOLD (default 0.9) */
  void setDensityThreshold(double density_threshold)
  {
    params_.density_threshold = density_threshold;
  }
  /** \brief Returns D_T, in (0, 1]. */
  double getDensityThreshold() const { return params_.density_threshold; }
  /** \brief Sets the share of occupied lattice voxels a non-planar box (Fig. 7) must
   * reach before it stops splitting in 3D: lower values give fewer, emptier boxes.
   * \param[in] density_threshold in
   * planar_cuboid_approximation_ranges::NON_PLANAR_DENSITY_THRESHOLD (default 0.25,
   * the pipeline's: emptier, fewer boxes than at D_T); 0 for D_T */
  void setNonPlanarDensityThreshold(double density_threshold)
  {
    params_.non_planar_density_threshold = density_threshold;
  }
  /** \brief Returns the non-planar box density threshold (0: D_T). */
  double getNonPlanarDensityThreshold() const
  {
    return params_.non_planar_density_threshold;
  }

  /** \brief Sets W_T of Fig. 8: a unit splits only while its width W > W_T.
   * \param[in] min_width_m in meters, in planar_cuboid_approximation_ranges::MIN_WIDTH
   * (default 0.1, i.e. split down to single raster cells; a unit never splits below one
   * raster cell) */
  void setMinWidth(double min_width_m) { params_.min_width_m = min_width_m; }
  /** \brief Returns W_T, in meters. */
  double getMinWidth() const { return params_.min_width_m; }

  /** \brief Sets H_T of Fig. 8: a unit splits only while its height H > H_T.
   * \param[in] min_height_m in meters, in
   * planar_cuboid_approximation_ranges::MIN_HEIGHT (default 0.1) */
  void setMinHeight(double min_height_m) { params_.min_height_m = min_height_m; }
  /** \brief Returns H_T, in meters. */
  double getMinHeight() const { return params_.min_height_m; }

  /** \brief Sets the smallest extrusion of a planar cuboid behind its face, and the
   * smallest depth of a non-planar cuboid (Fig. 6(c)).
   * \param[in] thickness_m in meters, in planar_cuboid_approximation_ranges::THICKNESS
   * (default 0.1) */
  void setThickness(double thickness_m) { params_.thickness_m = thickness_m; }
  /** \brief Returns the smallest thickness, in meters. */
  double getThickness() const { return params_.thickness_m; }

  /** \brief Sets the fewest points of an output cuboid (a merged planar rectangle or
   * a non-planar part).
   * \param[in] min_points_per_cell in
   * planar_cuboid_approximation_ranges::MIN_POINTS_PER_CELL (default 3) */
  void setMinPointsPerCell(int min_points_per_cell)
  {
    params_.min_points_per_cell = min_points_per_cell;
  }
  /** \brief Returns the fewest points of a cuboid. */
  int getMinPointsPerCell() const { return params_.min_points_per_cell; }

  /** \brief Returns the fixed horizontal reference e1 used for non-planar cuboids and
   * for horizontal planes: the first of the x, y, z unit axes whose component
   * perpendicular to the up axis is longest, projected and normalised. For up =
   * (0, 0, 1) it is x (and e2 = y); for the camera up (0, -1, 0) it is x (e2 = z).
   * \return a unit vector perpendicular to the normalised up axis, or zero when the
   * up axis is invalid */
  Eigen::Vector3f getHorizontalReference() const;

  /** \brief Builds the cuboids (Fig. 8).
   * \param[out] cuboids planar cuboids (in plane order, then row order) followed by
   * the non-planar ones; empty on degenerate input or invalid parameters */
  void approximate(PlanarCuboids& cuboids);

  /** \brief Builds the cuboids (Fig. 8) as a triangle mesh, as
   * pcl::MeshConstruction::reconstruct() does: the header is the input cloud's,
   * mesh.cloud holds the vertices (pcl::PointXYZ, in meters, the input's frame) and
   * every polygon is a triangle indexing them.
   * \param[out] mesh per cuboid, in approximate()'s order: its 8 corners in
   * PlanarCuboid::corners() order (vertices 8 i to 8 i + 7) and 12 triangles, two per
   * face, counter-clockwise seen from outside the box (normals point out); an empty
   * mesh (no vertices, no polygons) on degenerate input or invalid parameters */
  void reconstruct(pcl::PolygonMesh& mesh);

  /** \brief Checks the parameters against their documented ranges, as approximate()
   * does before it starts (it then reports the same text with PCL_ERROR and gives no
   * cuboids). \return nullptr when every parameter is valid, else what is wrong (e.g.
   * "thickness must be in (0, 10] m") */
  const char* checkParameters() const;

protected:
  using pcl::PCLBase<PointT>::input_;
  using pcl::PCLBase<PointT>::indices_;

  /** \brief A square quadtree unit on a raster: corner cell and side, in cells. */
  struct Unit {
    /** \brief First raster column. */
    int u0;
    /** \brief First raster row. */
    int v0;
    /** \brief Side in raster cells (a power of two). */
    int side;
  };

  /** \brief Base initCompute plus checkParameters(); PCL_ERROR if false. */
  bool initCompute();

  /** \brief The algorithm; called between initCompute() and deinitCompute(). */
  virtual void applyApproximation(PlanarCuboids& cuboids);

  /** \brief Quadtree split of Fig. 8 over the occupancy of the current raster
   * (occupied_, nu_ x nv_ cells of cell_m meters); fills units_ with the kept
   * leaves. */
  void splitUnits(double cell_m);

  /** \brief Builds the cuboids of one plane from the points in plane_points_. */
  void approximatePlane(int plane_id,
                        const Eigen::Vector3f& normal,
                        float d,
                        PlanarCuboids& cuboids);

  /** \brief Builds the non-planar cuboids of the points in remainder_. */
  void approximateRemainder(PlanarCuboids& cuboids);
  /** \brief Splits one depth-cut part of the remainder (indices into coords_, in
   * (e1, up, e2) meters) into boxes its points support: octree steps on a lattice of
   * edge \a cell until a box's share of occupied lattice voxels reaches D_T or the box
   * is one voxel; each box bounds its points, widened to \a cell (thickness_m along
   * e2). */
  void splitNonPlanarPart(std::vector<std::size_t>::iterator first,
                          std::vector<std::size_t>::iterator last,
                          float cell,
                          PlanarCuboids& cuboids);

  /** \brief Sizes the raster for the (u, v) extent; returns the raster cell size in
   * meters (params_.min_cell_size_m, doubled while the raster would exceed
   * MAX_RASTER_CELLS). */
  double setUpRaster(float u_min, float u_max, float v_min, float v_max);

  /** \brief Returns the class name for messages. */
  const std::string& getClassName() const { return class_name_; }

  /** \brief Largest number of raster cells of one cluster. */
  static constexpr std::size_t MAX_RASTER_CELLS = std::size_t{1} << 24;

  /** \brief Class name used in messages. */
  std::string class_name_{"PlanarCuboidApproximation"};
  /** \brief The planes of the input cloud. */
  PlanarSegments planes_;
  /** \brief Up axis. */
  Eigen::Vector3f up_axis_{0.0f, 0.0f, 1.0f};
  /** \brief Sensor origin in meters, when set. */
  Eigen::Vector3f sensor_origin_{Eigen::Vector3f::Zero()};
  /** \brief Whether sensor_origin_ was set. */
  bool sensor_origin_set_{false};
  /** \brief The parameters of Params. */
  Params params_;

  // Scratch buffers, reused across planes and calls (no per-point allocations).
  /** \brief Per input point: 0 excluded, 1 available, 2 taken by a plane. */
  std::vector<std::uint8_t> state_;
  /** \brief Indices of the current cluster's points. */
  std::vector<int> plane_points_;
  /** \brief (u, v, w) coordinates of the current cluster's points, in meters. */
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> coords_;
  /** \brief Raster cell of each point of the current cluster. */
  std::vector<int> cell_of_point_;
  /** \brief Indices of the non-planar remainder. */
  std::vector<int> remainder_;
  /** \brief Raster width (along u), in cells. */
  int nu_{0};
  /** \brief Raster height (along v), in cells. */
  int nv_{0};
  /** \brief Raster origin along u, in meters. */
  float u_origin_{0.0f};
  /** \brief Raster origin along v, in meters. */
  float v_origin_{0.0f};
  /** \brief Occupancy of the raster (row-major, nu_ x nv_). */
  std::vector<std::uint8_t> occupied_;
  /** \brief Summed-area table of occupied_, (nu_ + 1) x (nv_ + 1). */
  std::vector<std::uint32_t> integral_;
  /** \brief Kept quadtree leaves. */
  std::vector<Unit> units_;
  /** \brief Label per raster cell (rectangle or leaf id, -1 none). */
  std::vector<int> label_;
  /** \brief The raster cells the kept units cover (rasterCellKey(), row-major), the
   * input of the merge. */
  std::vector<std::uint64_t> covered_keys_;
  /** \brief Their class for the merge (all 0: one class). */
  std::vector<std::uint8_t> covered_classes_;

public:
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/surface/impl/planar_cuboid_approximation.hpp>
#endif
