// SPDX-License-Identifier: BSD-3-Clause
// The completeness of a map: the truth voxels against the occupied cells of a voxel
// grid, boxes, cuboids or an octree, within a tolerance.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/console/print.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "mapping_error_impl.h"

namespace planar_grid {

namespace {

using detail::checkResolution;
using detail::checkTolerance;

constexpr int MAX_INDEX = StandardVoxelGrid::MAX_INDEX;
/** \brief Largest tolerance of the lattice completeness, in cells (its neighbourhood
 * holds about 4 (t + 1/2)^3 offsets, probed per uncovered truth voxel). */
constexpr double MAX_TOLERANCE_CELLS = 16.0;

/** \brief Packs an index in [-MAX_INDEX, MAX_INDEX]^3 into 3 x 21 bits, z in the high
 * bits (so that sorting the keys sorts by (z, y, x)); the top bit stays 0. */
std::uint64_t
packIndex(int x, int y, int z)
{
  constexpr std::uint64_t mask = (std::uint64_t{1} << 21) - 1;
  const auto field = [](int i) {
    return static_cast<std::uint64_t>(static_cast<std::int64_t>(i) + (1 << 20)) & mask;
  };
  return (field(z) << 42) | (field(y) << 21) | field(x);
}

VoxelIndex
unpackIndex(std::uint64_t key)
{
  constexpr std::uint64_t mask = (std::uint64_t{1} << 21) - 1;
  const auto index = [](std::uint64_t field) {
    return static_cast<int>(static_cast<std::int64_t>(field) - (1 << 20));
  };
  return {index(key & mask), index((key >> 21) & mask), index((key >> 42) & mask)};
}

/** \brief A voxel index or count in 64 bits (no overflow when adding sizes). */
using Index64 = Eigen::Matrix<std::int64_t, 3, 1>;

bool
inIndexRange(const VoxelIndex& i)
{
  return (i.array().abs() <= MAX_INDEX).all();
}

/** \brief A set of packed voxel keys: open addressing with linear probing in a
 * power-of-two table at most half full (one flat array, no node per key as in
 * std::unordered_set, for the millions of keys and probes of a whole map). */
class KeySet {
public:
  void insert(std::uint64_t key)
  {
    if (2 * (size_ + 1) > slots_.size())
      grow();
    std::size_t i = mix(key) & (slots_.size() - 1);
    while (slots_[i] != EMPTY) {
      if (slots_[i] == key)
        return;
      i = (i + 1) & (slots_.size() - 1);
    }
    slots_[i] = key;
    ++size_;
  }

  [[nodiscard]] bool contains(std::uint64_t key) const
  {
    if (slots_.empty())
      return false;
    std::size_t i = mix(key) & (slots_.size() - 1);
    while (slots_[i] != EMPTY) {
      if (slots_[i] == key)
        return true;
      i = (i + 1) & (slots_.size() - 1);
    }
    return false;
  }

private:
  /** A packed key never has its top bit set. */
  static constexpr std::uint64_t EMPTY = ~std::uint64_t{0};

  /** The finaliser of splitmix64: neighbouring keys spread over the table. */
  static std::size_t mix(std::uint64_t k)
  {
    k ^= k >> 30;
    k *= 0xbf58476d1ce4e5b9ULL;
    k ^= k >> 27;
    k *= 0x94d049bb133111ebULL;
    k ^= k >> 31;
    return static_cast<std::size_t>(k);
  }

  void grow()
  {
    std::vector<std::uint64_t> old(std::max<std::size_t>(64, 2 * slots_.size()), EMPTY);
    old.swap(slots_); // slots_ is the new, larger table
    size_ = 0;
    for (const std::uint64_t key : old)
      if (key != EMPTY)
        insert(key);
  }

  std::vector<std::uint64_t> slots_;
  std::size_t size_{0};
};

void
checkTruthResolution(const TruthVoxels& truth, double resolution_m, const char* what)
{
  if (std::abs(truth.getResolution() - resolution_m) > 1e-9 * resolution_m)
    throw Exception(std::string("completeness: the truth voxels (")
                    + std::to_string(truth.getResolution()) + " m) and " + what + " ("
                    + std::to_string(resolution_m) + " m) must share the cell size");
}

/** \brief The truth voxels counted: inside the region and, with \a nonground_only, not
 * ground. */
std::vector<std::size_t>
countedTruthVoxels(const TruthVoxels& truth,
                   const MappingErrorRegion& region,
                   bool nonground_only)
{
  std::vector<std::size_t> out;
  out.reserve(truth.size());
  for (std::size_t i = 0; i < truth.size(); ++i)
    if (!(nonground_only && truth.isGround(i)) && region.contains(truth.getCentre(i)))
      out.push_back(i);
  return out;
}

/** \brief The counts of the truth voxels \a counted, \a covered flagging (parallel to
 * it) those within the tolerance of an occupied cell. */
Completeness
tally(const TruthVoxels& truth,
      const std::vector<std::size_t>& counted,
      const std::vector<std::uint8_t>& covered)
{
  Completeness out;
  out.truth_voxels = counted.size();
  for (std::size_t q = 0; q < counted.size(); ++q) {
    const std::size_t i = counted[q];
    const bool is_covered = covered[q] != 0;
    const bool nonground = !truth.isGround(i);
    const bool in_range = nonground && truth.isInRange(i);
    out.covered += is_covered;
    out.nonground_voxels += nonground;
    out.nonground_covered += nonground && is_covered;
    out.range_nonground_voxels += in_range;
    out.range_nonground_covered += in_range && is_covered;
  }
  return out;
}

/** \brief Completeness against cells made of voxels of the truth's lattice. Either the
 * caller adds the occupied voxels through add(min, size) (a block of voxels, clipped
 * here to the voxels that can cover a counted truth voxel) and calls evaluate(), or it
 * calls evaluate(is_occupied) with its own lookup. */
class LatticeCompleteness {
public:
  LatticeCompleteness(const TruthVoxels& truth,
                      double tolerance_m,
                      const MappingErrorRegion& region) :
      truth_(truth),
      counted_(countedTruthVoxels(truth, region, false))
  {
    checkTolerance(tolerance_m);
    // The offsets d whose voxel reaches within tolerance_m of a voxel's centre, in
    // cells: |max(|d| - 1/2, 0)| <= tolerance_m / r (a relative 1e-9 keeps a voxel at
    // exactly the tolerance in); nearest first, so a covered voxel stops early.
    const double t = tolerance_m / truth.getResolution() * (1.0 + 1e-9);
    if (t > MAX_TOLERANCE_CELLS)
      throw Exception("completeness: tolerance_m must be at most "
                      + std::to_string(MAX_TOLERANCE_CELLS) + " cell sizes, got "
                      + std::to_string(tolerance_m) + " m at "
                      + std::to_string(truth.getResolution()) + " m");
    const int reach = static_cast<int>(std::floor(t + 0.5));
    std::vector<std::pair<double, VoxelIndex>> offsets;
    for (int z = -reach; z <= reach; ++z)
      for (int y = -reach; y <= reach; ++y)
        for (int x = -reach; x <= reach; ++x) {
          const Eigen::Vector3d e =
            (Eigen::Vector3d(x, y, z).cwiseAbs().array() - 0.5).max(0.0);
          if (e.squaredNorm() <= t * t)
            offsets.emplace_back(e.squaredNorm(), VoxelIndex(x, y, z));
        }
    std::stable_sort(offsets.begin(), offsets.end(),
                     [](const auto& a, const auto& b) { return a.first < b.first; });
    for (const auto& o : offsets)
      offsets_.push_back(o.second);
    // Only occupied voxels within reach of a counted truth voxel matter.
    if (!counted_.empty()) {
      clip_min_ = truth.getIndex(counted_.front());
      clip_max_ = clip_min_;
      for (const std::size_t i : counted_) {
        clip_min_ = clip_min_.cwiseMin(truth.getIndex(i));
        clip_max_ = clip_max_.cwiseMax(truth.getIndex(i));
      }
      clip_min_.array() -= reach;
      clip_max_.array() += reach;
    }
  }

  /** Adds the occupied voxels [min, min + size) per axis. */
  void add(const Index64& min, const Index64& size)
  {
    if (counted_.empty())
      return;
    const Index64 lo = min.cwiseMax(clip_min_.cast<std::int64_t>());
    const Index64 hi =
      (min + size).cwiseMin(clip_max_.cast<std::int64_t>() + Index64::Ones());
    for (std::int64_t z = lo.z(); z < hi.z(); ++z)
      for (std::int64_t y = lo.y(); y < hi.y(); ++y)
        for (std::int64_t x = lo.x(); x < hi.x(); ++x)
          if (std::abs(x) <= MAX_INDEX && std::abs(y) <= MAX_INDEX
              && std::abs(z) <= MAX_INDEX)
            occupied_.insert(
              packIndex(static_cast<int>(x), static_cast<int>(y), static_cast<int>(z)));
  }

  /** Adds the occupied voxel \a index. */
  void add(const VoxelIndex& index)
  {
    add(index.cast<std::int64_t>(), Index64::Ones());
  }

  /** Flags (parallel to getCounted()) the truth voxels with an occupied voxel among
   * their offsets, \a is_occupied(index) telling whether a voxel (in the index range)
   * is occupied; the flags already set stay. */
  template <typename IsOccupied>
  void cover(const IsOccupied& is_occupied, std::vector<std::uint8_t>& covered) const
  {
    covered.resize(counted_.size(), 0);
    for (std::size_t q = 0; q < counted_.size(); ++q) {
      if (covered[q])
        continue;
      const VoxelIndex& k = truth_.getIndex(counted_[q]);
      for (const VoxelIndex& d : offsets_) {
        const VoxelIndex n = k + d;
        if (inIndexRange(n) && is_occupied(n)) {
          covered[q] = 1;
          break;
        }
      }
    }
  }

  /** Flags them against the voxels added. */
  void cover(std::vector<std::uint8_t>& covered) const
  {
    cover(
      [this](const VoxelIndex& n) {
        return occupied_.contains(packIndex(n.x(), n.y(), n.z()));
      },
      covered);
  }

  /** Counts the truth voxels with an occupied voxel among their offsets, \a
   * is_occupied(index) telling whether a voxel (in the index range) is occupied. */
  template <typename IsOccupied>
  [[nodiscard]] Completeness evaluate(const IsOccupied& is_occupied) const
  {
    std::vector<std::uint8_t> covered;
    cover(is_occupied, covered);
    return tally(truth_, counted_, covered);
  }

  /** Counts them against the voxels added. */
  [[nodiscard]] Completeness evaluate() const
  {
    std::vector<std::uint8_t> covered;
    cover(covered);
    return tally(truth_, counted_, covered);
  }

  /** The truth voxels counted (indices into the truth voxels). */
  [[nodiscard]] const std::vector<std::size_t>& getCounted() const { return counted_; }
  /** Whether any truth voxel is counted. */
  [[nodiscard]] bool hasCounted() const { return !counted_.empty(); }
  /** The voxels that can cover a counted truth voxel lie in [getClipMin(),
   * getClipMax()] (valid when hasCounted()). */
  [[nodiscard]] const VoxelIndex& getClipMin() const { return clip_min_; }
  [[nodiscard]] const VoxelIndex& getClipMax() const { return clip_max_; }

private:
  const TruthVoxels& truth_;
  std::vector<std::size_t> counted_;
  std::vector<VoxelIndex> offsets_;
  VoxelIndex clip_min_{VoxelIndex::Zero()}, clip_max_{VoxelIndex::Constant(-1)};
  KeySet occupied_;
};

/** \brief A solid oriented box: centre, unit axes and half extents, meters. */
struct SolidBox {
  Eigen::Vector3d centre, u, v, n, half;

  [[nodiscard]] double squaredDistance(const Eigen::Vector3d& p) const
  {
    const Eigen::Vector3d d = p - centre;
    const Eigen::Vector3d local(d.dot(u), d.dot(v), d.dot(n));
    return (local.cwiseAbs() - half).cwiseMax(0.0).squaredNorm();
  }
};

/** \brief Flags (parallel to \a counted) the truth voxels \a counted within the
 * tolerance of an occupied (and, with \a planar_only, planar) cuboid; the flags already
 * set stay, and those voxels are not tested again.
 * Cuboids and truth voxel centres meet in cubic buckets: each cuboid is listed in the
 * buckets that its box grown by the tolerance may reach, the (bucket, cuboid) and
 * (bucket, truth voxel) lists are sorted by bucket and walked together. */
void
coverByCuboids(const PlanarCuboids& cuboids,
               double occupancy_thres,
               bool planar_only,
               const TruthVoxels& truth,
               const std::vector<std::size_t>& counted,
               double tolerance_m,
               std::vector<std::uint8_t>& covered)
{
  checkTolerance(tolerance_m);
  if (!(occupancy_thres >= 0.0 && occupancy_thres <= 1.0))
    throw Exception("completeness: occupancy_thres must be a probability in [0, 1], "
                    "got "
                    + std::to_string(occupancy_thres));
  covered.resize(counted.size(), 0);
  if (counted.empty())
    return;

  const double bucket_m = 2.0 * (truth.getResolution() + tolerance_m);
  // Buckets are at least two voxels wide and taken within the truth voxels' bounds,
  // so their indices stay in the packed range.
  const auto bucketOf = [bucket_m](const Eigen::Vector3d& p) {
    return Index64(static_cast<std::int64_t>(std::floor(p.x() / bucket_m)),
                   static_cast<std::int64_t>(std::floor(p.y() / bucket_m)),
                   static_cast<std::int64_t>(std::floor(p.z() / bucket_m)));
  };
  const auto packBucket = [](const Index64& b) {
    return packIndex(static_cast<int>(b.x()), static_cast<int>(b.y()),
                     static_cast<int>(b.z()));
  };
  std::vector<std::pair<std::uint64_t, std::uint32_t>> queries;
  queries.reserve(counted.size());
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  for (std::size_t q = 0; q < counted.size(); ++q) {
    if (covered[q])
      continue;
    const Eigen::Vector3d c = truth.getCentre(counted[q]).cast<double>();
    lo = lo.cwiseMin(c);
    hi = hi.cwiseMax(c);
    queries.emplace_back(packBucket(bucketOf(c)), static_cast<std::uint32_t>(q));
  }
  if (queries.empty())
    return;
  std::sort(queries.begin(), queries.end());

  std::vector<SolidBox> boxes;
  std::vector<std::pair<std::uint64_t, std::uint32_t>> listed;
  const double reach_m = tolerance_m + bucket_m * std::sqrt(3.0) / 2.0 + 1e-6;
  std::size_t skipped = 0;
  for (const auto& c : cuboids) {
    if (!(static_cast<double>(c.probability) >= occupancy_thres)
        || (planar_only && !c.is_planar))
      continue;
    if (!c.centre.allFinite() || !c.normal.allFinite() || !c.horizontal_axis.allFinite()
        || !(c.width_m >= 0.0f) || !(c.height_m >= 0.0f) || !(c.thickness_m >= 0.0f)
        || !std::isfinite(c.width_m) || !std::isfinite(c.height_m)
        || !std::isfinite(c.thickness_m)) {
      ++skipped;
      continue;
    }
    SolidBox box{c.centre.cast<double>(), c.horizontal_axis.cast<double>(),
                 c.verticalAxis().cast<double>(), c.normal.cast<double>(),
                 0.5 * Eigen::Vector3d(c.width_m, c.height_m, c.thickness_m)};
    // The axis-aligned bounds of the box grown by the tolerance, clipped to the truth
    // voxels'.
    const Eigen::Vector3d extent =
      box.u.cwiseAbs() * box.half.x() + box.v.cwiseAbs() * box.half.y()
      + box.n.cwiseAbs() * box.half.z() + Eigen::Vector3d::Constant(tolerance_m);
    const Eigen::Vector3d box_lo = box.centre - extent;
    const Eigen::Vector3d box_hi = box.centre + extent;
    if ((box_lo.array() > hi.array()).any() || (box_hi.array() < lo.array()).any())
      continue;
    const Index64 b_lo = bucketOf(box_lo.cwiseMax(lo));
    const Index64 b_hi = bucketOf(box_hi.cwiseMin(hi));
    const auto index = static_cast<std::uint32_t>(boxes.size());
    bool listed_any = false;
    for (std::int64_t z = b_lo.z(); z <= b_hi.z(); ++z)
      for (std::int64_t y = b_lo.y(); y <= b_hi.y(); ++y)
        for (std::int64_t x = b_lo.x(); x <= b_hi.x(); ++x) {
          const Index64 bucket(x, y, z);
          // A truth voxel centre within the tolerance of the box is within
          // tolerance + half the bucket's diagonal of the bucket's centre.
          if (box.squaredDistance((bucket.cast<double>().array() + 0.5).matrix()
                                  * bucket_m)
              <= reach_m * reach_m) {
            listed.emplace_back(packBucket(bucket), index);
            listed_any = true;
          }
        }
    if (listed_any)
      boxes.push_back(box);
  }
  if (skipped > 0)
    PCL_WARN(
      "[planar_grid::evaluateCompleteness] %zu cuboids with non-finite fields or "
      "negative extents skipped.\n",
      skipped);
  std::sort(listed.begin(), listed.end());

  const double tolerance_sq = tolerance_m * tolerance_m;
  auto b = listed.begin();
  for (auto q = queries.begin(); q != queries.end();) {
    const std::uint64_t key = q->first;
    while (b != listed.end() && b->first < key)
      ++b;
    auto b_end = b;
    while (b_end != listed.end() && b_end->first == key)
      ++b_end;
    for (; q != queries.end() && q->first == key; ++q) {
      const Eigen::Vector3d c = truth.getCentre(counted[q->second]).cast<double>();
      for (auto it = b; it != b_end; ++it)
        if (boxes[it->second].squaredDistance(c) <= tolerance_sq) {
          covered[q->second] = 1;
          break;
        }
    }
    b = b_end;
  }
}

/** \brief Completeness against the occupied (and, with \a planar_only, planar)
 * cuboids, over the truth voxels in \a region (non-ground only with \a
 * nonground_only). */
Completeness
cuboidCompleteness(const PlanarCuboids& cuboids,
                   double occupancy_thres,
                   bool planar_only,
                   bool nonground_only,
                   const TruthVoxels& truth,
                   double tolerance_m,
                   const MappingErrorRegion& region)
{
  const std::vector<std::size_t> counted =
    countedTruthVoxels(truth, region, nonground_only);
  std::vector<std::uint8_t> covered(counted.size(), 0);
  coverByCuboids(cuboids, occupancy_thres, planar_only, truth, counted, tolerance_m,
                 covered);
  return tally(truth, counted, covered);
}

} // namespace

TruthVoxels::TruthVoxels(const GroundTruthSurface& truth, double resolution_m) :
    resolution_m_(resolution_m)
{
  checkResolution(resolution_m);
  const GroundTruthSurface::PointCloudConstPtr points = truth.getPoints();
  std::vector<std::uint64_t> keys;
  keys.reserve(points->size());
  std::size_t out_of_range = 0;
  for (const auto& p : points->points) {
    int index[3];
    bool in_range = true;
    for (int k = 0; k < 3; ++k) {
      const double f = std::floor(static_cast<double>(p.data[k]) / resolution_m);
      in_range = in_range && f >= -MAX_INDEX && f <= MAX_INDEX;
      index[k] = in_range ? static_cast<int>(f) : 0;
    }
    if (in_range)
      keys.push_back(packIndex(index[0], index[1], index[2]));
    else
      ++out_of_range;
  }
  if (out_of_range > 0)
    PCL_WARN("[planar_grid::TruthVoxels] %zu truth points outside the index range "
             "left out.\n",
             out_of_range);
  std::sort(keys.begin(), keys.end());
  keys.erase(std::unique(keys.begin(), keys.end()), keys.end());
  indices_.reserve(keys.size());
  for (const std::uint64_t key : keys)
    indices_.push_back(unpackIndex(key));

  // Ground: within GROUND_HEIGHT_M of the lowest voxel centre of its (x, y) column.
  const auto columnOf = [this](std::size_t i) {
    const Eigen::Vector3f c = getCentre(i);
    const auto cx = static_cast<std::int64_t>(
      std::floor(static_cast<double>(c.x()) / GROUND_COLUMN_SIZE_M));
    const auto cy = static_cast<std::int64_t>(
      std::floor(static_cast<double>(c.y()) / GROUND_COLUMN_SIZE_M));
    return (static_cast<std::uint64_t>(cx) << 32)
           ^ (static_cast<std::uint64_t>(cy) & 0xFFFFFFFFULL);
  };
  std::unordered_map<std::uint64_t, int> lowest; // column -> lowest z index
  for (std::size_t i = 0; i < indices_.size(); ++i) {
    const auto it = lowest.emplace(columnOf(i), indices_[i].z()).first;
    it->second = std::min(it->second, indices_[i].z());
  }
  ground_.resize(indices_.size(), 0);
  for (std::size_t i = 0; i < indices_.size(); ++i) {
    const double above_m =
      static_cast<double>(indices_[i].z() - lowest.at(columnOf(i))) * resolution_m_;
    ground_[i] = above_m <= GROUND_HEIGHT_M + 1e-6 ? 1 : 0;
    ground_count_ += ground_[i];
  }
}

Eigen::Vector3f
TruthVoxels::getCentre(std::size_t i) const
{
  return ((indices_[i].cast<double>().array() + 0.5) * resolution_m_)
    .matrix()
    .cast<float>();
}

void
TruthVoxels::setMappedRange(double max_depth_m)
{
  if (!(max_depth_m > 0.0))
    throw Exception("TruthVoxels::setMappedRange: max_depth_m must be > 0, got "
                    + std::to_string(max_depth_m));
  has_range_ = true;
  max_depth_m_ = max_depth_m;
  in_range_.assign(indices_.size(), 0);
}

void
TruthVoxels::addView(const RangeView& view)
{
  if (!has_range_)
    return;
  const Eigen::Isometry3d camera_T_world = view.world_T_camera.inverse();
  const bool bounded =
    view.focal_length_px > 0.0 && view.width_px > 0 && view.height_px > 0;
  for (std::size_t i = 0; i < indices_.size(); ++i) {
    if (in_range_[i])
      continue;
    const Eigen::Vector3d p = camera_T_world * getCentre(i).cast<double>();
    if (!(p.z() > 0.0 && p.z() <= max_depth_m_))
      continue;
    if (bounded) {
      // The pixel the centre projects to, inside the image's [0, size) range.
      const double u = view.focal_length_px * p.x() / p.z() + view.cx_px;
      const double v = view.focal_length_px * p.y() / p.z() + view.cy_px;
      if (!(u >= 0.0 && u < view.width_px && v >= 0.0 && v < view.height_px))
        continue;
    }
    in_range_[i] = 1;
  }
}

Completeness
evaluateCompleteness(const StandardVoxelGrid& grid,
                     const TruthVoxels& truth,
                     double tolerance_m,
                     const MappingErrorRegion& region)
{
  checkTruthResolution(truth, grid.getParams().resolution_m, "the voxel grid");
  // The grid's own hash map answers the probes: cheaper than collecting its occupied
  // voxels, which means visiting every observed (mostly free) voxel.
  const LatticeCompleteness lattice(truth, tolerance_m, region);
  return lattice.evaluate([&grid](const VoxelIndex& n) { return grid.isOccupied(n); });
}

Completeness
evaluateCompleteness(const AxisAlignedBoxes& boxes,
                     double resolution_m,
                     const TruthVoxels& truth,
                     double tolerance_m,
                     const MappingErrorRegion& region)
{
  checkResolution(resolution_m);
  checkTruthResolution(truth, resolution_m, "the boxes");
  LatticeCompleteness lattice(truth, tolerance_m, region);
  for (const auto& box : boxes)
    if (box.occupied)
      lattice.add(box.min_index.cast<std::int64_t>(), box.size.cast<std::int64_t>());
  return lattice.evaluate();
}

Completeness
evaluateCompleteness(const octomap::OcTree& tree,
                     const TruthVoxels& truth,
                     double tolerance_m,
                     const MappingErrorRegion& region)
{
  const double r = tree.getResolution();
  checkTruthResolution(truth, r, "the octree");
  LatticeCompleteness lattice(truth, tolerance_m, region);
  if (!lattice.hasCounted())
    return lattice.evaluate();
  // Only the leaves in the box of voxels that can cover a counted truth voxel (a
  // place's neighbourhood, not the whole tree): OctoMap's key of voxel index i is
  // i + 2^(depth - 1).
  const unsigned depth = tree.getTreeDepth();
  const int key_offset = 1 << (depth - 1);
  const auto toKey = [key_offset](int index) {
    return static_cast<octomap::key_type>(
      std::clamp(index + key_offset, 0, 2 * key_offset - 1));
  };
  const octomap::OcTreeKey min_key(toKey(lattice.getClipMin().x()),
                                   toKey(lattice.getClipMin().y()),
                                   toKey(lattice.getClipMin().z()));
  const octomap::OcTreeKey max_key(toKey(lattice.getClipMax().x()),
                                   toKey(lattice.getClipMax().y()),
                                   toKey(lattice.getClipMax().z()));
  for (auto it = tree.begin_leafs_bbx(min_key, max_key), end = tree.end_leafs_bbx();
       it != end; ++it) {
    if (!tree.isNodeOccupied(*it))
      continue;
    // A leaf at depth d is a cube of n = 2^(depth - d) voxels; its minimum corner is
    // a whole multiple of r.
    const std::int64_t n = std::int64_t{1} << (depth - it.getDepth());
    const octomap::point3d centre = it.getCoordinate();
    const Index64 min(std::llround(centre.x() / r - 0.5 * static_cast<double>(n)),
                      std::llround(centre.y() / r - 0.5 * static_cast<double>(n)),
                      std::llround(centre.z() / r - 0.5 * static_cast<double>(n)));
    lattice.add(min, Index64::Constant(n));
  }
  return lattice.evaluate();
}

Completeness
evaluateCompleteness(const PlanarCuboids& cuboids,
                     double occupancy_thres,
                     const TruthVoxels& truth,
                     double tolerance_m,
                     const MappingErrorRegion& region)
{
  return cuboidCompleteness(cuboids, occupancy_thres, false, false, truth, tolerance_m,
                            region);
}

Completeness
evaluateMapCompleteness(const PlanarGridMap& map,
                        const TruthVoxels& truth,
                        double tolerance_m,
                        const MappingErrorRegion& region)
{
  const double r = map.getParams().resolution_m;
  checkTruthResolution(truth, r, "the map");
  const double thres = map.getParams().surface.occupancy_thres;
  const PlanarCuboids cuboids = map.getSurfaceLayer().getCuboids();
  LatticeCompleteness lattice(truth, tolerance_m, region);
  if (lattice.hasCounted()) {
    // getState() at a point: the lowest-index cuboid containing it decides (occupied
    // at probability >= the threshold), else the space layer. It is evaluated here on
    // a bin hash of the cuboids rather than through the map, whose query index would
    // stay allocated and count in the map's memory, measured next to this.
    const double bin_m = 8.0 * r;
    const auto binOf = [bin_m](double x) {
      return static_cast<std::int64_t>(std::floor(x / bin_m));
    };
    const auto binKey = [](std::int64_t x, std::int64_t y, std::int64_t z) {
      const auto field = [](std::int64_t i) {
        return static_cast<std::uint64_t>(i + (1 << 20))
               & ((std::uint64_t{1} << 21) - 1);
      };
      return (field(z) << 42) | (field(y) << 21) | field(x);
    };
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> bins;
    bool any_free = false;
    for (std::size_t i = 0; i < cuboids.size(); ++i) {
      const PlanarCuboid& c = cuboids[i];
      any_free = any_free || static_cast<double>(c.probability) < thres;
      const Eigen::Vector3d half(0.5 * c.width_m, 0.5 * c.height_m,
                                 0.5 * c.thickness_m);
      const Eigen::Vector3d extent =
        c.horizontal_axis.cast<double>().cwiseAbs() * half.x()
        + c.verticalAxis().cast<double>().cwiseAbs() * half.y()
        + c.normal.cast<double>().cwiseAbs() * half.z();
      const Eigen::Vector3d lo = c.centre.cast<double>() - extent;
      const Eigen::Vector3d hi = c.centre.cast<double>() + extent;
      // Cuboids with non-finite fields contain no point; a bin index beyond the packed
      // range (a cuboid 1e5 bins away) is left out with them.
      if (!lo.allFinite() || !hi.allFinite()
          || (lo.array().abs() / bin_m > double{1 << 19}).any()
          || (hi.array().abs() / bin_m > double{1 << 19}).any())
        continue;
      for (std::int64_t z = binOf(lo.z()); z <= binOf(hi.z()); ++z)
        for (std::int64_t y = binOf(lo.y()); y <= binOf(hi.y()); ++y)
          for (std::int64_t x = binOf(lo.x()); x <= binOf(hi.x()); ++x)
            bins[binKey(x, y, z)].push_back(static_cast<std::uint32_t>(i));
    }
    const auto readsOccupied = [&](const Eigen::Vector3f& p) {
      if (!any_free)
        return true;
      const auto it = bins.find(binKey(binOf(p.x()), binOf(p.y()), binOf(p.z())));
      if (it == bins.end())
        return true;
      // The bin's list is in increasing cuboid index: the first containing one decides.
      for (const std::uint32_t i : it->second)
        if (cuboids[i].contains(p))
          return static_cast<double>(cuboids[i].probability) >= thres;
      return true;
    };
    const ExplicitSpaceGrid& space = map.getSpaceLayer();
    const VoxelIndex& lo = lattice.getClipMin();
    const VoxelIndex& hi = lattice.getClipMax();
    space.forEachVoxelIn(
      SpaceState::OCCUPIED, [&](const ExplicitSpaceGrid::VoxelKey& k) {
        if ((k.array() < lo.array()).any() || (k.array() > hi.array()).any())
          return;
        if (readsOccupied(space.toCentre(k)))
          lattice.add(k);
      });
  }
  std::vector<std::uint8_t> covered;
  lattice.cover(covered);
  // The truth voxels no voxel covers, against the occupied cuboids.
  coverByCuboids(cuboids, thres, false, truth, lattice.getCounted(), tolerance_m,
                 covered);
  return tally(truth, lattice.getCounted(), covered);
}

Completeness
evaluatePlanarShare(const PlanarCuboids& cuboids,
                    double occupancy_thres,
                    const TruthVoxels& truth,
                    double tolerance_m,
                    const MappingErrorRegion& region)
{
  return cuboidCompleteness(cuboids, occupancy_thres, true, true, truth, tolerance_m,
                            region);
}

} // namespace planar_grid
