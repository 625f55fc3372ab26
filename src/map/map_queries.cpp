// SPDX-License-Identifier: BSD-3-Clause
// The planner's queries of PlanarGridMap: distance with gradient and collision of
// bodies, answered from the obstacle index (map_queries_index.h) built on the first
// query.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "map_queries_index.h"

namespace planar_grid {
namespace map_queries {

namespace {

/** \brief Squared distance from \a p to the box [lo, hi]. */
float
aabbDistance2(const Eigen::Vector3f& p,
              const Eigen::Vector3f& lo,
              const Eigen::Vector3f& hi)
{
  const Eigen::Vector3f d = (lo - p).cwiseMax(Eigen::Vector3f::Zero()).cwiseMax(p - hi);
  return d.squaredNorm();
}

/** \brief Distance from \a p to box \a b; 0 inside with \a grad the outward normal of
 * the nearest face, else \a grad from the closest point toward \a p. */
float
boxDistance(const ObstacleBox& b, const Eigen::Vector3f& p, Eigen::Vector3f& grad)
{
  const Eigen::Vector3f q = b.local(p);
  const Eigen::Vector3f d = q.cwiseAbs() - b.half;
  if ((d.array() <= 0.0f).all()) {
    int axis = 0;
    d.maxCoeff(&axis);
    Eigen::Vector3f n = Eigen::Vector3f::Zero();
    n[axis] = q[axis] < 0.0f ? -1.0f : 1.0f;
    grad = b.world(n);
    return 0.0f;
  }
  Eigen::Vector3f e;
  for (int k = 0; k < 3; ++k)
    e[k] = d[k] > 0.0f ? std::copysign(d[k], q[k]) : 0.0f;
  const float dist = e.norm();
  grad = b.world(e / dist);
  return dist;
}

/** \brief Exact overlap (closed sets) of an oriented box A (centre, axes, half) and
 * obstacle box B: the 15 separating axes. */
bool
boxesOverlap(const Eigen::Vector3f& ca,
             const Eigen::Matrix3f& ra,
             const Eigen::Vector3f& ha,
             const ObstacleBox& b)
{
  // B's axes and centre in A's frame.
  const Eigen::Matrix3f rb = b.aligned ? Eigen::Matrix3f::Identity() : b.axes;
  const Eigen::Matrix3f R = ra.transpose() * rb;
  const Eigen::Vector3f t = ra.transpose() * (b.centre - ca);
  // A small term keeps near-parallel edge pairs (whose cross product vanishes) from
  // reporting a separation that rounding made up.
  const Eigen::Matrix3f absR = R.cwiseAbs().array() + 1e-6f;
  const Eigen::Vector3f& hb = b.half;
  for (int i = 0; i < 3; ++i)
    if (std::abs(t[i]) > ha[i] + absR.row(i).dot(hb))
      return false;
  for (int j = 0; j < 3; ++j)
    if (std::abs(t.dot(R.col(j))) > absR.col(j).dot(ha) + hb[j])
      return false;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const float ra_ = ha[i1] * absR(i2, j) + ha[i2] * absR(i1, j);
      const float rb_ = hb[j1] * absR(i, j2) + hb[j2] * absR(i, j1);
      if (std::abs(t[i2] * R(i1, j) - t[i1] * R(i2, j)) > ra_ + rb_)
        return false;
    }
  }
  return true;
}

/** \brief Distance and gradient at one point (finite), capped at \a cap. */
float
queryPoint(const ObstacleIndex& index,
           const Eigen::Vector3f& p,
           float cap,
           Eigen::Vector3f& grad)
{
  grad.setZero();
  if (index.everything_is_obstacle) {
    grad = Eigen::Vector3f::UnitZ();
    return 0.0f;
  }
  float best = cap;
  if (index.outside_is_obstacle) {
    const Eigen::Vector3f below = p - index.known_lo, above = index.known_hi - p;
    if ((below.array() < 0.0f).any() || (above.array() < 0.0f).any()) {
      // Outside the stored bounds: inside the unknown; the way out is toward them.
      const Eigen::Vector3f in =
        p.cwiseMax(index.known_lo).cwiseMin(index.known_hi) - p;
      grad = in / in.norm();
      return 0.0f;
    }
    int a = 0, c = 0;
    const float from_lo = below.minCoeff(&a), from_hi = above.minCoeff(&c);
    if (std::min(from_lo, from_hi) < best) {
      grad.setZero();
      if (from_lo <= from_hi) {
        best = from_lo;
        grad[a] = 1.0f;
      } else {
        best = from_hi;
        grad[c] = -1.0f;
      }
    }
  }
  if (index.nodes.empty())
    return best;
  float best2 = best * best;
  std::array<std::uint32_t, 128> stack;
  std::size_t top = 0;
  if (aabbDistance2(p, index.nodes[0].lo, index.nodes[0].hi) >= best2)
    return best;
  stack[top++] = 0;
  Eigen::Vector3f g;
  while (top > 0) {
    const Node& node = index.nodes[stack[--top]];
    if (aabbDistance2(p, node.lo, node.hi) >= best2)
      continue;
    if (node.count > 0) {
      for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
        const float d = boxDistance(index.boxes[k], p, g);
        if (d == 0.0f) {
          grad = g;
          return 0.0f;
        }
        if (d < best) {
          best = d;
          best2 = d * d;
          grad = g;
        }
      }
      continue;
    }
    const std::uint32_t left =
      static_cast<std::uint32_t>(&node - index.nodes.data()) + 1;
    const std::uint32_t right = node.first;
    const float dl = aabbDistance2(p, index.nodes[left].lo, index.nodes[left].hi);
    const float dr = aabbDistance2(p, index.nodes[right].lo, index.nodes[right].hi);
    // The nearer child is popped first.
    if (dl <= dr) {
      if (dr < best2)
        stack[top++] = right;
      if (dl < best2)
        stack[top++] = left;
    } else {
      if (dl < best2)
        stack[top++] = left;
      if (dr < best2)
        stack[top++] = right;
    }
  }
  return best;
}

/** \brief True when the body meets an obstacle of the index. */
bool
bodyCollides(const ObstacleIndex& index, const CollisionBody& body)
{
  if (index.everything_is_obstacle)
    return true;
  const bool is_box = body.shape == CollisionBody::Shape::BOX;
  const Eigen::Vector3f h =
    is_box ? Eigen::Vector3f(body.rotation.cwiseAbs() * body.half_extents)
           : Eigen::Vector3f::Constant(body.radius_m);
  const Eigen::Vector3f lo = body.centre - h, hi = body.centre + h;
  if (index.outside_is_obstacle
      && ((lo.array() < index.known_lo.array()).any()
          || (hi.array() > index.known_hi.array()).any()))
    return true;
  if (index.nodes.empty())
    return false;
  const float r2 = body.radius_m * body.radius_m;
  std::array<std::uint32_t, 128> stack;
  std::size_t top = 0;
  stack[top++] = 0;
  Eigen::Vector3f g;
  while (top > 0) {
    const std::uint32_t id = stack[--top];
    const Node& node = index.nodes[id];
    if ((node.lo.array() > hi.array()).any() || (node.hi.array() < lo.array()).any())
      continue;
    if (!is_box && aabbDistance2(body.centre, node.lo, node.hi) > r2)
      continue;
    if (node.count == 0) {
      stack[top++] = node.first;
      stack[top++] = id + 1;
      continue;
    }
    for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
      const ObstacleBox& b = index.boxes[k];
      if (is_box) {
        if (boxesOverlap(body.centre, body.rotation, body.half_extents, b))
          return true;
      } else if (boxDistance(b, body.centre, g) <= body.radius_m)
        return true;
    }
  }
  return false;
}

} // namespace

/** \brief Distances of the points at the index (NaN for non-finite points and, with
 * \a region, points outside it). */
void
distancesOf(const ObstacleIndex& index,
            const Eigen::Ref<const Eigen::Matrix3Xf>& points,
            float cap,
            Eigen::Ref<Eigen::VectorXf> distances,
            Eigen::Ref<Eigen::Matrix3Xf> gradients,
            const Eigen::AlignedBox3f* region)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3f p = points.col(i);
    if (!p.allFinite() || (region != nullptr && !region->contains(p))) {
      distances[i] = nan;
      gradients.col(i).setConstant(nan);
      continue;
    }
    Eigen::Vector3f g;
    distances[i] = queryPoint(index, p, cap, g);
    gradients.col(i) = g;
  }
}

/** \brief Free (1) or not (0) per body; with \a region, bodies whose bounding box
 * leaves it are not free. */
std::vector<std::uint8_t>
collisionsOf(const ObstacleIndex& index,
             const CollisionBodies& bodies,
             const Eigen::AlignedBox3f* region)
{
  std::vector<std::uint8_t> free(bodies.size(), 0);
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const CollisionBody& b = bodies[i];
    const bool is_box = b.shape == CollisionBody::Shape::BOX;
    const bool valid = b.centre.allFinite()
                       && (is_box ? b.rotation.allFinite() && b.half_extents.allFinite()
                                      && (b.half_extents.array() >= 0.0f).all()
                                  : std::isfinite(b.radius_m) && b.radius_m >= 0.0f);
    if (!valid)
      continue;
    if (region != nullptr) {
      const Eigen::Vector3f h =
        is_box ? Eigen::Vector3f(b.rotation.cwiseAbs() * b.half_extents)
               : Eigen::Vector3f::Constant(b.radius_m);
      if (!region->contains(b.centre - h) || !region->contains(b.centre + h))
        continue;
    }
    free[i] = bodyCollides(index, b) ? 0 : 1;
  }
  return free;
}

void
checkSizes(const char* what,
           Eigen::Index points,
           Eigen::Index distances,
           Eigen::Index gradients)
{
  if (distances != points || gradients != points)
    throw Exception(std::string(what) + ": " + std::to_string(points)
                    + " points but room for " + std::to_string(distances)
                    + " distances and " + std::to_string(gradients) + " gradients");
}

const ObstacleIndex&
getIndex(const std::shared_ptr<QueryCache>& cache,
         const PlanarGridMap& map,
         bool unknown_is_occupied)
{
  if (!cache)
    throw Exception("PlanarGridMap: query on a moved-from map");
  const std::size_t mode = unknown_is_occupied ? 1 : 0;
  if (!cache->ready[mode].load(std::memory_order_acquire)) {
    std::lock_guard<std::mutex> lock(cache->mutex);
    if (!cache->index[mode]) {
      cache->index[mode] = buildIndex(map, unknown_is_occupied);
      cache->ready[mode].store(true, std::memory_order_release);
    }
  }
  return *cache->index[mode];
}

} // namespace map_queries

void
PlanarGridMap::invalidateQueryCache()
{
  query_cache_ = std::make_shared<map_queries::QueryCache>();
}

void
PlanarGridMap::getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                           double max_distance_m,
                           Eigen::Ref<Eigen::VectorXf> distances,
                           Eigen::Ref<Eigen::Matrix3Xf> gradients,
                           bool unknown_is_occupied) const
{
  if (!(max_distance_m > 0.0) || !std::isfinite(max_distance_m))
    throw Exception(
      "PlanarGridMap::getDistance: max_distance_m must be finite and > 0, "
      "got "
      + std::to_string(max_distance_m));
  map_queries::checkSizes("PlanarGridMap::getDistance", points.cols(), distances.size(),
                          gradients.cols());
  const auto& index = map_queries::getIndex(query_cache_, *this, unknown_is_occupied);
  map_queries::distancesOf(index, points, static_cast<float>(max_distance_m), distances,
                           gradients, nullptr);
}

std::vector<std::uint8_t>
PlanarGridMap::isCollisionFree(const CollisionBodies& bodies,
                               bool unknown_is_occupied) const
{
  const auto& index = map_queries::getIndex(query_cache_, *this, unknown_is_occupied);
  return map_queries::collisionsOf(index, bodies, nullptr);
}

MapRegionIndex::MapRegionIndex(const PlanarGridMap& map,
                               const Eigen::Vector3f& min_m,
                               const Eigen::Vector3f& max_m,
                               double max_distance_m,
                               bool unknown_is_occupied) :
    min_(min_m),
    max_(max_m), max_distance_m_(static_cast<float>(max_distance_m))
{
  if (!min_m.allFinite() || !max_m.allFinite()
      || !(max_m.array() > min_m.array()).all())
    throw Exception("MapRegionIndex: the region needs finite corners min_m < max_m");
  if (!(max_distance_m > 0.0) || !std::isfinite(max_distance_m))
    throw Exception("MapRegionIndex: max_distance_m must be finite and > 0, got "
                    + std::to_string(max_distance_m));
  const Eigen::AlignedBox3f keep(min_m - Eigen::Vector3f::Constant(max_distance_m_),
                                 max_m + Eigen::Vector3f::Constant(max_distance_m_));
  index_ = map_queries::buildIndex(map, unknown_is_occupied, &keep);
}

MapRegionIndex::~MapRegionIndex() = default;
MapRegionIndex::MapRegionIndex(MapRegionIndex&&) noexcept = default;
MapRegionIndex& MapRegionIndex::operator=(MapRegionIndex&&) noexcept = default;

void
MapRegionIndex::getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                            Eigen::Ref<Eigen::VectorXf> distances,
                            Eigen::Ref<Eigen::Matrix3Xf> gradients) const
{
  map_queries::checkSizes("MapRegionIndex::getDistance", points.cols(),
                          distances.size(), gradients.cols());
  const Eigen::AlignedBox3f region(min_, max_);
  map_queries::distancesOf(*index_, points, max_distance_m_, distances, gradients,
                           &region);
}

std::vector<std::uint8_t>
MapRegionIndex::isCollisionFree(const CollisionBodies& bodies) const
{
  const Eigen::AlignedBox3f grown(min_ - Eigen::Vector3f::Constant(max_distance_m_),
                                  max_ + Eigen::Vector3f::Constant(max_distance_m_));
  return map_queries::collisionsOf(*index_, bodies, &grown);
}

std::size_t
MapRegionIndex::getObstacleCount() const
{
  return index_->boxes.size();
}

} // namespace planar_grid
