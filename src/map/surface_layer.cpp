// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>

#include <pcl/PolygonMesh.h>
#include <pcl/common/io.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/io/ply_io.h>
#include <pcl/io/vtk_io.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <unordered_map>
#include <utility>

namespace planar_grid {

namespace {

/** \brief Raster cells per face beyond which a face is skipped (a corrupt or
 * absurdly large cuboid). */
constexpr double MAX_FACE_CELLS = 1e7;
/** \brief Largest |raster index| (int32 with a margin). */
constexpr double MAX_CELL_INDEX = 2.0e9;
/** \brief Largest coordinate accepted, meters (corrupt data guard). */
constexpr float MAX_COORDINATE_M = 1e7f;
/** \brief Spatial-index bins per cuboid beyond which it goes to the "large" list. */
constexpr double MAX_BINS_PER_CUBOID = 4096.0;
/** \brief Section magic ("PGSL") and version of serialize(). */
constexpr std::uint32_t MAGIC = 0x4C534750u;
constexpr std::uint32_t VERSION = 3;
/** \brief Largest Params::close_gaps_cells. */
constexpr int MAX_CLOSE_GAPS_CELLS = 32;

/** \brief Key of raster cell (i, j), ordered by row j then column i. */
inline std::uint64_t
cellKey(std::int32_t i, std::int32_t j)
{
  return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(j) ^ 0x80000000u) << 32)
         | static_cast<std::uint64_t>(static_cast<std::uint32_t>(i) ^ 0x80000000u);
}
inline std::int32_t
keyI(std::uint64_t key)
{
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key & 0xffffffffu)
                                   ^ 0x80000000u);
}
inline std::int32_t
keyJ(std::uint64_t key)
{
  return static_cast<std::int32_t>(static_cast<std::uint32_t>(key >> 32) ^ 0x80000000u);
}

/** \brief Bytes of one node of a std::unordered_map (libstdc++: next pointer, value,
 * cached hash for non-fast hashes; we count the pointer, the value and round to 8). */
template <typename Map>
std::size_t
hashMapBytes(const Map& map)
{
  constexpr std::size_t node =
    (sizeof(void*) + sizeof(typename Map::value_type) + sizeof(std::size_t) + 7) / 8
    * 8;
  return map.bucket_count() * sizeof(void*) + map.size() * node;
}

template <typename Vector>
std::size_t
vectorBytes(const Vector& v)
{
  return v.capacity() * sizeof(typename Vector::value_type);
}

/** \brief Ray / oriented box slab test; \a dir unit. Returns the entry distance (0
 * when the origin is inside), or a negative value when missed. */
float
rayBoxEntry(const PlanarCuboid& box,
            const Eigen::Vector3f& origin,
            const Eigen::Vector3f& dir,
            float max_t)
{
  const Eigen::Vector3f axes[3] = {box.horizontal_axis, box.verticalAxis(), box.normal};
  const float half[3] = {0.5f * box.width_m, 0.5f * box.height_m,
                         0.5f * box.thickness_m};
  const Eigen::Vector3f rel = origin - box.centre;
  float t0 = 0.0f, t1 = max_t;
  for (int k = 0; k < 3; ++k) {
    const float o = rel.dot(axes[k]);
    const float d = dir.dot(axes[k]);
    if (std::abs(d) < 1e-12f) {
      if (std::abs(o) > half[k])
        return -1.0f;
      continue;
    }
    float a = (-half[k] - o) / d;
    float b = (half[k] - o) / d;
    if (a > b)
      std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1)
      return -1.0f;
  }
  return t0;
}

bool
finiteVector(const Eigen::Vector3f& v)
{
  return v.allFinite() && v.cwiseAbs().maxCoeff() <= MAX_COORDINATE_M;
}

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

/** \brief Features added to one raster cell (cellKey \a key), applied in the order
 * given. */
struct CellEvidence {
  std::uint64_t key;
  double sum;
  std::uint32_t count;
};

/** \brief A map plane's observed cells in tiles of 8 x 8 cells: per tile its key
 * (cellKey of the tile indices i >> 3, j >> 3), a 64-bit mask of the observed cells
 * (bit (j & 7) * 8 + (i & 7)) and a mask of the cells with feature evidence (24 bytes
 * per tile), sorted by key; the evidence (probability sum f32, feature count u16: 6
 * bytes) only for the cells in the evidence masks, in tile order, then bit order. A
 * cell is in the evidence mask when its count or its sum is not zero. */
struct Raster {
  struct Tile {
    std::uint64_t key;
    std::uint64_t observed;
    std::uint64_t evidence;
  };
  std::vector<Tile> tiles;
  /** Sum of the probabilities of the features in the cell. */
  std::vector<float> probability_sums;
  /** Number of features in the cell (saturating at MAX_FEATURE_COUNT). */
  std::vector<std::uint16_t> feature_counts;

  static std::uint64_t tileKey(std::uint64_t cell)
  {
    return cellKey(keyI(cell) >> 3, keyJ(cell) >> 3);
  }
  static std::uint64_t tileBit(std::uint64_t cell)
  {
    return std::uint64_t{1} << (((keyJ(cell) & 7) << 3) | (keyI(cell) & 7));
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
    std::vector<float> sums;
    std::vector<std::uint16_t> counts;
    sums.reserve(records);
    counts.reserve(records);
    std::size_t old = 0, e = 0;
    for (std::size_t t = 0; t < tiles.size(); ++t) {
      for (std::uint64_t rest = masks[t]; rest != 0; rest &= rest - 1) {
        const std::uint64_t bit = rest & (~rest + 1);
        float sum = 0.0f;
        std::uint16_t count = 0;
        if ((tiles[t].evidence & bit) != 0) {
          sum = probability_sums[old];
          count = feature_counts[old];
          ++old;
        }
        while (e < evidence.size()
               && order(evidence[e]) < std::make_pair(tiles[t].key, bit))
          ++e;
        for (; e < evidence.size()
               && order(evidence[e]) == std::make_pair(tiles[t].key, bit);
             ++e)
          addFeatures(sum, count, evidence[e].sum, evidence[e].count);
        sums.push_back(sum);
        counts.push_back(count);
      }
      tiles[t].evidence = masks[t];
    }
    probability_sums.swap(sums);
    feature_counts.swap(counts);
  }

  /** Calls f(key, probability sum, feature count) for every observed cell, sorted by
   * cellKey (row j, then column i). */
  template <typename F> void forEachCell(F f) const
  {
    std::vector<std::size_t> base;
    std::size_t records = 0;
    for (std::size_t g = 0; g < tiles.size();) {
      const std::int32_t tj = keyJ(tiles[g].key);
      std::size_t h = g;
      base.clear();
      while (h < tiles.size() && keyJ(tiles[h].key) == tj) {
        base.push_back(records);
        records += static_cast<std::size_t>(popcount64(tiles[h].evidence));
        ++h;
      }
      for (int row = 0; row < 8; ++row) {
        const auto j =
          static_cast<std::int32_t>(static_cast<std::int64_t>(tj) * 8 + row);
        for (std::size_t t = g; t < h; ++t) {
          const Tile& tile = tiles[t];
          const std::int64_t i0 = static_cast<std::int64_t>(keyI(tile.key)) * 8;
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
              sum = probability_sums[r];
              count = feature_counts[r];
            }
            f(cellKey(static_cast<std::int32_t>(i0 + col), j), sum, count);
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
      const std::int64_t i0 = static_cast<std::int64_t>(keyI(t.key)) * 8;
      const std::int64_t j0 = static_cast<std::int64_t>(keyJ(t.key)) * 8;
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
    probability_sums.clear();
    feature_counts.clear();
    insert(keys);
    std::vector<std::pair<std::pair<std::uint64_t, std::uint64_t>, std::size_t>>
      records;
    for (std::size_t k = 0; k < keys.size(); ++k)
      if (counts[k] != 0 || std::signbit(sums[k]) || sums[k] != 0.0f)
        records.push_back({{tileKey(keys[k]), tileBit(keys[k])}, k});
    std::sort(records.begin(), records.end());
    probability_sums.reserve(records.size());
    feature_counts.reserve(records.size());
    std::size_t t = 0;
    for (const auto& r : records) {
      while (tiles[t].key != r.first.first)
        ++t;
      tiles[t].evidence |= r.first.second;
      probability_sums.push_back(sums[r.second]);
      feature_counts.push_back(counts[r.second]);
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
    return probability_sums == o.probability_sums && feature_counts == o.feature_counts;
  }

  std::size_t bytes() const
  {
    return tiles.capacity() * sizeof(Tile) + probability_sums.capacity() * sizeof(float)
           + feature_counts.capacity() * sizeof(std::uint16_t);
  }
};

/** \brief Area moments of a map plane's evidence (the faces of the planar cuboids it
 * received), in double about an anchor point so that planes far from the world
 * origin keep their precision: weight = sum of the face areas, sum = sum of
 * area (centre - anchor), sum_sq = sum of area ((centre - anchor)(centre - anchor)^T
 * + width^2 / 12 h h^T + height^2 / 12 v v^T), the exact moments of the rectangles.
 * sum_sq is symmetric; its upper triangle is stored (xx, xy, xz, yy, yz, zz). */
struct PlaneMoments {
  Eigen::Vector3d anchor{Eigen::Vector3d::Zero()};
  double weight{0.0};
  Eigen::Vector3d sum{Eigen::Vector3d::Zero()};
  std::array<double, 6> sum_sq_upper{};

  /** The second moments as a symmetric matrix. */
  Eigen::Matrix3d sumSq() const
  {
    Eigen::Matrix3d s;
    s << sum_sq_upper[0], sum_sq_upper[1], sum_sq_upper[2], sum_sq_upper[1],
      sum_sq_upper[3], sum_sq_upper[4], sum_sq_upper[2], sum_sq_upper[4],
      sum_sq_upper[5];
    return s;
  }

  /** Stores \a s made exactly symmetric (rounding in the products of the updates is
   * not), so that the 6 values the file stores restore it bit for bit. */
  void setSumSq(const Eigen::Matrix3d& s)
  {
    const Eigen::Matrix3d sym = 0.5 * (s + s.transpose());
    sum_sq_upper = {sym(0, 0), sym(0, 1), sym(0, 2), sym(1, 1), sym(1, 2), sym(2, 2)};
  }

  /** Adds the face of \a c with weight its area plus \a min_weight (so that a face of
   * zero area still counts as a point). The first face sets the anchor. */
  void addFace(const PlanarCuboid& c, double min_weight)
  {
    const double w = c.width_m, h = c.height_m;
    const double area = w * h + min_weight;
    const Eigen::Vector3d centre = c.faceCentre().cast<double>();
    if (weight == 0.0)
      anchor = centre;
    const Eigen::Vector3d rel = centre - anchor;
    const Eigen::Vector3d hx = c.horizontal_axis.cast<double>();
    const Eigen::Vector3d vy = c.verticalAxis().cast<double>();
    weight += area;
    sum += area * rel;
    Eigen::Matrix3d sum_sq = sumSq();
    sum_sq += area
              * (rel * rel.transpose() + (w * w / 12.0) * hx * hx.transpose()
                 + (h * h / 12.0) * vy * vy.transpose());
    setSumSq(sum_sq);
  }

  /** Adds \a other (its moments moved to this anchor). */
  void add(const PlaneMoments& other)
  {
    if (other.weight == 0.0)
      return;
    if (weight == 0.0) {
      *this = other;
      return;
    }
    const Eigen::Vector3d delta = other.anchor - anchor;
    Eigen::Matrix3d sum_sq = sumSq();
    const Eigen::Matrix3d other_sum_sq = other.sumSq();
    sum_sq += other_sum_sq + other.sum * delta.transpose()
              + delta * other.sum.transpose()
              + other.weight * delta * delta.transpose();
    sum += other.sum + other.weight * delta;
    weight += other.weight;
    setSumSq(sum_sq);
  }

  /** Weighted mean squared distance of the evidence to the plane n . x + d = 0,
   * square meters (0 without evidence). */
  double meanSquaredDistance(const Eigen::Vector3d& n, double d) const
  {
    if (!(weight > 0.0))
      return 0.0;
    const double c = n.dot(anchor) + d;
    const double e =
      n.dot((sumSq() / weight) * n) + 2.0 * c * n.dot(sum / weight) + c * c;
    return std::max(0.0, e);
  }

  bool operator==(const PlaneMoments& o) const
  {
    return anchor == o.anchor && weight == o.weight && sum == o.sum
           && sum_sq_upper == o.sum_sq_upper;
  }
};

/** \brief A rectangle of a plane's cover, in raster cells [i0, i1) x [j0, j1), with
 * the mean probability of its cells and the number of features in it (24 bytes). */
struct RasterRect {
  std::int32_t i0, i1, j0, j1;
  float probability;
  std::uint32_t point_count;
};

/** \brief A map plane's raster frame: origin -d n on the plane it was created on,
 * u = z x n normalised (x projected for a horizontal plane), v = n x u. Derived from
 * the plane, not stored. */
struct RasterFrame {
  Eigen::Vector3f origin;
  Eigen::Vector3f u_axis;
  Eigen::Vector3f v_axis;

  RasterFrame(const Eigen::Vector3f& n, float offset)
  {
    origin = -offset * n;
    Eigen::Vector3f u = Eigen::Vector3f::UnitZ().cross(n);
    if (u.norm() < 1e-3f)
      u = Eigen::Vector3f::UnitX() - n * n.x();
    u_axis = u.normalized();
    v_axis = n.cross(u_axis);
  }
  /** Raster coordinates (in cells) of a world point projected on the frame. */
  Eigen::Vector2d toRaster(const Eigen::Vector3f& p, double inv_r) const
  {
    const Eigen::Vector3f q = p - origin;
    return {q.dot(u_axis) * inv_r, q.dot(v_axis) * inv_r};
  }
  /** World point of the centre of cell (i, j) on the frame's plane. */
  Eigen::Vector3f cellCentre(std::int64_t i, std::int64_t j, double r) const
  {
    return origin + u_axis * static_cast<float>((static_cast<double>(i) + 0.5) * r)
           + v_axis * static_cast<float>((static_cast<double>(j) + 0.5) * r);
  }
};

/** \brief How a raster frame's rectangles are placed on the refined plane: the
 * faces' horizontal axis on it (u projected along the normal, normalised) and the
 * lengths of the projections of u and v. Derived, not stored. */
struct FacePlacement {
  Eigen::Vector3f place_u;
  float scale_u;
  float scale_v;

  FacePlacement(const RasterFrame& frame, const Eigen::Vector3f& n)
  {
    const Eigen::Vector3f pu = frame.u_axis - n * n.dot(frame.u_axis);
    scale_u = pu.norm();
    // (u lies in the plane up to the angle between the normals, < pi / 2)
    place_u = scale_u > 1e-6f ? Eigen::Vector3f(pu / scale_u) : frame.u_axis;
    scale_v = (frame.v_axis - n * n.dot(frame.v_axis)).norm();
  }
};

/** \brief A map plane: the plane of its fixed raster frame, its refined
 * (least-squares) plane, the evidence moments, the raster and the cached cover. */
struct MapPlane {
  /** The plane the raster frame was created on (RasterFrame). */
  Eigen::Vector3f frame_normal{Eigen::Vector3f::UnitZ()};
  float frame_d{0.0f};
  /** The refined plane (its normal is within plane_merge_angle_rad / 2 of the
   * frame's after every integrate(), re-anchored otherwise). */
  Eigen::Vector3f normal{Eigen::Vector3f::UnitZ()};
  float d{0.0f};
  PlaneMoments moments;
  Raster raster;
  /** Cached cover (valid when !dirty). */
  std::vector<RasterRect> rects;
  bool dirty{true};

  void setFrame(const Eigen::Vector3f& n, float offset)
  {
    frame_normal = n;
    frame_d = offset;
  }
  void setRefined(const Eigen::Vector3f& n, float offset)
  {
    normal = n;
    d = offset;
  }
  RasterFrame frame() const { return RasterFrame(frame_normal, frame_d); }
};

/** \brief Key of a non-planar cell: quantised centre and size. */
struct NonPlanarKey {
  std::array<std::int32_t, 6> q;
  bool operator==(const NonPlanarKey& o) const { return q == o.q; }
};
struct NonPlanarKeyHash {
  std::size_t operator()(const NonPlanarKey& k) const
  {
    std::uint64_t h = 1469598103934665603ull;
    for (const auto v : k.q) {
      h ^= static_cast<std::uint32_t>(v);
      h *= 1099511628211ull;
    }
    return static_cast<std::size_t>(h);
  }
};

/** \brief Orientation of non-planar boxes (normal, horizontal axis), shared by the
 * cells that have it (typically one or a few for a whole map). */
struct BoxAxes {
  Eigen::Vector3f normal;
  Eigen::Vector3f horizontal_axis;
};

/** \brief A non-planar cell (40 bytes): the latest cuboid's box (its axes an index
 * into Impl::np_axes) and the sums of its features. */
struct NonPlanarCell {
  Eigen::Vector3f centre;
  float width_m;
  float height_m;
  float thickness_m;
  std::uint32_t axes;
  std::uint32_t feature_count{0};
  double probability_sum{0.0};

  NonPlanarCell(const PlanarCuboid& c, std::uint32_t axes_index) :
      centre(c.centre), width_m(c.width_m), height_m(c.height_m),
      thickness_m(c.thickness_m), axes(axes_index)
  {}
};

/** \brief Key of a box orientation: the bit patterns of its six floats. */
using AxesKey = std::array<std::uint32_t, 6>;

AxesKey
axesKey(const Eigen::Vector3f& normal, const Eigen::Vector3f& horizontal_axis)
{
  AxesKey key;
  const float v[6] = {normal.x(),          normal.y(),          normal.z(),
                      horizontal_axis.x(), horizontal_axis.y(), horizontal_axis.z()};
  std::memcpy(key.data(), v, sizeof(v));
  return key;
}

/** \brief An entry of the non-planar cells' spatial index: a bin key (split in two
 * words so that the entry is 12 bytes) and a cell index. */
struct BinEntry {
  std::uint32_t key_hi{0};
  std::uint32_t key_lo{0};
  std::uint32_t index{0};

  BinEntry() = default;
  BinEntry(std::uint64_t key, std::uint32_t i) :
      key_hi(static_cast<std::uint32_t>(key >> 32)),
      key_lo(static_cast<std::uint32_t>(key)), index(i)
  {}
  std::uint64_t key() const
  {
    return (static_cast<std::uint64_t>(key_hi) << 32) | key_lo;
  }
  bool operator<(const BinEntry& o) const { return key() < o.key(); }
};

} // namespace

struct SurfaceLayer::Impl {
  std::vector<MapPlane, Eigen::aligned_allocator<MapPlane>> planes;
  /** The refined planes, as returned by getPlanes(). */
  PlaneModels plane_models;
  std::vector<NonPlanarCell> non_planar;
  /** The distinct orientations of the non-planar cells. */
  std::vector<BoxAxes> np_axes;

  // The query index (built under mutex by ensureIndex(), freed by integrate()).
  std::mutex mutex;
  bool index_valid{false};
  /** The cuboids the index refers to (getCuboids() at the time it was built). */
  PlanarCuboids index_cuboids;
  /** Spatial index: bin key -> cuboid indices; "large" cuboids are tested always. */
  float bin_m{0.4f};
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> bins;
  std::vector<std::uint32_t> large;
  Eigen::Vector3f bounds_min{Eigen::Vector3f::Zero()};
  Eigen::Vector3f bounds_max{Eigen::Vector3f::Zero()};

  void invalidate()
  {
    index_valid = false;
    decltype(index_cuboids)().swap(index_cuboids);
    decltype(bins)().swap(bins);
    decltype(large)().swap(large);
  }
  /** Calls f(bin key) for the bins of the bounding box of \a c grown by \a grow;
   * returns false (nothing called) when they exceed MAX_BINS_PER_CUBOID. */
  template <typename F>
  bool forNonPlanarBins(const PlanarCuboid& c, float grow, float bin, F f) const;
  /** The cuboid of non-planar cell \a cell (plane_id -1; probability and point_count
   * unset). */
  PlanarCuboid nonPlanarCuboid(const NonPlanarCell& cell) const
  {
    PlanarCuboid c;
    c.centre = cell.centre;
    c.normal = np_axes[cell.axes].normal;
    c.horizontal_axis = np_axes[cell.axes].horizontal_axis;
    c.width_m = cell.width_m;
    c.height_m = cell.height_m;
    c.thickness_m = cell.thickness_m;
    c.plane_id = -1;
    c.is_planar = false;
    return c;
  }
  /** Index of the orientation of \a c in np_axes (added when new); \a lookup maps
   * the keys of np_axes to their index. */
  std::uint32_t internAxes(const PlanarCuboid& c,
                           std::map<AxesKey, std::uint32_t>& lookup)
  {
    const auto inserted = lookup.emplace(axesKey(c.normal, c.horizontal_axis),
                                         static_cast<std::uint32_t>(np_axes.size()));
    if (inserted.second)
      np_axes.push_back(BoxAxes{c.normal, c.horizontal_axis});
    return inserted.first->second;
  }
  /** Removes the orientations no cell uses. */
  void pruneAxes();
  /** Rebuilds dirty planes' covers; caller holds the mutex. */
  void ensureCovers(const Params& params);
  /** Appends the cuboids (planes' rectangles, then non-planar cells) to \a out;
   * caller holds the mutex. */
  void buildCuboids(const Params& params, PlanarCuboids& out);
  /** Builds the query index over all cuboids; caller holds the mutex. */
  void ensureIndex(const Params& params);
};

namespace {

std::uint64_t
binKey(std::int64_t x, std::int64_t y, std::int64_t z)
{
  // 21 bits per axis (+-1e6 bins) is ample for |coordinates| <= 1e7 m at >= 4 cm bins
  const auto pack = [](std::int64_t v) {
    return static_cast<std::uint64_t>(v + (std::int64_t{1} << 20)) & 0x1FFFFFu;
  };
  return (pack(x) << 42) | (pack(y) << 21) | pack(z);
}

void
cuboidBounds(const PlanarCuboid& c, Eigen::Vector3f& lo, Eigen::Vector3f& hi)
{
  const Eigen::Vector3f half = (c.horizontal_axis * (0.5f * c.width_m)).cwiseAbs()
                               + (c.verticalAxis() * (0.5f * c.height_m)).cwiseAbs()
                               + (c.normal * (0.5f * c.thickness_m)).cwiseAbs();
  lo = c.centre - half;
  hi = c.centre + half;
}

} // namespace

template <typename F>
bool
SurfaceLayer::Impl::forNonPlanarBins(const PlanarCuboid& c,
                                     float grow,
                                     float bin,
                                     F f) const
{
  Eigen::Vector3f lo, hi;
  cuboidBounds(c, lo, hi);
  lo.array() -= grow;
  hi.array() += grow;
  const Eigen::Vector3d a = (lo / bin).cast<double>().array().floor();
  const Eigen::Vector3d b = (hi / bin).cast<double>().array().floor();
  if (!((b - a + Eigen::Vector3d::Ones()).prod() <= MAX_BINS_PER_CUBOID))
    return false;
  for (auto x = static_cast<std::int64_t>(a.x()); x <= static_cast<std::int64_t>(b.x());
       ++x)
    for (auto y = static_cast<std::int64_t>(a.y());
         y <= static_cast<std::int64_t>(b.y()); ++y)
      for (auto z = static_cast<std::int64_t>(a.z());
           z <= static_cast<std::int64_t>(b.z()); ++z)
        f(binKey(x, y, z));
  return true;
}

void
SurfaceLayer::Impl::pruneAxes()
{
  constexpr std::uint32_t UNUSED = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> renumber(np_axes.size(), UNUSED);
  for (const auto& cell : non_planar)
    renumber[cell.axes] = 0;
  std::uint32_t used = 0;
  for (std::size_t a = 0; a < np_axes.size(); ++a)
    if (renumber[a] != UNUSED) {
      np_axes[used] = np_axes[a];
      renumber[a] = used++;
    }
  if (used == np_axes.size())
    return;
  np_axes.resize(used);
  np_axes.shrink_to_fit();
  for (auto& cell : non_planar)
    cell.axes = renumber[cell.axes];
}

namespace {

/** \brief Validates parameters; throws planar_grid::Exception. */
void
validate(const SurfaceLayer::Params& p)
{
  const auto bad = [](const std::string& what) {
    throw Exception("SurfaceLayer: invalid parameter " + what);
  };
  if (!(p.resolution_m >= 1e-3 && p.resolution_m <= 100.0))
    bad("resolution_m (must be in [0.001, 100] m)");
  if (!(p.thickness_m > 0.0) || !std::isfinite(p.thickness_m))
    bad("thickness_m (must be finite and > 0 m)");
  if (!(p.plane_merge_angle_rad > 0.0 && p.plane_merge_angle_rad < M_PI / 2))
    bad("plane_merge_angle_rad (must be in (0, pi/2) rad)");
  if (!(p.plane_merge_distance_m > 0.0) || !std::isfinite(p.plane_merge_distance_m))
    bad("plane_merge_distance_m (must be finite and > 0 m)");
  if (!(p.occupancy_thres > 0.0 && p.occupancy_thres < 1.0))
    bad("occupancy_thres (must be a probability in (0, 1))");
  if (!(p.feature_distance_m >= 0.0) || !std::isfinite(p.feature_distance_m))
    bad("feature_distance_m (must be finite and >= 0 m)");
  if (p.close_gaps_cells < 0 || p.close_gaps_cells > MAX_CLOSE_GAPS_CELLS)
    bad("close_gaps_cells (must be in [0, " + std::to_string(MAX_CLOSE_GAPS_CELLS)
        + "] cells)");
  if (p.merge_rule != SurfaceMergeRule::PAPER
      && p.merge_rule != SurfaceMergeRule::MIN_RECTANGLES
      && p.merge_rule != SurfaceMergeRule::DENSITY)
    bad("merge_rule (must be paper, min_rectangles or density)");
  if (!(p.cover_density >= 0.5 && p.cover_density <= 1.0))
    bad("cover_density (must be a share in [0.5, 1])");
}

NonPlanarKey
nonPlanarKey(const PlanarCuboid& c, double resolution_m)
{
  const double inv = 1.0 / resolution_m;
  const auto q = [](double x) {
    return static_cast<std::int32_t>(std::max(-2.0e9, std::min(2.0e9, std::floor(x))));
  };
  const auto r = [](double x) {
    return static_cast<std::int32_t>(std::max(-2.0e9, std::min(2.0e9, std::round(x))));
  };
  return NonPlanarKey{{q(c.centre.x() * inv), q(c.centre.y() * inv),
                       q(c.centre.z() * inv), r(c.width_m * inv), r(c.height_m * inv),
                       r(c.thickness_m * inv)}};
}

/** \brief Least-squares plane of the evidence \a m: the normal is the eigenvector of
 * the smallest eigenvalue of the covariance, oriented like \a current_normal, used
 * when the evidence spans a plane (middle eigenvalue >= 4 x the smallest, > 0) and
 * within the angle whose cosine is \a cos_max_angle of \a current_normal (else
 * \a current_normal is kept); d puts the plane through the centroid. Returns false
 * (outputs untouched) without evidence or for non-finite results. */
bool
fitPlane(const PlaneMoments& m,
         const Eigen::Vector3f& current_normal,
         double cos_max_angle,
         Eigen::Vector3d& normal,
         double& d)
{
  if (!(m.weight > 0.0) || !std::isfinite(m.weight))
    return false;
  const Eigen::Vector3d mean = m.sum / m.weight;
  const Eigen::Matrix3d covariance = m.sumSq() / m.weight - mean * mean.transpose();
  if (!mean.allFinite() || !covariance.allFinite())
    return false;
  Eigen::Vector3d n = current_normal.cast<double>().normalized();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() == Eigen::Success) {
    const Eigen::Vector3d ev = solver.eigenvalues(); // ascending
    if (ev(1) > 0.0 && ev(1) >= 4.0 * std::max(0.0, ev(0))) {
      Eigen::Vector3d e = solver.eigenvectors().col(0).normalized();
      if (e.dot(n) < 0.0)
        e = -e;
      if (e.allFinite() && e.dot(n) >= cos_max_angle)
        n = e;
    }
  }
  const double offset = -n.dot(m.anchor + mean);
  if (!n.allFinite() || !std::isfinite(offset) || std::abs(offset) > MAX_COORDINATE_M)
    return false;
  normal = n;
  d = offset;
  return true;
}

/** \brief Refits the plane of \a plane from its moments (kept when the fit fails). */
void
refitPlane(MapPlane& plane, double cos_angle)
{
  Eigen::Vector3d n;
  double d = 0.0;
  if (fitPlane(plane.moments, plane.normal, cos_angle, n, d))
    plane.setRefined(n.cast<float>().normalized(), static_cast<float>(d));
}

/** \brief True when one plane explains two evidence sets: \a a (normal \a na, a map
 * plane) and \a b (normal \a nb): the normals within the merge angle, and the
 * least-squares plane of both together within the merge angle of each normal and
 * within the merge distance (root mean square) of each set. \a rms_b is then the
 * root mean square distance of \a b to that plane, meters. */
bool
explainedByOnePlane(const PlaneMoments& a,
                    const Eigen::Vector3f& na,
                    const PlaneMoments& b,
                    const Eigen::Vector3f& nb,
                    const SurfaceLayer::Params& params,
                    double cos_angle,
                    double& rms_b)
{
  if (!(na.dot(nb) >= cos_angle) || !(a.weight > 0.0) || !(b.weight > 0.0))
    return false;
  PlaneMoments joint = a;
  joint.add(b);
  Eigen::Vector3d n;
  double d = 0.0;
  if (!fitPlane(joint, na, cos_angle, n, d) || !(n.dot(nb.cast<double>()) >= cos_angle))
    return false;
  const double limit = params.plane_merge_distance_m * params.plane_merge_distance_m;
  const double ea = a.meanSquaredDistance(n, d);
  const double eb = b.meanSquaredDistance(n, d);
  if (!(ea <= limit) || !(eb <= limit))
    return false;
  rms_b = std::sqrt(eb);
  return true;
}

/** \brief Cells inside a gap of at most \a max_gap cells between two observed cells
 * of one row or one column (the closing of Params::close_gaps_cells); \a keys sorted
 * by row, then column. The result is sorted, unique and disjoint from \a keys. */
std::vector<std::uint64_t>
closeGaps(const std::vector<std::uint64_t>& keys, int max_gap)
{
  std::vector<std::uint64_t> filled;
  if (max_gap <= 0 || keys.size() < 2)
    return filled;
  // Rows: consecutive keys of one row.
  for (std::size_t k = 0; k + 1 < keys.size(); ++k) {
    const std::int32_t j = keyJ(keys[k]);
    if (keyJ(keys[k + 1]) != j)
      continue;
    const std::int64_t a = keyI(keys[k]), b = keyI(keys[k + 1]);
    if (b - a - 1 >= 1 && b - a - 1 <= max_gap)
      for (std::int64_t i = a + 1; i < b; ++i)
        filled.push_back(cellKey(static_cast<std::int32_t>(i), j));
  }
  // Columns: the same on the transposed keys (column i, then row j).
  std::vector<std::uint64_t> transposed(keys.size());
  for (std::size_t k = 0; k < keys.size(); ++k)
    transposed[k] = cellKey(keyJ(keys[k]), keyI(keys[k]));
  std::sort(transposed.begin(), transposed.end());
  for (std::size_t k = 0; k + 1 < transposed.size(); ++k) {
    const std::int32_t i = keyJ(transposed[k]);
    if (keyJ(transposed[k + 1]) != i)
      continue;
    const std::int64_t a = keyI(transposed[k]), b = keyI(transposed[k + 1]);
    if (b - a - 1 >= 1 && b - a - 1 <= max_gap)
      for (std::int64_t j = a + 1; j < b; ++j)
        filled.push_back(cellKey(i, static_cast<std::int32_t>(j)));
  }
  std::sort(filled.begin(), filled.end());
  filled.erase(std::unique(filled.begin(), filled.end()), filled.end());
  return filled;
}

/** \brief A rectangle of raster cells [i0, i1) x [j0, j1). */
struct CellRect {
  std::int32_t i0, i1, j0, j1;
};

/** \brief The paper's merge (Fig. 6b): maximal runs of one class along u per row,
 * then runs with the same [i0, i1) and class in consecutive rows stacked into one
 * rectangle. \a keys sorted by row, then column; \a cls the class of each. */
std::vector<CellRect>
paperCover(const std::vector<std::uint64_t>& keys, const std::vector<std::uint8_t>& cls)
{
  struct Run {
    std::int32_t i0, i1;
    std::uint8_t cls;
    std::size_t rect;
  };
  std::vector<CellRect> rects;
  std::vector<Run> previous, current;
  std::int64_t previous_row = std::numeric_limits<std::int64_t>::min();
  const std::size_t n = keys.size();
  for (std::size_t k = 0; k < n;) {
    const std::int32_t j = keyJ(keys[k]);
    if (static_cast<std::int64_t>(j) != previous_row + 1)
      previous.clear();
    current.clear();
    std::size_t p = 0;
    while (k < n && keyJ(keys[k]) == j) {
      const std::uint8_t c = cls[k];
      const std::int32_t i0 = keyI(keys[k]);
      std::int64_t i1 = static_cast<std::int64_t>(i0) + 1;
      std::size_t e = k + 1;
      while (e < n && keyJ(keys[e]) == j && keyI(keys[e]) == i1 && cls[e] == c) {
        ++i1;
        ++e;
      }
      const auto end = static_cast<std::int32_t>(i1);
      while (p < previous.size() && previous[p].i0 < i0)
        ++p;
      std::size_t rect;
      if (p < previous.size() && previous[p].i0 == i0 && previous[p].i1 == end
          && previous[p].cls == c) {
        rect = previous[p].rect;
        rects[rect].j1 = j + 1;
      } else {
        rect = rects.size();
        rects.push_back(CellRect{i0, end, j, j + 1});
      }
      current.push_back(Run{i0, end, c, rect});
      k = e;
    }
    std::swap(previous, current);
    previous_row = j;
  }
  return rects;
}

/** \brief A minimum partition into rectangles of one 4-connected component \a keys
 * (inside the box of w x h cells at (i_lo, j_lo)), by the classical construction for
 * rectilinear polygons with holes (Lipski et al. 1979; Ohtsuki 1982; Ferrari et al.
 * 1979): a reflex (concave) corner of the region is a grid point with 3 of its 4
 * cells in it; a chord joins two reflex corners facing each other along a grid line
 * through the region's interior; a largest set of pairwise non-intersecting chords
 * (the complement of a minimum vertex cover of the bipartite intersection graph of
 * horizontal and vertical chords, by Koenig's theorem from a maximum matching) is
 * cut, then every reflex corner not yet resolved is cut horizontally until the
 * boundary or a cut. That gives the fewest rectangles: reflex corners - chords + 1 -
 * holes. Returns an empty vector if a region is not a rectangle (not expected; the
 * caller then keeps the paper's cover). */
std::vector<CellRect>
minimumPartition(const std::vector<std::uint64_t>& keys,
                 std::int64_t i_lo,
                 std::int64_t j_lo,
                 std::int64_t w,
                 std::int64_t h)
{
  const auto W = static_cast<std::size_t>(w);
  const auto H = static_cast<std::size_t>(h);
  std::vector<std::uint8_t> inside(W * H, 0);
  for (const auto key : keys)
    inside[static_cast<std::size_t>(keyJ(key) - j_lo) * W
           + static_cast<std::size_t>(keyI(key) - i_lo)] = 1;
  const auto in = [&](std::int64_t x, std::int64_t y) {
    return x >= 0 && y >= 0 && x < w && y < h
           && inside[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)]
                != 0;
  };
  // Cuts: cut_right[c] separates cell c = (x, y) from (x + 1, y); cut_up[c] from
  // (x, y + 1).
  std::vector<std::uint8_t> cut_right(W * H, 0), cut_up(W * H, 0);
  const auto cell = [W](std::int64_t x, std::int64_t y) {
    return static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x);
  };
  // Grid point (x, y), x in [0, w], y in [0, h], is the corner shared by the cells
  // (x - 1, y - 1), (x, y - 1), (x - 1, y), (x, y).
  const auto count_in = [&](std::int64_t x, std::int64_t y) {
    return (in(x - 1, y - 1) ? 1 : 0) + (in(x, y - 1) ? 1 : 0) + (in(x - 1, y) ? 1 : 0)
           + (in(x, y) ? 1 : 0);
  };
  struct Reflex {
    std::int64_t x, y;
    int dx, dy; // directions of its horizontal and vertical extensions
  };
  std::vector<Reflex> reflex;
  for (std::int64_t y = 0; y <= h; ++y)
    for (std::int64_t x = 0; x <= w; ++x)
      if (count_in(x, y) == 3) {
        const bool west_out = !in(x - 1, y - 1) || !in(x - 1, y);
        const bool south_out = !in(x - 1, y - 1) || !in(x, y - 1);
        reflex.push_back(Reflex{x, y, west_out ? 1 : -1, south_out ? 1 : -1});
      }
  // a point's reflex index, -1 otherwise
  std::vector<std::int32_t> reflex_at((W + 1) * (H + 1), -1);
  for (std::size_t k = 0; k < reflex.size(); ++k)
    reflex_at[static_cast<std::size_t>(reflex[k].y) * (W + 1)
              + static_cast<std::size_t>(reflex[k].x)] = static_cast<std::int32_t>(k);
  const auto reflexAt = [&](std::int64_t x, std::int64_t y) {
    return reflex_at[static_cast<std::size_t>(y) * (W + 1)
                     + static_cast<std::size_t>(x)];
  };
  // Chords: from each reflex corner extending +x (+y), walk through interior points
  // to the first boundary point; a chord when that is a reflex corner.
  struct Chord {
    std::int64_t fixed, lo, hi; // y (x) of the line, x (y) range of the points
    std::int32_t a, b;          // its reflex corners
  };
  std::vector<Chord> horizontal, vertical;
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    const Reflex& p = reflex[k];
    if (p.dx == 1) {
      std::int64_t x = p.x + 1;
      while (x <= w && in(x - 1, p.y - 1) && in(x - 1, p.y) && count_in(x, p.y) == 4)
        ++x;
      if (x <= w && in(x - 1, p.y - 1) && in(x - 1, p.y) && reflexAt(x, p.y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(x, p.y))].dx == -1)
        horizontal.push_back(
          Chord{p.y, p.x, x, static_cast<std::int32_t>(k), reflexAt(x, p.y)});
    }
    if (p.dy == 1) {
      std::int64_t y = p.y + 1;
      while (y <= h && in(p.x - 1, y - 1) && in(p.x, y - 1) && count_in(p.x, y) == 4)
        ++y;
      if (y <= h && in(p.x - 1, y - 1) && in(p.x, y - 1) && reflexAt(p.x, y) >= 0
          && reflex[static_cast<std::size_t>(reflexAt(p.x, y))].dy == -1)
        vertical.push_back(
          Chord{p.x, p.y, y, static_cast<std::int32_t>(k), reflexAt(p.x, y)});
    }
  }
  // Bipartite intersection graph (touching counts: a shared corner can take only
  // one chord) and a maximum matching (augmenting paths, iterative).
  std::vector<std::vector<std::uint32_t>> adjacent(horizontal.size());
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    for (std::size_t b = 0; b < vertical.size(); ++b)
      if (vertical[b].fixed >= horizontal[a].lo && vertical[b].fixed <= horizontal[a].hi
          && horizontal[a].fixed >= vertical[b].lo
          && horizontal[a].fixed <= vertical[b].hi)
        adjacent[a].push_back(static_cast<std::uint32_t>(b));
  constexpr std::uint32_t NONE = std::numeric_limits<std::uint32_t>::max();
  std::vector<std::uint32_t> match_h(horizontal.size(), NONE),
    match_v(vertical.size(), NONE);
  {
    std::vector<std::uint32_t> seen(vertical.size(), NONE);
    std::vector<std::pair<std::uint32_t, std::size_t>> stack; // (h, next edge)
    for (std::size_t root = 0; root < horizontal.size(); ++root) {
      stack.assign(1, {static_cast<std::uint32_t>(root), 0});
      bool found = false;
      while (!stack.empty() && !found) {
        auto& [a, next] = stack.back();
        if (next == adjacent[a].size()) {
          stack.pop_back();
          continue;
        }
        const std::uint32_t b = adjacent[a][next++];
        if (seen[b] == static_cast<std::uint32_t>(root))
          continue;
        seen[b] = static_cast<std::uint32_t>(root);
        if (match_v[b] == NONE) {
          // augment along the stack: each h on it takes the v it went through
          std::uint32_t v = b;
          for (auto it = stack.rbegin(); it != stack.rend(); ++it) {
            const std::uint32_t u = it->first;
            const std::uint32_t previous = match_h[u];
            match_h[u] = v;
            match_v[v] = u;
            v = previous;
          }
          found = true;
        } else {
          stack.push_back({match_v[b], 0});
        }
      }
    }
  }
  // Koenig: Z = vertices reachable from unmatched horizontal chords by alternating
  // paths; the largest independent set is (horizontal in Z) + (vertical not in Z).
  std::vector<std::uint8_t> z_h(horizontal.size(), 0), z_v(vertical.size(), 0);
  {
    std::vector<std::uint32_t> queue;
    for (std::size_t a = 0; a < horizontal.size(); ++a)
      if (match_h[a] == NONE) {
        z_h[a] = 1;
        queue.push_back(static_cast<std::uint32_t>(a));
      }
    for (std::size_t q = 0; q < queue.size(); ++q)
      for (const auto b : adjacent[queue[q]])
        if (z_v[b] == 0) {
          z_v[b] = 1;
          const std::uint32_t a = match_v[b];
          if (a != NONE && z_h[a] == 0) {
            z_h[a] = 1;
            queue.push_back(a);
          }
        }
  }
  std::vector<std::uint8_t> resolved(reflex.size(), 0);
  for (std::size_t a = 0; a < horizontal.size(); ++a)
    if (z_h[a] != 0) {
      const Chord& c = horizontal[a];
      for (std::int64_t x = c.lo; x < c.hi; ++x)
        cut_up[cell(x, c.fixed - 1)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  for (std::size_t b = 0; b < vertical.size(); ++b)
    if (z_v[b] == 0) {
      const Chord& c = vertical[b];
      for (std::int64_t y = c.lo; y < c.hi; ++y)
        cut_right[cell(c.fixed - 1, y)] = 1;
      resolved[static_cast<std::size_t>(c.a)] =
        resolved[static_cast<std::size_t>(c.b)] = 1;
    }
  // Every other reflex corner: a horizontal cut to the boundary or the first cut.
  // (A cut touching a reflex corner lies on one of its extensions: it is resolved.)
  const auto verticalCutAt = [&](std::int64_t x, std::int64_t y) {
    return (in(x - 1, y) && in(x, y) && cut_right[cell(x - 1, y)] != 0)
           || (in(x - 1, y - 1) && in(x, y - 1) && cut_right[cell(x - 1, y - 1)] != 0);
  };
  const auto touchesCut = [&](std::int64_t x, std::int64_t y) {
    return verticalCutAt(x, y)
           || (in(x - 1, y - 1) && in(x - 1, y) && cut_up[cell(x - 1, y - 1)] != 0)
           || (in(x, y - 1) && in(x, y) && cut_up[cell(x, y - 1)] != 0);
  };
  for (std::size_t k = 0; k < reflex.size(); ++k) {
    if (resolved[k] != 0 || touchesCut(reflex[k].x, reflex[k].y))
      continue;
    const Reflex& p = reflex[k];
    for (std::int64_t x = p.x;;) {
      const std::int64_t column = p.dx == 1 ? x : x - 1;
      if (!in(column, p.y - 1) || !in(column, p.y)
          || cut_up[cell(column, p.y - 1)] != 0)
        break;
      cut_up[cell(column, p.y - 1)] = 1;
      x += p.dx;
      if (count_in(x, p.y) != 4 || verticalCutAt(x, p.y))
        break;
    }
  }
  // The regions between cuts; each must be a rectangle.
  std::vector<std::uint32_t> region(W * H, NONE);
  std::vector<CellRect> rects;
  std::vector<std::size_t> queue;
  for (std::int64_t y0 = 0; y0 < h; ++y0)
    for (std::int64_t x0 = 0; x0 < w; ++x0) {
      if (!in(x0, y0) || region[cell(x0, y0)] != NONE)
        continue;
      const auto id = static_cast<std::uint32_t>(rects.size());
      std::int64_t x_min = x0, x_max = x0, y_min = y0, y_max = y0;
      std::size_t cells = 0;
      queue.assign(1, cell(x0, y0));
      region[cell(x0, y0)] = id;
      for (std::size_t q = 0; q < queue.size(); ++q) {
        const auto x = static_cast<std::int64_t>(queue[q] % W);
        const auto y = static_cast<std::int64_t>(queue[q] / W);
        ++cells;
        x_min = std::min(x_min, x);
        x_max = std::max(x_max, x);
        y_min = std::min(y_min, y);
        y_max = std::max(y_max, y);
        const auto visit = [&](std::int64_t nx, std::int64_t ny, bool blocked) {
          if (!blocked && in(nx, ny) && region[cell(nx, ny)] == NONE) {
            region[cell(nx, ny)] = id;
            queue.push_back(cell(nx, ny));
          }
        };
        visit(x + 1, y, x + 1 < w && cut_right[cell(x, y)] != 0);
        visit(x - 1, y, x > 0 && cut_right[cell(x - 1, y)] != 0);
        visit(x, y + 1, y + 1 < h && cut_up[cell(x, y)] != 0);
        visit(x, y - 1, y > 0 && cut_up[cell(x, y - 1)] != 0);
      }
      if (static_cast<std::int64_t>(cells) != (x_max - x_min + 1) * (y_max - y_min + 1))
        return {};
      rects.push_back(CellRect{static_cast<std::int32_t>(i_lo + x_min),
                               static_cast<std::int32_t>(i_lo + x_max + 1),
                               static_cast<std::int32_t>(j_lo + y_min),
                               static_cast<std::int32_t>(j_lo + y_max + 1)});
    }
  return rects;
}

/** \brief The 4-connected components of cells of one class: component c holds the
 * keys members[start[c]] .. members[start[c + 1] - 1], in key order; components are
 * numbered by their first cell. \a keys sorted by row, then column; \a cls the
 * class of each. */
struct CellComponents {
  std::vector<std::uint64_t> members;
  std::vector<std::size_t> start;
  std::size_t size() const { return start.size() - 1; }
};

CellComponents
cellComponents(const std::vector<std::uint64_t>& keys,
               const std::vector<std::uint8_t>& cls)
{
  const std::size_t n = keys.size();
  std::vector<std::uint32_t> parent(n);
  for (std::size_t k = 0; k < n; ++k)
    parent[k] = static_cast<std::uint32_t>(k);
  const auto root = [&parent](std::uint32_t k) {
    while (parent[k] != k) {
      parent[k] = parent[parent[k]];
      k = parent[k];
    }
    return k;
  };
  const auto unite = [&](std::size_t a, std::size_t b) {
    const std::uint32_t ra = root(static_cast<std::uint32_t>(a));
    const std::uint32_t rb = root(static_cast<std::uint32_t>(b));
    if (ra != rb)
      parent[std::max(ra, rb)] = std::min(ra, rb);
  };
  for (std::size_t k = 0; k < n; ++k) {
    const std::int32_t i = keyI(keys[k]), j = keyJ(keys[k]);
    if (k + 1 < n && keyJ(keys[k + 1]) == j
        && static_cast<std::int64_t>(keyI(keys[k + 1]))
             == static_cast<std::int64_t>(i) + 1
        && cls[k + 1] == cls[k])
      unite(k, k + 1);
    if (static_cast<std::int64_t>(j) + 1 > MAX_CELL_INDEX)
      continue;
    const std::uint64_t up = cellKey(i, j + 1);
    const auto it = std::lower_bound(keys.begin() + static_cast<std::ptrdiff_t>(k) + 1,
                                     keys.end(), up);
    if (it != keys.end() && *it == up
        && cls[static_cast<std::size_t>(it - keys.begin())] == cls[k])
      unite(k, static_cast<std::size_t>(it - keys.begin()));
  }
  // Components numbered by their first cell; members in key order.
  std::vector<std::uint32_t> component(n);
  std::vector<std::uint32_t> id_of_root(n, std::numeric_limits<std::uint32_t>::max());
  std::vector<std::size_t> sizes;
  for (std::size_t k = 0; k < n; ++k) {
    const std::uint32_t rt = root(static_cast<std::uint32_t>(k));
    if (id_of_root[rt] == std::numeric_limits<std::uint32_t>::max()) {
      id_of_root[rt] = static_cast<std::uint32_t>(sizes.size());
      sizes.push_back(0);
    }
    component[k] = id_of_root[rt];
    ++sizes[component[k]];
  }
  std::vector<std::size_t> start(sizes.size() + 1, 0);
  for (std::size_t c = 0; c < sizes.size(); ++c)
    start[c + 1] = start[c] + sizes[c];
  CellComponents out;
  out.members.resize(n);
  {
    std::vector<std::size_t> fill(start.begin(), start.end() - 1);
    for (std::size_t k = 0; k < n; ++k)
      out.members[fill[component[k]]++] = keys[k];
  }
  out.start = std::move(start);
  return out;
}

/** \brief Whether the dense grid of a component of \a cells cells in a \a w x \a h
 * bounding box is affordable (a 4-connected component of m cells spans at most
 * m x m cells: a long diagonal staircase would not be). */
bool
denseGridAffordable(std::int64_t w, std::int64_t h, std::size_t cells)
{
  return static_cast<double>(w) * static_cast<double>(h)
         <= 8.0 * static_cast<double>(cells) + 4096.0;
}

/** \brief Bounding box [i_lo, i_lo + w) x [j_lo, j_lo + h) of \a sub (sorted). */
void
cellBounds(const std::vector<std::uint64_t>& sub,
           std::int64_t& i_lo,
           std::int64_t& j_lo,
           std::int64_t& w,
           std::int64_t& h)
{
  i_lo = keyI(sub.front());
  std::int64_t i_hi = i_lo;
  for (const auto key : sub) {
    i_lo = std::min<std::int64_t>(i_lo, keyI(key));
    i_hi = std::max<std::int64_t>(i_hi, keyI(key));
  }
  j_lo = keyJ(sub.front());
  w = i_hi - i_lo + 1;
  h = keyJ(sub.back()) - j_lo + 1;
}

/** \brief The MIN_RECTANGLES cover of one component \a sub: the minimum partition,
 * or the paper's cover when that is as small (always when it is one rectangle) or
 * when the component's bounding box is much larger than its cells. */
std::vector<CellRect>
fewestRectangles(const std::vector<std::uint64_t>& sub)
{
  const std::vector<std::uint8_t> one_class(sub.size(), 0);
  std::vector<CellRect> paper = paperCover(sub, one_class);
  if (paper.size() > 1) {
    std::int64_t i_lo, j_lo, w, h;
    cellBounds(sub, i_lo, j_lo, w, h);
    if (denseGridAffordable(w, h, sub.size())) {
      std::vector<CellRect> fewest = minimumPartition(sub, i_lo, j_lo, w, h);
      if (!fewest.empty() && fewest.size() < paper.size())
        paper.swap(fewest);
    }
  }
  return paper;
}

/** \brief The MIN_RECTANGLES cover: per 4-connected component of one class, the
 * fewest rectangles (fewestRectangles). */
std::vector<CellRect>
minRectangleCover(const std::vector<std::uint64_t>& keys,
                  const std::vector<std::uint8_t>& cls)
{
  const CellComponents components = cellComponents(keys, cls);
  std::vector<CellRect> rects;
  std::vector<std::uint64_t> sub;
  for (std::size_t c = 0; c < components.size(); ++c) {
    sub.assign(components.members.begin()
                 + static_cast<std::ptrdiff_t>(components.start[c]),
               components.members.begin()
                 + static_cast<std::ptrdiff_t>(components.start[c + 1]));
    const std::vector<CellRect> part = fewestRectangles(sub);
    rects.insert(rects.end(), part.begin(), part.end());
  }
  return rects;
}

/** \brief The DENSITY cover (SurfaceMergeRule::DENSITY): per 4-connected component
 * of raster cells (either class), rectangles grown greedily on the component's
 * bounding box. A cell of the box is free (no raster cell), of class 0 or 1, or
 * blocked (a raster cell of another component, or one already covered). From each
 * uncovered cell in row-major order, a rectangle grows one column or row at a time on
 * the side whose new strip has the largest share of cells of the seed's class (more
 * of them on a tie; right, up, left, down on a further tie), while the strip holds
 * such a cell and no blocked cell and at least \a density of the rectangle's cells
 * are of the seed's class. */
std::vector<CellRect>
densityCover(const std::vector<std::uint64_t>& keys,
             const std::vector<std::uint8_t>& cls,
             double density)
{
  const CellComponents components =
    cellComponents(keys, std::vector<std::uint8_t>(keys.size(), 0));
  std::vector<CellRect> rects;
  std::vector<std::uint64_t> sub;
  enum : std::uint8_t { FREE = 0, CLASS_0 = 1, CLASS_1 = 2, BLOCKED = 3 };
  std::vector<std::uint8_t> grid;
  for (std::size_t c = 0; c < components.size(); ++c) {
    sub.assign(components.members.begin()
                 + static_cast<std::ptrdiff_t>(components.start[c]),
               components.members.begin()
                 + static_cast<std::ptrdiff_t>(components.start[c + 1]));
    std::int64_t i_lo, j_lo, w, h;
    cellBounds(sub, i_lo, j_lo, w, h);
    if (!denseGridAffordable(w, h, sub.size())) {
      const std::vector<CellRect> part = minRectangleCover(sub, [&] {
        std::vector<std::uint8_t> sub_cls(sub.size());
        for (std::size_t k = 0; k < sub.size(); ++k)
          sub_cls[k] = cls[static_cast<std::size_t>(
            std::lower_bound(keys.begin(), keys.end(), sub[k]) - keys.begin())];
        return sub_cls;
      }());
      rects.insert(rects.end(), part.begin(), part.end());
      continue;
    }
    const auto W = static_cast<std::size_t>(w);
    grid.assign(W * static_cast<std::size_t>(h), FREE);
    // Every raster cell in the box is blocked, then the component's own take their
    // class.
    for (std::int64_t y = 0; y < h; ++y) {
      const auto j = static_cast<std::int32_t>(j_lo + y);
      auto it = std::lower_bound(keys.begin(), keys.end(),
                                 cellKey(static_cast<std::int32_t>(i_lo), j));
      for (; it != keys.end() && keyJ(*it) == j && keyI(*it) < i_lo + w; ++it)
        grid[static_cast<std::size_t>(y) * W
             + static_cast<std::size_t>(keyI(*it) - i_lo)] = BLOCKED;
    }
    for (const auto key : sub) {
      const auto k = static_cast<std::size_t>(
        std::lower_bound(keys.begin(), keys.end(), key) - keys.begin());
      grid[static_cast<std::size_t>(keyJ(key) - j_lo) * W
           + static_cast<std::size_t>(keyI(key) - i_lo)] =
        cls[k] != 0 ? CLASS_1 : CLASS_0;
    }
    const auto at = [&](std::int64_t x, std::int64_t y) -> std::uint8_t& {
      return grid[static_cast<std::size_t>(y) * W + static_cast<std::size_t>(x)];
    };
    // Cells of class \a of in the strip x in [x0, x1), y in [y0, y1); -1 if it holds
    // a blocked cell.
    const auto strip = [&](std::uint8_t of, std::int64_t x0, std::int64_t x1,
                           std::int64_t y0, std::int64_t y1) -> std::int64_t {
      std::int64_t members = 0;
      for (std::int64_t y = y0; y < y1; ++y)
        for (std::int64_t x = x0; x < x1; ++x) {
          const std::uint8_t g = at(x, y);
          if (g == BLOCKED)
            return -1;
          members += g == of ? 1 : 0;
        }
      return members;
    };
    for (std::int64_t sy = 0; sy < h; ++sy)
      for (std::int64_t sx = 0; sx < w; ++sx) {
        const std::uint8_t of = at(sx, sy);
        if (of != CLASS_0 && of != CLASS_1)
          continue;
        std::int64_t x0 = sx, x1 = sx + 1, y0 = sy, y1 = sy + 1, members = 1;
        for (;;) {
          // right, up, left, down
          const std::int64_t len_u = y1 - y0, len_v = x1 - x0;
          const std::int64_t got[4] = {x1 < w ? strip(of, x1, x1 + 1, y0, y1) : -1,
                                       y1 < h ? strip(of, x0, x1, y1, y1 + 1) : -1,
                                       x0 > 0 ? strip(of, x0 - 1, x0, y0, y1) : -1,
                                       y0 > 0 ? strip(of, x0, x1, y0 - 1, y0) : -1};
          const std::int64_t len[4] = {len_u, len_v, len_u, len_v};
          const double area = static_cast<double>((x1 - x0) * (y1 - y0));
          int best = -1;
          for (int side = 0; side < 4; ++side) {
            if (got[side] <= 0
                || static_cast<double>(members + got[side])
                     < density * (area + static_cast<double>(len[side])))
              continue;
            if (best < 0 || got[side] * len[best] > got[best] * len[side]
                || (got[side] * len[best] == got[best] * len[side]
                    && got[side] > got[best]))
              best = side;
          }
          if (best < 0)
            break;
          members += got[best];
          if (best == 0)
            ++x1;
          else if (best == 1)
            ++y1;
          else if (best == 2)
            --x0;
          else
            --y0;
        }
        for (std::int64_t y = y0; y < y1; ++y)
          for (std::int64_t x = x0; x < x1; ++x)
            at(x, y) = BLOCKED;
        rects.push_back(CellRect{
          static_cast<std::int32_t>(i_lo + x0), static_cast<std::int32_t>(i_lo + x1),
          static_cast<std::int32_t>(j_lo + y0), static_cast<std::int32_t>(j_lo + y1)});
      }
  }
  return rects;
}

/** \brief Rebuilds the cover of one plane: the gap closing, the occupancy per cell
 * (features' mean, else the propagated neighbours' mean, else 0.5), then the cover of
 * Params::merge_rule over cells of one occupancy class, with each rectangle's mean
 * probability and feature count, sorted by first row, then first column. */
void
rebuildPlane(MapPlane& plane, const SurfaceLayer::Params& params)
{
  std::vector<RasterRect>().swap(plane.rects);
  plane.dirty = false;
  if (plane.raster.empty())
    return;
  // the raster's cells, sorted, with their evidence
  std::vector<std::uint64_t> observed;
  std::vector<float> sums;
  std::vector<std::uint16_t> counts;
  plane.raster.forEachCell([&](std::uint64_t key, float sum, std::uint16_t features) {
    observed.push_back(key);
    sums.push_back(sum);
    counts.push_back(features);
  });
  const std::vector<std::uint64_t> filled =
    closeGaps(observed, params.close_gaps_cells);
  const std::size_t n = observed.size() + filled.size();
  std::vector<std::uint64_t> keys;
  keys.reserve(n);
  // Occupancy (paper, end of III-F): features' mean; featureless and filled cells take
  // the mean of their valued 8-neighbours, layer by layer outward; unreachable cells
  // 0.5.
  std::vector<float> value;
  std::vector<std::uint32_t> count;
  value.reserve(n);
  count.reserve(n);
  for (std::size_t a = 0, b = 0; a < observed.size() || b < filled.size();) {
    if (b == filled.size() || (a < observed.size() && observed[a] < filled[b])) {
      keys.push_back(observed[a]);
      const std::uint32_t features = counts[a];
      count.push_back(features);
      value.push_back(features > 0
                        ? static_cast<float>(static_cast<double>(sums[a]) / features)
                        : std::numeric_limits<float>::quiet_NaN());
      ++a;
    } else {
      keys.push_back(filled[b++]);
      count.push_back(0);
      value.push_back(std::numeric_limits<float>::quiet_NaN());
    }
  }
  std::size_t valued_cells = 0;
  for (std::size_t k = 0; k < n; ++k)
    valued_cells += count[k] > 0 ? 1 : 0;
  // neighbours only matter when valued and featureless cells coexist
  const bool propagate = valued_cells > 0 && valued_cells < n;
  // The 8 neighbours (row below, same row, row above; by column), -1 when absent,
  // by one sweep over the rows with a pointer into the row below and the row above.
  std::vector<std::array<std::ptrdiff_t, 8>> neighbours(propagate ? n : 0);
  for (std::size_t start = 0; propagate && start < n;) {
    const std::int64_t j = keyJ(keys[start]);
    std::size_t end = start;
    while (end < n && keyJ(keys[end]) == j)
      ++end;
    // rows j - 1 and j + 1: [lo, hi) ranges, empty when absent
    std::size_t below_lo = start, below_hi = start, above_lo = end, above_hi = end;
    if (start > 0 && keyJ(keys[start - 1]) == j - 1) {
      below_hi = start;
      below_lo = start - 1;
      while (below_lo > 0 && keyJ(keys[below_lo - 1]) == j - 1)
        --below_lo;
    }
    if (end < n && keyJ(keys[end]) == j + 1) {
      above_hi = end;
      while (above_hi < n && keyJ(keys[above_hi]) == j + 1)
        ++above_hi;
    }
    std::size_t pb = below_lo, pa = above_lo;
    for (std::size_t k = start; k < end; ++k) {
      const std::int64_t i = keyI(keys[k]);
      const auto find3 = [&](std::size_t& p, std::size_t hi, std::ptrdiff_t* out) {
        while (p < hi && keyI(keys[p]) < i - 1)
          ++p;
        for (std::int64_t di = -1; di <= 1; ++di) {
          std::ptrdiff_t found = -1;
          for (std::size_t q = p; q < hi && q <= p + 2; ++q)
            if (keyI(keys[q]) == i + di)
              found = static_cast<std::ptrdiff_t>(q);
          out[di + 1] = found;
        }
      };
      std::array<std::ptrdiff_t, 8>& nb = neighbours[k];
      find3(pb, below_hi, nb.data());
      nb[3] = (k > start && keyI(keys[k - 1]) == i - 1)
                ? static_cast<std::ptrdiff_t>(k - 1)
                : -1;
      nb[4] = (k + 1 < end && keyI(keys[k + 1]) == i + 1)
                ? static_cast<std::ptrdiff_t>(k + 1)
                : -1;
      find3(pa, above_hi, nb.data() + 5);
    }
    start = end;
  }
  std::vector<std::size_t> layer, next;
  for (std::size_t k = 0; propagate && k < n; ++k)
    if (std::isnan(value[k]))
      for (const auto nb : neighbours[k])
        if (nb >= 0 && !std::isnan(value[static_cast<std::size_t>(nb)])) {
          layer.push_back(k);
          break;
        }
  std::vector<float> layer_values;
  std::vector<std::uint8_t> queued(propagate ? n : 0, 0);
  for (const auto k : layer)
    queued[k] = 1;
  while (!layer.empty()) {
    layer_values.assign(layer.size(), 0.0f);
    for (std::size_t l = 0; l < layer.size(); ++l) {
      double sum = 0.0;
      int valued = 0;
      for (const auto nb : neighbours[layer[l]])
        if (nb >= 0 && !std::isnan(value[static_cast<std::size_t>(nb)])) {
          sum += value[static_cast<std::size_t>(nb)];
          ++valued;
        }
      layer_values[l] = static_cast<float>(sum / valued);
    }
    for (std::size_t l = 0; l < layer.size(); ++l)
      value[layer[l]] = layer_values[l];
    next.clear();
    for (const auto k : layer)
      for (const auto nb : neighbours[k])
        if (nb >= 0 && std::isnan(value[static_cast<std::size_t>(nb)])
            && queued[static_cast<std::size_t>(nb)] == 0) {
          queued[static_cast<std::size_t>(nb)] = 1;
          next.push_back(static_cast<std::size_t>(nb));
        }
    std::swap(layer, next);
  }
  for (auto& v : value)
    if (std::isnan(v))
      v = 0.5f;

  std::vector<std::uint8_t> cls(n);
  for (std::size_t k = 0; k < n; ++k)
    cls[k] = value[k] >= params.occupancy_thres ? 1 : 0;
  std::vector<CellRect> cover = params.merge_rule == SurfaceMergeRule::PAPER
                                  ? paperCover(keys, cls)
                                : params.merge_rule == SurfaceMergeRule::DENSITY
                                  ? densityCover(keys, cls, params.cover_density)
                                  : minRectangleCover(keys, cls);
  std::sort(cover.begin(), cover.end(), [](const CellRect& a, const CellRect& b) {
    return a.j0 != b.j0 ? a.j0 < b.j0 : a.i0 < b.i0;
  });
  plane.rects.reserve(cover.size());
  for (const CellRect& rect : cover) {
    double sum = 0.0;
    std::uint64_t features = 0, cells = 0;
    for (std::int64_t j = rect.j0; j < rect.j1; ++j) {
      auto k = static_cast<std::size_t>(
        std::lower_bound(keys.begin(), keys.end(),
                         cellKey(rect.i0, static_cast<std::int32_t>(j)))
        - keys.begin());
      // the DENSITY cover may hold unobserved cells: only the raster's count
      for (; k < n && keyJ(keys[k]) == j && keyI(keys[k]) < rect.i1; ++k) {
        sum += value[k];
        features += count[k];
        ++cells;
      }
    }
    plane.rects.push_back(
      RasterRect{rect.i0, rect.i1, rect.j0, rect.j1,
                 static_cast<float>(cells > 0 ? sum / static_cast<double>(cells) : 0.5),
                 static_cast<std::uint32_t>(std::min<std::uint64_t>(
                   features, std::numeric_limits<std::uint32_t>::max()))});
  }
}

/** \brief The cuboid of rectangle \a rect of \a plane: the raster frame projected
 * onto the refined plane along its normal (the centre projected, the horizontal axis
 * u projected and normalised, the extents scaled by the projections of u and v,
 * factors within cos(plane_merge_angle_rad) of 1, so that rectangles adjacent in the
 * raster stay adjacent up to a shear of the order of the angle squared), extruded by
 * \a thickness behind the face. */
PlanarCuboid
rectCuboid(const MapPlane& plane,
           const RasterFrame& frame,
           const FacePlacement& placement,
           const RasterRect& rect,
           int plane_id,
           double r,
           float thickness)
{
  // In double: corrupt (but accepted) raster keys near the int range must not
  // overflow.
  const double u_mid = 0.5 * (static_cast<double>(rect.i0) + rect.i1) * r;
  const double v_mid = 0.5 * (static_cast<double>(rect.j0) + rect.j1) * r;
  const Eigen::Vector3f on_frame = frame.origin
                                   + frame.u_axis * static_cast<float>(u_mid)
                                   + frame.v_axis * static_cast<float>(v_mid);
  const Eigen::Vector3f on_plane =
    on_frame - plane.normal * (plane.normal.dot(on_frame) + plane.d);
  PlanarCuboid c;
  c.normal = plane.normal;
  c.horizontal_axis = placement.place_u;
  c.width_m = static_cast<float>((static_cast<double>(rect.i1) - rect.i0) * r
                                 * placement.scale_u);
  c.height_m = static_cast<float>((static_cast<double>(rect.j1) - rect.j0) * r
                                  * placement.scale_v);
  c.thickness_m = thickness;
  c.centre = on_plane - plane.normal * (0.5f * thickness);
  c.plane_id = plane_id;
  c.point_count = rect.point_count;
  c.is_planar = true;
  c.probability = rect.probability;
  return c;
}

/** \brief Raster index of a coordinate in cells, or false when beyond
 * MAX_CELL_INDEX. */
bool
cellIndex(double coordinate, std::int64_t& index)
{
  const double f = std::floor(coordinate);
  if (!(std::abs(f) <= MAX_CELL_INDEX))
    return false;
  index = static_cast<std::int64_t>(f);
  return true;
}

/** \brief Adds the cells of \a src to \a dst (another frame of about the same plane):
 * every dst cell whose centre, projected onto src's frame, falls in an observed src
 * cell is observed, and the features of a src cell go to the dst cell containing its
 * centre (observed too, so no evidence is lost). */
void
reprojectRaster(const MapPlane& src, MapPlane& dst, double r)
{
  const double inv_r = 1.0 / r;
  const RasterFrame src_frame = src.frame(), dst_frame = dst.frame();
  std::vector<std::uint64_t> keys;
  std::vector<CellEvidence> evidence;
  src.raster.forEachCell([&](std::uint64_t src_key, float sum, std::uint16_t count) {
    const std::int64_t i = keyI(src_key), j = keyJ(src_key);
    const Eigen::Vector2d f = dst_frame.toRaster(src_frame.cellCentre(i, j, r), inv_r);
    std::int64_t ci = 0, cj = 0;
    if (!cellIndex(f.x(), ci) || !cellIndex(f.y(), cj))
      return;
    const std::uint64_t key =
      cellKey(static_cast<std::int32_t>(ci), static_cast<std::int32_t>(cj));
    keys.push_back(key);
    if (count > 0)
      evidence.push_back(CellEvidence{key, sum, count});
    for (std::int64_t dj = -1; dj <= 1; ++dj)
      for (std::int64_t di = -1; di <= 1; ++di) {
        const std::int64_t a = ci + di, b = cj + dj;
        if ((di == 0 && dj == 0) || std::abs(a) > MAX_CELL_INDEX
            || std::abs(b) > MAX_CELL_INDEX)
          continue;
        const Eigen::Vector2d s =
          src_frame.toRaster(dst_frame.cellCentre(a, b, r), inv_r);
        if (std::floor(s.x()) == static_cast<double>(i)
            && std::floor(s.y()) == static_cast<double>(j))
          keys.push_back(
            cellKey(static_cast<std::int32_t>(a), static_cast<std::int32_t>(b)));
      }
  });
  dst.raster.insert(keys);
  dst.raster.addEvidence(evidence);
  dst.dirty = true;
}

/** \brief True when the rasters of \a a and \a b overlap or are adjacent: a cell
 * centre of the smaller, projected onto the other's frame, falls in or next to (8
 * neighbours) an observed cell of it. */
bool
rastersTouch(const MapPlane& a, const MapPlane& b, double r)
{
  if (a.raster.empty() || b.raster.empty())
    return false;
  const MapPlane& small = a.raster.size() <= b.raster.size() ? a : b;
  const MapPlane& big = &small == &a ? b : a;
  const RasterFrame small_frame = small.frame(), big_frame = big.frame();
  const double inv_r = 1.0 / r;
  // The bounding boxes first.
  std::int32_t si_min = 0, si_max = 0, sj_min = 0, sj_max = 0;
  std::int32_t bi_min = 0, bi_max = 0, bj_min = 0, bj_max = 0;
  small.raster.bounds(si_min, si_max, sj_min, sj_max);
  big.raster.bounds(bi_min, bi_max, bj_min, bj_max);
  Eigen::Vector2d lo = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
  Eigen::Vector2d hi = -lo;
  for (const std::int64_t i :
       {static_cast<std::int64_t>(si_min) - 1, static_cast<std::int64_t>(si_max) + 1})
    for (const std::int64_t j : {static_cast<std::int64_t>(sj_min) - 1,
                                 static_cast<std::int64_t>(sj_max) + 1}) {
      const Eigen::Vector2d f =
        big_frame.toRaster(small_frame.cellCentre(i, j, r), inv_r);
      lo = lo.cwiseMin(f);
      hi = hi.cwiseMax(f);
    }
  if (!(hi.x() >= bi_min - 2.0 && lo.x() <= bi_max + 3.0 && hi.y() >= bj_min - 2.0
        && lo.y() <= bj_max + 3.0))
    return false;
  for (const auto key : small.raster.keys()) {
    const Eigen::Vector2d f =
      big_frame.toRaster(small_frame.cellCentre(keyI(key), keyJ(key), r), inv_r);
    std::int64_t ci = 0, cj = 0;
    if (!cellIndex(f.x(), ci) || !cellIndex(f.y(), cj))
      continue;
    for (std::int64_t dj = -1; dj <= 1; ++dj)
      for (std::int64_t di = -1; di <= 1; ++di) {
        const std::int64_t x = ci + di, y = cj + dj;
        if (std::abs(x) <= MAX_CELL_INDEX && std::abs(y) <= MAX_CELL_INDEX
            && big.raster.contains(
              cellKey(static_cast<std::int32_t>(x), static_cast<std::int32_t>(y))))
          return true;
      }
  }
  return false;
}

/** \brief Moves the raster of \a plane into a frame of its refined plane (when the
 * refined normal has drifted from the frame's). */
void
reanchor(MapPlane& plane, double r)
{
  MapPlane fresh;
  fresh.setFrame(plane.normal, plane.d);
  fresh.setRefined(plane.normal, plane.d);
  fresh.moments = plane.moments;
  reprojectRaster(plane, fresh, r);
  plane = std::move(fresh);
}

} // namespace

/** \brief Rebuilds the covers of the planes changed since; caller holds the mutex. */
void
SurfaceLayer::Impl::ensureCovers(const Params& params)
{
  for (auto& plane : planes)
    if (plane.dirty)
      rebuildPlane(plane, params);
}

/** \brief Appends every plane's rectangles, then the non-planar cells; caller holds
 * the mutex. */
void
SurfaceLayer::Impl::buildCuboids(const Params& params, PlanarCuboids& out)
{
  ensureCovers(params);
  std::size_t total = non_planar.size();
  for (const auto& plane : planes)
    total += plane.rects.size();
  out.reserve(out.size() + total);
  const auto thickness = static_cast<float>(params.thickness_m);
  for (std::size_t p = 0; p < planes.size(); ++p) {
    const MapPlane& plane = planes[p];
    if (plane.rects.empty())
      continue;
    const RasterFrame frame = plane.frame();
    const FacePlacement placement(frame, plane.normal);
    for (const RasterRect& rect : plane.rects)
      out.push_back(rectCuboid(plane, frame, placement, rect, static_cast<int>(p),
                               params.resolution_m, thickness));
  }
  for (const auto& cell : non_planar) {
    PlanarCuboid c = nonPlanarCuboid(cell);
    c.probability = cell.feature_count > 0
                      ? static_cast<float>(cell.probability_sum / cell.feature_count)
                      : 0.5f;
    c.point_count = cell.feature_count;
    out.push_back(c);
  }
}

/** \brief Builds the spatial hash over all cuboids; caller holds the mutex. */
void
SurfaceLayer::Impl::ensureIndex(const Params& params)
{
  Impl& impl = *this;
  if (impl.index_valid)
    return;
  impl.index_cuboids.clear();
  buildCuboids(params, impl.index_cuboids);
  impl.bins.clear();
  impl.large.clear();
  impl.bounds_min = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  impl.bounds_max = -impl.bounds_min;
  for (const auto& cuboid : impl.index_cuboids) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(cuboid, lo, hi);
    impl.bounds_min = impl.bounds_min.cwiseMin((lo.array() - 1e-4f).matrix());
    impl.bounds_max = impl.bounds_max.cwiseMax((hi.array() + 1e-4f).matrix());
  }
  // Bins of 4 cells; never more than 1e5 bins across the map's extent (a ray walks at
  // most ~3e5 bins), whatever the data.
  const float span =
    impl.index_cuboids.empty() ? 0.0f : (impl.bounds_max - impl.bounds_min).maxCoeff();
  impl.bin_m = std::max(static_cast<float>(4.0 * params.resolution_m), span * 1e-5f);
  const float inv = 1.0f / impl.bin_m;
  for (std::size_t c = 0; c < impl.index_cuboids.size(); ++c) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(impl.index_cuboids[c], lo, hi);
    lo.array() -= 1e-4f;
    hi.array() += 1e-4f;
    const Eigen::Vector3d a = (lo * inv).cast<double>().array().floor();
    const Eigen::Vector3d b = (hi * inv).cast<double>().array().floor();
    const Eigen::Vector3d span = b - a + Eigen::Vector3d::Ones();
    if (!(span.prod() <= MAX_BINS_PER_CUBOID)) {
      impl.large.push_back(static_cast<std::uint32_t>(c));
      continue;
    }
    for (auto x = static_cast<std::int64_t>(a.x());
         x <= static_cast<std::int64_t>(b.x()); ++x)
      for (auto y = static_cast<std::int64_t>(a.y());
           y <= static_cast<std::int64_t>(b.y()); ++y)
        for (auto z = static_cast<std::int64_t>(a.z());
             z <= static_cast<std::int64_t>(b.z()); ++z)
          impl.bins[binKey(x, y, z)].push_back(static_cast<std::uint32_t>(c));
  }
  impl.index_valid = true;
}

SurfaceLayer::SurfaceLayer(const Params& params) :
    impl_(std::make_unique<Impl>()), params_(params)
{
  validate(params_);
}

SurfaceLayer::~SurfaceLayer() = default;
SurfaceLayer::SurfaceLayer(SurfaceLayer&&) noexcept = default;
SurfaceLayer& SurfaceLayer::operator=(SurfaceLayer&&) noexcept = default;

void
SurfaceLayer::clear()
{
  impl_ = std::make_unique<Impl>();
}

void
SurfaceLayer::integrate(const PlanarCuboids& cuboids,
                        const PlaneModels& planes,
                        const pcl::PointCloud<pcl::PointXYZ>& features,
                        const std::vector<float>& probabilities)
{
  Impl& impl = *impl_;
  const double r = params_.resolution_m;
  const double inv_r = 1.0 / r;
  const float tol = static_cast<float>(0.01 * r);
  const double cos_angle = std::cos(params_.plane_merge_angle_rad);
  // a face of zero area still counts, as a point
  const double min_face_weight = 1e-6 * r * r;
  const auto valid_geometry = [](const PlanarCuboid& c) {
    return finiteVector(c.centre) && c.normal.allFinite()
           && c.horizontal_axis.allFinite() && std::isfinite(c.width_m)
           && std::isfinite(c.height_m) && std::isfinite(c.thickness_m)
           && c.width_m >= 0.0f && c.height_m >= 0.0f && c.thickness_m >= 0.0f;
  };
  // the faces whose cells are marked below (larger ones are skipped there)
  const auto usable_face = [&valid_geometry, r](const PlanarCuboid& c) {
    return valid_geometry(c)
           && static_cast<double>(c.width_m) * c.height_m <= MAX_FACE_CELLS * r * r;
  };

  // 1. Frame planes, oriented like the frame's cuboids (toward its sensor).
  std::vector<int> map_of_frame(planes.size(), -1);
  std::vector<bool> orientation_known(planes.size(), false);
  std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>> oriented(
    planes.size());
  for (std::size_t p = 0; p < planes.size(); ++p) {
    const Eigen::Vector4f& c = planes[p];
    const float norm = c.head<3>().norm();
    if (!c.allFinite() || !(norm > 1e-6f) || std::abs(c[3] / norm) > MAX_COORDINATE_M)
      continue;
    oriented[p] = c / norm;
  }
  bool bad_plane_id = false;
  for (const PlanarCuboid& c : cuboids) {
    if (c.plane_id < 0 || !c.is_planar)
      continue;
    const auto p = static_cast<std::size_t>(c.plane_id);
    if (p >= planes.size() || !oriented[p].allFinite()
        || oriented[p].head<3>().squaredNorm() == 0.0f) {
      bad_plane_id = true;
      continue;
    }
    if (!orientation_known[p]) {
      if (oriented[p].head<3>().dot(c.normal) < 0.0f)
        oriented[p] = -oriented[p];
      orientation_known[p] = true;
    }
  }
  if (bad_plane_id)
    PCL_WARN("[planar_grid::SurfaceLayer::integrate] Cuboids with a plane_id outside "
             "the %zu valid planes are treated as non-planar.\n",
             planes.size());

  // 2. The area moments of each frame plane's faces.
  std::vector<PlaneMoments> frame_moments(planes.size());
  for (const PlanarCuboid& c : cuboids)
    if (c.is_planar && c.plane_id >= 0
        && static_cast<std::size_t>(c.plane_id) < planes.size()
        && orientation_known[static_cast<std::size_t>(c.plane_id)] && usable_face(c))
      frame_moments[static_cast<std::size_t>(c.plane_id)].addFace(c, min_face_weight);

  // 3. Frame plane -> map plane: the map plane that explains the frame's faces best
  //    together with its own evidence (header), else a new one. The frame's moments
  //    join the map plane at once, so that a second frame plane of the same surface
  //    is tested against them.
  std::vector<int> touched;
  for (std::size_t p = 0; p < planes.size(); ++p) {
    if (!orientation_known[p] || !(frame_moments[p].weight > 0.0))
      continue;
    const Eigen::Vector3f n = oriented[p].head<3>();
    const float d = oriented[p][3];
    int best = -1;
    double best_rms = std::numeric_limits<double>::infinity();
    for (std::size_t m = 0; m < impl.planes.size(); ++m) {
      const MapPlane& mp = impl.planes[m];
      double rms = 0.0;
      if (explainedByOnePlane(mp.moments, mp.normal, frame_moments[p], n, params_,
                              cos_angle, rms)
          && rms < best_rms) {
        best = static_cast<int>(m);
        best_rms = rms;
      }
    }
    if (best < 0) {
      MapPlane mp;
      mp.setFrame(n, d);
      mp.setRefined(n, d);
      impl.planes.push_back(std::move(mp));
      best = static_cast<int>(impl.planes.size()) - 1;
    }
    map_of_frame[p] = best;
    impl.planes[static_cast<std::size_t>(best)].moments.add(frame_moments[p]);
    if (std::find(touched.begin(), touched.end(), best) == touched.end())
      touched.push_back(best);
  }
  std::sort(touched.begin(), touched.end());

  // 4. Planar cuboids mark the map plane's cells whose centres fall inside the face.
  // Non-planar cuboids replace the cell with the same key.
  std::vector<std::vector<std::uint64_t>> marked(impl.planes.size());
  std::vector<std::uint32_t> frame_non_planar;
  std::vector<PlanarCuboid> incoming;
  std::unordered_map<NonPlanarKey, std::size_t, NonPlanarKeyHash> frame_keys;
  const auto np_bin = static_cast<float>(4.0 * r);
  bool skipped = false;
  for (const PlanarCuboid& c : cuboids) {
    if (!valid_geometry(c)) {
      skipped = true;
      continue;
    }
    const bool planar = c.is_planar && c.plane_id >= 0
                        && static_cast<std::size_t>(c.plane_id) < planes.size()
                        && orientation_known[static_cast<std::size_t>(c.plane_id)];
    if (planar && map_of_frame[static_cast<std::size_t>(c.plane_id)] < 0) {
      skipped = true; // its plane had only absurd faces (> 1e7 cells)
      continue;
    }
    if (!planar) {
      PlanarCuboid cell = c;
      cell.plane_id = -1;
      cell.is_planar = false;
      const auto inserted = frame_keys.emplace(nonPlanarKey(c, r), incoming.size());
      if (inserted.second)
        incoming.push_back(cell);
      else
        incoming[inserted.first->second] = cell; // same key twice in one frame
      continue;
    }
    const auto m =
      static_cast<std::size_t>(map_of_frame[static_cast<std::size_t>(c.plane_id)]);
    const RasterFrame mp = impl.planes[m].frame();
    const auto face = c.face();
    float u_lo = std::numeric_limits<float>::max(), u_hi = -u_lo;
    float v_lo = u_lo, v_hi = -u_lo;
    for (const auto& corner : face) {
      const Eigen::Vector3f q = corner - mp.origin;
      u_lo = std::min(u_lo, q.dot(mp.u_axis));
      u_hi = std::max(u_hi, q.dot(mp.u_axis));
      v_lo = std::min(v_lo, q.dot(mp.v_axis));
      v_hi = std::max(v_hi, q.dot(mp.v_axis));
    }
    // cells whose centre (i + 0.5) r lies in [lo - tol, hi + tol]
    const double i0 = std::ceil((u_lo - tol) * inv_r - 0.5);
    const double i1 = std::floor((u_hi + tol) * inv_r - 0.5);
    const double j0 = std::ceil((v_lo - tol) * inv_r - 0.5);
    const double j1 = std::floor((v_hi + tol) * inv_r - 0.5);
    if (i1 < i0 || j1 < j0)
      continue;
    if ((i1 - i0 + 1) * (j1 - j0 + 1) > MAX_FACE_CELLS || std::abs(i0) > MAX_CELL_INDEX
        || std::abs(i1) > MAX_CELL_INDEX || std::abs(j0) > MAX_CELL_INDEX
        || std::abs(j1) > MAX_CELL_INDEX) {
      skipped = true;
      continue;
    }
    const Eigen::Vector3f fc = c.faceCentre();
    const Eigen::Vector3f h = c.horizontal_axis;
    const Eigen::Vector3f vert = c.verticalAxis();
    const float hw = 0.5f * c.width_m + tol, hh = 0.5f * c.height_m + tol;
    for (auto j = static_cast<std::int32_t>(j0); j <= static_cast<std::int32_t>(j1);
         ++j) {
      const Eigen::Vector3f row =
        mp.origin + mp.v_axis * static_cast<float>((j + 0.5) * r) - fc;
      for (auto i = static_cast<std::int32_t>(i0); i <= static_cast<std::int32_t>(i1);
           ++i) {
        const Eigen::Vector3f q = row + mp.u_axis * static_cast<float>((i + 0.5) * r);
        if (std::abs(q.dot(h)) <= hw && std::abs(q.dot(vert)) <= hh)
          marked[m].push_back(cellKey(i, j));
      }
    }
  }
  if (skipped)
    PCL_WARN("[planar_grid::SurfaceLayer::integrate] Skipped cuboids with non-finite "
             "or absurd (> 1e7 m or > 1e7 cells) geometry.\n");
  // The marked cells join the rasters, and the touched planes are refitted to their
  // evidence.
  for (const int t : touched) {
    MapPlane& mp = impl.planes[static_cast<std::size_t>(t)];
    std::vector<std::uint64_t>& keys = marked[static_cast<std::size_t>(t)];
    mp.raster.insert(keys);
    std::vector<std::uint64_t>().swap(keys);
    refitPlane(mp, cos_angle);
    mp.dirty = true;
  }

  // 4b. Non-planar replacement (header): every stored cell of an earlier frame whose
  // centre lies in a new cuboid grown by half a cell, or that contains the new
  // cuboid's centre, is removed; then the new cells are appended.
  {
    const float half_cell = static_cast<float>(0.5 * r);
    std::vector<std::uint32_t> doomed;
    // a spatial index of the stored cells' bounding boxes (bins of 4 cells; cells
    // spanning more than MAX_BINS_PER_CUBOID bins in a list tested always)
    std::vector<BinEntry> np_bins;
    std::vector<std::uint32_t> np_large;
    if (!incoming.empty()) {
      for (std::size_t k = 0; k < impl.non_planar.size(); ++k) {
        const auto index = static_cast<std::uint32_t>(k);
        if (!impl.forNonPlanarBins(
              impl.nonPlanarCuboid(impl.non_planar[k]), 0.0f, np_bin,
              [&](std::uint64_t key) { np_bins.emplace_back(key, index); }))
          np_large.push_back(index);
      }
      std::sort(np_bins.begin(), np_bins.end());
    }
    // (every stored cell is of an earlier frame)
    const auto test = [&](const PlanarCuboid& nw, std::uint32_t index) {
      const NonPlanarCell& old = impl.non_planar[index];
      if (nw.contains(old.centre, half_cell)
          || impl.nonPlanarCuboid(old).contains(nw.centre))
        doomed.push_back(index);
    };
    for (const PlanarCuboid& nw : incoming) {
      const bool binned =
        impl.forNonPlanarBins(nw, half_cell, np_bin, [&](std::uint64_t key) {
          const auto range =
            std::equal_range(np_bins.begin(), np_bins.end(), BinEntry(key, 0));
          for (auto it = range.first; it != range.second; ++it)
            test(nw, it->index);
        });
      if (binned)
        for (const auto index : np_large)
          test(nw, index);
      else
        for (std::size_t index = 0; index < impl.non_planar.size(); ++index)
          test(nw, static_cast<std::uint32_t>(index));
    }
    std::vector<BinEntry>().swap(np_bins);
    std::sort(doomed.begin(), doomed.end());
    doomed.erase(std::unique(doomed.begin(), doomed.end()), doomed.end());
    // highest first: the cell moved into a freed slot is never one still to remove
    for (auto it = doomed.rbegin(); it != doomed.rend(); ++it) {
      if (*it + 1 != impl.non_planar.size())
        impl.non_planar[*it] = impl.non_planar.back();
      impl.non_planar.pop_back();
    }
    std::map<AxesKey, std::uint32_t> axes_lookup;
    for (std::size_t a = 0; a < impl.np_axes.size(); ++a)
      axes_lookup.emplace(
        axesKey(impl.np_axes[a].normal, impl.np_axes[a].horizontal_axis),
        static_cast<std::uint32_t>(a));
    impl.non_planar.reserve(impl.non_planar.size() + incoming.size());
    for (const PlanarCuboid& c : incoming) {
      frame_non_planar.push_back(static_cast<std::uint32_t>(impl.non_planar.size()));
      impl.non_planar.emplace_back(c, impl.internAxes(c, axes_lookup));
    }
    if (!doomed.empty())
      impl.pruneAxes();
    impl.non_planar.shrink_to_fit();
  }

  // 5. Features: each adds its probability to the observed cell it falls in on every
  // touched plane within feature_distance_m, and to this frame's non-planar cells
  // containing it.
  if (!features.empty() && probabilities.size() != features.size()) {
    PCL_WARN("[planar_grid::SurfaceLayer::integrate] %zu probabilities for %zu "
             "features; features ignored.\n",
             probabilities.size(), features.size());
  } else if (!features.empty()) {
    // bins over this frame's non-planar cuboids (each cell once)
    std::sort(frame_non_planar.begin(), frame_non_planar.end());
    frame_non_planar.erase(
      std::unique(frame_non_planar.begin(), frame_non_planar.end()),
      frame_non_planar.end());
    const float bin = static_cast<float>(4.0 * r);
    std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> bins;
    std::vector<std::uint32_t> large;
    for (const auto index : frame_non_planar) {
      Eigen::Vector3f lo, hi;
      cuboidBounds(impl.nonPlanarCuboid(impl.non_planar[index]), lo, hi);
      const Eigen::Vector3d a = (lo / bin).cast<double>().array().floor();
      const Eigen::Vector3d b = (hi / bin).cast<double>().array().floor();
      if (!((b - a + Eigen::Vector3d::Ones()).prod() <= MAX_BINS_PER_CUBOID)) {
        large.push_back(index);
        continue;
      }
      for (auto x = static_cast<std::int64_t>(a.x());
           x <= static_cast<std::int64_t>(b.x()); ++x)
        for (auto y = static_cast<std::int64_t>(a.y());
             y <= static_cast<std::int64_t>(b.y()); ++y)
          for (auto z = static_cast<std::int64_t>(a.z());
               z <= static_cast<std::int64_t>(b.z()); ++z)
            bins[binKey(x, y, z)].push_back(index);
    }
    const float feature_distance = static_cast<float>(params_.feature_distance_m);
    // the features of each touched plane's cells, added once per plane below
    std::vector<RasterFrame> frames;
    std::vector<std::vector<CellEvidence>> evidence(touched.size());
    for (const int m : touched)
      frames.push_back(impl.planes[static_cast<std::size_t>(m)].frame());
    for (std::size_t f = 0; f < features.size(); ++f) {
      const Eigen::Vector3f p = features[f].getVector3fMap();
      const float prob = probabilities[f];
      if (!finiteVector(p) || !(prob >= 0.0f && prob <= 1.0f))
        continue;
      for (std::size_t t = 0; t < touched.size(); ++t) {
        const MapPlane& mp = impl.planes[static_cast<std::size_t>(touched[t])];
        if (std::abs(mp.normal.dot(p) + mp.d) > feature_distance)
          continue;
        const Eigen::Vector2d cell = frames[t].toRaster(p, inv_r);
        std::int64_t i = 0, j = 0;
        if (!cellIndex(cell.x(), i) || !cellIndex(cell.y(), j))
          continue;
        // (cells not observed are ignored by addEvidence())
        evidence[t].push_back(CellEvidence{
          cellKey(static_cast<std::int32_t>(i), static_cast<std::int32_t>(j)), prob,
          1});
      }
      const auto add = [&](std::uint32_t index) {
        NonPlanarCell& cell = impl.non_planar[index];
        if (impl.nonPlanarCuboid(cell).contains(p)) {
          cell.probability_sum += prob;
          ++cell.feature_count;
        }
      };
      const auto it =
        bins.find(binKey(static_cast<std::int64_t>(std::floor(p.x() / bin)),
                         static_cast<std::int64_t>(std::floor(p.y() / bin)),
                         static_cast<std::int64_t>(std::floor(p.z() / bin))));
      if (it != bins.end())
        for (const auto index : it->second)
          add(index);
      for (const auto index : large)
        add(index);
    }
    for (std::size_t t = 0; t < touched.size(); ++t)
      if (!evidence[t].empty())
        impl.planes[static_cast<std::size_t>(touched[t])].raster.addEvidence(
          evidence[t]);
  }

  // 6. Map planes that converged merge (header): a touched plane and any other that
  // one plane explains and whose rasters overlap or touch. The plane with more
  // evidence survives (lower index on a tie). Each merge removes a plane, so this
  // ends.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t ti = 0; ti < touched.size() && !merged; ++ti) {
      const auto t = static_cast<std::size_t>(touched[ti]);
      for (std::size_t m = 0; m < impl.planes.size() && !merged; ++m) {
        const MapPlane& a = impl.planes[t];
        const MapPlane& b = impl.planes[m];
        double rms = 0.0;
        if (m == t
            || !explainedByOnePlane(a.moments, a.normal, b.moments, b.normal, params_,
                                    cos_angle, rms)
            || !rastersTouch(a, b, r))
          continue;
        std::size_t keep = t, gone = m;
        if (b.moments.weight > a.moments.weight
            || (b.moments.weight == a.moments.weight && m < t))
          std::swap(keep, gone);
        MapPlane& survivor = impl.planes[keep];
        reprojectRaster(impl.planes[gone], survivor, r);
        survivor.moments.add(impl.planes[gone].moments);
        refitPlane(survivor, cos_angle);
        impl.planes.erase(impl.planes.begin() + static_cast<std::ptrdiff_t>(gone));
        const auto shift = [gone](std::size_t x) {
          return static_cast<int>(x > gone ? x - 1 : x);
        };
        std::vector<int> next;
        for (const int x : touched)
          if (static_cast<std::size_t>(x) != gone)
            next.push_back(shift(static_cast<std::size_t>(x)));
        if (std::find(next.begin(), next.end(), shift(keep)) == next.end())
          next.push_back(shift(keep));
        std::sort(next.begin(), next.end());
        touched.swap(next);
        merged = true;
      }
    }
  }

  // 7. A refined normal that drifted from its raster frame's takes a new frame.
  const double cos_reanchor = std::cos(0.5 * params_.plane_merge_angle_rad);
  for (const int t : touched) {
    MapPlane& mp = impl.planes[static_cast<std::size_t>(t)];
    if (mp.normal.dot(mp.frame_normal) < cos_reanchor)
      reanchor(mp, r);
  }
  // no spare capacity: the map holds what it uses
  impl.planes.shrink_to_fit();
  impl.plane_models.resize(impl.planes.size());
  impl.plane_models.shrink_to_fit();
  for (std::size_t p = 0; p < impl.planes.size(); ++p)
    impl.plane_models[p] =
      Eigen::Vector4f(impl.planes[p].normal.x(), impl.planes[p].normal.y(),
                      impl.planes[p].normal.z(), impl.planes[p].d);
  impl.invalidate();
}

PlanarCuboids
SurfaceLayer::getCuboids() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PlanarCuboids cuboids;
  impl_->buildCuboids(params_, cuboids);
  return cuboids;
}

std::size_t
SurfaceLayer::getCuboidCount() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->ensureCovers(params_);
  std::size_t n = impl_->non_planar.size();
  for (const auto& plane : impl_->planes)
    n += plane.rects.size();
  return n;
}

const PlaneModels&
SurfaceLayer::getPlanes() const
{
  return impl_->plane_models;
}

std::size_t
SurfaceLayer::getCellCount() const
{
  std::size_t n = impl_->non_planar.size();
  for (const auto& plane : impl_->planes)
    n += plane.raster.size();
  return n;
}

std::size_t
SurfaceLayer::getMemoryBytes() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const Impl& impl = *impl_;
  std::size_t bytes = sizeof(SurfaceLayer) + sizeof(Impl);
  bytes += vectorBytes(impl.planes) + vectorBytes(impl.plane_models);
  for (const auto& plane : impl.planes)
    bytes += plane.raster.bytes() + vectorBytes(plane.rects);
  bytes += vectorBytes(impl.non_planar) + vectorBytes(impl.np_axes);
  bytes +=
    vectorBytes(impl.index_cuboids) + hashMapBytes(impl.bins) + vectorBytes(impl.large);
  for (const auto& kv : impl.bins)
    bytes += vectorBytes(kv.second);
  return bytes;
}

const PlanarCuboid*
SurfaceLayer::findCuboid(const Eigen::Vector3f& point) const
{
  if (!point.allFinite())
    return nullptr;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& impl = *impl_;
  impl.ensureIndex(params_);
  const float inv = 1.0f / impl.bin_m;
  const std::uint32_t* best = nullptr;
  const auto consider = [&](const std::uint32_t& c) {
    if ((best == nullptr || c < *best) && impl.index_cuboids[c].contains(point))
      best = &c;
  };
  if ((point.array() >= impl.bounds_min.array()).all()
      && (point.array() <= impl.bounds_max.array()).all()) {
    const auto it =
      impl.bins.find(binKey(static_cast<std::int64_t>(std::floor(point.x() * inv)),
                            static_cast<std::int64_t>(std::floor(point.y() * inv)),
                            static_cast<std::int64_t>(std::floor(point.z() * inv))));
    if (it != impl.bins.end())
      for (const auto& c : it->second)
        consider(c);
  }
  for (const auto& c : impl.large)
    consider(c);
  return best == nullptr ? nullptr : &impl.index_cuboids[*best];
}

bool
SurfaceLayer::castRay(const Eigen::Vector3f& origin,
                      const Eigen::Vector3f& direction,
                      double max_range_m,
                      float& distance_m,
                      std::size_t& index) const
{
  const float len = direction.norm();
  if (!origin.allFinite() || !direction.allFinite() || !(len > 0.0f)
      || !(max_range_m >= 0.0))
    return false;
  const Eigen::Vector3f dir = direction / len;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& impl = *impl_;
  impl.ensureIndex(params_);
  if (impl.index_cuboids.empty())
    return false;
  const float max_t = static_cast<float>(std::min(max_range_m, 1e9));
  const float thres = static_cast<float>(params_.occupancy_thres);
  float best_t = std::numeric_limits<float>::infinity();
  std::size_t best_index = 0;
  const auto test = [&](std::uint32_t c) {
    const PlanarCuboid& box = impl.index_cuboids[c];
    if (!(box.probability >= thres))
      return;
    const float t = rayBoxEntry(box, origin, dir, max_t);
    if (t >= 0.0f && (t < best_t || (t == best_t && c < best_index))) {
      best_t = t;
      best_index = c;
    }
  };
  for (const auto c : impl.large)
    test(c);
  // Clip the ray to the bounds of the index, then walk the bins (3D DDA).
  float t0 = 0.0f, t1 = max_t;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(dir[k]) < 1e-12f) {
      if (origin[k] < impl.bounds_min[k] || origin[k] > impl.bounds_max[k])
        t1 = -1.0f;
      continue;
    }
    float a = (impl.bounds_min[k] - origin[k]) / dir[k];
    float b = (impl.bounds_max[k] - origin[k]) / dir[k];
    if (a > b)
      std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 <= t1) {
    const float bin = impl.bin_m;
    const Eigen::Vector3f start = origin + dir * t0;
    std::int64_t cell[3], step[3];
    float t_next[3], t_delta[3];
    for (int k = 0; k < 3; ++k) {
      cell[k] = static_cast<std::int64_t>(std::floor(start[k] / bin));
      if (dir[k] > 0.0f) {
        step[k] = 1;
        t_delta[k] = bin / dir[k];
        t_next[k] = t0 + ((static_cast<float>(cell[k] + 1) * bin) - start[k]) / dir[k];
      } else if (dir[k] < 0.0f) {
        step[k] = -1;
        t_delta[k] = -bin / dir[k];
        t_next[k] = t0 + ((static_cast<float>(cell[k]) * bin) - start[k]) / dir[k];
      } else {
        step[k] = 0;
        t_delta[k] = std::numeric_limits<float>::infinity();
        t_next[k] = std::numeric_limits<float>::infinity();
      }
    }
    // at most the bins along the clipped segment (+ slack), never unbounded
    const double max_steps = 3.0 * (t1 - t0) / bin + 8.0;
    for (double s = 0; s < max_steps; ++s) {
      const auto it = impl.bins.find(binKey(cell[0], cell[1], cell[2]));
      if (it != impl.bins.end())
        for (const auto c : it->second)
          test(c);
      int k = 0;
      if (t_next[1] < t_next[k])
        k = 1;
      if (t_next[2] < t_next[k])
        k = 2;
      const float t_exit = t_next[k];
      // a hit entering before this bin's exit cannot be beaten by later bins
      if (best_t <= t_exit || t_exit > t1)
        break;
      cell[k] += step[k];
      t_next[k] += t_delta[k];
    }
  }
  if (!(best_t <= max_t))
    return false;
  distance_m = best_t;
  index = best_index;
  return true;
}

void
SurfaceLayer::serialize(std::vector<std::uint8_t>& bytes) const
{
  const Impl& impl = *impl_;
  ByteWriter w(bytes);
  w.put(MAGIC);
  w.put(VERSION);
  w.put(params_.resolution_m);
  w.put(params_.thickness_m);
  w.put(params_.plane_merge_angle_rad);
  w.put(params_.plane_merge_distance_m);
  w.put(params_.occupancy_thres);
  w.put(params_.feature_distance_m);
  w.put(static_cast<std::uint32_t>(params_.close_gaps_cells));
  w.put(static_cast<std::uint8_t>(params_.merge_rule));
  w.put(params_.cover_density);
  w.put(static_cast<std::uint64_t>(impl.planes.size()));
  for (const auto& plane : impl.planes) {
    for (int k = 0; k < 3; ++k)
      w.put(plane.frame_normal[k]);
    w.put(plane.frame_d);
    for (int k = 0; k < 3; ++k)
      w.put(plane.normal[k]);
    w.put(plane.d);
    const PlaneMoments& m = plane.moments;
    for (int k = 0; k < 3; ++k)
      w.put(m.anchor[k]);
    w.put(m.weight);
    for (int k = 0; k < 3; ++k)
      w.put(m.sum[k]);
    for (const double v : m.sum_sq_upper) // xx, xy, xz, yy, yz, zz
      w.put(v);
    const Raster& raster = plane.raster;
    w.put(static_cast<std::uint64_t>(raster.size()));
    raster.forEachCell([&w](std::uint64_t key, float sum, std::uint16_t count) {
      w.put(keyI(key));
      w.put(keyJ(key));
      w.put(sum);
      w.put(count);
    });
  }
  w.put(static_cast<std::uint64_t>(impl.non_planar.size()));
  for (const auto& c : impl.non_planar) {
    const BoxAxes& axes = impl.np_axes[c.axes];
    for (int k = 0; k < 3; ++k)
      w.put(c.centre[k]);
    for (int k = 0; k < 3; ++k)
      w.put(axes.normal[k]);
    for (int k = 0; k < 3; ++k)
      w.put(axes.horizontal_axis[k]);
    w.put(c.width_m);
    w.put(c.height_m);
    w.put(c.thickness_m);
    w.put(c.probability_sum);
    w.put(c.feature_count);
  }
}

namespace {
constexpr std::size_t PLANE_BYTES =
  8 * sizeof(float) + 13 * sizeof(double) + sizeof(std::uint64_t);
constexpr std::size_t CELL_BYTES =
  2 * sizeof(std::int32_t) + sizeof(float) + sizeof(std::uint16_t);
constexpr std::size_t NON_PLANAR_BYTES =
  12 * sizeof(float) + sizeof(double) + sizeof(std::uint32_t);

void
checkSum(double sum, std::uint32_t count, const char* what)
{
  // float sums of probabilities <= 1 may exceed the count by rounding only
  if (!std::isfinite(sum) || sum < -1e-9 || sum > count * (1.0 + 1e-5) + 1e-9)
    throw IOError(std::string("surface layer: ") + what
                  + " probability sum outside [0, feature count]");
}

bool
unitVector(const Eigen::Vector3f& v)
{
  return v.allFinite() && std::abs(v.norm() - 1.0f) < 1e-3f;
}
} // namespace

void
SurfaceLayer::deserialize(const std::uint8_t* data, std::size_t size)
{
  if (data == nullptr && size > 0)
    throw IOError("surface layer: null data");
  ByteReader rd(data, size, "surface layer");
  if (rd.get<std::uint32_t>() != MAGIC)
    throw IOError("surface layer: bad magic (not a surface layer section)");
  const auto version = rd.get<std::uint32_t>();
  if (version == 1)
    throw IOError("surface layer: version 1 section (written before the map planes "
                  "kept their evidence moments) is not supported by this reader "
                  "(versions 2 and 3); run the mapping again");
  if (version != 2 && version != VERSION)
    throw IOError("surface layer: unsupported version " + std::to_string(version));
  Params params;
  params.resolution_m = rd.get<double>();
  params.thickness_m = rd.get<double>();
  params.plane_merge_angle_rad = rd.get<double>();
  params.plane_merge_distance_m = rd.get<double>();
  params.occupancy_thres = rd.get<double>();
  params.feature_distance_m = rd.get<double>();
  const auto close_gaps = rd.get<std::uint32_t>();
  const auto rule = rd.get<std::uint8_t>();
  if (close_gaps > static_cast<std::uint32_t>(MAX_CLOSE_GAPS_CELLS))
    throw IOError("surface layer: close_gaps_cells " + std::to_string(close_gaps)
                  + " out of range");
  if (rule > static_cast<std::uint8_t>(version == 2 ? SurfaceMergeRule::MIN_RECTANGLES
                                                    : SurfaceMergeRule::DENSITY))
    throw IOError("surface layer: unknown merge_rule " + std::to_string(rule));
  params.close_gaps_cells = static_cast<int>(close_gaps);
  params.merge_rule = static_cast<SurfaceMergeRule>(rule);
  if (version >= 3) // version 2 had no DENSITY rule, so its value does not matter
    params.cover_density = rd.get<double>();
  try {
    validate(params);
  } catch (const Exception& e) {
    throw IOError(std::string("surface layer: ") + e.what());
  }
  const double cos_angle = std::cos(params.plane_merge_angle_rad);
  auto impl = std::make_unique<Impl>();
  const std::size_t plane_count = rd.getCount(PLANE_BYTES, "plane");
  impl->planes.reserve(plane_count);
  impl->plane_models.reserve(plane_count);
  for (std::size_t p = 0; p < plane_count; ++p) {
    const std::string which = "surface layer: plane " + std::to_string(p);
    Eigen::Vector3f frame_normal, normal;
    for (int k = 0; k < 3; ++k)
      frame_normal[k] = rd.get<float>();
    const auto frame_d = rd.get<float>();
    for (int k = 0; k < 3; ++k)
      normal[k] = rd.get<float>();
    const auto d = rd.get<float>();
    if (!unitVector(frame_normal) || !unitVector(normal) || !std::isfinite(frame_d)
        || !std::isfinite(d) || std::abs(frame_d) > MAX_COORDINATE_M
        || std::abs(d) > MAX_COORDINATE_M)
      throw IOError(which + " has a non-unit normal or a bad offset");
    if (!(normal.dot(frame_normal) >= cos_angle))
      throw IOError(which
                    + ": its plane is more than plane_merge_angle_rad from its "
                      "raster frame");
    MapPlane mp;
    mp.setFrame(frame_normal, frame_d);
    mp.setRefined(normal, d);
    PlaneMoments& m = mp.moments;
    for (int k = 0; k < 3; ++k)
      m.anchor[k] = rd.get<double>();
    m.weight = rd.get<double>();
    for (int k = 0; k < 3; ++k)
      m.sum[k] = rd.get<double>();
    for (double& v : m.sum_sq_upper)
      v = rd.get<double>();
    if (!m.anchor.allFinite() || m.anchor.cwiseAbs().maxCoeff() > MAX_COORDINATE_M
        || !(m.weight > 0.0) || !std::isfinite(m.weight) || !m.sum.allFinite()
        || !m.sumSq().allFinite())
      throw IOError(which + " has invalid evidence moments");
    const std::size_t cell_count = rd.getCount(CELL_BYTES, "cell");
    std::vector<std::uint64_t> keys;
    std::vector<float> sums;
    std::vector<std::uint16_t> counts;
    keys.reserve(cell_count);
    sums.reserve(cell_count);
    counts.reserve(cell_count);
    for (std::size_t c = 0; c < cell_count; ++c) {
      const auto i = rd.get<std::int32_t>();
      const auto j = rd.get<std::int32_t>();
      const auto sum = rd.get<float>();
      const auto count = rd.get<std::uint16_t>();
      if (std::abs(static_cast<double>(i)) > MAX_CELL_INDEX
          || std::abs(static_cast<double>(j)) > MAX_CELL_INDEX)
        throw IOError(which + ": cell index out of range");
      const std::uint64_t key = cellKey(i, j);
      if (!keys.empty() && !(key > keys.back()))
        throw IOError(which + ": cells not sorted or duplicated");
      checkSum(sum, count, "cell");
      keys.push_back(key);
      sums.push_back(sum);
      counts.push_back(count);
    }
    mp.raster.assign(keys, sums, counts);
    impl->plane_models.emplace_back(normal.x(), normal.y(), normal.z(), d);
    impl->planes.push_back(std::move(mp));
  }
  const std::size_t non_planar_count = rd.getCount(NON_PLANAR_BYTES, "non-planar cell");
  std::unordered_map<NonPlanarKey, std::uint32_t, NonPlanarKeyHash> non_planar_keys;
  impl->non_planar.reserve(non_planar_count);
  std::map<AxesKey, std::uint32_t> axes_lookup;
  for (std::size_t k = 0; k < non_planar_count; ++k) {
    PlanarCuboid c;
    for (int a = 0; a < 3; ++a)
      c.centre[a] = rd.get<float>();
    for (int a = 0; a < 3; ++a)
      c.normal[a] = rd.get<float>();
    for (int a = 0; a < 3; ++a)
      c.horizontal_axis[a] = rd.get<float>();
    c.width_m = rd.get<float>();
    c.height_m = rd.get<float>();
    c.thickness_m = rd.get<float>();
    const auto probability_sum = rd.get<double>();
    const auto feature_count = rd.get<std::uint32_t>();
    const auto extent_ok = [](float e) {
      return std::isfinite(e) && e >= 0.0f && e <= MAX_COORDINATE_M;
    };
    if (!finiteVector(c.centre) || !unitVector(c.normal)
        || !unitVector(c.horizontal_axis)
        || std::abs(c.normal.dot(c.horizontal_axis)) > 1e-3f || !extent_ok(c.width_m)
        || !extent_ok(c.height_m) || !extent_ok(c.thickness_m))
      throw IOError("surface layer: non-planar cell " + std::to_string(k)
                    + " has invalid geometry");
    checkSum(probability_sum, feature_count, "non-planar cell");
    const auto key = nonPlanarKey(c, params.resolution_m);
    if (!non_planar_keys.emplace(key, static_cast<std::uint32_t>(k)).second)
      throw IOError("surface layer: duplicate non-planar cell " + std::to_string(k));
    NonPlanarCell cell(c, impl->internAxes(c, axes_lookup));
    cell.probability_sum = probability_sum;
    cell.feature_count = feature_count;
    impl->non_planar.push_back(cell);
  }
  impl->np_axes.shrink_to_fit();
  if (rd.remaining() != 0)
    throw IOError("surface layer: " + std::to_string(rd.remaining())
                  + " unexpected trailing bytes");
  impl_ = std::move(impl);
  params_ = params;
}

void
SurfaceLayer::exportMesh(const std::string& path) const
{
  const auto dot = path.find_last_of('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  if (ext != ".ply" && ext != ".vtk")
    throw IOError(path + ": unknown mesh extension (expected .ply or .vtk)");
  const PlanarCuboids& cuboids = getCuboids();
  pcl::PointCloud<pcl::PointXYZRGB> vertices;
  vertices.reserve(cuboids.size() * 8);
  pcl::PolygonMesh mesh;
  mesh.polygons.reserve(cuboids.size() * 12);
  // corners(): face 0-3 (front), back 4-7; outward-facing triangles
  static const int TRIANGLES[12][3] = {{0, 1, 2}, {0, 2, 3}, {4, 6, 5}, {4, 7, 6},
                                       {0, 4, 5}, {0, 5, 1}, {1, 5, 6}, {1, 6, 2},
                                       {2, 6, 7}, {2, 7, 3}, {3, 7, 4}, {3, 4, 0}};
  for (const PlanarCuboid& c : cuboids) {
    const auto base = static_cast<pcl::index_t>(vertices.size());
    const float p = std::max(0.0f, std::min(1.0f, c.probability));
    const auto red = static_cast<std::uint8_t>(std::lround(255.0f * p));
    const auto blue = static_cast<std::uint8_t>(255 - red);
    for (const auto& corner : c.corners()) {
      pcl::PointXYZRGB v;
      v.getVector3fMap() = corner;
      v.r = red;
      v.g = c.is_planar ? 96 : 160;
      v.b = blue;
      vertices.push_back(v);
    }
    for (const auto& t : TRIANGLES) {
      pcl::Vertices poly;
      poly.vertices = {base + t[0], base + t[1], base + t[2]};
      mesh.polygons.push_back(std::move(poly));
    }
  }
  pcl::toPCLPointCloud2(vertices, mesh.cloud);
  const bool ply = ext == ".ply";
  writeFileAtomically(path, [&mesh, ply](const std::string& tmp) {
    return (ply ? pcl::io::savePLYFileBinary(tmp, mesh)
                : pcl::io::saveVTKFile(tmp, mesh))
           == 0;
  });
}

bool
SurfaceLayer::operator==(const SurfaceLayer& other) const
{
  const Params& a = params_;
  const Params& b = other.params_;
  if (a.resolution_m != b.resolution_m || a.thickness_m != b.thickness_m
      || a.plane_merge_angle_rad != b.plane_merge_angle_rad
      || a.plane_merge_distance_m != b.plane_merge_distance_m
      || a.occupancy_thres != b.occupancy_thres
      || a.feature_distance_m != b.feature_distance_m
      || a.close_gaps_cells != b.close_gaps_cells || a.merge_rule != b.merge_rule
      || a.cover_density != b.cover_density)
    return false;
  const Impl& x = *impl_;
  const Impl& y = *other.impl_;
  if (x.planes.size() != y.planes.size() || x.non_planar.size() != y.non_planar.size())
    return false;
  for (std::size_t p = 0; p < x.planes.size(); ++p) {
    const MapPlane& u = x.planes[p];
    const MapPlane& v = y.planes[p];
    if (u.frame_normal != v.frame_normal || u.frame_d != v.frame_d
        || u.normal != v.normal || u.d != v.d || !(u.moments == v.moments)
        || !(u.raster == v.raster))
      return false;
  }
  for (std::size_t k = 0; k < x.non_planar.size(); ++k) {
    const NonPlanarCell& c = x.non_planar[k];
    const NonPlanarCell& e = y.non_planar[k];
    const BoxAxes& ca = x.np_axes[c.axes];
    const BoxAxes& ea = y.np_axes[e.axes];
    if (c.centre != e.centre || ca.normal != ea.normal
        || ca.horizontal_axis != ea.horizontal_axis || c.width_m != e.width_m
        || c.height_m != e.height_m || c.thickness_m != e.thickness_m
        || c.probability_sum != e.probability_sum || c.feature_count != e.feature_count)
      return false;
  }
  return true;
}

std::string
toString(SurfaceMergeRule rule)
{
  switch (rule) {
    case SurfaceMergeRule::PAPER:
      return "paper";
    case SurfaceMergeRule::MIN_RECTANGLES:
      return "min_rectangles";
    case SurfaceMergeRule::DENSITY:
      return "density";
  }
  return "unknown";
}

SurfaceMergeRule
surfaceMergeRuleFromString(const std::string& name)
{
  if (name == "paper")
    return SurfaceMergeRule::PAPER;
  if (name == "min_rectangles")
    return SurfaceMergeRule::MIN_RECTANGLES;
  if (name == "density")
    return SurfaceMergeRule::DENSITY;
  throw Exception("Unknown surface merge rule '" + name
                  + "' (expected paper, min_rectangles or density)");
}

} // namespace planar_grid
