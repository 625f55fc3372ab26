// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/console/print.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <iomanip>
#include <iterator>
#include <limits>
#include <unordered_set>
#include <utility>

#include "cast_ray_check.h"
#include "octomap_writer.h"
#include "surface_layer_impl.h"

namespace planar_grid {

namespace {

/** OctoMap's default clamping bounds, the probabilities of a known voxel. */
constexpr float PROB_OCCUPIED_VOXEL = 0.971f;
constexpr float PROB_FREE_VOXEL = 0.1192f;

/** Share of a merged non-planar box the merged cells fill (mergeNonPlanarCells()). */
constexpr double NON_PLANAR_MERGE_MIN_FILL = 0.8;

/** True when both axes of \a cuboid are (up to float rounding) world axes. */
bool
hasWorldAxes(const PlanarCuboid& cuboid)
{
  constexpr float TOLERANCE = 1e-5f;
  return std::abs(cuboid.normal.cwiseAbs().maxCoeff() - 1.0f) < TOLERANCE
         && std::abs(cuboid.horizontal_axis.cwiseAbs().maxCoeff() - 1.0f) < TOLERANCE;
}

/** Snaps a cuboid with world axes to the voxel lattice of edge \a resolution_m: each
 * bound to the nearest multiple of it, at least one cell (the centre's) along each
 * axis. */
void
snapToLattice(PlanarCuboid& cuboid, float resolution_m)
{
  Eigen::Vector3f lo, hi;
  surface_layer_detail::cuboidBounds(cuboid, lo, hi);
  lo = (lo / resolution_m).array().round();
  hi = (hi / resolution_m).array().round();
  for (int i = 0; i < 3; ++i)
    if (hi[i] <= lo[i]) {
      lo[i] = std::floor(cuboid.centre[i] / resolution_m);
      hi[i] = lo[i] + 1.0f;
    }
  lo *= resolution_m;
  hi *= resolution_m;
  cuboid.centre = 0.5f * (lo + hi);
  const Eigen::Vector3f size = hi - lo;
  cuboid.width_m = std::abs(cuboid.horizontal_axis.dot(size));
  cuboid.height_m = std::abs(cuboid.verticalAxis().dot(size));
  cuboid.thickness_m = std::abs(cuboid.normal.dot(size));
}

/** Bounds of the cuboid probabilities written to OctoMap as log-odds (finite). */
constexpr float MIN_EXPORTED_PROBABILITY = 1e-4f;

/** Calls f(key) for every voxel (edge \a resolution_m, key floor(p / resolution_m))
 * whose centre lies in \a cuboid (PlanarCuboid::contains). The voxels are walked in
 * columns along the axis where the cuboid's bounding box is longest, each column
 * clipped to the box's three slabs, so a thin tilted cuboid costs its own voxels plus
 * the columns of its footprint, not its bounding box. */
template <typename F>
void
forEachVoxelInCuboid(const PlanarCuboid& cuboid, double resolution_m, F&& f)
{
  const auto corners = cuboid.corners();
  Eigen::Vector3d lo = corners[0].cast<double>(), hi = lo;
  for (const auto& c : corners) {
    lo = lo.cwiseMin(c.cast<double>());
    hi = hi.cwiseMax(c.cast<double>());
  }
  if (!lo.allFinite() || !hi.allFinite())
    return;
  // Keys whose centres (k + 0.5) resolution_m lie in [lo, hi].
  const Eigen::Vector3i k_lo =
    (lo / resolution_m - Eigen::Vector3d::Constant(0.5)).array().ceil().cast<int>();
  const Eigen::Vector3i k_hi =
    (hi / resolution_m - Eigen::Vector3d::Constant(0.5)).array().floor().cast<int>();
  if ((k_hi.array() < k_lo.array()).any())
    return;
  int a = 0; // the column axis
  for (int i = 1; i < 3; ++i)
    if (k_hi[i] - k_lo[i] > k_hi[a] - k_lo[a])
      a = i;
  const int b = (a + 1) % 3, c = (a + 2) % 3;
  const std::array<Eigen::Vector3d, 3> axes{cuboid.horizontal_axis.cast<double>(),
                                            cuboid.verticalAxis().cast<double>(),
                                            cuboid.normal.cast<double>()};
  // Half-extents with a slack above float rounding at map coordinates (contains() is
  // in float): the column is clipped a little wide, and contains() decides.
  constexpr double SLACK_M = 1e-4;
  const std::array<double, 3> half{0.5 * cuboid.width_m + SLACK_M,
                                   0.5 * cuboid.height_m + SLACK_M,
                                   0.5 * cuboid.thickness_m + SLACK_M};
  const Eigen::Vector3d centre = cuboid.centre.cast<double>();
  Eigen::Vector3i key;
  for (int kb = k_lo[b]; kb <= k_hi[b]; ++kb)
    for (int kc = k_lo[c]; kc <= k_hi[c]; ++kc) {
      // The column's line: p(t) = q + t e_a, t the coordinate along axis a.
      Eigen::Vector3d q = Eigen::Vector3d::Zero();
      q[b] = (kb + 0.5) * resolution_m;
      q[c] = (kc + 0.5) * resolution_m;
      double t0 = lo[a], t1 = hi[a];
      for (std::size_t s = 0; s < 3 && t0 <= t1; ++s) {
        const double d0 = (q - centre).dot(axes[s]); // with t = 0
        const double da = axes[s][a];
        if (std::abs(da) < 1e-12) {
          if (std::abs(d0) > half[s])
            t1 = t0 - 1.0;
          continue;
        }
        const double u = (-half[s] - d0) / da, v = (half[s] - d0) / da;
        t0 = std::max(t0, std::min(u, v));
        t1 = std::min(t1, std::max(u, v));
      }
      if (!(t0 <= t1))
        continue;
      // One voxel of slack on each side; contains() (in float, as findCuboid) decides.
      const int from =
        std::max(k_lo[a], static_cast<int>(std::ceil(t0 / resolution_m - 0.5)) - 1);
      const int to =
        std::min(k_hi[a], static_cast<int>(std::floor(t1 / resolution_m - 0.5)) + 1);
      key[b] = kb;
      key[c] = kc;
      for (int ka = from; ka <= to; ++ka) {
        key[a] = ka;
        const Eigen::Vector3f p =
          ((key.cast<double>().array() + 0.5) * resolution_m).cast<float>();
        if (cuboid.contains(p))
          f(key);
      }
    }
}

/** \a params with the map's resolution_m in both layers (their cells are one size,
 * the paper's minimum cell); the layers' constructors check its range. */
PlanarGridMap::Params
withSharedResolution(const PlanarGridMap::Params& params)
{
  PlanarGridMap::Params shared = params;
  shared.space.resolution_m = params.resolution_m;
  shared.surface.resolution_m = params.resolution_m;
  return shared;
}

} // namespace

PlanarGridMap::PlanarGridMap(const Params& params) :
    params_(withSharedResolution(params)), surface_(params_.surface),
    space_(params_.space)
{
  if (!planar_grid_map_ranges::NON_PLANAR_MIN_OCCUPIED.contains(
        params_.non_planar_min_occupied))
    throw Exception("PlanarGridMap: invalid parameter "
                    + paramRangeMessage("non_planar_min_occupied",
                                        planar_grid_map_ranges::NON_PLANAR_MIN_OCCUPIED)
                    + ", got " + formatParamNumber(params_.non_planar_min_occupied));
  invalidateQueryCache();
}

void
PlanarGridMap::integrateDepthImage(const DepthImage& depth,
                                   const Eigen::Isometry3d& world_T_camera)
{
  invalidateQueryCache();
  space_.integrateDepthImage(depth, world_T_camera);
  const bool merge_non_planar =
    params_.merge_non_planar && params_.non_planar_min_occupied > 0.0;
  if (!(params_.clear_non_planar || params_.clear_planar || merge_non_planar)
      || depth.width <= 0 || depth.height <= 0 || !(depth.fx > 0.0f)
      || !(depth.fy > 0.0f))
    return;
  const Eigen::Isometry3f camera_T_world = world_T_camera.inverse().cast<float>();
  const auto max_range = static_cast<float>(params_.space.max_range_m);
  const auto width = static_cast<float>(depth.width);
  const auto height = static_cast<float>(depth.height);
  const auto in_view = [&](const Eigen::Vector3f& centre, float radius) {
    const Eigen::Vector3f p = camera_T_world * centre;
    if (p.z() < -radius || p.z() - radius > max_range)
      return false;
    if (p.z() <= radius)
      return true; // the sphere reaches the camera's plane: tested
    // The sphere's image lies within its centre's projection +- f r / (z - r).
    const float inv_z = 1.0f / p.z();
    const float reach = radius / (p.z() - radius);
    const float u = depth.fx * p.x() * inv_z + depth.cx;
    const float v = depth.fy * p.y() * inv_z + depth.cy;
    return u >= -depth.fx * reach && u <= width + depth.fx * reach
           && v >= -depth.fy * reach && v <= height + depth.fy * reach;
  };
  if (params_.clear_non_planar)
    clearNonPlanarCells(in_view, params_.non_planar_min_occupied);
  if (merge_non_planar)
    mergeNonPlanarCells(in_view);
  if (params_.clear_planar)
    clearPlanarCells(in_view, world_T_camera.translation().cast<float>());
}

void
PlanarGridMap::integratePointCloud(const pcl::PointCloud<pcl::PointXYZ>& points,
                                   const Eigen::Vector3f& sensor_origin)
{
  invalidateQueryCache();
  space_.integratePointCloud(points, sensor_origin);
  if (!(params_.clear_non_planar || params_.clear_planar) || !sensor_origin.allFinite())
    return;
  const auto max_range = static_cast<float>(params_.space.max_range_m);
  const auto in_view = [&](const Eigen::Vector3f& centre, float radius) {
    return (centre - sensor_origin).norm() - radius <= max_range;
  };
  // A scan's reach is a ball, not a frustum: a cell beside its rays is no more
  // observed than one behind a surface, so only the free rule applies.
  if (params_.clear_non_planar)
    clearNonPlanarCells(in_view, 0.0);
  if (params_.clear_planar)
    clearPlanarCells(in_view, sensor_origin);
}

void
PlanarGridMap::integrateSurface(const PlanarCuboids& cuboids,
                                const PlaneModels& planes,
                                const pcl::PointCloud<pcl::PointXYZ>& features,
                                const std::vector<float>& probabilities)
{
  invalidateQueryCache();
  if (params_.merge_non_planar) {
    PlanarCuboids snapped = cuboids;
    const auto r = static_cast<float>(params_.resolution_m);
    for (PlanarCuboid& cuboid : snapped)
      if (!cuboid.is_planar && hasWorldAxes(cuboid) && cuboid.centre.allFinite())
        snapToLattice(cuboid, r);
    surface_.integrate(snapped, planes, features, probabilities);
  } else {
    surface_.integrate(cuboids, planes, features, probabilities);
  }
  if (params_.planes_absorb_overlapping)
    surface_.absorbOverlappingPlaneCells();
  if (params_.planes_replace_non_planar)
    removeNonPlanarCellsOnPlanes();
}

std::size_t
PlanarGridMap::clearPlanarCells(
  const std::function<bool(const Eigen::Vector3f&, float)>& in_view,
  const Eigen::Vector3f& sensor_origin)
{
  invalidateQueryCache();
  const auto r = static_cast<float>(params_.resolution_m);
  // A surface seen at a grazing angle lets the views' free space reach a cell's
  // voxels beside it; only views within 60 degrees of the normal test a cell.
  constexpr float MIN_COS_VIEW_ANGLE = 0.5f;
  return surface_.removePlaneCells(
    [&](const Eigen::Vector3f& centre, const Eigen::Vector3f& normal) {
      if (!in_view(centre, r))
        return false;
      const Eigen::Vector3f to_sensor = sensor_origin - centre;
      if (std::abs(to_sensor.dot(normal)) < MIN_COS_VIEW_ANGLE * to_sensor.norm())
        return false;
      for (int k = 0; k <= 2; ++k)
        if (space_.getState(space_.toKey(Eigen::Vector3f(centre - normal * (r * k))))
            != SpaceState::FREE)
          return false;
      return true;
    });
}

std::size_t
PlanarGridMap::clearNonPlanarCells(
  const std::function<bool(const Eigen::Vector3f&, float)>& in_view)
{
  return clearNonPlanarCells(in_view, params_.non_planar_min_occupied);
}

std::size_t
PlanarGridMap::clearNonPlanarCells(
  const std::function<bool(const Eigen::Vector3f&, float)>& in_view,
  double min_occupied)
{
  invalidateQueryCache();
  return surface_.removeNonPlanarCells([&](const PlanarCuboid& cuboid) {
    if (!cuboidInView(cuboid, in_view))
      return false;
    return !voxelShares(cuboid).heldOccupied(min_occupied);
  });
}

std::size_t
PlanarGridMap::mergeNonPlanarCells(
  const std::function<bool(const Eigen::Vector3f&, float)>& in_view)
{
  invalidateQueryCache();
  const double min_occupied = params_.non_planar_min_occupied;
  return surface_.mergeNonPlanarCells(
    [&](const PlanarCuboid& cuboid) { return cuboidInView(cuboid, in_view); },
    [&](const PlanarCuboid& box) {
      return voxelShares(box).heldOccupied(min_occupied);
    },
    NON_PLANAR_MERGE_MIN_FILL);
}

bool
PlanarGridMap::cuboidInView(
  const PlanarCuboid& cuboid,
  const std::function<bool(const Eigen::Vector3f&, float)>& in_view) const
{
  // A voxel tested lies within a voxel diagonal of the cell (its centre's voxel), and
  // a view may mark a voxel whose centre is outside the view.
  const auto voxel_diagonal = static_cast<float>(std::sqrt(3.0) * params_.resolution_m);
  const float radius =
    0.5f
      * std::sqrt(cuboid.width_m * cuboid.width_m + cuboid.height_m * cuboid.height_m
                  + cuboid.thickness_m * cuboid.thickness_m)
    + voxel_diagonal;
  return in_view(cuboid.centre, radius);
}

PlanarGridMap::VoxelShares
PlanarGridMap::voxelShares(const PlanarCuboid& cuboid) const
{
  const ExplicitSpaceGrid::VoxelKey centre_key = space_.toKey(cuboid.centre);
  VoxelShares shares;
  shares.voxels = 1;
  const SpaceState centre_state = space_.getState(centre_key);
  shares.free = centre_state == SpaceState::FREE ? 1 : 0;
  shares.occupied = centre_state == SpaceState::OCCUPIED ? 1 : 0;
  forEachVoxelInCuboid(cuboid, params_.resolution_m, [&](const Eigen::Vector3i& key) {
    if (key == centre_key)
      return;
    ++shares.voxels;
    const SpaceState state = space_.getState(key);
    shares.free += state == SpaceState::FREE ? 1 : 0;
    shares.occupied += state == SpaceState::OCCUPIED ? 1 : 0;
  });
  return shares;
}

SpaceState
PlanarGridMap::getState(const Eigen::Vector3f& point) const
{
  if (const PlanarCuboid* cuboid = surface_.findCuboid(point))
    return cuboid->probability >= params_.surface.occupancy_thres ? SpaceState::OCCUPIED
                                                                  : SpaceState::FREE;
  return space_.getState(point);
}

float
PlanarGridMap::getOccupancy(const Eigen::Vector3f& point) const
{
  if (const PlanarCuboid* cuboid = surface_.findCuboid(point))
    return cuboid->probability;
  switch (space_.getState(point)) {
    case SpaceState::OCCUPIED:
      return PROB_OCCUPIED_VOXEL;
    case SpaceState::FREE:
      return PROB_FREE_VOXEL;
    case SpaceState::UNKNOWN:
      break;
  }
  return 0.5f;
}

bool
PlanarGridMap::castRay(const Eigen::Vector3f& origin,
                       const Eigen::Vector3f& direction,
                       double max_range_m,
                       Eigen::Vector3f& hit) const
{
  checkCastRay(origin, direction, max_range_m, "PlanarGridMap::castRay");
  const float norm = direction.norm();
  const Eigen::Vector3f unit = direction / norm;
  Eigen::Vector3f voxel_hit;
  const bool has_voxel = space_.castRay(origin, unit, max_range_m, voxel_hit);
  float cuboid_distance = 0.0f;
  std::size_t index = 0;
  const bool has_cuboid =
    surface_.castRay(origin, unit, max_range_m, cuboid_distance, index);
  if (has_cuboid && (!has_voxel || cuboid_distance <= (voxel_hit - origin).norm())) {
    hit = origin + unit * cuboid_distance;
    return true;
  }
  if (has_voxel)
    hit = voxel_hit;
  return has_voxel;
}

MapMemory
PlanarGridMap::getMemory() const
{
  MapMemory memory;
  memory.surface_bytes = surface_.getMemoryBytes();
  memory.space_bytes = space_.getMemoryBytes();
  memory.total_bytes = memory.surface_bytes + memory.space_bytes;
  return memory;
}

OctoMapExportSummary
PlanarGridMap::exportOctoMap(const std::string& path) const
{
  octomap::OcTree tree(getResolution());
  const std::size_t skipped = fillOcTree(tree);
  OctoMapExportSummary summary = octomap_writer::write(tree, path);
  summary.skipped_voxels = skipped;
  return summary;
}

OctoMapExportSummary
PlanarGridMap::toOcTree(octomap::OcTree& tree, bool max_likelihood) const
{
  tree.clear();
  tree.setResolution(getResolution());
  const std::size_t skipped = fillOcTree(tree);
  octomap_writer::finish(tree, max_likelihood);
  OctoMapExportSummary summary = octomap_writer::summarize(tree);
  summary.skipped_voxels = skipped;
  return summary;
}

std::size_t
PlanarGridMap::fillOcTree(octomap::OcTree& tree) const
{
  const double res = getResolution();
  tree.setOccupancyThres(params_.surface.occupancy_thres);
  std::size_t skipped = space_.insertIntoOcTree(tree);
  const int offset = static_cast<int>(tree.coordToKey(0.0)); // the key of coordinate 0
  // The voxels of the cuboids, the lowest index first (findCuboid()'s rule where
  // cuboids overlap): each takes its cuboid's occupancy.
  std::unordered_set<std::uint64_t> taken;
  for (const PlanarCuboid& cuboid : surface_.getCuboids()) {
    const float p = std::clamp(cuboid.probability, MIN_EXPORTED_PROBABILITY,
                               1.0f - MIN_EXPORTED_PROBABILITY);
    const float log_odds = std::log(p / (1.0f - p));
    forEachVoxelInCuboid(cuboid, res, [&](const Eigen::Vector3i& key) {
      const Eigen::Vector3i k = key + Eigen::Vector3i::Constant(offset);
      if ((k.array() < 0).any() || (k.array() > 2 * offset - 1).any()) {
        ++skipped;
        return;
      }
      const std::uint64_t packed = static_cast<std::uint64_t>(k.x())
                                   | static_cast<std::uint64_t>(k.y()) << 16
                                   | static_cast<std::uint64_t>(k.z()) << 32;
      if (!taken.insert(packed).second)
        return;
      tree.setNodeValue(octomap::OcTreeKey(static_cast<octomap::key_type>(k.x()),
                                           static_cast<octomap::key_type>(k.y()),
                                           static_cast<octomap::key_type>(k.z())),
                        log_odds, true);
    });
  }
  if (skipped > 0)
    PCL_WARN("[planar_grid::PlanarGridMap] %zu voxels outside OctoMap's 2^16-voxel "
             "key range left out of the OctoMap.\n",
             skipped);
  return skipped;
}

} // namespace planar_grid
