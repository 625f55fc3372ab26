// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/log_odds.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

namespace planar_grid {

namespace {

/** \brief Offset of a packed component: index + 2^20 is in [1, 2^21 - 1], so a packed
 * index is never 0 (the empty scratch slot). */
constexpr std::int64_t OFFSET = std::int64_t{1} << 20;
/** \brief One packed component. */
constexpr std::uint64_t COMPONENT_MASK = (std::uint64_t{1} << 21) - 1;
/** \brief Bit of a scratch slot marking an end point (occupied). */
constexpr std::uint64_t OCCUPIED_BIT = std::uint64_t{1} << 63;
/** \brief The packed index in a scratch slot. */
constexpr std::uint64_t KEY_MASK = OCCUPIED_BIT - 1;
/** \brief Smallest scratch table (slots, a power of two). */
constexpr std::size_t MIN_SCRATCH = 1024;

/** \brief Packs an in-range index: x in bits 0-20, y in 21-41, z in 42-62 (so packed
 * order is (z, y, x) order). */
inline std::uint64_t
pack(int x, int y, int z)
{
  return static_cast<std::uint64_t>(x + OFFSET)
         | (static_cast<std::uint64_t>(y + OFFSET) << 21)
         | (static_cast<std::uint64_t>(z + OFFSET) << 42);
}

inline VoxelIndex
unpack(std::uint64_t key)
{
  return {
    static_cast<int>(static_cast<std::int64_t>(key & COMPONENT_MASK) - OFFSET),
    static_cast<int>(static_cast<std::int64_t>((key >> 21) & COMPONENT_MASK) - OFFSET),
    static_cast<int>(static_cast<std::int64_t>((key >> 42) & COMPONENT_MASK) - OFFSET)};
}

inline bool
inRange(const VoxelIndex& index)
{
  return (index.array().abs() <= StandardVoxelGrid::MAX_INDEX).all();
}

/** \brief OctoMap's coordToKeyChecked for one coordinate: floor(inv_resolution c),
 * false when outside [-MAX_INDEX, MAX_INDEX] or not finite. */
inline bool
toIndexChecked(double inv_resolution, float coordinate, int& index)
{
  const double f = std::floor(inv_resolution * static_cast<double>(coordinate));
  if (!(f >= -StandardVoxelGrid::MAX_INDEX && f <= StandardVoxelGrid::MAX_INDEX))
    return false;
  index = static_cast<int>(f);
  return true;
}

inline bool
toIndexChecked(double inv_resolution, const Eigen::Vector3f& p, int index[3])
{
  return toIndexChecked(inv_resolution, p.x(), index[0])
         && toIndexChecked(inv_resolution, p.y(), index[1])
         && toIndexChecked(inv_resolution, p.z(), index[2]);
}

/** \brief OctoMap's point3d::norm(): the squared length summed in float, the root in
 * double. */
inline double
octomapNorm(const Eigen::Vector3f& v)
{
  const float sq = v.x() * v.x() + v.y() * v.y() + v.z() * v.z();
  return std::sqrt(static_cast<double>(sq));
}

/** \brief The free voxels of the ray origin -> end, as OctoMap's computeRayKeys
 * (3D-DDA of Amanatides & Woo, the same float / double arithmetic): the origin's
 * voxel and every voxel entered before the end point's voxel; nothing when both lie
 * in one voxel. Calls free_voxel(packed) for each.
 * \return false when the origin or the end is out of range (no voxel visited) */
template <typename F>
bool
traceRay(double resolution,
         double inv_resolution,
         const Eigen::Vector3f& origin,
         const Eigen::Vector3f& end,
         F&& free_voxel)
{
  int key[3], key_end[3];
  if (!toIndexChecked(inv_resolution, origin, key)
      || !toIndexChecked(inv_resolution, end, key_end))
    return false;
  if (key[0] == key_end[0] && key[1] == key_end[1] && key[2] == key_end[2])
    return true;
  free_voxel(pack(key[0], key[1], key[2]));

  Eigen::Vector3f direction = end - origin;
  const auto length = static_cast<float>(octomapNorm(direction));
  direction /= length;
  int step[3];
  double t_max[3], t_delta[3];
  for (int i = 0; i < 3; ++i) {
    const float d = direction[i];
    step[i] = d > 0.0f ? 1 : (d < 0.0f ? -1 : 0);
    if (step[i] != 0) {
      double voxel_border = (static_cast<double>(key[i]) + 0.5) * resolution;
      voxel_border += static_cast<float>(step[i] * resolution * 0.5);
      t_max[i] = (voxel_border - static_cast<double>(origin[i])) / d;
      t_delta[i] = resolution / std::fabs(d);
    } else {
      t_max[i] = std::numeric_limits<double>::max();
      t_delta[i] = std::numeric_limits<double>::max();
    }
  }
  for (;;) {
    int dim;
    if (t_max[0] < t_max[1])
      dim = t_max[0] < t_max[2] ? 0 : 2;
    else
      dim = t_max[1] < t_max[2] ? 1 : 2;
    key[dim] += step[dim];
    t_max[dim] += t_delta[dim];
    if (key[0] == key_end[0] && key[1] == key_end[1] && key[2] == key_end[2])
      break;
    // Longer than the ray: the end voxel was missed by rounding (OctoMap stops too).
    if (std::min(std::min(t_max[0], t_max[1]), t_max[2]) > length)
      break;
    // Only reachable by rounding at the edge of the index range.
    if (key[dim] > StandardVoxelGrid::MAX_INDEX
        || key[dim] < -StandardVoxelGrid::MAX_INDEX)
      break;
    free_voxel(pack(key[0], key[1], key[2]));
  }
  return true;
}

/** \brief The scan's voxels, each once: an open-addressing (linear probing) set of
 * packed indices over \a slots (a power of two, 0 = empty), bit 63 = occupied. */
class ScanVoxelSet {
public:
  explicit ScanVoxelSet(std::vector<std::uint64_t>& slots) : slots_(slots)
  {
    if (slots_.size() < MIN_SCRATCH)
      slots_.assign(MIN_SCRATCH, 0);
    resize();
  }

  /** \brief Adds \a key (free: flag 0; occupied: OCCUPIED_BIT). An occupied mark is
   * never removed (occupied wins). */
  void insert(std::uint64_t key, std::uint64_t flag)
  {
    std::size_t i = slot(key);
    for (;;) {
      const std::uint64_t s = slots_[i];
      if (s == 0) {
        slots_[i] = key | flag;
        if (++size_ * 2 > slots_.size())
          grow();
        return;
      }
      if ((s & KEY_MASK) == key) {
        slots_[i] = s | flag;
        return;
      }
      i = (i + 1) & mask_;
    }
  }

  std::size_t size() const { return size_; }

private:
  /** \brief Fibonacci hashing: the high bits of key x 2^64 / phi. */
  std::size_t slot(std::uint64_t key) const
  {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift_);
  }

  /** \brief mask_ and shift_ for the current (power-of-two) size. */
  void resize()
  {
    mask_ = slots_.size() - 1;
    shift_ = 64;
    for (std::size_t n = slots_.size(); n > 1; n >>= 1)
      --shift_;
  }

  void grow()
  {
    std::vector<std::uint64_t> old(slots_.size() * 2, 0);
    old.swap(slots_);
    resize();
    for (const auto s : old)
      if (s != 0) {
        std::size_t i = slot(s & KEY_MASK);
        while (slots_[i] != 0)
          i = (i + 1) & mask_;
        slots_[i] = s;
      }
  }

  std::vector<std::uint64_t>& slots_;
  std::size_t mask_{0};
  int shift_{64};
  std::size_t size_{0};
};

void
check(bool ok, const std::string& what)
{
  if (!ok)
    throw Exception("StandardVoxelGrid: " + what);
}

} // namespace

StandardVoxelGrid::StandardVoxelGrid(const Params& params) : params_(params)
{
  check(params.resolution_m > 0.0 && params.resolution_m <= 100.0,
        "resolution_m must be in (0, 100] meters, got "
          + std::to_string(params.resolution_m));
  check(!std::isnan(params.max_range_m), "max_range_m is NaN");
  check(params.prob_hit > 0.5f && params.prob_hit < 1.0f,
        "prob_hit must be in (0.5, 1), got " + std::to_string(params.prob_hit));
  check(params.prob_miss > 0.0f && params.prob_miss < 0.5f,
        "prob_miss must be in (0, 0.5), got " + std::to_string(params.prob_miss));
  check(params.clamping_thres_min > 0.0f && params.clamping_thres_min <= 0.5f,
        "clamping_thres_min must be in (0, 0.5], got "
          + std::to_string(params.clamping_thres_min));
  check(params.clamping_thres_max >= 0.5f && params.clamping_thres_max < 1.0f,
        "clamping_thres_max must be in [0.5, 1), got "
          + std::to_string(params.clamping_thres_max));
  check(params.occupancy_thres >= params.clamping_thres_min
          && params.occupancy_thres <= params.clamping_thres_max
          && params.occupancy_thres > 0.0f && params.occupancy_thres < 1.0f,
        "occupancy_thres must be in (0, 1) and within [clamping_thres_min, "
        "clamping_thres_max], got "
          + std::to_string(params.occupancy_thres));
  inv_resolution_ = 1.0 / params.resolution_m;
  // OctoMap's logodds(double): the float of log(p / (1 - p)) in double.
  prob_hit_log_odds_ = static_cast<float>(toLogOdds(params.prob_hit));
  prob_miss_log_odds_ = static_cast<float>(toLogOdds(params.prob_miss));
  clamping_min_ = static_cast<float>(toLogOdds(params.clamping_thres_min));
  clamping_max_ = static_cast<float>(toLogOdds(params.clamping_thres_max));
  occupancy_log_odds_ = static_cast<float>(toLogOdds(params.occupancy_thres));
}

VoxelIndex
StandardVoxelGrid::toIndex(const Eigen::Vector3f& point) const
{
  return {static_cast<int>(std::floor(inv_resolution_ * point.x())),
          static_cast<int>(std::floor(inv_resolution_ * point.y())),
          static_cast<int>(std::floor(inv_resolution_ * point.z()))};
}

Eigen::Vector3f
StandardVoxelGrid::toCentre(const VoxelIndex& index) const
{
  return ((index.cast<double>().array() + 0.5) * params_.resolution_m)
    .matrix()
    .cast<float>();
}

void
StandardVoxelGrid::insertPointCloud(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                                    const Eigen::Vector3f& sensor_origin)
{
  if (cloud.empty())
    return;
  const double resolution = params_.resolution_m;
  const double inv_resolution = inv_resolution_;
  const double max_range = params_.max_range_m;
  ScanVoxelSet scan(scratch_);
  const auto add_free = [&scan](std::uint64_t key) {
    scan.insert(key, 0);
  };
  int origin_index[3];
  const bool origin_ok = toIndexChecked(inv_resolution, sensor_origin, origin_index);
  if (!origin_ok)
    PCL_WARN(
      "[planar_grid::StandardVoxelGrid::insertPointCloud] sensor_origin (%g, %g, "
      "%g) is not finite or outside the index range: end points only.\n",
      sensor_origin.x(), sensor_origin.y(), sensor_origin.z());
  std::size_t skipped = 0; // points whose end point or ray left the index range
  for (const auto& point : cloud.points) {
    const Eigen::Vector3f p = point.getVector3fMap();
    if (!p.allFinite())
      continue;
    bool in_range = true;
    if (max_range <= 0.0 || octomapNorm(p - sensor_origin) <= max_range) {
      if (origin_ok)
        in_range = traceRay(resolution, inv_resolution, sensor_origin, p, add_free);
      int k[3];
      if (toIndexChecked(inv_resolution, p, k))
        scan.insert(pack(k[0], k[1], k[2]), OCCUPIED_BIT);
      else
        in_range = false;
    } else if (origin_ok) {
      // OctoMap: (p - origin).normalized() divides by the float of the double norm.
      Eigen::Vector3f direction = p - sensor_origin;
      direction /= static_cast<float>(octomapNorm(direction));
      const Eigen::Vector3f new_end =
        sensor_origin + direction * static_cast<float>(max_range);
      in_range = traceRay(resolution, inv_resolution, sensor_origin, new_end, add_free);
    }
    skipped += in_range ? 0 : 1;
  }
  if (skipped > 0)
    PCL_WARN("[planar_grid::StandardVoxelGrid::insertPointCloud] %zu points whose end "
             "point or ray lies outside the index range of +-%d voxels skipped.\n",
             skipped, MAX_INDEX);

  // Apply: one update per voxel of the scan; the slots are emptied on the way. One
  // rehash up front (to at most the size the map grows to anyway) instead of several.
  if (voxels_.size() + scan.size() > voxels_.bucket_count())
    voxels_.reserve(voxels_.size() + scan.size());
  const float hit = prob_hit_log_odds_, miss = prob_miss_log_odds_;
  const float lo = clamping_min_, hi = clamping_max_;
  for (auto& slot : scratch_) {
    if (slot == 0)
      continue;
    const std::uint64_t key = slot & KEY_MASK;
    const float update = (slot & OCCUPIED_BIT) != 0 ? hit : miss;
    slot = 0;
    float& log_odds = voxels_.try_emplace(key, 0.0f).first->second;
    log_odds += update; // OctoMap's updateNodeLogOdds: add, then clamp
    if (log_odds < lo)
      log_odds = lo;
    else if (log_odds > hi)
      log_odds = hi;
  }
}

std::size_t
StandardVoxelGrid::getOccupiedCount() const
{
  std::size_t n = 0;
  for (const auto& kv : voxels_)
    n += kv.second >= occupancy_log_odds_ ? 1 : 0;
  return n;
}

std::size_t
StandardVoxelGrid::getFreeCount() const
{
  return voxels_.size() - getOccupiedCount();
}

bool
StandardVoxelGrid::isOccupied(const VoxelIndex& index) const
{
  float log_odds = 0.0f;
  return getLogOdds(index, log_odds) && log_odds >= occupancy_log_odds_;
}

bool
StandardVoxelGrid::getLogOdds(const VoxelIndex& index, float& log_odds) const
{
  if (!inRange(index))
    return false;
  const auto it = voxels_.find(pack(index.x(), index.y(), index.z()));
  if (it == voxels_.end())
    return false;
  log_odds = it->second;
  return true;
}

void
StandardVoxelGrid::getVoxels(std::vector<Voxel>& voxels) const
{
  std::vector<std::pair<std::uint64_t, float>> sorted(voxels_.begin(), voxels_.end());
  std::sort(sorted.begin(), sorted.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  voxels.clear();
  voxels.reserve(sorted.size());
  for (const auto& kv : sorted)
    voxels.push_back({unpack(kv.first), kv.second});
}

void
StandardVoxelGrid::getOccupiedCentres(pcl::PointCloud<pcl::PointXYZ>& centres) const
{
  std::vector<std::uint64_t> keys;
  for (const auto& kv : voxels_)
    if (kv.second >= occupancy_log_odds_)
      keys.push_back(kv.first);
  std::sort(keys.begin(), keys.end());
  centres.clear();
  centres.reserve(keys.size());
  for (const auto key : keys) {
    const Eigen::Vector3f c = toCentre(unpack(key));
    centres.push_back(pcl::PointXYZ(c.x(), c.y(), c.z()));
  }
  centres.width = static_cast<std::uint32_t>(centres.size());
  centres.height = 1;
  centres.is_dense = true;
}

std::size_t
StandardVoxelGrid::getMemoryBytes() const
{
  using Map = decltype(voxels_);
  // The formula of surface_layer.cpp's hashMapBytes (PG is measured the same way).
  constexpr std::size_t node =
    (sizeof(void*) + sizeof(Map::value_type) + sizeof(std::size_t) + 7) / 8 * 8;
  return voxels_.bucket_count() * sizeof(void*) + voxels_.size() * node;
}

void
StandardVoxelGrid::clear()
{
  decltype(voxels_)().swap(voxels_);
  std::vector<std::uint64_t>().swap(scratch_);
}

} // namespace planar_grid
