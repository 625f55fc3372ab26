// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/eval/standard_voxel_grid.h>

#include <Eigen/Core>

#include <cstddef>
#include <memory>
#include <vector>

namespace planar_grid {

/** \brief An axis-aligned box of voxels [min_index, min_index + size) of one occupancy
 * class: a cell of RA. \ingroup eval */
struct AxisAlignedBox {
  /** \brief Index of the voxel at the minimum corner. */
  VoxelIndex min_index;
  /** \brief Extent in voxels along x, y, z (each >= 1). */
  Eigen::Vector3i size;
  /** \brief True for a box of occupied voxels, false for free ones. */
  bool occupied;
};

/** \brief RA's boxes (the vector's capacity is what getMemoryBytes() counts).
 * \ingroup eval */
using AxisAlignedBoxes = std::vector<AxisAlignedBox>;

/** \brief RA, the rectangular cuboid approximation of the comparison in Sec. IV-B of
 * Zhang et al. (Figs. 12-14), after RMAP (Khan et al., "Rectangular maps for 3D
 * environment mapping", Autonomous Robots 2014): the observed voxels of a
 * StandardVoxelGrid covered by axis-aligned boxes, each of one occupancy class
 * (occupied: StandardVoxelGrid::isOccupied(), else free).
 *
 * Greedy merge: the voxels are visited in (z, y, x) order; an uncovered voxel starts a
 * box, which grows along +x while the next voxel is observed, uncovered and of the
 * same class, then along +y while the whole next row (all its x) is, then along +z
 * while the whole next slab (all its x and y) is; its voxels become covered. Every
 * observed voxel ends in exactly one box; unobserved voxels are in none. An empty grid
 * gives no boxes. Boxes are emitted in the (z, y, x) order of their min_index.
 * \ingroup eval */
class RectangularCuboidApproximation {
public:
  using Ptr = std::shared_ptr<RectangularCuboidApproximation>;
  using ConstPtr = std::shared_ptr<const RectangularCuboidApproximation>;

  /** \brief Covers the observed voxels of \a grid with boxes.
   * \param[in] grid the standard voxel grid
   * \param[out] boxes the boxes (replaced; shrunk to fit, so that getMemoryBytes()
   * counts the boxes, not the vector's growth slack) */
  void compute(const StandardVoxelGrid& grid, AxisAlignedBoxes& boxes) const;

  /** \brief Bytes held by \a boxes: capacity x sizeof(AxisAlignedBox) (28 bytes: two
   * index triples and the class flag, padded). */
  [[nodiscard]] static std::size_t getMemoryBytes(const AxisAlignedBoxes& boxes);
};

} // namespace planar_grid
