// SPDX-License-Identifier: BSD-3-Clause
// Ray casting in ExplicitSpaceGrid: integratePointCloud() (the free voxels along each
// ray, then the occupied voxel of each point) and castRay() (the walk to the first
// occupied voxel), both on one 3D DDA walk.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>

#include "cast_ray_check.h"
#include "explicit_space_grid_impl.h"

namespace planar_grid {

using namespace explicit_space;

namespace {

/** \brief The start of a 3D DDA walk (Amanatides and Woo) from \a o along the unit
 * direction \a d, both in voxel units: the first voxel, the step per axis, the ray
 * parameter of the first boundary crossed per axis and the parameter between two. */
struct DdaWalk {
  std::array<int, 3> key{}, step{};
  std::array<double, 3> t_max{}, t_delta{};

  DdaWalk(const Eigen::Vector3d& o, const Eigen::Vector3d& d)
  {
    for (std::size_t a = 0; a < 3; ++a) {
      const double oa = o[static_cast<Eigen::Index>(a)];
      const double da = d[static_cast<Eigen::Index>(a)];
      key[a] = static_cast<int>(std::floor(oa));
      if (da > 0.0) {
        step[a] = 1;
        t_delta[a] = 1.0 / da;
        t_max[a] = (std::floor(oa) + 1.0 - oa) / da;
      } else if (da < 0.0) {
        step[a] = -1;
        t_delta[a] = -1.0 / da;
        t_max[a] = (std::floor(oa) - oa) / da;
      } else {
        t_delta[a] = t_max[a] = std::numeric_limits<double>::infinity();
      }
    }
  }

  /** \brief The parameter where the ray enters the next voxel. */
  double next() const { return std::min({t_max[0], t_max[1], t_max[2]}); }

  /** \brief Moves to the next voxel; returns the parameter where the ray enters it. */
  double advance()
  {
    std::size_t a = 0;
    if (t_max[1] < t_max[a])
      a = 1;
    if (t_max[2] < t_max[a])
      a = 2;
    const double t = t_max[a];
    key[a] += step[a];
    t_max[a] += t_delta[a];
    return t;
  }
};

} // namespace

void
ExplicitSpaceGrid::integratePointCloud(const pcl::PointCloud<pcl::PointXYZ>& points,
                                       const Eigen::Vector3f& sensor_origin)
{
  if (!sensor_origin.allFinite())
    throw Exception("ExplicitSpaceGrid::integratePointCloud: non-finite sensor origin");
  const double res = params_.resolution_m;
  const double max_t = params_.max_range_m / res; // voxel units
  const double margin =
    (params_.surface_margin_m > 0.0 ? params_.surface_margin_m
                                    : params_.resolution_m * std::sqrt(3.0) / 2.0)
    / res;
  const Eigen::Vector3d o = sensor_origin.cast<double>() / res;
  if (o.cwiseAbs().maxCoeff() + max_t >= MAX_KEY) {
    PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integratePointCloud] Sensor origin "
              "too far from the map's origin; nothing integrated.\n");
    return;
  }
  BlockStorage& storage = impl_->storage;
  const auto prior = priorCode(params_.prior);
  const auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
  const auto occupied_code = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  BlockStorage::Cursor cursor(storage, prior);
  const auto set = [&](int kx, int ky, int kz, std::uint8_t state) {
    int i = 0;
    const std::uint32_t e = cursor.at(kx, ky, kz, i);
    const std::uint8_t current = storage.getEdit(e, i);
    // A ray passing through an occupied voxel leaves it occupied: one hit outweighs one
    // miss, as in OctoMap's sensor model (log-odds +0.85 against -0.41), and rays from
    // another scan graze floors and walls near their points.
    if (current == state || (current == occupied_code && state == free_code))
      return;
    storage.setEdit(e, i, state);
  };

  // Free: every voxel a ray crosses before its point's voxel (3D DDA, Amanatides and
  // Woo), up to max_range_m.
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d e = p.getVector3fMap().cast<double>() / res;
    const Eigen::Vector3d v = e - o;
    const double length = v.norm();
    if (!(length > 0.0))
      continue;
    const Eigen::Vector3d d = v / length;
    // A hit clears space up to the surface margin before it, as integrateDepthImage
    // does in front of the measured depth: rays that graze a surface near their own
    // point do not erase it.
    const double t_end = std::min(length - margin, max_t);
    const bool hits = length <= max_t;
    std::array<int, 3> end_key{};
    if (hits)
      end_key = {static_cast<int>(std::floor(e.x())),
                 static_cast<int>(std::floor(e.y())),
                 static_cast<int>(std::floor(e.z()))};
    DdaWalk walk(o, d);
    double t = 0.0;
    while (t <= t_end) {
      if (hits && walk.key == end_key)
        break;
      set(walk.key[0], walk.key[1], walk.key[2], free_code);
      t = walk.advance();
    }
  }
  // Occupied: the voxel of every point within range.
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d e = p.getVector3fMap().cast<double>() / res;
    if ((e - o).norm() > max_t)
      continue;
    set(static_cast<int>(std::floor(e.x())), static_cast<int>(std::floor(e.y())),
        static_cast<int>(std::floor(e.z())), occupied_code);
  }
  storage.commit(prior);
}

bool
ExplicitSpaceGrid::castRay(const Eigen::Vector3f& origin,
                           const Eigen::Vector3f& direction,
                           double max_range_m,
                           Eigen::Vector3f& hit) const
{
  checkCastRay(origin, direction, max_range_m, "ExplicitSpaceGrid::castRay");
  const double n = static_cast<double>(direction.norm());
  const double res = params_.resolution_m;
  const Eigen::Vector3d o = origin.cast<double>() / res;
  const Eigen::Vector3d d = direction.cast<double>() / n;
  const double reach = o.cwiseAbs().maxCoeff();
  if (reach >= MAX_KEY - 2.0)
    return false; // beyond every key the grid can hold: nothing stored there
  double max_t = max_range_m / res; // in voxel units; may be infinite
  impl_->storage.settle(
    priorCode(params_.prior)); // pending setState() edits (content unchanged)
  // A long walk ends where the stored super-blocks end: beyond them every voxel is
  // the prior, which (but for the occupied prior) is no hit. Their box is a few
  // hundred keys to read, where the exact bounds (getBounds()) read every block.
  constexpr double LONG_WALK_VOXELS = 4096.0;
  if (max_t > LONG_WALK_VOXELS && params_.prior != SpaceState::OCCUPIED) {
    Eigen::Vector3i lo, hi;
    if (!keyBounds(impl_->storage.supers, lo, hi))
      return false;
    constexpr int SUPER_VOXELS_SHIFT = SUPER_SHIFT + BLOCK_SHIFT;
    double t_enter = 0.0;
    double t_exit = max_t;
    for (int a = 0; a < 3; ++a) {
      const double low = std::ldexp(static_cast<double>(lo[a]), SUPER_VOXELS_SHIFT);
      const double high =
        std::ldexp(static_cast<double>(hi[a]) + 1.0, SUPER_VOXELS_SHIFT);
      if (d[a] == 0.0) {
        if (o[a] < low || o[a] >= high)
          return false;
        continue;
      }
      double ta = (low - o[a]) / d[a], tb = (high - o[a]) / d[a];
      if (ta > tb)
        std::swap(ta, tb);
      t_enter = std::max(t_enter, ta);
      t_exit = std::min(t_exit, tb);
    }
    if (t_enter > t_exit)
      return false;
    max_t = t_exit;
  }
  // The walk never leaves the keys the grid can hold.
  max_t = std::min(max_t, MAX_KEY - 2.0 - reach);
  DdaWalk walk(o, d);
  const auto occupied = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  const bool prior_occupied = params_.prior == SpaceState::OCCUPIED;
  BlockKey cached_key{0, 0, 0}; // super-block coordinates
  const SuperBlock* cached = nullptr;
  bool cached_valid = false;
  while (true) {
    const std::array<int, 3>& key = walk.key;
    const BlockKey bk{blockOf(key[0]), blockOf(key[1]), blockOf(key[2])};
    const BlockKey sk = BlockStorage::superOf(bk);
    if (!cached_valid || !(sk == cached_key)) {
      cached = impl_->storage.findSuper(sk);
      cached_key = sk;
      cached_valid = true;
    }
    const bool occ = cached
                       ? cached->get(BlockStorage::indexInSuper(bk), localOf(key[0]),
                                     localOf(key[1]), localOf(key[2]))
                           == occupied
                       : prior_occupied;
    if (occ) {
      hit = toCentre(VoxelKey(key[0], key[1], key[2]));
      return true;
    }
    if (walk.next() > max_t)
      return false;
    walk.advance();
  }
}

} // namespace planar_grid
