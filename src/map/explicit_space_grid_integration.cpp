// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid::integrateDepthImage(): the voxels of a camera frustum projected
// into the depth image (blocks and 4^3 cubes decided whole through the depth pyramid,
// the rest voxel by voxel), then the occupied voxel of every measured pixel.
// The free / occluded pass over the view's blocks is in explicit_space_grid_view.cpp.
#include <planar_grid/map/explicit_space_grid.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <vector>

#include "explicit_space_grid_impl.h"
#include "explicit_space_grid_row_keys.h"
#include "explicit_space_grid_view.h"

namespace planar_grid {

using namespace explicit_space;

namespace {

/** \brief Bit i of \a b moved to bit 2 i. */
inline std::uint64_t
spreadBits(std::uint32_t b)
{
  std::uint64_t x = b;
  x = (x | (x << 16)) & 0x0000FFFF0000FFFFULL;
  x = (x | (x << 8)) & 0x00FF00FF00FF00FFULL;
  x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0FULL;
  x = (x | (x << 2)) & 0x3333333333333333ULL;
  x = (x | (x << 1)) & 0x5555555555555555ULL;
  return x;
}

/** \brief Puts the observations into the edit buffer, block by block: free writes
 * free, occluded turns only the never-observed voxels unknown. */
void
applyObservations(const std::vector<std::vector<BlockResult>>& per_thread,
                  std::uint8_t prior,
                  BlockStorage& storage)
{
  const auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
  const auto unknown_code = static_cast<std::uint8_t>(SpaceState::UNKNOWN);
  constexpr std::uint64_t LOW = 0x5555555555555555ULL;
  for (const auto& list : per_thread)
    for (const BlockResult& res : list) {
      const std::uint32_t e = storage.open(res.key, prior);
      if (res.kind == BlockResult::ALL_FREE) {
        // Whole block in front of the surface: free without per-voxel work (observed
        // free is never the code of the prior).
        storage.edits[e].uniform = free_code;
        continue;
      }
      Payload& words = storage.mixedPayload(e);
      for (int k = 0; k < 16; ++k) {
        // voxels 32 k .. 32 k + 31: half of mask word k / 2
        const int shift = (k & 1) * 32;
        const std::uint64_t fs =
          res.kind == BlockResult::ALL_OCCLUDED
            ? 0
            : spreadBits(static_cast<std::uint32_t>(
              res.free[static_cast<std::size_t>(k >> 1)] >> shift));
        const std::uint64_t os =
          res.kind == BlockResult::ALL_OCCLUDED
            ? LOW
            : spreadBits(static_cast<std::uint32_t>(
              res.occluded[static_cast<std::size_t>(k >> 1)] >> shift));
        std::uint64_t w = words[static_cast<std::size_t>(k)];
        const std::uint64_t x = w ^ pattern(prior);
        const std::uint64_t at_prior = ~(x | (x >> 1)) & LOW;
        // occluded turns only the never-observed voxels unknown
        const std::uint64_t occ = os & at_prior;
        w &= ~((fs | occ) * 3);  // free = 00
        w |= occ * unknown_code; // unknown = 10
        words[static_cast<std::size_t>(k)] = w;
      }
    }
}

/** \brief Writes occupied the voxel of every measured pixel within max_range into the
 * edit buffer. The keys of a row come first, from a loop the compiler vectorises;
 * neighbouring pixels mostly fall in one voxel, which is written once per run of
 * them. */
void
markMeasuredVoxels(const ViewGeometry& view,
                   double resolution_m,
                   std::uint8_t prior,
                   IntegrationWorkspace& workspace,
                   BlockStorage& storage)
{
  const DepthPyramid& pyr = workspace.pyramid;
  const int W = view.W, H = view.H;
  BlockStorage::Cursor cursor(storage, prior);
  const auto occupied_code = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  const float inv_res = 1.0f / view.res;
  const auto w = static_cast<std::size_t>(W);
  std::vector<float>& column_x = workspace.column_x; // (u - cx) / fx
  column_x.resize(w);
  for (int u = 0; u < W; ++u)
    column_x[static_cast<std::size_t>(u)] = (static_cast<float>(u) - view.cx) / view.fx;
  workspace.row_kx.resize(w);
  workspace.row_ky.resize(w);
  workspace.row_kz.resize(w);
  workspace.row_ok.resize(w);
  int* const row_kx = workspace.row_kx.data();
  int* const row_ky = workspace.row_ky.data();
  int* const row_kz = workspace.row_kz.data();
  int* const row_ok = workspace.row_ok.data();
  const RowKeys kernel_keys{view.w_T_c.linear(), view.w_T_c.translation(),
                            column_x.data(), view.max_range, inv_res};
  // Every pixel's coordinates, (x, y, z) = z ((u - cx) / fx, (v - cy) / fy, 1) with
  // z in [0, max_range], lie within |t| + z (|(u - cx) / fx| + |(v - cy) / fy| + 1)
  // of the origin; below 2^29 voxels, with room for rounding, no conversion overflows.
  const float column_reach =
    std::max(std::abs(column_x.front()), std::abs(column_x.back()));
  const float row_reach =
    std::max(std::abs(view.cy / view.fy),
             std::abs((static_cast<float>(H - 1) - view.cy) / view.fy));
  const double reach_voxels =
    (static_cast<double>(kernel_keys.t.cwiseAbs().maxCoeff())
     + static_cast<double>(view.max_range)
         * (static_cast<double>(column_reach) + static_cast<double>(row_reach) + 1.0))
    / resolution_m;
  const bool clamp = !(reach_voxels < MAX_KEY / 2.0);
  for (int v = 0; v < H; ++v) {
    const float yn = (static_cast<float>(v) - view.cy) / view.fy;
    const float* row = &pyr.min_level[0][static_cast<std::size_t>(v) * w];
    if (clamp)
      rowKeys<true>(row, W, yn, kernel_keys, row_kx, row_ky, row_kz, row_ok);
    else
      rowKeys<false>(row, W, yn, kernel_keys, row_kx, row_ky, row_kz, row_ok);
    // |key| < 2^30 above: no voxel has this key
    int last_x = std::numeric_limits<int>::min(), last_y = 0, last_z = 0;
    // Only the pixels that start a run can hold another voxel than the last written;
    // one after a pixel without measurement may still repeat it.
    for (int first = 0; first < W; first += 64)
      for (std::uint64_t todo = runStarts(row_kx, row_ky, row_kz, row_ok, W, first);
           todo != 0; todo &= todo - 1) {
        const int u = first + __builtin_ctzll(todo);
        const int kx = row_kx[u], ky = row_ky[u], kz = row_kz[u];
        if (kx == last_x && ky == last_y && kz == last_z)
          continue;
        last_x = kx;
        last_y = ky;
        last_z = kz;
        int i = 0;
        const std::uint32_t e = cursor.at(kx, ky, kz, i);
        storage.setEdit(e, i, occupied_code);
      }
  }
}

/** \brief Whether the depth image and the pose can be integrated (sizes agree, the
 * intrinsics positive and finite, the pose finite); false after a warning or an
 * error message. */
bool
checkDepthImage(const DepthImage& depth, const Eigen::Isometry3d& world_T_camera)
{
  if (depth.width <= 0 || depth.height <= 0 || depth.depth_m.empty()) {
    PCL_WARN("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Empty depth image, "
             "nothing integrated.\n");
    return false;
  }
  if (!depth.isConsistent() || !world_T_camera.matrix().allFinite()) {
    PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Inconsistent "
              "depth image (%d x %d with %zu depths, fx %g, fy %g) or pose; nothing "
              "integrated.\n",
              depth.width, depth.height, depth.depth_m.size(),
              static_cast<double>(depth.fx), static_cast<double>(depth.fy));
    return false;
  }
  return true;
}

} // namespace

void
ExplicitSpaceGrid::integrateDepthImage(const DepthImage& depth,
                                       const Eigen::Isometry3d& world_T_camera)
{
  if (!checkDepthImage(depth, world_T_camera))
    return;

  BlockStorage& storage = impl_->storage;
  IntegrationWorkspace& workspace = impl_->workspace;
  DepthPyramid& pyr = workspace.pyramid;
  float max_valid_depth = 0.0f;
  pyr.build(depth, max_valid_depth);

  ViewGeometry view;
  view.res = static_cast<float>(params_.resolution_m);
  view.max_range = static_cast<float>(params_.max_range_m);
  view.margin = params_.surface_margin_m > 0.0
                  ? static_cast<float>(params_.surface_margin_m)
                  : static_cast<float>(params_.resolution_m * std::sqrt(3.0) / 2.0);
  const auto prior = priorCode(params_.prior);
  view.mark_occluded = params_.prior != SpaceState::UNKNOWN;
  // With an unknown prior, occlusion changes nothing: only space up to the farthest
  // measurement can change.
  view.z_far = view.mark_occluded
                 ? view.max_range
                 : std::min(view.max_range, max_valid_depth + view.margin);
  view.W = depth.width;
  view.H = depth.height;
  view.fx = depth.fx;
  view.fy = depth.fy;
  view.cx = depth.cx;
  view.cy = depth.cy;
  view.u_end = static_cast<float>(view.W) - 0.5f;
  view.v_end = static_cast<float>(view.H) - 0.5f;
  view.max_r = std::max(view.W, view.H);
  view.half_diag_px = std::max(view.fx, view.fy) * view.res * 0.8660254f;
  view.w_T_c = world_T_camera.cast<float>();
  view.R_cw = view.w_T_c.linear().transpose();
  view.t_cw = -(view.R_cw * view.w_T_c.translation());
  view.ex = view.R_cw.col(0) * view.res;
  view.ey = view.R_cw.col(1) * view.res;
  view.ez = view.R_cw.col(2) * view.res;

  // Voxels of the measured surface: every valid pixel within max_range back-projected.
  // Done after the free / occluded pass so that it wins.
  if (max_valid_depth > 0.0f && view.z_far > NEAR_Z) {
    // Frustum bounding box in the world frame.
    Eigen::Vector3f lo = view.w_T_c.translation(), hi = lo;
    for (const float u : {-0.5f, view.u_end})
      for (const float v : {-0.5f, view.v_end}) {
        const Eigen::Vector3f pc((u - view.cx) / view.fx * view.z_far,
                                 (v - view.cy) / view.fy * view.z_far, view.z_far);
        const Eigen::Vector3f pw = view.w_T_c * pc;
        lo = lo.cwiseMin(pw);
        hi = hi.cwiseMax(pw);
      }
    const double span =
      static_cast<double>((hi - lo).maxCoeff()) / params_.resolution_m;
    if (span > 1e6
        || std::abs(lo.cast<double>().maxCoeff()) / params_.resolution_m > 1e9
        || std::abs(lo.cast<double>().minCoeff()) / params_.resolution_m > 1e9
        || std::abs(hi.cast<double>().maxCoeff()) / params_.resolution_m > 1e9
        || std::abs(hi.cast<double>().minCoeff()) / params_.resolution_m > 1e9) {
      PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Frustum of "
                "%g voxels across or far from the origin; nothing integrated.\n",
                span);
      return;
    }
    const VoxelKey klo = toKey(lo), khi = toKey(hi);
    const BlockKey blo{blockOf(klo.x()), blockOf(klo.y()), blockOf(klo.z())};
    const BlockKey bhi{blockOf(khi.x()), blockOf(khi.y()), blockOf(khi.z())};

    // Every footprint radius is at least that of a voxel at z_far.
    pyr.buildSpans(pyr.levelFor(
      std::min(static_cast<int>(std::ceil(view.half_diag_px / view.z_far)), view.max_r)
      + 1));
    // The observations go to the edit buffer, block by block; the occupied voxels
    // below are written over them, and both reach the storage at once.
    const Counters total =
      observeView(view, pyr, storage, blo, bhi, num_threads_, workspace.results);
    applyObservations(workspace.results, prior, storage);
    PCL_DEBUG("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] %zu blocks "
              "seen, %zu free as a whole, %zu 4^3 cubes voxel by voxel.\n",
              total.visited, total.fast, total.slow);
  }

  markMeasuredVoxels(view, params_.resolution_m, prior, workspace, storage);
  storage.commit(prior);
}

} // namespace planar_grid
