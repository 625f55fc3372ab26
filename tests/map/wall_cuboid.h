// SPDX-License-Identifier: BSD-3-Clause
// A planar cuboid of a synthetic wall, for the map's tests.
#pragma once

#include <planar_grid/core/planar_cuboid.h>

#include <Eigen/Core>

namespace planar_grid_test {

/** A wall of \a width_m x \a height_m: face centre \a face, unit normal \a normal
 * (toward the sensors), horizontal axis \a u, plane \a plane_id, extruded 0.1 m behind
 * the face. */
inline planar_grid::PlanarCuboid
wallCuboid(const Eigen::Vector3f& face,
           const Eigen::Vector3f& normal,
           const Eigen::Vector3f& u,
           float width_m,
           float height_m,
           int plane_id)
{
  planar_grid::PlanarCuboid c;
  c.normal = normal;
  c.horizontal_axis = u;
  c.width_m = width_m;
  c.height_m = height_m;
  c.thickness_m = 0.1f;
  c.centre = face - normal * 0.05f;
  c.plane_id = plane_id;
  c.is_planar = true;
  return c;
}

} // namespace planar_grid_test
