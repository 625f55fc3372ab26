// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's codec: serialize(), deserialize() (validating) and equality.
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

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
  w.put(params_.absorb_distance_m);
  w.put(params_.terrain_plane_tile_m);
  w.put(params_.terrain_cover_density);
  w.put(static_cast<std::uint8_t>(params_.skip_isolated_non_planar ? 1 : 0));
  w.put(static_cast<std::uint32_t>(params_.min_plane_cells));
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
      w.put(rasterCellI(key));
      w.put(rasterCellJ(key));
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

/** \brief The parameters of a section of \a version (2 to VERSION), the fields older
 * versions lack at the values those versions behaved with. */
SurfaceLayer::Params
readParams(ByteReader& rd, std::uint32_t version)
{
  SurfaceLayer::Params params;
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
  // versions 2 and 3 moved cells to parallel planes only within half a cell
  params.absorb_distance_m = version >= 4 ? rd.get<double>() : 0.0;
  // versions 2 to 4 bounded no level plane to a tile
  params.terrain_plane_tile_m = version >= 5 ? rd.get<double>() : 0.0;
  // versions 2 to 5 covered the level planes at cover_density
  params.terrain_cover_density = version >= 6 ? rd.get<double>() : params.cover_density;
  // versions 2 to 6 reported every non-planar cell
  params.skip_isolated_non_planar = false;
  if (version >= 7) {
    const auto skip = rd.get<std::uint8_t>();
    if (skip > 1)
      throw IOError("surface layer: skip_isolated_non_planar " + std::to_string(skip)
                    + " is neither 0 nor 1");
    params.skip_isolated_non_planar = skip == 1;
  }
  // versions 2 to 7 demoted no plane; the range is validate()'s
  params.min_plane_cells =
    version >= 8 ? static_cast<int>(std::min<std::uint32_t>(
      rd.get<std::uint32_t>(), std::numeric_limits<std::int32_t>::max()))
                 : 0;
  return params;
}

/** \brief Plane \a p: its frame and refined plane (within \a cos_angle of each other),
 * its evidence moments and its raster's cells (sorted, unique, in range). */
MapPlane
readPlane(ByteReader& rd, std::size_t p, double cos_angle)
{
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
    const std::uint64_t key = rasterCellKey(i, j);
    if (!keys.empty() && !(key > keys.back()))
      throw IOError(which + ": cells not sorted or duplicated");
    checkSum(sum, count, "cell");
    keys.push_back(key);
    sums.push_back(sum);
    counts.push_back(count);
  }
  mp.raster.assign(keys, sums, counts);
  return mp;
}

/** \brief Non-planar cell \a k's box and evidence (finite, unit orthogonal axes,
 * extents in range). */
void
readNonPlanarCell(ByteReader& rd,
                  std::size_t k,
                  PlanarCuboid& c,
                  double& probability_sum,
                  std::uint32_t& feature_count)
{
  for (int a = 0; a < 3; ++a)
    c.centre[a] = rd.get<float>();
  for (int a = 0; a < 3; ++a)
    c.normal[a] = rd.get<float>();
  for (int a = 0; a < 3; ++a)
    c.horizontal_axis[a] = rd.get<float>();
  c.width_m = rd.get<float>();
  c.height_m = rd.get<float>();
  c.thickness_m = rd.get<float>();
  probability_sum = rd.get<double>();
  feature_count = rd.get<std::uint32_t>();
  const auto extent_ok = [](float e) {
    return std::isfinite(e) && e >= 0.0f && e <= MAX_COORDINATE_M;
  };
  if (!finiteVector(c.centre) || !unitVector(c.normal) || !unitVector(c.horizontal_axis)
      || std::abs(c.normal.dot(c.horizontal_axis)) > 1e-3f || !extent_ok(c.width_m)
      || !extent_ok(c.height_m) || !extent_ok(c.thickness_m))
    throw IOError("surface layer: non-planar cell " + std::to_string(k)
                  + " has invalid geometry");
  checkSum(probability_sum, feature_count, "non-planar cell");
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
                  "(versions 2 to "
                  + std::to_string(VERSION) + "); run the mapping again");
  if (version < 2 || version > VERSION)
    throw IOError("surface layer: unsupported version " + std::to_string(version));
  const Params params = readParams(rd, version);
  try {
    validate(params);
  } catch (const Exception& e) {
    throw IOError(std::string("surface layer: ") + e.what());
  }
  const double cos_angle = std::cos(params.plane_merge_angle_rad);
  auto impl = std::make_unique<Impl>();
  const std::size_t plane_count = rd.getCount(PLANE_BYTES, "plane");
  impl->planes.reserve(plane_count);
  for (std::size_t p = 0; p < plane_count; ++p)
    impl->planes.push_back(readPlane(rd, p, cos_angle));
  const std::size_t non_planar_count = rd.getCount(NON_PLANAR_BYTES, "non-planar cell");
  std::unordered_map<NonPlanarKey, std::uint32_t, NonPlanarKeyHash> non_planar_keys;
  impl->non_planar.reserve(non_planar_count);
  std::map<AxesKey, std::uint32_t> axes_lookup;
  for (std::size_t k = 0; k < non_planar_count; ++k) {
    PlanarCuboid c;
    double probability_sum = 0.0;
    std::uint32_t feature_count = 0;
    readNonPlanarCell(rd, k, c, probability_sum, feature_count);
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

bool
SurfaceLayer::operator==(const SurfaceLayer& other) const
{
  const Params& a = params_;
  const Params& b = other.params_;
  if (a.resolution_m != b.resolution_m || a.thickness_m != b.thickness_m
      || a.plane_merge_angle_rad != b.plane_merge_angle_rad
      || a.plane_merge_distance_m != b.plane_merge_distance_m
      || a.absorb_distance_m != b.absorb_distance_m
      || a.terrain_plane_tile_m != b.terrain_plane_tile_m
      || a.occupancy_thres != b.occupancy_thres
      || a.feature_distance_m != b.feature_distance_m
      || a.close_gaps_cells != b.close_gaps_cells || a.merge_rule != b.merge_rule
      || a.cover_density != b.cover_density
      || a.terrain_cover_density != b.terrain_cover_density
      || a.skip_isolated_non_planar != b.skip_isolated_non_planar
      || a.min_plane_cells != b.min_plane_cells)
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

} // namespace planar_grid
