// SPDX-License-Identifier: BSD-3-Clause
// The voxel keys of a depth image row, for the occupied pass of
// ExplicitSpaceGrid::integrateDepthImage(). Private to src/map.
#pragma once

#include <Eigen/Core>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>

#include "explicit_space_grid_storage.h"

namespace planar_grid {
namespace explicit_space {

/** \brief static_cast<int>(std::floor(x)) for |x| < 2^31, without the call to floorf
 * (x86-64 before SSE4.1 has no rounding instruction). */
inline int
floorToInt(float x)
{
  const int t = static_cast<int>(x); // truncation towards zero
  return t - (static_cast<float>(t) > x ? 1 : 0);
}

/** \brief What rowKeys() needs of a view: the camera pose, the column directions and
 * the range. */
struct RowKeys {
  /** \brief Rotation and translation of world_T_camera. */
  Eigen::Matrix3f R;
  Eigen::Vector3f t;
  /** \brief (u - cx) / fx per column. */
  const float* column_x;
  /** \brief Largest depth integrated, meters. */
  float max_range;
  /** \brief 1 / voxel edge, 1 / meters. */
  float inv_res;
};

/** \brief The voxel key of every pixel of a depth image row (\a row: depths in
 * meters, +inf for none; \a yn = (v - cy) / fy), with ok[u] = 1 where the pixel has a
 * measurement within range and a key below 2^30. One branch-free loop the compiler
 * vectorises, with the arithmetic of (world_T_camera * (x, y, z)) / resolution as
 * Eigen evaluates it, ((r0 x + r1 y) + r2 z) + t, so the keys are those of the
 * per-pixel product. CLAMP: clamp the coordinates to +-2^30 before the conversion to
 * int (needed only when some pixel's coordinates could overflow an int; the clamps
 * keep the compiler from vectorising the loop). */
template <bool CLAMP>
void
rowKeys(const float* row,
        int W,
        float yn,
        const RowKeys& k,
        int* kx,
        int* ky,
        int* kz,
        int* ok)
{
  const float r00 = k.R(0, 0), r01 = k.R(0, 1), r02 = k.R(0, 2);
  const float r10 = k.R(1, 0), r11 = k.R(1, 1), r12 = k.R(1, 2);
  const float r20 = k.R(2, 0), r21 = k.R(2, 1), r22 = k.R(2, 2);
  const float tx = k.t.x(), ty = k.t.y(), tz = k.t.z();
  const float max_range = k.max_range, inv_res = k.inv_res;
  const float* const column_x = k.column_x;
  const auto key_limit = static_cast<float>(MAX_KEY);
  for (int u = 0; u < W; ++u) {
    const float d = row[u];
    const bool in_range = d <= max_range; // +inf marks no measurement
    const float z = in_range ? d : 0.0f;
    const float x = column_x[u] * z, y = yn * z;
    float px = (((r00 * x + r01 * y) + r02 * z) + tx) * inv_res;
    float py = (((r10 * x + r11 * y) + r12 * z) + ty) * inv_res;
    float pz = (((r20 * x + r21 * y) + r22 * z) + tz) * inv_res;
    ok[u] = static_cast<int>(in_range) & static_cast<int>(std::abs(px) < key_limit)
            & static_cast<int>(std::abs(py) < key_limit)
            & static_cast<int>(std::abs(pz) < key_limit);
    if (CLAMP) { // NaN to -2^30; unchanged where ok
      px = std::min(key_limit, std::max(-key_limit, px));
      py = std::min(key_limit, std::max(-key_limit, py));
      pz = std::min(key_limit, std::max(-key_limit, pz));
    }
    kx[u] = floorToInt(px);
    ky[u] = floorToInt(py);
    kz[u] = floorToInt(pz);
  }
}

/** \brief Bit i set where flags[i] (0 or 1) is 1, for 64 flags: each 8 bytes gather
 * into one byte through a multiplication (byte j of x times 2^(56 - 7 j) lands on bit
 * 56 + j, and no other product reaches the top byte). */
inline std::uint64_t
packBits(const std::array<std::uint8_t, 64>& flags)
{
  std::uint64_t bits = 0;
  for (std::size_t b = 0; b < 8; ++b) {
    std::uint64_t x;
    std::memcpy(&x, flags.data() + 8 * b, sizeof(x)); // little-endian: byte j = flag j
    bits |= ((x * 0x0102040810204080ULL) >> 56) << (8 * b);
  }
  return bits;
}

/** \brief The pixels first .. first + 63 of a row that start a run of one voxel, as
 * bit u - first: ok[u], and pixel u - 1 is not a measured pixel of the same voxel. A
 * measured pixel that does not start a run has the voxel of the measured pixel before
 * it. The flags come from a branch-free loop the compiler vectorises (packBits). */
inline std::uint64_t
runStarts(const int* kx, const int* ky, const int* kz, const int* ok, int W, int first)
{
  std::array<std::uint8_t, 64> flags{};
  const int end = std::min(first + 64, W);
  int u = first;
  if (u == 0 && u < end) { // no pixel before it
    flags[0] = static_cast<std::uint8_t>(ok[0] != 0);
    ++u;
  }
  for (; u < end; ++u) {
    const int same = ok[u - 1] & static_cast<int>(kx[u] == kx[u - 1])
                     & static_cast<int>(ky[u] == ky[u - 1])
                     & static_cast<int>(kz[u] == kz[u - 1]);
    flags[static_cast<std::size_t>(u - first)] =
      static_cast<std::uint8_t>(ok[u] & (same ^ 1));
  }
  return packBits(flags);
}

} // namespace explicit_space
} // namespace planar_grid
