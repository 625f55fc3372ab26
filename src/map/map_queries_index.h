// SPDX-License-Identifier: BSD-3-Clause
// The obstacle index of the planner's queries of PlanarGridMap (private to the map
// module): the obstacles (occupied cuboids as oriented boxes, obstacle voxels merged
// into axis-aligned boxes per block) and their bounding-volume hierarchy. Built in
// map_queries_index.cpp, queried in map_queries.cpp.
#pragma once

#include <planar_grid/map/planar_grid_map.h>

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <array>
#include <atomic>
#include <cstdint>
#include <memory>
#include <mutex>
#include <vector>

namespace planar_grid {
namespace map_queries {

/** \brief One obstacle: a box of half extents \a half about \a centre along the
 * columns of \a axes (identity for voxel runs, flagged by \a aligned). */
struct ObstacleBox {
  Eigen::Matrix3f axes{Eigen::Matrix3f::Identity()};
  Eigen::Vector3f centre{Eigen::Vector3f::Zero()};
  Eigen::Vector3f half{Eigen::Vector3f::Zero()};
  bool aligned{true};

  /** \brief p in the box frame, relative to the centre. */
  Eigen::Vector3f local(const Eigen::Vector3f& p) const
  {
    const Eigen::Vector3f d = p - centre;
    return aligned ? d : Eigen::Vector3f(axes.transpose() * d);
  }
  /** \brief The world vector of a vector \a v given in the box frame. */
  Eigen::Vector3f world(const Eigen::Vector3f& v) const
  {
    return aligned ? v : Eigen::Vector3f(axes * v);
  }
  /** \brief Half extents of the axis-aligned bounding box. */
  Eigen::Vector3f aabbHalf() const
  {
    return aligned ? half : Eigen::Vector3f(axes.cwiseAbs() * half);
  }
};

/** \brief Node of the hierarchy: a leaf holds count > 0 boxes from first; an inner
 * node (count 0) has its left child next in the array and its right child at first.
 */
struct Node {
  Eigen::Vector3f lo;
  Eigen::Vector3f hi;
  std::uint32_t first{0};
  std::uint32_t count{0};
};

/** \brief The obstacles of one query mode and their hierarchy. */
struct ObstacleIndex {
  std::vector<ObstacleBox, Eigen::aligned_allocator<ObstacleBox>> boxes;
  std::vector<Node> nodes;
  /** \brief Space outside [known_lo, known_hi] is an obstacle (unknown). */
  bool outside_is_obstacle{false};
  /** \brief With outside_is_obstacle and nothing stored: everything is. */
  bool everything_is_obstacle{false};
  Eigen::Vector3f known_lo{Eigen::Vector3f::Zero()};
  Eigen::Vector3f known_hi{Eigen::Vector3f::Zero()};
};

/** \brief The lazily built indices, one per unknown_is_occupied. */
struct QueryCache {
  std::mutex mutex;
  std::array<std::atomic<bool>, 2> ready{{false, false}};
  std::array<std::unique_ptr<ObstacleIndex>, 2> index;
};

/** \brief Gathers the obstacles of \a map for one mode. */
std::unique_ptr<ObstacleIndex> buildIndex(const PlanarGridMap& map,
                                          bool unknown_is_occupied,
                                          const Eigen::AlignedBox3f* keep = nullptr);

} // namespace map_queries
} // namespace planar_grid
