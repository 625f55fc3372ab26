// SPDX-License-Identifier: BSD-3-Clause
// planar_grid.TerrainRemoval: the ground and what lies on it, from a cloud and its
// planes (planar_grid::TerrainRemoval), its parameters from the class's declarations.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/terrain_removal.h>

#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <tuple>
#include <vector>

#include "param_kwargs.h"
#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

using Removal = TerrainRemoval<pcl::PointXYZ>;

} // namespace

void
bindTerrainRemoval(py::module_& m)
{
  py::class_<Removal, std::unique_ptr<Removal>> cls(
    m, "TerrainRemoval",
    R"doc(Removes the terrain (the ground and what lies on it) from points and their planes.

planar_grid::TerrainRemoval<pcl::PointXYZ> (paper Sec. III-F, its second assumption:
the ground plane goes before the cuboid approximation). The ground is the plane with
the most inliers whose normal lies within eps_angle_rad of the up axis and that lies
at least min_sensor_height_m below the sensor; planes within terrain_max_slope_rad of
up that step at most terrain_max_step_m from a terrain plane join it (pavements,
ramps), and so do the points in no plane up to terrain_height_m above it. With
terrain_plane_tile_m > 0 the terrain planes stay, one per tile, so that the
approximation makes them planar cells; only the loose terrain points go.

The parameters are the keyword arguments (the pipeline's ground_removal keys, with
the same defaults) and read-write properties.
)doc");
  bindDeclaredParams(
    cls, "TerrainRemoval", Removal::getParamDeclarations(),
    [](const Removal& r) -> const Removal::Params& { return r.getParams(); },
    [](Removal& r, const Removal::Params& p) { r.setParams(p); });
  cls.def(
    "segment",
    [](Removal& self, const FloatArray& points, const Planes& planes,
       const DoubleArray& up_axis, const DoubleArray& sensor_origin) {
      const auto cloud = toCloud(points, "points");
      checkInlierIndices(planes.segments, cloud->size(), "TerrainRemoval.segment");
      self.setUpAxis(toVector3f(up_axis, "up_axis"));
      self.setSensorOrigin(toVector3f(sensor_origin, "sensor_origin"));
      Planes kept = planes;
      std::vector<std::uint8_t> terrain;
      bool found = false;
      try {
        py::gil_scoped_release release;
        found = self.segment(*cloud, kept.segments, terrain);
      } catch (const planar_grid::Exception& e) {
        throw py::value_error(e.what());
      }
      py::array_t<bool> is_terrain(static_cast<py::ssize_t>(terrain.size()));
      std::copy(terrain.begin(), terrain.end(), is_terrain.mutable_data());
      std::optional<py::array_t<double>> ground;
      if (found) {
        ground.emplace(4);
        for (int j = 0; j < 4; ++j)
          ground->mutable_data()[j] = self.getGroundCoefficients()[j];
      }
      return std::make_tuple(is_terrain, kept, ground);
    },
    py::arg("points"), py::arg("planes"), py::kw_only(),
    py::arg("up_axis") = std::vector<double>{0.0, 0.0, 1.0},
    py::arg("sensor_origin") = std::vector<double>{0.0, 0.0, 0.0},
    R"doc(Finds the terrain of the points and their planes.

Parameters
----------
points : array_like, shape (N, 3)
    x, y, z in meters, the points the planes' inliers index.
planes : PlanarSegments
    The planes of those points (SACMultiPlaneSegmentation.segment()).
up_axis : array_like, shape (3,), optional
    The up direction (need not be unit length), default +z.
sensor_origin : array_like, shape (3,), optional
    The sensor's position, meters: the ground lies min_sensor_height_m below it.

Returns
-------
tuple of (numpy.ndarray, PlanarSegments, numpy.ndarray or None)
    is_terrain, shape (N,), bool: the points to remove (all False without a ground
    plane); the planes without the terrain planes (or with one plane per tile, with
    terrain_plane_tile_m > 0); the ground plane [a, b, c, d], shape (4,), normal up so
    that the sensor's signed distance is its height in meters, or None when there is
    no ground plane.

Raises
------
ValueError
    For arrays of another shape or a zero up axis.
IndexError
    For a plane inlier outside the points.
)doc");
}

} // namespace python
} // namespace planar_grid
