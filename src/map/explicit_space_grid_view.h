// SPDX-License-Identifier: BSD-3-Clause
// One depth image's view in ExplicitSpaceGrid::integrateDepthImage(): its camera in the
// grid, and the free / occluded pass over the blocks of its frustum
// (explicit_space_grid_view.cpp), which the integration
// (explicit_space_grid_integration.cpp) then writes into the storage. Private to
// src/map.
#pragma once

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

#include "explicit_space_grid_integration.h"
#include "explicit_space_grid_storage.h"

namespace planar_grid {
namespace explicit_space {

/** \brief Nearest camera depth considered, meters (avoids the projection pole). */
constexpr float NEAR_Z = 1e-3f;

/** \brief Counters of the free / occluded pass (debug output). */
struct Counters {
  std::size_t visited{0}, fast{0}, slow{0};
};

/** \brief One depth image's camera in the grid: intrinsics, pose, ranges and the voxel
 * axes, computed once per view. */
struct ViewGeometry {
  int W, H;
  float fx, fy, cx, cy;
  /** \brief The image's far pixel edges, W - 0.5 and H - 0.5, pixels. */
  float u_end, v_end;
  /** \brief Voxel edge, meters. */
  float res;
  float max_range, margin;
  /** \brief Farthest camera depth the view can change, meters. */
  float z_far;
  bool mark_occluded;
  /** \brief Pixel footprint of a voxel's half diagonal at depth 1 m, pixels. */
  float half_diag_px;
  int max_r;
  Eigen::Isometry3f w_T_c;
  Eigen::Matrix3f R_cw;
  Eigen::Vector3f t_cw;
  /** \brief The voxel axes in the camera frame, one voxel edge long, meters. */
  Eigen::Vector3f ex, ey, ez;
};

/** \brief The free / occluded pass of one view: observeBlocks() of the blocks from
 * \a blo to \a bhi with the view's BlockObserver (over \a view, the depth pyramid
 * \a pyr and \a storage); returns the summed counters. */
Counters observeView(const ViewGeometry& view,
                     const DepthPyramid& pyr,
                     const BlockStorage& storage,
                     const BlockKey& blo,
                     const BlockKey& bhi,
                     int num_threads,
                     std::vector<std::vector<BlockResult>>& per_thread);

} // namespace explicit_space
} // namespace planar_grid
