// SPDX-License-Identifier: BSD-3-Clause
// The integration methods of PlanarGridMap on numpy arrays: point clouds, depth images,
// surfaces, one whole frame, and setting voxel states.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pybind11/stl.h>

#include <optional>
#include <string>
#include <vector>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

using Map = PlanarGridMap;
using MapClass = py::class_<Map, std::shared_ptr<Map>>;

/** The (K, 4) plane models [a, b, c, d] of \a planes (empty: none).
 * \throws py::value_error for another shape */
PlaneModels
toPlaneModels(const DoubleArray& planes)
{
  PlaneModels models;
  if (planes.size() == 0)
    return models;
  if (planes.ndim() != 2 || planes.shape(1) != 4)
    throw py::value_error("planes must be a (K, 4) array of [a, b, c, d]");
  const auto p = planes.unchecked<2>();
  for (py::ssize_t i = 0; i < planes.shape(0); ++i)
    models.emplace_back(
      Eigen::Vector4d(p(i, 0), p(i, 1), p(i, 2), p(i, 3)).cast<float>());
  return models;
}

/** The depth image of an (H, W) array of depths (meters) and its intrinsics (px).
 * \throws py::value_error for an array of another dimension */
DepthImage
toDepthImage(const FloatArray& depth, double fx, double fy, double cx, double cy)
{
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
  return image;
}
/** Integration of scans, depth views and surfaces, and setting voxel states. */
void
bindViewIntegration(MapClass& cls)
{
  cls
    .def(
      "set_state",
      [](Map& self, const FloatArray& points, const py::object& state) {
        requireWritable(self, "set_state");
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
        requireWritable(self, "integrate_point_cloud");
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
        requireWritable(self, "integrate_depth_image");
        const DepthImage image = toDepthImage(depth, fx, fy, cx, cy);
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
        requireWritable(self, "integrate_surface");
        const PlaneModels models = toPlaneModels(planes);
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
)doc");
}

/** PlanarGridMap.integrate(): one frame into both layers (PlanarGridMap::integrate()).
 */
void
bindFrameIntegration(MapClass& cls)
{
  cls.def(
    "integrate",
    [](Map& self, const Cuboids& cuboids, const DoubleArray& planes,
       const DoubleArray& world_T_sensor, const py::object& features,
       const py::object& probabilities, const py::object& depth,
       std::optional<double> fx, std::optional<double> fy, std::optional<double> cx,
       std::optional<double> cy, const py::object& points, double observation_order,
       double window_half_size_m) {
      requireWritable(self, "integrate");
      const PlaneModels models = toPlaneModels(planes);
      MapFrame frame;
      frame.cuboids = &cuboids.cuboids;
      frame.planes = &models;
      pcl::PointCloud<pcl::PointXYZ>::Ptr feature_cloud;
      std::vector<float> prob;
      if (!features.is_none()) {
        const FloatArray f = FloatArray::ensure(features);
        if (!f)
          throw py::value_error("features must be an (F, 3) array of points");
        feature_cloud = toCloud(f, "features");
        frame.features = feature_cloud.get();
      }
      if (!probabilities.is_none()) {
        const DoubleArray p = DoubleArray::ensure(probabilities);
        if (!p || p.ndim() != 1)
          throw py::value_error("probabilities must be a (F,) array, one per feature");
        prob.assign(p.data(), p.data() + p.shape(0));
        frame.probabilities = &prob;
      }
      frame.world_T_sensor = toIsometry(world_T_sensor, "world_T_sensor");
      DepthImage image;
      if (!depth.is_none()) {
        const FloatArray d = FloatArray::ensure(depth);
        if (!d)
          throw py::value_error("depth must be an (H, W) array of depths in meters");
        if (!fx || !fy || !cx || !cy)
          throw py::value_error("a depth image needs its intrinsics fx, fy, cx, cy");
        image = toDepthImage(d, *fx, *fy, *cx, *cy);
        frame.depth = &image;
      }
      pcl::PointCloud<pcl::PointXYZ>::Ptr rays;
      if (!points.is_none()) {
        const FloatArray r = FloatArray::ensure(points);
        if (!r)
          throw py::value_error("points must be an (N, 3) array of points");
        rays = toCloud(r, "points");
        frame.rays = rays.get();
      }
      frame.observation_order = observation_order;
      frame.window_half_size_m = window_half_size_m;
      MapWindowRemoval removed;
      {
        py::gil_scoped_release release;
        removed = self.integrate(frame);
      }
      py::dict out;
      out["space_blocks"] = removed.space_blocks;
      out["space_voxels"] = removed.space_voxels;
      out["plane_cells"] = removed.plane_cells;
      out["planes"] = removed.planes;
      out["non_planar_cells"] = removed.non_planar_cells;
      return out;
    },
    py::arg("cuboids"), py::arg("planes"), py::arg("world_T_sensor"), py::kw_only(),
    py::arg("features") = py::none(), py::arg("probabilities") = py::none(),
    py::arg("depth") = py::none(), py::arg("fx") = py::none(),
    py::arg("fy") = py::none(), py::arg("cx") = py::none(), py::arg("cy") = py::none(),
    py::arg("points") = py::none(), py::arg("observation_order") = 0.0,
    py::arg("window_half_size_m") = 0.0,
    R"doc(Integrates one frame into the map in one call (paper Sec. III-F, Fig. 5c).

In order: integrate_surface() with the cuboids, planes, features and probabilities;
the space layer from the one measurement given, integrate_depth_image() for ``depth``
(the camera at ``world_T_sensor``) or integrate_point_cloud() for ``points`` (rays from
the sensor origin, the pose's translation); note_observation_order(); and with
``window_half_size_m > 0`` the rolling window: only the box of that half-size around the
sensor in x and y (every height) is kept. The map is the one those calls give.

Parameters
----------
cuboids : Cuboids
    The frame's cuboids in the world frame; plane_ids index ``planes`` (-1 non-planar).
planes : array_like, shape (K, 4)
    The frame's planes [a, b, c, d] in the world frame (unit normal, meters).
world_T_sensor : array_like, shape (4, 4)
    The sensor pose (a camera: x right, y down, z forward), meters.
features : array_like, shape (F, 3), optional
    Key feature points in the world frame, meters.
probabilities : array_like, shape (F,), optional
    One occupancy probability per feature, in [0, 1].
depth : array_like, shape (H, W), optional
    Depth along the optical axis per pixel, meters (NaN or <= 0: no measurement).
fx, fy, cx, cy : float, optional
    The depth image's intrinsics, pixels (needed with ``depth``).
points : array_like, shape (N, 3), optional
    The scan's points in the world frame, meters: rays from the sensor origin.
observation_order : float
    The frame's order key (note_observation_order()), e.g. its index.
window_half_size_m : float
    The rolling window's half-size, meters; 0: off.

Returns
-------
dict
    What the window removed: space_blocks, space_voxels, plane_cells, planes,
    non_planar_cells (all 0 when it is off).

Raises
------
planar_grid.Error
    Before the map changes, when neither or both of ``depth`` and ``points`` are given,
    the numbers of features and probabilities differ, or the order or window is not
    finite (or the window negative).
ValueError
    For arrays of the wrong shape, a pose that is not a finite rigid transform, or
    ``depth`` without its intrinsics.
)doc");
}

} // namespace

void
bindMapIntegration(py::module_& m)
{
  // The class is registered by bindMap(); the integration methods are added to it here.
  auto cls = py::reinterpret_borrow<MapClass>(m.attr("PlanarGridMap"));
  bindViewIntegration(cls);
  bindFrameIntegration(cls);
}

} // namespace python
} // namespace planar_grid
