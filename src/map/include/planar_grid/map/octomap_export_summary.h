// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>

namespace planar_grid {

/** \brief What PlanarGridMap::exportOctoMap() wrote, counted in the octree as written
 * (after pruning, and for .bt after the conversion to maximum likelihood) the way
 * liboctomap counts a tree it reads from that file. A leaf at depth d stands for
 * 8^(16 - d) voxels of resolution_m (a pruned node of uniform state); occupied means
 * OcTree::isNodeOccupied at the exported tree's occupancy_thres. \ingroup map */
struct OctoMapExportSummary {
  /** \brief Every node of the tree, inner and leaf (OcTree::size(), the file's "size").
   */
  std::size_t nodes{0};
  /** \brief OcTree::getNumLeafNodes(). */
  std::size_t leaf_nodes{0};
  /** \brief Leaves that are occupied. */
  std::size_t occupied_leaves{0};
  /** \brief Leaves that are free (observed free space, cuboids below occupancy_thres).
   */
  std::size_t free_leaves{0};
  /** \brief Voxels of resolution_m under the occupied leaves. */
  std::uint64_t occupied_voxels{0};
  /** \brief Voxels of resolution_m under the free leaves. */
  std::uint64_t free_voxels{0};
  /** \brief Voxels of the map outside OctoMap's key range (2^16 voxels along each
   * axis, centred on the origin), left out of the file. */
  std::uint64_t skipped_voxels{0};
};

} // namespace planar_grid
