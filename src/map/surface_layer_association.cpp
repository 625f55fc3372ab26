// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's plane association: frame planes join map planes (the shared
// PlaneAssociation with the evidence criteria), map planes that converged merge, and
// drifted planes take a new raster frame.
#include <planar_grid/map/plane_association.h>
#include <planar_grid/map/surface_layer.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

namespace surface_layer_detail {

/** \brief Refits the plane of \a plane from its moments (kept when the fit fails). */
void
refitPlane(MapPlane& plane, double cos_angle)
{
  Eigen::Vector3d n;
  double d = 0.0;
  if (fitPlane(plane.moments, plane.normal, cos_angle, n, d))
    plane.setRefined(n.cast<float>().normalized(), static_cast<float>(d));
}

PlaneAssociationCriteria
associationCriteria(const SurfaceLayer::Params& params)
{
  PlaneAssociationCriteria criteria;
  criteria.eps_angle_rad = params.plane_merge_angle_rad;
  criteria.distance_threshold_m = params.plane_merge_distance_m;
  criteria.orientation = PlaneOrientation::SAME;
  criteria.distance = PlaneDistance::EVIDENCE_RMS;
  return criteria;
}

PlaneObservation
observation(const MapPlane& plane)
{
  return PlaneObservation{
    Eigen::Vector4f(plane.normal.x(), plane.normal.y(), plane.normal.z(), plane.d),
    &plane.moments};
}

void
reprojectRaster(const Raster& src,
                const RasterFrame& src_frame,
                MapPlane& dst,
                double r)
{
  const double inv_r = 1.0 / r;
  const RasterFrame dst_frame = dst.frame();
  std::vector<std::uint64_t> keys;
  std::vector<CellEvidence> evidence;
  src.forEachCell([&](std::uint64_t src_key, float sum, std::uint16_t count) {
    const std::int64_t i = rasterCellI(src_key), j = rasterCellJ(src_key);
    const Eigen::Vector2d f = dst_frame.toRaster(src_frame.cellCentre(i, j, r), inv_r);
    std::int64_t ci = 0, cj = 0;
    if (!cellIndex(f.x(), ci) || !cellIndex(f.y(), cj))
      return;
    const std::uint64_t key =
      rasterCellKey(static_cast<std::int32_t>(ci), static_cast<std::int32_t>(cj));
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
            rasterCellKey(static_cast<std::int32_t>(a), static_cast<std::int32_t>(b)));
      }
  });
  dst.raster.insert(keys);
  dst.raster.addEvidence(evidence);
  dst.dirty = true;
}

bool
sameTerrainTile(double tile_m, const PlaneObservation& a, const PlaneObservation& b)
{
  if (!(tile_m > 0.0) || a.evidence == nullptr || b.evidence == nullptr
      || !(a.evidence->weight > 0.0) || !(b.evidence->weight > 0.0)
      || !isLevel(a.model_coefficients.z()) || !isLevel(b.model_coefficients.z()))
    return true;
  const PlaneMoments& ma = *a.evidence;
  const PlaneMoments& mb = *b.evidence;
  const Eigen::Vector3d ca = ma.anchor + ma.sum / ma.weight;
  const Eigen::Vector3d cb = mb.anchor + mb.sum / mb.weight;
  return std::floor(ca.x() / tile_m) == std::floor(cb.x() / tile_m)
         && std::floor(ca.y() / tile_m) == std::floor(cb.y() / tile_m);
}

} // namespace surface_layer_detail

using namespace surface_layer_detail;

namespace {

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
    const Eigen::Vector2d f = big_frame.toRaster(
      small_frame.cellCentre(rasterCellI(key), rasterCellJ(key), r), inv_r);
    std::int64_t ci = 0, cj = 0;
    if (!cellIndex(f.x(), ci) || !cellIndex(f.y(), cj))
      continue;
    for (std::int64_t dj = -1; dj <= 1; ++dj)
      for (std::int64_t di = -1; di <= 1; ++di) {
        const std::int64_t x = ci + di, y = cj + dj;
        if (std::abs(x) <= MAX_CELL_INDEX && std::abs(y) <= MAX_CELL_INDEX
            && big.raster.contains(rasterCellKey(static_cast<std::int32_t>(x),
                                                 static_cast<std::int32_t>(y))))
          return true;
      }
  }
  return false;
}

/** \brief Smallest share of the smaller plane's observed cells lying over the other
 * plane's observed cells, within the absorb distance of it, for two parallel planes to
 * be one surface mapped twice (mergeConvergedPlanes()). */
constexpr double STACKED_MIN_OVERLAP_SHARE = 0.25;

/** \brief Smallest ratio of the weaker plane's evidence (moments weight) to the
 * stronger's for two stacked planes to merge: two estimates of one surface. A small
 * plane in front of a well-observed one (an object before a wall, or a fragment) is
 * left to absorbOverlappingPlaneCells(), which moves only the cells lying on the
 * other plane. */
constexpr double STACKED_MIN_WEIGHT_RATIO = 0.25;

/** \brief True when \a a and \a b, parallel (normals within the cosine \a
 * cos_parallel, facing the same way) and of comparable evidence (the weaker's weight at
 * least STACKED_MIN_WEIGHT_RATIO of the stronger's), are one surface mapped as two
 * planes a little apart: at least STACKED_MIN_OVERLAP_SHARE of the smaller raster's
 * observed cells, placed on their own refined plane, lie within \a max_gap_m of the
 * other's refined plane and project into an observed cell of it. Two level planes are
 * never stacked (a step, a curb is real). */
bool
stackedPlanes(const MapPlane& a,
              const MapPlane& b,
              double r,
              double cos_parallel,
              double max_gap_m)
{
  const double weak = std::min(a.moments.weight, b.moments.weight);
  const double strong = std::max(a.moments.weight, b.moments.weight);
  if (a.raster.empty() || b.raster.empty()
      || !(weak >= STACKED_MIN_WEIGHT_RATIO * strong)
      || static_cast<double>(a.normal.dot(b.normal)) < cos_parallel
      || (isLevel(a.normal.z()) && isLevel(b.normal.z())))
    return false;
  const MapPlane& small = a.raster.size() <= b.raster.size() ? a : b;
  const MapPlane& big = &small == &a ? b : a;
  const RasterFrame small_frame = small.frame(), big_frame = big.frame();
  const float along = small.normal.dot(small.frame_normal);
  if (!(along > 0.5f))
    return false;
  const double inv_r = 1.0 / r;
  const std::size_t n = small.raster.size();
  const auto needed = static_cast<std::size_t>(
    std::ceil(STACKED_MIN_OVERLAP_SHARE * static_cast<double>(n)));
  std::size_t over = 0, seen = 0;
  for (const auto key : small.raster.keys()) {
    ++seen;
    Eigen::Vector3f p = small_frame.cellCentre(rasterCellI(key), rasterCellJ(key), r);
    p -= small.frame_normal * ((small.normal.dot(p) + small.d) / along);
    if (std::abs(static_cast<double>(big.normal.dot(p) + big.d)) <= max_gap_m) {
      const Eigen::Vector2d f = big_frame.toRaster(p, inv_r);
      std::int64_t ci = 0, cj = 0;
      if (cellIndex(f.x(), ci) && cellIndex(f.y(), cj)
          && big.raster.contains(
            rasterCellKey(static_cast<std::int32_t>(ci), static_cast<std::int32_t>(cj)))
          && ++over >= needed)
        return true;
    }
    if (over + (n - seen) < needed)
      return false;
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
  reprojectRaster(plane.raster, plane.frame(), fresh, r);
  plane = std::move(fresh);
}

} // namespace

void
SurfaceLayer::Impl::associateFramePlanes(const PlanarCuboids& cuboids,
                                         const PlaneModels& planes,
                                         const Params& params,
                                         FramePlanes& frame)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  // a face of zero area still counts, as a point
  const double min_face_weight = 1e-6 * r * r;
  const PlaneAssociation association(associationCriteria(params));

  // 1. Frame planes, oriented like the frame's cuboids (toward its sensor).
  std::vector<int>& map_of_frame = frame.map_of_frame;
  std::vector<bool>& orientation_known = frame.orientation_known;
  auto& oriented = frame.oriented;
  map_of_frame.assign(planes.size(), -1);
  orientation_known.assign(planes.size(), false);
  oriented.resize(planes.size());
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
        && orientation_known[static_cast<std::size_t>(c.plane_id)] && usableFace(c, r))
      frame_moments[static_cast<std::size_t>(c.plane_id)].addFace(c, min_face_weight);

  // 3. Frame plane -> map plane: the map plane that explains the frame's faces best
  //    together with its own evidence (SurfaceLayer's documentation), else a new one.
  //    The frame's moments join the map plane at once, so that a second frame plane of
  //    the same surface is tested against them.
  std::vector<int>& touched = frame.touched;
  touched.clear();
  for (std::size_t p = 0; p < planes.size(); ++p) {
    if (!orientation_known[p] || !(frame_moments[p].weight > 0.0))
      continue;
    const Eigen::Vector3f n = oriented[p].head<3>();
    const float d = oriented[p][3];
    int best = static_cast<int>(findBestMapPlane(
      impl.planes, association,
      PlaneObservation{Eigen::Vector4f(n.x(), n.y(), n.z(), d), &frame_moments[p]},
      params.terrain_plane_tile_m));
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
}

void
SurfaceLayer::Impl::mergeConvergedPlanes(std::vector<int>& touched,
                                         const Params& params)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  const double cos_angle = std::cos(params.plane_merge_angle_rad);
  const double max_gap = std::max(0.5 * r, params.absorb_distance_m);
  const PlaneAssociation association(associationCriteria(params));
  // 6. Map planes that converged merge (SurfaceLayer's documentation): a touched plane
  // and any other that one plane explains and whose rasters overlap or touch, or that
  // lies stacked over it (one surface mapped twice a little apart). The plane
  // with more evidence survives (lower index on a tie). Each merge removes a plane, so
  // this ends.
  for (bool merged = true; merged;) {
    merged = false;
    for (std::size_t ti = 0; ti < touched.size() && !merged; ++ti) {
      const auto t = static_cast<std::size_t>(touched[ti]);
      for (std::size_t m = 0; m < impl.planes.size() && !merged; ++m) {
        const MapPlane& a = impl.planes[t];
        const MapPlane& b = impl.planes[m];
        double rms = 0.0;
        if (m == t
            || !sameTerrainTile(params.terrain_plane_tile_m, observation(a),
                                observation(b)))
          continue;
        const bool converged = association.match(observation(a), observation(b), rms)
                               && rastersTouch(a, b, r);
        if (!converged && !stackedPlanes(a, b, r, cos_angle, max_gap))
          continue;
        std::size_t keep = t, gone = m;
        if (b.moments.weight > a.moments.weight
            || (b.moments.weight == a.moments.weight && m < t))
          std::swap(keep, gone);
        MapPlane& survivor = impl.planes[keep];
        reprojectRaster(impl.planes[gone].raster, impl.planes[gone].frame(), survivor,
                        r);
        survivor.moments.add(impl.planes[gone].moments);
        refitPlane(survivor, cos_angle);
        impl.planes.erase(impl.planes.begin() + static_cast<std::ptrdiff_t>(gone));
        impl.tidy_all = true;
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
}

void
SurfaceLayer::Impl::reanchorDrifted(const std::vector<int>& touched,
                                    const Params& params)
{
  Impl& impl = *this;
  const double r = params.resolution_m;
  // 7. A refined normal that drifted from its raster frame's takes a new frame.
  const double cos_reanchor = std::cos(0.5 * params.plane_merge_angle_rad);
  for (const int t : touched) {
    MapPlane& mp = impl.planes[static_cast<std::size_t>(t)];
    if (mp.normal.dot(mp.frame_normal) < cos_reanchor)
      reanchor(mp, r);
  }
}

} // namespace planar_grid
