// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/surface/rectangle_merge.h>

#include <pcl/memory.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each numeric SurfaceLayer::Params member, declared once:
 * the SurfaceLayer constructor tests the values against them and the pipeline's
 * map_integration stage table takes them as its ranges (the map's resolution_m is the
 * surface layer's). \ingroup map */
namespace surface_layer_ranges {
/** \brief Raster cell edge: [0.001, 10] meters. */
inline constexpr ParamRange RESOLUTION = ParamRange::closed(0.001, 10.0);
/** \brief Extrusion of the planar cuboids: (0, 10] meters. */
inline constexpr ParamRange THICKNESS = ParamRange::openMin(0.0, 10.0);
/** \brief Largest normal angle of one plane's views: (0, 1.5] radians. */
inline constexpr ParamRange PLANE_MERGE_ANGLE = ParamRange::openMin(0.0, 1.5);
/** \brief Largest RMS distance of a view's faces to the joint plane: (0, 10] meters.
 */
inline constexpr ParamRange PLANE_MERGE_DISTANCE = ParamRange::openMin(0.0, 10.0);
/** \brief Occupancy class boundary, a probability: (0, 1). */
inline constexpr ParamRange OCCUPANCY_THRES = ParamRange::open(0.0, 1.0);
/** \brief Distance of a feature that counts for a planar cell: [0, 10] meters. */
inline constexpr ParamRange FEATURE_DISTANCE = ParamRange::closed(0.0, 10.0);
/** \brief Widest gap closed in a plane's raster: [0, 32] cells. */
inline constexpr ParamRange CLOSE_GAPS = ParamRange::closed(0, 32);
/** \brief merge_rule DENSITY, smallest share of a rectangle's cells: [0.5, 1]. */
inline constexpr ParamRange COVER_DENSITY = ParamRange::closed(0.5, 1.0);
/** \brief Largest distance at which a parallel plane's cells are absorbed: [0, 10]
 * meters. */
inline constexpr ParamRange ABSORB_DISTANCE = ParamRange::closed(0.0, 10.0);
/** \brief Side of the tiles that bound a level plane: [0, 1000] meters (0: level
 * planes are unbounded). */
inline constexpr ParamRange TERRAIN_PLANE_TILE = ParamRange::closed(0.0, 1000.0);
/** \brief SurfaceLayer::Params::terrain_cover_density. */
inline constexpr ParamRange TERRAIN_COVER_DENSITY = ParamRange::closed(0.5, 1.0);
/** \brief SurfaceLayer::Params::min_plane_cells: [0, 1000000] cells. */
inline constexpr ParamRange MIN_PLANE_CELLS = ParamRange::closed(0, 1000000);
} // namespace surface_layer_ranges

/** \brief A map plane whose normal is within this angle of the world z axis is level
 * (terrain, a floor, a step, a table top; SurfaceLayer::Params::terrain_plane_tile_m):
 * 0.3 rad, ground_removal's default terrain_max_slope_rad. */
inline constexpr double LEVEL_MAX_ANGLE_RAD = 0.3;

/** \brief Plane models [a, b, c, d] (unit normal, meters), aligned allocator
 * (fixed-size vectorizable Eigen types need it in std::vector).
 * \ingroup map */
using PlaneModels =
  std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>>;

/** \brief How the surface layer covers a map plane's raster with rectangles (the
 * merge of Fig. 6b): the rules of planar_grid::RectangleMergeRule, whose toString()
 * names them. \ingroup map */
using SurfaceMergeRule = RectangleMergeRule;

/** \brief Parses "paper", "min_rectangles" or "density"
 * (rectangleMergeRuleFromString()).
 * \throws planar_grid::Exception for any other name \ingroup map */
SurfaceMergeRule surfaceMergeRuleFromString(const std::string& name);

/** \brief The surface layer of the planar grid map (paper Sec. III-F, Figs. 6-8): the
 * planar and non-planar cuboids of every frame, in the world frame, merged across
 * frames so that the map grows with the surface seen, not with the number of frames.
 *
 * - Evidence: each map plane accumulates the area moments of the faces of the planar
 *   cuboids it received (weight = face area in m^2, the face's centre and its
 *   in-plane spread width^2 / 12 and height^2 / 12 along its axes: the exact first
 *   and second moments of the face rectangles), kept in double about an anchor (the
 *   first face's centre). Its plane [a, b, c, d] (getPlanes()) is the least-squares
 *   plane of that evidence: the normal is the eigenvector of the smallest eigenvalue
 *   of the covariance (refitted when the middle eigenvalue is at least 4 times the
 *   smallest, i.e. the evidence spans a plane, and within plane_merge_angle_rad of the
 *   current normal; otherwise the normal is kept), and d puts the plane through the
 *   centroid. So the plane converges to the surface as frames accumulate, instead of
 *   keeping the first frame's estimate.
 * - Association: a frame's plane, oriented like its cuboids' normals (toward that
 *   frame's sensor), joins a map plane when one plane explains both: their normals
 *   are within plane_merge_angle_rad (same orientation: the two faces of a wall stay
 *   separate), and the least-squares plane of the map plane's evidence together with
 *   the frame's faces has each of the two within plane_merge_distance_m (root mean
 *   square distance of the area-weighted faces to that plane, i.e. the distance where
 *   the faces are, not a difference of offsets d). Among several such map planes the
 *   one nearest to the frame's faces wins (lowest index on a tie); with none, the
 *   frame's plane starts a new map plane.
 * - Map planes that converge are merged: after a frame, a plane it touched and any
 *   other plane that pass the same test and whose rasters overlap or are adjacent (a
 *   cell centre of one projects into or next to an observed cell of the other)
 *   become one; so do two planes stacked over each other (one surface mapped twice a
 *   little apart): normals within plane_merge_angle_rad (facing the same way), not
 *   both level, the weaker's evidence at least a quarter of the stronger's, and at
 *   least a quarter of the smaller raster's observed cells, placed on their plane,
 *   within absorb_distance_m of the other plane and projecting into an observed cell
 *   of it. The plane with more evidence (lower index on a tie) survives; the
 *   other's raster is re-projected into the survivor's frame (every cell whose
 *   centre falls in an observed cell of the other is observed; the feature sums of a
 *   cell go to the cell containing its centre) and its moments are added.
 * - Raster frame: a map plane has a fixed 2D frame taken from the plane when it was
 *   created: origin -d n on that plane, u = z x n normalised (world x projected when
 *   the plane is horizontal), v = n x u, the convention of
 *   PlanarCuboidApproximation for up = +z. Its sparse raster holds square cells of
 *   edge resolution_m, cell (i, j) covering [i, i + 1) x [j, j + 1) resolution_m in
 *   (u, v). The frame stays fixed as the plane is refined (re-anchoring would move
 *   cells), unless the refined normal drifts more than plane_merge_angle_rad / 2 from
 *   the frame's normal: then the raster is re-projected into a frame of the refined
 *   plane.
 * - Cells: a frame's planar cuboid marks the raster cells whose centres fall inside
 *   its face (projected along the normal of the raster frame, tolerance 1 % of a
 *   cell).
 * - Cuboids (rebuilt lazily on the next query, only for planes changed since):
 *   first the observed cells are closed over gaps of up to close_gaps_cells cells
 *   (every run of unobserved cells of at most that length between two observed cells
 *   of one row or of one column is filled: the union of the morphological closings
 *   with a horizontal and a vertical segment of close_gaps_cells + 1 cells; a gap
 *   open on one side, like a ragged border, is not filled). Filled cells carry no
 *   evidence; they take their neighbours' occupancy like any cell without features
 *   and are not counted by getCellCount(). Then the cells are covered by rectangles
 *   of one occupancy class (probability >= occupancy_thres or below) with merge_rule:
 *   every observed or filled cell lies in one rectangle; PAPER and MIN_RECTANGLES
 *   cover no other cell, DENSITY up to 1 - cover_density of each rectangle's area in
 *   unobserved cells and cells of the other class. Each rectangle's face is placed on
 * the refined plane: the raster frame is projected onto it along the plane's normal
 * (the rectangle's centre projected, its horizontal axis u projected and normalised,
 * width and height scaled by the lengths of the projected u and v, within
 * cos(plane_merge_angle_rad / 2) of 1), so rectangles adjacent in the raster stay
 * adjacent up to a shear of the order of the angle squared (at most 0.15 mm per metre
 * for a refined plane 1 degree off the frame). It is extruded by thickness_m behind the
 * face (Fig. 6c). Rectangles are listed by their first row, then first column. The
 * raster is a set, so the same frame integrated twice gives the same cells and cuboids
 * as once.
 * - Non-planar cuboids (Fig. 7), and cuboids whose plane_id is -1, out of range or
 *   not is_planar, are stored as given; the newest view wins, as in the space layer:
 *   a non-planar cuboid of a new frame removes every stored non-planar cell of an
 *   earlier frame that it overlaps substantially, i.e. whose centre lies inside the
 *   new box grown by resolution_m / 2 on every side, or whose box contains the new
 *   box's centre (so a region re-split differently by the next frame's quadtree is
 *   replaced, not piled up; a stored cell that no new cell overlaps so is kept).
 *   Cells of the same frame never remove each other, except that of two with the
 *   same key (centre quantised to resolution_m cells, extents rounded to
 *   resolution_m) the later is kept. Candidates come from a spatial index of the
 *   stored cells' bounding boxes (bins of 4 cells: a sorted array built by each
 *   integrate() that has non-planar cuboids, not held), so integrate() costs
 *   O(stored cells log stored cells + new cells x cells per bin).
 * - Occupancy (end of Sec. III-F): a planar cell's probability is the mean probability
 *   of the features that fell inside it (all frames; a feature counts when it is
 *   within feature_distance_m of a map plane the frame touched and its cell is
 *   observed); a cell with none takes the mean of its 8 neighbours that have a value,
 *   propagated outward layer by layer; cells not reached (a plane without features)
 *   keep 0.5. A cell stores its probability sum as a float and its feature count as
 *   a 16-bit count; past 65535 features the count stays at 65535 and the sum is
 *   rescaled to keep the mean. A planar cuboid's probability is the mean over its
 *   cells and its point_count the number of features in it. A non-planar cuboid's
 *   probability is the mean of its frame's features inside the box, 0.5 without any
 *   (neighbours of non-planar cells are not defined on a raster).
 * - Small planes: after a frame, a map plane of fewer than min_plane_cells observed
 *   cells that none of the frame's planes joined becomes non-planar cells, one box
 *   per observed cell (its face on the refined plane, thickness_m deep) holding the
 *   cell's feature evidence, and the plane goes.
 * - Memory: a raster is a sorted array of tiles of 8 x 8 cells (tile key, a 64-bit
 *   mask of the observed cells and one of the cells with features: 24 B per tile)
 *   and the evidence (probability sum f32, feature count u16: 6 B) of the cells with
 *   features only. A plane holds its frame and refined planes (32 B) and its moments
 *   (13 doubles); the frame's axes and the faces' placement are derived when needed.
 *   Its cover is cached, 24 B per rectangle. A non-planar cell is 40 B (centre,
 *   extents, f64 sum, u32 count and the index of its orientation in a table of the
 *   distinct (normal, horizontal axis) pairs, 24 B each: typically one for a whole
 *   map). The vectors hold no spare capacity after integrate(). The cuboid list is
 *   not held: getCuboids() builds it.
 * - Queries (findCuboid(), castRay()) use a copy of the cuboids and a spatial hash of
 *   their bounding boxes (bins of 4 cells), built on the first query and freed by
 *   integrate() (it is stale then); getMemoryBytes() counts them while held. Const
 *   methods are safe to call from several threads (a mutex guards the builds),
 *   integrate() is not.
 * - Invalid input (non-finite cuboids or features, probabilities outside [0, 1], a
 *   face of more than 1e7 cells) is skipped with a PCL_WARN; integrate() never throws.
 * \ingroup map */
class SurfaceLayer {
public:
  /** \brief Parameters with defaults and valid ranges. */
  struct Params {
    /** Raster cell edge in each plane, meters; in surface_layer_ranges::RESOLUTION (the
     * paper's minimum cell). */
    double resolution_m{0.1};
    /** Extrusion of the planar cuboids behind their face, meters; in
     * surface_layer_ranges::THICKNESS. */
    double thickness_m{0.1};
    /** Largest angle between the normals of one plane seen in two frames, radians;
     * in surface_layer_ranges::PLANE_MERGE_ANGLE. */
    double plane_merge_angle_rad{0.1};
    /** Largest root mean square distance of a frame's faces (or of a map plane's
     * evidence) to the least-squares plane fitted to them together with the map
     * plane they join, meters; in surface_layer_ranges::PLANE_MERGE_DISTANCE. */
    double plane_merge_distance_m{0.15};
    /** Occupancy class boundary for merging cells, a probability in
     * surface_layer_ranges::OCCUPANCY_THRES. */
    double occupancy_thres{0.5};
    /** A feature counts for a planar cell when within this distance of the plane,
     * meters; in surface_layer_ranges::FEATURE_DISTANCE. */
    double feature_distance_m{0.1};
    /** Widest gap closed in a plane's raster before the merge, in cells; in
     * surface_layer_ranges::CLOSE_GAPS
     * (0: no closing; 2: holes and notches up to 2 cells wide, i.e. 0.2 m at the
     * paper's 0.1 m cell, are filled). */
    int close_gaps_cells{2};
    /** How the closed raster is covered by rectangles (the merge of Fig. 6b). */
    SurfaceMergeRule merge_rule{SurfaceMergeRule::MIN_RECTANGLES};
    /** With merge_rule DENSITY: the smallest share of a rectangle's cells that are
     * cells of the plane's raster (observed or filled), in
     * surface_layer_ranges::COVER_DENSITY; 1 gives exact rectangles like the other
     * rules. The paper's D_T. */
    double cover_density{0.9};
    /** Largest distance along a stronger plane's normal at which the cells of a
     * plane parallel to it (normals within plane_merge_angle_rad, facing the same
     * way) are the same surface seen at another depth and move to it
     * (absorbOverlappingPlaneCells()), and the largest gap at which two such planes
     * of comparable evidence, one stacked over the other, merge (the class
     * documentation), meters; in surface_layer_ranges::ABSORB_DISTANCE; below
     * resolution_m / 2 it is resolution_m / 2, the tolerance for planes that are not
     * parallel. 0.5 m is about twice the stereo depth error (paper eq. 4) at the range
     * the pipeline maps planes, 0.3 m: two views of one wall, each off by up to that
     * error. */
    double absorb_distance_m{0.5};
    /** Side of the square tiles of the world's x, y plane that bound a level plane
     * (normal within LEVEL_MAX_ANGLE_RAD of the z axis: road, pavement, floor),
     * meters; in surface_layer_ranges::TERRAIN_PLANE_TILE. With a side > 0, a level
     * frame plane joins only a level map plane whose evidence's centroid lies in the
     * same tile as its own, two level map planes of different tiles never merge, and
     * two level planes never absorb each other's cells (a curb, a stair is a real
     * step): terrain stays piecewise planar, so a road that sags or crowns over tens
     * of meters is not fitted by one plane. Give the frames' level planes split at the
     * same tiles (the pipeline's ground_removal with its terrain_plane_tile_m). 0:
     * level planes join, merge and absorb like any other. */
    double terrain_plane_tile_m{0.0};
    /** With terrain tiles (terrain_plane_tile_m > 0) and the DENSITY rule, the
     * cover_density of the level planes; in surface_layer_ranges::
     * TERRAIN_COVER_DENSITY. A road or a floor is seen sparsely and at a grazing
     * angle, so its tiles' rasters hold many unobserved cells that a loose cover
     * spans and marks occupied; walls keep cover_density. 1: the level planes'
     * rectangles hold observed cells only. */
    double terrain_cover_density{0.9};
    /** getCuboids() leaves out a non-planar cell of one voxel (volume at most 1.5
     * resolution_m^3) that no other cuboid touches (none within resolution_m of its
     * centre): a speckle of the stereo noise, not an object (the split boxes of
     * Fig. 7 are clusters of points). As PCL's RadiusOutlierRemoval drops a point
     * without neighbours. The cell stays stored with its evidence, so a neighbour
     * seen later brings it back; getCellCount() and getMemoryBytes() count it. */
    bool skip_isolated_non_planar{true};
    /** Smallest number of observed raster cells of a map plane that a frame did not
     * see (none of the frame's planes joined it); in surface_layer_ranges::
     * MIN_PLANE_CELLS. After integrate(), such a plane of fewer cells goes, and each
     * of its observed cells becomes a non-planar box of one cell (resolution_m square
     * on the plane, thickness_m deep) with the cell's feature evidence: a plane of a
     * cell or two at the map's cell size is a fragment of clutter or of a surface
     * seen from afar more often than a surface, and its record (about 200 bytes)
     * outweighs its cells. A plane that frames keep seeing keeps growing; a surface
     * seen again later makes a new plane, which replaces the boxes on it
     * (removeNonPlanarCellsOnPlanes()). 0: planes are never demoted. */
    int min_plane_cells{4};
  };

  /** \brief Throws planar_grid::Exception for out-of-range parameters. */
  explicit SurfaceLayer(const Params& params);
  SurfaceLayer(const SurfaceLayer&) = delete;
  SurfaceLayer& operator=(const SurfaceLayer&) = delete;
  /** \brief Moves (defined in the .cpp, where Impl is complete; the moved-from layer
   * may only be destroyed or assigned to). */
  SurfaceLayer(SurfaceLayer&&) noexcept;
  /** \brief Move assignment (see the move constructor). */
  SurfaceLayer& operator=(SurfaceLayer&&) noexcept;
  ~SurfaceLayer();

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Merges one frame's cells into the layer.
   * \param[in] cuboids the frame's cuboids in the world frame; plane_id indexes
   * \a planes (-1: non-planar); a plane_id out of range is treated as non-planar with
   * a PCL_WARN
   * \param[in] planes the frame's plane models in the world frame
   * \param[in] features key feature points in the world frame, meters
   * \param[in] probabilities one occupancy probability per feature, in [0, 1] (a size
   * other than the features' ignores the features with a PCL_WARN) */
  void integrate(const PlanarCuboids& cuboids,
                 const PlaneModels& planes,
                 const pcl::PointCloud<pcl::PointXYZ>& features,
                 const std::vector<float>& probabilities);

  /** \brief Merges another layer (a map of another recording) into this one: its
   * planes join this layer's through the association integrate() uses, its cells are
   * added.
   * - Planes: each plane of \a other, moved into this frame, goes through the
   *   association of integrate() (same criteria: normals of the same orientation
   *   within plane_merge_angle_rad, the least-squares plane of both evidence sets
   *   within plane_merge_distance_m of each; the nearest such plane wins, the planes
   *   of \a other added so far included). A plane that matches one of this layer
   *   becomes that plane: its moments are added, the plane is refitted to them and
   *   the raster of the plane with less evidence is re-projected into the frame of the
   *   other, with its feature evidence (on equal evidence, the plane whose frame plane
   *   [a, b, c, d] is lexicographically first keeps its frame). A plane without a match
   *   is added. Then the planes that changed merge with any plane that converged with
   *   them, and drifted planes take a new raster frame, as after integrate().
   * - Direction: which plane keeps its frame depends on the planes, not on the layer
   *   they come from, so merging A into B and B into A give the same planes, cells and
   *   cuboids up to their order wherever each plane matches at most one plane of the
   *   other layer. Where one layer holds a surface as several planes, the order in
   *   which the association meets them can pair them differently.
   * - Non-planar cells: both layers' cells are kept (neither recording is newer
   *   than the other); a cell of \a other whose geometry equals a stored cell's
   *   (same centre, extents and axes) adds its feature evidence to it instead. Of two
   *   cells with the same key (centre quantised to resolution_m, extents rounded) but
   *   other axes or centres, the one with more evidence stays (more features, then
   *   the larger probability sum, then the lexicographically smaller geometry), so
   *   the layer keeps one cell per key in either merge direction.
   * - \a this_T_other exactly the identity: planes and cells are copied as they
   *   are. Otherwise every plane's frame, refined plane and moments are moved exactly,
   *   and its raster cells are re-projected into a raster frame of the moved plane
   *   (cell centres to cells, as when two map planes merge: an observed area stays
   *   observed, up to one cell at its border).
   * \param[in] other the layer merged in (unchanged; not this layer)
   * \param[in] this_T_other rigid transform from \a other's world frame to this
   * layer's, meters
   * \throws planar_grid::Exception naming the parameter when a parameter of the two
   * layers differs (every Params member must be equal), when \a other is this layer,
   * or for a transform that is not finite and rigid; the layer is then unchanged */
  void merge(const SurfaceLayer& other, const Eigen::Isometry3d& this_T_other);

  /** \brief Removes the non-planar cells for which \a remove returns true. The
   * cells keep their order; the planes are untouched.
   * \param[in] remove called once per non-planar cell with its cuboid (centre,
   * axes and size in meters; probability and point_count unset)
   * \return the number of cells removed */
  std::size_t
  removeNonPlanarCells(const std::function<bool(const PlanarCuboid&)>& remove);

  /** \brief Merges touching non-planar cells of one orientation into their bounding
   * box (Fig. 7's boxes across frames). In rounds, until a round merges nothing:
   * every pair of cells with equal axes for which \a candidate holds, whose extents
   * along each of the three axes overlap or lie at most resolution_m / 2 apart, is a
   * candidate; smallest bounding box first, each cell at most once per round, a pair
   * becomes its bounding box when the cells merged into it fill at least \a min_fill
   * of its volume and \a accept(bounding box) returns true. The merged
   * cell sums the two cells' features (its probability is their features' mean).
   * Planar cells are not changed.
   * \param[in] candidate called once per non-planar cell per call with its cuboid
   * (centre, axes and size in meters; probability and point_count unset)
   * \param[in] accept called with the bounding box of a candidate pair (the same
   * fields)
   * \param[in] min_fill share of the bounding box's volume the merged cells' volumes
   * must fill (their overlaps counted once), in [0, 1]; a cell merged in an earlier
   * call counts as filled
   * \return the number of cells removed (the cell count before less after)
   * \throws planar_grid::Exception for \a min_fill outside [0, 1] (the layer unchanged)
   */
  std::size_t
  mergeNonPlanarCells(const std::function<bool(const PlanarCuboid&)>& candidate,
                      const std::function<bool(const PlanarCuboid&)>& accept,
                      double min_fill);

  /** \brief Removes the planes' observed raster cells for which \a remove returns
   * true, with their feature evidence; a plane left without cells is removed. The
   * planes' least-squares models are not changed.
   * \param[in] remove called once per observed raster cell with the centre of the
   * cell on its plane (meters, world) and the plane's unit normal (toward the
   * sensors that saw it)
   * \return the number of cells removed */
  std::size_t
  removePlaneCells(const std::function<bool(const Eigen::Vector3f& centre,
                                            const Eigen::Vector3f& normal)>& remove);

  /** \brief Removes the non-planar cells lying on a map plane: a cell whose centre
   * lies inside a planar cuboid grown by resolution_m / 2 on every side, and whose
   * whole footprint on that plane (its extent along the cuboid's two face axes,
   * tested at points at most resolution_m apart, corners included) lies inside that
   * plane's cuboids grown likewise. Cells reaching past the plane's cells (an edge, a
   * hole) stay, and so do cells more than 64 cells across. Planar cells are not
   * changed; the covers of the planes changed since the last query are rebuilt.
   * After the first call, a call tests only the cells within reach of what changed
   * since the previous one (the non-planar cells integrate() added, the cuboids of
   * the planes whose cover was rebuilt); every cell again after a plane was removed,
   * a merge() or a deserialize(). The result is that of testing every cell, at a cost
   * that follows the frame, not the map.
   * \return the number of cells removed */
  std::size_t removeNonPlanarCellsOnPlanes();

  /** \brief Moves the rectangles of a map plane that lie on another plane with more
   * evidence (a larger moments weight; the lower index on a tie) to that plane: a
   * rectangle of a plane's cover moves when every observed raster cell in it has its
   * face centre and four face corners inside that one plane's cuboids grown by
   * resolution_m / 2 on every side; for a plane parallel to the other (normals
   * within plane_merge_angle_rad, facing the same way), within absorb_distance_m of
   * those cuboids along
   * their normal (and resolution_m / 2 along their faces). Its cells' feature
   * evidence joins the other
   * plane's cells that hold their face centres (observed there), and they leave their
   * plane; a plane left without cells is removed (later planes' indices shift down).
   * Of a rectangle reaching past the other planes' cuboids, the cells lying on them
   * move when the cells that stay keep one rectangle (none of the moved cells within
   * their bounds: full rows or columns at its ends), or, when they all move to
   * parallel planes, when they are every observed cell within their own bounds (one
   * rectangle, e.g. where two views of one wall overlap); else it stays whole. Where
   * frames
   * found one surface as planes a few degrees apart (beyond plane_merge_angle_rad), or
   * planes crossing near their line, the surface is then covered once. Two level
   * planes (normals within LEVEL_MAX_ANGLE_RAD of the world z axis: road and pavement,
   * floor and step) never absorb each other: the step between them is real. The
   * planes' fits (moments) are not changed. \return the number of raster cells moved */
  std::size_t absorbOverlappingPlaneCells();

  /** \brief The merged cuboids: every map plane's rectangles (plane_id = the map's
   * plane index, into getPlanes()), then the non-planar cells (plane_id -1). Stable
   * order for the same integrations. Built on each call from the planes' cached
   * rectangles (the covers of the planes changed since the last query are rebuilt
   * first) and returned by value: the layer does not hold the list, and
   * getMemoryBytes() does not count it. Bind the result (const auto& cuboids =
   * layer.getCuboids()) rather than calling it in a loop. With
   * Params::skip_isolated_non_planar the isolated one-voxel non-planar cells are left
   * out. */
  PlanarCuboids getCuboids() const;
  /** \brief getCuboids().size(), without building the list. */
  [[nodiscard]] std::size_t getCuboidCount() const;
  /** \brief The map's planes [a, b, c, d] (unit normal toward the sensors that saw
   * them, d in meters), world frame: each the least-squares plane of its evidence;
   * a copy, index p the map's plane p (the plane_id of its cuboids). */
  PlaneModels getPlanes() const;
  /** \brief getPlanes().size(), without building the list. */
  [[nodiscard]] std::size_t getPlaneCount() const;
  /** \brief Number of cells: observed raster cells over all planes (not the cells
   * filled by the gap closing) plus non-planar cells. */
  [[nodiscard]] std::size_t getCellCount() const;
  /** \brief Observed raster cells over all planes (getCellCount() without the
   * non-planar cells). */
  [[nodiscard]] std::size_t getRasterCellCount() const;
  /** \brief Bytes held: vector capacities (planes, rasters, cached rectangles,
   * non-planar cells and their index) and, while held, the query index of
   * findCuboid() and castRay() (its copy of the cuboids, hash-map buckets and
   * nodes) and the list of the isolated non-planar cells getCuboids() leaves out (4 B
   * each). Allocator overhead per allocation is not counted. */
  [[nodiscard]] std::size_t getMemoryBytes() const;

  /** \brief What removeOutside() removed. */
  struct WindowRemoval {
    /** \brief Observed raster cells of the planes (with their feature evidence). */
    std::size_t plane_cells{0};
    /** \brief Planes left without cells, removed (later planes' indices shift down).
     */
    std::size_t planes{0};
    /** \brief Non-planar cells. */
    std::size_t non_planar_cells{0};
  };

  /** \brief Keeps the cells inside \a keep and drops the others (the rolling window
   * of a long run): a plane's observed raster cell goes when the centre of its face
   * (the cell's centre on the refined plane) lies outside the box, a non-planar cell
   * when its centre does. A plane left without cells is removed; the planes that keep
   * cells keep their fits (moments). The storage of what goes is freed
   * (getMemoryBytes() falls). The cells inside keep their evidence; the planes whose
   * rasters changed are covered again at the next query, so a rectangle that joined
   * cells on both sides of the boundary is replaced by rectangles of the cells left
   * (their mean probability over the cells left).
   * \param[in] keep the box, meters, world frame; a bound may be +-infinity (that
   * axis unlimited); an empty box (min > max on an axis) or a NaN bound keeps
   * nothing
   * \return the cells and planes removed */
  WindowRemoval removeOutside(const Eigen::AlignedBox3f& keep);

  /** \brief The cuboid containing \a point (PlanarCuboid::contains, boundary
   * included), or nullptr; when several contain it, the one with the lowest index in
   * getCuboids(). The pointer (into the query index's copy of the cuboids) is valid
   * until the next integrate(), deserialize() or clear(). */
  [[nodiscard]] const PlanarCuboid* findCuboid(const Eigen::Vector3f& point) const;

  /** \brief First cuboid hit by a ray whose probability >= occupancy_thres.
   * \param[in] origin, direction the ray (direction of any length > 0), meters
   * \param[in] max_range_m largest distance, meters
   * \param[out] distance_m distance to the entry point, meters
   * \param[out] index index of the cuboid in getCuboids()
   * \return true on a hit (entry distance <= max_range_m; 0 when the origin is inside
   * an occupied cuboid); false for a zero or non-finite direction or origin, and
   * the outputs are then untouched */
  bool castRay(const Eigen::Vector3f& origin,
               const Eigen::Vector3f& direction,
               double max_range_m,
               float& distance_m,
               std::size_t& index) const;

  /** \brief Encodes the layer in a fixed little-endian layout: u32 magic "PGSL",
   * u32 version 8, the six real Params as f64, close_gaps_cells as u32, merge_rule as
   * u8 (0 paper, 1 min_rectangles, 2 density), cover_density, absorb_distance_m,
   * terrain_plane_tile_m and terrain_cover_density as f64,
   * skip_isolated_non_planar as u8 (0 or 1), min_plane_cells as u32; u64 planes, per
   * plane: the raster frame's plane f32 a, b, c, d, the refined plane f32 a, b, c, d,
   * the evidence moments as f64 (anchor[3], weight, sum[3], sum of outer products xx,
   * xy, xz, yy, yz, zz), u64 cells, per cell i32 i, i32 j, f32 probability sum, u16
   * feature count (sorted by row, column); u64 non-planar cells, per cell f32
   * centre[3], normal[3], horizontal_axis[3], width, height, thickness, f64 probability
   * sum, u32 feature count. The frames' axes, the rectangles and the cuboids are
   * derived, not stored: a decoded layer gives identical cuboids and continues
   * identically. \param[out] bytes appended to */
  void serialize(std::vector<std::uint8_t>& bytes) const;
  /** \brief Replaces the content and the parameters by a decoding of serialize()'s
   * output (exactly \a size bytes); every count is checked against the remaining bytes
   * before anything is allocated, and every value (parameter ranges, unit normals,
   * finite coordinates <= 1e7 m, probability sums in [0, count], cells strictly
   * sorted, finite moments of positive weight, a refined normal within
   * plane_merge_angle_rad of its frame's). Sections of version 1 (before the planes
   * carried their evidence) are rejected: run the mapping again. Version 2 (no
   * density rule, no cover_density) is read with the default cover_density; versions
   * 2 and 3 (no absorb_distance_m) with absorb_distance_m 0 (only the non-parallel
   * tolerance, as they were written); versions 2 to 4 (no terrain_plane_tile_m) with
   * terrain_plane_tile_m 0; versions 2 to 5 (no terrain_cover_density) with
   * terrain_cover_density = cover_density, the density their covers were made with;
   * versions 2 to 6 (no skip_isolated_non_planar) with it false, as they reported
   * every cell; versions 2 to 7 (no min_plane_cells) with min_plane_cells 0, as they
   * demoted no plane.
   * \throws planar_grid::IOError on truncated, trailing or inconsistent data or
   * another version (layer unchanged) */
  void deserialize(const std::uint8_t* data, std::size_t size);

  /** \brief Writes the cuboids as a mesh (12 triangles per box, per-face colour by
   * probability): ".ply" (pcl::io::savePLYFileBinary) or ".vtk" (legacy VTK polydata,
   * pcl::io::saveVTKFile). Atomic (temporary file, rename).
   * \throws planar_grid::IOError for another extension or a write error */
  void exportMesh(const std::string& path) const;

  /** \brief True when the parameters, planes (frames, refined planes, moments),
   * rasters and non-planar cells are equal. */
  [[nodiscard]] bool operator==(const SurfaceLayer& other) const;
  /** \brief True when the parameters, planes, rasters or non-planar cells differ. */
  [[nodiscard]] bool operator!=(const SurfaceLayer& other) const
  {
    return !(*this == other);
  }

  /** \brief Removes everything. */
  void clear();

private:
  struct Impl;
  /** \brief Planes, rasters, cells, cached cuboids (pimpl). */
  std::unique_ptr<Impl> impl_;
  /** \brief The parameters (validated). */
  Params params_;
};

} // namespace planar_grid
