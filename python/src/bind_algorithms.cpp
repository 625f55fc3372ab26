// SPDX-License-Identifier: BSD-3-Clause
// SACMultiPlaneSegmentation and PlanarCuboidApproximation on numpy arrays (instantiated
// for pcl::PointXYZ), with their results as arrays.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <limits>
#include <string>
#include <vector>

#include "param_kwargs.h"
#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

using Segmentation = SACMultiPlaneSegmentation<pcl::PointXYZ>;
using Approximation = PlanarCuboidApproximation<pcl::PointXYZ>;

/** (K, n) float64 array from a per-item function filling n values. */
template <typename Container, typename Fill>
py::array_t<double>
rows(const Container& items, py::ssize_t n, Fill fill)
{
  py::array_t<double> out({static_cast<py::ssize_t>(items.size()), n});
  auto o = out.template mutable_unchecked<2>();
  for (std::size_t i = 0; i < items.size(); ++i)
    fill(items[i], &o(static_cast<py::ssize_t>(i), 0));
  return out;
}

template <typename Vector>
void
put3(const Vector& v, double* out)
{
  out[0] = v[0];
  out[1] = v[1];
  out[2] = v[2];
}

/** Planes from (K, 4) coefficients and K index arrays (for the approximation). */
Planes
makePlanes(const DoubleArray& model_coefficients,
           const std::vector<IndexArray>& inliers)
{
  const bool empty = model_coefficients.size() == 0 && inliers.empty();
  if (!empty && (model_coefficients.ndim() != 2 || model_coefficients.shape(1) != 4))
    throw py::value_error(
      "PlanarSegments: model_coefficients must be a (K, 4) array of "
      "[a, b, c, d] (unit normal, d in meters)");
  const auto k =
    empty ? std::size_t{0} : static_cast<std::size_t>(model_coefficients.shape(0));
  if (inliers.size() != k)
    throw py::value_error("PlanarSegments: " + std::to_string(inliers.size())
                          + " inlier arrays for " + std::to_string(k)
                          + " planes; give one per plane");
  Planes planes;
  planes.segments.resize(k);
  for (std::size_t i = 0; i < k; ++i) {
    auto& segment = planes.segments[i];
    const auto c = model_coefficients.unchecked<2>();
    for (py::ssize_t j = 0; j < 4; ++j)
      segment.model_coefficients.values.push_back(
        static_cast<float>(c(static_cast<py::ssize_t>(i), j)));
    const IndexArray& ids = inliers[i];
    if (ids.ndim() != 1)
      throw py::value_error("PlanarSegments: inliers[" + std::to_string(i)
                            + "] must be a 1-D array of point indices");
    const auto v = ids.unchecked<1>();
    for (py::ssize_t j = 0; j < v.shape(0); ++j) {
      if (v(j) < 0 || v(j) > std::numeric_limits<int>::max())
        throw py::value_error("PlanarSegments: inliers[" + std::to_string(i)
                              + "] holds the negative or too large index "
                              + std::to_string(v(j)));
      segment.inliers.indices.push_back(static_cast<int>(v(j)));
    }
  }
  return planes;
}

void
bindPlanes(py::module_& m)
{
  py::class_<Planes>(m, "PlanarSegments",
                     R"doc(Planes found by SACMultiPlaneSegmentation.

Parallel arrays, one row per plane, sorted by descending inlier count (the C++
planar_grid::PlanarSegments). len() is the number of planes K.

Parameters
----------
model_coefficients : array_like, shape (K, 4)
    [a, b, c, d] per plane (eq. 1): unit normal (a, b, c) and offset d in meters.
inliers : sequence of K array_like of int
    Indices of each plane's points in the cloud it is used with.

Notes
-----
Built by hand, the centroids, tilts and sample inlier counts are zero; only the
coefficients and inliers are used by PlanarCuboidApproximation.approximate().
)doc")
    .def(py::init(&makePlanes), py::arg("model_coefficients"), py::arg("inliers"))
    .def("__len__", [](const Planes& p) { return p.segments.size(); })
    .def("__repr__",
         [](const Planes& p) {
           return "<planar_grid.PlanarSegments: " + std::to_string(p.segments.size())
                  + " planes>";
         })
    .def_property_readonly(
      "model_coefficients",
      [](const Planes& p) {
        return rows(p.segments, 4, [](const PlanarSegment& s, double* out) {
          for (std::size_t j = 0; j < 4; ++j)
            out[j] = j < s.model_coefficients.values.size()
                       ? s.model_coefficients.values[j]
                       : 0.0;
        });
      },
      "numpy.ndarray, shape (K, 4), float64: [a, b, c, d] per plane; (a, b, c) is a "
      "unit "
      "normal pointing toward the sensor origin, d in meters (a x + b y + c z + d = "
      "0).")
    .def_property_readonly(
      "normals",
      [](const Planes& p) {
        return rows(p.segments, 3, [](const PlanarSegment& s, double* out) {
          for (std::size_t j = 0; j < 3; ++j)
            out[j] = j < s.model_coefficients.values.size()
                       ? s.model_coefficients.values[j]
                       : 0.0;
        });
      },
      "numpy.ndarray, shape (K, 3), float64: the unit normals (a, b, c).")
    .def_property_readonly(
      "inliers",
      [](const Planes& p) {
        py::list out;
        for (const auto& s : p.segments) {
          py::array_t<std::int64_t> ids(
            static_cast<py::ssize_t>(s.inliers.indices.size()));
          std::copy(s.inliers.indices.begin(), s.inliers.indices.end(),
                    ids.mutable_data());
          out.append(ids);
        }
        return out;
      },
      "list of K numpy.ndarray of int64: each plane's dense inliers (eq. 11: distance "
      "<= d_T), indices into the segmented points, ascending.")
    .def_property_readonly(
      "centroids",
      [](const Planes& p) {
        return rows(p.segments, 3,
                    [](const PlanarSegment& s, double* out) { put3(s.centroid, out); });
      },
      "numpy.ndarray, shape (K, 3), float64: centroid of each plane's inliers, meters.")
    .def_property_readonly(
      "tilt_rad",
      [](const Planes& p) {
        return column<double>(p.segments,
                              [](const PlanarSegment& s) { return s.tilt_rad; });
      },
      "numpy.ndarray, shape (K,), float64: theta of eq. 2, the angle between the "
      "normal "
      "and the up axis, radians in [0, pi] (0 floor, pi/2 wall).")
    .def_property_readonly(
      "normalized_tilt_rad",
      [](const Planes& p) {
        return column<double>(
          p.segments, [](const PlanarSegment& s) { return s.normalized_tilt_rad; });
      },
      "numpy.ndarray, shape (K,), float64: the normalised tilt of eq. 3, radians in "
      "(-pi/2, pi/2].")
    .def_property_readonly(
      "sample_inliers",
      [](const Planes& p) {
        return column<std::int64_t>(
          p.segments, [](const PlanarSegment& s) { return s.sample_inliers; });
      },
      "numpy.ndarray, shape (K,), int64: points of the sample cloud on each plane.");
}

/** \brief The Python class of the cuboid arrays. */
using CuboidsClass = py::class_<Cuboids>;

/** \brief The cuboids' centres, normals, axes, extents, rotations and corners. */
void
bindCuboidGeometry(CuboidsClass& cls)
{
  cls
    .def_property_readonly(
      "centres",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3,
                    [](const PlanarCuboid& q, double* out) { put3(q.centre, out); });
      },
      "numpy.ndarray, shape (M, 3), float64: box centres, meters.")
    .def_property_readonly(
      "normals",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3,
                    [](const PlanarCuboid& q, double* out) { put3(q.normal, out); });
      },
      "numpy.ndarray, shape (M, 3), float64: unit face normals (toward the sensor for "
      "a "
      "planar cuboid).")
    .def_property_readonly(
      "horizontal_axes",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3, [](const PlanarCuboid& q, double* out) {
          put3(q.horizontal_axis, out);
        });
      },
      "numpy.ndarray, shape (M, 3), float64: unit in-plane horizontal axes.")
    .def_property_readonly(
      "vertical_axes",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3, [](const PlanarCuboid& q, double* out) {
          put3(q.verticalAxis(), out);
        });
      },
      "numpy.ndarray, shape (M, 3), float64: vertical axes, normal x horizontal axis.")
    .def_property_readonly(
      "extents_m",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3, [](const PlanarCuboid& q, double* out) {
          out[0] = q.width_m;
          out[1] = q.height_m;
          out[2] = q.thickness_m;
        });
      },
      "numpy.ndarray, shape (M, 3), float64: width, height and thickness, meters, "
      "along "
      "the columns of rotations.")
    .def_property_readonly(
      "rotations",
      [](const Cuboids& c) {
        py::array_t<double> out(
          {static_cast<py::ssize_t>(c.cuboids.size()), py::ssize_t{3}, py::ssize_t{3}});
        auto o = out.mutable_unchecked<3>();
        for (std::size_t i = 0; i < c.cuboids.size(); ++i) {
          const auto& q = c.cuboids[i];
          const Eigen::Vector3f axes[3] = {q.horizontal_axis, q.verticalAxis(),
                                           q.normal};
          for (py::ssize_t col = 0; col < 3; ++col)
            for (py::ssize_t row = 0; row < 3; ++row)
              o(static_cast<py::ssize_t>(i), row, col) = axes[col][row];
        }
        return out;
      },
      "numpy.ndarray, shape (M, 3, 3), float64: per box the rotation whose columns are "
      "the horizontal axis, the vertical axis and the normal (box frame to world), as "
      "open3d.geometry.OrientedBoundingBox(centre, R, extent) takes it with extents_m.")
    .def_property_readonly(
      "corners",
      [](const Cuboids& c) {
        py::array_t<double> out(
          {static_cast<py::ssize_t>(c.cuboids.size()), py::ssize_t{8}, py::ssize_t{3}});
        auto o = out.mutable_unchecked<3>();
        for (std::size_t i = 0; i < c.cuboids.size(); ++i) {
          const auto corners = c.cuboids[i].corners();
          for (py::ssize_t k = 0; k < 8; ++k)
            for (py::ssize_t d = 0; d < 3; ++d)
              o(static_cast<py::ssize_t>(i), k, d) =
                corners[static_cast<std::size_t>(k)][d];
        }
        return out;
      },
      "numpy.ndarray, shape (M, 8, 3), float64: the corners, meters: the face's four "
      "(-w,-h), (+w,-h), (+w,+h), (-w,+h) in (horizontal, vertical) half-extents, then "
      "the same four at the back.");
}

/** \brief The cuboids' axis-aligned bounds. */
void
bindCuboidBounds(CuboidsClass& cls)
{
  cls
    .def_property_readonly(
      "min_bounds",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3, [](const PlanarCuboid& q, double* out) {
          Eigen::Vector3f low =
            Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
          for (const auto& corner : q.corners())
            low = low.cwiseMin(corner);
          put3(low, out);
        });
      },
      "numpy.ndarray, shape (M, 3), float64: axis-aligned lower corner of each box, "
      "meters.")
    .def_property_readonly(
      "max_bounds",
      [](const Cuboids& c) {
        return rows(c.cuboids, 3, [](const PlanarCuboid& q, double* out) {
          Eigen::Vector3f high =
            Eigen::Vector3f::Constant(std::numeric_limits<float>::lowest());
          for (const auto& corner : q.corners())
            high = high.cwiseMax(corner);
          put3(high, out);
        });
      },
      "numpy.ndarray, shape (M, 3), float64: axis-aligned upper corner of each box, "
      "meters.");
}

/** \brief The cuboids' planes, point counts, probabilities and volumes. */
void
bindCuboidAttributes(CuboidsClass& cls)
{
  cls
    .def_property_readonly(
      "plane_ids",
      [](const Cuboids& c) {
        return column<std::int64_t>(c.cuboids,
                                    [](const PlanarCuboid& q) { return q.plane_id; });
      },
      "numpy.ndarray, shape (M,), int64: index of the cuboid's plane (into the planes "
      "given "
      "to the approximation, or the map's planes), -1 for a non-planar cuboid.")
    .def_property_readonly(
      "is_planar",
      [](const Cuboids& c) {
        return column<bool>(c.cuboids,
                            [](const PlanarCuboid& q) { return q.is_planar; });
      },
      "numpy.ndarray, shape (M,), bool: True for a split-and-merged planar cuboid "
      "(Fig. 6), "
      "False for a non-planar one (Fig. 7).")
    .def_property_readonly(
      "point_counts",
      [](const Cuboids& c) {
        return column<std::int64_t>(
          c.cuboids, [](const PlanarCuboid& q) { return q.point_count; });
      },
      "numpy.ndarray, shape (M,), int64: points (or, in a map, features) each cuboid "
      "was "
      "built from.")
    .def_property_readonly(
      "probabilities",
      [](const Cuboids& c) {
        return column<double>(c.cuboids,
                              [](const PlanarCuboid& q) { return q.probability; });
      },
      "numpy.ndarray, shape (M,), float64: occupancy probability in [0, 1] (0.5 "
      "unknown).")
    .def_property_readonly(
      "volumes_m3",
      [](const Cuboids& c) {
        return column<double>(c.cuboids,
                              [](const PlanarCuboid& q) { return q.volume(); });
      },
      "numpy.ndarray, shape (M,), float64: volumes, cubic meters.");
}

void
bindCuboids(py::module_& m)
{
  CuboidsClass cls(m, "Cuboids",
                   R"doc(Oriented cuboids (planar_grid::PlanarCuboid), as arrays.

One row per cuboid; len() is their number M. Each box is spanned by the unit
horizontal axis, the vertical axis (normal x horizontal axis) and the unit normal,
with extents width, height and thickness along them about its centre. A planar
cuboid's normal points toward the sensor and its face is at the measured surface; the
box reaches thickness_m behind it. Returned by PlanarCuboidApproximation.approximate(),
PlanarGridMap.cuboids and run_pipeline().
)doc");
  cls.def("__len__", [](const Cuboids& c) { return c.cuboids.size(); })
    .def("__repr__", [](const Cuboids& c) {
      const auto planar =
        std::count_if(c.cuboids.begin(), c.cuboids.end(),
                      [](const PlanarCuboid& q) { return q.is_planar; });
      return "<planar_grid.Cuboids: " + std::to_string(c.cuboids.size()) + " cuboids, "
             + std::to_string(planar) + " planar>";
    });
  bindCuboidGeometry(cls);
  bindCuboidBounds(cls);
  bindCuboidAttributes(cls);
}

using SegmentationClass = py::class_<Segmentation, std::unique_ptr<Segmentation>>;

/** \brief segment(). */
void
bindSegmentationMethods(SegmentationClass& cls)
{
  cls.def(
    "segment",
    [](Segmentation& self, const FloatArray& points, const py::object& sample_points,
       const DoubleArray& sensor_origin, const DoubleArray& up_axis,
       double depth_noise_coefficient_per_m) {
      auto cloud = toCloud(points, "points");
      cloud->sensor_origin_.head<3>() = toVector3f(sensor_origin, "sensor_origin");
      const Eigen::Vector3f up = toVector3f(up_axis, "up_axis");
      if (!(up.norm() > 0.0f))
        throw py::value_error("SACMultiPlaneSegmentation.segment: up_axis must not be "
                              "zero");
      if (!sac_multi_plane_segmentation_ranges::DEPTH_NOISE_COEFFICIENT.contains(
            depth_noise_coefficient_per_m))
        throw py::value_error(
          "SACMultiPlaneSegmentation.segment: "
          + paramRangeMessage(
            "depth_noise_coefficient_per_m",
            sac_multi_plane_segmentation_ranges::DEPTH_NOISE_COEFFICIENT, "1/m"));
      pcl::PointCloud<pcl::PointXYZ>::Ptr sample;
      if (!sample_points.is_none())
        sample = toCloud(sample_points.cast<FloatArray>(), "sample_points");
      Planes planes;
      {
        py::gil_scoped_release release;
        self.setUpAxis(up);
        self.setDepthNoiseCoefficient(depth_noise_coefficient_per_m);
        self.setInputCloud(cloud);
        self.setSampleCloud(sample);
        self.segment(planes.segments);
        self.setInputCloud(nullptr);
        self.setSampleCloud(nullptr);
      }
      return planes;
    },
    py::arg("points"), py::kw_only(), py::arg("sample_points") = py::none(),
    py::arg("sensor_origin") = std::vector<double>{0.0, 0.0, 0.0},
    py::arg("up_axis") = std::vector<double>{0.0, 0.0, 1.0},
    py::arg("depth_noise_coefficient_per_m") = 0.0,
    R"doc(Segments the points into planes.

Parameters
----------
points : array_like, shape (N, 3)
    x, y, z in meters (float32 internally); NaN rows are skipped.
sample_points : array_like, shape (S, 3), optional
    Sparse points the hypotheses are drawn from (e.g. stereo key features), meters.
sensor_origin : array_like, shape (3,), optional
    The sensor's position, meters (default (0, 0, 0)): the normals point toward it.
up_axis : array_like, shape (3,), optional
    The up direction of eqs. 2-3 (need not be unit length; default (0, 0, 1);
    (0, -1, 0) for points in a camera frame).
depth_noise_coefficient_per_m : float, optional
    The sensor's stereo depth noise, Delta d / (B f) of eq. 4, 1/m, >= 0: a point at
    range r from sensor_origin is an inlier within max(distance_threshold_m,
    coefficient r^2). 0 (the default) keeps the paper's fixed threshold.

Returns
-------
PlanarSegments
    The planes, sorted by descending inlier count; empty when none has min_inliers.

Raises
------
ValueError
    For points of another shape, a zero up axis or a negative coefficient.
)doc");
}

void
bindSegmentation(py::module_& m)
{
  SegmentationClass cls(m, "SACMultiPlaneSegmentation",
                        R"doc(Multi-plane segmentation by repeated sample consensus.

planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ>: the multi-RANSAC of the paper
(Zhang et al., Sec. III-C, eqs. 1-3) with the dense inlier selection of eq. 11. Plane
hypotheses come from ``sample_points`` (e.g. stereo key features) when given, else from
a seeded subsample of the points; each plane's dense inliers are the points within
``distance_threshold_m`` of it that no earlier plane took.

The parameters are the constructor's keyword arguments, e.g.
``SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=300, seed=0)``:
the keys of the pipeline's multi_plane_segmentation stage that the class declares
(docs/STAGES.md), with the same defaults, and read-write properties. What describes
the sensor (its origin, the up axis, its depth noise) goes to segment().

Notes
-----
Deterministic: the same points, parameters and seed give the same planes. Degenerate
input (no points, only NaN, colinear points) gives no plane.
)doc");
  bindDeclaredParams(
    cls, "SACMultiPlaneSegmentation", Segmentation::getParamDeclarations(),
    [](const Segmentation& s) -> const Segmentation::Params& { return s.getParams(); },
    [](Segmentation& s, const Segmentation::Params& p) { s.setParams(p); });
  bindSegmentationMethods(cls);
}

void
bindApproximation(py::module_& m)
{
  using Class = py::class_<Approximation, std::unique_ptr<Approximation>>;
  Class cls(
    m, "PlanarCuboidApproximation",
    R"doc(Split-and-merge grid approximation of planes and the rest by oriented cuboids.

planar_grid::PlanarCuboidApproximation<pcl::PointXYZ>: Sec. III-F, Figs. 6-8 of the
paper. Each plane's inliers are rastered at ``min_cell_size_m``, split by a quadtree
while the occupied share is below ``density_threshold`` and merged into the largest
rectangles, which are extruded ``thickness_m`` behind their face; the remaining points
become non-planar boxes (Fig. 7).

The parameters are the constructor's keyword arguments, e.g.
``PlanarCuboidApproximation(min_cell_size_m=0.05, thickness_m=0.05)``: the keys of the
pipeline's planar_cuboid_approximation stage (docs/STAGES.md), with the same defaults,
and read-write properties. What describes the sensor (its origin, the up axis) goes
to approximate().

Notes
-----
With min_points_per_cell = 1 every finite input point lies in some cuboid. Empty or
all-NaN input gives no cuboid.
)doc");
  bindDeclaredParams(
    cls, "PlanarCuboidApproximation", Approximation::getParamDeclarations(),
    [](const Approximation& a) -> const Approximation::Params& {
      return a.getParams();
    },
    [](Approximation& a, const Approximation::Params& p) { a.setParams(p); });
  cls.def(
    "approximate",
    [](Approximation& self, const FloatArray& points, const py::object& planes,
       const DoubleArray& sensor_origin, const DoubleArray& up_axis) {
      auto cloud = toCloud(points, "points");
      PlanarSegments segments;
      if (!planes.is_none()) {
        if (!py::isinstance<Planes>(planes))
          throw py::type_error(
            "PlanarCuboidApproximation: planes must be a "
            "PlanarSegments (e.g. from SACMultiPlaneSegmentation) or "
            "None");
        segments = planes.cast<Planes*>()->segments;
      }
      checkInlierIndices(segments, cloud->size(), "PlanarCuboidApproximation");
      const Eigen::Vector3f origin = toVector3f(sensor_origin, "sensor_origin");
      const Eigen::Vector3f up = toVector3f(up_axis, "up_axis");
      if (!(up.norm() > 0.0f))
        throw py::value_error("PlanarCuboidApproximation.approximate: up_axis must not "
                              "be zero");
      self.setSensorOrigin(origin);
      self.setUpAxis(up);
      if (const char* bad = self.checkParameters())
        throw py::value_error(
          std::string("PlanarCuboidApproximation: invalid parameter: ") + bad);
      Cuboids cuboids;
      {
        py::gil_scoped_release release;
        self.setInputCloud(cloud);
        self.setPlanes(segments);
        self.approximate(cuboids.cuboids);
        self.setInputCloud(nullptr);
        self.setPlanes({});
      }
      return cuboids;
    },
    py::arg("points"), py::arg("planes") = py::none(), py::kw_only(),
    py::arg("sensor_origin") = std::vector<double>{0.0, 0.0, 0.0},
    py::arg("up_axis") = std::vector<double>{0.0, 0.0, 1.0},
    R"doc(Builds the cuboids of the points and their planes.

Parameters
----------
points : array_like, shape (N, 3)
    x, y, z in meters (e.g. the cloud without the ground).
planes : PlanarSegments, optional
    Planes of these points (their inliers index ``points``), e.g. from
    SACMultiPlaneSegmentation.segment(); None makes every point non-planar.
sensor_origin : array_like, shape (3,), optional
    Decides the front of each plane: boxes are extruded away from it, meters (default
    (0, 0, 0)).
up_axis : array_like, shape (3,), optional
    The up direction (need not be unit length; default (0, 0, 1); (0, -1, 0) for
    points in a camera frame): a plane's raster rows run along its direction
    perpendicular to it (a wall's cells are upright rectangles), and the non-planar
    boxes stand upright along it.

Returns
-------
Cuboids
    Planar cuboids (in plane order, then row order), then the non-planar ones.

Raises
------
ValueError
    For points of another shape or a zero up axis.
IndexError
    For a plane inlier outside the points.
)doc");
}

} // namespace

void
bindAlgorithms(py::module_& m)
{
  bindPlanes(m);
  bindCuboids(m);
  bindSegmentation(m);
  bindApproximation(m);
  bindTerrainRemoval(m);
}

} // namespace python
} // namespace planar_grid
