// SPDX-License-Identifier: BSD-3-Clause
// The free / occluded pass of ExplicitSpaceGrid::integrateDepthImage() over one view:
// the voxels of the camera frustum projected into the depth image, blocks and 4^3
// cubes decided whole through the depth pyramid, the rest voxel by voxel.
#include "explicit_space_grid_view.h"

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <thread>
#include <vector>

#include "explicit_space_grid_integration.h"
#include "explicit_space_grid_row_keys.h"
#include "explicit_space_grid_storage.h"

namespace planar_grid {
namespace explicit_space {

namespace {

/** \brief What the per-voxel test of one view reads: camera, thresholds, the depth
 * pyramid and the voxel axes (copied to locals where the test runs). */
struct VoxelKernel {
  float fx, fy, cx, cy, u_end, v_end, max_range, margin;
  int W, H;
  bool mark_occluded;
  const float* depth0; // min_level[0]: the measured depth per pixel, +inf for none
  const DepthPyramid* pyramid;
  /** \brief The voxel axes in the camera frame, one voxel edge long, meters. */
  Eigen::Vector3f ex, ey, ez;
};

/** \brief A 4^3 cube of a block, the unit of the per-voxel test, with the depth
 * pyramid level its voxels' footprints are read at. */
struct CubeQuery {
  /** \brief Min corner of the block, camera frame, meters. */
  Eigen::Vector3f c0;
  /** \brief Local offset of the cube in the block, voxels (0 or 4 each). */
  int ox, oy, oz;
  /** \brief Pyramid level: at most 3 x 3 cells per footprint. */
  int level;
  /** \brief Footprint radius of the cube's voxels, pixels. */
  int r;
};

/** \brief Eight points of a cube (its corners, or its corner voxels' centres), camera
 * frame, meters, coordinate by coordinate. */
struct Corners {
  float x[8], y[8], z[8];
};

/** \brief The smallest and largest of eight numbers (none NaN), halves first so that
 * the compiler vectorises it. */
inline void
minMax8(const float* a, float& lo, float& hi)
{
  float l[4], h[4];
  for (int i = 0; i < 4; ++i) {
    l[i] = std::min(a[i], a[i + 4]);
    h[i] = std::max(a[i], a[i + 4]);
  }
  lo = std::min(std::min(l[0], l[1]), std::min(l[2], l[3]));
  hi = std::max(std::max(h[0], h[1]), std::max(h[2], h[3]));
}

/** \brief The pixel bounds of eight points in front of the camera (z > 0): the
 * extremes of u = fx x / z + cx and v = fy y / z + cy, in one loop the compiler
 * vectorises (the same arithmetic per point as a scalar loop). */
inline void
projectCorners(const Corners& p,
               float fx,
               float fy,
               float cx,
               float cy,
               float& umin,
               float& umax,
               float& vmin,
               float& vmax)
{
  float u[8], v[8];
  for (int i = 0; i < 8; ++i) {
    const float inv = 1.0f / p.z[i];
    u[i] = fx * p.x[i] * inv + cx;
    v[i] = fy * p.y[i] * inv + cy;
  }
  minMax8(u, umin, umax);
  minMax8(v, vmin, vmax);
}

/** \brief What the 8 corner centres of a 4^3 cube tell of observeCube()'s per-voxel
 * test for all 64 voxels. */
enum class CubeBound : std::uint8_t {
  UNDECIDED, // the 64 centres must be tested
  ALL_FREE,  // every voxel is free
  NONE_FREE  // no voxel is free (and without mark_occluded, none is observed)
};

/** \brief Bounds observeCube()'s per-voxel test over the 4^3 cube \a cube from its 8
 * corner centres instead of all 64 projections. The projection is monotone along any
 * line, so the extremes of the centres' pixel coordinates and depths are those of the
 * corner centres; they are widened by a pixel and 1 mm against rounding. ALL_FREE:
 * every centre is in range and inside the image, and every level cell meeting the union
 * of the footprints holds a measurement the largest centre depth is in front of (minus
 * the margin), so every voxel passes its own test. NONE_FREE: the smallest centre depth
 * is not in front of any level cell that holds a centre's pixel (minus the margin);
 * each voxel's footprint contains its own pixel's cell, so no voxel passes. */
CubeBound
boundCube(const VoxelKernel& kernel, const CubeQuery& cube)
{
  const Eigen::Vector3f &c0 = cube.c0, &ex = kernel.ex, &ey = kernel.ey,
                        &ez = kernel.ez;
  const int ox = cube.ox, oy = cube.oy, oz = cube.oz, level = cube.level, r = cube.r;
  const auto l = static_cast<std::size_t>(level);
  const float* const lmin = kernel.pyramid->min_level[l].data();
  const int level_width = kernel.pyramid->w[l];
  constexpr float SLACK_PX = 1.0f, SLACK_M = 1e-3f, FAR_PX = 1e6f;
  constexpr float FLT_LIMIT = std::numeric_limits<float>::max();
  // The 8 corner centres, coordinate by coordinate, as c0 + a ex + b ey + c ez
  // evaluates them; then their projections, in loops the compiler vectorises.
  const float a[2] = {static_cast<float>(ox) + 0.5f, static_cast<float>(ox + 3) + 0.5f};
  const float b[2] = {static_cast<float>(oy) + 0.5f, static_cast<float>(oy + 3) + 0.5f};
  const float c[2] = {static_cast<float>(oz) + 0.5f, static_cast<float>(oz + 3) + 0.5f};
  Corners p;
  for (int i = 0; i < 8; ++i) {
    const float ai = a[i & 1], bi = b[(i >> 1) & 1], ci = c[i >> 2];
    p.x[i] = ((c0.x() + ai * ex.x()) + bi * ey.x()) + ci * ez.x();
    p.y[i] = ((c0.y() + ai * ex.y()) + bi * ey.y()) + ci * ez.y();
    p.z[i] = ((c0.z() + ai * ex.z()) + bi * ey.z()) + ci * ez.z();
  }
  float zmin, zmax;
  minMax8(p.z, zmin, zmax);
  if (!(zmin > NEAR_Z + SLACK_M))
    return CubeBound::UNDECIDED;
  float umin, umax, vmin, vmax;
  projectCorners(p, kernel.fx, kernel.fy, kernel.cx, kernel.cy, umin, umax, vmin, vmax);
  zmin -= SLACK_M;
  zmax += SLACK_M;
  umin = std::max(umin - SLACK_PX, -FAR_PX);
  umax = std::min(umax + SLACK_PX, FAR_PX);
  vmin = std::max(vmin - SLACK_PX, -FAR_PX);
  vmax = std::min(vmax + SLACK_PX, FAR_PX);
  const auto lw = static_cast<std::ptrdiff_t>(level_width);
  const float margin = kernel.margin;
  if (zmax <= kernel.max_range && umin >= -0.5f && umax < kernel.u_end && vmin >= -0.5f
      && vmax < kernel.v_end) {
    // every centre valid; the footprints' cells as observeCube() bounds them
    const int u0 = static_cast<int>(umin + 0.5f), u1 = static_cast<int>(umax + 0.5f);
    const int v0 = static_cast<int>(vmin + 0.5f), v1 = static_cast<int>(vmax + 0.5f);
    const int cu0 = std::max(u0 - r, 0) >> level,
              cu2 = std::min(u1 + r, kernel.W - 1) >> level;
    const int cv0 = std::max(v0 - r, 0) >> level,
              cv2 = std::min(v1 + r, kernel.H - 1) >> level;
    bool all_free = true;
    for (int cv = cv0; cv <= cv2 && all_free; ++cv) {
      const float* row = lmin + cv * lw;
      for (int cu = cu0; cu <= cu2; ++cu)
        if (!(zmax < row[cu] - margin) || !(row[cu] <= FLT_LIMIT)) {
          all_free = false;
          break;
        }
    }
    if (all_free)
      return CubeBound::ALL_FREE;
  }
  // the cells of the centres' own pixels (those of the valid ones lie in the image)
  const int pu0 = std::max(static_cast<int>(std::floor(umin + 0.5f)), 0),
            pu1 = std::min(static_cast<int>(std::floor(umax + 0.5f)), kernel.W - 1);
  const int pv0 = std::max(static_cast<int>(std::floor(vmin + 0.5f)), 0),
            pv1 = std::min(static_cast<int>(std::floor(vmax + 0.5f)), kernel.H - 1);
  if (pu0 > pu1 || pv0 > pv1)
    return CubeBound::NONE_FREE; // no centre inside the image
  for (int cv = pv0 >> level; cv <= (pv1 >> level); ++cv) {
    const float* row = lmin + cv * lw;
    for (int cu = pu0 >> level; cu <= (pu1 >> level); ++cu)
      if (!(zmin >= row[cu] - margin))
        return CubeBound::UNDECIDED;
  }
  return CubeBound::NONE_FREE;
}

/** \brief Per-voxel observations of the 4^3 cube \a cube: free when the centre is in
 * front of the smallest depth over the level cells meeting its footprint (radius
 * cube.r pixels, at most 3 x 3 cells of cube.level) minus the margin and those cells
 * hold a measurement, occluded (only
 * with mark_occluded) when behind its pixel's depth plus the margin. Sets bits
 * x + 8 y of words z of the block's masks. */
void
observeCube(const VoxelKernel& kernel,
            const CubeQuery& cube,
            std::array<std::uint64_t, BLOCK_EDGE>& free_mask,
            std::array<std::uint64_t, BLOCK_EDGE>& occluded_mask)
{
  const int ox = cube.ox, oy = cube.oy, oz = cube.oz;
  const CubeBound bound = boundCube(kernel, cube);
  if (bound == CubeBound::ALL_FREE) {
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        free_mask[static_cast<std::size_t>(oz + z)] |= std::uint64_t{15}
                                                       << (ox + 8 * (oy + y));
    return;
  }
  if (bound == CubeBound::NONE_FREE && !kernel.mark_occluded) {
    return;
  }
  const Eigen::Vector3f &c0 = cube.c0, &ex = kernel.ex, &ey = kernel.ey,
                        &ez = kernel.ez;
  const int level = cube.level, r = cube.r;
  const DepthPyramid& pyr = *kernel.pyramid;
  const int level_width = pyr.w[static_cast<std::size_t>(level)];
  const float fx = kernel.fx, fy = kernel.fy, cx = kernel.cx, cy = kernel.cy;
  const float u_end = kernel.u_end, v_end = kernel.v_end;
  const float max_range = kernel.max_range, margin = kernel.margin;
  const int W = kernel.W, H = kernel.H;
  const float exx = ex.x(), exy = ex.y(), exz = ex.z();
  // The 64 centres (index x + 4 y + 16 z, local to the cube), then their projections
  // in a branch-free loop the compiler vectorises.
  std::array<float, 64> xs, ys, zs;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const Eigen::Vector3f p0 = c0 + (static_cast<float>(ox) + 0.5f) * ex
                                 + (static_cast<float>(oy + y) + 0.5f) * ey
                                 + (static_cast<float>(oz + z) + 0.5f) * ez;
      float px = p0.x(), py = p0.y(), pz = p0.z();
      for (int x = 0; x < 4; ++x, px += exx, py += exy, pz += exz) {
        const auto i = static_cast<std::size_t>(x + 4 * y + 16 * z);
        xs[i] = px;
        ys[i] = py;
        zs[i] = pz;
      }
    }
  std::array<int, 64> us, vs;
  std::array<std::uint8_t, 64> in; // in range and inside the image
  const auto u_max = static_cast<float>(W - 1), v_max = static_cast<float>(H - 1);
  for (std::size_t i = 0; i < 64; ++i) {
    const float zc = zs[i];
    const float inv = 1.0f / zc;
    const float u = fx * xs[i] * inv + cx, v = fy * ys[i] * inv + cy;
    const int ok = static_cast<int>(zc > NEAR_Z) & static_cast<int>(zc <= max_range)
                   & static_cast<int>(u >= -0.5f) & static_cast<int>(u < u_end)
                   & static_cast<int>(v >= -0.5f) & static_cast<int>(v < v_end);
    in[i] = static_cast<std::uint8_t>(ok);
    // clamped into the image (NaN to 0), which leaves the valid centres' pixels as they
    // are: int(u + 0.5) for u in [-0.5, W - 0.5)
    us[i] = static_cast<int>(std::min(u_max, std::max(0.0f, u)) + 0.5f);
    vs[i] = static_cast<int>(std::min(v_max, std::max(0.0f, v)) + 0.5f);
  }
  // The smallest valid depth over the level cells meeting each footprint: one lookup
  // in the pyramid's minimum over the 1 to 3 cells it spans per axis. The cells come
  // from a loop the compiler vectorises, then the look-ups, then the test, again
  // vectorised (every centre's pixel is clamped into the image, so every look-up is
  // in bounds, the invalid centres' too).
  std::array<const float*, 9> span_min;
  for (int k = 0; k < 9; ++k)
    span_min[static_cast<std::size_t>(k)] = pyr.spanMin(level, k);
  std::array<int, 64> span_k, span_offset;
  for (std::size_t i = 0; i < 64; ++i) {
    const int ui = us[i], vi = vs[i];
    const int cu0 = std::max(ui - r, 0) >> level,
              cu2 = std::min(ui + r, W - 1) >> level;
    const int cv0 = std::max(vi - r, 0) >> level,
              cv2 = std::min(vi + r, H - 1) >> level;
    span_k[i] = 3 * (cu2 - cu0) + (cv2 - cv0);
    span_offset[i] = cv0 * level_width + cu0;
  }
  std::array<float, 64> fmin;
  for (std::size_t i = 0; i < 64; ++i)
    fmin[i] = span_min[static_cast<std::size_t>(span_k[i])][span_offset[i]];
  // A footprint without any measurement (+inf) says nothing: the voxel is not free.
  constexpr float FLT_LIMIT = std::numeric_limits<float>::max();
  std::array<std::uint8_t, 64> is_free;
  for (std::size_t i = 0; i < 64; ++i)
    is_free[i] = static_cast<std::uint8_t>(
      in[i] & static_cast<std::uint8_t>(zs[i] < fmin[i] - margin)
      & static_cast<std::uint8_t>(fmin[i] <= FLT_LIMIT));
  const std::uint64_t valid = packBits(in), free_bits = packBits(is_free);
  std::uint64_t occ_bits = 0;
  if (kernel.mark_occluded) {
    const float inf = std::numeric_limits<float>::infinity();
    for (std::uint64_t todo = valid & ~free_bits; todo != 0; todo &= todo - 1) {
      const int i = __builtin_ctzll(todo);
      const auto si = static_cast<std::size_t>(i);
      const float d = kernel.depth0[static_cast<std::ptrdiff_t>(vs[si]) * W
                                    + static_cast<std::ptrdiff_t>(us[si])];
      occ_bits |= static_cast<std::uint64_t>(d < inf && zs[si] > d + margin) << i;
    }
  }
  // cube bits x + 4 y + 16 z to block bits (ox + x) + 8 (oy + y) of word oz + z
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const int shift = 4 * y + 16 * z, to = ox + 8 * (oy + y);
      free_mask[static_cast<std::size_t>(oz + z)] |= ((free_bits >> shift) & 15u) << to;
      occluded_mask[static_cast<std::size_t>(oz + z)] |= ((occ_bits >> shift) & 15u)
                                                         << to;
    }
}

/** \brief How a cube of voxels is observed as a whole. */
enum class Cube { NONE, FREE, OCCLUDED, SPLIT };

/** \brief The pixel region a cube projects to. */
struct CubeInfo {
  int r{0};                       // footprint radius of its voxels, pixels
  int u0{0}, v0{0}, u1{0}, v1{0}; // pixel region (clamped)
};

/** \brief Classifies the cube of s^3 voxels whose min corner is \a c (camera frame,
 * meters) through the depth pyramid, filling \a info unless the cube is NONE. */
Cube
classifyCube(const ViewGeometry& view,
             const DepthPyramid& pyr,
             const Eigen::Vector3f& c,
             float s,
             CubeInfo& info)
{
  const Eigen::Vector3f sx = s * view.ex, sy = s * view.ey, sz = s * view.ez;
  // corner i = ((c + sx if i & 1) + sy if i & 2) + sz if i & 4, coordinate by
  // coordinate
  Corners p;
  const auto corners = [](float c, float x, float y, float z, float* out) {
    const float base[4] = {c, c + x, c + y, (c + x) + y};
    for (int i = 0; i < 4; ++i) {
      out[i] = base[i];
      out[i + 4] = base[i] + z;
    }
  };
  corners(c.x(), sx.x(), sy.x(), sz.x(), p.x);
  corners(c.y(), sx.y(), sy.y(), sz.y(), p.y);
  corners(c.z(), sx.z(), sy.z(), sz.z(), p.z);
  float zmin, zmax;
  minMax8(p.z, zmin, zmax);
  if (zmax <= NEAR_Z || zmin > view.z_far)
    return Cube::NONE;
  if (zmin <= NEAR_Z) { // straddles the camera plane: voxel by voxel
    info = {view.max_r, 0, 0, view.W - 1, view.H - 1};
    return Cube::SPLIT;
  }
  float umin, umax, vmin, vmax;
  projectCorners(p, view.fx, view.fy, view.cx, view.cy, umin, umax, vmin, vmax);
  if (umax < -0.5f || vmax < -0.5f || umin >= view.u_end || vmin >= view.v_end)
    return Cube::NONE;
  const bool inside =
    umin >= -0.5f && vmin >= -0.5f && umax < view.u_end && vmax < view.v_end;
  info.r = std::min(static_cast<int>(std::ceil(view.half_diag_px / zmin)), view.max_r);
  info.u0 = static_cast<int>(std::floor(umin + 0.5f)) - info.r;
  info.v0 = static_cast<int>(std::floor(vmin + 0.5f)) - info.r;
  info.u1 = static_cast<int>(std::floor(umax + 0.5f)) + info.r;
  info.v1 = static_cast<int>(std::floor(vmax + 0.5f)) + info.r;
  pyr.clampRect(info.u0, info.v0, info.u1, info.v1);
  float mn, mx;
  pyr.queryRect(info.u0, info.v0, info.u1, info.v1, mn, mx);
  if (std::isinf(mn))
    return Cube::NONE; // no measurement under the cube: no information
  if (zmax < mn - view.margin) {
    if (!inside || zmax > view.max_range)
      return Cube::SPLIT;
    // every voxel's footprint must hold a measurement: it contains a whole cell
    // of level j
    const int r_far = static_cast<int>(view.half_diag_px / zmax);
    int j = 0;
    while ((2 << j) <= r_far + 1)
      ++j;
    return pyr.noHoles(j, info.u0, info.v0, info.u1, info.v1) ? Cube::FREE
                                                              : Cube::SPLIT;
  }
  if (zmin > mx + view.margin) { // behind every measurement of the region
    if (!view.mark_occluded)
      return Cube::NONE;
    return inside && zmax <= view.max_range
               && pyr.noHoles(0, info.u0, info.v0, info.u1, info.v1)
             ? Cube::OCCLUDED
             : Cube::SPLIT;
  }
  return Cube::SPLIT;
}

/** \brief Sets the bits of the 4^3 cube at local offset o in a block's mask. */
inline void
setCubeBits(std::array<std::uint64_t, BLOCK_EDGE>& mask, int ox, int oy, int oz)
{
  const std::uint64_t rows = std::uint64_t{0xF0F0F0F} << (ox + 8 * oy);
  for (int z = oz; z < oz + 4; ++z)
    mask[static_cast<std::size_t>(z)] |= rows;
}

/** \brief What one view says of each block of the grid: whole blocks and 4^3 cubes
 * through the depth pyramid, the rest voxel by voxel. Safe to call from several
 * threads at once (it reads the view, the pyramid and the storage). */
class BlockObserver {
public:
  BlockObserver(const ViewGeometry& view,
                const DepthPyramid& pyr,
                const BlockStorage& storage) :
      view_(view),
      pyr_(pyr), storage_(storage), kernel_{view.fx,
                                            view.fy,
                                            view.cx,
                                            view.cy,
                                            view.u_end,
                                            view.v_end,
                                            view.max_range,
                                            view.margin,
                                            view.W,
                                            view.H,
                                            view.mark_occluded,
                                            pyr.min_level[0].data(),
                                            &pyr,
                                            view.ex,
                                            view.ey,
                                            view.ez},
      // Inward unit normals of the frustum's side planes (through the camera centre,
      // along the image border u = -0.5, u = W - 0.5, v = -0.5, v = H - 0.5).
      side_normals_{Eigen::Vector3f(view.fx, 0.0f, view.cx + 0.5f).normalized(),
                    Eigen::Vector3f(-view.fx, 0.0f, view.u_end - view.cx).normalized(),
                    Eigen::Vector3f(0.0f, view.fy, view.cy + 0.5f).normalized(),
                    Eigen::Vector3f(0.0f, -view.fy, view.v_end - view.cy).normalized()},
      block_half_((view.ex + view.ey + view.ez) * (0.5f * BLOCK_EDGE)),
      // half block diagonal plus slack for rounding
      reject_radius_(block_half_.norm() * 1.01f + 1e-3f),
      block_edge_(view.res * BLOCK_EDGE),
      // A voxel already free stays free whatever a view says of it (observed free
      // writes free, occluded changes only never-observed voxels): the 4^3 cubes free
      // in the storage are not observed. Pending setState() edits are not in the
      // storage; with any, every cube is observed.
      skip_stored_free_(storage.edits.empty())
  {}

  /** \brief The observations of block (bx, by, bz) into \a res; false when the view
   * says nothing of it. */
  bool observe(int bx, int by, int bz, BlockResult& res, Counters& counters) const
  {
    const Eigen::Vector3f c0 = view_.R_cw
                                 * Eigen::Vector3f(static_cast<float>(bx) * block_edge_,
                                                   static_cast<float>(by) * block_edge_,
                                                   static_cast<float>(bz) * block_edge_)
                               + view_.t_cw;
    if (outsideFrustum(c0 + block_half_))
      return false;
    const std::uint32_t stored_free =
      skip_stored_free_ ? storage_.storedFreeCubes({bx, by, bz}) : 0u;
    if (stored_free == 0xFFu)
      return false;
    CubeInfo info;
    const Cube kind =
      classifyCube(view_, pyr_, c0, static_cast<float>(BLOCK_EDGE), info);
    if (kind == Cube::NONE)
      return false;
    ++counters.visited;
    res.key = {bx, by, bz};
    if (kind == Cube::FREE) {
      ++counters.fast;
      res.kind = BlockResult::ALL_FREE;
      return true;
    }
    if (kind == Cube::OCCLUDED) {
      res.kind = BlockResult::ALL_OCCLUDED;
      return true;
    }
    return observeCubes(c0, stored_free, res, counters);
  }

private:
  /** \brief Whether a block whose centre is \a centre (camera frame) lies, with its
   * bounding sphere and slack, beyond the depth range or outside a side plane of the
   * frustum: it projects outside the image, and classifyCube() would say NONE. */
  bool outsideFrustum(const Eigen::Vector3f& centre) const
  {
    if (centre.z() + reject_radius_ <= NEAR_Z
        || centre.z() - reject_radius_ > view_.z_far)
      return true;
    if (centre.z() - reject_radius_ > NEAR_Z)
      for (const auto& n : side_normals_)
        if (n.dot(centre) < -reject_radius_)
          return true;
    return false;
  }

  /** \brief The block at \a c0 cube by cube (cubes free in the storage skipped), into
   * the masks of \a res; false when no voxel is observed. */
  bool observeCubes(const Eigen::Vector3f& c0,
                    std::uint32_t stored_free,
                    BlockResult& res,
                    Counters& counters) const
  {
    res.kind = BlockResult::MASKS;
    res.free.fill(0);
    res.occluded.fill(0);
    bool any = false;
    for (int c = 0; c < 8; ++c) {
      if ((stored_free >> c) & 1u)
        continue;
      const int ox = (c & 1) * 4, oy = ((c >> 1) & 1) * 4, oz = ((c >> 2) & 1) * 4;
      const Eigen::Vector3f cc = c0 + static_cast<float>(ox) * view_.ex
                                 + static_cast<float>(oy) * view_.ey
                                 + static_cast<float>(oz) * view_.ez;
      CubeInfo sub;
      const Cube sk = classifyCube(view_, pyr_, cc, 4.0f, sub);
      if (sk == Cube::NONE)
        continue;
      if (sk == Cube::FREE) {
        setCubeBits(res.free, ox, oy, oz);
        any = true;
      } else if (sk == Cube::OCCLUDED) {
        setCubeBits(res.occluded, ox, oy, oz);
        any = true;
      } else {
        ++counters.slow;
        // at most 3 x 3 cells per footprint
        const CubeQuery cube{c0, ox, oy, oz, pyr_.levelFor(sub.r + 1), sub.r};
        observeCube(kernel_, cube, res.free, res.occluded);
      }
    }
    if (!any)
      for (int z = 0; z < BLOCK_EDGE; ++z)
        any = any || res.free[static_cast<std::size_t>(z)] != 0
              || res.occluded[static_cast<std::size_t>(z)] != 0;
    return any;
  }

  const ViewGeometry& view_;
  const DepthPyramid& pyr_;
  const BlockStorage& storage_;
  const VoxelKernel kernel_;
  const std::array<Eigen::Vector3f, 4> side_normals_;
  const Eigen::Vector3f block_half_;
  const float reject_radius_;
  /** \brief A block's edge, meters. */
  const float block_edge_;
  const bool skip_stored_free_;
};

/** \brief Observes the blocks from \a blo to \a bhi (slabs of z split between up to
 * \a num_threads threads, each slab's blocks in x-fastest order: the concatenation is
 * the single-threaded order) into \a per_thread; returns the summed counters. */
Counters
observeBlocks(const BlockObserver& observer,
              const BlockKey& blo,
              const BlockKey& bhi,
              int num_threads,
              std::vector<std::vector<BlockResult>>& per_thread)
{
  const int n_slabs = bhi.z - blo.z + 1;
  const int n_threads = std::max(1, std::min(num_threads, n_slabs));
  per_thread.resize(static_cast<std::size_t>(n_threads));
  std::vector<Counters> counters(static_cast<std::size_t>(n_threads));
  const auto work = [&](int t) {
    auto& out = per_thread[static_cast<std::size_t>(t)];
    out.clear();
    const int z0 =
      blo.z + static_cast<int>(static_cast<long long>(n_slabs) * t / n_threads);
    const int z1 =
      blo.z + static_cast<int>(static_cast<long long>(n_slabs) * (t + 1) / n_threads);
    BlockResult res;
    for (int bz = z0; bz < z1; ++bz)
      for (int by = blo.y; by <= bhi.y; ++by)
        for (int bx = blo.x; bx <= bhi.x; ++bx)
          if (observer.observe(bx, by, bz, res, counters[static_cast<std::size_t>(t)]))
            out.push_back(res);
  };
  if (n_threads == 1)
    work(0);
  else {
    std::vector<std::thread> threads;
    for (int t = 1; t < n_threads; ++t)
      threads.emplace_back(work, t);
    work(0);
    for (auto& th : threads)
      th.join();
  }
  Counters total;
  for (const auto& c : counters) {
    total.visited += c.visited;
    total.fast += c.fast;
    total.slow += c.slow;
  }
  return total;
}

} // namespace

Counters
observeView(const ViewGeometry& view,
            const DepthPyramid& pyr,
            const BlockStorage& storage,
            const BlockKey& blo,
            const BlockKey& bhi,
            int num_threads,
            std::vector<std::vector<BlockResult>>& per_thread)
{
  const BlockObserver observer(view, pyr, storage);
  return observeBlocks(observer, blo, bhi, num_threads, per_thread);
}

} // namespace explicit_space
} // namespace planar_grid
