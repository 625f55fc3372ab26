// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid::removeOutside(): the rolling window of a long run. The voxels
// outside a box go back to never observed, and the storage they held is freed.
#include <planar_grid/map/explicit_space_grid.h>

#include <algorithm>
#include <cmath>

#include "explicit_space_grid_impl.h"

namespace planar_grid {

using namespace explicit_space;

namespace {

/** \brief Inclusive voxel key range along one axis whose centres lie in [lo, hi]
 * (meters); empty (first > last) when none does. Infinite bounds reach past every key
 * the grid can hold. */
struct KeyRange {
  std::int64_t first;
  std::int64_t last;

  KeyRange(float lo, float hi, double r)
  {
    // centre (k + 1/2) r in [lo, hi]  <=>  k in [lo / r - 1/2, hi / r - 1/2]
    const double a = std::ceil(static_cast<double>(lo) / r - 0.5);
    const double b = std::floor(static_cast<double>(hi) / r - 0.5);
    const auto clamp = [](double v) {
      return static_cast<std::int64_t>(
        std::max(-2.0 * MAX_KEY, std::min(2.0 * MAX_KEY, v)));
    };
    // NaN bounds keep nothing (every comparison with NaN fails)
    if (!(a <= b)) {
      first = 1;
      last = 0;
      return;
    }
    first = clamp(a);
    last = clamp(b);
  }
  /** The keys [k0, k0 + n) all inside. */
  bool holds(std::int64_t k0, std::int64_t n) const
  {
    return k0 >= first && k0 + n - 1 <= last;
  }
  /** None of the keys [k0, k0 + n) inside. */
  bool misses(std::int64_t k0, std::int64_t n) const
  {
    return k0 + n - 1 < first || k0 > last;
  }
  bool contains(std::int64_t k) const { return k >= first && k <= last; }
};

/** \brief Observed voxels (codes other than \a prior) of block \a j of \a sb. */
std::uint64_t
observedVoxels(const SuperBlock& sb, int j, std::uint8_t prior)
{
  if (!sb.isMixed(j))
    return sb.code(j) == prior ? 0 : BLOCK_VOXELS;
  std::array<std::size_t, 4> n{};
  countCompact(sb.compact(j), n);
  std::uint64_t observed = 0;
  for (std::uint8_t c = 0; c < 4; ++c)
    if (c != prior)
      observed += n[c];
  return observed;
}

} // namespace

ExplicitSpaceGrid::WindowRemoval
ExplicitSpaceGrid::removeOutside(const Eigen::AlignedBox3f& keep)
{
  WindowRemoval removed;
  BlockStorage& storage = impl_->storage;
  const std::uint8_t prior = priorCode(params_.prior);
  // Pending setState() edits go to the storage first, so that the storage alone holds
  // the content walked here.
  storage.settle(prior);
  const double r = params_.resolution_m;
  const KeyRange range[3] = {KeyRange(keep.min().x(), keep.max().x(), r),
                             KeyRange(keep.min().y(), keep.max().y(), r),
                             KeyRange(keep.min().z(), keep.max().z(), r)};
  const auto holds = [&](const BlockKey& k, std::int64_t n) {
    return range[0].holds(std::int64_t{k.x} * n, n)
           && range[1].holds(std::int64_t{k.y} * n, n)
           && range[2].holds(std::int64_t{k.z} * n, n);
  };
  const auto misses = [&](const BlockKey& k, std::int64_t n) {
    return range[0].misses(std::int64_t{k.x} * n, n)
           || range[1].misses(std::int64_t{k.y} * n, n)
           || range[2].misses(std::int64_t{k.z} * n, n);
  };
  constexpr std::int64_t SUPER_VOXELS = BLOCK_EDGE << SUPER_SHIFT; // 64

  // 1. Super-blocks wholly outside go at once; those across the boundary are edited
  // block by block below.
  std::vector<BlockKey> across;
  std::size_t kept = 0;
  for (std::size_t s = 0; s < storage.supers.size(); ++s) {
    SuperBlock& sb = storage.supers[s];
    if (!holds(sb.key, SUPER_VOXELS)) {
      if (misses(sb.key, SUPER_VOXELS)) {
        for (int j = 0; j < SUPER_BLOCKS; ++j)
          if (sb.isMixed(j) || sb.code(j) != prior) {
            ++removed.blocks;
            removed.voxels += observedVoxels(sb, j, prior);
          }
        continue;
      }
      across.push_back(sb.key);
    }
    if (kept != s)
      storage.supers[kept] = std::move(sb);
    ++kept;
  }
  const bool dropped_supers = kept != storage.supers.size();
  if (dropped_supers) {
    storage.supers.erase(storage.supers.begin() + static_cast<std::ptrdiff_t>(kept),
                         storage.supers.end());
    storage.supers.shrink_to_fit();
    storage.directory.release();
    for (std::size_t i = 0; i < storage.supers.size(); ++i)
      storage.directory.insert(storage.supers[i].key, static_cast<std::uint32_t>(i));
  }

  // 2. The blocks of the super-blocks across the boundary: a block wholly outside
  // becomes the prior, one across it loses its voxels outside; commit() drops the
  // blocks and super-blocks left at the prior and frees their bytes.
  for (const BlockKey& s : across) {
    const SuperBlock* sb = storage.findSuper(s);
    for (int j = 0; j < SUPER_BLOCKS; ++j) {
      if (!(sb->isMixed(j) || sb->code(j) != prior))
        continue;
      const BlockKey bk = blockKeyOf(s, j);
      if (holds(bk, BLOCK_EDGE))
        continue;
      if (misses(bk, BLOCK_EDGE)) {
        ++removed.blocks;
        removed.voxels += observedVoxels(*sb, j, prior);
        const std::uint32_t e = storage.open(bk, prior);
        storage.edits[e].uniform = prior;
        sb = storage.findSuper(s); // open() does not move the super-blocks; kept safe
        continue;
      }
      const std::uint32_t e = storage.open(bk, prior);
      sb = storage.findSuper(s);
      for (int i = 0; i < BLOCK_VOXELS; ++i) {
        const std::int64_t kx = std::int64_t{bk.x} * BLOCK_EDGE + (i & 7);
        const std::int64_t ky = std::int64_t{bk.y} * BLOCK_EDGE + ((i >> 3) & 7);
        const std::int64_t kz = std::int64_t{bk.z} * BLOCK_EDGE + (i >> 6);
        if (range[0].contains(kx) && range[1].contains(ky) && range[2].contains(kz))
          continue;
        if (storage.getEdit(e, i) == prior)
          continue;
        ++removed.voxels;
        storage.setEdit(e, i, prior);
      }
    }
  }
  if (!storage.edits.empty())
    storage.commit(prior);
  if (dropped_supers || !across.empty()) {
    // The directory sized for what is left (commit() keeps its slots), and the edit
    // buffer of this one-off pass freed.
    storage.directory.release();
    for (std::size_t i = 0; i < storage.supers.size(); ++i)
      storage.directory.insert(storage.supers[i].key, static_cast<std::uint32_t>(i));
    storage.releaseEdits();
  }
  return removed;
}

} // namespace planar_grid
