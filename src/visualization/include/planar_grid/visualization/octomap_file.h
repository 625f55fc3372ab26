// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>

#include <cstddef>
#include <string>

namespace planar_grid {

/** \brief The leaves of an OctoMap octree, for drawing. \ingroup visualization */
struct OctoMapLeaves {
  /** \brief Voxel edge of the tree (its resolution), meters. */
  double resolution_m{0.0};
  /** \brief One axis-aligned box per occupied leaf (a pruned leaf is one larger box):
   * centre and edge (width_m = height_m = thickness_m) in meters, probability the
   * leaf's occupancy in [0, 1], plane_id -1. */
  PlanarCuboids occupied;
  /** \brief Occupied voxels (of resolution_m edge) the boxes cover. */
  std::size_t occupied_voxels{0};
  /** \brief Free voxels (of resolution_m edge) of the free leaves. */
  std::size_t free_voxels{0};
};

/** \brief Checks that \a path is an OctoMap octree file that liboctomap can read
 * safely, before it does: liboctomap's readers take any header and then read the node
 * stream without checking for its end, so a truncated or corrupt stream reads
 * indeterminate bytes and can recurse without bound. The file must be a non-empty
 * regular file that starts with "# Octomap OcTree binary file" (.bt,
 * OcTree::writeBinary) or "# Octomap OcTree file" (.ot, AbstractOcTree::write), whose
 * header gives "id OcTree", "size <n>", "res <r>" (r > 0) and ends with "data"; and
 * whose node stream is complete, no deeper than OctoMap's 16 levels, without trailing
 * bytes and (.ot) of finite log-odds. The walk reads each node's child bits only (2
 * bits per child in .bt, a 4-byte float and an 8-bit child mask per node in .ot).
 * \param[in] path the file
 * \throws planar_grid::IOError naming the file and the cause ("the file is empty (0
 * bytes)", "not an OctoMap file: ...", "truncated: ...", "id ColorOcTree is not ...")
 * \ingroup visualization */
void checkOctoMapFile(const std::string& path);

/** \brief Reads an OctoMap .bt or .ot file (checkOctoMapFile(), then liboctomap's
 * OcTree::readBinary or AbstractOcTree::read) and lists its leaves.
 * \param[in] path the file
 * \param[in] max_boxes most occupied boxes listed (the counts cover every leaf)
 * \throws planar_grid::IOError naming the file and the cause
 * \ingroup visualization */
OctoMapLeaves loadOctoMapLeaves(const std::string& path,
                                std::size_t max_boxes = 2000000);

} // namespace planar_grid
