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

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <limits>
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
constexpr std::uint32_t VERSION = 1;

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

/** \brief One raster cell: sum and count of the feature probabilities inside it. */
struct RasterCell {
  double probability_sum{0.0};
  std::uint32_t feature_count{0};
  bool operator==(const RasterCell& o) const
  {
    return probability_sum == o.probability_sum && feature_count == o.feature_count;
  }
};

/** \brief A map plane: coefficients as created, its fixed 2D frame, raster and cached
 * cuboids. */
struct MapPlane {
  Eigen::Vector3f normal{Eigen::Vector3f::UnitZ()};
  float d{0.0f};
  Eigen::Vector3f origin{Eigen::Vector3f::Zero()};
  Eigen::Vector3f u_axis{Eigen::Vector3f::UnitX()};
  Eigen::Vector3f v_axis{Eigen::Vector3f::UnitY()};
  /** Observed cells (key cellKey(i, j)). */
  std::unordered_map<std::uint64_t, RasterCell> cells;
  /** Cached cuboids of this plane (valid when !dirty). */
  PlanarCuboids cuboids;
  bool dirty{true};

  /** Sets the coefficients and derives the frame (header: u = up x n or projected x,
   * v = n x u, origin = -d n). */
  void setPlane(const Eigen::Vector3f& n, float offset)
  {
    normal = n;
    d = offset;
    origin = -offset * n;
    Eigen::Vector3f u = Eigen::Vector3f::UnitZ().cross(n);
    if (u.norm() < 1e-3f)
      u = Eigen::Vector3f::UnitX() - n * n.x();
    u_axis = u.normalized();
    v_axis = n.cross(u_axis);
  }
  PCL_MAKE_ALIGNED_OPERATOR_NEW
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

/** \brief A non-planar cell: the latest cuboid with its key and feature sums. */
struct NonPlanarCell {
  PlanarCuboid cuboid;
  double probability_sum{0.0};
  std::uint32_t feature_count{0};
  /** integrate() call that stored it (cells of the same frame never replace each
   * other). */
  std::uint32_t generation{0};
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};

} // namespace

struct SurfaceLayer::Impl {
  std::vector<MapPlane, Eigen::aligned_allocator<MapPlane>> planes;
  PlaneModels plane_models;
  std::vector<NonPlanarCell, Eigen::aligned_allocator<NonPlanarCell>> non_planar;
  /** Spatial hash of the non-planar cells' bounding boxes (bins of 4 cells; cells
   * spanning more than MAX_BINS_PER_CUBOID bins in np_large), for the replacement. */
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> np_bins;
  std::vector<std::uint32_t> np_large;
  std::uint32_t generation{0};

  // Caches (rebuilt under mutex by ensureBuilt()).
  std::mutex mutex;
  bool cache_valid{false};
  PlanarCuboids all_cuboids;
  /** Spatial index: bin key -> cuboid indices; "large" cuboids are tested always. */
  bool index_valid{false};
  float bin_m{0.4f};
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> bins;
  std::vector<std::uint32_t> large;
  Eigen::Vector3f bounds_min{Eigen::Vector3f::Zero()};
  Eigen::Vector3f bounds_max{Eigen::Vector3f::Zero()};

  void invalidate()
  {
    cache_valid = false;
    index_valid = false;
    // a stale query index is freed (rebuilt on the next query)
    decltype(bins)().swap(bins);
    decltype(large)().swap(large);
  }
  /** Calls f(bin key) for the bins of the bounding box of \a c grown by \a grow;
   * returns false (nothing called) when they exceed MAX_BINS_PER_CUBOID. */
  template <typename F>
  bool forNonPlanarBins(const PlanarCuboid& c, float grow, float bin, F f) const;
  void addNonPlanarBins(std::uint32_t index, float bin);
  void eraseNonPlanarBins(std::uint32_t index, float bin, std::uint32_t replacement);
  /** Removes non_planar[index] (the last cell moves to its place). */
  void removeNonPlanar(std::uint32_t index, float bin);
  /** Rebuilds dirty planes and the concatenated cuboids; caller holds the mutex. */
  void ensureCuboids(const Params& params);
  /** Builds the spatial hash over all cuboids; caller holds the mutex. */
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
SurfaceLayer::Impl::addNonPlanarBins(std::uint32_t index, float bin)
{
  if (!forNonPlanarBins(non_planar[index].cuboid, 0.0f, bin,
                        [&](std::uint64_t key) { np_bins[key].push_back(index); }))
    np_large.push_back(index);
}

void
SurfaceLayer::Impl::eraseNonPlanarBins(std::uint32_t index,
                                       float bin,
                                       std::uint32_t replacement)
{
  const auto update = [&](std::vector<std::uint32_t>& v) {
    const auto it = std::find(v.begin(), v.end(), index);
    if (it == v.end())
      return;
    if (replacement == std::numeric_limits<std::uint32_t>::max())
      v.erase(it);
    else
      *it = replacement;
  };
  if (!forNonPlanarBins(non_planar[index].cuboid, 0.0f, bin, [&](std::uint64_t key) {
        const auto it = np_bins.find(key);
        if (it == np_bins.end())
          return;
        update(it->second);
        if (it->second.empty())
          np_bins.erase(it);
      }))
    update(np_large);
}

void
SurfaceLayer::Impl::removeNonPlanar(std::uint32_t index, float bin)
{
  const auto last = static_cast<std::uint32_t>(non_planar.size() - 1);
  eraseNonPlanarBins(index, bin, std::numeric_limits<std::uint32_t>::max());
  if (index != last) {
    eraseNonPlanarBins(last, bin, index);
    non_planar[index] = non_planar[last];
  }
  non_planar.pop_back();
}

namespace {

/** \brief Validates parameters (S23); throws planar_grid::Exception. */
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

/** \brief Rebuilds the cuboids of one plane: occupancy per cell (features' mean,
 * else propagated neighbours' mean, else 0.5), then the horizontal-then-vertical
 * merge of cells of one occupancy class. */
void
rebuildPlane(MapPlane& plane, int plane_id, const SurfaceLayer::Params& params)
{
  plane.cuboids.clear();
  plane.dirty = false;
  const std::size_t n = plane.cells.size();
  if (n == 0)
    return;
  std::vector<std::uint64_t> keys;
  keys.reserve(n);
  for (const auto& kv : plane.cells)
    keys.push_back(kv.first);
  std::sort(keys.begin(), keys.end()); // row j, then column i
  const auto indexOf = [&keys](std::int32_t i, std::int32_t j) -> std::ptrdiff_t {
    const std::uint64_t k = cellKey(i, j);
    const auto it = std::lower_bound(keys.begin(), keys.end(), k);
    return (it != keys.end() && *it == k) ? it - keys.begin() : -1;
  };

  // Occupancy (paper, end of III-F): features' mean; featureless cells take the mean
  // of their valued 8-neighbours, layer by layer outward; unreachable cells 0.5.
  std::vector<float> value(n, std::numeric_limits<float>::quiet_NaN());
  std::vector<std::uint32_t> count(n, 0);
  for (std::size_t k = 0; k < n; ++k) {
    const RasterCell& cell = plane.cells.find(keys[k])->second;
    count[k] = cell.feature_count;
    if (cell.feature_count > 0)
      value[k] = static_cast<float>(cell.probability_sum / cell.feature_count);
  }
  std::size_t valued_cells = 0;
  for (std::size_t k = 0; k < n; ++k)
    valued_cells += count[k] > 0 ? 1 : 0;
  // neighbours only matter when valued and featureless cells coexist
  const bool propagate = valued_cells > 0 && valued_cells < n;
  std::vector<std::array<std::ptrdiff_t, 8>> neighbours(propagate ? n : 0);
  for (std::size_t k = 0; propagate && k < n; ++k) {
    const std::int32_t i = keyI(keys[k]), j = keyJ(keys[k]);
    int m = 0;
    for (int dj = -1; dj <= 1; ++dj)
      for (int di = -1; di <= 1; ++di)
        if (di != 0 || dj != 0)
          neighbours[k][m++] = indexOf(i + di, j + dj);
  }
  std::vector<std::size_t> layer, next;
  for (std::size_t k = 0; propagate && k < n; ++k)
    if (std::isnan(value[k]))
      for (const auto nb : neighbours[k])
        if (nb >= 0 && !std::isnan(value[nb])) {
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
        if (nb >= 0 && !std::isnan(value[nb])) {
          sum += value[nb];
          ++valued;
        }
      layer_values[l] = static_cast<float>(sum / valued);
    }
    for (std::size_t l = 0; l < layer.size(); ++l)
      value[layer[l]] = layer_values[l];
    next.clear();
    for (const auto k : layer)
      for (const auto nb : neighbours[k])
        if (nb >= 0 && std::isnan(value[nb]) && queued[nb] == 0) {
          queued[nb] = 1;
          next.push_back(static_cast<std::size_t>(nb));
        }
    std::swap(layer, next);
  }
  for (auto& v : value)
    if (std::isnan(v))
      v = 0.5f;

  // Merge (Fig. 6(b)): maximal runs along u of one class per row, then runs with the
  // same [i0, i1) and class in consecutive rows are stacked into one rectangle.
  struct Run {
    std::int32_t i0, i1;
    bool occupied;
    std::size_t rect;
  };
  struct Rect {
    std::int32_t i0, i1, j0, j1;
    double probability_sum;
    std::size_t feature_count;
    std::size_t cells;
  };
  std::vector<Rect> rects;
  std::vector<Run> previous, current;
  std::int32_t previous_row = 0;
  const double thres = params.occupancy_thres;
  for (std::size_t k = 0; k < n;) {
    const std::int32_t j = keyJ(keys[k]);
    if (j != previous_row + 1)
      previous.clear();
    current.clear();
    std::size_t p = 0;
    while (k < n && keyJ(keys[k]) == j) {
      const bool occupied = value[k] >= thres;
      const std::int32_t i0 = keyI(keys[k]);
      std::int32_t i1 = i0 + 1;
      double sum = value[k];
      std::size_t features = count[k];
      std::size_t e = k + 1;
      while (e < n && keyJ(keys[e]) == j && keyI(keys[e]) == i1
             && (value[e] >= thres) == occupied) {
        sum += value[e];
        features += count[e];
        ++i1;
        ++e;
      }
      while (p < previous.size() && previous[p].i0 < i0)
        ++p;
      std::size_t rect;
      if (p < previous.size() && previous[p].i0 == i0 && previous[p].i1 == i1
          && previous[p].occupied == occupied) {
        rect = previous[p].rect;
        rects[rect].j1 = j + 1;
        rects[rect].probability_sum += sum;
        rects[rect].feature_count += features;
        rects[rect].cells += static_cast<std::size_t>(i1 - i0);
      } else {
        rect = rects.size();
        rects.push_back(
          Rect{i0, i1, j, j + 1, sum, features, static_cast<std::size_t>(i1 - i0)});
      }
      current.push_back(Run{i0, i1, occupied, rect});
      k = e;
    }
    std::swap(previous, current);
    previous_row = j;
  }

  const double r = params.resolution_m;
  const float thickness = static_cast<float>(params.thickness_m);
  plane.cuboids.reserve(rects.size());
  for (const Rect& rect : rects) {
    // In double: corrupt (but accepted) raster keys near the int range must not
    // overflow.
    const double u_mid = 0.5 * (static_cast<double>(rect.i0) + rect.i1) * r;
    const double v_mid = 0.5 * (static_cast<double>(rect.j0) + rect.j1) * r;
    PlanarCuboid c;
    c.normal = plane.normal;
    c.horizontal_axis = plane.u_axis;
    c.width_m = static_cast<float>((static_cast<double>(rect.i1) - rect.i0) * r);
    c.height_m = static_cast<float>((static_cast<double>(rect.j1) - rect.j0) * r);
    c.thickness_m = thickness;
    c.centre = plane.origin + plane.u_axis * static_cast<float>(u_mid)
               + plane.v_axis * static_cast<float>(v_mid)
               - plane.normal * (0.5f * thickness);
    c.plane_id = plane_id;
    c.point_count = rect.feature_count;
    c.is_planar = true;
    c.probability = static_cast<float>(rect.probability_sum / rect.cells);
    plane.cuboids.push_back(c);
  }
}

} // namespace

/** \brief Rebuilds dirty planes and the concatenated cuboids; caller holds the
 * mutex. */
void
SurfaceLayer::Impl::ensureCuboids(const Params& params)
{
  Impl& impl = *this;
  if (impl.cache_valid)
    return;
  std::size_t total = impl.non_planar.size();
  for (std::size_t p = 0; p < impl.planes.size(); ++p) {
    if (impl.planes[p].dirty)
      rebuildPlane(impl.planes[p], static_cast<int>(p), params);
    total += impl.planes[p].cuboids.size();
  }
  impl.all_cuboids.clear();
  impl.all_cuboids.reserve(total);
  for (const auto& plane : impl.planes)
    impl.all_cuboids.insert(impl.all_cuboids.end(), plane.cuboids.begin(),
                            plane.cuboids.end());
  for (const auto& cell : impl.non_planar) {
    PlanarCuboid c = cell.cuboid;
    c.probability = cell.feature_count > 0
                      ? static_cast<float>(cell.probability_sum / cell.feature_count)
                      : 0.5f;
    c.point_count = cell.feature_count;
    impl.all_cuboids.push_back(c);
  }
  impl.cache_valid = true;
  impl.index_valid = false;
}

/** \brief Builds the spatial hash over all cuboids; caller holds the mutex. */
void
SurfaceLayer::Impl::ensureIndex(const Params& params)
{
  Impl& impl = *this;
  ensureCuboids(params);
  if (impl.index_valid)
    return;
  impl.bins.clear();
  impl.large.clear();
  impl.bounds_min = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  impl.bounds_max = -impl.bounds_min;
  for (const auto& cuboid : impl.all_cuboids) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(cuboid, lo, hi);
    impl.bounds_min = impl.bounds_min.cwiseMin((lo.array() - 1e-4f).matrix());
    impl.bounds_max = impl.bounds_max.cwiseMax((hi.array() + 1e-4f).matrix());
  }
  // Bins of 4 cells; never more than 1e5 bins across the map's extent (a ray walks at
  // most ~3e5 bins), whatever the data.
  const float span =
    impl.all_cuboids.empty() ? 0.0f : (impl.bounds_max - impl.bounds_min).maxCoeff();
  impl.bin_m = std::max(static_cast<float>(4.0 * params.resolution_m), span * 1e-5f);
  const float inv = 1.0f / impl.bin_m;
  for (std::size_t c = 0; c < impl.all_cuboids.size(); ++c) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(impl.all_cuboids[c], lo, hi);
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

  // 1. Frame plane -> map plane (oriented like the frame's cuboids, toward its
  //    sensor; the nearest map plane within the angle and offset tolerances, else new).
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
  std::vector<int> touched;
  for (std::size_t p = 0; p < planes.size(); ++p) {
    if (!orientation_known[p])
      continue;
    const Eigen::Vector3f n = oriented[p].head<3>();
    const float d = oriented[p][3];
    int best = -1;
    float best_dd = std::numeric_limits<float>::max();
    for (std::size_t m = 0; m < impl.planes.size(); ++m) {
      const MapPlane& mp = impl.planes[m];
      const float dd = std::abs(mp.d - d);
      if (mp.normal.dot(n) >= cos_angle && dd <= params_.plane_merge_distance_m
          && dd < best_dd) {
        best = static_cast<int>(m);
        best_dd = dd;
      }
    }
    if (best < 0) {
      MapPlane mp;
      mp.setPlane(n.normalized(), d);
      impl.planes.push_back(std::move(mp));
      impl.plane_models.emplace_back(impl.planes.back().normal.x(),
                                     impl.planes.back().normal.y(),
                                     impl.planes.back().normal.z(), d);
      best = static_cast<int>(impl.planes.size()) - 1;
    }
    map_of_frame[p] = best;
    impl.planes[static_cast<std::size_t>(best)].dirty = true;
    if (std::find(touched.begin(), touched.end(), best) == touched.end())
      touched.push_back(best);
  }

  // 2. Planar cuboids mark the map plane's cells whose centres fall inside the face.
  // Non-planar cuboids replace the cell with the same key.
  std::vector<std::uint32_t> frame_non_planar;
  std::vector<NonPlanarCell, Eigen::aligned_allocator<NonPlanarCell>> incoming;
  std::unordered_map<NonPlanarKey, std::size_t, NonPlanarKeyHash> frame_keys;
  const std::uint32_t generation = ++impl.generation;
  const auto np_bin = static_cast<float>(4.0 * r);
  bool skipped = false;
  for (const PlanarCuboid& c : cuboids) {
    if (!finiteVector(c.centre) || !c.normal.allFinite()
        || !c.horizontal_axis.allFinite() || !std::isfinite(c.width_m)
        || !std::isfinite(c.height_m) || !std::isfinite(c.thickness_m)
        || c.width_m < 0.0f || c.height_m < 0.0f || c.thickness_m < 0.0f) {
      skipped = true;
      continue;
    }
    const bool planar = c.is_planar && c.plane_id >= 0
                        && static_cast<std::size_t>(c.plane_id) < planes.size()
                        && map_of_frame[static_cast<std::size_t>(c.plane_id)] >= 0;
    if (!planar) {
      NonPlanarCell cell;
      cell.cuboid = c;
      cell.cuboid.plane_id = -1;
      cell.cuboid.is_planar = false;
      cell.generation = generation;
      const auto inserted = frame_keys.emplace(nonPlanarKey(c, r), incoming.size());
      if (inserted.second)
        incoming.push_back(cell);
      else
        incoming[inserted.first->second] = cell; // same key twice in one frame
      continue;
    }
    MapPlane& mp = impl.planes[static_cast<std::size_t>(
      map_of_frame[static_cast<std::size_t>(c.plane_id)])];
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
    mp.dirty = true;
    for (auto j = static_cast<std::int32_t>(j0); j <= static_cast<std::int32_t>(j1);
         ++j) {
      const Eigen::Vector3f row =
        mp.origin + mp.v_axis * static_cast<float>((j + 0.5) * r) - fc;
      for (auto i = static_cast<std::int32_t>(i0); i <= static_cast<std::int32_t>(i1);
           ++i) {
        const Eigen::Vector3f q = row + mp.u_axis * static_cast<float>((i + 0.5) * r);
        if (std::abs(q.dot(h)) <= hw && std::abs(q.dot(vert)) <= hh)
          mp.cells.try_emplace(cellKey(i, j));
      }
    }
  }
  if (skipped)
    PCL_WARN("[planar_grid::SurfaceLayer::integrate] Skipped cuboids with non-finite "
             "or absurd (> 1e7 m or > 1e7 cells) geometry.\n");

  // 2b. Non-planar replacement (header): every stored cell of an earlier frame whose
  // centre lies in a new cuboid grown by half a cell, or that contains the new
  // cuboid's centre, is removed; then the new cells are appended.
  {
    const float half_cell = static_cast<float>(0.5 * r);
    std::vector<std::uint32_t> doomed;
    const auto test = [&](const PlanarCuboid& nw, std::uint32_t index) {
      const NonPlanarCell& old = impl.non_planar[index];
      if (old.generation != generation
          && (nw.contains(old.cuboid.centre, half_cell)
              || old.cuboid.contains(nw.centre)))
        doomed.push_back(index);
    };
    for (const NonPlanarCell& cell : incoming) {
      const PlanarCuboid& nw = cell.cuboid;
      const bool binned =
        impl.forNonPlanarBins(nw, half_cell, np_bin, [&](std::uint64_t key) {
          const auto it = impl.np_bins.find(key);
          if (it != impl.np_bins.end())
            for (const auto index : it->second)
              test(nw, index);
        });
      if (binned)
        for (const auto index : impl.np_large)
          test(nw, index);
      else
        for (std::size_t index = 0; index < impl.non_planar.size(); ++index)
          test(nw, static_cast<std::uint32_t>(index));
    }
    std::sort(doomed.begin(), doomed.end());
    doomed.erase(std::unique(doomed.begin(), doomed.end()), doomed.end());
    // highest first: the cell moved into a freed slot is never one still to remove
    for (auto it = doomed.rbegin(); it != doomed.rend(); ++it)
      impl.removeNonPlanar(*it, np_bin);
    impl.non_planar.reserve(impl.non_planar.size() + incoming.size());
    for (const NonPlanarCell& cell : incoming) {
      const auto index = static_cast<std::uint32_t>(impl.non_planar.size());
      impl.non_planar.push_back(cell);
      impl.addNonPlanarBins(index, np_bin);
      frame_non_planar.push_back(index);
    }
  }

  // 3. Features: each adds its probability to the observed cell it falls in on every
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
      cuboidBounds(impl.non_planar[index].cuboid, lo, hi);
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
    for (std::size_t f = 0; f < features.size(); ++f) {
      const Eigen::Vector3f p = features[f].getVector3fMap();
      const float prob = probabilities[f];
      if (!finiteVector(p) || !(prob >= 0.0f && prob <= 1.0f))
        continue;
      for (const int m : touched) {
        MapPlane& mp = impl.planes[static_cast<std::size_t>(m)];
        if (std::abs(mp.normal.dot(p) + mp.d) > feature_distance)
          continue;
        const Eigen::Vector3f q = p - mp.origin;
        const double fi = std::floor(q.dot(mp.u_axis) * inv_r);
        const double fj = std::floor(q.dot(mp.v_axis) * inv_r);
        if (std::abs(fi) > MAX_CELL_INDEX || std::abs(fj) > MAX_CELL_INDEX)
          continue;
        const auto i = static_cast<std::int32_t>(fi);
        const auto j = static_cast<std::int32_t>(fj);
        const auto it = mp.cells.find(cellKey(i, j));
        if (it == mp.cells.end())
          continue;
        it->second.probability_sum += prob;
        ++it->second.feature_count;
      }
      const auto add = [&](std::uint32_t index) {
        NonPlanarCell& cell = impl.non_planar[index];
        if (cell.cuboid.contains(p)) {
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
  }
  impl.invalidate();
}

const PlanarCuboids&
SurfaceLayer::getCuboids() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  impl_->ensureCuboids(params_);
  return impl_->all_cuboids;
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
    n += plane.cells.size();
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
    bytes += hashMapBytes(plane.cells) + vectorBytes(plane.cuboids);
  bytes += vectorBytes(impl.non_planar) + hashMapBytes(impl.np_bins)
           + vectorBytes(impl.np_large);
  for (const auto& kv : impl.np_bins)
    bytes += vectorBytes(kv.second);
  bytes +=
    vectorBytes(impl.all_cuboids) + hashMapBytes(impl.bins) + vectorBytes(impl.large);
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
    if ((best == nullptr || c < *best) && impl.all_cuboids[c].contains(point))
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
  return best == nullptr ? nullptr : &impl.all_cuboids[*best];
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
  if (impl.all_cuboids.empty())
    return false;
  const float max_t = static_cast<float>(std::min(max_range_m, 1e9));
  const float thres = static_cast<float>(params_.occupancy_thres);
  float best_t = std::numeric_limits<float>::infinity();
  std::size_t best_index = 0;
  const auto test = [&](std::uint32_t c) {
    const PlanarCuboid& box = impl.all_cuboids[c];
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
  w.put(static_cast<std::uint64_t>(impl.planes.size()));
  std::vector<std::uint64_t> keys;
  for (const auto& plane : impl.planes) {
    w.put(plane.normal.x());
    w.put(plane.normal.y());
    w.put(plane.normal.z());
    w.put(plane.d);
    w.put(static_cast<std::uint64_t>(plane.cells.size()));
    keys.clear();
    for (const auto& kv : plane.cells)
      keys.push_back(kv.first);
    std::sort(keys.begin(), keys.end());
    for (const auto key : keys) {
      const RasterCell& cell = plane.cells.find(key)->second;
      w.put(keyI(key));
      w.put(keyJ(key));
      w.put(cell.probability_sum);
      w.put(cell.feature_count);
    }
  }
  w.put(static_cast<std::uint64_t>(impl.non_planar.size()));
  for (const auto& cell : impl.non_planar) {
    const PlanarCuboid& c = cell.cuboid;
    for (int k = 0; k < 3; ++k)
      w.put(c.centre[k]);
    for (int k = 0; k < 3; ++k)
      w.put(c.normal[k]);
    for (int k = 0; k < 3; ++k)
      w.put(c.horizontal_axis[k]);
    w.put(c.width_m);
    w.put(c.height_m);
    w.put(c.thickness_m);
    w.put(cell.probability_sum);
    w.put(cell.feature_count);
  }
}

namespace {
constexpr std::size_t PLANE_BYTES = 4 * sizeof(float) + sizeof(std::uint64_t);
constexpr std::size_t CELL_BYTES =
  2 * sizeof(std::int32_t) + sizeof(double) + sizeof(std::uint32_t);
constexpr std::size_t NON_PLANAR_BYTES =
  12 * sizeof(float) + sizeof(double) + sizeof(std::uint32_t);

void
checkSum(double sum, std::uint32_t count, const char* what)
{
  if (!std::isfinite(sum) || sum < -1e-9 || sum > count * (1.0 + 1e-9) + 1e-9)
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
  if (version != VERSION)
    throw IOError("surface layer: unsupported version " + std::to_string(version));
  Params params;
  params.resolution_m = rd.get<double>();
  params.thickness_m = rd.get<double>();
  params.plane_merge_angle_rad = rd.get<double>();
  params.plane_merge_distance_m = rd.get<double>();
  params.occupancy_thres = rd.get<double>();
  params.feature_distance_m = rd.get<double>();
  try {
    validate(params);
  } catch (const Exception& e) {
    throw IOError(std::string("surface layer: ") + e.what());
  }
  auto impl = std::make_unique<Impl>();
  const std::size_t plane_count = rd.getCount(PLANE_BYTES, "plane");
  impl->planes.reserve(plane_count);
  impl->plane_models.reserve(plane_count);
  for (std::size_t p = 0; p < plane_count; ++p) {
    Eigen::Vector3f n;
    n.x() = rd.get<float>();
    n.y() = rd.get<float>();
    n.z() = rd.get<float>();
    const auto d = rd.get<float>();
    if (!unitVector(n) || !std::isfinite(d) || std::abs(d) > MAX_COORDINATE_M)
      throw IOError("surface layer: plane " + std::to_string(p)
                    + " has a non-unit normal or a bad offset");
    MapPlane mp;
    mp.setPlane(n, d);
    const std::size_t cell_count = rd.getCount(CELL_BYTES, "cell");
    mp.cells.reserve(cell_count);
    for (std::size_t c = 0; c < cell_count; ++c) {
      const auto i = rd.get<std::int32_t>();
      const auto j = rd.get<std::int32_t>();
      RasterCell cell;
      cell.probability_sum = rd.get<double>();
      cell.feature_count = rd.get<std::uint32_t>();
      checkSum(cell.probability_sum, cell.feature_count, "cell");
      if (!mp.cells.emplace(cellKey(i, j), cell).second)
        throw IOError("surface layer: duplicate cell in plane " + std::to_string(p));
    }
    impl->plane_models.emplace_back(n.x(), n.y(), n.z(), d);
    impl->planes.push_back(std::move(mp));
  }
  const std::size_t non_planar_count = rd.getCount(NON_PLANAR_BYTES, "non-planar cell");
  std::unordered_map<NonPlanarKey, std::uint32_t, NonPlanarKeyHash> non_planar_keys;
  impl->non_planar.reserve(non_planar_count);
  for (std::size_t k = 0; k < non_planar_count; ++k) {
    NonPlanarCell cell;
    PlanarCuboid& c = cell.cuboid;
    for (int a = 0; a < 3; ++a)
      c.centre[a] = rd.get<float>();
    for (int a = 0; a < 3; ++a)
      c.normal[a] = rd.get<float>();
    for (int a = 0; a < 3; ++a)
      c.horizontal_axis[a] = rd.get<float>();
    c.width_m = rd.get<float>();
    c.height_m = rd.get<float>();
    c.thickness_m = rd.get<float>();
    cell.probability_sum = rd.get<double>();
    cell.feature_count = rd.get<std::uint32_t>();
    const auto extent_ok = [](float e) {
      return std::isfinite(e) && e >= 0.0f && e <= MAX_COORDINATE_M;
    };
    if (!finiteVector(c.centre) || !unitVector(c.normal)
        || !unitVector(c.horizontal_axis)
        || std::abs(c.normal.dot(c.horizontal_axis)) > 1e-3f || !extent_ok(c.width_m)
        || !extent_ok(c.height_m) || !extent_ok(c.thickness_m))
      throw IOError("surface layer: non-planar cell " + std::to_string(k)
                    + " has invalid geometry");
    checkSum(cell.probability_sum, cell.feature_count, "non-planar cell");
    c.plane_id = -1;
    c.is_planar = false;
    const auto key = nonPlanarKey(c, params.resolution_m);
    if (!non_planar_keys.emplace(key, static_cast<std::uint32_t>(k)).second)
      throw IOError("surface layer: duplicate non-planar cell " + std::to_string(k));
    impl->non_planar.push_back(cell);
  }
  const auto np_bin = static_cast<float>(4.0 * params.resolution_m);
  for (std::size_t k = 0; k < impl->non_planar.size(); ++k)
    impl->addNonPlanarBins(static_cast<std::uint32_t>(k), np_bin);
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
      || a.feature_distance_m != b.feature_distance_m)
    return false;
  const Impl& x = *impl_;
  const Impl& y = *other.impl_;
  if (x.planes.size() != y.planes.size() || x.non_planar.size() != y.non_planar.size())
    return false;
  for (std::size_t p = 0; p < x.planes.size(); ++p)
    if (x.planes[p].normal != y.planes[p].normal || x.planes[p].d != y.planes[p].d
        || x.planes[p].cells != y.planes[p].cells)
      return false;
  for (std::size_t k = 0; k < x.non_planar.size(); ++k) {
    const NonPlanarCell& c = x.non_planar[k];
    const NonPlanarCell& e = y.non_planar[k];
    if (c.cuboid.centre != e.cuboid.centre || c.cuboid.normal != e.cuboid.normal
        || c.cuboid.horizontal_axis != e.cuboid.horizontal_axis
        || c.cuboid.width_m != e.cuboid.width_m
        || c.cuboid.height_m != e.cuboid.height_m
        || c.cuboid.thickness_m != e.cuboid.thickness_m
        || c.probability_sum != e.probability_sum || c.feature_count != e.feature_count)
      return false;
  }
  return true;
}

} // namespace planar_grid
