// SPDX-License-Identifier: BSD-3-Clause
// A synthetic street whose surfaces are known exactly, for the tests
// of maps built from its frames.
#pragma once

#include <planar_grid/map/planar_grid_map.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

#include "wall_cuboid.h"

namespace planar_grid_test {
namespace street {

using planar_grid::DepthImage;
using planar_grid::ExplicitSpaceGrid;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarGridMap;
using planar_grid::PlaneModels;
using planar_grid::SpaceState;
using planar_grid_test::wallCuboid;

// ---- the scene ---------------------------------------------------------------------
//
// A street 6 m wide along +x, world z up: the ground z = 0, walls y = +3 and y = -3
// (4 m high) from x = -2 to x = 20, an end wall x = 20, and a 0.4 m box on the ground
// at x in [7.8, 8.2], y in [0.8, 1.2]. A camera 1.5 m high drives along the street
// looking down it (+x), FRAMES frames 0.45 m apart. Each frame sees the surfaces 1 to
// 14 m ahead: one planar cuboid per surface in view, on that surface's plane offset by
// a few millimetres and turned by a few milliradians (a frame's plane estimate),
// features on the surfaces (occupancy 0.85), the box's eight 0.2 m cells as non-planar
// cuboids, and a depth view of the scene for the space layer.

constexpr int FRAMES = 16;
constexpr float STEP_M = 0.45f;
constexpr float NEAR_M = 1.0f;
constexpr float FAR_M = 14.0f;
constexpr float END_X = 20.0f;
constexpr float HALF_WIDTH = 3.0f;
constexpr float WALL_HEIGHT = 4.0f;
const Eigen::AlignedBox3f BOX(Eigen::Vector3f(7.8f, 0.8f, 0.0f),
                              Eigen::Vector3f(8.2f, 1.2f, 0.4f));

constexpr float INF = std::numeric_limits<float>::infinity();
/** All of space: the region whose tiles are every tile of a tiled map. */
const Eigen::AlignedBox3f EVERYWHERE(Eigen::Vector3f::Constant(-INF),
                                     Eigen::Vector3f::Constant(INF));

inline PlanarGridMap::Params
params()
{
  PlanarGridMap::Params p;
  p.resolution_m = 0.1;
  p.space.max_range_m = 15.0;
  p.space.prior = SpaceState::UNKNOWN;
  // The box is given as its eight solid octants, whose insides no view observes: the
  // occupied rule of the clearing would take them (tested on its own in
  // test_planar_grid_map.cpp); the tests of this scene compare maps and merges.
  p.non_planar_min_occupied = 0.0;
  return p;
}

/** The camera of frame \a f (x right, y down, z forward), world frame. */
inline Eigen::Isometry3d
cameraPose(int f)
{
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  pose.translation() = Eigen::Vector3d(STEP_M * f, 0.0, 1.5);
  return pose;
}

/** The depth of the scene along the ray \a origin + t \a direction (world), or
 * infinity: the nearest of the ground, the walls, the end wall and the box. */
inline double
sceneDistance(const Eigen::Vector3d& origin, const Eigen::Vector3d& direction)
{
  double best = std::numeric_limits<double>::infinity();
  const auto inside = [](double v, double lo, double hi) {
    return v >= lo && v <= hi;
  };
  const auto hit = [&](int axis, double value, int a, double a_lo, double a_hi, int b,
                       double b_lo, double b_hi) {
    if (std::abs(direction[axis]) < 1e-12)
      return;
    const double t = (value - origin[axis]) / direction[axis];
    if (!(t > 1e-6) || t >= best)
      return;
    const Eigen::Vector3d p = origin + t * direction;
    if (inside(p[a], a_lo, a_hi) && inside(p[b], b_lo, b_hi))
      best = t;
  };
  hit(2, 0.0, 0, -2.0, END_X, 1, -HALF_WIDTH, HALF_WIDTH);        // ground
  hit(1, HALF_WIDTH, 0, -2.0, END_X, 2, 0.0, WALL_HEIGHT);        // left wall
  hit(1, -HALF_WIDTH, 0, -2.0, END_X, 2, 0.0, WALL_HEIGHT);       // right wall
  hit(0, END_X, 1, -HALF_WIDTH, HALF_WIDTH, 2, 0.0, WALL_HEIGHT); // end wall
  const Eigen::Vector3d lo = BOX.min().cast<double>(), hi = BOX.max().cast<double>();
  hit(0, lo.x(), 1, lo.y(), hi.y(), 2, lo.z(), hi.z()); // box, front
  hit(1, lo.y(), 0, lo.x(), hi.x(), 2, lo.z(), hi.z()); // box, right side
  hit(2, hi.z(), 0, lo.x(), hi.x(), 1, lo.y(), hi.y()); // box, top
  return best;
}

/** A 64 x 48 view (f = 40 px) of the scene from \a pose (world). */
inline DepthImage
renderView(const Eigen::Isometry3d& pose)
{
  DepthImage image;
  image.width = 64;
  image.height = 48;
  image.fx = image.fy = 40.0f;
  image.cx = 31.5f;
  image.cy = 23.5f;
  image.depth_m.resize(64 * 48);
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u) {
      const Eigen::Vector3d ray((u - image.cx) / image.fx, (v - image.cy) / image.fy,
                                1.0);
      const double t = sceneDistance(pose.translation(), pose.linear() * ray);
      // t along a ray whose camera z is 1: t is the depth
      image.depth_m[static_cast<std::size_t>(v * image.width + u)] =
        std::isfinite(t) ? static_cast<float>(t) : 0.0f;
    }
  return image;
}

/** One frame's surface input. */
struct FrameSurface {
  PlanarCuboids cuboids;
  PlaneModels planes;
  pcl::PointCloud<pcl::PointXYZ> features;
  std::vector<float> probabilities;
};

/** The surfaces frame \a f sees (the scene's description above), world frame. */
inline FrameSurface
frameSurface(int f)
{
  FrameSurface out;
  const float x0 = STEP_M * static_cast<float>(f) + NEAR_M;
  const float x1 = std::min(STEP_M * static_cast<float>(f) + FAR_M, END_X);
  // a frame's plane estimate: the true plane moved by up to 5 mm along its normal and
  // turned by up to 2 mrad about its vertical axis
  const auto offset = [f](int surface) {
    return 0.005f
           * std::sin(1.7f * static_cast<float>(f) + static_cast<float>(surface));
  };
  const auto tilt = [f](int surface) {
    return 0.002f
           * std::cos(2.3f * static_cast<float>(f) + static_cast<float>(surface));
  };
  const auto add = [&](const Eigen::Vector3f& point_on_plane,
                       const Eigen::Vector3f& true_normal, const Eigen::Vector3f& u,
                       float width, float height) {
    const int id = static_cast<int>(out.planes.size());
    const Eigen::Vector3f v = true_normal.cross(u);
    const Eigen::Vector3f n =
      Eigen::AngleAxisf(tilt(id), v).toRotationMatrix() * true_normal;
    const Eigen::Vector3f face_u = (u - n * n.dot(u)).normalized();
    const Eigen::Vector3f face = point_on_plane + n * offset(id);
    out.planes.emplace_back(n.x(), n.y(), n.z(), -n.dot(face));
    out.cuboids.push_back(wallCuboid(face, n, face_u, width, height, id));
    // features every 0.5 m on the face
    const Eigen::Vector3f face_v = n.cross(face_u);
    for (float a = -0.5f * width + 0.25f; a < 0.5f * width; a += 0.5f)
      for (float b = -0.5f * height + 0.25f; b < 0.5f * height; b += 0.5f) {
        const Eigen::Vector3f p = face + a * face_u + b * face_v;
        out.features.push_back(pcl::PointXYZ(p.x(), p.y(), p.z()));
        out.probabilities.push_back(0.85f);
      }
  };
  const float mid = 0.5f * (x0 + x1), length = x1 - x0;
  add(Eigen::Vector3f(mid, 0.0f, 0.0f), Eigen::Vector3f::UnitZ(),
      Eigen::Vector3f::UnitX(), length, 2.0f * HALF_WIDTH);
  add(Eigen::Vector3f(mid, HALF_WIDTH, 0.5f * WALL_HEIGHT), -Eigen::Vector3f::UnitY(),
      Eigen::Vector3f::UnitX(), length, WALL_HEIGHT);
  add(Eigen::Vector3f(mid, -HALF_WIDTH, 0.5f * WALL_HEIGHT), Eigen::Vector3f::UnitY(),
      -Eigen::Vector3f::UnitX(), length, WALL_HEIGHT);
  if (STEP_M * static_cast<float>(f) + FAR_M >= END_X)
    add(Eigen::Vector3f(END_X, 0.0f, 0.5f * WALL_HEIGHT), -Eigen::Vector3f::UnitX(),
        -Eigen::Vector3f::UnitY(), 2.0f * HALF_WIDTH, WALL_HEIGHT);
  if (BOX.min().x() >= x0 && BOX.min().x() <= x1)
    for (int k = 0; k < 8; ++k) {
      PlanarCuboid cell;
      cell.normal = -Eigen::Vector3f::UnitX();
      cell.horizontal_axis = -Eigen::Vector3f::UnitY();
      cell.width_m = cell.height_m = cell.thickness_m = 0.2f;
      cell.centre = BOX.min()
                    + Eigen::Vector3f(0.1f + 0.2f * static_cast<float>(k & 1),
                                      0.1f + 0.2f * static_cast<float>((k >> 1) & 1),
                                      0.1f + 0.2f * static_cast<float>(k >> 2));
      cell.plane_id = -1;
      cell.is_planar = false;
      out.cuboids.push_back(cell);
      out.features.push_back(
        pcl::PointXYZ(cell.centre.x(), cell.centre.y(), cell.centre.z()));
      out.probabilities.push_back(0.9f);
    }
  return out;
}

/** \a surface moved by \a t (the frame's input as seen in another world frame). */
inline FrameSurface
moved(const FrameSurface& surface, const Eigen::Isometry3d& t)
{
  const Eigen::Isometry3f tf = t.cast<float>();
  FrameSurface out = surface;
  for (PlanarCuboid& c : out.cuboids) {
    c.centre = tf * c.centre;
    c.normal = tf.linear() * c.normal;
    c.horizontal_axis = tf.linear() * c.horizontal_axis;
  }
  for (Eigen::Vector4f& p : out.planes) {
    const Eigen::Vector3f n = tf.linear() * p.head<3>();
    p = Eigen::Vector4f(n.x(), n.y(), n.z(), p[3] - n.dot(tf.translation()));
  }
  for (pcl::PointXYZ& p : out.features)
    p.getVector3fMap() = tf * p.getVector3fMap();
  return out;
}

/** The map of frames [first, last), every input moved by \a world_to_map (the frame
 * the map is built in, from the scene's world frame); each frame's number is noted as
 * its observation order, as the pipeline notes a frame's index. */
inline PlanarGridMap
mapFrames(int first,
          int last,
          const Eigen::Isometry3d& world_to_map = Eigen::Isometry3d::Identity())
{
  PlanarGridMap map(params());
  for (int f = first; f < last; ++f) {
    const FrameSurface s = moved(frameSurface(f), world_to_map);
    map.integrateSurface(s.cuboids, s.planes, s.features, s.probabilities);
    map.integrateDepthImage(renderView(cameraPose(f)), world_to_map * cameraPose(f));
    map.noteObservationOrder(f);
  }
  return map;
}

inline PlanarGridMap
copyOf(const PlanarGridMap& map)
{
  std::string bytes;
  map.serialize(bytes);
  return PlanarGridMap::deserialize(bytes, "copy");
}

inline std::string
bytesOf(const PlanarGridMap& map)
{
  std::string bytes;
  map.serialize(bytes);
  return bytes;
}

/** Probe points every 0.15 m over the street (x in [-1, 21], y in [-3.5, 3.5], z in
 * [-0.3, 4.3]), off the voxel grid's faces. */
inline std::vector<Eigen::Vector3f>
probes()
{
  std::vector<Eigen::Vector3f> out;
  for (float x = -1.0f; x <= 21.0f; x += 0.15f)
    for (float y = -3.5f; y <= 3.5f; y += 0.15f)
      for (float z = -0.3f; z <= 4.3f; z += 0.15f)
        out.emplace_back(x + 0.0123f, y + 0.0231f, z + 0.0312f);
  return out;
}

} // namespace street
} // namespace planar_grid_test
