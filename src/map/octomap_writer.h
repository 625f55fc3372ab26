// SPDX-License-Identifier: BSD-3-Clause
// Writing an octomap::OcTree built by the map's export: the pruning both layers use,
// the choice between OctoMap's two file formats and the count of what was written.
// Private to src/map.
#pragma once

#include <planar_grid/core/atomic_file.h>
#include <planar_grid/map/octomap_export_summary.h>

#include <octomap/OcTree.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
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

/** \brief The nodes, leaves and voxels of \a tree, counted as liboctomap counts a tree
 * it reads (OcTree::size(), getNumLeafNodes(), isNodeOccupied() per leaf; a leaf at
 * depth d holds 8^(tree depth - d) voxels). */
inline OctoMapExportSummary
summarize(const octomap::OcTree& tree)
{
  OctoMapExportSummary summary;
  summary.nodes = tree.size();
  summary.leaf_nodes = tree.getNumLeafNodes();
  const unsigned tree_depth = tree.getTreeDepth();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const std::uint64_t voxels = std::uint64_t{1} << (3 * (tree_depth - it.getDepth()));
    if (tree.isNodeOccupied(*it)) {
      ++summary.occupied_leaves;
      summary.occupied_voxels += voxels;
    } else {
      ++summary.free_leaves;
      summary.free_voxels += voxels;
    }
  }
  return summary;
}

/** \brief Writes \a tree in OctoMap's binary format (.bt) to \a path, byte for byte
 * what OcTree::writeBinaryConst() writes (its header, then
 * OccupancyOcTreeBase::writeBinaryData()), without liboctomap's " done." on stderr
 * (Debian builds it with its debug output on).
 * \return false when the file cannot be written */
inline bool
writeBinaryQuietly(const octomap::OcTree& tree, const std::string& path)
{
  std::ofstream out(path, std::ios_base::out | std::ios_base::binary);
  if (!out.is_open())
    return false;
  out
    << "# Octomap OcTree binary file\n# (feel free to add / change comments, but leave "
       "the first line as it is!)\n#\n";
  out << "id " << tree.getTreeType() << std::endl;
  out << "size " << tree.size() << std::endl;
  out << "res " << tree.getResolution() << std::endl;
  out << "data" << std::endl;
  tree.writeBinaryData(out);
  out.close();
  return !out.fail();
}

/** \brief Converts \a tree to maximum likelihood when \a max_likelihood (what the
 * binary format keeps), updates its inner nodes and prunes it completely, so that
 * nodes whose voxels differ in log-odds but not in state collapse too (writeBinary's
 * own prune() stops at the first depth where nothing collapses). */
inline void
finish(octomap::OcTree& tree, bool max_likelihood)
{
  if (max_likelihood)
    tree.toMaxLikelihood();
  tree.updateInnerOccupancy();
  if (tree.getRoot() != nullptr)
    pruneSubtree(tree, tree.getRoot());
}

/** \brief Prunes \a tree completely and writes it atomically: ".ot" as OctoMap's full
 * format (AbstractOcTree::write: every node's log-odds as a float), anything else as
 * the binary format (OcTree::writeBinary: the maximum-likelihood free / occupied state
 * of each node, 2 bits). For the binary format \a tree is converted to maximum
 * likelihood before the pruning, so that nodes whose voxels differ in log-odds but
 * not in state collapse too (writeBinary's own prune() stops at the first depth where
 * nothing collapses).
 * \return what the file holds (summarize() of the tree as written)
 * \throws planar_grid::IOError when the file cannot be written */
inline OctoMapExportSummary
write(octomap::OcTree& tree, const std::string& path)
{
  const bool full = isFullFormat(path);
  finish(tree, !full);
  writeFileAtomically(path, [&tree, full](const std::string& temporary) {
    // The tree is in maximum likelihood and pruned already: what writeBinary() would
    // do before writing changes nothing.
    return full ? tree.write(temporary) : writeBinaryQuietly(tree, temporary);
  });
  return summarize(tree);
}

} // namespace octomap_writer
} // namespace planar_grid
