// SPDX-License-Identifier: BSD-3-Clause
// The streaming mapper (planar_grid::Mapper): one frame per call from numpy arrays, the
// map read between frames or under its lock from other threads; and the frames of a
// configuration's input, read as the pipeline reads them.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <pybind11/stl.h>

#include <memory>
#include <optional>
#include <string>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** \brief Any array-like converted to a C-contiguous uint8 array. */
using ByteArray = py::array_t<std::uint8_t, py::array::c_style | py::array::forcecast>;

/** Largest side of an image, px: OpenCV sizes are int, and no camera comes near. */
constexpr py::ssize_t MAX_IMAGE_SIDE_PX = py::ssize_t{1} << 16;

/** Throws ValueError unless \a image is (H, W) with both sides in [1,
 * MAX_IMAGE_SIDE_PX]; checked before any copy (a broadcast array of a huge width
 * would be copied whole, and its width overflow an int). \a kind says what array is
 * expected, for the message. */
void
checkImageShape(const py::array& image, const char* name, const char* kind)
{
  if (image.ndim() != 2)
    throw py::value_error(std::string(name) + " must be " + kind + ", got "
                          + std::to_string(image.ndim()) + " dimensions");
  for (int k = 0; k < 2; ++k)
    if (image.shape(k) < 1 || image.shape(k) > MAX_IMAGE_SIDE_PX)
      throw py::value_error(std::string(name) + " is " + std::to_string(image.shape(0))
                            + " x " + std::to_string(image.shape(1))
                            + " px; each side must be 1 to "
                            + std::to_string(MAX_IMAGE_SIDE_PX) + " px");
}

/** \a image as a C-contiguous uint8 array: another dtype is refused rather than cast
 * (a float image in [0, 1] would become a black one). */
ByteArray
toByteImage(const py::array& image, const char* name)
{
  checkImageShape(image, name, "an (H, W) uint8 array (8-bit grey)");
  if (!image.dtype().is(py::dtype::of<std::uint8_t>()))
    throw py::value_error(
      std::string(name) + " must be an (H, W) uint8 array (8-bit grey), got dtype "
      + py::str(image.dtype()).cast<std::string>()
      + "; convert it first (a float image in [0, 1]: (image * 255).astype(np.uint8))");
  return ByteArray::ensure(image);
}

/** An (H, W) uint8 array as a cv::Mat over the same memory (no copy). */
cv::Mat
toImage(const ByteArray& image, const char* name)
{
  if (image.ndim() != 2)
    throw py::value_error(std::string(name)
                          + " must be an (H, W) uint8 array (8-bit grey), got "
                          + std::to_string(image.ndim()) + " dimensions");
  return cv::Mat(static_cast<int>(image.shape(0)), static_cast<int>(image.shape(1)),
                 CV_8UC1, const_cast<std::uint8_t*>(image.data()));
}

/** A cv::Mat of CV_8UC1 as an (H, W) uint8 array (a copy). */
ByteArray
imageToArray(const cv::Mat& image)
{
  ByteArray out(
    {static_cast<py::ssize_t>(image.rows), static_cast<py::ssize_t>(image.cols)});
  auto o = out.mutable_unchecked<2>();
  for (int r = 0; r < image.rows; ++r)
    for (int c = 0; c < image.cols; ++c)
      o(r, c) = image.at<std::uint8_t>(r, c);
  return out;
}

StereoCalibration
toCalibration(const py::dict& d)
{
  StereoCalibration c;
  for (const auto& [key, value] : d) {
    const std::string k = py::str(key);
    if (k == "focal_length_px")
      c.focal_length_px = value.cast<double>();
    else if (k == "cx_px")
      c.cx_px = value.cast<double>();
    else if (k == "cy_px")
      c.cy_px = value.cast<double>();
    else if (k == "baseline_m")
      c.baseline_m = value.cast<double>();
    else if (k == "width")
      c.width = value.cast<int>();
    else if (k == "height")
      c.height = value.cast<int>();
    else
      throw py::value_error("calibration: unknown key '" + k
                            + "'; the keys are focal_length_px, cx_px, cy_px, "
                              "baseline_m, width, height");
  }
  return c;
}

py::dict
toDict(const StereoCalibration& c)
{
  py::dict d;
  d["focal_length_px"] = c.focal_length_px;
  d["cx_px"] = c.cx_px;
  d["cy_px"] = c.cy_px;
  d["baseline_m"] = c.baseline_m;
  d["width"] = c.width;
  d["height"] = c.height;
  return d;
}

DoubleArray
toMatrix(const Eigen::Isometry3d& pose)
{
  DoubleArray out({py::ssize_t{4}, py::ssize_t{4}});
  auto o = out.mutable_unchecked<2>();
  for (py::ssize_t r = 0; r < 4; ++r)
    for (py::ssize_t c = 0; c < 4; ++c)
      o(r, c) = pose.matrix()(static_cast<int>(r), static_cast<int>(c));
  return out;
}

py::dict
toDict(const FrameStats& stats)
{
  py::dict d;
  d["sequence_number"] = stats.sequence_number;
  d["total_ms"] = stats.total_ms;
  d["lock_wait_ms"] = stats.lock_wait_ms;
  d["exclusive_ms"] = stats.exclusive_ms;
  d["planes"] = stats.planes;
  d["cuboids"] = stats.cuboids;
  d["map_cells"] = stats.map_cells;
  d["world_T_camera"] = toMatrix(stats.world_T_camera);
  py::list stages;
  for (const auto& s : stats.stages) {
    py::dict e;
    e["type"] = s.type;
    e["ms"] = s.ms;
    e["points_in"] = s.points_in;
    e["points_out"] = s.points_out;
    for (const auto& [name, value] : s.counters)
      e[py::str(name)] = value;
    stages.append(e);
  }
  d["stages"] = stages;
  return d;
}

/** The map under the mapper's shared lock, as a context manager. */
struct MapReadContext {
  const Mapper* mapper{nullptr};
  std::optional<Mapper::MapReader> reader;
};

/** The frames of a configuration's input, read as the pipeline reads them. */
struct InputFrames {
  std::unique_ptr<FrameSource> source;
};

using MapperClass = py::class_<Mapper>;

/** A configuration given as its file (str or os.PathLike) or as a dict of the file's
 * content, as yaml.safe_load gives it (relative paths resolved against the working
 * folder; messages name "<config dict>" and the line:col of its JSON text). */
PipelineConfig
toPipelineConfig(const py::object& config)
{
  if (py::isinstance<py::dict>(config)) {
    const std::string text =
      py::str(py::module_::import("json").attr("dumps")(config, py::arg("indent") = 2));
    const std::string folder = py::str(py::module_::import("os").attr("getcwd")());
    py::gil_scoped_release release;
    return parsePipelineConfig(text, "<config dict>", folder);
  }
  const std::string path = toPath(config);
  py::gil_scoped_release release;
  return loadPipelineConfig(path);
}

/** A Mapper's stages given as a configuration file, a dict of a file's content
 * (toPipelineConfig()), a dict holding only its `pipeline` key, or that key's list of
 * {type, params} (parseMapperConfig(): no input section; messages name "<stages>"). */
MapperConfig
toStages(const py::object& config)
{
  const bool is_list = py::isinstance<py::list>(config);
  if (is_list || (py::isinstance<py::dict>(config) && !config.contains("input"))) {
    py::object document = config;
    if (is_list) {
      py::dict wrapped;
      wrapped["pipeline"] = config;
      document = wrapped;
    }
    const std::string text = py::str(
      py::module_::import("json").attr("dumps")(document, py::arg("indent") = 2));
    const std::string folder = py::str(py::module_::import("os").attr("getcwd")());
    py::gil_scoped_release release;
    return parseMapperConfig(text, "<stages>", folder);
  }
  return toMapperConfig(toPipelineConfig(config));
}

/** The docstring of the Mapper class. */
constexpr const char* MAPPER_DOC = R"doc(Builds a map frame by frame from your data.

The C++ planar_grid::Mapper: each call runs one frame through the stages of a pipeline
(those of a YAML configuration: the stages planar_grid_pipeline and run_pipeline() run,
so the same frames give the same map file, byte for byte). No input file is read. The
mapper takes stereo pairs when a stage reads stereo images (stereo_disparity,
feature_matching), else point clouds and depth images. The pipeline needs a
map_integration stage.

Threads: integrate_stereo() and integrate_cloud() release the GIL while the frame is
integrated; calls from several threads (and reset()) run one frame at a time. Another
thread reads the map with
``with mapper.read_map() as m:`` or save(): each frame locks readers out only while its
map_integration stage changes the map (docs/LIVE.md gives the measured wait). The
``map`` property is the map without the lock: read it between frames from the thread
that integrates.

Parameters
----------
config : str, os.PathLike, dict or list
    The configuration file (schema: config/example.yaml), or its content as a dict
    (e.g. the file's yaml.safe_load with a parameter changed); or the stages alone: a
    dict with only the key ``pipeline``, or its list of ``{"type": ..., "params":
    {...}}`` dicts, in run order (keys left out take their defaults; no input section).
    A dict's relative paths are resolved against the working folder.

Raises
------
planar_grid.ConfigError
    (a ValueError) for a bad configuration; a dict's errors name "<config dict>", the
    stages' "<stages>".
TypeError
    For a dict holding values JSON cannot write (e.g. numpy scalars: use float()).
planar_grid.Error
    When the pipeline has no map_integration stage.
)doc";

/** MapReadLock, the context manager that holds the map under the shared lock. */
void
bindMapReadLock(py::module_& m)
{
  py::class_<MapReadContext>(m, "MapReadLock",
                             R"doc(The map of a Mapper under its shared lock.

Returned by Mapper.read_map(); use it in a ``with`` block, which gives the map and holds
the lock until the block ends: the map cannot change inside it, also while another
thread integrates a frame. Do not keep the map beyond the block, and do not integrate a
frame inside the block on the same thread (it would wait for the block's lock).
)doc")
    .def("__enter__",
         [](MapReadContext& self) {
           {
             py::gil_scoped_release release;
             self.reader.emplace(self.mapper->readMap());
           }
           markMapperOwned(self.mapper->getMap());
           return std::const_pointer_cast<PlanarGridMap>(self.mapper->getMap());
         })
    .def("__exit__", [](MapReadContext& self, const py::args&) {
      self.reader.reset();
      return false;
    });
}

/** Frames from images: stereo pairs and depth images. */
void
bindMapperImageFrames(MapperClass& cls)
{
  cls
    .def(
      "integrate_stereo",
      [](Mapper& self, const py::array& left_array, const py::array& right_array,
         const py::dict& calibration, const py::object& world_T_camera) {
        const ByteArray left = toByteImage(left_array, "left");
        const ByteArray right = toByteImage(right_array, "right");
        const cv::Mat l = toImage(left, "left");
        const cv::Mat r = toImage(right, "right");
        const StereoCalibration c = toCalibration(calibration);
        std::optional<Eigen::Isometry3d> pose;
        if (!world_T_camera.is_none())
          pose = toIsometry(world_T_camera.cast<DoubleArray>(), "world_T_camera");
        FrameStats stats;
        {
          py::gil_scoped_release release;
          stats =
            pose ? self.integrateStereo(l, r, c, *pose) : self.integrateStereo(l, r, c);
        }
        return toDict(stats);
      },
      py::arg("left"), py::arg("right"), py::arg("calibration"),
      py::arg("world_T_camera") = py::none(),
      R"doc(Maps a rectified stereo pair.

Parameters
----------
left, right : numpy.ndarray, shape (H, W), uint8
    The rectified grey images (the calibration's size when it gives one).
calibration : dict
    focal_length_px, cx_px, cy_px (pixels), baseline_m (meters), and optionally width
    and height (pixels), as InputFrames gives it.
world_T_camera : numpy.ndarray, shape (4, 4), optional
    The left camera's pose (meters; camera x right, y down, z forward; z-up world).
    None: the pipeline's visual_odometry stage estimates it.

Returns
-------
dict
    The frame's statistics: sequence_number, total_ms, lock_wait_ms, exclusive_ms,
    planes and cuboids (the frame's), map_cells (the map's surface cells), world_T_camera
    (4, 4), and stages:
    a list of dicts with type, ms, points_in, points_out and the stage's counters.

Raises
------
ValueError
    For an array of another shape or a calibration with an unknown key.
planar_grid.Error
    For an empty image, sizes that differ, an invalid calibration, no pose without
    visual_odometry (or a pose with it), or a stage failing on the frame.
)doc")
    .def(
      "integrate_depth",
      [](Mapper& self, const py::array& depth, double fx_px, double fy_px, double cx_px,
         double cy_px, const DoubleArray& world_T_camera) {
        checkImageShape(depth, "depth", "an (H, W) array");
        using MillimeterArray =
          py::array_t<std::uint16_t, py::array::c_style | py::array::forcecast>;
        // uint16 stays millimeters; any other dtype is taken as meters (float32).
        py::array held;
        cv::Mat image;
        const int rows = static_cast<int>(depth.shape(0));
        const int cols = static_cast<int>(depth.shape(1));
        if (py::isinstance<py::array_t<std::uint16_t>>(depth)) {
          const auto a = MillimeterArray::ensure(depth);
          held = a;
          image = cv::Mat(rows, cols, CV_16UC1, const_cast<std::uint16_t*>(a.data()));
        } else {
          const auto a = FloatArray::ensure(depth);
          if (!a)
            throw py::value_error(
              "depth must hold numbers (uint16 millimeters or float "
              "meters)");
          held = a;
          image = cv::Mat(rows, cols, CV_32FC1, const_cast<float*>(a.data()));
        }
        const PinholeView camera{cols, rows, fx_px, fy_px, cx_px, cy_px};
        const Eigen::Isometry3d pose = toIsometry(world_T_camera, "world_T_camera");
        FrameStats stats;
        {
          py::gil_scoped_release release;
          stats = self.integrateDepth(image, camera, pose);
        }
        return toDict(stats);
      },
      py::arg("depth"), py::arg("fx_px"), py::arg("fy_px"), py::arg("cx_px"),
      py::arg("cy_px"), py::arg("world_T_camera"),
      R"doc(Maps a depth image, as its organized point cloud, with the camera's own pinhole
model for the free space.

Parameters
----------
depth : numpy.ndarray, shape (H, W)
    Depth along the optical axis: uint16 in millimeters, or float in meters (REP 118, as
    ROS depth cameras publish it); 0, NaN and infinity are invalid pixels.
fx_px, fy_px, cx_px, cy_px : float
    The depth camera's focal lengths and principal point, pixels.
world_T_camera : numpy.ndarray, shape (4, 4)
    The camera's pose (meters; camera x right, y down, z forward).

Returns
-------
dict
    The frame's statistics, as integrate_stereo().

Raises
------
ValueError
    For an array that is not (H, W) or not numeric.
planar_grid.Error
    For a pipeline that takes stereo pairs, focal lengths that are not positive, an
    image without a valid pixel, or a stage failing on the frame.
)doc");
}

/** Frames from point clouds. */
void
bindMapperCloudFrames(MapperClass& cls)
{
  cls.def(
    "integrate_cloud",
    [](Mapper& self, const FloatArray& points, const DoubleArray& world_T_sensor) {
      const auto cloud = toCloud(points, "points");
      const Eigen::Isometry3d pose = toIsometry(world_T_sensor, "world_T_sensor");
      FrameStats stats;
      {
        py::gil_scoped_release release;
        stats = self.integrateCloud(*cloud, pose);
      }
      return toDict(stats);
    },
    py::arg("points"), py::arg("world_T_sensor"),
    R"doc(Maps a point cloud.

Parameters
----------
points : numpy.ndarray, shape (N, 3), float
    x, y, z in the sensor frame, meters (NaN rows are invalid points).
world_T_sensor : numpy.ndarray, shape (4, 4)
    The sensor's pose, meters.

Returns
-------
dict
    The frame's statistics, as integrate_stereo().

Raises
------
planar_grid.Error
    For an empty cloud, a pipeline that takes stereo pairs, or a stage failing.
)doc");
}

/** The map (with or without the lock), saving, reset, frame count and trajectory. */
void
bindMapperState(MapperClass& cls)
{
  cls
    .def(
      "read_map",
      [](const Mapper& self) {
        MapReadContext context;
        context.mapper = &self;
        return context;
      },
      py::keep_alive<0, 1>(),
      "MapReadLock: ``with mapper.read_map() as m:`` gives the map under the shared "
      "lock (safe from any thread). The map is read-only: its changing methods raise "
      "planar_grid.Error.")
    .def_property_readonly(
      "map",
      [](const Mapper& self) {
        markMapperOwned(self.getMap());
        return std::const_pointer_cast<PlanarGridMap>(self.getMap());
      },
      "PlanarGridMap: the map without the lock; read it between frames from the thread "
      "that integrates (other threads: read_map()). Read-only: its changing methods "
      "raise planar_grid.Error.")
    .def(
      "save",
      [](const Mapper& self, const py::object& path) {
        const std::string p = toPath(path);
        py::gil_scoped_release release;
        self.save(p);
      },
      py::arg("path"),
      "Writes the map file (.pgmap) under the shared lock; raises planar_grid.IOError "
      "when it cannot be written.")
    .def(
      "reset",
      [](Mapper& self) {
        py::gil_scoped_release release;
        self.reset();
      },
      "Empties the map and restarts every stage (the odometry too).")
    .def_property_readonly("frame_count", &Mapper::getFrameCount,
                           "int: frames integrated since construction or reset().")
    .def_property_readonly(
      "trajectory",
      [](const Mapper& self) {
        const Trajectory& t = self.getTrajectory();
        DoubleArray out(
          {static_cast<py::ssize_t>(t.size()), py::ssize_t{4}, py::ssize_t{4}});
        auto o = out.mutable_unchecked<3>();
        for (std::size_t i = 0; i < t.size(); ++i)
          for (py::ssize_t r = 0; r < 4; ++r)
            for (py::ssize_t c = 0; c < 4; ++c)
              o(static_cast<py::ssize_t>(i), r, c) =
                t[i].matrix()(static_cast<int>(r), static_cast<int>(c));
        return out;
      },
      "numpy.ndarray, shape (F, 4, 4): world_T_camera of each integrated frame.")
    .def("__repr__", [](const Mapper& self) {
      const std::string& name = self.getConfig().name;
      return "<planar_grid.Mapper: " + (name.empty() ? std::string("<stages>") : name)
             + ", " + std::to_string(self.getFrameCount()) + " frames>";
    });
}

/** InputFrames: the frames of a configuration's input as dicts of arrays. */
void
bindInputFrames(py::module_& m)
{
  py::class_<InputFrames>(m, "InputFrames", R"doc(The frames of a configuration's input.

Read as the pipeline reads them (planar_grid::createFrameSource(): images rectified,
poses in the z-up world), one at a time, e.g. to feed a Mapper as a camera would.

Parameters
----------
config : str, os.PathLike or dict
    The configuration file, or its content as a dict (as Mapper takes it); its input
    section is used.

Raises
------
planar_grid.ConfigError, planar_grid.IOError
    For a bad configuration or a missing input.
)doc")
    .def(py::init([](const py::object& config) {
           const PipelineConfig parsed = toPipelineConfig(config);
           py::gil_scoped_release release;
           InputFrames frames;
           frames.source = createFrameSource(parsed.input);
           return frames;
         }),
         py::arg("config"))
    .def("__len__", [](const InputFrames& self) { return self.source->size(); })
    .def(
      "__getitem__",
      [](const InputFrames& self, std::size_t i) {
        if (i >= self.source->size())
          throw py::index_error("frame " + std::to_string(i) + " of "
                                + std::to_string(self.source->size()));
        Frame frame;
        {
          py::gil_scoped_release release;
          self.source->load(i, frame);
        }
        py::dict d;
        d["name"] = frame.name;
        if (frame.cloud)
          d["points"] = cloudToArray(*frame.cloud);
        else {
          d["left"] = imageToArray(frame.left);
          d["right"] = imageToArray(frame.right);
          d["calibration"] = toDict(frame.calibration);
        }
        d["world_T_camera"] =
          frame.has_pose ? py::object(toMatrix(frame.world_T_camera)) : py::none();
        return d;
      },
      py::arg("i"),
      "dict: frame i: name; left and right ((H, W) uint8) and calibration (dict) for "
      "stereo input, points ((N, 3) float64, sensor frame) for clouds; "
      "world_T_camera ((4, 4) or None).");
}

} // namespace

void
bindMapper(py::module_& m)
{
  bindMapReadLock(m);
  MapperClass cls(m, "Mapper", MAPPER_DOC);
  cls.def(py::init([](const py::object& config) {
            const MapperConfig stages = toStages(config);
            py::gil_scoped_release release;
            return std::make_unique<Mapper>(stages);
          }),
          py::arg("config"));
  bindMapperImageFrames(cls);
  bindMapperCloudFrames(cls);
  bindMapperState(cls);
  bindInputFrames(m);
}

} // namespace python
} // namespace planar_grid
