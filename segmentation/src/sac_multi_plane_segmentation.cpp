// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
PLANAR_GRID_INSTANTIATE(SACMultiPlaneSegmentation, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE

// The RANSAC's inner loop: on x86-64 with GNU ifunc, an AVX2 clone (8 floats a step
// instead of SSE2's 4) beside the baseline one, chosen by the loader. AVX2 alone does
// not enable FMA, so both clones round a x + b y + c z + d alike.
#if defined(__x86_64__) && defined(__GNUC__) && defined(__ELF__) \
  && !defined(__INTEL_COMPILER)
#define PLANAR_GRID_TARGET_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PLANAR_GRID_TARGET_CLONES
#endif

namespace planar_grid {
namespace detail {

PLANAR_GRID_TARGET_CLONES std::size_t
countWithinDistance(const float* px,
                    const float* py,
                    const float* pz,
                    std::size_t n,
                    const Eigen::Vector4f& plane,
                    float t,
                    std::size_t to_beat)
{
  constexpr std::size_t BLOCK = 256;
  const float a = plane[0], b = plane[1], c = plane[2], d = plane[3];
  std::size_t count = 0;
  for (std::size_t begin = 0; begin < n; begin += BLOCK) {
    const std::size_t end = std::min(n, begin + BLOCK);
    std::uint32_t block_count = 0;
    for (std::size_t k = begin; k < end; ++k)
      block_count += std::abs(a * px[k] + b * py[k] + c * pz[k] + d) <= t ? 1u : 0u;
    count += block_count;
    if (to_beat > 0 && count + (n - end) <= to_beat)
      return count;
  }
  return count;
}

} // namespace detail
} // namespace planar_grid
