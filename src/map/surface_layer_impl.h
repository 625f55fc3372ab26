// SPDX-License-Identifier: BSD-3-Clause
// The private storage of the surface layer and the helpers its source files share
// (private to the map module; the public API is planar_grid/map/surface_layer.h).
#pragma once

#include <planar_grid/map/plane_association.h>
#include <planar_grid/map/surface_layer.h>
#include <planar_grid/surface/rectangle_merge.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <map>
#include <mutex>
#include <unordered_map>
#include <utility>
#include <vector>

#include "surface_raster.h"

namespace planar_grid {
namespace surface_layer_detail {

/** \brief Raster cells per face beyond which a face is skipped (a corrupt or
 * absurdly large cuboid). */
inline constexpr double MAX_FACE_CELLS = 1e7;
/** \brief Largest coordinate accepted, meters (corrupt data guard). */
inline constexpr float MAX_COORDINATE_M = 1e7f;
/** \brief Spatial-index bins per cuboid beyond which it goes to the "large" list. */
inline constexpr double MAX_BINS_PER_CUBOID = 4096.0;
/** \brief Section magic ("PGSL") and version of serialize(). */
inline constexpr std::uint32_t MAGIC = 0x4C534750u;
inline constexpr std::uint32_t VERSION = 8;
/** \brief Largest Params::close_gaps_cells. */
inline constexpr int MAX_CLOSE_GAPS_CELLS =
  static_cast<int>(surface_layer_ranges::CLOSE_GAPS.max);

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

/** \brief True when \a v is finite and within MAX_COORDINATE_M. */
inline bool
finiteVector(const Eigen::Vector3f& v)
{
  return v.allFinite() && v.cwiseAbs().maxCoeff() <= MAX_COORDINATE_M;
}

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
  /** The cover was rebuilt since the last removeNonPlanarCellsOnPlanes(), which
   * tests the non-planar cells near its cuboids again. */
  bool tidy_pending{true};

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

inline AxesKey
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

/** \brief Key of the spatial-index bin (x, y, z). */
inline std::uint64_t
binKey(std::int64_t x, std::int64_t y, std::int64_t z)
{
  // 21 bits per axis (+-1e6 bins) is ample for |coordinates| <= 1e7 m at >= 4 cm bins
  const auto pack = [](std::int64_t v) {
    return static_cast<std::uint64_t>(v + (std::int64_t{1} << 20)) & 0x1FFFFFu;
  };
  return (pack(x) << 42) | (pack(y) << 21) | pack(z);
}

/** \brief Axis-aligned bounds of a cuboid. */
inline void
cuboidBounds(const PlanarCuboid& c, Eigen::Vector3f& lo, Eigen::Vector3f& hi)
{
  const Eigen::Vector3f half = (c.horizontal_axis * (0.5f * c.width_m)).cwiseAbs()
                               + (c.verticalAxis() * (0.5f * c.height_m)).cwiseAbs()
                               + (c.normal * (0.5f * c.thickness_m)).cwiseAbs();
  lo = c.centre - half;
  hi = c.centre + half;
}

/** \brief Indices of the bin of edge \a bin (meters) holding point \a p (meters). */
inline Eigen::Vector3d
binOf(const Eigen::Vector3f& p, float bin)
{
  return (p / bin).cast<double>().array().floor();
}

/** \brief The bins of edge \a bin (meters) that the bounding box of \a c grown by
 * \a grow (meters) meets: indices \a first to \a last per axis. */
inline void
binRange(const PlanarCuboid& c,
         float grow,
         float bin,
         Eigen::Vector3d& first,
         Eigen::Vector3d& last)
{
  Eigen::Vector3f lo, hi;
  cuboidBounds(c, lo, hi);
  lo.array() -= grow;
  hi.array() += grow;
  first = binOf(lo, bin);
  last = binOf(hi, bin);
}

/** \brief Calls f(bin key) for the bins of binRange(); returns false (nothing called)
 * when they exceed MAX_BINS_PER_CUBOID. */
template <typename F>
bool
forEachBin(const PlanarCuboid& c, float grow, float bin, F f)
{
  Eigen::Vector3d a, b;
  binRange(c, grow, bin, a, b);
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

/** \brief Fills \a bins with a (bin key, index) entry per bin of edge \a bin (meters)
 * that each of \a cuboids, grown by \a grow (meters), meets (forEachBin()), sorted by
 * key and by index within a key; the cuboids spanning more than MAX_BINS_PER_CUBOID
 * bins go to \a large instead. */
inline void
binCuboids(const PlanarCuboids& cuboids,
           float grow,
           float bin,
           std::vector<BinEntry>& bins,
           std::vector<std::uint32_t>& large)
{
  bins.clear();
  large.clear();
  for (std::size_t k = 0; k < cuboids.size(); ++k) {
    const auto index = static_cast<std::uint32_t>(k);
    if (!forEachBin(cuboids[k], grow, bin,
                    [&](std::uint64_t key) { bins.emplace_back(key, index); }))
      large.push_back(index);
  }
  std::stable_sort(bins.begin(), bins.end());
}

/** \brief binCuboids() for the pairs of which one cuboid is \a hot (hot(k) true for
 * cuboid k): the other cuboids get entries only in the bins a hot cuboid meets, so a
 * bin either holds a hot cuboid or is absent; the bins that hold a hot cuboid are
 * binCuboids()' bins exactly. The large cuboids go to \a large as there, but for
 * those beyond every hot cuboid's reach, which pair with none. */
template <typename Hot>
void
binCuboidsNearHot(const PlanarCuboids& cuboids,
                  float grow,
                  float bin,
                  const Hot& hot,
                  std::vector<BinEntry>& bins,
                  std::vector<std::uint32_t>& large)
{
  bins.clear();
  large.clear();
  // the hot cuboids' bins, and the box of the bins they span
  std::vector<std::uint64_t> reached;
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  for (std::size_t k = 0; k < cuboids.size(); ++k) {
    if (!hot(k))
      continue;
    const auto index = static_cast<std::uint32_t>(k);
    if (!forEachBin(cuboids[k], grow, bin, [&](std::uint64_t key) {
          bins.emplace_back(key, index);
          reached.push_back(key);
        })) {
      large.push_back(index);
      continue;
    }
    Eigen::Vector3f c_lo, c_hi;
    cuboidBounds(cuboids[k], c_lo, c_hi);
    lo = lo.cwiseMin(c_lo - Eigen::Vector3f::Constant(grow + bin));
    hi = hi.cwiseMax(c_hi + Eigen::Vector3f::Constant(grow + bin));
  }
  std::sort(reached.begin(), reached.end());
  reached.erase(std::unique(reached.begin(), reached.end()), reached.end());
  for (std::size_t k = 0; k < cuboids.size(); ++k) {
    if (hot(k))
      continue;
    const auto index = static_cast<std::uint32_t>(k);
    Eigen::Vector3f c_lo, c_hi;
    cuboidBounds(cuboids[k], c_lo, c_hi);
    // (a cuboid beyond every hot cuboid's reach pairs with none, large or not)
    if (!((c_hi.array() + grow >= lo.array()).all()
          && (c_lo.array() - grow <= hi.array()).all()))
      continue;
    if (!forEachBin(cuboids[k], grow, bin, [&](std::uint64_t key) {
          if (std::binary_search(reached.begin(), reached.end(), key))
            bins.emplace_back(key, index);
        }))
      large.push_back(index);
  }
  // by key, then by index within a key, as binCuboids()
  std::sort(bins.begin(), bins.end(), [](const BinEntry& a, const BinEntry& b) {
    return a.key() < b.key() || (a.key() == b.key() && a.index < b.index);
  });
}

/** \brief Raster index of a coordinate in cells, or false when beyond
 * MAX_CELL_INDEX. */
inline bool
cellIndex(double coordinate, std::int64_t& index)
{
  const double f = std::floor(coordinate);
  if (!(std::abs(f) <= MAX_CELL_INDEX))
    return false;
  index = static_cast<std::int64_t>(f);
  return true;
}

/** \brief True for a cuboid of finite geometry (centre within MAX_COORDINATE_M,
 * non-negative extents). */
inline bool
validGeometry(const PlanarCuboid& c)
{
  return finiteVector(c.centre) && c.normal.allFinite() && c.horizontal_axis.allFinite()
         && std::isfinite(c.width_m) && std::isfinite(c.height_m)
         && std::isfinite(c.thickness_m) && c.width_m >= 0.0f && c.height_m >= 0.0f
         && c.thickness_m >= 0.0f;
}

/** \brief True for a face whose cells are marked (valid, at most MAX_FACE_CELLS
 * cells of edge \a r). */
inline bool
usableFace(const PlanarCuboid& c, double r)
{
  return validGeometry(c)
         && static_cast<double>(c.width_m) * c.height_m <= MAX_FACE_CELLS * r * r;
}

/** \brief Validates parameters; throws planar_grid::Exception. */
void validate(const SurfaceLayer::Params& p);

/** \brief Key of a non-planar cell: centre quantised to cells of \a resolution_m,
 * extents rounded to cells. */
NonPlanarKey nonPlanarKey(const PlanarCuboid& c, double resolution_m);

/** \brief Refits the refined plane of \a plane to its evidence (fitPlane(), the
 * normal within the angle whose cosine is \a cos_angle); kept when the fit fails. */
void refitPlane(MapPlane& plane, double cos_angle);

/** \brief The surface layer's association criteria: normals of the same orientation
 * within plane_merge_angle_rad, evidence within plane_merge_distance_m (root mean
 * square) of the least-squares plane of both. */
PlaneAssociationCriteria associationCriteria(const SurfaceLayer::Params& params);

/** \brief A map plane as the association sees it: its refined plane and evidence. */
PlaneObservation observation(const MapPlane& plane);

/** \brief Whether a plane whose unit normal has the z component \a normal_z is
 * level: within LEVEL_MAX_ANGLE_RAD of the world z axis, either sign (road, pavement,
 * floor, a step). */
inline bool
isLevel(float normal_z)
{
  static const auto cos_level = static_cast<float>(std::cos(LEVEL_MAX_ANGLE_RAD));
  return std::abs(normal_z) >= cos_level;
}

/** \brief True unless terrain tiles are on (\a tile_m > 0), both planes are level
 * (normals within LEVEL_MAX_ANGLE_RAD of the world z axis) and their evidence's
 * centroids lie in different tiles of \a tile_m (SurfaceLayer::Params::
 * terrain_plane_tile_m); an observation without evidence is in every tile. */
bool
sameTerrainTile(double tile_m, const PlaneObservation& a, const PlaneObservation& b);

/** \brief The plane of \a planes that \a observed matches at the smallest distance
 * (PlaneAssociation::findBest()) among those in its terrain tile (sameTerrainTile()),
 * the lowest index on a tie; -1 when none matches. */
template <typename Planes>
std::ptrdiff_t
findBestMapPlane(const Planes& planes,
                 const PlaneAssociation& association,
                 const PlaneObservation& observed,
                 double tile_m)
{
  std::ptrdiff_t best = -1;
  double best_distance = std::numeric_limits<double>::infinity();
  for (std::size_t m = 0; m < planes.size(); ++m) {
    const PlaneObservation registered = observation(planes[m]);
    double distance = 0.0;
    if (sameTerrainTile(tile_m, registered, observed)
        && association.match(registered, observed, distance)
        && distance < best_distance) {
      best = static_cast<std::ptrdiff_t>(m);
      best_distance = distance;
    }
  }
  return best;
}

/** \brief Adds the cells of raster \a src, laid out in \a src_frame, to \a dst
 * (another frame of about the same plane): every dst cell whose centre, projected
 * onto src_frame, falls in an observed src cell is observed, and the features of a src
 * cell go to the dst cell containing its centre (observed too, so no evidence is
 * lost); \a r is the cell edge, meters. */
void reprojectRaster(const Raster& src,
                     const RasterFrame& src_frame,
                     MapPlane& dst,
                     double r);

/** \brief Scratch of one integrate(): the frame's planes, oriented toward its
 * sensor, and the map planes they joined. */
struct FramePlanes {
  /** The map plane of each frame plane (-1: none). */
  std::vector<int> map_of_frame;
  /** Whether a planar cuboid gave the frame plane its orientation. */
  std::vector<bool> orientation_known;
  /** The frame planes, unit normals oriented like their cuboids. */
  std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>> oriented;
  /** The map planes the frame touched, sorted. */
  std::vector<int> touched;
};

/** \brief The query index of findCuboid() and castRay(): a copy of the cuboids and a
 * spatial hash of their bounding boxes (built on the first query, freed by
 * integrate()). */
struct CuboidQueryIndex {
  bool valid{false};
  /** The cuboids the index refers to (getCuboids() at the time it was built). */
  PlanarCuboids cuboids;
  /** Spatial index: bin key -> cuboid indices; "large" cuboids are tested always. */
  float bin_m{0.4f};
  std::unordered_map<std::uint64_t, std::vector<std::uint32_t>> bins;
  std::vector<std::uint32_t> large;
  Eigen::Vector3f bounds_min{Eigen::Vector3f::Zero()};
  Eigen::Vector3f bounds_max{Eigen::Vector3f::Zero()};

  /** Frees the index (it is stale). */
  void clear()
  {
    valid = false;
    decltype(cuboids)().swap(cuboids);
    decltype(bins)().swap(bins);
    decltype(large)().swap(large);
  }
};

/** \brief The cuboid of rectangle \a rect of \a plane: the raster frame projected
 * onto the refined plane along its normal (the centre projected, the horizontal axis
 * u projected and normalised, the extents scaled by the projections of u and v,
 * factors within cos(plane_merge_angle_rad) of 1, so that rectangles adjacent in the
 * raster stay adjacent up to a shear of the order of the angle squared), extruded by
 * \a thickness (meters) behind the face; \a r is the cell size, meters. */
PlanarCuboid rectCuboid(const MapPlane& plane,
                        const RasterFrame& frame,
                        const FacePlacement& placement,
                        const RasterRect& rect,
                        int plane_id,
                        double r,
                        float thickness);

} // namespace surface_layer_detail

/** \brief The storage of the surface layer (planes with their rasters and covers,
 * non-planar cells) and its query index. The methods are defined by concern:
 * surface_layer_association.cpp (frame planes to map planes, merging and re-anchoring
 * map planes), surface_layer_non_planar.cpp (the non-planar cells),
 * surface_layer_cover.cpp (the planes' rectangles and the cuboids),
 * surface_layer_query.cpp (findCuboid(), castRay()). */
struct SurfaceLayer::Impl {
  std::vector<surface_layer_detail::MapPlane,
              Eigen::aligned_allocator<surface_layer_detail::MapPlane>>
    planes;
  std::vector<surface_layer_detail::NonPlanarCell> non_planar;
  /** The distinct orientations of the non-planar cells. */
  std::vector<surface_layer_detail::BoxAxes> np_axes;

  /** removeNonPlanarCellsOnPlanes() tests only the non-planar cells that may have come
   * to lie on a plane since its last call: those near the non-planar cells added since
   * (tidy_added, their bounds) or near the cuboids of a plane whose cover was rebuilt
   * since (MapPlane::tidy_pending). Every cell is tested when tidy_all is set: a new,
   * loaded or merged layer, or one that lost a plane (which may have been the first
   * plane holding a cell's centre). */
  bool tidy_all{true};
  Eigen::AlignedBox3f tidy_added;

  /** Guards the lazy builds of the covers and of the query index. */
  std::mutex mutex;
  /** The query index (built under mutex by ensureIndex(), freed by integrate()). */
  surface_layer_detail::CuboidQueryIndex index;

  /** Indices (ascending) of the non-planar cells getCuboids() leaves out as isolated
   * (Params::skip_isolated_non_planar); valid while isolated_valid (built under mutex
   * by ensureIsolated(), reset by invalidate()). */
  std::vector<std::uint32_t> isolated;
  bool isolated_valid{false};

  /** Frees the query index and the isolated cells' list (both are stale). */
  void invalidate()
  {
    index.clear();
    isolated_valid = false;
    std::vector<std::uint32_t>().swap(isolated);
  }
  /** The cuboid of non-planar cell \a cell (plane_id -1; probability and point_count
   * unset). */
  PlanarCuboid nonPlanarCuboid(const surface_layer_detail::NonPlanarCell& cell) const
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
  std::uint32_t
  internAxes(const PlanarCuboid& c,
             std::map<surface_layer_detail::AxesKey, std::uint32_t>& lookup)
  {
    const auto inserted =
      lookup.emplace(surface_layer_detail::axesKey(c.normal, c.horizontal_axis),
                     static_cast<std::uint32_t>(np_axes.size()));
    if (inserted.second)
      np_axes.push_back(surface_layer_detail::BoxAxes{c.normal, c.horizontal_axis});
    return inserted.first->second;
  }
  /** Removes the orientations no cell uses. */
  void pruneAxes();
  /** Removes the planes' observed raster cells for which \a remove(centre of the cell
   * on its refined plane, unit normal) is true, with their evidence and the storage
   * they held; a plane left without cells goes. The caller holds the mutex and
   * invalidates the index. Returns the cells and the planes removed. */
  std::pair<std::size_t, std::size_t> removePlaneCellsIf(
    const std::function<bool(const Eigen::Vector3f&, const Eigen::Vector3f&)>& remove,
    double resolution_m);
  /** Erases the planes left without raster cells (later planes' indices shift down;
   * every non-planar cell is tested again by the next removeNonPlanarCellsOnPlanes())
   * and frees the spare capacity. Returns the planes erased. */
  std::size_t erasePlanesWithoutCells();

  // integrate(), step by step
  /** Orients the frame's planes like their cuboids, and joins each to the map plane
   * that explains its faces together with its own evidence, else to a new one. */
  void associateFramePlanes(const PlanarCuboids& cuboids,
                            const PlaneModels& planes,
                            const Params& params,
                            surface_layer_detail::FramePlanes& frame);
  /** Marks the raster cells of the frame's planar cuboids and refits the touched
   * planes; collects the frame's non-planar cuboids (one per key) in \a incoming. */
  void markFaces(const PlanarCuboids& cuboids,
                 const PlaneModels& planes,
                 const Params& params,
                 const surface_layer_detail::FramePlanes& frame,
                 std::vector<PlanarCuboid>& incoming);
  /** Replaces the stored non-planar cells that \a incoming overlaps and appends
   * \a incoming; \a added receives the indices of the new cells. */
  void replaceNonPlanar(const std::vector<PlanarCuboid>& incoming,
                        const Params& params,
                        std::vector<std::uint32_t>& added);
  /** Adds the features to the touched planes' cells and to the frame's non-planar
   * cells (\a frame_non_planar, sorted and made unique here). */
  void addFeatureEvidence(const pcl::PointCloud<pcl::PointXYZ>& features,
                          const std::vector<float>& probabilities,
                          const Params& params,
                          const std::vector<int>& touched,
                          std::vector<std::uint32_t>& frame_non_planar);
  /** Merges the map planes that converged (a touched plane and any other that one
   * plane explains and whose rasters overlap or touch); \a touched is renumbered. */
  void mergeConvergedPlanes(std::vector<int>& touched, const Params& params);
  /** Gives a new raster frame to a touched plane whose refined normal drifted from
   * its frame's. */
  void reanchorDrifted(const std::vector<int>& touched, const Params& params);

  // merge(), step by step (surface_layer_merge.cpp)
  /** Joins the planes of \a other, moved by \a this_T_other, to this layer's planes
   * (the association of integrate()); \a touched receives the planes that changed,
   * sorted. */
  void mergePlanes(const Impl& other,
                   const Eigen::Isometry3d& this_T_other,
                   const Params& params,
                   std::vector<int>& touched);
  /** Adds the non-planar cells of \a other, moved by \a this_T_other; a cell equal
   * in geometry to a stored one adds its feature evidence to it. */
  void mergeNonPlanar(const Impl& other,
                      const Eigen::Isometry3d& this_T_other,
                      const Params& params);

  /** Moves the planes of fewer than \a min_cells observed raster cells that the
   * frame did not touch (not in \a touched, sorted) to non-planar boxes, one per
   * observed cell with its feature evidence (step 8 of integrate()); the planes go
   * (later planes' indices shift down). 0: none. Returns the planes moved. */
  std::size_t demoteSmallPlanes(const std::vector<int>& touched,
                                const Params& params,
                                std::size_t min_cells);

  /** Rebuilds dirty planes' covers; caller holds the mutex. */
  void ensureCovers(const Params& params);
  /** Appends the cuboids (planes' rectangles, then non-planar cells) to \a out;
   * caller holds the mutex. */
  void buildCuboids(const Params& params, PlanarCuboids& out);
  /** \brief Appends every plane's rectangles (the first part of buildCuboids());
   * caller holds the mutex. */
  void buildPlanarCuboids(const Params& params, PlanarCuboids& out);
  /** Builds the query index over all cuboids; caller holds the mutex. */
  void ensureIndex(const Params& params);
  /** Finds the isolated non-planar cells (Params::skip_isolated_non_planar) unless
   * known; caller holds the mutex. */
  void ensureIsolated(const Params& params);
};

} // namespace planar_grid
