// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of SyntheticStereoScene: the seed hash and the texture maker.
#pragma once

#include <cstdint>
#include <vector>

namespace planar_grid {
namespace detail {

/** \brief SplitMix64's finaliser: a well-mixed 64-bit hash, the same on every
 * platform (std:: distributions are not). */
inline std::uint64_t
mix(std::uint64_t x)
{
  x += 0x9E3779B97F4A7C15ULL;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ULL;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBULL;
  return x ^ (x >> 31);
}

/** \brief A grey texture of nu x nv texels covering width_m x height_m (texel (i, j)
 * centred at ((i + 0.5) width_m / nu, (j + 0.5) height_m / nv)), row-major with i
 * fastest: multi-octave value noise plus random blobs and strokes, normalised to
 * mean TEXTURE_MEAN and standard deviation TEXTURE_STDDEV. */
std::vector<unsigned char>
makeTexture(std::uint64_t seed, int nu, int nv, double width_m, double height_m);

} // namespace detail
} // namespace planar_grid
