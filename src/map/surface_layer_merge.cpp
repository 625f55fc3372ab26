// SPDX-License-Identifier: BSD-3-Clause
// SurfaceLayer::merge(): the planes and non-planar cells of another layer (another
// recording's map) join this one through the association integrate() uses.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/plane_association.h>
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "map_merge_transform.h"
#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

namespace {

/** \brief Throws planar_grid::Exception naming every parameter in which \a a and \a b
 * differ. */
void
checkSameParams(const SurfaceLayer::Params& a, const SurfaceLayer::Params& b)
{
  using map_merge::difference;
  std::string differences;
  const auto add = [&differences](const std::string& d) {
    if (!d.empty())
      differences += (differences.empty() ? "" : ", ") + d;
  };
  add(difference("resolution_m", a.resolution_m, b.resolution_m, "m"));
  add(difference("thickness_m", a.thickness_m, b.thickness_m, "m"));
  add(difference("plane_merge_angle_rad", a.plane_merge_angle_rad,
                 b.plane_merge_angle_rad, "rad"));
  add(difference("plane_merge_distance_m", a.plane_merge_distance_m,
                 b.plane_merge_distance_m, "m"));
  add(difference("occupancy_thres", a.occupancy_thres, b.occupancy_thres, ""));
  add(
    difference("feature_distance_m", a.feature_distance_m, b.feature_distance_m, "m"));
  add(difference("close_gaps_cells", a.close_gaps_cells, b.close_gaps_cells, "cells"));
  add(difference("merge_rule", toString(a.merge_rule), toString(b.merge_rule), ""));
  add(difference("cover_density", a.cover_density, b.cover_density, ""));
  add(difference("absorb_distance_m", a.absorb_distance_m, b.absorb_distance_m, "m"));
  add(difference("terrain_plane_tile_m", a.terrain_plane_tile_m, b.terrain_plane_tile_m,
                 "m"));
  add(difference("terrain_cover_density", a.terrain_cover_density,
                 b.terrain_cover_density, ""));
  add(difference("min_plane_cells", a.min_plane_cells, b.min_plane_cells, "cells"));
  const auto flag = [](bool on) {
    return std::string(on ? "true" : "false");
  };
  add(difference("skip_isolated_non_planar", flag(a.skip_isolated_non_planar),
                 flag(b.skip_isolated_non_planar), ""));
  if (!differences.empty())
    throw Exception("SurfaceLayer::merge: the layers' parameters must be equal, but "
                    + differences);
}

/** \brief Plane [n, d] (n . x + d = 0) moved by \a t: n' = R n, d' = d - n' . t. */
void
movePlane(const Eigen::Isometry3d& t,
          const Eigen::Vector3f& n,
          float d,
          Eigen::Vector3f& moved_n,
          float& moved_d)
{
  const Eigen::Vector3d rn = (t.linear() * n.cast<double>()).normalized();
  moved_n = rn.cast<float>();
  moved_d = static_cast<float>(static_cast<double>(d) - rn.dot(t.translation()));
}

/** \brief Evidence moments moved by \a t: the anchor moved, the first moments (about
 * the anchor) and the second moments rotated; the weight is unchanged. */
PlaneMoments
moveMoments(const PlaneMoments& m, const Eigen::Isometry3d& t)
{
  PlaneMoments out;
  out.anchor = t * m.anchor;
  out.weight = m.weight;
  out.sum = t.linear() * m.sum;
  out.setSumSq(t.linear() * m.sumSq() * t.linear().transpose());
  return out;
}

/** \brief A plane of the other layer, in this layer's frame: its planes and moments
 * moved, its raster (not copied) with the raster frame it is laid out in, moved. */
struct IncomingPlane {
  /** Frame plane, refined plane and moments moved; no raster. */
  MapPlane plane;
  /** The other layer's raster of the plane. */
  const Raster* raster{nullptr};
  /** The frame \a raster is laid out in, moved into this layer's frame. */
  RasterFrame frame{Eigen::Vector3f::UnitZ(), 0.0f};
  /** The moved frame is the plane's own frame (identity transform): the raster is
   * copied without re-projection. */
  bool exact{false};

  /** The plane with its raster in a raster frame of its own (MapPlane::frame()). */
  MapPlane settle(double r) const
  {
    MapPlane out = plane;
    if (exact)
      out.raster = *raster;
    else
      reprojectRaster(*raster, frame, out, r);
    out.dirty = true;
    return out;
  }
};

/** \brief True when \a a keeps its raster frame when it and \a b become one plane:
 * more evidence (a larger moments weight), and on a tie the frame plane [n, d] that
 * comes first (lexicographically); false for equal frames too. */
bool
survives(const MapPlane& a, const MapPlane& b)
{
  if (a.moments.weight != b.moments.weight)
    return a.moments.weight > b.moments.weight;
  const std::array<float, 4> fa{a.frame_normal.x(), a.frame_normal.y(),
                                a.frame_normal.z(), a.frame_d};
  const std::array<float, 4> fb{b.frame_normal.x(), b.frame_normal.y(),
                                b.frame_normal.z(), b.frame_d};
  return fa < fb;
}

/** \brief Plane \a src of the other layer as this layer sees it, moved by \a t
 * (\a identity: \a t is exactly the identity, nothing is moved). */
IncomingPlane
incomingPlane(const MapPlane& src, const Eigen::Isometry3d& t, bool identity)
{
  IncomingPlane in;
  in.raster = &src.raster;
  in.exact = identity;
  in.frame = src.frame();
  if (identity) {
    // (field by field: the raster is not copied here)
    in.plane.setFrame(src.frame_normal, src.frame_d);
    in.plane.setRefined(src.normal, src.d);
    in.plane.moments = src.moments;
    return in;
  }
  Eigen::Vector3f n;
  float d = 0.0f;
  movePlane(t, src.frame_normal, src.frame_d, n, d);
  in.plane.setFrame(n, d);
  movePlane(t, src.normal, src.d, n, d);
  in.plane.setRefined(n, d);
  in.plane.moments = moveMoments(src.moments, t);
  const Eigen::Matrix3f rotation = t.linear().cast<float>();
  in.frame.origin = (t * in.frame.origin.cast<double>()).cast<float>();
  in.frame.u_axis = rotation * in.frame.u_axis;
  in.frame.v_axis = rotation * in.frame.v_axis;
  return in;
}

} // namespace

void
SurfaceLayer::merge(const SurfaceLayer& other, const Eigen::Isometry3d& this_T_other)
{
  if (&other == this)
    throw Exception("SurfaceLayer::merge: a layer cannot be merged into itself");
  checkSameParams(params_, other.params_);
  map_merge::checkRigid(this_T_other, "SurfaceLayer::merge");
  Impl& impl = *impl_;
  std::vector<int> touched;
  impl.mergePlanes(*other.impl_, this_T_other, params_, touched);
  // Map planes that converged merge and drifted planes take a new raster frame, as
  // after integrate() (surface_layer_association.cpp).
  impl.mergeConvergedPlanes(touched, params_);
  impl.reanchorDrifted(touched, params_);
  impl.mergeNonPlanar(*other.impl_, this_T_other, params_);
  // no spare capacity: the map holds what it uses
  impl.planes.shrink_to_fit();
  impl.invalidate();
}

void
SurfaceLayer::Impl::mergePlanes(const Impl& other,
                                const Eigen::Isometry3d& this_T_other,
                                const Params& params,
                                std::vector<int>& touched)
{
  const double r = params.resolution_m;
  const double cos_angle = std::cos(params.plane_merge_angle_rad);
  const PlaneAssociation association(associationCriteria(params));
  const bool identity = map_merge::isIdentity(this_T_other);
  touched.clear();
  // Each plane of the other layer is matched like a frame's plane in integrate(): the
  // plane of this layer that explains both evidence sets best, searched among the
  // planes added so far too, so that two planes of the other layer on one surface
  // become one here.
  for (const MapPlane& src : other.planes) {
    const IncomingPlane in = incomingPlane(src, this_T_other, identity);
    const std::ptrdiff_t best = findBestMapPlane(
      planes, association, observation(in.plane), params.terrain_plane_tile_m);
    int index = static_cast<int>(best);
    if (best < 0) {
      planes.push_back(in.settle(r));
      index = static_cast<int>(planes.size()) - 1;
    } else {
      // The plane with more evidence keeps its raster frame, as when two map planes
      // converge (on a tie, the one whose frame plane comes first), so that the
      // result is the same whichever layer is merged into which.
      MapPlane& existing = planes[static_cast<std::size_t>(best)];
      if (survives(in.plane, existing)) {
        MapPlane survivor = in.settle(r);
        reprojectRaster(existing.raster, existing.frame(), survivor, r);
        survivor.moments.add(existing.moments);
        existing = std::move(survivor);
      } else {
        reprojectRaster(*in.raster, in.frame, existing, r);
        existing.moments.add(in.plane.moments);
      }
      refitPlane(existing, cos_angle);
      existing.dirty = true;
    }
    if (std::find(touched.begin(), touched.end(), index) == touched.end())
      touched.push_back(index);
  }
  std::sort(touched.begin(), touched.end());
}

void
SurfaceLayer::Impl::mergeNonPlanar(const Impl& other,
                                   const Eigen::Isometry3d& this_T_other,
                                   const Params& params)
{
  tidy_all = true;
  if (other.non_planar.empty())
    return;
  const double r = params.resolution_m;
  const bool identity = map_merge::isIdentity(this_T_other);
  const Eigen::Matrix3f rotation = this_T_other.linear().cast<float>();
  // The stored cells by key (quantised centre and extents), to find equal ones.
  std::unordered_multimap<NonPlanarKey, std::uint32_t, NonPlanarKeyHash> stored;
  stored.reserve(non_planar.size());
  for (std::size_t k = 0; k < non_planar.size(); ++k)
    stored.emplace(nonPlanarKey(nonPlanarCuboid(non_planar[k]), r),
                   static_cast<std::uint32_t>(k));
  std::map<AxesKey, std::uint32_t> axes_lookup;
  for (std::size_t a = 0; a < np_axes.size(); ++a)
    axes_lookup.emplace(axesKey(np_axes[a].normal, np_axes[a].horizontal_axis),
                        static_cast<std::uint32_t>(a));
  const auto same = [](const PlanarCuboid& a, const PlanarCuboid& b) {
    return a.centre == b.centre && a.normal == b.normal
           && a.horizontal_axis == b.horizontal_axis && a.width_m == b.width_m
           && a.height_m == b.height_m && a.thickness_m == b.thickness_m;
  };
  // Two cells of one key (the same quantised centre and size) but another geometry
  // cannot both stay: the layer holds one cell per key, as integration's replacement
  // keeps it and the file reader checks it. The one with more evidence stays (more
  // features, then the larger probability sum, then the smaller geometry), an order
  // that does not depend on which map is merged into which.
  const auto geometry = [](const PlanarCuboid& c) {
    return std::array<float, 12>{c.centre.x(),
                                 c.centre.y(),
                                 c.centre.z(),
                                 c.normal.x(),
                                 c.normal.y(),
                                 c.normal.z(),
                                 c.horizontal_axis.x(),
                                 c.horizontal_axis.y(),
                                 c.horizontal_axis.z(),
                                 c.width_m,
                                 c.height_m,
                                 c.thickness_m};
  };
  const auto stronger = [&geometry](const NonPlanarCell& a, const PlanarCuboid& ca,
                                    const NonPlanarCell& b, const PlanarCuboid& cb) {
    if (a.feature_count != b.feature_count)
      return a.feature_count > b.feature_count;
    if (a.probability_sum != b.probability_sum)
      return a.probability_sum > b.probability_sum;
    return geometry(ca) < geometry(cb);
  };
  bool replaced = false;
  non_planar.reserve(non_planar.size() + other.non_planar.size());
  for (const NonPlanarCell& src : other.non_planar) {
    PlanarCuboid c = other.nonPlanarCuboid(src);
    if (!identity) {
      c.centre = (this_T_other * c.centre.cast<double>()).cast<float>();
      c.normal = (rotation * c.normal).normalized();
      c.horizontal_axis = (rotation * c.horizontal_axis).normalized();
    }
    const auto range = stored.equal_range(nonPlanarKey(c, r));
    bool joined = false;
    for (auto it = range.first; it != range.second && !joined; ++it) {
      NonPlanarCell& cell = non_planar[it->second];
      const PlanarCuboid kept = nonPlanarCuboid(cell);
      if (same(kept, c)) {
        cell.probability_sum += src.probability_sum;
        cell.feature_count += src.feature_count;
      } else if (!stronger(cell, kept, src, c)) {
        NonPlanarCell moved(c, internAxes(c, axes_lookup));
        moved.probability_sum = src.probability_sum;
        moved.feature_count = src.feature_count;
        cell = moved;
        replaced = true;
      }
      joined = true;
    }
    if (joined)
      continue;
    NonPlanarCell cell(c, internAxes(c, axes_lookup));
    cell.probability_sum = src.probability_sum;
    cell.feature_count = src.feature_count;
    non_planar.push_back(cell);
  }
  if (replaced)
    pruneAxes(); // the orientations only the replaced cells had
  non_planar.shrink_to_fit();
}

} // namespace planar_grid
