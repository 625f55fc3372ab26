// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

namespace surface_layer_detail {

/** \brief Validates parameters; throws planar_grid::Exception. */
void
validate(const SurfaceLayer::Params& p)
{
  namespace ranges = surface_layer_ranges;
  const auto check = [](const char* name, double value, const ParamRange& range,
                        const char* unit) {
    if (!range.contains(value))
      throw Exception("SurfaceLayer: invalid parameter "
                      + paramRangeMessage(name, range, unit) + ", got "
                      + formatParamNumber(value));
  };
  check("resolution_m", p.resolution_m, ranges::RESOLUTION, "m");
  check("thickness_m", p.thickness_m, ranges::THICKNESS, "m");
  check("plane_merge_angle_rad", p.plane_merge_angle_rad, ranges::PLANE_MERGE_ANGLE,
        "rad");
  check("plane_merge_distance_m", p.plane_merge_distance_m,
        ranges::PLANE_MERGE_DISTANCE, "m");
  check("occupancy_thres", p.occupancy_thres, ranges::OCCUPANCY_THRES, "");
  check("feature_distance_m", p.feature_distance_m, ranges::FEATURE_DISTANCE, "m");
  check("close_gaps_cells", p.close_gaps_cells, ranges::CLOSE_GAPS, "cells");
  if (p.merge_rule != SurfaceMergeRule::PAPER
      && p.merge_rule != SurfaceMergeRule::MIN_RECTANGLES
      && p.merge_rule != SurfaceMergeRule::DENSITY)
    throw Exception(
      "SurfaceLayer: invalid parameter merge_rule (must be paper, min_rectangles or "
      "density)");
  check("cover_density", p.cover_density, ranges::COVER_DENSITY, "");
  check("absorb_distance_m", p.absorb_distance_m, ranges::ABSORB_DISTANCE, "m");
  check("terrain_plane_tile_m", p.terrain_plane_tile_m, ranges::TERRAIN_PLANE_TILE,
        "m");
  check("terrain_cover_density", p.terrain_cover_density, ranges::TERRAIN_COVER_DENSITY,
        "");
  check("min_plane_cells", p.min_plane_cells, ranges::MIN_PLANE_CELLS, "cells");
}

} // namespace surface_layer_detail

using namespace surface_layer_detail;

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
  // 1.-3. Frame planes -> map planes (surface_layer_association.cpp).
  FramePlanes frame;
  impl.associateFramePlanes(cuboids, planes, params_, frame);
  // 4. The planar cuboids' cells join the rasters; the non-planar ones are collected.
  std::vector<PlanarCuboid> incoming;
  impl.markFaces(cuboids, planes, params_, frame, incoming);
  // 4b. Non-planar replacement (surface_layer_non_planar.cpp).
  std::vector<std::uint32_t> frame_non_planar;
  impl.replaceNonPlanar(incoming, params_, frame_non_planar);
  // 5. Features.
  impl.addFeatureEvidence(features, probabilities, params_, frame.touched,
                          frame_non_planar);
  // 6. Map planes that converged merge; 7. drifted planes take a new raster frame.
  impl.mergeConvergedPlanes(frame.touched, params_);
  impl.reanchorDrifted(frame.touched, params_);
  // 8. Small planes the frame did not see become non-planar boxes.
  impl.demoteSmallPlanes(frame.touched, params_,
                         static_cast<std::size_t>(params_.min_plane_cells));
  // no spare capacity: the map holds what it uses
  impl.planes.shrink_to_fit();
  impl.invalidate();
}

void
SurfaceLayer::Impl::markFaces(const PlanarCuboids& cuboids,
                              const PlaneModels& planes,
                              const Params& params,
                              const FramePlanes& frame,
                              std::vector<PlanarCuboid>& incoming)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  const double inv_r = 1.0 / r;
  const float tol = static_cast<float>(0.01 * r);
  const double cos_angle = std::cos(params.plane_merge_angle_rad);
  // 4. Planar cuboids mark the map plane's cells whose centres fall inside the face.
  // Non-planar cuboids replace the cell with the same key.
  std::vector<std::vector<std::uint64_t>> marked(impl.planes.size());
  std::unordered_map<NonPlanarKey, std::size_t, NonPlanarKeyHash> frame_keys;
  bool skipped = false;
  for (const PlanarCuboid& c : cuboids) {
    if (!validGeometry(c)) {
      skipped = true;
      continue;
    }
    const bool planar =
      c.is_planar && c.plane_id >= 0
      && static_cast<std::size_t>(c.plane_id) < planes.size()
      && frame.orientation_known[static_cast<std::size_t>(c.plane_id)];
    if (planar && frame.map_of_frame[static_cast<std::size_t>(c.plane_id)] < 0) {
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
    const auto m = static_cast<std::size_t>(
      frame.map_of_frame[static_cast<std::size_t>(c.plane_id)]);
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
          marked[m].push_back(rasterCellKey(i, j));
      }
    }
  }
  if (skipped)
    PCL_WARN("[planar_grid::SurfaceLayer::integrate] Skipped cuboids with non-finite "
             "or absurd (> 1e7 m or > 1e7 cells) geometry.\n");
  // The marked cells join the rasters, and the touched planes are refitted to their
  // evidence.
  for (const int t : frame.touched) {
    MapPlane& mp = impl.planes[static_cast<std::size_t>(t)];
    std::vector<std::uint64_t>& keys = marked[static_cast<std::size_t>(t)];
    mp.raster.insert(keys);
    std::vector<std::uint64_t>().swap(keys);
    refitPlane(mp, cos_angle);
    mp.dirty = true;
  }
}

void
SurfaceLayer::Impl::addFeatureEvidence(const pcl::PointCloud<pcl::PointXYZ>& features,
                                       const std::vector<float>& probabilities,
                                       const Params& params,
                                       const std::vector<int>& touched,
                                       std::vector<std::uint32_t>& frame_non_planar)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  const double inv_r = 1.0 / r;
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
    for (const auto index : frame_non_planar)
      if (!forEachBin(
            impl.nonPlanarCuboid(impl.non_planar[index]), 0.0f, bin,
            [&bins, index](std::uint64_t key) { bins[key].push_back(index); }))
        large.push_back(index);
    const float feature_distance = static_cast<float>(params.feature_distance_m);
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
          rasterCellKey(static_cast<std::int32_t>(i), static_cast<std::int32_t>(j)),
          prob, 1});
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
  impl_->ensureIsolated(params_);
  std::size_t n = impl_->non_planar.size() - impl_->isolated.size();
  for (const auto& plane : impl_->planes)
    n += plane.rects.size();
  return n;
}

std::size_t
SurfaceLayer::getRasterCellCount() const
{
  std::size_t n = 0;
  for (const auto& plane : impl_->planes)
    n += plane.raster.size();
  return n;
}

std::size_t
SurfaceLayer::getPlaneCount() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  return impl_->planes.size();
}

PlaneModels
SurfaceLayer::getPlanes() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  PlaneModels models;
  models.reserve(impl_->planes.size());
  for (const auto& plane : impl_->planes)
    models.emplace_back(plane.normal.x(), plane.normal.y(), plane.normal.z(), plane.d);
  return models;
}

std::size_t
SurfaceLayer::getCellCount() const
{
  return getRasterCellCount() + impl_->non_planar.size();
}

std::size_t
SurfaceLayer::getMemoryBytes() const
{
  std::lock_guard<std::mutex> lock(impl_->mutex);
  const Impl& impl = *impl_;
  std::size_t bytes = sizeof(SurfaceLayer) + sizeof(Impl);
  bytes += vectorBytes(impl.planes);
  for (const auto& plane : impl.planes)
    bytes += plane.raster.bytes() + vectorBytes(plane.rects);
  bytes += vectorBytes(impl.non_planar) + vectorBytes(impl.np_axes)
           + vectorBytes(impl.isolated);
  bytes += vectorBytes(impl.index.cuboids) + hashMapBytes(impl.index.bins)
           + vectorBytes(impl.index.large);
  for (const auto& kv : impl.index.bins)
    bytes += vectorBytes(kv.second);
  return bytes;
}

SurfaceMergeRule
surfaceMergeRuleFromString(const std::string& name)
{
  return rectangleMergeRuleFromString(name);
}

} // namespace planar_grid
