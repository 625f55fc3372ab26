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
#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {
class PlanarGridMap;
enum class SpaceState : std::uint8_t;
} // namespace planar_grid

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

/** \brief A state given as SpaceState, int (0 free, 1 occupied, 2 unknown) or name.
 * \throws py::value_error for another value */
SpaceState toSpaceState(const py::handle& state);

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

/** \brief \a text wrapped at word boundaries into lines of at most \a width characters
 * after \a indent spaces (docstrings). */
std::string wrapText(const std::string& text, std::size_t indent, std::size_t width);

/** \brief Binds SACMultiPlaneSegmentation, PlanarCuboidApproximation and their result
 * types. */
void bindAlgorithms(py::module_& m);
/** \brief Binds TerrainRemoval. */
void bindTerrainRemoval(py::module_& m);
/** \brief Binds KLDivergenceOccupancyFilter and the occupancy functions of its
 * equations. */
void bindOccupancyFilter(py::module_& m);
/** \brief Binds PlanarGridMap (construction, the map file, merging, its cuboids,
 * planes and memory, export) and SpaceState. */
void bindMap(py::module_& m);
/** \brief Adds the integration methods (point clouds, depth images, surfaces, whole
 * frames, voxel states) to PlanarGridMap (bound by bindMap()). */
void bindMapIntegration(py::module_& m);
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
