// SPDX-License-Identifier: BSD-3-Clause
// Shared by the translation units of the Python module planar_grid: numpy <-> PCL and
// Eigen conversions, the result types the bindings return, and one helper that binds
// a class's parameters as properties, constructor arguments, repr and signature.
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <cstddef>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <tuple>
#include <type_traits>
#include <utility>
#include <vector>

namespace planar_grid {
class PlanarGridMap;
}

namespace planar_grid {
namespace python {

namespace py = pybind11;

/** \brief Any array-like converted to a C-contiguous float32 array (numpy casts). */
using FloatArray = py::array_t<float, py::array::c_style | py::array::forcecast>;
/** \brief Any array-like converted to a C-contiguous float64 array. */
using DoubleArray = py::array_t<double, py::array::c_style | py::array::forcecast>;
/** \brief Any array-like converted to a C-contiguous int64 array. */
using IndexArray = py::array_t<std::int64_t, py::array::c_style | py::array::forcecast>;

/** \brief Copies an (N, 3) array of points (meters) into a cloud; is_dense tells
 * whether every coordinate is finite. \throws py::value_error naming \a name for
 * another shape */
pcl::PointCloud<pcl::PointXYZ>::Ptr toCloud(const FloatArray& points, const char* name);

/** \brief Points of an (N, 3) array, or the one point of a (3,) array, as floats
 * (meters). \throws py::value_error naming \a name for another shape */
std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>
toPoints(const FloatArray& points, const char* name);

/** \brief A (3,) array as a vector. \throws py::value_error naming \a name */
Eigen::Vector3f toVector3f(const DoubleArray& vector, const char* name);

/** \brief Checks that every inlier of \a planes indexes one of \a point_count points
 * (the cloud the planes are used with).
 * \throws py::index_error naming \a who, the plane and the index */
void checkInlierIndices(const PlanarSegments& planes,
                        std::size_t point_count,
                        const std::string& who);

/** \brief A vector as a (3,) float64 array. */
inline DoubleArray
toArray(const Eigen::Vector3f& vector)
{
  DoubleArray out(3);
  for (py::ssize_t k = 0; k < 3; ++k)
    out.mutable_at(k) = vector[static_cast<int>(k)];
  return out;
}

/** \brief A (4, 4) rigid transform as an isometry (the last row must be 0 0 0 1 and the
 * rotation orthonormal within 1e-3). \throws py::value_error naming \a name */
Eigen::Isometry3d toIsometry(const DoubleArray& matrix, const char* name);

/** \brief Records \a map as a Mapper's map, as Mapper.map and Mapper.read_map() hand it
 * to Python: it changes only through the Mapper, under its lock, so its own changing
 * methods refuse (requireWritable()) for as long as it lives. */
void markMapperOwned(const std::shared_ptr<const PlanarGridMap>& map);

/** \brief \throws planar_grid::Exception (planar_grid.Error) naming \a method when
 * \a map is a Mapper's (markMapperOwned()). */
void requireWritable(const PlanarGridMap& map, const char* method);

/** \brief A path given as str or os.PathLike, as text. */
inline std::string
toPath(const py::handle& path)
{
  return py::str(py::module_::import("os").attr("fspath")(path));
}

/** \brief An (N, 3) float64 array of the cloud's x, y, z (meters). */
template <typename PointT>
py::array_t<double>
cloudToArray(const pcl::PointCloud<PointT>& cloud)
{
  py::array_t<double> out({static_cast<py::ssize_t>(cloud.size()), py::ssize_t{3}});
  auto o = out.mutable_unchecked<2>();
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    const auto i_py = static_cast<py::ssize_t>(i);
    o(i_py, 0) = cloud[i].x;
    o(i_py, 1) = cloud[i].y;
    o(i_py, 2) = cloud[i].z;
  }
  return out;
}

/** \brief A (K,) array of type T from a per-item function. */
template <typename T, typename Container, typename Get>
py::array_t<T>
column(const Container& items, Get get)
{
  py::array_t<T> out(static_cast<py::ssize_t>(items.size()));
  auto o = out.template mutable_unchecked<1>();
  for (std::size_t i = 0; i < items.size(); ++i)
    o(static_cast<py::ssize_t>(i)) = static_cast<T>(get(items[i]));
  return out;
}

/** \brief Planes of a segmentation, held for Python (PlanarSegments in Python). */
struct Planes {
  /** \brief The planes, sorted by descending inlier count. */
  PlanarSegments segments;
};

/** \brief Cuboids of an approximation or a map, held for Python (Cuboids in Python). */
struct Cuboids {
  /** \brief The cuboids. */
  PlanarCuboids cuboids;
};

/** \brief One parameter of a bound class, for ParamBinder: its Python name, the type
 * \a V of its value, \a get(const T&) that reads it, \a set(T&, V) that writes it, and
 * its meaning with unit and range (ParamBinder adds the type and the default, read from
 * the C++ object). */
template <typename V, typename Get, typename Set> struct Param {
  /** \brief The value type of the property and of the constructor argument. */
  using Value = V;
  /** \brief The name of the property and of the constructor argument. */
  const char* name;
  /** \brief Reads the value from the object. */
  Get get;
  /** \brief Writes the value to the object. */
  Set set;
  /** \brief Meaning, unit and range, without type or default (a range is quoted
   * from the class's declaration, formatParamRange()). */
  std::string doc;
};

/** \brief A parameter whose constructor default is the value of a default-constructed
 * C++ object. */
template <typename V, typename Get, typename Set>
Param<V, Get, Set>
param(const char* name, Get get, Set set, std::string doc)
{
  return {name, std::move(get), std::move(set), std::move(doc)};
}

/** \brief The Python type of a parameter value, as docstrings name it: an array is
 * array_like as a constructor \a argument, numpy.ndarray as a property (which stubgen
 * reads from the property's docstring). */
template <typename V>
const char*
pythonTypeName(bool argument)
{
  if constexpr (std::is_same_v<V, bool>)
    return "bool";
  else if constexpr (std::is_integral_v<V>)
    return "int";
  else if constexpr (std::is_floating_point_v<V>)
    return "float";
  else if constexpr (std::is_same_v<V, std::string>)
    return "str";
  else
    return argument ? "array_like" : "numpy.ndarray";
}

/** \brief The Python type of a parameter value, as an annotation of inspect.signature()
 * (numpy.ndarray for an array, which any array-like converts to). */
template <typename V>
py::object
pythonType()
{
  if constexpr (std::is_same_v<V, bool>)
    return py::module_::import("builtins").attr("bool");
  else if constexpr (std::is_integral_v<V>)
    return py::module_::import("builtins").attr("int");
  else if constexpr (std::is_floating_point_v<V>)
    return py::module_::import("builtins").attr("float");
  else if constexpr (std::is_same_v<V, std::string>)
    return py::module_::import("builtins").attr("str");
  else
    return py::module_::import("numpy").attr("ndarray");
}

/** \brief \a text wrapped at word boundaries into lines of at most \a width characters
 * after \a indent spaces (docstrings). */
std::string wrapText(const std::string& text, std::size_t indent, std::size_t width);

/** \brief Binds the parameters of \a T, each given once as a Param, as the class's
 * Python interface: read-write properties, a constructor that takes them as named
 * arguments with their types and defaults, __repr__, and __signature__.
 *
 * The defaults are read from a default-constructed \a T through the getters, so the C++
 * class owns each default; the property and constructor docstrings show them. After a
 * property assignment the object's own range check runs (\a check, which returns
 * nullptr or what is wrong): an invalid value raises ValueError with that text and
 * leaves the old value. The constructor sets every argument, then runs the check once,
 * so the order of the arguments does not matter. An unknown keyword is pybind11's
 * TypeError, which names it and shows the signature. */
template <typename T, typename Holder> class ParamBinder {
public:
  /** \brief The object's range check. */
  using Check = std::function<const char*(const T&)>;

  ParamBinder(py::class_<T, Holder>& cls, std::string class_name, Check check) :
      cls_(cls), class_name_(std::move(class_name)), check_(std::move(check))
  {}

  /** \brief Binds the properties, the constructor, __repr__ and __signature__.
   * \param[in] leading parameters the constructor takes first, positional or by name,
   * without default (e.g. the stereo rig of an occupancy filter)
   * \param[in] keywords parameters the constructor takes by name only, with the C++
   * defaults */
  template <typename... Leading, typename... Keywords>
  void bind(const std::tuple<Leading...>& leading,
            const std::tuple<Keywords...>& keywords)
  {
    const T defaults{};
    std::string init_doc = "Parameters\n----------\n";
    std::apply(
      [&](const auto&... p) { (bindProperty(p, defaults, false, init_doc), ...); },
      leading);
    std::apply(
      [&](const auto&... p) { (bindProperty(p, defaults, true, init_doc), ...); },
      keywords);
    init_doc += "\nRaises\n------\nTypeError\n    For an unknown keyword or a value of "
                "another type.\nValueError\n"
                + wrapText("For a value out of its range (the library's range check, "
                           "with its message).",
                           4, 88);
    bindRepr();
    bindInit(leading, keywords, defaults, init_doc,
             std::index_sequence_for<Leading...>{},
             std::index_sequence_for<Keywords...>{});
  }

private:
  /** \brief The value for Python: an array as a list, which the setters take too. */
  template <typename V> static py::object toPython(const V& value)
  {
    py::object python;
    if constexpr (std::is_base_of_v<py::handle, V>)
      python = py::reinterpret_borrow<py::object>(value);
    else
      python = py::cast(value);
    if (py::isinstance<py::array>(python))
      python = python.attr("tolist")();
    return python;
  }

  /** \brief The constructor default of \a p: the value of \a defaults. An array as a
   * tuple, so that the signature shows no mutable default. */
  template <typename P> static py::object defaultOf(const P& p, const T& defaults)
  {
    py::object value = toPython(std::invoke(p.get, defaults));
    if (py::isinstance<py::list>(value))
      value = py::tuple(value);
    return value;
  }

  /** \brief Binds \a p as a property and adds it to the constructor's docstring. */
  template <typename P>
  void bindProperty(const P& p, const T& defaults, bool keyword, std::string& init_doc)
  {
    using V = typename P::Value;
    const std::string type = pythonTypeName<V>(true);
    std::string property_doc = pythonTypeName<V>(false) + std::string(": ") + p.doc;
    std::string argument_doc = p.doc;
    if (keyword) {
      const std::string value =
        py::repr(defaultOf(p, defaults)).template cast<std::string>();
      property_doc += " (default " + value + ")";
      argument_doc += ". Default " + value + ".";
      init_doc += std::string(p.name) + " : " + type + ", optional\n";
    } else {
      argument_doc += ".";
      init_doc += std::string(p.name) + " : " + type + "\n";
    }
    init_doc += wrapText(argument_doc, 4, 88);
    property_doc += ".";

    const Check check = check_;
    const std::string class_name = class_name_;
    const auto get = p.get;
    const auto set = p.set;
    const auto assign = [get, set, check, class_name](T& object, V value) {
      auto old = std::invoke(get, static_cast<const T&>(object));
      std::invoke(set, object, value);
      if (check) {
        if (const char* bad = check(object)) {
          std::invoke(set, object, old);
          throw py::value_error(class_name + ": invalid parameter: " + bad);
        }
      }
    };
    cls_.def_property(
      p.name, [get](const T& object) { return std::invoke(get, object); }, assign,
      property_doc.c_str());
    reprs_.emplace_back(p.name, [get](const T& object) {
      return py::repr(toPython(std::invoke(get, object))).template cast<std::string>();
    });
    Parameter parameter{p.name, pythonType<V>(), py::none(), keyword};
    if (keyword)
      parameter.default_value = defaultOf(p, defaults);
    parameters_.push_back(std::move(parameter));
  }

  /** \brief Sets one constructor argument. */
  template <typename P, typename I>
  static void setInitial(T& object, const P& p, const I& value)
  {
    std::invoke(p.set, object, value);
  }

  /** \brief Binds the constructor and __signature__ (inspect.signature() cannot read
   * pybind11's docstring signatures). */
  template <typename... L, typename... K, std::size_t... I, std::size_t... J>
  void bindInit(const std::tuple<L...>& leading,
                const std::tuple<K...>& keywords,
                const T& defaults,
                const std::string& doc,
                std::index_sequence<I...>,
                std::index_sequence<J...>)
  {
    const Check check = check_;
    const std::string class_name = class_name_;
    auto make = [leading, keywords, check, class_name](typename L::Value... lead,
                                                       typename K::Value... keyword) {
      auto object = std::make_unique<T>();
      (setInitial(*object, std::get<I>(leading), lead), ...);
      (setInitial(*object, std::get<J>(keywords), keyword), ...);
      if (check) {
        if (const char* bad = check(*object))
          throw py::value_error(class_name + ": invalid parameter: " + bad);
      }
      return object;
    };
    cls_.def(py::init(make), py::arg(std::get<I>(leading).name)..., py::kw_only(),
             py::arg_v(std::get<J>(keywords).name,
                       defaultOf(std::get<J>(keywords), defaults))...,
             doc.c_str());

    const py::module_ inspect = py::module_::import("inspect");
    const py::object parameter_type = inspect.attr("Parameter");
    py::list parameters;
    for (const Parameter& p : parameters_) {
      const py::object kind =
        parameter_type.attr(p.keyword_only ? "KEYWORD_ONLY" : "POSITIONAL_OR_KEYWORD");
      if (p.keyword_only)
        parameters.append(parameter_type(p.name, kind,
                                         py::arg("default") = p.default_value,
                                         py::arg("annotation") = p.annotation));
      else
        parameters.append(
          parameter_type(p.name, kind, py::arg("annotation") = p.annotation));
    }
    cls_.attr("__signature__") = inspect.attr("Signature")(parameters);
  }

  /** \brief Binds __repr__: "planar_grid.<class>(name=value, ...)" with every
   * parameter in binding order: a constructor call that rebuilds the object. */
  void bindRepr()
  {
    const auto reprs = reprs_;
    const std::string class_name = class_name_;
    cls_.def("__repr__", [reprs, class_name](const T& object) {
      std::string text = "planar_grid." + class_name + "(";
      for (std::size_t i = 0; i < reprs.size(); ++i)
        text += (i == 0 ? "" : ", ") + reprs[i].first + "=" + reprs[i].second(object);
      return text + ")";
    });
  }

  /** \brief A constructor argument, for __signature__. */
  struct Parameter {
    /** \brief Its name. */
    const char* name;
    /** \brief Its type. */
    py::object annotation;
    /** \brief Its default (for a keyword-only argument). */
    py::object default_value;
    /** \brief Whether it is keyword-only (else positional or keyword, required). */
    bool keyword_only;
  };

  py::class_<T, Holder>& cls_;
  std::string class_name_;
  Check check_;
  std::vector<std::pair<std::string, std::function<std::string(const T&)>>> reprs_;
  std::vector<Parameter> parameters_;
};

/** \brief Binds SACMultiPlaneSegmentation, PlanarCuboidApproximation and their result
 * types. */
void bindAlgorithms(py::module_& m);
/** \brief Binds TerrainRemoval. */
void bindTerrainRemoval(py::module_& m);
/** \brief Binds KLDivergenceOccupancyFilter and the occupancy functions of its
 * equations. */
void bindOccupancyFilter(py::module_& m);
/** \brief Binds PlanarGridMap (construction, the map file, integration, its cuboids,
 * planes and memory) and SpaceState. */
void bindMap(py::module_& m);
/** \brief Adds the point, ray, distance and collision queries to PlanarGridMap (bound
 * by bindMap()) and binds MapRegionIndex. */
void bindMapQueries(py::module_& m);
/** \brief Adds save_tiles and load_tiles to PlanarGridMap (bound by bindMap()) and
 * binds the module's tile functions (save, load, read the index, merge tile sets). */
void bindMapTiles(py::module_& m);
/** \brief Binds run_pipeline(), PipelineResult and stage_types(). */
void bindPipeline(py::module_& m);
/** \brief Binds Mapper, its MapReadLock and InputFrames. */
void bindMapper(py::module_& m);

} // namespace python
} // namespace planar_grid
