// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/map/map_queries.h>

#include <Eigen/Core>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <vector>

namespace planar_grid {

class PlanarGridMap;

namespace map_queries {
struct ObstacleIndex;
} // namespace map_queries

/** \brief The distance and collision queries of PlanarGridMap over one region (a
 * planner's local window, as a distance transform is built over a bounding box):
 * only the obstacles whose bounding box meets the region grown by max_distance_m are
 * indexed, so building it costs what the region holds, not the whole map. Inside the
 * region the answers are those of PlanarGridMap::getDistance() and
 * isCollisionFree() (the same obstacles, the same exact geometry). The index is a
 * snapshot: later changes of the map are not seen. Const methods are safe from
 * several threads. \ingroup map */
class MapRegionIndex {
public:
  /** \brief Indexes the obstacles of \a map near [min_m, max_m].
   * \param[in] map the map (read once; not kept)
   * \param[in] min_m, max_m the region's corners, meters (min_m < max_m)
   * \param[in] max_distance_m the distance cap, meters (> 0)
   * \param[in] unknown_is_occupied count unknown space as an obstacle
   * \throws planar_grid::Exception for an empty or non-finite region or a bad cap */
  MapRegionIndex(const PlanarGridMap& map,
                 const Eigen::Vector3f& min_m,
                 const Eigen::Vector3f& max_m,
                 double max_distance_m,
                 bool unknown_is_occupied = false);
  ~MapRegionIndex();
  /** \brief Takes over the other index (which may then only be destroyed or assigned
   * to). */
  MapRegionIndex(MapRegionIndex&&) noexcept;
  /** \brief Takes over the other index (which may then only be destroyed or assigned
   * to). */
  MapRegionIndex& operator=(MapRegionIndex&&) noexcept;
  MapRegionIndex(const MapRegionIndex&) = delete;
  MapRegionIndex& operator=(const MapRegionIndex&) = delete;

  /** \brief PlanarGridMap::getDistance() with the index's cap, for points inside the
   * region; a point outside it (or non-finite) gives NaN.
   * \throws planar_grid::Exception when the outputs' sizes do not match \a points */
  void getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                   Eigen::Ref<Eigen::VectorXf> distances,
                   Eigen::Ref<Eigen::Matrix3Xf> gradients) const;

  /** \brief PlanarGridMap::isCollisionFree() for bodies whose bounding box lies inside
   * the region grown by the cap; a body reaching beyond it is reported in collision
   * (0), as is a non-finite one. */
  std::vector<std::uint8_t> isCollisionFree(const CollisionBodies& bodies) const;

  /** \brief Number of obstacle boxes indexed. */
  [[nodiscard]] std::size_t getObstacleCount() const;

private:
  std::unique_ptr<map_queries::ObstacleIndex> index_;
  Eigen::Vector3f min_;
  Eigen::Vector3f max_;
  float max_distance_m_;
};

} // namespace planar_grid
