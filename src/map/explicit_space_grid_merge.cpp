// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid::merge(): the observed voxels of another grid (another recording's
// map, or another part of one) combined with this grid's, voxel by voxel, by the rule
// in the header.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <pcl/console/print.h>

#include <array>
#include <cmath>
#include <limits>
#include <string>

#include "explicit_space_grid_impl.h"
#include "map_merge_transform.h"

namespace planar_grid {

using namespace explicit_space;

namespace {

/** \brief The merged code of two observations of one voxel, \a a this grid's and \a b
 * the other's, by the rule of \a order (ExplicitSpaceGrid::merge()). */
std::uint8_t
combine(std::uint8_t a, std::uint8_t b, ExplicitSpaceGrid::MergeOrder order)
{
  // codes: FREE (0), OCCUPIED (1), UNKNOWN (2), NEVER_OBSERVED (3); free and occupied
  // are the observed states a view writes over older ones
  if (order == ExplicitSpaceGrid::MergeOrder::OTHER_IS_NEWER && b <= 1)
    return b;
  if (order == ExplicitSpaceGrid::MergeOrder::THIS_IS_NEWER && a <= 1)
    return a;
  // Otherwise the state of higher rank, occupied > free > unknown (occluded) > never
  // observed: the states' log-odds at OctoMap's clamping bounds added (occupied +3.5
  // and free -2.0 give +1.5, occupied; occluded space carries no evidence, 0; never
  // observed is no observation). With an order, at most one side is observed here,
  // and the rank keeps it.
  constexpr std::array<std::uint8_t, 4> RANK{2, 3, 1, 0};
  return RANK[a] >= RANK[b] ? a : b;
}

/** \brief Combines \a code into voxel \a i of edit \a e of \a storage. */
void
combineVoxel(BlockStorage& storage,
             std::uint32_t e,
             int i,
             std::uint8_t code,
             ExplicitSpaceGrid::MergeOrder order)
{
  const std::uint8_t current = storage.getEdit(e, i);
  const std::uint8_t merged = combine(current, code, order);
  if (merged != current)
    storage.setEdit(e, i, merged);
}

/** \brief Combines the decoded block \a block into block \a target of \a storage. */
void
combineBlock(BlockStorage& storage,
             const BlockKey& target,
             const DenseBlock& block,
             std::uint8_t prior,
             ExplicitSpaceGrid::MergeOrder order)
{
  const std::uint32_t e = storage.open(target, prior);
  if (block.uniform != MIXED && storage.edits[e].uniform != MIXED) {
    storage.edits[e].uniform = combine(storage.edits[e].uniform, block.uniform, order);
    return;
  }
  for (int i = 0; i < BLOCK_VOXELS; ++i)
    combineVoxel(storage, e, i, block.get(i), order);
}

/** \brief The integer voxel offset of \a t when it is a translation by whole voxels of
 * edge \a r (rotation exactly the identity, translation within 1e-6 voxel of whole
 * voxels, within MAX_KEY); false otherwise. */
bool
voxelTranslation(const Eigen::Isometry3d& t, double r, Eigen::Vector3i& offset)
{
  if (t.linear() != Eigen::Matrix3d::Identity())
    return false;
  const Eigen::Vector3d voxels = t.translation() / r;
  const Eigen::Vector3d whole = voxels.array().round();
  if ((voxels - whole).cwiseAbs().maxCoeff() > 1e-6
      || whole.cwiseAbs().maxCoeff() > MAX_KEY)
    return false;
  offset = whole.cast<int>();
  return true;
}

/** \brief Combines the decoded block \a block of the other grid (its first voxel
 * \a first) into \a dst, moved by \a this_T_other (its inverse \a other_T_this);
 * \a r is the voxel edge, meters. \return the observed voxels left out because the
 * moved block lies beyond the keys the grid handles (all or none) */
std::size_t
resampleBlock(BlockStorage& dst,
              double r,
              const DenseBlock& block,
              const Eigen::Vector3i& first,
              const Eigen::Isometry3d& this_T_other,
              const Eigen::Isometry3d& other_T_this,
              std::uint8_t prior,
              ExplicitSpaceGrid::MergeOrder order)
{
  // Every voxel of this grid whose centre, moved back into the other grid, falls in
  // the block takes the state of the voxel it falls in (nearest-neighbour
  // resampling: each voxel of this grid is sampled once, so a rotation leaves no
  // holes). The candidates are the voxels whose centres lie in the bounding box of
  // the moved block.
  Eigen::Vector3d lo = Eigen::Vector3d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector3d hi = -lo;
  for (int c = 0; c < 8; ++c) {
    const Eigen::Vector3d corner =
      (first + Eigen::Vector3i(c & 1, (c >> 1) & 1, c >> 2) * BLOCK_EDGE).cast<double>()
      * r;
    const Eigen::Vector3d moved = this_T_other * corner;
    lo = lo.cwiseMin(moved);
    hi = hi.cwiseMax(moved);
  }
  const Eigen::Vector3d k_lo = (lo / r - Eigen::Vector3d::Constant(0.5)).array().ceil();
  const Eigen::Vector3d k_hi =
    (hi / r - Eigen::Vector3d::Constant(0.5)).array().floor();
  if (k_lo.cwiseAbs().maxCoeff() > MAX_KEY || k_hi.cwiseAbs().maxCoeff() > MAX_KEY) {
    std::size_t observed = 0;
    for (int i = 0; i < BLOCK_VOXELS; ++i)
      observed += block.get(i) != prior ? 1 : 0;
    return observed;
  }
  BlockStorage::Cursor cursor(dst, prior);
  for (auto z = static_cast<int>(k_lo.z()); z <= static_cast<int>(k_hi.z()); ++z)
    for (auto y = static_cast<int>(k_lo.y()); y <= static_cast<int>(k_hi.y()); ++y)
      for (auto x = static_cast<int>(k_lo.x()); x <= static_cast<int>(k_hi.x()); ++x) {
        const Eigen::Vector3d centre =
          (Eigen::Vector3d(x, y, z) + Eigen::Vector3d::Constant(0.5)) * r;
        const Eigen::Vector3i source =
          ((other_T_this * centre) / r).array().floor().cast<int>() - first.array();
        if ((source.array() < 0).any() || (source.array() >= BLOCK_EDGE).any())
          continue;
        const std::uint8_t code =
          block.get(source.x() + BLOCK_EDGE * source.y() + 64 * source.z());
        if (code == prior)
          continue;
        int local = 0;
        const std::uint32_t e = cursor.at(x, y, z, local);
        combineVoxel(dst, e, local, code, order);
      }
  return 0;
}

} // namespace

void
ExplicitSpaceGrid::merge(const ExplicitSpaceGrid& other,
                         const Eigen::Isometry3d& this_T_other,
                         MergeOrder order)
{
  if (&other == this)
    throw Exception("ExplicitSpaceGrid::merge: a grid cannot be merged into itself");
  const std::string differences =
    map_merge::difference("resolution_m", params_.resolution_m,
                          other.params_.resolution_m, "m")
    + map_merge::difference("prior", toString(params_.prior),
                            toString(other.params_.prior), "");
  if (!differences.empty())
    throw Exception("ExplicitSpaceGrid::merge: the grids' " + differences);
  map_merge::checkRigid(this_T_other, "ExplicitSpaceGrid::merge");
  const std::uint8_t prior = priorCode(params_.prior);
  BlockStorage& dst = impl_->storage;
  dst.settle(prior);
  other.impl_->storage.settle(prior); // pending setState() edits (content unchanged)
  const BlockStorage& src = other.impl_->storage;
  const double r = params_.resolution_m;

  Eigen::Vector3i offset = Eigen::Vector3i::Zero();
  const bool translation = voxelTranslation(this_T_other, r, offset);
  const bool aligned = translation && offset.x() % BLOCK_EDGE == 0
                       && offset.y() % BLOCK_EDGE == 0 && offset.z() % BLOCK_EDGE == 0;
  const Eigen::Isometry3d other_T_this = this_T_other.inverse();
  std::size_t outside = 0; // voxels moved beyond the keys the grid handles
  DenseBlock block;
  for (const SuperBlock& sb : src.supers)
    for (int j = 0; j < SUPER_BLOCKS; ++j) {
      if (!sb.isMixed(j) && sb.code(j) == prior)
        continue;
      sb.load(j, block);
      const BlockKey bk = blockKeyOf(sb.key, j);
      const Eigen::Vector3i first = Eigen::Vector3i(bk.x, bk.y, bk.z) * BLOCK_EDGE;
      if (aligned) {
        // whole blocks onto whole blocks
        combineBlock(dst,
                     {bk.x + offset.x() / BLOCK_EDGE, bk.y + offset.y() / BLOCK_EDGE,
                      bk.z + offset.z() / BLOCK_EDGE},
                     block, prior, order);
      } else if (translation) {
        BlockStorage::Cursor cursor(dst, prior);
        for (int i = 0; i < BLOCK_VOXELS; ++i) {
          const std::uint8_t code = block.get(i);
          if (code == prior)
            continue;
          const Eigen::Vector3d key =
            (first + Eigen::Vector3i(i & 7, (i >> 3) & 7, i >> 6) + offset)
              .cast<double>();
          if (key.cwiseAbs().maxCoeff() > MAX_KEY) {
            ++outside;
            continue;
          }
          int local = 0;
          const std::uint32_t e =
            cursor.at(static_cast<int>(key.x()), static_cast<int>(key.y()),
                      static_cast<int>(key.z()), local);
          combineVoxel(dst, e, local, code, order);
        }
      } else {
        outside +=
          resampleBlock(dst, r, block, first, this_T_other, other_T_this, prior, order);
      }
      if (dst.edits.size() >= MAX_PENDING_BLOCKS)
        dst.commit(prior);
    }
  if (!dst.edits.empty())
    dst.commit(prior);
  // the edit buffer of this one-off pass freed
  dst.releaseEdits();
  if (outside > 0)
    PCL_WARN("[planar_grid::ExplicitSpaceGrid::merge] %zu observed voxels moved beyond "
             "+-2^30 voxels from the origin were left out.\n",
             outside);
}

} // namespace planar_grid
