// SPDX-License-Identifier: BSD-3-Clause
// Writing an octomap::OcTree built by the map's export: the pruning both layers use and
// the choice between OctoMap's two file formats. Private to src/map.
#pragma once

#include <planar_grid/core/atomic_file.h>

#include <octomap/OcTree.h>

#include <filesystem>
#include <string>

namespace planar_grid {
namespace octomap_writer {

/** \brief Collapses, bottom-up, every node of \a node's subtree whose eight children
 * are leaves of one value (OctoMap's pruning, at every depth; OcTree::prune() stops at
 * the first depth where nothing collapses). */
inline void
pruneSubtree(octomap::OcTree& tree, octomap::OcTreeNode* node)
{
  if (!tree.nodeHasChildren(node))
    return;
  for (unsigned child = 0; child < 8; ++child)
    if (tree.nodeChildExists(node, child))
      pruneSubtree(tree, tree.getNodeChild(node, child));
  tree.pruneNode(node);
}

/** \brief True for a path ending in ".ot" (OctoMap's full format). */
inline bool
isFullFormat(const std::string& path)
{
  return std::filesystem::path(path).extension() == ".ot";
}

/** \brief Prunes \a tree completely and writes it atomically: ".ot" as OctoMap's full
 * format (AbstractOcTree::write: every node's log-odds as a float), anything else as
 * the binary format (OcTree::writeBinary: the maximum-likelihood free / occupied state
 * of each node, 2 bits). The binary write converts \a tree to maximum likelihood.
 * \throws planar_grid::IOError when the file cannot be written */
inline void
write(octomap::OcTree& tree, const std::string& path)
{
  tree.updateInnerOccupancy();
  if (tree.getRoot() != nullptr)
    pruneSubtree(tree, tree.getRoot());
  const bool full = isFullFormat(path);
  writeFileAtomically(path, [&tree, full](const std::string& temporary) {
    return full ? tree.write(temporary) : tree.writeBinary(temporary);
  });
}

} // namespace octomap_writer
} // namespace planar_grid
