// SPDX-License-Identifier: BSD-3-Clause
// Shared by the translation units of the Python module planar_grid: numpy <-> PCL and
// Eigen conversions, the result types the bindings return, and one helper that binds
// a class's parameters both as properties and as constructor keywords.
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
#include <map>
#include <memory>
#include <string>
#include <type_traits>
#include <utility>
#include <vector>

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

/** \brief Binds the parameters of \a T as read-write properties, and remembers their
 * setters so that a constructor can take them as keywords. After each assignment the
 * object's own range check runs (\a check, which returns nullptr or what is wrong): an
 * invalid value raises ValueError with that text and leaves the old value. */
template <typename T, typename Holder> class ParamBinder {
public:
  /** \brief The object's range check. */
  using Check = std::function<const char*(const T&)>;

  ParamBinder(py::class_<T, Holder>& cls, std::string class_name, Check check) :
      cls_(cls), class_name_(std::move(class_name)), check_(std::move(check))
  {}

  /** \brief Binds one parameter: \a get(const T&) returns it, \a set(T&, V) sets it. */
  template <typename V, typename Get, typename Set>
  ParamBinder& param(const char* name, Get get, Set set, const char* doc)
  {
    const Check check = check_;
    const std::string class_name = class_name_;
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
      name, [get](const T& object) { return std::invoke(get, object); }, assign, doc);
    setters_[name] = [assign](T& object, py::handle value) {
      assign(object, value.cast<V>());
    };
    getters_.emplace_back(name, [get](const T& object) {
      auto value = std::invoke(get, object);
      py::object python;
      if constexpr (std::is_base_of_v<py::handle, decltype(value)>)
        python = py::reinterpret_borrow<py::object>(value);
      else
        python = py::cast(value);
      // A numpy array as a list, which the setter takes too and repr() spells as code.
      if (py::isinstance<py::array>(python))
        python = python.attr("tolist")();
      return py::repr(python).template cast<std::string>();
    });
    return *this;
  }

  /** \brief A parameter's name and its value as Python code. */
  using Field = std::pair<std::string, std::function<std::string(const T&)>>;

  /** \brief Binds __repr__: "planar_grid.<class>(name=value, ...)" with the
   * constructor's own arguments \a leading, then every parameter bound so far, in
   * binding order: a constructor call that rebuilds the object. */
  void bindRepr(std::vector<Field> leading = {})
  {
    std::vector<Field> getters = std::move(leading);
    getters.insert(getters.end(), getters_.begin(), getters_.end());
    const std::string class_name = class_name_;
    cls_.def("__repr__", [getters, class_name](const T& object) {
      std::string text = "planar_grid." + class_name + "(";
      for (std::size_t i = 0; i < getters.size(); ++i)
        text +=
          (i == 0 ? "" : ", ") + getters[i].first + "=" + getters[i].second(object);
      return text + ")";
    });
  }

  /** \brief Applies keyword arguments through the setters; an unknown keyword is a
   * TypeError that lists the known ones. */
  static void
  apply(T& object,
        const py::kwargs& kwargs,
        const std::map<std::string, std::function<void(T&, py::handle)>>& setters,
        const std::string& class_name)
  {
    for (const auto& item : kwargs) {
      const std::string key = py::str(item.first);
      const auto it = setters.find(key);
      if (it == setters.end()) {
        std::string known;
        for (const auto& setter : setters)
          known += (known.empty() ? "" : ", ") + setter.first;
        throw py::type_error(class_name + ": unknown parameter '" + key
                             + "'; the parameters are: " + known);
      }
      it->second(object, item.second);
    }
  }

  /** \brief The setters by name (for apply()). */
  const std::map<std::string, std::function<void(T&, py::handle)>>& setters() const
  {
    return setters_;
  }

private:
  py::class_<T, Holder>& cls_;
  std::string class_name_;
  Check check_;
  std::map<std::string, std::function<void(T&, py::handle)>> setters_;
  std::vector<std::pair<std::string, std::function<std::string(const T&)>>> getters_;
};

/** \brief Binds SACMultiPlaneSegmentation, PlanarCuboidApproximation and their result
 * types. */
void bindAlgorithms(py::module_& m);
/** \brief Binds KLDivergenceOccupancyFilter and the occupancy functions of its
 * equations. */
void bindOccupancyFilter(py::module_& m);
/** \brief Binds PlanarGridMap (construction, the map file, integration, its cuboids,
 * planes and memory) and SpaceState. */
void bindMap(py::module_& m);
/** \brief Adds the point, ray, distance and collision queries to PlanarGridMap (bound
 * by bindMap()) and binds MapRegionIndex. */
void bindMapQueries(py::module_& m);
/** \brief Binds run_pipeline(), PipelineResult and stage_types(). */
void bindPipeline(py::module_& m);
/** \brief Binds Mapper, its MapReadLock and InputFrames. */
void bindMapper(py::module_& m);

} // namespace python
} // namespace planar_grid
