// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief A body for PlanarGridMap::isCollisionFree(): an oriented box or a sphere,
 * world frame, meters. Build one with box() or sphere(). \ingroup map */
struct CollisionBody {
  /** \brief The body's shape. */
  enum class Shape : std::uint8_t { BOX = 0, SPHERE = 1 };
  /** \brief BOX or SPHERE. */
  Shape shape{Shape::SPHERE};
  /** \brief Centre of the box or of the sphere, meters. */
  Eigen::Vector3f centre{Eigen::Vector3f::Zero()};
  /** \brief BOX: the box's axes as the columns (a rotation, world_R_box). */
  Eigen::Matrix3f rotation{Eigen::Matrix3f::Identity()};
  /** \brief BOX: half of the edge lengths along the columns of rotation, meters,
   * >= 0. */
  Eigen::Vector3f half_extents{Eigen::Vector3f::Zero()};
  /** \brief SPHERE: the radius, meters, >= 0. */
  float radius_m{0.0f};

  /** \brief An oriented box (e.g. a robot's footprint at a pose).
   * \param[in] centre the centre, meters
   * \param[in] half_extents half edge lengths along the box axes, meters
   * \param[in] rotation world_R_box, its columns the box axes (orthonormal) */
  static CollisionBody
  box(const Eigen::Vector3f& centre,
      const Eigen::Vector3f& half_extents,
      const Eigen::Matrix3f& rotation = Eigen::Matrix3f::Identity())
  {
    CollisionBody b;
    b.shape = Shape::BOX;
    b.centre = centre;
    b.half_extents = half_extents;
    b.rotation = rotation;
    return b;
  }
  /** \brief A sphere of \a radius_m meters about \a centre (meters). */
  static CollisionBody sphere(const Eigen::Vector3f& centre, float radius_m)
  {
    CollisionBody b;
    b.shape = Shape::SPHERE;
    b.centre = centre;
    b.radius_m = radius_m;
    return b;
  }

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief Bodies with Eigen's aligned allocator. \ingroup map */
using CollisionBodies =
  std::vector<CollisionBody, Eigen::aligned_allocator<CollisionBody>>;

/** \brief The valid ranges of OccupancyGrid2DParams, which computeOccupancyGrid2D()
 * checks and the pipeline's `output.map_grid_2d_band` keys take (its angles in degrees,
 * the same ranges converted). */
namespace occupancy_grid_2d_ranges {
/** \brief Cell edge of the 2D map, when not 0 (the map's): [0.001, 100] m. */
inline constexpr ParamRange RESOLUTION = ParamRange::closed(0.001, 100.0);
/** \brief Reference height: [-10000, 10000] m. */
inline constexpr ParamRange Z_REF = ParamRange::closed(-1e4, 1e4);
/** \brief Ends of the band above the reference: [-1000, 1000] m. */
inline constexpr ParamRange Z_BAND = ParamRange::closed(-1e3, 1e3);
/** \brief Edge of the terrain tiles: (0, 100] m. */
inline constexpr ParamRange TERRAIN_TILE = ParamRange::openMin(0.0, 100.0);
/** \brief Angles from vertical (terrain_max_angle_rad, max_slope_rad): [0, pi/2] rad.
 */
inline constexpr ParamRange ANGLE = ParamRange::closed(0.0, 1.5707963267948966);
} // namespace occupancy_grid_2d_ranges

/** \brief What PlanarGridMap::computeOccupancyGrid2D() projects and how it is
 * written. Heights in meters, world frame (z up). \ingroup map */
struct OccupancyGrid2DParams {
  /** Cell edge of the 2D map, meters; 0 takes the map's resolution_m; else within
   * occupancy_grid_2d_ranges::RESOLUTION. */
  double resolution_m{0.0};
  /** The fixed reference height, meters (occupancy_grid_2d_ranges::Z_REF): the band
   * is [z_ref_m + z_min_m, z_ref_m + z_max_m] (where above_terrain finds no terrain,
   * too). */
  double z_ref_m{0.0};
  /** Lower end of the band above the reference, meters
   * (occupancy_grid_2d_ranges::Z_BAND). */
  double z_min_m{0.2};
  /** Upper end of the band above the reference, meters
   * (occupancy_grid_2d_ranges::Z_BAND); > z_min_m. */
  double z_max_m{2.0};
  /** Measure the band above the local terrain instead of z_ref_m: in a cell covered
   * by a walkable terrain cuboid, the highest top of those cuboids in the cell's
   * column; elsewhere the terrain the space layer saw: per cell the lowest top of an
   * occupied voxel whose upper neighbour was observed free (a surface seen from above),
   * and per square tile of terrain_tile_m the 20th percentile of its cells' values (so
   * that a car roof in a tile of road is not the terrain); z_ref_m where neither is
   * known. */
  bool above_terrain{false};
  /** With above_terrain: the edge of the tiles of the space layer's terrain, meters
   * (occupancy_grid_2d_ranges::TERRAIN_TILE). */
  double terrain_tile_m{2.0};
  /** A planar cuboid whose normal is within terrain_max_angle_rad of vertical is
   * terrain; within occupancy_grid_2d_ranges::ANGLE. */
  double terrain_max_angle_rad{1.0471975511965976};
  /** Terrain steeper than this (normal to vertical, radians; within
   * occupancy_grid_2d_ranges::ANGLE) is an
   * obstacle wherever it covers a cell; flatter terrain is walkable and seen free. */
  double max_slope_rad{0.3490658503988659};
  /** Use min_xy / max_xy instead of the map's extent (the XY bounds of the space
   * layer's stored blocks and of the cuboids). */
  bool use_bounds{false};
  /** With use_bounds: the lower-left corner of the 2D map, meters. */
  Eigen::Vector2d min_xy{Eigen::Vector2d::Zero()};
  /** With use_bounds: the upper-right corner of the 2D map, meters (> min_xy). */
  Eigen::Vector2d max_xy{Eigen::Vector2d::Zero()};
  /** map_server's occupied_thresh written to the YAML, in (free_thresh, 1). */
  double occupied_thresh{0.65};
  /** map_server's free_thresh written to the YAML, in (0, occupied_thresh). */
  double free_thresh{0.196};
};

/** \brief A 2D occupancy grid (ROS nav_msgs/OccupancyGrid conventions): cell (col,
 * row) covers [origin + col r, origin + (col + 1) r) x [origin + row r, ...), row 0
 * at the lowest y. \ingroup map */
struct OccupancyGrid2D {
  /** \brief Cell value of a cell never seen. */
  static constexpr std::int8_t UNKNOWN = -1;
  /** \brief Cell value of a cell seen free. */
  static constexpr std::int8_t FREE = 0;
  /** \brief Cell value of an obstacle cell. */
  static constexpr std::int8_t OCCUPIED = 100;
  /** \brief Columns (along x). */
  int width{0};
  /** \brief Rows (along y). */
  int height{0};
  /** \brief Cell edge, meters. */
  double resolution_m{0.0};
  /** \brief World coordinates of the lower-left corner of cell (0, 0), meters. */
  Eigen::Vector2d origin{Eigen::Vector2d::Zero()};
  /** \brief width x height values (UNKNOWN, FREE, OCCUPIED), row-major, row 0 at the
   * lowest y. */
  std::vector<std::int8_t> cells;

  /** \brief Value of cell (col, row) (no bounds check). */
  [[nodiscard]] std::int8_t at(int col, int row) const
  {
    return cells[static_cast<std::size_t>(row) * static_cast<std::size_t>(width)
                 + static_cast<std::size_t>(col)];
  }
  /** \brief Number of cells holding \a value. */
  [[nodiscard]] std::size_t count(std::int8_t value) const;
};

/** \brief Writes \a grid as the 8-bit binary PGM (P5) of a ROS map_server map: 0
 * occupied, 254 free, 205 unknown, the top image row at the largest y. Atomic
 * (temporary file, rename).
 * \throws planar_grid::IOError when it cannot be written \ingroup map */
void writeOccupancyGrid2DImage(const OccupancyGrid2D& grid,
                               const std::string& pgm_path);

/** \brief Writes the map_server YAML of \a grid: image (\a image_name, relative to
 * the YAML's folder), mode trinary, resolution, origin [x, y, 0], negate 0,
 * occupied_thresh, free_thresh. Atomic (temporary file, rename).
 * \throws planar_grid::IOError when it cannot be written \ingroup map */
void writeOccupancyGrid2DYaml(const OccupancyGrid2D& grid,
                              const std::string& yaml_path,
                              const std::string& image_name,
                              double occupied_thresh,
                              double free_thresh);

} // namespace planar_grid
