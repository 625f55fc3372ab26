// SPDX-License-Identifier: BSD-3-Clause
// The pipeline run from a YAML configuration, as planar_grid_pipeline runs it (without
// the PNG snapshots), with its state, trajectory and report returned to Python.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>
#include <planar_grid/pipeline/stage.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <atomic>
#include <cstdint>
#include <optional>
#include <string>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** What a run leaves: its report, the shared state and the poses. */
struct PipelineResult {
  RunReport report;
  PipelineState state;
  Trajectory trajectory;
};

/** run_pipeline()'s memory_limit: the machine's limit for None, else a count of bytes
 * or a size text ("16G", "none"); ValueError for a negative count or a bad text. */
MemoryLimit
memoryLimitArgument(const py::object& memory_limit)
{
  MemoryLimit limit = machineMemoryLimit();
  if (!memory_limit.is_none()) {
    if (py::isinstance<py::str>(memory_limit)) {
      const std::string text = memory_limit.cast<std::string>();
      try {
        limit.bytes = parseMemorySize(text);
      } catch (const Exception& e) {
        throw py::value_error(std::string("memory_limit: ") + e.what());
      }
      limit.source = "memory_limit='" + text + "'";
    } else {
      const auto bytes = memory_limit.cast<long long>();
      if (bytes < 0)
        throw py::value_error("memory_limit must be >= 0 bytes (0: no limit)");
      limit.bytes = static_cast<std::uint64_t>(bytes);
      limit.source = "memory_limit=" + std::to_string(bytes);
    }
  }
  return limit;
}

/** run_pipeline()'s frames: (begin, end) positions, either may be None. */
void
frameRangeArgument(const py::object& frames,
                   std::optional<std::size_t>& begin,
                   std::optional<std::size_t>& end)
{
  if (!frames.is_none()) {
    const auto range = frames.cast<py::tuple>();
    if (range.size() != 2)
      throw py::value_error("frames must be (begin, end): 0-based positions, end "
                            "excluded; either may be None");
    if (!range[0].is_none())
      begin = range[0].cast<std::size_t>();
    if (!range[1].is_none())
      end = range[1].cast<std::size_t>();
  }
}

/** run_pipeline(): loads the configuration, runs its frames with the GIL released (the
 * progress callback and Ctrl-C are seen after each frame) and writes the outputs as one
 * set. */
PipelineResult
runPipeline(const py::object& config,
            const py::object& frames,
            const py::object& output_folder,
            bool write_outputs,
            bool sequential,
            bool resume,
            const py::object& progress,
            const py::object& memory_limit)
{
  const std::string config_path = toPath(config);
  const MemoryLimit limit = memoryLimitArgument(memory_limit);
  std::optional<std::size_t> begin, end;
  frameRangeArgument(frames, begin, end);
  std::optional<std::string> folder;
  if (!output_folder.is_none())
    folder = toPath(output_folder);
  // The runner keeps only a pointer to the callback, so that no Python object is
  // copied or destroyed while the GIL is released.
  const py::function* callback = nullptr;
  py::function progress_function;
  if (!progress.is_none()) {
    progress_function = progress.cast<py::function>();
    callback = &progress_function;
  }

  PipelineResult result;
  py::gil_scoped_release release;
  PipelineConfig cfg = loadPipelineConfig(config_path);
  if (folder)
    cfg.output.folder = *folder;
  // The module renders no PNG snapshot (the command-line tool does, with VTK).
  for (std::string* name :
       {&cfg.output.snapshot, &cfg.output.planes_snapshot, &cfg.output.cuboids_snapshot,
        &cfg.output.cuboids_street_snapshot, &cfg.output.map_snapshot})
    name->clear();
  PipelineRunner runner(cfg);
  runner.setFrameOverlap(!sequential);
  runner.setMemoryLimit(limit);
  if (begin || end)
    runner.setFrameRange(begin.value_or(0), end.value_or(runner.frameCount()));
  const std::string checkpoint_path = cfg.output.checkpoint.empty()
                                        ? std::string()
                                        : outputPath(cfg.output, cfg.output.checkpoint);
  if (resume) {
    if (checkpoint_path.empty())
      throw Exception("resume needs output.checkpoint (a file name)");
    runner.resumeFrom(checkpoint_path);
  }
  if (write_outputs && cfg.output.checkpoint_every_n_frames > 0)
    runner.setCheckpoint(checkpoint_path, cfg.output.checkpoint_every_n_frames);
  // As the tool does: an output that would replace a file the run reads, or that
  // names a folder, is refused before the first frame; the outputs replace the
  // previous set in the folder together, and an unwritable folder is found before
  // the first frame too.
  std::optional<OutputTransaction> outputs;
  if (write_outputs) {
    checkOutputPaths(cfg.output, runner.inputFiles(),
                     cfg.output.checkpoint_every_n_frames > 0);
    outputs.emplace(cfg.output.folder);
  }
  // Ctrl-C (Python's KeyboardInterrupt) is seen after each frame: the run stops
  // there, as the tool does on SIGINT, and nothing is written.
  std::atomic<bool> stop{false};
  runner.setStopFlag(&stop);
  runner.setProgressCallback(
    [callback, &stop](std::size_t done, std::size_t total, double seconds) {
      py::gil_scoped_acquire acquire;
      try {
        if (callback != nullptr)
          (*callback)(done, total, seconds);
        if (PyErr_CheckSignals() != 0)
          throw py::error_already_set();
      } catch (py::error_already_set& e) {
        // Ctrl-C, seen in the callback or here: a KeyboardInterrupt is raised
        // again when run() has stopped; any other error ends the run.
        if (!e.matches(PyExc_KeyboardInterrupt))
          throw;
        stop.store(true);
      }
    });
  try {
    result.report = runner.run();
  } catch (const Interrupted& e) {
    py::gil_scoped_acquire acquire;
    PyErr_SetString(PyExc_KeyboardInterrupt, (std::string(e.what())
                                              + "; no output was written, the previous "
                                                "outputs in "
                                              + cfg.output.folder + " are as they were")
                                               .c_str());
    throw py::error_already_set();
  }
  if (outputs) {
    writeRunOutputs(cfg.output, runner, result.report, *outputs);
    writeRunReport(cfg.output, result.report, *outputs);
    outputs->commit();
  }
  result.state = runner.state();
  result.trajectory = runner.trajectory();
  return result;
}

/** PipelineResult: a run's state, trajectory and report, as arrays and dicts. */
void
bindPipelineResult(py::module_& m)
{
  py::class_<PipelineResult>(m, "PipelineResult", R"doc(What run_pipeline() produced.

The accumulated clouds, the map, the poses and the report of the run (the C++
PipelineRunner's state, trajectory and RunReport).
)doc")
    .def_property_readonly(
      "report",
      [](const PipelineResult& r) {
        return py::module_::import("json").attr("loads")(r.report.toJson());
      },
      "dict: the run report, as report.json (per-stage milliseconds, points in/out, "
      "features, planes, cuboids, the map's cells and memory, frames/s).")
    .def_property_readonly(
      "timing_table", [](const PipelineResult& r) { return r.report.timingTable(); },
      "str: the per-stage timing table the command-line tool prints.")
    .def_property_readonly(
      "frames", [](const PipelineResult& r) { return r.report.frames; },
      "int: frames run.")
    .def_property_readonly(
      "outputs",
      [](const PipelineResult& r) {
        py::dict out;
        for (const auto& [kind, path] : r.report.outputs)
          out[py::str(kind)] = path;
        return out;
      },
      "dict: written files by kind (cloud, planes, map, map_octomap, map_mesh, "
      "trajectory, report), empty with write_outputs=False.")
    .def_property_readonly(
      "map",
      [](const PipelineResult& r) -> py::object {
        if (!r.state.map)
          return py::none();
        return py::cast(r.state.map);
      },
      "PlanarGridMap or None: the map (map_integration stage).")
    .def_property_readonly(
      "world_cloud",
      [](const PipelineResult& r) { return cloudToArray(*r.state.world_cloud); },
      "numpy.ndarray, shape (N, 3), float64: the accumulated world cloud, meters "
      "(accumulate stage).")
    .def_property_readonly(
      "world_cloud_intensity",
      [](const PipelineResult& r) {
        const auto& cloud = *r.state.world_cloud;
        py::array_t<double> out(static_cast<py::ssize_t>(cloud.size()));
        double* o = out.mutable_data();
        for (std::size_t i = 0; i < cloud.size(); ++i)
          o[i] = cloud[i].intensity;
        return out;
      },
      "numpy.ndarray, shape (N,), float64: the world cloud's intensity (the grey value "
      "for stereo input).")
    .def_property_readonly(
      "plane_cloud",
      [](const PipelineResult& r) {
        return cloudToArray(r.state.planes->getInlierCloud());
      },
      "numpy.ndarray, shape (M, 3), float64: the accumulated inliers of the non-ground "
      "planes, meters.")
    .def_property_readonly(
      "plane_labels",
      [](const PipelineResult& r) {
        const auto& cloud = r.state.planes->getInlierCloud();
        py::array_t<std::int64_t> out(static_cast<py::ssize_t>(cloud.size()));
        std::int64_t* o = out.mutable_data();
        for (std::size_t i = 0; i < cloud.size(); ++i)
          o[i] = cloud[i].label;
        return out;
      },
      "numpy.ndarray, shape (M,), int64: the run-wide plane of each plane_cloud point "
      "(a row of plane_models).")
    .def_property_readonly(
      "plane_models",
      [](const PipelineResult& r) {
        const auto& planes = r.state.planes->getModelCoefficients();
        py::array_t<double> out(
          {static_cast<py::ssize_t>(planes.size()), py::ssize_t{4}});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t i = 0; i < planes.size(); ++i)
          for (py::ssize_t j = 0; j < 4; ++j)
            o(static_cast<py::ssize_t>(i), j) = planes[i][static_cast<int>(j)];
        return out;
      },
      "numpy.ndarray, shape (K, 4), float64: the run-wide planes [a, b, c, d] (unit "
      "normal, meters), world frame.")
    .def_property_readonly(
      "cuboids", [](const PipelineResult& r) { return Cuboids{r.state.cuboids}; },
      "Cuboids: every frame's cells in the world frame, accumulated when no "
      "map_integration stage ran (with a map, use map.cuboids).")
    .def_property_readonly(
      "trajectory",
      [](const PipelineResult& r) {
        py::array_t<double> out({static_cast<py::ssize_t>(r.trajectory.size()),
                                 py::ssize_t{4}, py::ssize_t{4}});
        auto o = out.mutable_unchecked<3>();
        for (std::size_t i = 0; i < r.trajectory.size(); ++i)
          for (py::ssize_t row = 0; row < 4; ++row)
            for (py::ssize_t col = 0; col < 4; ++col)
              o(static_cast<py::ssize_t>(i), row, col) =
                r.trajectory[i].matrix()(static_cast<int>(row), static_cast<int>(col));
        return out;
      },
      "numpy.ndarray, shape (F, 4, 4), float64: world_T_camera of each frame that ran "
      "(meters), in the z-up world.")
    .def("__repr__", [](const PipelineResult& r) {
      return "<planar_grid.PipelineResult: " + std::to_string(r.report.frames)
             + " frames, " + std::to_string(r.state.world_cloud->size())
             + " world points" + (r.state.map ? ", a map>" : ">");
    });
}

/** run_pipeline() and input_frame_count(): run a configuration, count its frames. */
void
bindRunPipeline(py::module_& m)
{
  m.def(
    "run_pipeline", &runPipeline, py::arg("config"), py::kw_only(),
    py::arg("frames") = py::none(), py::arg("output_folder") = py::none(),
    py::arg("write_outputs") = true, py::arg("sequential") = false,
    py::arg("resume") = false, py::arg("progress") = py::none(),
    py::arg("memory_limit") = py::none(),
    R"doc(Runs the pipeline a YAML configuration describes, as planar_grid_pipeline does.

Parameters
----------
config : str or os.PathLike
    The configuration file (schema: config/example.yaml); relative input paths are
    resolved against its folder.
frames : tuple of (int or None, int or None), optional
    (begin, end): run frame positions begin..end-1 of the input (0-based); None for an
    open side. Default: every frame.
output_folder : str or os.PathLike, optional
    Write the outputs here instead of the configuration's output.folder.
write_outputs : bool, optional
    Write the configured files (world cloud and planes PCD, map, OctoMap, mesh,
    trajectory, report.json; replaced as one set) (default True). PNG snapshots are not
    rendered (use the command-line tool).
sequential : bool, optional
    Run every frame on one thread (default False: the leading frame-local stages run
    up to two frames ahead on a second thread; the results are the same).
resume : bool, optional
    Continue from the checkpoint in the output folder (output.checkpoint).
progress : callable, optional
    Called after each frame as progress(frames_done, frames_total, seconds_elapsed).
memory_limit : int or str, optional
    Refuse the run before its first frame when its memory estimate exceeds this many
    bytes ("16G", "512M": powers of 1024; 0 or "none": no check). Default: the
    machine's memory, or the process's limit where smaller (docs/RELIABILITY.md).

Returns
-------
PipelineResult

Raises
------
planar_grid.ConfigError
    (a ValueError) for a bad configuration, with file, line and column.
planar_grid.IOError
    (an OSError) for a missing or unreadable input or an output that cannot be written.
planar_grid.Error
    When a frame cannot be processed (the message names the frame and stage) or the
    frame range is outside the input.
KeyboardInterrupt
    On Ctrl-C (SIGINT), after the frame under way (checkpointed when checkpoints are
    on); nothing else is written and the previous outputs stay.
)doc");

  m.def(
    "input_frame_count",
    [](const py::object& config) {
      const std::string config_path = toPath(config);
      py::gil_scoped_release release;
      // The runner opens the input (the frame list, the poses) without reading a frame.
      return PipelineRunner(loadPipelineConfig(config_path)).frameCount();
    },
    py::arg("config"),
    R"doc(Number of frames in the input a YAML configuration describes.

The input is opened (its file list, poses and calibration checked) but no frame is
read, so this is cheap beside a run; it is what ``frames=(begin, end)`` of
run_pipeline() ranges over.

Parameters
----------
config : str or os.PathLike
    The configuration file (schema: config/example.yaml).

Returns
-------
int
    Frames in the input (0-based positions 0 .. count - 1).

Raises
------
planar_grid.ConfigError
    (a ValueError) for a bad configuration, with file, line and column.
planar_grid.IOError
    (an OSError) for a missing or unreadable input.
)doc");
}

/** stage_types() and stage_parameters(): the stage registry's parameter tables. */
void
bindStageTables(py::module_& m)
{
  m.def(
    "stage_types",
    [] {
      py::dict out;
      for (const auto& info : stageRegistry())
        out[py::str(info.type)] = info.description + "\n" + describeParams(info.params);
      return out;
    },
    R"doc(The pipeline's stage types.

Returns
-------
dict
    Stage type -> its description and parameters (defaults, units, ranges), as
    ``planar_grid_pipeline --list-stages`` prints them.
)doc");

  m.def(
    "stage_parameters",
    [](const std::string& type) {
      const StageInfo* info = findStage(type);
      if (!info)
        throw Exception("stage_parameters: unknown stage type '" + type
                        + "'; known types: " + knownStageTypes());
      const ParamValues defaults = defaultParams(info->params);
      py::list out;
      for (const ParamSpec& spec : info->params) {
        py::dict row;
        row["key"] = spec.key;
        const bool ranged =
          spec.type == ParamSpec::Type::DOUBLE || spec.type == ParamSpec::Type::INT;
        switch (spec.type) {
          case ParamSpec::Type::DOUBLE:
            row["type"] = "float";
            row["default"] = defaults.getDouble(spec.key);
            break;
          case ParamSpec::Type::INT:
            row["type"] = "int";
            row["default"] = defaults.getInt(spec.key);
            break;
          case ParamSpec::Type::BOOL:
            row["type"] = "bool";
            row["default"] = defaults.getBool(spec.key);
            break;
          case ParamSpec::Type::CHOICE:
            row["type"] = "choice";
            row["default"] = defaults.getChoice(spec.key);
            break;
        }
        row["min"] = ranged ? py::object(py::float_(spec.range.min)) : py::none();
        row["max"] = ranged ? py::object(py::float_(spec.range.max)) : py::none();
        row["min_open"] =
          ranged ? py::object(py::bool_(spec.range.min_open)) : py::none();
        row["max_open"] =
          ranged ? py::object(py::bool_(spec.range.max_open)) : py::none();
        row["unit"] = spec.unit;
        row["choices"] = spec.choices;
        row["description"] = spec.description;
        out.append(row);
      }
      return out;
    },
    py::arg("stage_type"),
    R"doc(The parameter table of one stage type: the one declaration from which the
configuration check, ``planar_grid_pipeline --list-stages``, ``stage_types()`` and the
stage list of config/example.yaml are made.

Parameters
----------
stage_type : str
    A stage type, e.g. ``"voxel_grid"`` (the keys of ``stage_types()``).

Returns
-------
list of dict
    One dict per parameter, in the table's order: ``key`` (the YAML key, ending in its
    unit), ``type`` ('float', 'int', 'bool' or 'choice'), ``default`` (of that type),
    ``min`` and ``max`` (the range's ends in the unit; None for bool and choice),
    ``min_open`` and ``max_open`` (True where that end is not in the range, as in
    "(0, 1]"; None for bool and choice), ``unit`` ('' for counts and flags), ``choices`` (the allowed names of a choice)
    and ``description``.

Raises
------
planar_grid.Error
    For an unknown stage type (the message lists the known ones).
)doc");
}

} // namespace

void
bindPipeline(py::module_& m)
{
  bindPipelineResult(m);
  bindRunPipeline(m);
  bindStageTables(m);
}

} // namespace python
} // namespace planar_grid
