// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/point_cloud.h>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <vector>

namespace planar_grid {

/** \brief Valid ranges of TerrainRemoval's parameters, declared once for the class's
 * checks and the ground_removal stage. \ingroup segmentation */
namespace terrain_removal_ranges {
/** \brief eps_angle_rad and terrain_max_slope_rad, radians. */
inline constexpr ParamRange ANGLE = ParamRange::closed(0.0, 1.5708);
/** \brief min_sensor_height_m, meters. */
inline constexpr ParamRange MIN_SENSOR_HEIGHT = ParamRange::closed(0.0, 100.0);
/** \brief terrain_max_step_m and terrain_height_m, meters. */
inline constexpr ParamRange HEIGHT = ParamRange::closed(0.0, 10.0);
/** \brief terrain_cell_m, meters. */
inline constexpr ParamRange TERRAIN_CELL = ParamRange::closed(0.05, 100.0);
/** \brief terrain_plane_tile_m, meters (0: the terrain planes go). */
inline constexpr ParamRange PLANE_TILE = ParamRange::closed(0.0, 1000.0);
} // namespace terrain_removal_ranges

/** \brief TerrainRemoval's parameters; their ranges are terrain_removal_ranges' and
 * their declarations terrainRemovalParamDeclarations(). \ingroup segmentation */
struct TerrainRemovalParams {
  /** \brief Largest angle between the ground's normal and the up axis, radians. */
  double eps_angle_rad{0.2};
  /** \brief The sensor is at least this high above the ground plane, meters. */
  double min_sensor_height_m{0.3};
  /** \brief Largest angle between a terrain plane's normal and the up axis,
   * radians (0: the ground plane is the only terrain plane). */
  double terrain_max_slope_rad{0.3};
  /** \brief Largest step from a terrain plane up to the next (a curb), meters. */
  double terrain_max_step_m{0.3};
  /** \brief Points in no plane up to this height above the terrain are terrain,
   * and a terrain plane's inliers higher above it stay, meters (0: no loose point
   * is terrain, every inlier is). */
  double terrain_height_m{0.2};
  /** \brief Cell of the terrain height map, meters. */
  double terrain_cell_m{1.0};
  /** \brief Side of the terrain planes' tiles, meters (0: the terrain planes go). */
  double terrain_plane_tile_m{0.0};
};

/** \brief The one declaration of each TerrainRemovalParams member (key with unit,
 * range, meaning), in the order documented. \ingroup segmentation */
const ParamDeclarations<TerrainRemovalParams>& terrainRemovalParamDeclarations();

/** \brief Removes the terrain (the ground and what lies on it) from a cloud and its
 * planes, before the cuboid approximation.
 *
 * The paper (Sec. III-F, its second assumption) removes the ground plane: here the
 * ground is the first plane (planes come sorted by inlier count) whose normal is
 * within eps_angle_rad of the up axis and that lies at least min_sensor_height_m
 * below the sensor. The rest is ours: every plane within terrain_max_slope_rad of the
 * up axis whose lowest inlier is within terrain_max_step_m of a terrain plane's mean
 * height joins the terrain (sidewalks, lawns, ramps; repeated until none joins); a
 * point in no plane that lies at most terrain_height_m above the terrain (the highest
 * mean height of the terrain planes' inliers per terrain_cell_m cell of the ground
 * plane, else the ground plane) is terrain; a terrain plane's inlier standing more
 * than terrain_height_m above its plane stays (the foot of a guardrail, a post).
 * Inliers of the other planes (walls, down to their feet) and points higher up stay.
 *
 * With terrain_plane_tile_m > 0 the terrain planes stay as planes, one per square
 * tile of that side in the world's x, y plane, each refitted to the inliers lying on
 * it, so that the approximation makes them planar cells; only the loose terrain points
 * go. With 0 (the paper's rule) the terrain planes and all terrain points go.
 *
 * Usage (the planes from SACMultiPlaneSegmentation on the same cloud):
 * \code
 * planar_grid::TerrainRemoval<pcl::PointXYZ> terrain;
 * terrain.setUpAxis(Eigen::Vector3f::UnitZ());
 * terrain.setSensorOrigin(cloud->sensor_origin_.head<3>());
 * std::vector<std::uint8_t> is_terrain;
 * if (terrain.segment(*cloud, planes, is_terrain))
 *   ... // drop the points with is_terrain[i] != 0; planes holds the others
 * \endcode
 * \tparam PointT a point type with x, y, z \ingroup segmentation */
template <typename PointT> class TerrainRemoval {
public:
  /** \brief The input cloud's type. */
  using PointCloud = pcl::PointCloud<PointT>;

  /** \brief The parameters (TerrainRemovalParams). */
  using Params = TerrainRemovalParams;

  /** \brief Each parameter's one declaration (key, range, unit, meaning): the
   * ground_removal stage, its reference and the Python keywords are made from it.
   * \return terrainRemovalParamDeclarations() */
  static const ParamDeclarations<Params>& getParamDeclarations()
  {
    return terrainRemovalParamDeclarations();
  }

  /** \brief A removal with the default parameters. */
  TerrainRemoval() = default;
  /** \brief A removal with \a params (checked by segment()). */
  explicit TerrainRemoval(const Params& params) : params_(params) {}

  /** \brief Sets the parameters (checked by segment()). */
  void setParams(const Params& params) { params_ = params; }
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Sets the up direction in the cloud's frame (need not be unit length;
   * default +z). */
  void setUpAxis(const Eigen::Vector3f& up) { up_ = up; }
  /** \brief The up direction. */
  const Eigen::Vector3f& getUpAxis() const { return up_; }

  /** \brief Sets the sensor's position in the cloud's frame, meters (default the
   * origin): the ground lies min_sensor_height_m below it. */
  void setSensorOrigin(const Eigen::Vector3f& origin) { origin_ = origin; }
  /** \brief The sensor's position, meters. */
  const Eigen::Vector3f& getSensorOrigin() const { return origin_; }

  /** \brief Finds the terrain of \a cloud and its \a planes.
   * \param[in] cloud the points the planes' inliers index (N points)
   * \param[in,out] planes the planes, sorted by inlier count: without a ground plane
   * unchanged; else the terrain planes are removed (terrain_plane_tile_m 0, the other
   * planes keep their order) or each replaced in its place by one plane per tile
   * (terrain_plane_tile_m > 0; each with the inliers lying on it)
   * \param[out] terrain N flags: 1 for a terrain point (to remove), all 0 without a
   * ground plane
   * \return whether a ground plane was found
   * \throws planar_grid::Exception naming the parameter for a value out of its range,
   * or for a zero up axis */
  bool segment(const PointCloud& cloud,
               PlanarSegments& planes,
               std::vector<std::uint8_t>& terrain);

  /** \brief The ground plane of the last segment() that found one: [a, b, c, d] with
   * the normal turned up, so that the sensor's signed distance is its height. */
  const Eigen::Vector4f& getGroundCoefficients() const { return ground_; }

  /** \brief How many of the last segment()'s planes were terrain. */
  std::size_t getTerrainPlaneCount() const { return terrain_plane_count_; }

private:
  /** \brief Throws for a parameter out of its range or a zero up axis. */
  void checkParameters() const;

  /** \brief \a planes' k-th coefficients with the normal turned up; false when the
   * plane has no four coefficients. */
  bool upward(const PlanarSegments& planes, std::size_t k, Eigen::Vector4f& c) const;

  /** \brief The signed height of \a p above the ground plane, meters. */
  float heightAboveGround(const PointT& p) const
  {
    return ground_.template head<3>().dot(p.getVector3fMap()) + ground_[3];
  }

  /** \brief The index of the ground plane among \a planes, or planes.size(). */
  std::size_t findGround(const PlanarSegments& planes) const;

  /** \brief Which planes are terrain: the ground, then every plane within
   * terrain_max_slope of the up axis whose lowest inlier is within terrain_max_step
   * of a terrain plane's mean height, until none joins. */
  std::vector<std::uint8_t> terrainPlanes(const PointCloud& cloud,
                                          const PlanarSegments& planes,
                                          std::size_t ground) const;

  /** \brief Per point: whether a terrain plane's inlier stands more than
   * terrain_height above that plane (above each of the terrain planes it is an inlier
   * of); 0 unseen, 1 stands, 2 lies. */
  std::vector<std::uint8_t>
  standingInliers(const PointCloud& cloud,
                  const PlanarSegments& planes,
                  const std::vector<std::uint8_t>& terrain) const;

  /** \brief The terrain points: the terrain planes' lying inliers (with tiles: none
   * of them), and the points in no plane at most terrain_height above the terrain's
   * height in their cell. */
  std::vector<std::uint8_t>
  terrainPoints(const PointCloud& cloud,
                const PlanarSegments& planes,
                const std::vector<std::uint8_t>& terrain,
                const std::vector<std::uint8_t>& standing) const;

  /** \brief Replaces each terrain plane by one plane per tile, each refitted to its
   * own inliers; a tile's inliers too few for a plane (fewer than 3) are marked in
   * \a remove. */
  void splitIntoTiles(const PointCloud& cloud,
                      const std::vector<std::uint8_t>& terrain,
                      PlanarSegments& planes,
                      std::vector<std::uint8_t>& remove) const;

  Params params_;
  Eigen::Vector3f up_{Eigen::Vector3f::UnitZ()};
  Eigen::Vector3f origin_{Eigen::Vector3f::Zero()};
  /** \brief up_ normalized, set by segment(). */
  Eigen::Vector3f unit_up_{Eigen::Vector3f::UnitZ()};
  Eigen::Vector4f ground_{Eigen::Vector4f::Zero()};
  std::size_t terrain_plane_count_{0};
};

} // namespace planar_grid

#ifdef PCL_NO_PRECOMPILE
#include <planar_grid/segmentation/impl/terrain_removal.hpp>
#endif
