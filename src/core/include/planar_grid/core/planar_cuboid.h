// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/memory.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>

#include <array>
#include <cmath>
#include <cstddef>
#include <vector>

namespace planar_grid {

/** \brief One oriented rectangular cuboid of the planar grid map: a grid approximation
 * of Sec. III-F of the paper ("Efficient Planar Surface-Based 3D Mapping Method for
 * Mobile Robots Using Stereo Vision") (Figs. 6(c) and 7).
 *
 * The box is spanned by three orthonormal axes: the unit \a normal, the in-plane
 * \a horizontal_axis (perpendicular to the normal) and the derived vertical axis
 * normal x horizontal_axis (see verticalAxis()). Its extents along them are
 * \a thickness_m, \a width_m and \a height_m, about \a centre.
 *
 * For a planar cuboid (is_planar, plane_id >= 0) the normal points toward the sensor
 * and the face rectangle (face()) lies at the measured surface; the box is extruded
 * from the face to the BACK, away from the sensor (Fig. 6(c): "extend a certain size
 * along the normal (back) of the plane"). For a non-planar cuboid (Fig. 7) the axes
 * are the up-aligned frame of PlanarCuboidApproximation (vertical axis = up).
 *
 * The header needs the PCL include directories (pcl_common) for pcl/memory.h only.
 * \ingroup core */
struct PlanarCuboid {
  /** \brief Centre of the box, in meters. */
  Eigen::Vector3f centre{Eigen::Vector3f::Zero()};
  /** \brief Unit normal of the face (toward the sensor for a planar cuboid). */
  Eigen::Vector3f normal{Eigen::Vector3f::UnitZ()};
  /** \brief Unit in-plane horizontal axis, perpendicular to the normal. */
  Eigen::Vector3f horizontal_axis{Eigen::Vector3f::UnitX()};
  /** \brief Extent along horizontal_axis, in meters, >= 0. */
  float width_m{0.0f};
  /** \brief Extent along verticalAxis(), in meters, >= 0. */
  float height_m{0.0f};
  /** \brief Extent along the normal, in meters, >= 0; the box reaches from the face
   * (centre + normal thickness_m / 2) back to centre - normal thickness_m / 2. */
  float thickness_m{0.0f};
  /** \brief Index of the plane (into the planes given to the approximation), -1 for
   * a non-planar cuboid. */
  int plane_id{-1};
  /** \brief Number of input points the cuboid was built from. */
  std::size_t point_count{0};
  /** \brief True for a split-and-merged planar cuboid (Fig. 6), false for a split
   * non-planar one (Fig. 7). */
  bool is_planar{false};
  /** \brief Occupancy probability in [0, 1] (default 0.5, unknown; Sec. III-F, filled
   * by the occupancy update). */
  float probability{0.5f};

  /** \brief Returns the vertical axis normal x horizontal_axis (unit when the two
   * axes are orthonormal). */
  [[nodiscard]] Eigen::Vector3f verticalAxis() const
  {
    return normal.cross(horizontal_axis);
  }

  /** \brief Returns the centre of the face rectangle (the sensor-facing side), in
   * meters. */
  [[nodiscard]] Eigen::Vector3f faceCentre() const
  {
    return centre + normal * (0.5f * thickness_m);
  }

  /** \brief Returns the four corners of the face rectangle, in meters, in the order
   * (-w,-h), (+w,-h), (+w,+h), (-w,+h) of (horizontal, vertical) half-extents. */
  [[nodiscard]] std::array<Eigen::Vector3f, 4> face() const
  {
    const Eigen::Vector3f c = faceCentre();
    const Eigen::Vector3f du = horizontal_axis * (0.5f * width_m);
    const Eigen::Vector3f dv = verticalAxis() * (0.5f * height_m);
    return {c - du - dv, c + du - dv, c + du + dv, c - du + dv};
  }

  /** \brief Returns the eight corners, in meters: the face() corners, then the same
   * four at the back (moved by -normal thickness_m). */
  [[nodiscard]] std::array<Eigen::Vector3f, 8> corners() const
  {
    const auto f = face();
    const Eigen::Vector3f back = -normal * thickness_m;
    return {f[0], f[1], f[2], f[3], f[0] + back, f[1] + back, f[2] + back, f[3] + back};
  }

  /** \brief Returns the volume, in cubic meters. */
  [[nodiscard]] float volume() const { return width_m * height_m * thickness_m; }

  /** \brief Returns the face area width_m height_m, in square meters. */
  [[nodiscard]] float faceArea() const { return width_m * height_m; }

  /** \brief Returns whether a point lies inside the box grown by a tolerance.
   * \param[in] point the point, in meters
   * \param[in] tolerance_m added to every half-extent, in meters (>= 0)
   * \return false for a non-finite point */
  [[nodiscard]] bool contains(const Eigen::Vector3f& point,
                              float tolerance_m = 0.0f) const
  {
    const Eigen::Vector3f d = point - centre;
    return std::abs(d.dot(horizontal_axis)) <= 0.5f * width_m + tolerance_m
           && std::abs(d.dot(verticalAxis())) <= 0.5f * height_m + tolerance_m
           && std::abs(d.dot(normal)) <= 0.5f * thickness_m + tolerance_m;
  }

  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief A vector of PlanarCuboid with Eigen's aligned allocator (its
 * fixed-size vectorizable members need it in std::vector).
 * \ingroup core */
using PlanarCuboids = std::vector<PlanarCuboid, Eigen::aligned_allocator<PlanarCuboid>>;

} // namespace planar_grid
