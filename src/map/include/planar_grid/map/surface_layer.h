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
 * - Planes: a frame's plane joins the map's plane whose unit normal is within
 *   plane_merge_angle_rad and whose offset d is within plane_merge_distance_m (the
 *   nearest such), else it starts a new map plane. Each map plane has a fixed 2D frame
 *   (set when it is created) and a sparse raster of square cells of edge resolution_m
 *   in it. A frame's planar cuboid marks the raster cells whose centres fall inside its
 *   face; the plane's cuboids are then rebuilt from the raster by the paper's merge
 *   (runs along the horizontal axis first, then equal runs stacked vertically) over
 *   cells of one occupancy class (probability >= occupancy_thres or below), each
 *   rectangle extruded by thickness_m behind the face (Fig. 6c).
 * - Non-planar cuboids (Fig. 7) are kept per (quantised centre, size): a cell of a new
 *   frame replaces the one with the same key, so repeated views do not pile up.
 * - Occupancy (end of Sec. III-F): a cell's probability is the mean probability of the
 *   features that fell inside it (all frames); a cell with none takes the mean of its
 *   8 neighbours that have a value (propagated outward); a plane without features
 *   keeps 0.5. A cuboid's probability is the mean over its cells.
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
  /** \brief Number of raster cells over all planes. */
  [[nodiscard]] std::size_t getCellCount() const;
  /** \brief Bytes held (rasters, non-planar cells, cuboids, planes). */
  [[nodiscard]] std::size_t getMemoryBytes() const;

  /** \brief The cuboid containing \a point, or nullptr (the first found when cuboids
   * overlap). */
  [[nodiscard]] const PlanarCuboid* findCuboid(const Eigen::Vector3f& point) const;

  /** \brief First cuboid hit by a ray whose probability >= occupancy_thres.
   * \param[in] origin, direction the ray (direction of any length > 0), meters
   * \param[in] max_range_m largest distance, meters
   * \param[out] distance_m distance to the entry point, meters
   * \param[out] index index of the cuboid in getCuboids()
   * \return true on a hit */
  bool castRay(const Eigen::Vector3f& origin,
               const Eigen::Vector3f& direction,
               double max_range_m,
               float& distance_m,
               std::size_t& index) const;

  /** \brief Encodes the layer (planes, their frames and rasters, the non-planar cells)
   * in a fixed little-endian layout. \param[out] bytes appended to */
  void serialize(std::vector<std::uint8_t>& bytes) const;
  /** \brief Replaces the content by a decoding of serialize()'s output; every count is
   * checked against the remaining bytes before anything is allocated.
   * \throws planar_grid::IOError on truncated or inconsistent data (layer unchanged) */
  void deserialize(const std::uint8_t* data, std::size_t size);

  /** \brief Writes the cuboids as a mesh (12 triangles per box, per-face colour by
   * probability): ".ply" (pcl::io::savePLYFileBinary) or ".vtk" (legacy VTK polydata,
   * pcl::io::saveVTKFile). Atomic (temporary file, rename).
   * \throws planar_grid::IOError for another extension or a write error */
  void exportMesh(const std::string& path) const;

  /** \brief True when the parameters, planes, rasters and non-planar cells are equal.
   */
  [[nodiscard]] bool operator==(const SurfaceLayer& other) const;
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
