// SPDX-License-Identifier: BSD-3-Clause
// The sparse raster of a map plane of the surface layer: tiles of 8 x 8 cells with
// their feature evidence (private to the map module).
#pragma once

#include <planar_grid/surface/rectangle_merge.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstring>
#include <limits>
#include <utility>
#include <vector>

namespace planar_grid {
namespace surface_layer_detail {

/** \brief Largest feature count of a raster cell (u16); beyond it the sum is rescaled
 * so that the mean stays that of all features. */
constexpr std::uint32_t MAX_FEATURE_COUNT = 65535u;

inline int
popcount64(std::uint64_t x)
{
  return __builtin_popcountll(x);
}

inline int
lowestBit(std::uint64_t x)
{
  return __builtin_ctzll(x);
}

/** \brief Adds \a count features of probability sum \a sum to a cell's evidence (sum,
 * count); past MAX_FEATURE_COUNT the sum is rescaled to keep the mean of all
 * features. */
inline void
addFeatures(float& probability_sum,
            std::uint16_t& feature_count,
            double sum,
            std::uint32_t count)
{
  if (count == 0)
    return;
  const std::uint32_t total = feature_count + count;
  double new_sum = static_cast<double>(probability_sum) + sum;
  if (total > MAX_FEATURE_COUNT) {
    new_sum *= static_cast<double>(MAX_FEATURE_COUNT) / total;
    feature_count = static_cast<std::uint16_t>(MAX_FEATURE_COUNT);
  } else {
    feature_count = static_cast<std::uint16_t>(total);
  }
  probability_sum =
    static_cast<float>(std::min(new_sum, static_cast<double>(feature_count)));
}

/** \brief Features added to one raster cell (rasterCellKey \a key), applied in the
 * order given. */
struct CellEvidence {
  std::uint64_t key;
  double sum;
  std::uint32_t count;
};

/** \brief A map plane's observed cells in tiles of 8 x 8 cells: per tile its key
 * (rasterCellKey of the tile indices i >> 3, j >> 3), a 64-bit mask of the observed
 * cells (bit (j & 7) * 8 + (i & 7)) and a mask of the cells with feature evidence (24
 * bytes per tile), sorted by key; the evidence (probability sum f32, feature count u16:
 * 6 bytes, in one array) only for the cells in the evidence masks, in tile order, then
 * bit order. A cell is in the evidence mask when its count or its sum is not zero. */
struct Raster {
  struct Tile {
    std::uint64_t key;
    std::uint64_t observed;
    std::uint64_t evidence;
  };
  std::vector<Tile> tiles;
  /** Per cell with evidence: the bits of its probability sum (the sum of the
   * probabilities of its features) as two 16-bit halves, low half first, then its
   * feature count (saturating at MAX_FEATURE_COUNT). */
  std::vector<std::uint16_t> evidence_records;

  /** 16-bit words of one evidence record. */
  static constexpr std::size_t RECORD_WORDS = 3;

  /** Probability sum of evidence record \a r. */
  float probabilitySum(std::size_t r) const
  {
    const std::uint32_t bits =
      static_cast<std::uint32_t>(evidence_records[RECORD_WORDS * r])
      | (static_cast<std::uint32_t>(evidence_records[RECORD_WORDS * r + 1]) << 16);
    float sum;
    std::memcpy(&sum, &bits, sizeof(sum));
    return sum;
  }
  /** Feature count of evidence record \a r. */
  std::uint16_t featureCount(std::size_t r) const
  {
    return evidence_records[RECORD_WORDS * r + 2];
  }
  /** Appends the evidence record (\a sum, \a count) to \a out. */
  static void
  appendRecord(std::vector<std::uint16_t>& out, float sum, std::uint16_t count)
  {
    std::uint32_t bits;
    std::memcpy(&bits, &sum, sizeof(bits));
    out.push_back(static_cast<std::uint16_t>(bits & 0xffffu));
    out.push_back(static_cast<std::uint16_t>(bits >> 16));
    out.push_back(count);
  }

  static std::uint64_t tileKey(std::uint64_t cell)
  {
    return rasterCellKey(rasterCellI(cell) >> 3, rasterCellJ(cell) >> 3);
  }
  static std::uint64_t tileBit(std::uint64_t cell)
  {
    return std::uint64_t{1} << (((rasterCellJ(cell) & 7) << 3)
                                | (rasterCellI(cell) & 7));
  }

  bool empty() const { return tiles.empty(); }

  /** Number of observed cells. */
  std::size_t size() const
  {
    std::size_t n = 0;
    for (const Tile& t : tiles)
      n += static_cast<std::size_t>(popcount64(t.observed));
    return n;
  }

  /** Index of the tile with \a tile_key, or -1. */
  std::ptrdiff_t findTile(std::uint64_t tile_key) const
  {
    const auto it =
      std::lower_bound(tiles.begin(), tiles.end(), tile_key,
                       [](const Tile& t, std::uint64_t k) { return t.key < k; });
    return (it != tiles.end() && it->key == tile_key) ? it - tiles.begin() : -1;
  }

  bool contains(std::uint64_t key) const
  {
    const std::ptrdiff_t t = findTile(tileKey(key));
    return t >= 0 && (tiles[static_cast<std::size_t>(t)].observed & tileBit(key)) != 0;
  }

  /** Adds the cells of \a keys (any order, duplicates allowed) not yet present,
   * without evidence; the tiles are reallocated to their exact size. Returns the
   * number added. */
  std::size_t insert(const std::vector<std::uint64_t>& keys)
  {
    if (keys.empty())
      return 0;
    std::vector<Tile> fresh;
    fresh.reserve(keys.size());
    for (const auto key : keys)
      fresh.push_back(Tile{tileKey(key), tileBit(key), 0});
    std::sort(fresh.begin(), fresh.end(),
              [](const Tile& a, const Tile& b) { return a.key < b.key; });
    std::size_t unique = 0;
    for (std::size_t k = 0; k < fresh.size(); ++k) {
      if (unique > 0 && fresh[unique - 1].key == fresh[k].key)
        fresh[unique - 1].observed |= fresh[k].observed;
      else
        fresh[unique++] = fresh[k];
    }
    fresh.resize(unique);
    std::size_t added = 0, new_tiles = 0;
    for (std::size_t a = 0, b = 0; b < fresh.size();) {
      if (a < tiles.size() && tiles[a].key < fresh[b].key)
        ++a;
      else if (a < tiles.size() && tiles[a].key == fresh[b].key) {
        added +=
          static_cast<std::size_t>(popcount64(fresh[b].observed & ~tiles[a].observed));
        ++a;
        ++b;
      } else {
        added += static_cast<std::size_t>(popcount64(fresh[b].observed));
        ++new_tiles;
        ++b;
      }
    }
    if (added == 0)
      return 0;
    if (new_tiles == 0) {
      for (std::size_t a = 0, b = 0; b < fresh.size(); ++a)
        if (tiles[a].key == fresh[b].key)
          tiles[a].observed |= fresh[b++].observed;
      return added;
    }
    std::vector<Tile> merged;
    merged.reserve(tiles.size() + new_tiles);
    std::size_t a = 0, b = 0;
    while (a < tiles.size() || b < fresh.size()) {
      if (b == fresh.size() || (a < tiles.size() && tiles[a].key < fresh[b].key))
        merged.push_back(tiles[a++]);
      else if (a < tiles.size() && tiles[a].key == fresh[b].key) {
        merged.push_back(tiles[a++]);
        merged.back().observed |= fresh[b++].observed;
      } else
        merged.push_back(fresh[b++]);
    }
    tiles.swap(merged);
    return added;
  }

  /** Adds the features of \a evidence (observed cells; others are ignored), each
   * cell's in the order given (addFeatures()); the evidence arrays are reallocated to
   * their exact size. \a evidence is reordered. */
  void addEvidence(std::vector<CellEvidence>& evidence)
  {
    const auto order = [](const CellEvidence& e) {
      const std::uint64_t bit = tileBit(e.key);
      return std::make_pair(tileKey(e.key), bit);
    };
    std::stable_sort(evidence.begin(), evidence.end(),
                     [&order](const CellEvidence& a, const CellEvidence& b) {
                       return order(a) < order(b);
                     });
    // The evidence masks after the update, and the number of records.
    std::vector<std::uint64_t> masks(tiles.size());
    std::size_t records = 0;
    for (std::size_t t = 0, e = 0; t < tiles.size(); ++t) {
      std::uint64_t mask = tiles[t].evidence;
      for (; e < evidence.size() && tileKey(evidence[e].key) <= tiles[t].key; ++e)
        if (tileKey(evidence[e].key) == tiles[t].key && evidence[e].count > 0)
          mask |= tileBit(evidence[e].key) & tiles[t].observed;
      masks[t] = mask;
      records += static_cast<std::size_t>(popcount64(mask));
    }
    std::vector<std::uint16_t> updated;
    updated.reserve(RECORD_WORDS * records);
    std::size_t old = 0, e = 0;
    for (std::size_t t = 0; t < tiles.size(); ++t) {
      for (std::uint64_t rest = masks[t]; rest != 0; rest &= rest - 1) {
        const std::uint64_t bit = rest & (~rest + 1);
        float sum = 0.0f;
        std::uint16_t count = 0;
        if ((tiles[t].evidence & bit) != 0) {
          sum = probabilitySum(old);
          count = featureCount(old);
          ++old;
        }
        while (e < evidence.size()
               && order(evidence[e]) < std::make_pair(tiles[t].key, bit))
          ++e;
        for (; e < evidence.size()
               && order(evidence[e]) == std::make_pair(tiles[t].key, bit);
             ++e)
          addFeatures(sum, count, evidence[e].sum, evidence[e].count);
        appendRecord(updated, sum, count);
      }
      tiles[t].evidence = masks[t];
    }
    evidence_records.swap(updated);
  }

  /** Calls f(key, probability sum, feature count) for every observed cell, sorted by
   * rasterCellKey (row j, then column i). */
  template <typename F> void forEachCell(F f) const
  {
    std::vector<std::size_t> base;
    std::size_t records = 0;
    for (std::size_t g = 0; g < tiles.size();) {
      const std::int32_t tj = rasterCellJ(tiles[g].key);
      std::size_t h = g;
      base.clear();
      while (h < tiles.size() && rasterCellJ(tiles[h].key) == tj) {
        base.push_back(records);
        records += static_cast<std::size_t>(popcount64(tiles[h].evidence));
        ++h;
      }
      for (int row = 0; row < 8; ++row) {
        const auto j =
          static_cast<std::int32_t>(static_cast<std::int64_t>(tj) * 8 + row);
        for (std::size_t t = g; t < h; ++t) {
          const Tile& tile = tiles[t];
          const std::int64_t i0 = static_cast<std::int64_t>(rasterCellI(tile.key)) * 8;
          for (std::uint64_t bits = (tile.observed >> (8 * row)) & 0xffu; bits != 0;
               bits &= bits - 1) {
            const int col = lowestBit(bits);
            const std::uint64_t bit = std::uint64_t{1} << (8 * row + col);
            float sum = 0.0f;
            std::uint16_t count = 0;
            if ((tile.evidence & bit) != 0) {
              const std::size_t r =
                base[t - g]
                + static_cast<std::size_t>(popcount64(tile.evidence & (bit - 1)));
              sum = probabilitySum(r);
              count = featureCount(r);
            }
            f(rasterCellKey(static_cast<std::int32_t>(i0 + col), j), sum, count);
          }
        }
      }
      g = h;
    }
  }

  /** The observed cells' keys, sorted. */
  std::vector<std::uint64_t> keys() const
  {
    std::vector<std::uint64_t> out;
    out.reserve(size());
    forEachCell(
      [&out](std::uint64_t key, float, std::uint16_t) { out.push_back(key); });
    return out;
  }

  /** Bounding box of the observed cells, in cells (false when empty). */
  bool bounds(std::int32_t& i_min,
              std::int32_t& i_max,
              std::int32_t& j_min,
              std::int32_t& j_max) const
  {
    if (tiles.empty())
      return false;
    std::int64_t lo_i = std::numeric_limits<std::int64_t>::max(), hi_i = -lo_i;
    std::int64_t lo_j = lo_i, hi_j = -lo_i;
    for (const Tile& t : tiles) {
      std::uint64_t columns = 0, rows = 0;
      for (int row = 0; row < 8; ++row) {
        const std::uint64_t byte = (t.observed >> (8 * row)) & 0xffu;
        columns |= byte;
        rows |= (byte != 0 ? std::uint64_t{1} : 0) << row;
      }
      const std::int64_t i0 = static_cast<std::int64_t>(rasterCellI(t.key)) * 8;
      const std::int64_t j0 = static_cast<std::int64_t>(rasterCellJ(t.key)) * 8;
      lo_i = std::min(lo_i, i0 + lowestBit(columns));
      hi_i = std::max(hi_i, i0 + 63 - __builtin_clzll(columns));
      lo_j = std::min(lo_j, j0 + lowestBit(rows));
      hi_j = std::max(hi_j, j0 + 63 - __builtin_clzll(rows));
    }
    i_min = static_cast<std::int32_t>(lo_i);
    i_max = static_cast<std::int32_t>(hi_i);
    j_min = static_cast<std::int32_t>(lo_j);
    j_max = static_cast<std::int32_t>(hi_j);
    return true;
  }

  /** Builds the raster of \a keys (sorted, unique) with their evidence (parallel). */
  void assign(const std::vector<std::uint64_t>& keys,
              const std::vector<float>& sums,
              const std::vector<std::uint16_t>& counts)
  {
    tiles.clear();
    evidence_records.clear();
    insert(keys);
    std::vector<std::pair<std::pair<std::uint64_t, std::uint64_t>, std::size_t>>
      records;
    for (std::size_t k = 0; k < keys.size(); ++k)
      if (counts[k] != 0 || std::signbit(sums[k]) || sums[k] != 0.0f)
        records.push_back({{tileKey(keys[k]), tileBit(keys[k])}, k});
    std::sort(records.begin(), records.end());
    evidence_records.reserve(RECORD_WORDS * records.size());
    std::size_t t = 0;
    for (const auto& r : records) {
      while (tiles[t].key != r.first.first)
        ++t;
      tiles[t].evidence |= r.first.second;
      appendRecord(evidence_records, sums[r.second], counts[r.second]);
    }
  }

  bool operator==(const Raster& o) const
  {
    if (tiles.size() != o.tiles.size())
      return false;
    for (std::size_t t = 0; t < tiles.size(); ++t)
      if (tiles[t].key != o.tiles[t].key || tiles[t].observed != o.tiles[t].observed
          || tiles[t].evidence != o.tiles[t].evidence)
        return false;
    return evidence_records == o.evidence_records;
  }

  std::size_t bytes() const
  {
    return tiles.capacity() * sizeof(Tile)
           + evidence_records.capacity() * sizeof(std::uint16_t);
  }
};

} // namespace surface_layer_detail
} // namespace planar_grid
