// SPDX-License-Identifier: BSD-3-Clause
// Working memory of ExplicitSpaceGrid::integrateDepthImage(), kept between views so
// that a view allocates nothing: the depth pyramid of the image, the per-thread block
// observations and the occupied pass's column table. Private to src/map.
#pragma once

#include <planar_grid/map/explicit_space_grid.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

#include "explicit_space_grid_storage.h"

namespace planar_grid {
namespace explicit_space {

/** \brief True when \a value is finite and positive (a valid depth or disparity): NaN
 * and infinity fail. Branch-free, so that the loops over images vectorise. */
inline bool
isFiniteAndPositive(float value)
{
  return (value > 0.0f) & (value <= std::numeric_limits<float>::max());
}

/** \brief Depth pyramids of a depth image, over the measured (valid) pixels only:
 * min_level (+inf where a cell has no measurement), max_level (0 there), and, per
 * level j, hole[j][k] (k >= 1; k = 0 is min_level[j] itself): the max over 2^k x 2^k
 * cells of min_level[j], finite only when every level-j cell of the region holds a
 * measurement. */
struct DepthPyramid {
  std::vector<std::vector<float>> min_level, max_level;
  std::vector<std::vector<std::vector<float>>> hole;
  std::vector<int> w, h;
  /** \brief spanMin()'s arrays per level (k = 0 unused: min_level itself). */
  std::vector<std::array<std::vector<float>, 9>> span;

  /** \brief dst = the min (or max) over 2 x 2 cells of src (sw x sh), the last row
   * and column repeated where sw or sh is odd. Each row is a loop the compiler
   * vectorises (min and max are exact, so the order of the four does not matter). */
  static void reduce(const std::vector<float>& src,
                     int sw,
                     int sh,
                     bool take_max,
                     std::vector<float>& dst)
  {
    if (take_max)
      reduceRows<true>(src, sw, sh, dst);
    else
      reduceRows<false>(src, sw, sh, dst);
  }

  template <bool TAKE_MAX> static float pick(float a, float b)
  {
    return TAKE_MAX ? std::max(a, b) : std::min(a, b);
  }

  template <bool TAKE_MAX>
  static void
  reduceRows(const std::vector<float>& src, int sw, int sh, std::vector<float>& dst)
  {
    const int nw = (sw + 1) / 2, nh = (sh + 1) / 2, pairs = sw / 2;
    dst.resize(static_cast<std::size_t>(nw) * static_cast<std::size_t>(nh));
    for (int v = 0; v < nh; ++v) {
      const float* r0 =
        src.data() + static_cast<std::size_t>(2 * v) * static_cast<std::size_t>(sw);
      const float* r1 = src.data()
                        + static_cast<std::size_t>(std::min(2 * v + 1, sh - 1))
                            * static_cast<std::size_t>(sw);
      float* out =
        dst.data() + static_cast<std::size_t>(v) * static_cast<std::size_t>(nw);
      for (int u = 0; u < pairs; ++u)
        out[u] = pick<TAKE_MAX>(pick<TAKE_MAX>(r0[2 * u], r0[2 * u + 1]),
                                pick<TAKE_MAX>(r1[2 * u], r1[2 * u + 1]));
      if (pairs < nw) // odd width: the last column alone
        out[pairs] = pick<TAKE_MAX>(r0[sw - 1], r1[sw - 1]);
    }
  }

  void build(const DepthImage& image, float& max_valid_depth)
  {
    // Buffers are kept between views (no reallocation, no fresh pages).
    const float inf = std::numeric_limits<float>::infinity();
    w.assign(1, image.width);
    h.assign(1, image.height);
    while (w.back() > 1 || h.back() > 1) {
      w.push_back((w.back() + 1) / 2);
      h.push_back((h.back() + 1) / 2);
    }
    const std::size_t n_levels = w.size();
    min_level.resize(n_levels);
    max_level.resize(n_levels);
    auto& m0 = min_level[0];
    auto& x0 = max_level[0];
    m0.resize(image.depth_m.size());
    x0.resize(image.depth_m.size());
    const float* const depth = image.depth_m.data();
    for (std::size_t i = 0; i < m0.size(); ++i) {
      const float d = depth[i];
      const bool valid = isFiniteAndPositive(d);
      m0[i] = valid ? d : inf;
      x0[i] = valid ? d : 0.0f;
    }
    for (std::size_t l = 1; l < n_levels; ++l) {
      reduce(min_level[l - 1], w[l - 1], h[l - 1], false, min_level[l]);
      reduce(max_level[l - 1], w[l - 1], h[l - 1], true, max_level[l]);
    }
    // the top level's single cell: the largest valid depth, 0 without one
    max_valid_depth = max_level.back()[0];
    hole.resize(n_levels);
    for (std::size_t j = 0; j < n_levels; ++j) {
      auto& hj = hole[j];
      hj.resize(n_levels - j); // hj[0] stays empty: it would be min_level[j]
      for (std::size_t k = 1; k < hj.size(); ++k)
        reduce(k == 1 ? min_level[j] : hj[k - 1], w[j + k - 1], h[j + k - 1], true,
               hj[k]);
    }
  }

  int levels() const { return static_cast<int>(w.size()); }

  /** \brief min_level[l] over the cells (cu .. cu + su) x (cv .. cv + sv), at
   * cu + cv w[l], for k = 3 su + sv (su, sv in 0..2); valid where those cells lie in
   * the level. Needs buildSpans() from a level <= l. */
  const float* spanMin(int l, int k) const
  {
    const auto sl = static_cast<std::size_t>(l);
    return k == 0 ? min_level[sl].data() : span[sl][static_cast<std::size_t>(k)].data();
  }

  /** \brief The span minima of levels first .. levels() - 1. */
  void buildSpans(int first)
  {
    span.resize(w.size());
    for (std::size_t l = static_cast<std::size_t>(std::max(first, 0)); l < w.size();
         ++l) {
      const int lw = w[l], lh = h[l];
      const std::size_t n = min_level[l].size();
      auto& sp = span[l];
      // along u: k = 3 and 6 (su = 1, 2)
      const std::vector<float>& m = min_level[l];
      sp[3].resize(n);
      sp[6].resize(n);
      for (int cv = 0; cv < lh; ++cv) {
        const std::size_t row =
          static_cast<std::size_t>(cv) * static_cast<std::size_t>(lw);
        for (int cu = 0; cu < lw; ++cu) {
          const std::size_t i = row + static_cast<std::size_t>(cu);
          const float a = m[i];
          const float b = m[row + static_cast<std::size_t>(std::min(cu + 1, lw - 1))];
          const float c = m[row + static_cast<std::size_t>(std::min(cu + 2, lw - 1))];
          sp[3][i] = std::min(a, b);
          sp[6][i] = std::min(std::min(a, b), c);
        }
      }
      // along v, from each of su = 0, 1, 2: k = 3 su + 1 and 3 su + 2
      for (int su = 0; su < 3; ++su) {
        const std::vector<float>& src =
          su == 0 ? m : sp[static_cast<std::size_t>(3 * su)];
        auto& d1 = sp[static_cast<std::size_t>(3 * su + 1)];
        auto& d2 = sp[static_cast<std::size_t>(3 * su + 2)];
        d1.resize(n);
        d2.resize(n);
        for (int cv = 0; cv < lh; ++cv) {
          const std::size_t r0 =
            static_cast<std::size_t>(cv) * static_cast<std::size_t>(lw);
          const std::size_t r1 = static_cast<std::size_t>(std::min(cv + 1, lh - 1))
                                 * static_cast<std::size_t>(lw);
          const std::size_t r2 = static_cast<std::size_t>(std::min(cv + 2, lh - 1))
                                 * static_cast<std::size_t>(lw);
          for (int cu = 0; cu < lw; ++cu) {
            const auto c = static_cast<std::size_t>(cu);
            const float ab = std::min(src[r0 + c], src[r1 + c]);
            d1[r0 + c] = ab;
            d2[r0 + c] = std::min(ab, src[r2 + c]);
          }
        }
      }
    }
  }

  /** \brief Smallest level whose cells are at least \a size pixels wide. */
  int levelFor(int size) const
  {
    int l = 0;
    while ((1 << l) < size && l + 1 < levels())
      ++l;
    return l;
  }

  /** \brief Min and max of the valid depths over the level-l cells covering the
   * clamped rectangle [u0, u1] x [v0, v1]. */
  void query(int l, int u0, int v0, int u1, int v1, float& mn, float& mx) const
  {
    const auto& lmin = min_level[static_cast<std::size_t>(l)];
    const auto& lmax = max_level[static_cast<std::size_t>(l)];
    const auto lw = static_cast<std::size_t>(w[static_cast<std::size_t>(l)]);
    mn = std::numeric_limits<float>::infinity();
    mx = 0.0f;
    for (int cv = v0 >> l; cv <= (v1 >> l); ++cv) {
      const std::size_t row = static_cast<std::size_t>(cv) * lw;
      for (int cu = u0 >> l; cu <= (u1 >> l); ++cu) {
        mn = std::min(mn, lmin[row + static_cast<std::size_t>(cu)]);
        mx = std::max(mx, lmax[row + static_cast<std::size_t>(cu)]);
      }
    }
  }

  /** \brief Clamps a pixel rectangle into the image; false when it misses it. */
  bool clampRect(int& u0, int& v0, int& u1, int& v1) const
  {
    u0 = std::max(u0, 0);
    v0 = std::max(v0, 0);
    u1 = std::min(u1, w[0] - 1);
    v1 = std::min(v1, h[0] - 1);
    return u0 <= u1 && v0 <= v1;
  }

  /** \brief Min and max valid depth over (a superset of) a clamped rectangle. */
  void queryRect(int u0, int v0, int u1, int v1, float& mn, float& mx) const
  {
    // cells of a quarter of the size: at most 5 x 5 of them, a tight superset
    query(levelFor((std::max(u1 - u0 + 1, v1 - v0 + 1) + 3) / 4), u0, v0, u1, v1, mn,
          mx);
  }

  /** \brief True when every level-j cell meeting the clamped rectangle holds a
   * measurement. */
  bool noHoles(int j, int u0, int v0, int u1, int v1) const
  {
    j = std::min(j, levels() - 1);
    const int l = std::max(levelFor((std::max(u1 - u0 + 1, v1 - v0 + 1) + 3) / 4), j);
    const auto& hk =
      l == j ? min_level[static_cast<std::size_t>(j)]
             : hole[static_cast<std::size_t>(j)][static_cast<std::size_t>(l - j)];
    const auto lw = static_cast<std::size_t>(w[static_cast<std::size_t>(l)]);
    for (int cv = v0 >> l; cv <= (v1 >> l); ++cv)
      for (int cu = u0 >> l; cu <= (u1 >> l); ++cu)
        if (!std::isfinite(
              hk[static_cast<std::size_t>(cv) * lw + static_cast<std::size_t>(cu)]))
          return false;
    return true;
  }
};

/** \brief What one view says of one block: free or occluded as a whole, or per voxel
 * (bit x + 8 y of word z; a voxel in neither mask is not observed). */
struct BlockResult {
  enum Kind : std::uint8_t { ALL_FREE, ALL_OCCLUDED, MASKS };
  BlockKey key{0, 0, 0};
  Kind kind{MASKS};
  std::array<std::uint64_t, BLOCK_EDGE> free{}, occluded{};
};

/** \brief The scratch of integrateDepthImage(): one view's worth of working memory,
 * not part of the map (getMemoryBytes() does not count what it holds). */
struct IntegrationWorkspace {
  /** \brief The depth pyramid of the last view. */
  DepthPyramid pyramid;
  /** \brief The occupied pass's (u - cx) / fx per image column. */
  std::vector<float> column_x;
  /** \brief The occupied pass's voxel keys of one image row (x, y, z per column) and
   * whether each pixel has one (a measurement within range). */
  std::vector<int> row_kx, row_ky, row_kz, row_ok;
  /** \brief Per-thread observations of the blocks of the last view. */
  std::vector<std::vector<BlockResult>> results;
};

} // namespace explicit_space
} // namespace planar_grid
