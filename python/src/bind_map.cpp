// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap: construction, the map file, point and ray queries on numpy arrays, its
// cuboids, planes and memory; SpaceState as a Python IntEnum.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pybind11/stl.h>

#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** A state given as SpaceState, int (0 free, 1 occupied, 2 unknown) or name. */
SpaceState
toSpaceState(const py::handle& state)
{
  if (py::isinstance<py::str>(state)) {
    try {
      return spaceStateFromString(state.cast<std::string>());
    } catch (const planar_grid::Exception& e) {
      throw py::value_error(e.what());
    }
  }
  const int value = state.cast<int>();
  if (value < 0 || value > 2)
    throw py::value_error(
      "state " + std::to_string(value)
      + " must be SpaceState.FREE (0), OCCUPIED (1) or UNKNOWN (2)");
  return static_cast<SpaceState>(value);
}

/** Points of an (N, 3) array, as floats. */
std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>
toPoints(const FloatArray& points, const char* name)
{
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error(std::string(name)
                          + " must be an (N, 3) array of x, y, z in meters");
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> out(
    static_cast<std::size_t>(points.shape(0)));
  const auto p = points.unchecked<2>();
  for (py::ssize_t i = 0; i < points.shape(0); ++i)
    out[static_cast<std::size_t>(i)] = Eigen::Vector3f(p(i, 0), p(i, 1), p(i, 2));
  return out;
}

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

py::dict
paramsDict(const PlanarGridMap::Params& p)
{
  py::dict d;
  d["resolution_m"] = p.resolution_m;
  d["max_range_m"] = p.space.max_range_m;
  d["surface_margin_m"] = p.space.surface_margin_m;
  d["prior"] = toString(p.space.prior);
  d["thickness_m"] = p.surface.thickness_m;
  d["plane_merge_angle_rad"] = p.surface.plane_merge_angle_rad;
  d["plane_merge_distance_m"] = p.surface.plane_merge_distance_m;
  d["occupancy_thres"] = p.surface.occupancy_thres;
  d["feature_distance_m"] = p.surface.feature_distance_m;
  d["close_gaps_cells"] = p.surface.close_gaps_cells;
  d["merge_rule"] = toString(p.surface.merge_rule);
  d["cover_density"] = p.surface.cover_density;
  return d;
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
  if (points.ndim() != 2 || points.shape(1) != 3)
    throw py::value_error("points must be an (N, 3) array of x, y, z in meters");
  const Eigen::Index n = points.shape(0);
  Eigen::VectorXf d(n);
  Eigen::Matrix3Xf g(3, n);
  {
    // An (N, 3) C-contiguous float32 array is a 3 x N column-major matrix.
    const Eigen::Map<const Eigen::Matrix3Xf> p(points.data(), 3, n);
    py::gil_scoped_release release;
    query(p, d, g);
  }
  return toDistanceArrays(d, g);
}

} // namespace

void
bindMap(py::module_& m)
{
  py::object int_enum = py::module_::import("enum").attr("IntEnum");
  py::dict members;
  members["FREE"] = static_cast<int>(SpaceState::FREE);
  members["OCCUPIED"] = static_cast<int>(SpaceState::OCCUPIED);
  members["UNKNOWN"] = static_cast<int>(SpaceState::UNKNOWN);
  py::object space_state =
    int_enum("SpaceState", members, py::arg("module") = "planar_grid");
  space_state.attr("__doc__") =
    "State of a cell of the map, with the paper's 2-bit labels (Sec. IV): FREE = 0, "
    "OCCUPIED = 1, UNKNOWN = 2. An IntEnum, so it compares with the uint8 arrays of "
    "PlanarGridMap.get_state().";
  m.attr("SpaceState") = space_state;

  using Map = PlanarGridMap;
  py::class_<Map, std::shared_ptr<Map>> cls(
    m, "PlanarGridMap",
    R"doc(The planar grid map: plane-aligned cuboids and explicit free / occupied / unknown space.

planar_grid::PlanarGridMap (paper Sec. III-F, Fig. 5c, Sec. IV): a surface layer of
cuboids with occupancy probabilities, merged across frames, and an explicit space
layer of voxels of edge resolution_m. A point inside a cuboid takes the cuboid's
probability (occupied when >= occupancy_thres); elsewhere the voxel's state decides.

Parameters
----------
resolution_m : float, optional
    The minimum cell size (voxel edge and raster cell), meters, > 0 (default 0.1).
max_range_m : float, optional
    Largest depth integrated per view, meters, > 0 (default 25).
surface_margin_m : float, optional
    Half-thickness of a measured surface, meters, >= 0; 0 selects half a voxel diagonal.
prior : {"unknown", "free"}, optional
    State of space never observed (default "unknown").
thickness_m : float, optional
    Extrusion of planar cuboids behind their face, meters, > 0 (default 0.1).
plane_merge_angle_rad : float, optional
    Largest angle between one plane's normals in two frames, radians, in (0, pi/2).
plane_merge_distance_m : float, optional
    Largest RMS distance of faces to the merged plane, meters, > 0 (default 0.15).
occupancy_thres : float, optional
    Occupancy class boundary, probability in (0, 1) (default 0.5).
feature_distance_m : float, optional
    A feature counts for a planar cell within this distance of the plane, meters.
close_gaps_cells : int, optional
    Widest gap closed in a plane's raster, cells, in [0, 32] (default 2).
merge_rule : {"min_rectangles", "paper", "density"}, optional
    How a plane's cells are covered by rectangles (default "min_rectangles").
cover_density : float, optional
    With merge_rule "density": smallest share of a rectangle's cells that are the
    plane's cells of its occupancy class, in [0.5, 1] (default 0.9, the paper's D_T).

Raises
------
ValueError
    For a parameter out of its range (the library's message).

Notes
-----
Maps are not copied (copy.copy raises); pickling goes through the map file format.
)doc");
  const Map::Params d;
  cls
    .def(py::init([](double resolution_m, double max_range_m, double surface_margin_m,
                     const std::string& prior, double thickness_m,
                     double plane_merge_angle_rad, double plane_merge_distance_m,
                     double occupancy_thres, double feature_distance_m,
                     int close_gaps_cells, const std::string& merge_rule,
                     double cover_density) {
           Map::Params p;
           p.resolution_m = resolution_m;
           p.space.max_range_m = max_range_m;
           p.space.surface_margin_m = surface_margin_m;
           p.surface.thickness_m = thickness_m;
           p.surface.plane_merge_angle_rad = plane_merge_angle_rad;
           p.surface.plane_merge_distance_m = plane_merge_distance_m;
           p.surface.occupancy_thres = occupancy_thres;
           p.surface.feature_distance_m = feature_distance_m;
           p.surface.close_gaps_cells = close_gaps_cells;
           p.surface.cover_density = cover_density;
           try {
             p.space.prior = spaceStateFromString(prior);
           } catch (const planar_grid::Exception& e) {
             throw py::value_error(std::string("PlanarGridMap: prior: ") + e.what());
           }
           try {
             p.surface.merge_rule = surfaceMergeRuleFromString(merge_rule);
           } catch (const planar_grid::Exception& e) {
             throw py::value_error(std::string("PlanarGridMap: merge_rule: ")
                                   + e.what());
           }
           try {
             return std::make_shared<Map>(p);
           } catch (const planar_grid::Exception& e) {
             throw py::value_error(std::string("PlanarGridMap: ") + e.what());
           }
         }),
         py::kw_only(), py::arg("resolution_m") = d.resolution_m,
         py::arg("max_range_m") = d.space.max_range_m,
         py::arg("surface_margin_m") = d.space.surface_margin_m,
         py::arg("prior") = toString(d.space.prior),
         py::arg("thickness_m") = d.surface.thickness_m,
         py::arg("plane_merge_angle_rad") = d.surface.plane_merge_angle_rad,
         py::arg("plane_merge_distance_m") = d.surface.plane_merge_distance_m,
         py::arg("occupancy_thres") = d.surface.occupancy_thres,
         py::arg("feature_distance_m") = d.surface.feature_distance_m,
         py::arg("close_gaps_cells") = d.surface.close_gaps_cells,
         py::arg("merge_rule") = toString(d.surface.merge_rule),
         py::arg("cover_density") = d.surface.cover_density)
    .def_static(
      "load",
      [](const py::object& path) {
        const std::string file = toPath(path);
        py::gil_scoped_release release;
        return std::make_shared<Map>(Map::load(file));
      },
      py::arg("path"),
      R"doc(Reads a map file (.pgmap, written by save() or the pipeline).

Parameters
----------
path : str or os.PathLike

Returns
-------
PlanarGridMap

Raises
------
planar_grid.IOError
    (an OSError) for a missing, truncated or corrupt file, an unknown version or a bad
    header value; the message names the file and the cause.
)doc")
    .def(
      "save",
      [](const Map& self, const py::object& path) {
        const std::string file = toPath(path);
        py::gil_scoped_release release;
        self.save(file);
      },
      py::arg("path"),
      R"doc(Writes the map file, atomically (a temporary file renamed over path).

Raises
------
planar_grid.IOError
    When it cannot be written.
)doc")
    .def(
      "get_state",
      [](const Map& self, const FloatArray& points) {
        const auto p = toPoints(points, "points");
        py::array_t<std::uint8_t> out(static_cast<py::ssize_t>(p.size()));
        std::uint8_t* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < p.size(); ++i)
            o[i] = static_cast<std::uint8_t>(self.getState(p[i]));
        }
        return out;
      },
      py::arg("points"), R"doc(State at each point.

Parameters
----------
points : array_like, shape (N, 3)
    Query points, meters.

Returns
-------
numpy.ndarray, shape (N,), uint8
    SpaceState per point: OCCUPIED inside a cuboid with probability >= occupancy_thres,
    FREE inside one below it, else the voxel's state (the prior where never observed).
)doc")
    .def(
      "get_occupancy",
      [](const Map& self, const FloatArray& points) {
        const auto p = toPoints(points, "points");
        py::array_t<double> out(static_cast<py::ssize_t>(p.size()));
        double* o = out.mutable_data();
        {
          py::gil_scoped_release release;
          for (std::size_t i = 0; i < p.size(); ++i)
            o[i] = self.getOccupancy(p[i]);
        }
        return out;
      },
      py::arg("points"), R"doc(Occupancy probability at each point.

Parameters
----------
points : array_like, shape (N, 3)
    Query points, meters.

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
            h[i] = self.castRay(o[i], d[i], max_range_m, end);
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
    Ray directions (any length > 0).
max_range_m : float
    Largest distance, meters.

Returns
-------
hit : numpy.ndarray, shape (N,), bool
    True where an occupied cuboid or voxel lies within max_range_m.
points : numpy.ndarray, shape (N, 3), float64
    The entry point into the occupied cuboid or the occupied voxel's centre, meters;
    NaN where nothing was hit.
)doc")
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
)doc")
    .def(
      "export_occupancy_grid_2d",
      [](const Map& self, const py::object& path, double z_min_m, double z_max_m,
         double z_ref_m, bool above_terrain, double terrain_tile_m, double resolution_m,
         double max_slope_rad, double terrain_max_angle_rad, const py::object& bounds,
         double occupied_thresh, double free_thresh) {
        OccupancyGrid2DParams params;
        params.z_min_m = z_min_m;
        params.z_max_m = z_max_m;
        params.z_ref_m = z_ref_m;
        params.above_terrain = above_terrain;
        params.terrain_tile_m = terrain_tile_m;
        params.resolution_m = resolution_m;
        params.max_slope_rad = max_slope_rad;
        params.terrain_max_angle_rad = terrain_max_angle_rad;
        params.occupied_thresh = occupied_thresh;
        params.free_thresh = free_thresh;
        if (!bounds.is_none()) {
          const DoubleArray b = DoubleArray::ensure(bounds);
          if (b.size() != 4)
            throw py::value_error(
              "bounds must be (min_x, min_y, max_x, max_y), meters");
          params.use_bounds = true;
          params.min_xy = Eigen::Vector2d(b.data()[0], b.data()[1]);
          params.max_xy = Eigen::Vector2d(b.data()[2], b.data()[3]);
        }
        const std::string file = toPath(path);
        OccupancyGrid2D grid;
        {
          py::gil_scoped_release release;
          grid = self.exportOccupancyGrid2D(file, params);
        }
        py::array_t<std::int8_t> cells({static_cast<py::ssize_t>(grid.height),
                                        static_cast<py::ssize_t>(grid.width)});
        std::copy(grid.cells.begin(), grid.cells.end(), cells.mutable_data());
        py::dict out;
        out["cells"] = cells;
        out["origin"] = py::make_tuple(grid.origin.x(), grid.origin.y());
        out["resolution"] = grid.resolution_m;
        return out;
      },
      py::arg("path"), py::kw_only(), py::arg("z_min_m") = 0.2,
      py::arg("z_max_m") = 2.0, py::arg("z_ref_m") = 0.0,
      py::arg("above_terrain") = false, py::arg("terrain_tile_m") = 2.0,
      py::arg("resolution_m") = 0.0, py::arg("max_slope_rad") = 0.3490658503988659,
      py::arg("terrain_max_angle_rad") = 1.0471975511965976,
      py::arg("bounds") = py::none(), py::arg("occupied_thresh") = 0.65,
      py::arg("free_thresh") = 0.196,
      R"doc(Writes the map projected over a height band as a ROS map_server map.

A cell is occupied where an occupied cuboid or voxel meets its column inside the band
[z_ref_m + z_min_m, z_ref_m + z_max_m] (above the local terrain with above_terrain) or
terrain steeper than max_slope_rad covers it, free where the views saw free space in
the band or walkable terrain, unknown elsewhere. Writes ``path`` (YAML: image, mode,
resolution, origin, negate, occupied_thresh, free_thresh) and the PGM it names beside
it (0 occupied, 254 free, 205 unknown), atomically.

Parameters
----------
path : str or os.PathLike
    The YAML file, ending in ".yaml" or ".yml"; the image is the same name with ".pgm".
z_min_m, z_max_m, z_ref_m : float
    The band, meters.
above_terrain : bool
    Measure the band from the local terrain: the walkable terrain cuboids under a cell,
    else the surfaces the space layer saw from above (20th percentile per tile).
terrain_tile_m : float
    The tile of the space layer's terrain, meters.
resolution_m : float
    Cell edge, meters (0: the map's).
max_slope_rad, terrain_max_angle_rad : float
    Terrain (planar cuboids within terrain_max_angle_rad of horizontal) steeper than
    max_slope_rad is an obstacle.
bounds : array_like (min_x, min_y, max_x, max_y), optional
    The area, meters (default: the map's extent).
occupied_thresh, free_thresh : float
    Written to the YAML for map_server.

Returns
-------
dict
    ``cells`` (H, W) int8 (-1 unknown, 0 free, 100 occupied; row 0 at the lowest y),
    ``origin`` (x, y) of the lower-left corner, meters, and ``resolution``.
)doc")
    .def(
      "set_state",
      [](Map& self, const FloatArray& points, const py::object& state) {
        const auto p = toPoints(points, "points");
        const SpaceState s = toSpaceState(state);
        auto& space = self.getSpaceLayer();
        for (const auto& point : p)
          if (point.allFinite())
            space.setState(space.toKey(point), s);
      },
      py::arg("points"), py::arg("state"),
      R"doc(Sets the voxels containing the points to a state (the explicit space layer).

Parameters
----------
points : array_like, shape (N, 3)
    Points, meters; non-finite rows are skipped.
state : SpaceState, int or str
    The state ("free", "occupied" or "unknown").
)doc")
    .def(
      "integrate_point_cloud",
      [](Map& self, const FloatArray& points, const DoubleArray& sensor_origin) {
        const auto cloud = toCloud(points, "points");
        const Eigen::Vector3f origin = toVector3f(sensor_origin, "sensor_origin");
        py::gil_scoped_release release;
        self.integratePointCloud(*cloud, origin);
      },
      py::arg("points"), py::arg("sensor_origin"),
      R"doc(Integrates a scan into the space layer by ray casting.

The voxels each ray crosses from the sensor origin to its point become FREE and the
voxel of every point within max_range_m OCCUPIED (as OctoMap's insertPointCloud).

Parameters
----------
points : array_like, shape (N, 3)
    The scan in the world frame, meters.
sensor_origin : array_like, shape (3,)
    Where the rays start, meters.
)doc")
    .def(
      "integrate_depth_image",
      [](Map& self, const FloatArray& depth, double fx, double fy, double cx, double cy,
         const DoubleArray& world_T_camera) {
        if (depth.ndim() != 2)
          throw py::value_error("depth must be an (H, W) array of depths in meters");
        DepthImage image;
        image.height = static_cast<int>(depth.shape(0));
        image.width = static_cast<int>(depth.shape(1));
        image.fx = static_cast<float>(fx);
        image.fy = static_cast<float>(fy);
        image.cx = static_cast<float>(cx);
        image.cy = static_cast<float>(cy);
        image.depth_m.assign(depth.data(), depth.data() + depth.size());
        const Eigen::Isometry3d pose = toIsometry(world_T_camera, "world_T_camera");
        py::gil_scoped_release release;
        self.integrateDepthImage(image, pose);
      },
      py::arg("depth"), py::arg("fx"), py::arg("fy"), py::arg("cx"), py::arg("cy"),
      py::arg("world_T_camera"),
      R"doc(Integrates one pinhole depth view into the space layer.

Voxels in front of the measured depth become FREE, those at it OCCUPIED and those
behind it UNKNOWN where they held the prior.

Parameters
----------
depth : array_like, shape (H, W)
    Depth along the optical axis per pixel, meters (NaN or <= 0: no measurement).
fx, fy, cx, cy : float
    Intrinsics, pixels.
world_T_camera : array_like, shape (4, 4)
    The camera pose (camera x right, y down, z forward), meters.
)doc")
    .def(
      "integrate_surface",
      [](Map& self, const Cuboids& cuboids, const DoubleArray& planes,
         const FloatArray& features, const DoubleArray& probabilities) {
        PlaneModels models;
        if (planes.size() != 0) {
          if (planes.ndim() != 2 || planes.shape(1) != 4)
            throw py::value_error("planes must be a (K, 4) array of [a, b, c, d]");
          const auto p = planes.unchecked<2>();
          for (py::ssize_t i = 0; i < planes.shape(0); ++i)
            models.emplace_back(
              Eigen::Vector4d(p(i, 0), p(i, 1), p(i, 2), p(i, 3)).cast<float>());
        }
        const auto cloud = toCloud(features, "features");
        if (probabilities.ndim() != 1
            || static_cast<std::size_t>(probabilities.shape(0)) != cloud->size())
          throw py::value_error("probabilities must be a (F,) array, one per feature");
        const std::vector<float> prob(probabilities.data(),
                                      probabilities.data() + probabilities.shape(0));
        py::gil_scoped_release release;
        self.integrateSurface(cuboids.cuboids, models, *cloud, prob);
      },
      py::arg("cuboids"), py::arg("planes"), py::arg("features"),
      py::arg("probabilities"),
      R"doc(Merges one frame's cuboids and feature occupancies into the surface layer.

Parameters
----------
cuboids : Cuboids
    The frame's cuboids in the world frame; plane_ids index ``planes`` (-1 non-planar).
planes : array_like, shape (K, 4)
    The frame's planes [a, b, c, d] in the world frame (unit normal, meters).
features : array_like, shape (F, 3)
    Key feature points in the world frame, meters (may be empty).
probabilities : array_like, shape (F,)
    One occupancy probability per feature, in [0, 1].
)doc")
    .def_property_readonly(
      "cuboids",
      [](const Map& self) { return Cuboids{self.getSurfaceLayer().getCuboids()}; },
      "Cuboids: the merged cuboids, every map plane's rectangles (plane_ids index "
      "planes) "
      "then the non-planar cells (plane_id -1), with their probabilities.")
    .def_property_readonly(
      "planes",
      [](const Map& self) {
        const auto& planes = self.getSurfaceLayer().getPlanes();
        py::array_t<double> out(
          {static_cast<py::ssize_t>(planes.size()), py::ssize_t{4}});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t i = 0; i < planes.size(); ++i)
          for (py::ssize_t j = 0; j < 4; ++j)
            o(static_cast<py::ssize_t>(i), j) = planes[i][static_cast<int>(j)];
        return out;
      },
      "numpy.ndarray, shape (K, 4), float64: the map's planes [a, b, c, d] (unit "
      "normal, "
      "d in meters), world frame.")
    .def_property_readonly("resolution_m", &Map::getResolution,
                           "float: the minimum cell size, meters.")
    .def_property_readonly(
      "params", [](const Map& self) { return paramsDict(self.getParams()); },
      "dict: the parameters, by the constructor's keyword names.")
    .def_property_readonly(
      "memory",
      [](const Map& self) {
        const MapMemory memory = self.getMemory();
        py::dict out;
        out["surface_bytes"] = memory.surface_bytes;
        out["space_bytes"] = memory.space_bytes;
        out["total_bytes"] = memory.total_bytes;
        return out;
      },
      "dict: bytes held by the surface layer, the space layer and both (surface_bytes, "
      "space_bytes, total_bytes).")
    .def_property_readonly(
      "cell_count",
      [](const Map& self) { return self.getSurfaceLayer().getCellCount(); },
      "int: observed raster cells over all planes plus non-planar cells.")
    .def_property_readonly(
      "voxel_counts",
      [](const Map& self) {
        const auto& space = self.getSpaceLayer();
        py::dict out;
        for (const SpaceState s :
             {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
          out[py::str(toString(s))] = space.getVoxelCount(s);
        return out;
      },
      "dict: voxels per state ('free', 'occupied', 'unknown') that differ from the "
      "prior (0 for the prior's own state).")
    .def(
      "voxel_centres",
      [](const Map& self, const py::object& state) {
        const SpaceState wanted = toSpaceState(state);
        const auto& space = self.getSpaceLayer();
        std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> centres;
        space.forEachVoxel([&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState s) {
          if (s == wanted)
            centres.push_back(space.toCentre(key));
        });
        py::array_t<double> out(
          {static_cast<py::ssize_t>(centres.size()), py::ssize_t{3}});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t i = 0; i < centres.size(); ++i)
          for (py::ssize_t k = 0; k < 3; ++k)
            o(static_cast<py::ssize_t>(i), k) = centres[i][static_cast<int>(k)];
        return out;
      },
      py::arg("state"),
      R"doc(Centres of the observed voxels in a state (never-observed space, which reads
as the prior, is not listed).

Parameters
----------
state : SpaceState, int or str

Returns
-------
numpy.ndarray, shape (N, 3), float64
    Voxel centres, meters (voxel edge resolution_m), in a deterministic order.
)doc")
    .def(
      "export_octomap",
      [](const Map& self, const py::object& path) {
        const planar_grid::OctoMapExportSummary s = self.exportOctoMap(toPath(path));
        py::dict out;
        out["nodes"] = s.nodes;
        out["leaf_nodes"] = s.leaf_nodes;
        out["occupied_leaves"] = s.occupied_leaves;
        out["free_leaves"] = s.free_leaves;
        out["occupied_voxels"] = s.occupied_voxels;
        out["free_voxels"] = s.free_voxels;
        out["skipped_voxels"] = s.skipped_voxels;
        return out;
      },
      py::arg("path"),
      "Writes the observed space and the cuboids as an OctoMap tree: .bt (binary: "
      "free / occupied per voxel) or .ot (full: each voxel's log-odds, a cuboid's "
      "from its occupancy); never-observed and occluded space are left out. Returns "
      "what was written, as liboctomap counts it: a dict of nodes, leaf_nodes, "
      "occupied_leaves, free_leaves, occupied_voxels, free_voxels (voxels of "
      "resolution_m under those leaves) and skipped_voxels (outside OctoMap's key "
      "range). Raises planar_grid.IOError when it cannot be written.")
    .def(
      "export_mesh",
      [](const Map& self, const py::object& path) { self.exportMesh(toPath(path)); },
      py::arg("path"),
      "Writes the cuboids as a mesh (.ply or .vtk), coloured by probability; raises "
      "planar_grid.IOError for another extension or a write error.")
    .def(
      "__eq__",
      [](const Map& self, const py::object& other) {
        return py::isinstance<Map>(other) && self == *other.cast<Map*>();
      },
      py::arg("other"), "True when both layers are equal (parameters, cells, voxels).")
    .def("__ne__",
         [](const Map& self, const py::object& other) {
           return !(py::isinstance<Map>(other) && self == *other.cast<Map*>());
         })
    .def("__copy__",
         [](const Map&) -> std::shared_ptr<Map> {
           throw py::type_error(
             "PlanarGridMap is not copied (maps are heavy); save and "
             "load it, or pickle it");
         })
    .def("__repr__",
         [](const Map& self) {
           std::ostringstream text;
           text << "<planar_grid.PlanarGridMap: resolution " << self.getResolution()
                << " m, " << self.getSurfaceLayer().getCuboidCount() << " cuboids, "
                << self.getMemory().total_bytes << " bytes>";
           return text.str();
         })
    .def(py::pickle(
      [](const Map& self) {
        std::string bytes;
        self.serialize(bytes);
        return py::bytes(bytes);
      },
      [](const py::bytes& bytes) {
        return std::make_shared<Map>(Map::deserialize(bytes, "<pickle>"));
      }));

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

} // namespace python
} // namespace planar_grid
