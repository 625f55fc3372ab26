// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>

#include <pcl/memory.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Plane models [a, b, c, d] (unit normal, meters), aligned allocator (S16).
 * \ingroup map */
using PlaneModels =
  std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>>;

/** \brief The surface layer of the planar grid map (paper Sec. III-F): the planar and
 * non-planar cuboids of every frame, in the world frame, merged across frames so that
 * the map grows with the surface seen, not with the number of frames.
 *
 * - Planes: a frame's plane, oriented like its cuboids' normals (toward that frame's
 *   sensor), joins the map plane whose unit normal is within plane_merge_angle_rad of
 *   it (same orientation: the two faces of a wall stay separate) and whose offset d is
 *   within plane_merge_distance_m (the nearest in d), else it starts a new map plane.
 *   A map plane keeps the coefficients it was created with. Its fixed 2D frame: origin
 *   -d n on the plane, u = z x n normalised (world x projected when the plane is
 *   horizontal), v = n x u, the same convention as PlanarCuboidApproximation for
 *   up = +z. Its sparse raster holds square cells of edge resolution_m, cell (i, j)
 *   covering [i, i + 1) x [j, j + 1) resolution_m in (u, v).
 * - A frame's planar cuboid marks the raster cells whose centres fall inside its face
 *   (projected along the map normal, tolerance 1 % of a cell). The plane's cuboids
 *   are rebuilt from the raster (lazily, on the next query, only for planes touched
 *   since) by the paper's merge (Fig. 6b: maximal runs along u first, then runs with
 *   equal extent stacked along v) over cells of one occupancy class (probability >=
 *   occupancy_thres or below); each rectangle's face lies on the map plane and is
 *   extruded by thickness_m behind it (Fig. 6c). The raster is a set, so the same
 *   frame integrated twice gives the same cuboids as once.
 * - Non-planar cuboids (Fig. 7), and cuboids whose plane_id is -1, out of range or
 *   not is_planar, are stored as given; the newest view wins, as in the space layer:
 *   a non-planar cuboid of a new frame removes every stored non-planar cell of an
 *   earlier frame that it overlaps substantially, i.e. whose centre lies inside the
 *   new box grown by resolution_m / 2 on every side, or whose box contains the new
 *   box's centre (so a region re-split differently by the next frame's quadtree is
 *   replaced, not piled up; a stored cell that no new cell overlaps so is kept).
 *   Cells of the same frame never remove each other, except that of two with the
 *   same key (centre quantised to resolution_m cells, extents rounded to
 *   resolution_m) the later is kept. Candidates come from a spatial hash of the
 *   stored cells' bounding boxes (bins of 4 cells), so integrate() costs O(new
 *   cells x cells per bin).
 * - Occupancy (end of Sec. III-F): a planar cell's probability is the mean probability
 *   of the features that fell inside it (all frames; a feature counts when it is
 *   within feature_distance_m of a plane of its frame and its cell is already
 *   observed); a cell with none takes the mean of its 8 neighbours that have a value,
 *   propagated outward layer by layer; cells not reached (a plane without features)
 *   keep 0.5. A planar cuboid's probability is the mean over its cells and its
 *   point_count the number of features in it. A non-planar cuboid's probability is
 *   the mean of its frame's features inside the box, 0.5 without any (neighbours of
 *   non-planar cells are not defined on a raster).
 * - Queries use a spatial hash of the cuboids' bounding boxes (bins of 4 cells),
 *   rebuilt lazily and freed by integrate() (it is stale then); const methods are safe
 * to call from several threads (a mutex guards the rebuild), integrate() is not.
 * - Invalid input (non-finite cuboids or features, probabilities outside [0, 1], a
 *   face of more than 1e7 cells) is skipped with a PCL_WARN; integrate() never throws.
 * \ingroup map */
class SurfaceLayer {
public:
  /** \brief Parameters with defaults and valid ranges. */
  struct Params {
    /** Raster cell edge in each plane, meters; in [0.001, 100] (the paper's minimum
     * cell). */
    double resolution_m{0.1};
    /** Extrusion of the planar cuboids behind their face, meters; > 0. */
    double thickness_m{0.1};
    /** Largest angle between the normals of one plane seen in two frames, radians;
     * in (0, pi/2). */
    double plane_merge_angle_rad{0.1};
    /** Largest difference of the offsets d of one plane seen in two frames, meters;
     * > 0. */
    double plane_merge_distance_m{0.15};
    /** Occupancy class boundary for merging cells, probability in (0, 1). */
    double occupancy_thres{0.5};
    /** A feature counts for a planar cell when within this distance of the plane,
     * meters; >= 0. */
    double feature_distance_m{0.1};
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

  /** \brief The merged cuboids: every map plane's rectangles (plane_id = the map's
   * plane index, into getPlanes()), then the non-planar cells (plane_id -1). Stable
   * order for the same integrations. */
  const PlanarCuboids& getCuboids() const;
  /** \brief The map's planes [a, b, c, d], world frame. */
  const PlaneModels& getPlanes() const;
  /** \brief Number of cells: observed raster cells over all planes plus non-planar
   * cells. */
  [[nodiscard]] std::size_t getCellCount() const;
  /** \brief Bytes held: hash-map buckets and nodes (rasters, non-planar index,
   * spatial index) and vector capacities (planes, non-planar cells, cached cuboids),
   * as currently built (the caches are built by the queries). */
  [[nodiscard]] std::size_t getMemoryBytes() const;

  /** \brief The cuboid containing \a point (PlanarCuboid::contains, boundary
   * included), or nullptr; when several contain it, the one with the lowest index in
   * getCuboids(). The pointer is valid until the next integrate(), deserialize() or
   * clear(). */
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
   * u32 version 1, the six Params as f64; u64 planes, per plane f32 a, b, c, d, u64
   * cells, per cell i32 i, i32 j, f64 probability sum, u32 feature count (sorted by
   * row, column); u64 non-planar cells, per cell f32 centre[3], normal[3],
   * horizontal_axis[3], width, height, thickness, f64 probability sum, u32 feature
   * count. The plane frames and cuboids are derived, not stored.
   * \param[out] bytes appended to */
  void serialize(std::vector<std::uint8_t>& bytes) const;
  /** \brief Replaces the content and the parameters by a decoding of serialize()'s
   * output (exactly \a size bytes); every count is checked against the remaining bytes
   * before anything is allocated, and every value (parameter ranges, unit normals,
   * finite coordinates <= 1e7 m, probability sums in [0, count], no duplicate cells).
   * \throws planar_grid::IOError on truncated, trailing or inconsistent data (layer
   * unchanged) */
  void deserialize(const std::uint8_t* data, std::size_t size);

  /** \brief Writes the cuboids as a mesh (12 triangles per box, per-face colour by
   * probability): ".ply" (pcl::io::savePLYFileBinary) or ".vtk" (legacy VTK polydata,
   * pcl::io::saveVTKFile). Atomic (temporary file, rename).
   * \throws planar_grid::IOError for another extension or a write error */
  void exportMesh(const std::string& path) const;

  /** \brief True when the parameters, planes, rasters and non-planar cells are equal.
   */
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
