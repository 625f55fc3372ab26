// SPDX-License-Identifier: BSD-3-Clause
// The extension module planar_grid._planar_grid, which the package planar_grid
// re-exports (python/planar_grid/__init__.py): its docstring, the exception classes
// that carry the library's errors into Python, and the PCL console verbosity.
#include <planar_grid/core/exceptions.h>

#include <pcl/console/print.h>

#include <string>

#include "planar_grid_python.h"

namespace py = pybind11;

namespace {

// The exception classes, created once when the module is imported and kept for the
// life of the interpreter (the module holds them too).
PyObject* error_type = nullptr;
PyObject* config_error_type = nullptr;
PyObject* io_error_type = nullptr;

PyObject*
addException(py::module_& m, const char* name, const py::tuple& bases, const char* doc)
{
  const std::string qualified = std::string("planar_grid.") + name;
  PyObject* type =
    PyErr_NewExceptionWithDoc(qualified.c_str(), doc, bases.ptr(), nullptr);
  if (type == nullptr)
    throw py::error_already_set();
  m.add_object(name, py::handle(type));
  return type;
}

} // namespace

PYBIND11_MODULE(_planar_grid, m)
{
  m.doc() = R"doc(PlanarGrid: planar surface-based 3D mapping for mobile robots.

Python bindings of the C++ library (pybind11): the multi-RANSAC plane segmentation,
the split-and-merge cuboid approximation and the KL occupancy filter on numpy arrays,
the planar grid map (load, save, state, occupancy and ray queries, its cuboids) and
the YAML-configured pipeline. Points are (N, 3) arrays of x, y, z in meters; results
are numpy arrays (float64 geometry in meters, angles in radians, probabilities in
[0, 1]). Implements Zhang et al., "Efficient Planar Surface-Based 3D Mapping Method
for Mobile Robots Using Stereo Vision" (IEEE Access). See docs/PYTHON.md.

Errors: planar_grid.ConfigError (also a ValueError) for a bad configuration, with the
file, line and column; planar_grid.IOError (also an OSError) for a missing, unreadable
or corrupt file; planar_grid.Error (a RuntimeError) for the other library errors;
ValueError for an invalid argument or parameter.
)doc";

  m.attr("__version__") = PLANAR_GRID_VERSION;

  error_type =
    addException(m, "Error", py::make_tuple(py::handle(PyExc_RuntimeError)),
                 "An error of the PlanarGrid library (planar_grid::Exception); "
                 "the message is the library's.");
  config_error_type = addException(
    m, "ConfigError",
    py::make_tuple(py::handle(error_type), py::handle(PyExc_ValueError)),
    "A configuration error (planar_grid::ConfigError): str() reads "
    "'<file>:<line>:<col>: <message>'; the attributes file, line and column (1-based, "
    "0 when unknown) give the place.");
  // The attributes' types, for the type stubs (tools/stubgen.py declares them).
  py::dict config_error_attributes;
  config_error_attributes["file"] = "str";
  config_error_attributes["line"] = "int";
  config_error_attributes["column"] = "int";
  py::handle(config_error_type).attr("__annotations__") = config_error_attributes;
  io_error_type = addException(
    m, "IOError", py::make_tuple(py::handle(error_type), py::handle(PyExc_OSError)),
    "A missing, unreadable, truncated or corrupt file "
    "(planar_grid::IOError); the message names the file and the cause.");

  py::register_exception_translator([](std::exception_ptr thrown) {
    try {
      if (thrown)
        std::rethrow_exception(thrown);
    } catch (const planar_grid::ConfigError& e) {
      py::object error =
        py::reinterpret_borrow<py::object>(config_error_type)(e.what());
      error.attr("file") = e.file();
      error.attr("line") = e.line();
      error.attr("column") = e.column();
      PyErr_SetObject(config_error_type, error.ptr());
    } catch (const planar_grid::IOError& e) {
      PyErr_SetString(io_error_type, e.what());
    } catch (const planar_grid::Exception& e) {
      PyErr_SetString(error_type, e.what());
    }
  });

  m.def(
    "set_verbosity",
    [](const std::string& level) {
      using pcl::console::VERBOSITY_LEVEL;
      VERBOSITY_LEVEL value = VERBOSITY_LEVEL::L_INFO;
      if (level == "always")
        value = VERBOSITY_LEVEL::L_ALWAYS;
      else if (level == "error")
        value = VERBOSITY_LEVEL::L_ERROR;
      else if (level == "warn")
        value = VERBOSITY_LEVEL::L_WARN;
      else if (level == "info")
        value = VERBOSITY_LEVEL::L_INFO;
      else if (level == "debug")
        value = VERBOSITY_LEVEL::L_DEBUG;
      else if (level == "verbose")
        value = VERBOSITY_LEVEL::L_VERBOSE;
      else
        throw py::value_error("verbosity '" + level
                              + "' must be one of always, error, warn, info, debug, "
                                "verbose");
      pcl::console::setVerbosityLevel(value);
    },
    py::arg("level"),
    R"doc(Sets how much the library prints to the console (PCL's console verbosity).

Parameters
----------
level : str
    "always", "error", "warn" (PCL_WARN and above), "info" (the default), "debug" or
    "verbose".

Raises
------
ValueError
    For another name.
)doc");

  planar_grid::python::bindAlgorithms(m);
  planar_grid::python::bindOccupancyFilter(m);
  planar_grid::python::bindMap(m);
  planar_grid::python::bindMapIntegration(m);
  planar_grid::python::bindMapQueries(m);
  planar_grid::python::bindMapTiles(m);
  planar_grid::python::bindPipeline(m);
  planar_grid::python::bindMapper(m);
}
