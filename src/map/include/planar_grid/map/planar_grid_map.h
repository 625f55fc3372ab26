// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/map/map_frame.h>
#include <planar_grid/map/map_queries.h>
#include <planar_grid/map/octomap_export_summary.h>
#include <planar_grid/map/surface_layer.h>

#include <Eigen/Geometry>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each numeric PlanarGridMap::Params member of its own
 * (the layers' are in explicit_space_grid_ranges and surface_layer_ranges): the
 * PlanarGridMap constructor tests the values against them and the pipeline's
 * map_integration stage table takes them as its ranges. \ingroup map */
namespace planar_grid_map_ranges {
/** \brief Smallest occupied share of a non-planar cell's voxels: [0, 1]. */
inline constexpr ParamRange NON_PLANAR_MIN_OCCUPIED = ParamRange::closed(0.0, 1.0);
} // namespace planar_grid_map_ranges

namespace map_queries {
struct QueryCache;
} // namespace map_queries

/** \brief Memory held by a PlanarGridMap, bytes. \ingroup map */
struct MapMemory {
  /** \brief The surface layer (cuboids, plane rasters, non-planar cells). */
  std::size_t surface_bytes{0};
  /** \brief The explicit space layer (blocks, hash map). */
  std::size_t space_bytes{0};
  /** \brief surface_bytes + space_bytes. */
  std::size_t total_bytes{0};
};

/** \brief What PlanarGridMap::removeOutside() removed. \ingroup map */
struct MapWindowRemoval {
  /** \brief The space layer's stored blocks (8^3 voxels) wholly outside the box. */
  std::size_t space_blocks{0};
  /** \brief The space layer's observed voxels outside the box (in those blocks and in
   * the blocks across the boundary). */
  std::uint64_t space_voxels{0};
  /** \brief The planes' observed raster cells outside the box. */
  std::size_t plane_cells{0};
  /** \brief Planes left without cells, removed. */
  std::size_t planes{0};
  /** \brief Non-planar cells outside the box. */
  std::size_t non_planar_cells{0};
};

/** \brief The planar grid map of Zhang et al. (Sec. III-F, Fig. 5c, Sec. IV): a surface
 * layer of plane-aligned cuboids with occupancy probabilities (SurfaceLayer) and an
 * explicit space layer of free / occupied / unknown voxels inside the camera views
 * (ExplicitSpaceGrid), with one file format.
 *
 * Queries combine the layers: a point inside a cuboid of the surface layer takes the
 * cuboid's probability (occupied when >= occupancy_thres); elsewhere the space layer's
 * state decides. Rays stop at the nearer of the first occupied voxel and the first
 * occupied cuboid.
 *
 * File (OctoMap's discipline: self-describing and validated on reading): a text
 * header of "key value" lines,
 * \code
 * # Planar grid map file
 * version 3
 * id PlanarGridMap
 * resolution_m 0.1
 * prior unknown
 * bounds_m min_x min_y min_z max_x max_y max_z
 * voxels free occupied unknown
 * planes P
 * cuboids C
 * space_bytes S
 * surface_bytes T
 * observation_span first last
 * checksum_crc32 0x........
 * data
 * \endcode
 * (observation_span, getObservationSpan(), only when the span is not empty: files
 * without it, and every file written before it existed, read as an empty span; a
 * reader that does not know the key warns and ignores it),
 * then S bytes of the space layer's octree bit stream (2-bit labels,
 * ExplicitSpaceGrid::serialize(), whose version is the file's) and T bytes of the
 * surface layer, little-endian. Versions 1 and 2 are still read (their space stream
 * cannot tell observed free space from the free prior: it reads as never observed).
 * The reader checks the magic line, the version,
 * every key, resolution_m > 0, the section sizes against the file length (before it
 * allocates), the CRC-32 of the data, and that the decoded counts match the header.
 * \ingroup map */
class PlanarGridMap {
public:
  /** \brief Parameters of both layers. The map's minimum cell size has one owner,
   * resolution_m: the constructor gives it to both layers. */
  struct Params {
    /** The map's minimum cell size (the paper's 0.1 m), meters: the space layer's
     * voxel edge and the surface layer's raster cell edge; in [0.001, 100]. */
    double resolution_m{0.1};
    /** The explicit space layer; its resolution_m is replaced by the map's. */
    ExplicitSpaceGrid::Params space;
    /** The surface layer; its resolution_m is replaced by the map's. */
    SurfaceLayer::Params surface;
    /** Ray clearing of the non-planar cells (Fig. 7's boxes): after each view, a
     * non-planar cell in the view whose voxels the space layer holds observed free,
     * more than half of them, is removed. The view saw through it: the cell was
     * stereo noise or an object that has moved, as OctoMap's misses clear a voxel
     * hit before. The voxels of a cell are those whose centres it contains and the
     * voxel of its centre. See also non_planar_min_occupied. Planar cells:
     * clear_planar. */
    bool clear_non_planar{true};
    /** With clear_non_planar, after each depth image (a pinhole view) a non-planar
     * cell in the view is also removed when the space layer holds fewer than this
     * share of its voxels occupied (the rest free, or never observed: behind the
     * surfaces from every view): a box of one frame's stereo points spans the space
     * between and behind them, which the views show is no surface. The space layer
     * keeps its occupied voxels, so getState() still reports them. Scans
     * (integratePointCloud) apply the free rule alone: their reach is a ball, and a
     * cell beside their rays is no more observed than one behind a surface. 0 keeps
     * only the free rule; in planar_grid_map_ranges::NON_PLANAR_MIN_OCCUPIED
     * (share). */
    double non_planar_min_occupied{0.75};
    /** Fig. 7's boxes on the map's voxel lattice, merged across frames. Each frame's
     * boxes bound that frame's points, so one object seen in many frames is many
     * boxes offset from each other by fractions of a cell. (1) integrateSurface()
     * snaps a non-planar cuboid whose axes are the world's to the lattice of the space
     * layer's voxels: each bound to the nearest multiple of resolution_m, at least one
     * cell along each axis. (2) After each depth image, and after its clearing, two
     * non-planar cells in the view with equal axes whose extents touch (at most
     * resolution_m / 2 apart along each axis) become their bounding box when the two
     * fill at least 0.8 of it and the space layer holds at least
     * non_planar_min_occupied of its voxels occupied and at most half of them free,
     * the evidence that keeps a cell (SurfaceLayer::mergeNonPlanarCells()). The merge
     * is off when non_planar_min_occupied is 0 (the views' occupied voxels are the
     * evidence); scans do not merge. */
    bool merge_non_planar{true};
    /** Ray clearing of the planar cells (a car that drove away): after each view, a
     * plane's raster cell in the view, seen within 60 degrees of its plane's normal,
     * is removed when the space layer holds the voxel of its centre on the plane and
     * the two voxels behind it (resolution_m and 2 resolution_m away from the sensors
     * that saw the plane) observed free: the view saw through the surface to the space
     * behind it, where a surface still there would have left its voxel occupied and
     * the space behind it occluded. One such view clears a cell. A plane left without
     * cells goes. */
    bool clear_planar{false};
    /** Planes replace the non-planar cells lying on them: after each
     * integrateSurface(), a non-planar cell whose centre and footprint lie within
     * resolution_m / 2 of a plane's cuboids is removed (the rule:
     * SurfaceLayer::removeNonPlanarCellsOnPlanes()). A frame that did not find a
     * plane splits the plane's points into Fig. 7's boxes; where the map holds the
     * plane (found in earlier or later frames) those boxes repeat its surface with
     * the depth spread of that frame's points. */
    bool planes_replace_non_planar{true};
    /** Planes absorb the rectangles of weaker planes lying on them: after each
     * integrateSurface() (before planes_replace_non_planar), a rectangle of a map
     * plane whose observed cells all lie within resolution_m / 2 of the cuboids of a
     * plane with more evidence moves to that plane
     * (SurfaceLayer::absorbOverlappingPlaneCells()). */
    bool planes_absorb_overlapping{true};
  };

  /** \brief The one declaration of every member of Params: key (with unit), range,
   * unit and meaning, in the order documented. The pipeline's map_integration stage,
   * its reference (docs/STAGES.md) and the Python PlanarGridMap's keyword arguments
   * are made from it; the defaults are Params' initializers.
   * \return the table (built once) */
  static const ParamDeclarations<Params>& getParamDeclarations();

  /** \brief Builds an empty map; getParams() returns \a params with both layers'
   * resolution_m set to params.resolution_m.
   * \throws planar_grid::Exception for invalid parameters */
  explicit PlanarGridMap(const Params& params);
  PlanarGridMap(const PlanarGridMap&) = delete;
  PlanarGridMap& operator=(const PlanarGridMap&) = delete;
  /** \brief Moves the map (maps are heavy: no copies). */
  PlanarGridMap(PlanarGridMap&&) noexcept = default;
  /** \brief Moves the map. */
  PlanarGridMap& operator=(PlanarGridMap&&) noexcept = default;
  ~PlanarGridMap() = default;

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }
  /** \brief The minimum cell size, meters. */
  [[nodiscard]] double getResolution() const { return params_.resolution_m; }

  /** \brief Merges one frame's cells and feature occupancies into the surface layer
   * (see SurfaceLayer::integrate()); with Params::merge_non_planar, the non-planar
   * cuboids whose axes are the world's are first snapped to the voxel lattice. */
  void integrateSurface(const PlanarCuboids& cuboids,
                        const PlaneModels& planes,
                        const pcl::PointCloud<pcl::PointXYZ>& features,
                        const std::vector<float>& probabilities);

  /** \brief Merges another map into this one: the map of another recording (or of
   * another part of one), mapped on its own, so that many recordings can be mapped in
   * parallel and their maps joined by plane. Merging an empty map changes nothing;
   * merging A into B and B into A give the same voxels, and the same planes and
   * cuboids up to their order (except where a surface is split over several planes of
   * one map: SurfaceLayer::merge()).
   * - Surface layer (SurfaceLayer::merge()): each plane of \a other joins the plane of
   *   this map that the association of integrateSurface() matches (same criteria:
   *   one plane explains both evidence sets): its moments are added, the plane is
   *   refitted and the rasters are re-projected into one frame, so a wall seen in
   *   both maps becomes one plane, not two parallel ones; planes without a match are
   *   added. The non-planar cells of both maps are kept.
   * - Space layer (ExplicitSpaceGrid::merge()): voxel by voxel. When one map's
   *   observation span (getObservationSpan()) lies wholly after the other's, the newer
   *   map's free or occupied observation wins where both observed a voxel, as
   *   integration keeps the newest view: two halves of a drive merge into the drive's
   *   own space layer. When the spans overlap or one is empty (maps from files without
   *   a span, unordered recordings), occupied > free > unknown (occluded) > never
   *   observed, the safe side for planning, which grows occupied space where the maps
   *   disagree. The precedence comes from the maps, not from the argument order, so A
   *   into B and B into A give the same voxels. The merged span is the union.
   * - Then, as after integrateSurface(), Params::planes_absorb_overlapping and
   *   Params::planes_replace_non_planar tidy the planes that met.
   * Maps of one recording split in two differ from the map of all its frames where the
   * later part's first views lacked the evidence the earlier frames had built up
   * (non-planar cells those views would have cleared, plane association) and where the
   * planes' evidence, joined in another order, is covered by other rectangles.
   * \param[in] other the map merged in (unchanged; not this map)
   * \param[in] this_T_other rigid transform from \a other's world frame to this map's
   * (4 x 4, rotation and translation in meters); the identity for maps whose poses
   * are in one world frame (GPS/INS). Other transforms resample both layers (raster
   * cells and voxels to the nearest cell, whole-voxel translations exactly).
   * \throws planar_grid::Exception naming the parameters when the maps' resolution_m,
   * space prior or any surface layer parameter (SurfaceLayer::Params) differ; when
   * \a other is this map; for a transform that is not finite and rigid. The map is
   * then unchanged. The parameters that only steer later integration (max_range_m,
   * surface_margin_m, the clearing and tidying switches) are this map's. */
  void merge(const PlanarGridMap& other, const Eigen::Isometry3d& this_T_other);

  /** \brief The observation order of a map's content: the least and the greatest order
   * key of the views integrated into it (noteObservationOrder()), or empty (first >
   * last) when none was noted. merge() lets the newer map's voxels win when one span
   * lies wholly after the other; the merged map's span is the union. */
  struct ObservationSpan {
    /** \brief The least order key; +infinity when empty. */
    double first{std::numeric_limits<double>::infinity()};
    /** \brief The greatest order key; -infinity when empty. */
    double last{-std::numeric_limits<double>::infinity()};
    /** \brief True when no observation was noted. */
    [[nodiscard]] bool empty() const { return !(first <= last); }
  };

  /** \brief Notes that the map holds a view of order key \a order (the span grows to
   * include it). The key is any number that grows with the time of the views and is
   * comparable between the maps that will be merged: the pipeline notes the frame's
   * index in its recording (Frame::file_index), so segments of one recording compare;
   * maps of different recordings need a common clock (timestamps in seconds).
   * \throws planar_grid::Exception for a non-finite \a order */
  void noteObservationOrder(double order);

  /** \brief The span of the order keys noted (empty for a new map and for maps read
   * from files written before the span was stored). */
  [[nodiscard]] const ObservationSpan& getObservationSpan() const
  {
    return observation_span_;
  }

  /** \brief Replaces the span (e.g. for a map assembled by hand).
   * \throws planar_grid::Exception for a non-finite bound of a non-empty span */
  void setObservationSpan(const ObservationSpan& span);

  /** \brief Integrates one view into the explicit space layer (see
   * ExplicitSpaceGrid::integrateDepthImage()), then, with Params::clear_non_planar,
   * clears the non-planar cells the view saw through (those whose bounding sphere
   * reaches into the camera frustum up to max_range_m are tested). */
  void integrateDepthImage(const DepthImage& depth,
                           const Eigen::Isometry3d& world_T_camera);

  /** \brief Integrates a scan into the explicit space layer by ray casting (see
   * ExplicitSpaceGrid::integratePointCloud()): points in the world frame, meters.
   * Then, with Params::clear_non_planar, clears the non-planar cells the rays went
   * through (those within max_range_m of \a sensor_origin are tested). */
  void integratePointCloud(const pcl::PointCloud<pcl::PointXYZ>& points,
                           const Eigen::Vector3f& sensor_origin);

  /** \brief Integrates one frame into the map (Sec. III-F, Fig. 5c), the steps of a
   * frame in their order:
   * 1. integrateSurface() with the frame's cuboids, plane models, feature points and
   *    probabilities (all world frame);
   * 2. the explicit space layer: integrateDepthImage(*frame.depth,
   *    frame.world_T_sensor) for a depth image, or integratePointCloud(*frame.rays,
   *    sensor origin) for a scan, the sensor origin being world_T_sensor's
   *    translation; each then clears (and merges) the non-planar cells its view holds
   *    as Params asks;
   * 3. noteObservationOrder(frame.observation_order);
   * 4. with frame.window_half_size_m > 0, removeOutside() of the box of that
   *    half-size around the sensor origin in x and y, unbounded in z.
   * The result is that of the four calls made in this order.
   * \param[in] frame the frame's measurements (MapFrame documents their shapes,
   * units and frames)
   * \return what the rolling window removed (all zero when it is off)
   * \throws planar_grid::Exception before the map changes when frame sets neither or
   * both of depth and rays, for a depth image whose depths are not width x height (>
   * 0) or whose intrinsics are not finite with positive focal lengths, when the
   * numbers of feature points and probabilities
   * differ, for a non-finite world_T_sensor or observation_order, or for a negative
   * or non-finite window_half_size_m */
  MapWindowRemoval integrate(const MapFrame& frame);

  /** \brief Removes the non-planar cells that lie on a plane of the map
   * (SurfaceLayer::removeNonPlanarCellsOnPlanes(); called by integrateSurface() with
   * Params::planes_replace_non_planar).
   * \return the number of cells removed */
  std::size_t removeNonPlanarCellsOnPlanes()
  {
    invalidateQueryCache();
    return surface_.removeNonPlanarCellsOnPlanes();
  }

  /** \brief Removes the non-planar cells for which \a in_view (called with a cell's
   * centre and bounding radius, meters, world frame) returns true and whose voxels
   * the space layer holds observed free, more than half of them, or occupied, fewer
   * than Params::non_planar_min_occupied of them (see Params::clear_non_planar;
   * called by the integrations, public for maps whose space layer is filled
   * otherwise). \return the number of cells removed */
  std::size_t clearNonPlanarCells(
    const std::function<bool(const Eigen::Vector3f&, float)>& in_view);

  /** \brief clearNonPlanarCells(in_view) with \a min_occupied (share, [0, 1]) in
   * place of Params::non_planar_min_occupied; 0 applies the free rule alone. */
  std::size_t
  clearNonPlanarCells(const std::function<bool(const Eigen::Vector3f&, float)>& in_view,
                      double min_occupied);

  /** \brief Merges the non-planar cells for which \a in_view (called with a cell's
   * centre and bounding radius, meters, world frame) returns true, pairwise into their
   * bounding boxes, where the space layer holds at least
   * Params::non_planar_min_occupied of a box's voxels occupied and at most half of
   * them free (see Params::merge_non_planar; called by integrateDepthImage(), public
   * for maps whose space layer is filled otherwise). \return the number of cells
   * removed by merging */
  std::size_t mergeNonPlanarCells(
    const std::function<bool(const Eigen::Vector3f&, float)>& in_view);

  /** \brief Removes the planes' raster cells for which \a in_view (called with a
   * cell's centre on its plane and a radius of resolution_m, meters, world frame)
   * returns true, that \a sensor_origin sees within 60 degrees of their plane's
   * normal, and whose voxel and the two voxels behind it the space layer holds
   * observed free (the rule of Params::clear_planar; called by the integrations when
   * it is set, public for maps whose space layer is filled otherwise).
   * \param[in] in_view whether a cell (centre, radius) is in the view's reach
   * \param[in] sensor_origin the view's sensor position, meters, world frame
   * \return the number of raster cells removed */
  std::size_t
  clearPlanarCells(const std::function<bool(const Eigen::Vector3f&, float)>& in_view,
                   const Eigen::Vector3f& sensor_origin);

  /** \brief State at \a point: OCCUPIED inside a cuboid with probability >=
   * occupancy_thres, FREE inside one below it, else the space layer's state. */
  [[nodiscard]] SpaceState getState(const Eigen::Vector3f& point) const;

  /** \brief Occupancy probability at \a point: the cuboid's probability inside a
   * cuboid; else 0.971 / 0.1192 / 0.5 (OctoMap's clamping bounds) for an occupied /
   * free / unknown voxel. */
  [[nodiscard]] float getOccupancy(const Eigen::Vector3f& point) const;

  /** \brief Casts a ray to the first occupied cell of either layer.
   * \param[in] origin, direction the ray (origin finite; direction finite, of any
   * length > 0), meters
   * \param[in] max_range_m largest distance, meters, >= 0 (infinity: to the end of the
   * map)
   * \param[out] hit the entry point into the occupied cuboid or the occupied voxel's
   * centre, meters
   * \return true on a hit within max_range_m
   * \throws planar_grid::Exception for a non-finite origin, a zero or non-finite
   * direction, or a negative or NaN range */
  bool castRay(const Eigen::Vector3f& origin,
               const Eigen::Vector3f& direction,
               double max_range_m,
               Eigen::Vector3f& hit) const;

  /** \brief Distance to the nearest obstacle for a batch of points: the exact
   * Euclidean distance to the union of the occupied cuboids (probability >= the
   * surface layer's occupancy_thres, as oriented boxes) and the occupied voxels of the
   * space layer (axis-aligned boxes of edge resolution_m), and with
   * \a unknown_is_occupied the space layer's unknown space too (occluded voxels and,
   * with the unknown prior, never-observed space: every voxel not observed inside the
   * stored blocks' bounds and all space outside them). Cuboids do not carve the space
   * layer: an occupied voxel inside a free cuboid is an obstacle.
   * Obstacles are indexed by a bounding-volume hierarchy built on the first query for
   * each \a unknown_is_occupied and kept until the map changes (any non-const method).
   * \param[in] points 3 x N points, meters, world frame
   * \param[in] max_distance_m the cap, meters (> 0): distances beyond it are returned
   * as max_distance_m with a zero gradient
   * \param[out] distances N distances, meters, in [0, max_distance_m]; 0 inside an
   * obstacle (boundary included); NaN for a non-finite point
   * \param[out] gradients 3 x N unit vectors: outside an obstacle, from the nearest
   * obstacle point toward the point (the gradient of the distance); inside one, the
   * outward normal of the nearest face of a box containing the point (this may point
   * into a neighbouring obstacle box); zero beyond the cap, NaN for a non-finite point
   * \param[in] unknown_is_occupied count unknown space as an obstacle
   * \throws planar_grid::Exception for max_distance_m <= 0 or not finite, or outputs
   * whose sizes do not match \a points */
  void getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                   double max_distance_m,
                   Eigen::Ref<Eigen::VectorXf> distances,
                   Eigen::Ref<Eigen::Matrix3Xf> gradients,
                   bool unknown_is_occupied = false) const;

  /** \brief Collision test for a batch of bodies against the obstacles of
   * getDistance() (same index): exact separating-axis tests between a box body and
   * each obstacle box (15 axes), closest point for a sphere. Touching counts as a
   * collision (closed sets).
   * \param[in] bodies oriented boxes and spheres, world frame, meters
   * \param[in] unknown_is_occupied count unknown space as an obstacle
   * \return one value per body: 1 free, 0 in collision (or a non-finite body, or
   * negative extents) */
  std::vector<std::uint8_t> isCollisionFree(const CollisionBodies& bodies,
                                            bool unknown_is_occupied = false) const;

  /** \brief Projects the map over a height band into a 2D occupancy grid. A cell
   * (its centre's vertical line, the column) is OCCUPIED when an occupied cuboid or
   * occupied voxel meets its column inside the band, or when a terrain cuboid steeper
   * than max_slope_rad crosses the column (at any height up to the band's top); else
   * FREE when an observed free voxel meets the column inside the band or a walkable
   * terrain cuboid crosses it; else UNKNOWN (never seen).
   * \throws planar_grid::Exception for invalid \a params or a grid of more than 1e8
   * cells */
  OccupancyGrid2D computeOccupancyGrid2D(const OccupancyGrid2DParams& params) const;

  /** \brief Writes computeOccupancyGrid2D() as a ROS map_server map: the YAML file
   * \a yaml_path (image, mode trinary, resolution, origin [x, y, 0], negate 0,
   * occupied_thresh, free_thresh) and beside it the 8-bit binary PGM (P5) it names,
   * the YAML's name with ".pgm" for ".yaml": 0 occupied, 254 free, 205 unknown, top
   * row at the largest y. Both files are written atomically (temporary file, rename),
   * the image first.
   * \return the grid written
   * \throws planar_grid::Exception for invalid params; planar_grid::IOError for a
   * path not ending in ".yaml" or ".yml", a missing folder or a failed write */
  OccupancyGrid2D exportOccupancyGrid2D(const std::string& yaml_path,
                                        const OccupancyGrid2DParams& params) const;

  /** \brief Drops the query index of getDistance() and isCollisionFree() (the
   * non-const methods do it; call it after changing the space layer through a
   * reference kept from getSpaceLayer()). */
  void invalidateQueryCache();

  /** \brief The surface layer. */
  const SurfaceLayer& getSurfaceLayer() const { return surface_; }
  /** \brief The explicit space layer. */
  const ExplicitSpaceGrid& getSpaceLayer() const { return space_; }
  /** \brief The explicit space layer (e.g. to set voxels in tests); drops the query
   * index (invalidateQueryCache()). */
  ExplicitSpaceGrid& getSpaceLayer()
  {
    invalidateQueryCache();
    return space_;
  }

  /** \brief Memory held, bytes. */
  [[nodiscard]] MapMemory getMemory() const;

  /** \brief Keeps the part of the map inside \a keep and drops the rest from both
   * layers (the rolling window of a long run, so that its memory stays bounded):
   * ExplicitSpaceGrid::removeOutside() (voxels whose centres lie outside go back to
   * never observed) and SurfaceLayer::removeOutside() (raster cells whose face centres
   * lie outside, planes left without cells, non-planar cells whose centres lie
   * outside). The storage they held is freed: getMemory() falls with the content.
   * Inside the box getState() answers as before, except within a cell of the boundary
   * where a cuboid that joined cells on both sides is re-covered from the cells left.
   * The result saves and loads like any map.
   * \param[in] keep the box, meters, world frame; a bound may be +-infinity (that axis
   * unlimited); an empty box (min > max on an axis) or a NaN bound keeps nothing
   * \return what was removed */
  MapWindowRemoval removeOutside(const Eigen::AlignedBox3f& keep);

  /** \brief Writes the map file (format in the class brief) to a temporary file in the
   * same folder, then renames it over \a path: a crash never leaves a half-written map.
   * \throws planar_grid::IOError when it cannot be written */
  void save(const std::string& path) const;

  /** \brief Reads a map file written by save().
   * \throws planar_grid::IOError naming the file and what is wrong for a missing,
   * truncated or corrupt file, an unknown version or a bad header value */
  static PlanarGridMap load(const std::string& path);

  /** \brief The content of the map file save() writes (text header and data
   * sections), in memory (e.g. to embed the map in a pipeline checkpoint).
   * \param[out] bytes replaced by the file content */
  void serialize(std::string& bytes) const;

  /** \brief Decodes serialize()'s output with every check of load().
   * \param[in] bytes the file content
   * \param[in] name names the data in error messages (a file path)
   * \throws planar_grid::IOError as load() */
  static PlanarGridMap deserialize(const std::string& bytes, const std::string& name);

  /** \brief Writes the map as an OctoMap octree of resolution_m voxels, atomically.
   * The space layer's observed voxels go in as ExplicitSpaceGrid::insertIntoOcTree()
   * puts them (occupied at log-odds clamping_thres_max, observed free at
   * clamping_thres_min; occluded and never-observed space absent, whatever the prior);
   * then every voxel whose centre lies in a cuboid (PlanarCuboid::contains; the
   * lowest-index cuboid where several do, as getOccupancy()) takes the cuboid's
   * occupancy as log-odds, log(p / (1 - p)) with p clamped to [1e-4, 1 - 1e-4], over
   * the space layer's state. The tree's occupancy_thres is the surface layer's.
   * \param[in] path ".ot": OctoMap's full format (AbstractOcTree::write), which keeps
   * each voxel's log-odds (a float); any other name (".bt"): the binary format
   * (OcTree::writeBinary), which keeps the maximum-likelihood state only (occupied
   * where p >= occupancy_thres, else free); a reader of a .ot file judges occupancy at
   * its own threshold (liboctomap's default 0.5)
   * \return the nodes, leaves and voxels the file holds
   * \throws planar_grid::IOError when the file cannot be written */
  OctoMapExportSummary exportOctoMap(const std::string& path) const;

  /** \brief The map as the OctoMap octree exportOctoMap() writes, in memory (e.g. to
   * send as an octomap_msgs/Octomap without a file): \a tree is cleared, takes
   * resolution_m and the surface layer's occupancy_thres, and is filled and pruned as
   * exportOctoMap() does. Uses liboctomap (link octomap; the header
   * <octomap/OcTree.h> is the caller's).
   * \param[out] tree the octree, replaced
   * \param[in] max_likelihood true: each voxel's maximum-likelihood state, what the
   * binary format (.bt, OcTree::writeBinary) keeps; false: each voxel's log-odds, what
   * the full format (.ot) keeps
   * \return the nodes, leaves and voxels the tree holds */
  OctoMapExportSummary toOcTree(octomap::OcTree& tree, bool max_likelihood) const;
  /** \brief Writes the cuboids as .ply or .vtk (SurfaceLayer::exportMesh). */
  void exportMesh(const std::string& path) const { surface_.exportMesh(path); }

  /** \brief True when both layers are equal. */
  [[nodiscard]] bool operator==(const PlanarGridMap& other) const
  {
    return space_ == other.space_ && surface_ == other.surface_;
  }
  /** \brief True when a layer differs. */
  [[nodiscard]] bool operator!=(const PlanarGridMap& other) const
  {
    return !(*this == other);
  }

private:
  /** \brief Inserts both layers into \a tree (exportOctoMap()'s rule, unpruned);
   * \return the voxels left out, outside OctoMap's key range */
  std::size_t fillOcTree(octomap::OcTree& tree) const;
  /** \brief The space layer's voxels of a cuboid (those whose centres it contains and
   * the voxel of its centre), and how many of them are free and occupied. */
  struct VoxelShares {
    std::size_t voxels{0};
    std::size_t free{0};
    std::size_t occupied{0};
    /** \brief True when at most half of the voxels are free and at least
     * \a min_occupied (share) of them occupied: the evidence that keeps a non-planar
     * cell (clearNonPlanarCells()) and lets two merge (mergeNonPlanarCells()). */
    [[nodiscard]] bool heldOccupied(double min_occupied) const
    {
      return 2 * free <= voxels
             && static_cast<double>(occupied)
                  >= min_occupied * static_cast<double>(voxels);
    }
  };
  /** \brief Counts the space layer's states over \a cuboid's voxels. */
  [[nodiscard]] VoxelShares voxelShares(const PlanarCuboid& cuboid) const;
  /** \brief \a in_view of \a cuboid's centre, with its half diagonal grown by a voxel
   * diagonal as the radius (a view may mark a voxel whose centre is outside it). */
  [[nodiscard]] bool
  cuboidInView(const PlanarCuboid& cuboid,
               const std::function<bool(const Eigen::Vector3f&, float)>& in_view) const;
  /** \brief The parameters (validated). */
  Params params_;
  /** \brief The surface layer. */
  SurfaceLayer surface_;
  /** \brief The explicit space layer. */
  ExplicitSpaceGrid space_;
  /** \brief The order keys of the views the map holds. */
  ObservationSpan observation_span_;
  /** \brief The obstacle index of getDistance() and isCollisionFree(), built lazily
   * under its own mutex; replaced by every non-const method. */
  std::shared_ptr<map_queries::QueryCache> query_cache_;
};

} // namespace planar_grid
