// SPDX-License-Identifier: BSD-3-Clause
// KLDivergenceOccupancyFilter on numpy arrays (instantiated for pcl::PointXYZ) and the
// occupancy functions of its equations, numpy-broadcast.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>

#include <pybind11/stl.h>

#include <functional>
#include <string>
#include <vector>

#include "param_kwargs.h"
#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** The filter with its parameter check public, so that Python gets the library's text
 * as a ValueError instead of an empty result and a console message. */
class OccupancyFilter : public KLDivergenceOccupancyFilter<pcl::PointXYZ> {
public:
  using KLDivergenceOccupancyFilter<pcl::PointXYZ>::checkParameters;
};

using Filter = OccupancyFilter;
using FilterClass = py::class_<Filter, std::unique_ptr<Filter>>;

/** \brief The declarations of the filter's parameters that Python takes: the
 * library's table without the depth-camera and range-sensor models' keys (Python's
 * filter is the paper's stereo one; the pipeline's kl_occupancy_filter stage chooses
 * the model). */
const ParamDeclarations<Filter::Params>&
stereoParamDeclarations()
{
  static const ParamDeclarations<Filter::Params> table = [] {
    ParamDeclarations<Filter::Params> stereo;
    for (const auto& declaration : Filter::getParamDeclarations())
      if (declaration.key != "depth_error_coefficient_per_m"
          && declaration.key != "range_error_m")
        stereo.push_back(declaration);
    return stereo;
  }();
  return table;
}

/** \brief The filter's parameters: the stereo rig first, then the keyword arguments of
 * its declared table, each a read-write property with its range. */
void
bindFilterParameters(FilterClass& cls)
{
  const std::vector<LeadingParam<Filter>> rig{
    {"focal_length_px", "f of the rectified stereo rig (eq. 4), pixels, > 0.",
     [](const Filter& f) { return f.getFocalLength(); },
     [](Filter& f, double focal_length_px) {
       f.setStereoParameters(focal_length_px, f.getBaseline());
     }},
    {"baseline_m", "B of the rectified stereo rig (eq. 4), meters, > 0.",
     [](const Filter& f) { return f.getBaseline(); },
     [](Filter& f, double baseline_m) {
       f.setStereoParameters(f.getFocalLength(), baseline_m);
     }}};
  bindDeclaredParams(
    cls, "KLDivergenceOccupancyFilter", stereoParamDeclarations(),
    [](const Filter& f) -> const Filter::Params& { return f.getParams(); },
    [](Filter& f, const Filter::Params& p) { f.setParams(p); }, rig,
    std::function<const char*(const Filter&)>(
      [](const Filter& f) { return f.checkParameters(); }));
}

/** \brief filter(), the tracks' probabilities and ids, and reset(). */
void
bindFilterMethods(FilterClass& cls)
{
  cls
    .def(
      "filter",
      [](Filter& self, const FloatArray& features, const py::object& track_ids,
         const py::object& sensor_pose, double motion_likelihood, bool negative) {
        auto cloud = toCloud(features, "features");
        if (!sensor_pose.is_none()) {
          const Eigen::Isometry3d pose =
            toIsometry(sensor_pose.cast<DoubleArray>(), "sensor_pose");
          cloud->sensor_origin_ << pose.translation().cast<float>(), 0.0f;
          cloud->sensor_orientation_ =
            Eigen::Quaternionf(pose.rotation().cast<float>());
        }
        std::vector<std::int64_t> ids;
        if (!track_ids.is_none()) {
          const auto array = track_ids.cast<IndexArray>();
          if (array.ndim() != 1
              || static_cast<std::size_t>(array.shape(0)) != cloud->size())
            throw py::value_error(
              "KLDivergenceOccupancyFilter: track_ids must be a 1-D "
              "array with one id per feature ("
              + std::to_string(cloud->size()) + ")");
          ids.assign(array.data(), array.data() + array.shape(0));
        }
        self.setInputCloud(cloud);
        self.setTrackIds(ids);
        self.setMotionLikelihood(motion_likelihood);
        self.setNegative(negative);
        if (const char* bad = self.checkParameters())
          throw py::value_error(std::string("KLDivergenceOccupancyFilter: ") + bad);
        pcl::Indices kept;
        {
          py::gil_scoped_release release;
          self.filter(kept);
        }
        py::array_t<std::int64_t> out(static_cast<py::ssize_t>(kept.size()));
        std::copy(kept.begin(), kept.end(), out.mutable_data());
        return out;
      },
      py::arg("features"), py::kw_only(), py::arg("track_ids") = py::none(),
      py::arg("sensor_pose") = py::none(), py::arg("motion_likelihood") = 1.0,
      py::arg("negative") = false,
      R"doc(Integrates one frame of features and selects the occupied ones.

Parameters
----------
features : array_like, shape (N, 3)
    Key feature points, meters: in the camera frame (x right, y down, z forward) when
    ``sensor_pose`` is None, else in the world frame.
track_ids : array_like of int, shape (N,), optional
    One track id per feature (>= 0; -1 for none); the same id in a later frame is the
    same feature seen again. None associates features with tracks by position (within
    association_radius_m).
sensor_pose : array_like, shape (4, 4), optional
    world_T_camera of the frame (rotation and translation in meters).
motion_likelihood : float, optional
    m of eq. 9 for this frame, probability in [0, 1] (default 1: known poses).
negative : bool, optional
    Return the features below the occupancy threshold instead.

Returns
-------
numpy.ndarray, shape (K,), int64
    Indices of the kept features (probability >= occupancy_thres).

Raises
------
ValueError
    For features or track_ids of another shape, or a motion likelihood outside [0, 1].
)doc")
    .def_property_readonly(
      "probabilities",
      [](const Filter& self) {
        return column<double>(self.getProbabilities(), [](float p) { return p; });
      },
      "numpy.ndarray, shape (N,), float64: each feature's occupancy probability after "
      "the "
      "last filter(), in [0, 1] (0 for an invalid feature).")
    .def_property_readonly(
      "assigned_track_ids",
      [](const Filter& self) {
        return column<std::int64_t>(self.getAssignedTrackIds(),
                                    [](std::int64_t id) { return id; });
      },
      "numpy.ndarray, shape (N,), int64: each feature's track id after the last "
      "filter() "
      "(-1 without a track).")
    .def_property_readonly("track_count", &Filter::getTrackCount,
                           "int: the number of tracks stored.")
    .def_property_readonly("memory_bytes", &Filter::getMemoryBytes,
                           "int: bytes held by the tracks and work buffers (estimate).")
    .def(
      "track_probability",
      [](const Filter& self, std::int64_t track_id) -> py::object {
        float probability = 0.0f;
        if (!self.getTrackProbability(track_id, probability))
          return py::none();
        return py::float_(probability);
      },
      py::arg("track_id"),
      "The probability of a track, in [clamping_thres_min, clamping_thres_max], or "
      "None "
      "for an unknown track.")
    .def("reset", &Filter::reset,
         "Forgets every track; the next filter() is a first frame.");
}

/** \brief Eqs. 4-6 and 10 as numpy-broadcast functions. */
void
bindOccupancyFunctions(py::module_& m)
{
  m.def(
    "range_occupancy_probability", py::vectorize(&rangeOccupancyProbability),
    py::arg("range_m"), py::arg("mean_range_m"), py::arg("depth_m"),
    py::arg("focal_length_px"), py::arg("baseline_m"), py::arg("disparity_error_px"),
    R"doc(Eq. 4, unclamped: the occupancy probability of one feature (numpy-broadcast).

dz = z^2 dd / (B f), dr = (r_bar / z) dz, p = exp(-0.5 ((r - r_bar) / dr)^2).

Parameters
----------
range_m, mean_range_m, depth_m : array_like
    r, r_bar and the depth z, meters.
focal_length_px, baseline_m, disparity_error_px : array_like
    f in pixels, B in meters, dd in pixels.

Returns
-------
numpy.ndarray or float
    Probability in [0, 1]; 0 where an argument is out of its range.
)doc");
  m.def(
    "bernoulli_kl_divergence", py::vectorize(&bernoulliKLDivergence), py::arg("p"),
    py::arg("q"),
    R"doc(KL divergence of two Bernoulli distributions (eqs. 5-6), nats (numpy-broadcast).

D = p ln(p / q) + (1 - p) ln((1 - p) / (1 - q)); q is moved into [1e-9, 1 - 1e-9].
)doc");
  m.def(
    "kl_divergence_update", py::vectorize(&klDivergenceUpdate), py::arg("p"),
    py::arg("q"), py::arg("offset_nats") = 1.07,
    R"doc(One KL update (eq. 10): exp(-E), E = |D| + A when p <= 0.5 and q <= 0.5, else |D|.

Parameters
----------
p, q : array_like
    The stored and the new probability, in [0, 1].
offset_nats : array_like, optional
    A, nats (the paper's 1.07).

Returns
-------
numpy.ndarray or float
    The updated probability in (0, 1] (not clamped).
)doc");
}

} // namespace

void
bindOccupancyFilter(py::module_& m)
{
  FilterClass cls(m, "KLDivergenceOccupancyFilter",
                  R"doc(Occupancy probability of stereo key features across frames.

planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ>: each feature's probability of
eq. 4 (a Gaussian of its range around the mean range of its neighbourhood, with the
stereo depth error z^2 dd / (B f)), updated across frames by the Kullback-Leibler rule
of eqs. 5-10 (or OctoMap's log-odds rule). Each filter() call is one frame.

The stereo rig (focal_length_px, baseline_m) comes first, positional or by name; the
other parameters are keyword arguments with the C++ class's defaults (listed under
__init__). All are read-write properties.
)doc");
  bindFilterParameters(cls);
  bindFilterMethods(cls);
  bindOccupancyFunctions(m);
}

} // namespace python
} // namespace planar_grid
