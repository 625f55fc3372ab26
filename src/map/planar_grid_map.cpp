// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/console/print.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <set>
#include <sstream>
#include <tuple>
#include <unordered_set>
#include <utility>

#include "cast_ray_check.h"
#include "octomap_writer.h"
#include "surface_layer_impl.h"

namespace planar_grid {

namespace {

constexpr const char* MAGIC_LINE = "# Planar grid map file";
/** Version 3: the space layer's stream keeps observed free space apart from the free
 * prior (ExplicitSpaceGrid::STREAM_VERSION). Version 2: the checksum covers the header
 * lines before it as well as the data. Versions 1 (the checksum covers the data only)
 * and 2 are still read. */
constexpr std::uint64_t FORMAT_VERSION = ExplicitSpaceGrid::STREAM_VERSION;
/** The oldest version read. */
constexpr std::uint64_t OLDEST_FORMAT_VERSION = 1;

/** CRC-32 of \a header_size header bytes followed by \a data_size data bytes (version
 * 2); of the data alone with \a header_size 0 (version 1). */
std::string
checksumText(const char* header,
             std::size_t header_size,
             const std::uint8_t* data,
             std::size_t data_size)
{
  boost::crc_32_type crc;
  crc.process_bytes(header, header_size);
  crc.process_bytes(data, data_size);
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08x", crc.checksum());
  return text;
}
/** The text header is small; anything longer is not a map file. */
constexpr std::size_t MAX_HEADER_BYTES = 64 * 1024;
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

/** Shortest text of a double that reads back to the same value (std::to_chars). */
std::string
exact(double value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** The "key value..." lines of a map file header. */
class HeaderReader {
public:
  HeaderReader(std::string path, std::map<std::string, std::string> values) :
      path_(std::move(path)), values_(std::move(values))
  {}

  double number(const std::string& key)
  {
    std::istringstream in(require(key));
    double value = 0.0;
    std::string rest;
    if (!(in >> value) || (in >> rest) || !std::isfinite(value))
      fail("'" + key + "' must be one finite number, got '" + values_.at(key) + "'");
    return value;
  }

  std::uint64_t count(const std::string& key) { return parseCount(key, require(key)); }

  /** True when the header has a \a key line. */
  bool has(const std::string& key) const { return values_.count(key) > 0; }

  /** Two finite numbers, the first not above the second. */
  std::pair<double, double> orderedPair(const std::string& key)
  {
    std::istringstream in(require(key));
    double a = 0.0, b = 0.0;
    std::string rest;
    if (!(in >> a >> b) || (in >> rest) || !std::isfinite(a) || !std::isfinite(b)
        || a > b) {
      const std::string what = "' must be two finite numbers, the first not above "
                               "the second, got '";
      fail("'" + key + what + values_.at(key) + "'");
    }
    return {a, b};
  }

  std::vector<std::uint64_t> counts(const std::string& key, std::size_t n)
  {
    std::istringstream in(require(key));
    std::vector<std::uint64_t> out;
    std::string word;
    while (in >> word)
      out.push_back(parseCount(key, word));
    if (out.size() != n)
      fail("'" + key + "' must hold " + std::to_string(n) + " integers");
    return out;
  }

  const std::string& require(const std::string& key)
  {
    const auto it = values_.find(key);
    if (it == values_.end())
      fail("the header has no '" + key + "' line");
    used_.insert(key);
    return it->second;
  }

  void warnUnused() const
  {
    for (const auto& kv : values_)
      if (!used_.count(kv.first))
        PCL_WARN("[planar_grid::PlanarGridMap::load] %s: unknown header key '%s' "
                 "ignored.\n",
                 path_.c_str(), kv.first.c_str());
  }

  /** One non-negative integer of \a key's value (at most 19 digits: fits 64 bits). */
  std::uint64_t parseCount(const std::string& key, const std::string& text) const
  {
    if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos
        || text.size() > 19)
      fail("'" + key + "' must hold non-negative integers, got '" + text + "'");
    return std::stoull(text);
  }

  [[noreturn]] void fail(const std::string& what) const
  {
    throw IOError("map file " + path_ + ": " + what);
  }

private:
  std::string path_;
  std::map<std::string, std::string> values_;
  std::set<std::string> used_;
};

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

void
PlanarGridMap::serialize(std::string& bytes) const
{
  std::vector<std::uint8_t> data;
  space_.serialize(data);
  const std::size_t space_bytes = data.size();
  surface_.serialize(data);
  const std::size_t surface_bytes = data.size() - space_bytes;

  ExplicitSpaceGrid::VoxelKey min_key, max_key;
  Eigen::Vector3d min_m = Eigen::Vector3d::Zero(), max_m = Eigen::Vector3d::Zero();
  const double res = getResolution();
  if (space_.getBounds(min_key, max_key)) {
    min_m = min_key.cast<double>() * res;
    max_m = (max_key.cast<double>() + Eigen::Vector3d::Ones()) * res;
  }

  const auto& sp = params_.space;
  const auto& su = params_.surface;
  std::ostringstream header;
  header << MAGIC_LINE << "\n"
         << "version " << FORMAT_VERSION << "\n"
         << "id PlanarGridMap\n"
         << "resolution_m " << exact(res) << "\n"
         << "max_range_m " << exact(sp.max_range_m) << "\n"
         << "surface_margin_m " << exact(sp.surface_margin_m) << "\n"
         << "prior " << toString(sp.prior) << "\n"
         << "thickness_m " << exact(su.thickness_m) << "\n"
         << "plane_merge_angle_rad " << exact(su.plane_merge_angle_rad) << "\n"
         << "plane_merge_distance_m " << exact(su.plane_merge_distance_m) << "\n"
         << "occupancy_thres " << exact(su.occupancy_thres) << "\n"
         << "feature_distance_m " << exact(su.feature_distance_m) << "\n"
         << "bounds_m " << exact(min_m.x()) << " " << exact(min_m.y()) << " "
         << exact(min_m.z()) << " " << exact(max_m.x()) << " " << exact(max_m.y())
         << " " << exact(max_m.z()) << "\n"
         << "voxels " << space_.getVoxelCount(SpaceState::FREE) << " "
         << space_.getVoxelCount(SpaceState::OCCUPIED) << " "
         << space_.getVoxelCount(SpaceState::UNKNOWN) << "\n"
         << "planes " << surface_.getPlanes().size() << "\n"
         << "cuboids " << surface_.getCuboidCount() << "\n"
         << "space_bytes " << space_bytes << "\n"
         << "surface_bytes " << surface_bytes << "\n";
  if (!observation_span_.empty())
    header << "observation_span " << exact(observation_span_.first) << " "
           << exact(observation_span_.last) << "\n";
  // The checksum covers every header byte before its own line, then the data: a
  // changed header value (resolution_m) is refused like a changed data byte.
  bytes = header.str();
  bytes += "checksum_crc32 "
           + checksumText(bytes.data(), bytes.size(), data.data(), data.size()) + "\n"
           + "data\n";
  bytes.append(reinterpret_cast<const char*>(data.data()), data.size());
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

void
PlanarGridMap::save(const std::string& path) const
{
  std::string bytes;
  serialize(bytes);
  writeFileAtomically(path, [&](const std::string& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    return static_cast<bool>(out);
  });
}

PlanarGridMap
PlanarGridMap::load(const std::string& path)
{
  // A device such as /dev/zero never ends: reading it would take all the memory.
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw IOError("map file " + path
                  + ": not a regular file (a device, pipe or folder); a map is read "
                    "from a .pgmap file");
  std::ifstream file(path, std::ios::binary);
  if (!file)
    throw IOError("map file " + path + ": cannot be opened for reading");
  std::ostringstream content;
  content << file.rdbuf();
  if (file.bad())
    throw IOError("map file " + path + ": read error");
  return deserialize(content.str(), path);
}

PlanarGridMap
PlanarGridMap::deserialize(const std::string& bytes, const std::string& path)
{
  std::istringstream in(bytes);
  const auto file_size = static_cast<std::uint64_t>(bytes.size());

  // The text header, line by line, up to "data".
  std::string line;
  if (!std::getline(in, line) || line != MAGIC_LINE)
    throw IOError("map file " + path + ": not a planar grid map (first line must be '"
                  + std::string(MAGIC_LINE) + "')");
  std::map<std::string, std::string> values;
  std::uint64_t header_bytes = line.size() + 1;
  bool found_data = false;
  int line_number = 1;
  // Where the checksum line starts and its line number: in version 2 it is the last
  // line before "data" and covers the header bytes before it.
  std::uint64_t checksum_line_start = 0;
  int checksum_line = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.rfind("checksum_crc32 ", 0) == 0) {
      checksum_line_start = header_bytes;
      checksum_line = line_number;
    }
    header_bytes += line.size() + 1;
    if (header_bytes > MAX_HEADER_BYTES)
      throw IOError("map file " + path + ": no 'data' line in the first "
                    + std::to_string(MAX_HEADER_BYTES) + " bytes");
    if (line == "data") {
      found_data = true;
      break;
    }
    if (line.empty() || line[0] == '#')
      continue;
    const auto space = line.find(' ');
    const std::string key = line.substr(0, space);
    const std::string value = space == std::string::npos ? "" : line.substr(space + 1);
    if (!values.emplace(key, value).second)
      throw IOError("map file " + path + ":" + std::to_string(line_number)
                    + ": header key '" + key + "' given twice");
  }
  if (!found_data)
    throw IOError("map file " + path + ": truncated header (no 'data' line)");

  HeaderReader header(path, std::move(values));
  const auto version = header.count("version");
  if (version < OLDEST_FORMAT_VERSION || version > FORMAT_VERSION)
    header.fail("version " + std::to_string(version)
                + " is not supported (this reader knows versions "
                + std::to_string(OLDEST_FORMAT_VERSION) + " to "
                + std::to_string(FORMAT_VERSION) + ")");
  if (version >= 2 && checksum_line != line_number - 1)
    header.fail("the checksum_crc32 line must be the last line before 'data'");
  if (version < 2)
    PCL_WARN("[planar_grid::PlanarGridMap::load] %s: a version %d map file, whose "
             "checksum covers the data only; saving it again writes version %d, which "
             "covers the header too.\n",
             path.c_str(), static_cast<int>(version), static_cast<int>(FORMAT_VERSION));
  if (header.require("id") != "PlanarGridMap")
    header.fail("id must be 'PlanarGridMap'");
  const bool old_free_prior = version < 3 && header.require("prior") == "free";

  Params params;
  params.resolution_m = header.number("resolution_m");
  if (!(params.resolution_m > 0.0))
    header.fail("resolution_m must be > 0");
  params.space.max_range_m = header.number("max_range_m");
  params.space.surface_margin_m = header.number("surface_margin_m");
  try {
    params.space.prior = spaceStateFromString(header.require("prior"));
  } catch (const Exception& e) {
    header.fail(std::string("prior: ") + e.what());
  }
  params.surface.thickness_m = header.number("thickness_m");
  params.surface.plane_merge_angle_rad = header.number("plane_merge_angle_rad");
  params.surface.plane_merge_distance_m = header.number("plane_merge_distance_m");
  params.surface.occupancy_thres = header.number("occupancy_thres");
  params.surface.feature_distance_m = header.number("feature_distance_m");
  header.require("bounds_m"); // informative; the layers carry their own extent
  const auto voxels = header.counts("voxels", 3);
  const auto planes = header.count("planes");
  const auto cuboids = header.count("cuboids");
  const auto space_bytes = header.count("space_bytes");
  const auto surface_bytes = header.count("surface_bytes");
  // Optional: files written before the span was stored have none (an empty span).
  ObservationSpan span;
  if (header.has("observation_span"))
    std::tie(span.first, span.last) = header.orderedPair("observation_span");
  const std::string crc_text = header.require("checksum_crc32");
  header.warnUnused();

  // Sizes against the file length before allocating anything.
  const std::uint64_t remaining = file_size - header_bytes;
  if (space_bytes > remaining || surface_bytes > remaining - space_bytes)
    header.fail("truncated: the header announces " + std::to_string(space_bytes) + " + "
                + std::to_string(surface_bytes) + " data bytes, the file has "
                + std::to_string(remaining));
  if (space_bytes + surface_bytes != remaining)
    header.fail(std::to_string(remaining - space_bytes - surface_bytes)
                + " bytes of trailing data after the announced sections");
  std::vector<std::uint8_t> data(static_cast<std::size_t>(remaining));
  if (!data.empty()
      && !in.read(reinterpret_cast<char*>(data.data()),
                  static_cast<std::streamsize>(data.size())))
    header.fail("could not read the data section");
  const std::string expected = checksumText(
    bytes.data(), version >= 2 ? checksum_line_start : 0, data.data(), data.size());
  if (crc_text != expected)
    header.fail("checksum mismatch (file " + crc_text + ", content " + expected
                + "): the file is corrupt");

  PlanarGridMap map = [&]() {
    try {
      PlanarGridMap decoded(params);
      decoded.space_.deserialize(data.data(), static_cast<std::size_t>(space_bytes),
                                 static_cast<unsigned>(version));
      decoded.surface_.deserialize(data.data() + space_bytes,
                                   static_cast<std::size_t>(surface_bytes));
      // The surface section carries all of its layer's parameters, the header only
      // some of them (close_gaps_cells and merge_rule are in the section alone).
      decoded.params_.surface = decoded.surface_.getParams();
      decoded.observation_span_ = span;
      return decoded;
    } catch (const Exception& e) {
      header.fail(e.what());
    }
  }();
  // The map has one cell size: the surface section's must be the header's.
  if (map.params_.surface.resolution_m != params.resolution_m)
    header.fail("the surface section's resolution_m "
                + exact(map.params_.surface.resolution_m)
                + " differs from the header's " + exact(params.resolution_m));
  if (map.space_.getVoxelCount(SpaceState::FREE) != voxels[0]
      || map.space_.getVoxelCount(SpaceState::OCCUPIED) != voxels[1]
      || map.space_.getVoxelCount(SpaceState::UNKNOWN) != voxels[2])
    header.fail("the decoded voxel counts differ from the header's 'voxels'");
  if (map.surface_.getPlanes().size() != planes
      || map.surface_.getCuboidCount() != cuboids)
    header.fail("the decoded plane or cuboid count differs from the header's");
  if (old_free_prior)
    PCL_WARN("[planar_grid::PlanarGridMap::load] %s: a version %d map with the free "
             "prior does not tell observed free space from space never observed; both "
             "read as never observed (free by the prior, absent from OctoMap exports). "
             "Map the data again for observed free space.\n",
             path.c_str(), static_cast<int>(version));
  return map;
}

} // namespace planar_grid
