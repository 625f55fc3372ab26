// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/core/stereo_calibration.h>

#include <pcl/memory.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <type_traits>
#include <unordered_map>
#include <vector>

namespace octomap {
class OcTree;
} // namespace octomap

namespace planar_grid {

/** \brief The valid range of each numeric ExplicitSpaceGrid::Params member, declared
 * once: the ExplicitSpaceGrid constructor tests the values against them and the
 * pipeline's map_integration stage table takes them as its ranges. \ingroup map */
namespace explicit_space_grid_ranges {
/** \brief Voxel edge: (0, inf) meters (a map's is its surface layer's, narrower). */
inline constexpr ParamRange RESOLUTION = ParamRange::open(0.0, ParamRange::UNBOUNDED);
/** \brief Largest depth integrated per view: (0, 1000] meters. */
inline constexpr ParamRange MAX_RANGE = ParamRange::openMin(0.0, 1000.0);
/** \brief Half-thickness of the measured surface: [0, 10] meters. */
inline constexpr ParamRange SURFACE_MARGIN = ParamRange::closed(0.0, 10.0);
} // namespace explicit_space_grid_ranges

/** \brief The state of a cell of the explicit space layer, with the paper's 2-bit
 * labels (Sec. IV: 00 free, 01 occupied, 10 unknown; 11 marks an inner octree node in
 * the file). \ingroup map */
enum class SpaceState : std::uint8_t { FREE = 0, OCCUPIED = 1, UNKNOWN = 2 };

/** \brief "free", "occupied" or "unknown". \ingroup map */
std::string toString(SpaceState state);

/** \brief Parses "free", "occupied" or "unknown".
 * \throws planar_grid::Exception for any other name \ingroup map */
SpaceState spaceStateFromString(const std::string& name);

/** \brief A pinhole depth image: depth along the optical axis per pixel, row-major.
 * Camera frame: x right, y down, z forward (meters). \ingroup map */
struct DepthImage {
  /** \brief Width in pixels (> 0 for a usable image). */
  int width{0};
  /** \brief Height in pixels (> 0 for a usable image). */
  int height{0};
  /** \brief Horizontal focal length, pixels (> 0). */
  float fx{0.0f};
  /** \brief Vertical focal length, pixels (> 0). */
  float fy{0.0f};
  /** \brief Principal point column, pixels. */
  float cx{0.0f};
  /** \brief Principal point row, pixels. */
  float cy{0.0f};
  /** \brief width x height depths, meters; NaN or <= 0 = no measurement. */
  std::vector<float> depth_m;

  /** \brief Depth at pixel (u, v), meters (no bounds check). */
  [[nodiscard]] float at(int u, int v) const
  {
    return depth_m[static_cast<std::size_t>(v) * static_cast<std::size_t>(width)
                   + static_cast<std::size_t>(u)];
  }

  /** \brief Converts a disparity image of a rectified stereo pair into depth,
   * f B / d per pixel (the pinhole of the left camera).
   * \param[in] disparity row-major disparities, pixels (<= 0 or non-finite: no
   * measurement)
   * \param[in] width, height image size, pixels (> 0)
   * \param[in] row_stride_bytes bytes from one row to the next (>= width * 4), e.g.
   * cv::Mat::step for a CV_32FC1 image
   * \param[in] calibration the rectified rig (focal_length_px, cx_px, cy_px,
   * baseline_m > 0)
   * \return the depth image, meters
   * \throws planar_grid::Exception for a non-positive size, a short stride or an
   * invalid calibration */
  static DepthImage fromDisparity(const float* disparity,
                                  int width,
                                  int height,
                                  std::size_t row_stride_bytes,
                                  const StereoCalibration& calibration);

  /** \brief fromDisparity() into this image, in place: a depth image filled frame after
   * frame keeps its buffer (no allocation when the size is unchanged). The arguments
   * and exceptions are fromDisparity()'s; on an exception the image is unchanged. */
  void assignFromDisparity(const float* disparity,
                           int image_width,
                           int image_height,
                           std::size_t row_stride_bytes,
                           const StereoCalibration& calibration);

  /** \brief Number of pixels with a measurement (finite depth > 0). */
  [[nodiscard]] std::size_t countValid() const;

  /** \brief Whether the image can be integrated: width and height > 0, width x height
   * depths, finite intrinsics and positive focal lengths. */
  [[nodiscard]] bool isConsistent() const;

  /** \brief Renders points given in the camera frame into a depth image with a
   * z-buffer (the nearest point wins per pixel); works for organized and unorganized
   * clouds. Points behind the camera or non-finite are skipped.
   * \param[in] cloud points in the camera frame, meters
   * \param[in] width, height image size, pixels (> 0)
   * \param[in] fx, fy, cx, cy intrinsics, pixels (fx, fy > 0)
   * \return the depth image
   * \throws planar_grid::Exception for a non-positive size or focal length */
  static DepthImage fromPointCloud(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                                   int width,
                                   int height,
                                   float fx,
                                   float fy,
                                   float cx,
                                   float cy);
};

/** \brief The explicit space layer of the planar grid map (the paper's "local explicit
 * modelling space", Sec. III-F, Fig. 5c): voxels of edge resolution_m that are free (in
 * front of the measured surface), occupied (at it) or unknown (behind it: occluded),
 * inside each camera frustum up to max_range_m. Space never inside any view has the
 * prior state, and stays apart from what a view observed: with the free prior a voxel
 * seen free and one never seen both read FREE from getState(), but only the first is
 * stored (forEachVoxel(), getVoxelCount(), the file) and exported to OctoMap.
 *
 * Integration projects the voxels of the frustum into the depth image (no ray per
 * point): a voxel whose centre depth is below the smallest measured depth over its
 * footprint minus surface_margin_m is free, one behind the measured depth plus the
 * margin is unknown (occluded), and the voxel of each back-projected valid pixel is
 * occupied. Free and occupied observations replace older ones (newest wins); "no
 * information" (outside the image, beyond max_range_m, a footprint without any
 * measurement) changes nothing; an occluded voxel becomes unknown only where it holds
 * the prior (was never observed). Occlusion therefore never erases an observed
 * state, with either prior. The footprint is approximated by min-depth mip cells (a
 * superset of at most 3 x 3 cells, each narrower than twice the footprint's radius, so
 * up to about three times its width): a voxel is free when that superset holds a
 * measurement and the voxel lies in front of every one of them, so a voxel whose own
 * footprint is unmeasured may still be freed by measured pixels within about two
 * footprint radii of it; whole
 * 8^3 blocks and 4^3 sub-cubes in front of (or behind) every measurement of their
 * footprint are decided at once, the rest voxel by voxel. In that per-voxel step a 4^3
 * cube is decided at once when its 8 corner centres bound the test of all 64 voxels
 * (every centre in the image and in front of the minimum over the union of their
 * footprint cells: all free; with the unknown prior, no centre in front of the cell of
 * its own pixel: none observed); otherwise each voxel's minimum is one look-up in
 * per-level minima over 1 to 3 cells per axis. Either way the result is the
 * voxel-by-voxel one. A view's observations are gathered per block as bit masks and
 * applied word-wise.
 *
 * Storage is sparse: blocks of 8 x 8 x 8 voxels with a 2-bit code per voxel (00 free,
 * 01 occupied, 10 unknown, 11 never observed with the free prior; with the unknown
 * prior, never observed is 10). A block whose voxels all have one state is that code
 * alone, and a block never observed is not stored (pruned), so the representation is
 * canonical: two grids with the same observations hold the same blocks. Blocks are
 * grouped in super-blocks of 8 x 8 x 8 blocks (64^3 voxels), found through a flat
 * open-addressing table: a super-block holds the 2-bit code of each uniform block, a
 * bit per mixed block and the mixed blocks' compact forms back to back, each a fixed
 * two-level octree (the 4^3 cubes, then the 2^3 cells of each mixed cube, then each
 * mixed cell's 8 voxels). A block holding two states (the usual edge of the observed
 * space) writes one bit per node and per voxel, 6 to 83 bytes; one holding three or
 * four writes their 2-bit codes, 9 to 156 bytes. A query decodes only the bytes on
 * its voxel's path (O(1)); writes edit decoded blocks and rebuild each touched
 * super-block once per view.
 * \ingroup map */
class ExplicitSpaceGrid {
public:
  /** \brief Parameters with defaults and valid ranges. */
  struct Params {
    /** Voxel edge, meters; in explicit_space_grid_ranges::RESOLUTION (the paper's
     * minimum cell, 0.1 m). */
    double resolution_m{0.1};
    /** Largest depth integrated per view, meters; in
     * explicit_space_grid_ranges::MAX_RANGE. */
    double max_range_m{25.0};
    /** Half-thickness of the measured surface, meters; in
     * explicit_space_grid_ranges::SURFACE_MARGIN. 0 selects one voxel
     * diagonal / 2 (resolution_m sqrt(3) / 2). */
    double surface_margin_m{0.0};
    /** State of space never inside a view: the paper treats it as free; UNKNOWN is
     * the conservative choice. */
    SpaceState prior{SpaceState::UNKNOWN};
  };

  /** \brief Integer voxel coordinates: floor(p / resolution_m) per axis. */
  using VoxelKey = Eigen::Vector3i;

  /** \brief Version of the bit stream serialize() writes (the map file's version):
   * 3 keeps observed free space apart from the free prior. */
  static constexpr unsigned STREAM_VERSION = 3;
  /** \brief Oldest stream version deserialize() reads (versions 1 and 2 share one
   * encoding, without never-observed leaves). */
  static constexpr unsigned OLDEST_STREAM_VERSION = 1;

  /** \brief Throws planar_grid::Exception for out-of-range parameters. */
  explicit ExplicitSpaceGrid(const Params& params);
  ExplicitSpaceGrid(const ExplicitSpaceGrid&) = delete;
  ExplicitSpaceGrid& operator=(const ExplicitSpaceGrid&) = delete;
  /** \brief Moves (defined in the .cpp, where Impl is complete). */
  ExplicitSpaceGrid(ExplicitSpaceGrid&&) noexcept;
  /** \brief Move assignment (defined in the .cpp, where Impl is complete). */
  ExplicitSpaceGrid& operator=(ExplicitSpaceGrid&&) noexcept;
  ~ExplicitSpaceGrid();

  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Integrates one view.
   * \param[in] depth the depth image (an empty or zero-sized image is a no-op with a
   * PCL_WARN)
   * \param[in] world_T_camera the camera pose (camera x right, y down, z forward),
   * meters */
  void integrateDepthImage(const DepthImage& depth,
                           const Eigen::Isometry3d& world_T_camera);

  /** \brief Integrates one scan by ray casting, the sensor model of an unorganized
   * cloud (a 360 degree LiDAR scan, or any cloud without an image): the voxels each ray
   * crosses from \a sensor_origin to its point become FREE, and the voxel of every
   * point within max_range_m becomes OCCUPIED (after the free ones, so that a point
   * wins over another ray through its voxel, as in OctoMap's insertPointCloud). A ray
   * to a point beyond max_range_m clears space up to max_range_m only. Non-finite
   * points are skipped. Space behind the points is not observed: it keeps its state.
   * \param[in] points the scan's points in the world frame, meters
   * \param[in] sensor_origin where the rays start (the scan's sensor origin), meters
   * \throws planar_grid::Exception for a non-finite origin */
  void integratePointCloud(const pcl::PointCloud<pcl::PointXYZ>& points,
                           const Eigen::Vector3f& sensor_origin);

  /** \brief Key of the voxel containing \a point (meters). */
  [[nodiscard]] VoxelKey toKey(const Eigen::Vector3f& point) const;
  /** \brief Centre of voxel \a key, meters. */
  [[nodiscard]] Eigen::Vector3f toCentre(const VoxelKey& key) const;

  /** \brief State of the voxel containing \a point (the prior where nothing was
   * observed; non-finite points give the prior). */
  [[nodiscard]] SpaceState getState(const Eigen::Vector3f& point) const;
  /** \brief State of voxel \a key. */
  [[nodiscard]] SpaceState getState(const VoxelKey& key) const;
  /** \brief Sets one voxel as observed in \a state (tests, file reading, merging):
   * FREE is stored as observed free space with either prior; UNKNOWN with the unknown
   * prior is the never-observed state (the voxel is dropped).
   * \note Writes wait in an edit buffer (up to 4096 blocks) so that voxel-by-voxel
   * writes do not rebuild their super-block each; getState() reads the buffer, and the
   * other queries (counts, bytes, castRay(), serialize(), ...) write it to the storage
   * first. Like any write, setState() must not run while another thread queries the
   * grid, and neither must the first query after it. */
  void setState(const VoxelKey& key, SpaceState state);

  /** \brief Which of two merged grids holds the newer observations (merge()). */
  enum class MergeOrder {
    /** Neither is known to be newer (independent recordings, or observation times
     * that interleave): the symmetric rule decides. */
    UNORDERED,
    /** Every observation of this grid is newer than every one of the other. */
    THIS_IS_NEWER,
    /** Every observation of the other grid is newer than every one of this grid. */
    OTHER_IS_NEWER
  };

  /** \brief Merges another grid (the space layer of another recording's map, or of
   * another part of one) into this one, voxel by voxel.
   *
   * With \a order THIS_IS_NEWER or OTHER_IS_NEWER, the rule of integration: where both
   * grids observed a voxel free or occupied, the newer grid's state wins (a later view
   * replaces an earlier one); where only one did, its state stays (occlusion never
   * erases an observed state); occluded (unknown) beats never observed. This is what
   * integrating the older grid's views and then the newer grid's views into one grid
   * gives, so the halves of a drive merged give the drive's own grid.
   *
   * With UNORDERED (no newer grid to follow), the state of higher rank in occupied >
   * free > unknown (occluded) > never observed: the clamped log-odds of two
   * independent observations added as OctoMap fuses them (+3.5 - 2.0 = +1.5) give
   * occupied where the grids disagree, the safe side for planning. It grows occupied
   * space where the grids disagree (an object that moved, stereo noise seen once).
   *
   * Either rule is commutative when \a order names the same grid as newer from
   * either side (merging an empty grid changes nothing); both are associative for
   * grids whose observation times do not interleave.
   * \param[in] other the grid merged in (unchanged; not this grid)
   * \param[in] this_T_other rigid transform from \a other's world frame to this
   * grid's, meters. A translation by whole voxels (rotation exactly the identity)
   * moves the voxels exactly; any other transform resamples: every voxel of this grid
   * whose centre, moved back into \a other, falls in an observed voxel of \a other
   * takes that voxel's state into the merge (nearest neighbour, no holes).
   * \param[in] order which grid holds the newer observations
   * \throws planar_grid::Exception when the resolutions or the priors differ, when
   * \a other is this grid, or for a transform that is not finite and rigid; the grid
   * is then unchanged */
  void merge(const ExplicitSpaceGrid& other,
             const Eigen::Isometry3d& this_T_other,
             MergeOrder order = MergeOrder::UNORDERED);

  /** \brief Walks the voxels along a ray (Amanatides-Woo) to the first occupied one.
   * \param[in] origin start, meters, finite
   * \param[in] direction direction (any finite length > 0)
   * \param[in] max_range_m largest distance walked, meters, >= 0; infinity walks to
   * the end of the stored blocks
   * \param[out] hit centre of the first occupied voxel, meters
   * \return true when an occupied voxel was found within max_range_m
   * \throws planar_grid::Exception for a non-finite origin, a zero or non-finite
   * direction, or a negative or NaN range */
  bool castRay(const Eigen::Vector3f& origin,
               const Eigen::Vector3f& direction,
               double max_range_m,
               Eigen::Vector3f& hit) const;

  /** \brief Calls f(key, state) for every observed voxel (free, occupied, and with
   * the free prior unknown = occluded; never the ones never observed), in a
   * deterministic order (blocks sorted by key, voxels x fastest). */
  template <typename F> void forEachVoxel(F&& f) const;

  /** \brief Calls f(key) for every observed voxel in \a state, in forEachVoxel()'s
   * order (nothing for UNKNOWN with the unknown prior). Stored blocks whose voxels all
   * have another state are skipped whole, so this is much faster than forEachVoxel()
   * when few voxels have \a state (occupied voxels among free space). */
  template <typename F> void forEachVoxelIn(SpaceState state, F&& f) const;

  /** \brief Calls f(bottom_key, length, state) for every vertical run of observed
   * voxels in one state: the voxels bottom_key + (0, 0, k), k = 0 .. length - 1
   * (length 1 to 8). Runs end at the storage's 8-voxel block boundaries, so a longer
   * column comes as several runs; together the runs cover exactly the voxels
   * forEachVoxel() visits, with the same states. A block whose voxels share one state
   * costs 64 calls instead of 512: the fast way to project the space onto the ground
   * plane (2D maps, height maps). Blocks in forEachVoxel()'s order, columns x fastest.
   */
  template <typename F> void forEachVoxelRun(F&& f) const;

  /** \brief Number of observed voxels in \a state (as forEachVoxel() visits them;
   * 0 for UNKNOWN with the unknown prior). */
  [[nodiscard]] std::size_t getVoxelCount(SpaceState state) const;
  /** \brief Number of stored blocks. */
  [[nodiscard]] std::size_t getBlockCount() const;
  /** \brief Bytes the storage holds: every allocation (the super-block array's
   * capacity, each super-block's compact forms and offsets, the lookup table's slots)
   * plus 16 bytes of allocator overhead per allocation. The scratch buffers of
   * integration (depth pyramid, per-view observations, edit buffer; one view's worth)
   * are working memory, not counted. */
  [[nodiscard]] std::size_t getMemoryBytes() const;
  /** \brief Edge of the storage's blocks, in voxels (8): the unit of
   * workingBytesBound() and storageBytesBound(). */
  static constexpr int BLOCK_EDGE_VOXELS = 8;
  /** \brief Upper bound of the working memory one view's integration holds (kept
   * between views): the per-block observations and the edit buffer of every block the
   * view touches (at their vectors' largest capacity, twice the count), and the depth
   * pyramid of the image.
   * \param[in] view_blocks blocks of 8^3 voxels the view can touch (those meeting
   * its frustum up to max_range_m, or the ball of max_range_m of a scan)
   * \param[in] image_pixels pixels of the depth image (0 for a scan)
   * \return bytes */
  [[nodiscard]] static std::uint64_t workingBytesBound(std::uint64_t view_blocks,
                                                       std::uint64_t image_pixels);
  /** \brief Upper bound of getMemoryBytes() for a grid of \a blocks stored blocks in
   * \a super_blocks super-blocks (64^3 voxels): every block mixed, at the largest
   * compact form, and the super-block array and directory at their largest capacity.
   * \param[in] blocks stored blocks
   * \param[in] super_blocks super-blocks holding them (<= blocks)
   * \return bytes */
  [[nodiscard]] static std::uint64_t storageBytesBound(std::uint64_t blocks,
                                                       std::uint64_t super_blocks);
  /** \brief Inclusive bounds of the stored blocks, in voxel keys (block-aligned:
   * min_key multiples of 8, max_key = 8 k + 7); false when nothing is stored. */
  bool getBounds(VoxelKey& min_key, VoxelKey& max_key) const;

  /** \brief What removeOutside() removed. */
  struct WindowRemoval {
    /** \brief Stored blocks (8^3 voxels) wholly outside the box, dropped. */
    std::size_t blocks{0};
    /** \brief Observed voxels outside the box (as getVoxelCount() counts them: free,
     * occupied, and with the free prior occluded), now never observed. */
    std::uint64_t voxels{0};
  };

  /** \brief Keeps the voxels whose centres lie inside \a keep and drops every other
   * one (the rolling window of a long run): a voxel outside becomes never observed
   * (the prior, as if no view had seen it), and the storage it held is freed
   * (getMemoryBytes() falls with the content: blocks, super-blocks and the lookup
   * table are reallocated to what is left). The voxels inside keep their state.
   * \param[in] keep the box, meters, world frame; a bound may be +-infinity (that
   * axis unlimited); an empty box (min > max on an axis) or a NaN bound keeps
   * nothing
   * \return the blocks and voxels removed */
  WindowRemoval removeOutside(const Eigen::AlignedBox3f& keep);

  /** \brief Encodes the layer as an octree bit stream (Sec. IV): a small fixed header
   * (root key, depth, prior, fixed little-endian byte order) followed by one 2-bit
   * label per node in depth-first order, 4 labels per byte: 00 free, 01 occupied, 10
   * unknown, and 11 an escape followed by a second label: 11 an inner node with 8
   * children, 00 a never-observed leaf (only with the free prior; with the unknown
   * prior never observed is 10). Regions without stored blocks are never-observed
   * leaves. Version STREAM_VERSION (3); versions 1 and 2 wrote 11 alone for an inner
   * node and the prior's label for never-observed space, so that with the free prior
   * observed free space was not told apart.
   * Header (22 bytes): root key int32 x3 (block-aligned min corner of the smallest
   * power-of-two cube covering the stored blocks), depth uint8 (root edge 2^depth
   * voxels), prior uint8, label count uint64; children in x, y, z order (x fastest);
   * first label of a byte in its low bits.
   * \param[out] bytes the encoding (appended to)
   * \throws planar_grid::Exception when the stored blocks span more than 2^21 voxels */
  void serialize(std::vector<std::uint8_t>& bytes) const;

  /** \brief Replaces the content by a decoding of serialize()'s output.
   * \param[in] data, size the encoded bytes
   * \param[in] format_version the stream's version (the map file's): 3, or 1 and 2,
   * whose free leaves with the free prior are read as never observed
   * \throws planar_grid::IOError when the bytes are truncated, have trailing data, an
   * inner node at voxel level, a depth over 21, a version outside
   * [OLDEST_STREAM_VERSION, STREAM_VERSION], an escape followed by 01 or 10 (or by 00
   * with the unknown prior);
   * a root key that is not a multiple of 8, a prior other than free/unknown,
   * non-zero padding bits, or leaves that would create more than 2^22 blocks (checked
   * before allocating); the grid is unchanged on error. The prior is taken from the
   * stream; the resolution is the grid's own. */
  void deserialize(const std::uint8_t* data,
                   std::size_t size,
                   unsigned format_version = STREAM_VERSION);

  /** \brief Inserts the observed voxels into an empty OctoMap tree: occupied voxels
   * at the tree's clamping_thres_max (log-odds), observed free ones at
   * clamping_thres_min; occluded (unknown) and never-observed voxels are left out
   * (unknown in OctoMap), whatever the prior. A uniform 8^3 block becomes one node
   * three levels above the voxels, and each block is pruned as it is inserted.
   * \param[in,out] tree an empty octomap::OcTree of the grid's resolution_m
   * \return the number of observed voxels left out because they lie outside OctoMap's
   * key range (2^16 voxels per axis around the origin)
   * \throws planar_grid::Exception for a tree of another resolution or not empty */
  std::size_t insertIntoOcTree(octomap::OcTree& tree) const;

  /** \brief Writes the observed voxels (insertIntoOcTree()) to an OctoMap file:
   * ".ot" as the full format (AbstractOcTree::write, log-odds per node), any other
   * name as the binary format (.bt, OcTree::writeBinary: free / occupied per node).
   * Atomic (temporary file, rename).
   * \throws planar_grid::IOError when the file cannot be written */
  void exportOctoMap(const std::string& path) const;

  /** \brief True when both grids have the same resolution, prior and state in every
   * voxel. */
  [[nodiscard]] bool operator==(const ExplicitSpaceGrid& other) const;
  /** \brief True when a voxel's state, the resolution or the prior differ. */
  [[nodiscard]] bool operator!=(const ExplicitSpaceGrid& other) const
  {
    return !(*this == other);
  }

  /** \brief Removes every voxel (everything at the prior again). */
  void clear();

private:
  struct Impl;
  /** \brief Blocks and scratch buffers (pimpl keeps the storage out of this header).
   */
  std::unique_ptr<Impl> impl_;
  /** \brief The parameters (validated). */
  Params params_;
  /** \brief Threads of integrateDepthImage()'s free / occluded pass (>= 1); the
   * result is the same for any count. Not public API: set by tests and benchmarks
   * through the friend ExplicitSpaceGridThreads. */
  int num_threads_{1};
  friend struct ExplicitSpaceGridThreads;
  /** \brief Visits the non-prior voxels (implementation of forEachVoxel). */
  void visitVoxels(void (*visit)(void*, const VoxelKey&, SpaceState),
                   void* context) const;
  /** \brief Visits the vertical runs (implementation of forEachVoxelRun). */
  void visitVoxelRuns(void (*visit)(void*, const VoxelKey&, int, SpaceState),
                      void* context) const;
  /** \brief Visits the voxels of one state (implementation of forEachVoxelIn). */
  void visitVoxelsIn(SpaceState state,
                     void (*visit)(void*, const VoxelKey&),
                     void* context) const;
};

template <typename F>
void
ExplicitSpaceGrid::forEachVoxel(F&& f) const
{
  visitVoxels(
    [](void* context, const VoxelKey& key, SpaceState state) {
      (*static_cast<std::remove_reference_t<F>*>(context))(key, state);
    },
    const_cast<void*>(static_cast<const void*>(&f)));
}

template <typename F>
void
ExplicitSpaceGrid::forEachVoxelIn(SpaceState state, F&& f) const
{
  visitVoxelsIn(
    state,
    [](void* context, const VoxelKey& key) {
      (*static_cast<std::remove_reference_t<F>*>(context))(key);
    },
    const_cast<void*>(static_cast<const void*>(&f)));
}

template <typename F>
void
ExplicitSpaceGrid::forEachVoxelRun(F&& f) const
{
  visitVoxelRuns(
    [](void* context, const VoxelKey& key, int length, SpaceState state) {
      (*static_cast<std::remove_reference_t<F>*>(context))(key, length, state);
    },
    const_cast<void*>(static_cast<const void*>(&f)));
}

} // namespace planar_grid
