// SPDX-License-Identifier: BSD-3-Clause
// The point, ray, distance and collision queries of PlanarGridMap on numpy arrays, and
// MapRegionIndex, the same distance and collision queries over one region.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** (N, 3) rows, or one (3,) row repeated to \a n (n = 0: its own count). */
std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>
toRays(const FloatArray& array, std::size_t n, const char* name)
{
  if (array.ndim() == 1 && array.shape(0) == 3) {
    const auto v = array.unchecked<1>();
    return std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>(
      std::max<std::size_t>(n, 1), Eigen::Vector3f(v(0), v(1), v(2)));
  }
  auto rows = toPoints(array, name);
  if (n != 0 && rows.size() != n)
    throw py::value_error(std::string(name) + " has " + std::to_string(rows.size())
                          + " rows for " + std::to_string(n) + " rays");
  return rows;
}

/** Bodies from numpy arrays: centres (N, 3) and either half_extents ((N, 3) or (3,))
 * with rotations ((N, 3, 3) or (3, 3)) or yaw ((N,) or scalar), or radii ((N,) or
 * scalar). */
CollisionBodies
toBodies(const FloatArray& centres,
         const py::object& half_extents,
         const py::object& rotations,
         const py::object& yaw,
         const py::object& radii)
{
  if (centres.ndim() != 2 || centres.shape(1) != 3)
    throw py::value_error("centres must be an (N, 3) array of x, y, z in meters");
  const py::ssize_t n = centres.shape(0);
  const auto c = centres.unchecked<2>();
  CollisionBodies bodies(static_cast<std::size_t>(n));
  const bool spheres = !radii.is_none();
  if (spheres == !half_extents.is_none())
    throw py::value_error("give half_extents (boxes) or radii (spheres), not both");
  if (spheres && (!rotations.is_none() || !yaw.is_none()))
    throw py::value_error("rotations and yaw apply to boxes only");
  if (!rotations.is_none() && !yaw.is_none())
    throw py::value_error("give rotations or yaw, not both");
  // A per-body array of shape (N, ...) or one value shared by every body.
  const auto perBody = [n](const FloatArray& a, py::ssize_t row_size,
                           const char* name) {
    const py::ssize_t rows = a.size() / std::max<py::ssize_t>(row_size, 1);
    if (a.size() == row_size)
      return false;
    if (rows != n || a.size() != n * row_size || a.shape(0) != n)
      throw py::value_error(std::string(name)
                            + " must hold one value for all bodies "
                              "or one per body (first axis N = "
                            + std::to_string(n) + ")");
    return true;
  };
  if (spheres) {
    const FloatArray r = FloatArray::ensure(radii);
    const bool each = perBody(r, 1, "radii");
    for (py::ssize_t i = 0; i < n; ++i)
      bodies[static_cast<std::size_t>(i)] = CollisionBody::sphere(
        Eigen::Vector3f(c(i, 0), c(i, 1), c(i, 2)), r.data()[each ? i : 0]);
  } else {
    const FloatArray h = FloatArray::ensure(half_extents);
    const bool each_h = perBody(h, 3, "half_extents");
    FloatArray rot, yaws;
    bool each_r = false;
    const bool has_rot = !rotations.is_none(), has_yaw = !yaw.is_none();
    if (has_rot) {
      rot = FloatArray::ensure(rotations);
      each_r = perBody(rot, 9, "rotations");
    }
    if (has_yaw) {
      yaws = FloatArray::ensure(yaw);
      each_r = perBody(yaws, 1, "yaw");
    }
    for (py::ssize_t i = 0; i < n; ++i) {
      const float* hp = h.data() + (each_h ? 3 * i : 0);
      Eigen::Matrix3f r = Eigen::Matrix3f::Identity();
      if (has_rot) {
        const float* rp = rot.data() + (each_r ? 9 * i : 0);
        for (int a = 0; a < 3; ++a)
          for (int b = 0; b < 3; ++b)
            r(a, b) = rp[3 * a + b];
      } else if (has_yaw) {
        r = Eigen::AngleAxisf(yaws.data()[each_r ? i : 0], Eigen::Vector3f::UnitZ())
              .toRotationMatrix();
      }
      bodies[static_cast<std::size_t>(i)] =
        CollisionBody::box(Eigen::Vector3f(c(i, 0), c(i, 1), c(i, 2)),
                           Eigen::Vector3f(hp[0], hp[1], hp[2]), r);
    }
  }
  return bodies;
}

/** A (N,) bool array of free bodies. */
py::array_t<bool>
toFreeArray(const std::vector<std::uint8_t>& free)
{
  py::array_t<bool> out(static_cast<py::ssize_t>(free.size()));
  bool* o = out.mutable_data();
  for (std::size_t i = 0; i < free.size(); ++i)
    o[i] = free[i] != 0;
  return out;
}

/** (distances (N,), gradients (N, 3)) as float64 arrays. */
py::tuple
toDistanceArrays(const Eigen::VectorXf& d, const Eigen::Matrix3Xf& g)
{
  const Eigen::Index n = d.size();
  py::array_t<double> distances(static_cast<py::ssize_t>(n));
  py::array_t<double> gradients({static_cast<py::ssize_t>(n), py::ssize_t{3}});
  double* dd = distances.mutable_data();
  double* gg = gradients.mutable_data();
  for (Eigen::Index i = 0; i < n; ++i) {
    dd[i] = d[i];
    for (int k = 0; k < 3; ++k)
      gg[3 * i + k] = g(k, i);
  }
  return py::make_tuple(distances, gradients);
}

/** Runs query(points 3 x N, distances, gradients) without the GIL on an (N, 3) float
 * array of points, meters, and returns toDistanceArrays() of its answers.
 * \throws ValueError when points is not (N, 3) */
template <typename Query>
py::tuple
distancesOf(const FloatArray& points, Query query)
{
  const bool single = points.ndim() == 1 && points.shape(0) == 3;
  if (!single && (points.ndim() != 2 || points.shape(1) != 3))
    throw py::value_error("points must be an (N, 3) array of x, y, z in meters, or one "
                          "(3,) point");
  const Eigen::Index n = single ? 1 : points.shape(0);
  Eigen::VectorXf d(n);
  Eigen::Matrix3Xf g(3, n);
  {
    // An (N, 3) C-contiguous float32 array is a 3 x N column-major matrix.
    const Eigen::Map<const Eigen::Matrix3Xf> p(points.data(), 3, n);
    py::gil_scoped_release release;
    query(p, d, g);
  }
  const py::tuple arrays = toDistanceArrays(d, g);
  if (!single)
    return arrays;
  // One (3,) point: its distance and its (3,) gradient.
  return py::make_tuple(arrays[0].attr("__getitem__")(0),
                        arrays[1].attr("__getitem__")(0));
}

/** \brief The map's Python class, registered by bindMap(). */
using MapClass = py::class_<PlanarGridMap, std::shared_ptr<PlanarGridMap>>;

/** \brief get_state, get_occupancy and cast_rays. */
void
bindStateQueries(MapClass& cls)
{
  using Map = PlanarGridMap;
  cls
    .def(
      "get_state",
      [](const Map& self, const FloatArray& points) -> py::object {
        const auto p = toPoints(points, "points");
        py::array_t<std::uint8_t> out(static_cast<py::ssize_t>(p.size()));
        std::uint8_t* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < p.size(); ++i)
            o[i] = static_cast<std::uint8_t>(self.getState(p[i]));
        }
        if (points.ndim() == 1) // one (3,) point: its value
          return out.attr("__getitem__")(0);
        return out;
      },
      py::arg("points"), R"doc(State at each point.

Parameters
----------
points : array_like, shape (N, 3) or (3,)
    Query points, meters (a (3,) array: one point, and its value is returned).

Returns
-------
numpy.ndarray, shape (N,), uint8
    SpaceState per point: OCCUPIED inside a cuboid with probability >= occupancy_thres,
    FREE inside one below it, else the voxel's state (the prior where never observed).
)doc")
    .def(
      "get_occupancy",
      [](const Map& self, const FloatArray& points) -> py::object {
        const auto p = toPoints(points, "points");
        py::array_t<double> out(static_cast<py::ssize_t>(p.size()));
        double* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < p.size(); ++i)
            o[i] = self.getOccupancy(p[i]);
        }
        if (points.ndim() == 1) // one (3,) point: its value
          return out.attr("__getitem__")(0);
        return out;
      },
      py::arg("points"), R"doc(Occupancy probability at each point.

Parameters
----------
points : array_like, shape (N, 3) or (3,)
    Query points, meters (a (3,) array: one point, and its value is returned).

Returns
-------
numpy.ndarray, shape (N,), float64
    Probability in [0, 1]: the cuboid's inside a cuboid, else 0.971 / 0.1192 / 0.5 for
    an occupied / free / unknown voxel (OctoMap's clamping bounds).
)doc")
    .def(
      "cast_rays",
      [](const Map& self, const FloatArray& origins, const FloatArray& directions,
         double max_range_m) {
        const auto d = toRays(directions, 0, "directions");
        const auto o = toRays(origins, d.size(), "origins");
        py::array_t<bool> hit(static_cast<py::ssize_t>(d.size()));
        py::array_t<double> points(
          {static_cast<py::ssize_t>(d.size()), py::ssize_t{3}});
        bool* h = hit.mutable_data();
        double* q = points.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < d.size(); ++i) {
            Eigen::Vector3f end;
            try {
              h[i] = self.castRay(o[i], d[i], max_range_m, end);
            } catch (const Exception& e) {
              throw py::value_error("cast_rays: ray " + std::to_string(i) + ": "
                                    + e.what());
            }
            for (int k = 0; k < 3; ++k)
              q[3 * i + static_cast<std::size_t>(k)] =
                h[i] ? end[k] : std::numeric_limits<double>::quiet_NaN();
          }
        }
        return py::make_tuple(hit, points);
      },
      py::arg("origins"), py::arg("directions"), py::arg("max_range_m"),
      R"doc(Casts rays to the first occupied cell of either layer.

Parameters
----------
origins : array_like, shape (N, 3) or (3,)
    Ray starts, meters; one (3,) origin is shared by every ray.
directions : array_like, shape (N, 3) or (3,)
    Ray directions (finite, any length > 0).
max_range_m : float
    Largest distance, meters, >= 0; ``math.inf`` casts to the end of the map.

Returns
-------
hit : numpy.ndarray, shape (N,), bool
    True where an occupied cuboid or voxel lies within max_range_m.
points : numpy.ndarray, shape (N, 3), float64
    The entry point into the occupied cuboid or the occupied voxel's centre, meters;
    NaN where nothing was hit.

Raises
------
ValueError
    For a zero or non-finite direction, a non-finite origin, or a negative or NaN
    max_range_m, naming the ray.
)doc");
}

/** \brief get_distance and is_collision_free. */
void
bindDistanceQueries(MapClass& cls)
{
  using Map = PlanarGridMap;
  cls
    .def(
      "get_distance",
      [](const Map& self, const FloatArray& points, double max_distance_m,
         bool unknown_is_occupied) {
        return distancesOf(points, [&](const auto& p, auto& d, auto& g) {
          self.getDistance(p, max_distance_m, d, g, unknown_is_occupied);
        });
      },
      py::arg("points"), py::arg("max_distance_m"),
      py::arg("unknown_is_occupied") = false,
      R"doc(Distance to the nearest obstacle and its gradient, for a batch of points.

Exact Euclidean distance to the union of the occupied cuboids (oriented boxes) and the
occupied voxels (boxes of the cell size); with ``unknown_is_occupied`` unknown space
counts too (with the unknown prior: everything not observed, also outside the map).
The obstacle index is built on the first call and kept until the map changes.

Parameters
----------
points : array_like, shape (N, 3)
    Query points, meters.
max_distance_m : float
    The cap, meters (> 0).
unknown_is_occupied : bool
    Count unknown space as an obstacle.

Returns
-------
distances : numpy.ndarray, shape (N,), float64
    Meters, in [0, max_distance_m]: 0 inside an obstacle, max_distance_m where nothing
    is nearer; NaN for a non-finite point.
gradients : numpy.ndarray, shape (N, 3), float64
    Unit vectors away from the nearest obstacle (outside: from its closest point toward
    the point; inside: the outward normal of the nearest face of a box containing the
    point); zero beyond the cap.
)doc")
    .def(
      "is_collision_free",
      [](const Map& self, const FloatArray& centres, const py::object& half_extents,
         const py::object& rotations, const py::object& yaw, const py::object& radii,
         bool unknown_is_occupied) {
        const CollisionBodies bodies =
          toBodies(centres, half_extents, rotations, yaw, radii);
        std::vector<std::uint8_t> free;
        {
          py::gil_scoped_release release;
          free = self.isCollisionFree(bodies, unknown_is_occupied);
        }
        return toFreeArray(free);
      },
      py::arg("centres"), py::kw_only(), py::arg("half_extents") = py::none(),
      py::arg("rotations") = py::none(), py::arg("yaw") = py::none(),
      py::arg("radii") = py::none(), py::arg("unknown_is_occupied") = false,
      R"doc(Collision test for a batch of oriented boxes or spheres.

Exact: separating axes between a box and each obstacle box (occupied cuboids, occupied
voxels as boxes of the cell size), closest point for a sphere. Touching collides.

Parameters
----------
centres : array_like, shape (N, 3)
    Centres of the bodies, meters.
half_extents : array_like, shape (N, 3) or (3,), optional
    Boxes: half edge lengths along the box axes, meters.
rotations : array_like, shape (N, 3, 3) or (3, 3), optional
    Boxes: world_R_box (the box axes as columns); default axis-aligned.
yaw : array_like, shape (N,) or scalar, optional
    Boxes: rotation about +z, radians (instead of rotations).
radii : array_like, shape (N,) or scalar, optional
    Spheres: radii, meters (instead of half_extents).
unknown_is_occupied : bool
    Count unknown space as an obstacle.

Returns
-------
numpy.ndarray, shape (N,), bool
    True where the body touches no obstacle (False also for a non-finite body).
)doc");
}

/** \brief MapRegionIndex: the distance and collision queries over one region. */
void
bindRegionIndex(py::module_& m)
{
  using Map = PlanarGridMap;
  py::class_<MapRegionIndex>(
    m, "MapRegionIndex",
    R"doc(The distance and collision queries of a map over one region (a planner's local
window): only the obstacles within max_distance_m of the box are indexed, so building it
costs what the region holds. Inside the region the answers are the map's; it is a
snapshot (later changes of the map are not seen).

Parameters
----------
map : PlanarGridMap
min_m, max_m : array_like, shape (3,)
    The region's corners, meters.
max_distance_m : float
    The distance cap, meters.
unknown_is_occupied : bool
    Count unknown space as an obstacle.
)doc")
    .def(py::init([](const Map& map, const DoubleArray& min_m, const DoubleArray& max_m,
                     double max_distance_m, bool unknown_is_occupied) {
           const Eigen::Vector3f lo = toVector3f(min_m, "min_m");
           const Eigen::Vector3f hi = toVector3f(max_m, "max_m");
           py::gil_scoped_release release;
           return std::make_unique<MapRegionIndex>(map, lo, hi, max_distance_m,
                                                   unknown_is_occupied);
         }),
         py::arg("map"), py::arg("min_m"), py::arg("max_m"), py::arg("max_distance_m"),
         py::arg("unknown_is_occupied") = false)
    .def(
      "get_distance",
      [](const MapRegionIndex& self, const FloatArray& points) {
        return distancesOf(
          points, [&](const auto& p, auto& d, auto& g) { self.getDistance(p, d, g); });
      },
      py::arg("points"),
      "PlanarGridMap.get_distance() with the index's cap: (distances (N,), gradients "
      "(N, 3)); NaN for points outside the region.")
    .def(
      "is_collision_free",
      [](const MapRegionIndex& self, const FloatArray& centres,
         const py::object& half_extents, const py::object& rotations,
         const py::object& yaw, const py::object& radii) {
        const CollisionBodies bodies =
          toBodies(centres, half_extents, rotations, yaw, radii);
        std::vector<std::uint8_t> free;
        {
          py::gil_scoped_release release;
          free = self.isCollisionFree(bodies);
        }
        return toFreeArray(free);
      },
      py::arg("centres"), py::kw_only(), py::arg("half_extents") = py::none(),
      py::arg("rotations") = py::none(), py::arg("yaw") = py::none(),
      py::arg("radii") = py::none(),
      "PlanarGridMap.is_collision_free() (the same arguments); a body reaching beyond "
      "the region grown by the cap is not free.")
    .def_property_readonly("obstacle_count", &MapRegionIndex::getObstacleCount,
                           "Number of obstacle boxes indexed.");
}

} // namespace

void
bindMapQueries(py::module_& m)
{
  // The class is registered by bindMap(); the queries are added to it here.
  auto cls = py::reinterpret_borrow<MapClass>(m.attr("PlanarGridMap"));
  bindStateQueries(cls);
  bindDistanceQueries(cls);
  bindRegionIndex(m);
}

} // namespace python
} // namespace planar_grid
