// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid's export to OctoMap: the observed voxels inserted into an
// octomap::OcTree block by block (a uniform block as one node, a mixed block's
// sub-cubes pruned as they are built), and the tree written to a .bt or .ot file.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <pcl/console/print.h>

#include <octomap/OcTree.h>

#include <cmath>
#include <cstdint>
#include <string>

#include "explicit_space_grid_impl.h"
#include "octomap_writer.h"

namespace planar_grid {

using namespace explicit_space;

std::size_t
ExplicitSpaceGrid::insertIntoOcTree(octomap::OcTree& tree) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  if (std::abs(tree.getResolution() - params_.resolution_m)
      > 1e-9 * params_.resolution_m)
    throw Exception("ExplicitSpaceGrid::insertIntoOcTree: the tree's resolution ("
                    + std::to_string(tree.getResolution())
                    + " m) differs from the grid's ("
                    + std::to_string(params_.resolution_m) + " m)");
  if (tree.size() != 0)
    throw Exception("ExplicitSpaceGrid::insertIntoOcTree: the tree must be empty");
  const float occupied_log_odds = tree.getClampingThresMaxLog();
  const float free_log_odds = tree.getClampingThresMinLog();
  const int offset = static_cast<int>(tree.coordToKey(0.0)); // the key of coordinate 0
  // A block (8^3 voxels, aligned to multiples of 8 like the key offset) is one
  // OctoMap node three levels above the voxels.
  const unsigned block_depth = tree.getTreeDepth() - BLOCK_SHIFT;
  constexpr auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
  constexpr auto occupied = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  // Only what a view observed goes in: occluded and never-observed space stay out of
  // the tree (unknown in OctoMap), whatever the prior.
  const auto exported = [](std::uint8_t code) {
    return code == free_code || code == occupied;
  };
  const auto sorted = impl_->storage.sortedBlocks(priorCode(params_.prior));
  std::size_t skipped = 0;
  DenseBlock dense;
  const DenseBlock* const block = &dense;
  for (const auto& stored : sorted) {
    const BlockKey& bk = stored.key;
    stored.super->load(stored.j, dense);
    const Eigen::Vector3i base = Eigen::Vector3i(bk.x, bk.y, bk.z) * BLOCK_EDGE
                                 + Eigen::Vector3i::Constant(offset);
    if ((base.array() < 0).any()
        || (base.array() > 2 * offset - 1 - (BLOCK_EDGE - 1)).any()) {
      for (int i = 0; i < BLOCK_VOXELS; ++i)
        skipped += exported(block->get(i)) ? 1 : 0;
      continue;
    }
    const auto keyOf = [&base](int i) {
      return octomap::OcTreeKey(
        static_cast<octomap::key_type>(base.x() + (i & 7)),
        static_cast<octomap::key_type>(base.y() + ((i >> 3) & 7)),
        static_cast<octomap::key_type>(base.z() + (i >> 6)));
    };
    if (block->uniform != MIXED && !exported(block->uniform))
      continue;
    if (block->uniform == MIXED) {
      const auto counts = countCodes(block->bits);
      if (counts[free_code] + counts[occupied] == 0)
        continue; // occluded and never-observed voxels only: nothing to create
    }
    if (tree.getRoot() == nullptr) {
      // OcTree creates its root only through its updates: the first block exported
      // voxel by voxel, then collapsed like OctoMap's pruning.
      for (int i = 0; i < BLOCK_VOXELS; ++i) {
        const std::uint8_t code = block->get(i);
        if (exported(code))
          tree.setNodeValue(keyOf(i),
                            code == occupied ? occupied_log_odds : free_log_odds, true);
      }
      if (octomap::OcTreeNode* node = tree.search(keyOf(0), block_depth))
        octomap_writer::pruneSubtree(tree, node);
      continue;
    }
    // The block's node at its depth, created down from the root (blocks are disjoint
    // and the tree was empty, so the path never runs through a leaf).
    const octomap::OcTreeKey key = keyOf(0);
    octomap::OcTreeNode* node = tree.getRoot();
    for (unsigned depth = 0; depth < block_depth; ++depth) {
      const unsigned child = octomap::computeChildIdx(
        key, static_cast<int>(tree.getTreeDepth() - 1 - depth));
      if (!tree.nodeChildExists(node, child))
        tree.createNodeChild(node, child);
      node = tree.getNodeChild(node, child);
    }
    if (block->uniform != MIXED) {
      // A uniform block is one leaf.
      node->setLogOdds(block->uniform == occupied ? occupied_log_odds : free_log_odds);
      continue;
    }
    // A mixed block: its sub-cubes (4^3, 2^3, voxels) built below the block's node,
    // a sub-cube whose voxels all have one exported state as one leaf (OctoMap's
    // pruning, done as the tree is built), one with nothing exported left out.
    struct SubCubes {
      octomap::OcTree& tree;
      const DenseBlock& block;
      float occupied_log_odds, free_log_odds;
      std::uint8_t occupied_code, free_code;

      void build(octomap::OcTreeNode* parent, int level, int x, int y, int z)
      {
        // parent: a cube of edge 2^level voxels at local (x, y, z); its children
        const int h = 1 << (level - 1);
        for (unsigned c = 0; c < 8; ++c) {
          const int cx = x + static_cast<int>(c & 1) * h;
          const int cy = y + static_cast<int>((c >> 1) & 1) * h;
          const int cz = z + static_cast<int>((c >> 2) & 1) * h;
          const std::uint8_t first = block.get(cx + 8 * cy + 64 * cz);
          bool uniform = true;
          bool any = false;
          for (int k = cz; k < cz + h; ++k)
            for (int j = cy; j < cy + h; ++j)
              for (int i = cx; i < cx + h; ++i) {
                const std::uint8_t code = block.get(i + 8 * j + 64 * k);
                uniform = uniform && code == first;
                any = any || code == occupied_code || code == free_code;
              }
          if (!any)
            continue;
          octomap::OcTreeNode* child = tree.createNodeChild(parent, c);
          if (uniform)
            child->setLogOdds(first == occupied_code ? occupied_log_odds
                                                     : free_log_odds);
          else
            build(child, level - 1, cx, cy, cz);
        }
      }
    } sub_cubes{tree, *block, occupied_log_odds, free_log_odds, occupied, free_code};
    sub_cubes.build(node, BLOCK_SHIFT, 0, 0, 0);
  }
  tree.updateInnerOccupancy();
  return skipped;
}

void
ExplicitSpaceGrid::exportOctoMap(const std::string& path) const
{
  octomap::OcTree tree(params_.resolution_m);
  const std::size_t skipped = insertIntoOcTree(tree);
  if (skipped > 0)
    PCL_WARN("[planar_grid::ExplicitSpaceGrid::exportOctoMap] %zu voxels outside "
             "OctoMap's 2^16-voxel key range left out.\n",
             skipped);
  octomap_writer::write(tree, path);
}

} // namespace planar_grid
