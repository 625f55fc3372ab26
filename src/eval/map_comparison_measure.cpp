// SPDX-License-Identifier: BSD-3-Clause
// The measurement of one lane of the map comparison: SG's, OG's, RA's and PG's rows
// (error, completeness, planar share, plane precision) against the ground truth, over
// the whole map or a place.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <octomap/octomap.h>

#include <chrono>
#include <memory>
#include <utility>
#include <vector>

#include "map_comparison_lane.h"

namespace planar_grid {
namespace detail {

namespace {

/** What one measurement of a lane compares against: the truth, its voxels at the
 * lane's cell size, the mapped views, the tolerance, and the region (null: the whole
 * map; the completeness then counts every truth voxel). */
struct LaneTruth {
  const GroundTruthSurface& truth;
  const TruthVoxels& voxels;
  const MappedViews& mapped;
  double tolerance_m;
  const MappingErrorRegion* region;
  const MappingErrorRegion& truth_region;
};

/** \brief The error figures of \a e in \a row (and, in a region, its cell count). */
void
applyError(ComparisonRow& row, const MappingError& e, const LaneTruth& t)
{
  row.samples = e.samples;
  row.erroneous = e.erroneous;
  row.own_error = e.ownError();
  if (t.region)
    row.cells = e.cells;
}

/** \brief The completeness figures of \a c in \a row. SG's, OG's and RA's maps are
 * their occupied cells alone: the whole map's completeness is theirs; PG's is
 * measured on both layers apart. */
void
applyCompleteness(ComparisonRow& row, const Completeness& c, const LaneTruth& t)
{
  row.truth_voxels = c.truth_voxels;
  row.covered_voxels = c.covered;
  row.completeness = c.ratio();
  row.map_covered_voxels = c.covered;
  row.map_completeness = c.ratio();
  row.nonground_voxels = c.nonground_voxels;
  row.nonground_covered_voxels = c.nonground_covered;
  row.nonground_completeness = c.nongroundRatio();
  row.mapped_range_m = t.mapped.max_depth_m;
  row.range_nonground_voxels = c.range_nonground_voxels;
  row.range_nonground_covered_voxels = c.range_nonground_covered;
  row.range_nonground_completeness = c.rangeNongroundRatio();
}

/** \brief The truth voxels of \a lane at its cell size, their mapped range grown
 * with the views mapped since the last measurement. */
const TruthVoxels&
laneTruthVoxels(Lane& lane, const GroundTruthSurface& truth, const MappedViews& mapped)
{
  if (!lane.truth_voxels) {
    lane.truth_voxels = std::make_unique<TruthVoxels>(truth, lane.resolution_m);
    lane.truth_voxels->setMappedRange(mapped.max_depth_m);
  }
  for (; lane.views_added < mapped.views.size(); ++lane.views_added)
    lane.truth_voxels->addView(mapped.views[lane.views_added]);
  return *lane.truth_voxels;
}

/** \brief The completeness \a evaluate() gives, in \a row; its time goes to the
 * lane's completeness time, apart from the method's. */
template <typename Evaluate>
void
addCompleteness(Lane& lane, ComparisonRow& row, const LaneTruth& t, Evaluate&& evaluate)
{
  const auto start = std::chrono::steady_clock::now();
  applyCompleteness(row, evaluate(), t);
  lane.completeness_ms += msSince(start);
}

/** \brief SG's row: its occupied voxels. */
ComparisonRow
measureSG(Lane& lane, const ComparisonRow& base, double ms, const LaneTruth& t)
{
  ComparisonRow sg = base;
  sg.method = "SG";
  sg.cells = lane.sg->getOccupiedCount();
  sg.all_cells = lane.sg->getVoxelCount();
  sg.memory_bytes = lane.sg->getMemoryBytes();
  sg.ms_per_frame = ms;
  applyError(sg,
             t.region ? evaluateVoxels(*lane.sg, t.truth, t.tolerance_m, *t.region)
                      : evaluateVoxels(*lane.sg, t.truth, t.tolerance_m),
             t);
  addCompleteness(lane, sg, t, [&] {
    return evaluateCompleteness(*lane.sg, t.voxels, t.tolerance_m, t.truth_region);
  });
  return sg;
}

/** \brief OG's row: OctoMap's occupied leaves after pruning. */
ComparisonRow
measureOG(Lane& lane, const ComparisonRow& base, double ms, const LaneTruth& t)
{
  ComparisonRow og = base;
  og.method = "OG";
  lane.og->prune();
  for (auto it = lane.og->begin_leafs(); it != lane.og->end_leafs(); ++it) {
    ++og.all_cells;
    og.cells += lane.og->isNodeOccupied(*it);
  }
  og.memory_bytes = lane.og->memoryUsage();
  og.ms_per_frame = ms;
  applyError(og,
             t.region ? evaluateOcTree(*lane.og, t.truth, t.tolerance_m, *t.region)
                      : evaluateOcTree(*lane.og, t.truth, t.tolerance_m),
             t);
  addCompleteness(lane, og, t, [&] {
    return evaluateCompleteness(*lane.og, t.voxels, t.tolerance_m, t.truth_region);
  });
  return og;
}

/** \brief RA's row: SG's voxels merged into boxes here; its time is SG's plus the
 * merge's spread over \a ra_divisor frames. */
ComparisonRow
measureRA(Lane& lane,
          const ComparisonRow& base,
          double sg_ms,
          double ra_divisor,
          const LaneTruth& t)
{
  using Clock = std::chrono::steady_clock;
  const double r = lane.resolution_m;
  ComparisonRow ra = base;
  ra.method = "RA";
  AxisAlignedBoxes boxes;
  const auto merge_start = Clock::now();
  RectangularCuboidApproximation().compute(*lane.sg, boxes);
  ra.ms_per_frame = sg_ms + msSince(merge_start) / ra_divisor;
  for (const auto& b : boxes)
    ra.cells += b.occupied;
  ra.all_cells = boxes.size();
  ra.memory_bytes = RectangularCuboidApproximation::getMemoryBytes(boxes);
  applyError(ra,
             t.region ? evaluateBoxes(boxes, r, t.truth, t.tolerance_m, *t.region)
                      : evaluateBoxes(boxes, r, t.truth, t.tolerance_m),
             t);
  addCompleteness(lane, ra, t, [&] {
    return evaluateCompleteness(boxes, r, t.voxels, t.tolerance_m, t.truth_region);
  });
  return ra;
}

/** \brief PG's row: its occupied cuboids' error (and its planar ones' apart), the
 * completeness of its cuboids and of its whole map, the planar share and the plane
 * precision. \a planar_counts gets its planar cuboids (count, occupied). */
ComparisonRow
measurePG(Lane& lane,
          const ComparisonRow& base,
          double ms,
          const LaneTruth& t,
          std::pair<std::size_t, std::size_t>& planar_counts)
{
  using Clock = std::chrono::steady_clock;
  const double r = lane.resolution_m;
  ComparisonRow pg = base;
  pg.method = "PG";
  pg.ms_per_frame = ms;
  if (!lane.pipeline->state().map)
    throw Exception("dataset " + base.dataset
                    + ": the pipeline has no map_integration stage (PG is its map)");
  const PlanarGridMap& map = *lane.pipeline->state().map;
  const PlanarCuboids& cuboids = map.getSurfaceLayer().getCuboids();
  const double thres = map.getParams().surface.occupancy_thres;
  for (const auto& c : cuboids)
    pg.cells += c.probability >= thres;
  pg.all_cells = cuboids.size();
  pg.memory_bytes = map.getMemory().total_bytes;
  applyError(pg,
             t.region
               ? evaluateCuboids(cuboids, thres, r, t.truth, t.tolerance_m, *t.region)
               : evaluateCuboids(cuboids, thres, r, t.truth, t.tolerance_m),
             t);
  PlanarCuboids planar;
  planar_counts = {0, 0};
  for (const auto& c : cuboids)
    if (c.is_planar) {
      planar.push_back(c);
      planar_counts.second += c.probability >= thres;
    }
  planar_counts.first = planar.size();
  const MappingError planar_error =
    t.region ? evaluateCuboids(planar, thres, r, t.truth, t.tolerance_m, *t.region)
             : evaluateCuboids(planar, thres, r, t.truth, t.tolerance_m);
  pg.planar_samples = planar_error.samples;
  pg.planar_erroneous = planar_error.erroneous;
  const auto completeness_start = Clock::now();
  applyCompleteness(
    pg, evaluateCompleteness(cuboids, thres, t.voxels, t.tolerance_m, t.truth_region),
    t);
  const Completeness planar_share =
    evaluatePlanarShare(cuboids, thres, t.voxels, t.tolerance_m, t.truth_region);
  pg.planar_covered_voxels = planar_share.covered;
  pg.planar_share = planar_share.ratio();
  pg.range_planar_covered_voxels = planar_share.range_nonground_covered;
  pg.range_planar_share = planar_share.rangeNongroundRatio();
  const Completeness whole_map =
    evaluateMapCompleteness(map, t.voxels, t.tolerance_m, t.truth_region);
  pg.map_covered_voxels = whole_map.covered;
  pg.map_completeness = whole_map.ratio();
  lane.completeness_ms += msSince(completeness_start);
  const auto precision_start = Clock::now();
  const PlanePrecision precision =
    evaluatePlanePrecision(cuboids, thres, r, t.truth, t.truth_region);
  pg.plane_area_m2 = precision.face_area_m2;
  pg.plane_precision = precision.ratio();
  if (precision.face_area_m2 > 0.0) {
    pg.plane_no_truth_share = precision.no_truth_area_m2 / precision.face_area_m2;
    pg.plane_not_surface_share = precision.not_surface_area_m2 / precision.face_area_m2;
    pg.plane_misoriented_share = precision.misoriented_area_m2 / precision.face_area_m2;
  }
  lane.plane_precision_ms += msSince(precision_start);
  return pg;
}

} // namespace

/** SG, OG, RA and PG of \a lane as they stand, against \a truth: over the whole map
 * (\a region null) or the cells reaching into \a region (the paper's places). RA is
 * merged from SG here; \a ra_divisor spreads its merge time (frames of the mean). The
 * memory is always the whole map's. Rows in the order SG, OG, RA, PG; \a planar gets
 * PG's planar cuboids (count, occupied) for the progress line. */
std::vector<ComparisonRow>
measureLane(Lane& lane,
            const ComparisonRow& base,
            const GroundTruthSurface& truth,
            const MappedViews& mapped,
            double tolerance_m,
            const MappingErrorRegion* region,
            const MethodTimes& ms,
            double ra_divisor,
            std::pair<std::size_t, std::size_t>& planar_counts)
{
  using Clock = std::chrono::steady_clock;
  // The completeness counts the truth voxels in the region (all without one) against
  // every occupied cell of the map; its time is kept apart from the methods'.
  const MappingErrorRegion everywhere;
  const auto completeness_start = Clock::now();
  const TruthVoxels& truth_voxels = laneTruthVoxels(lane, truth, mapped);
  lane.completeness_ms += msSince(completeness_start);
  const LaneTruth t{truth,       truth_voxels, mapped,
                    tolerance_m, region,       region ? *region : everywhere};
  const ComparisonRow sg = measureSG(lane, base, ms.sg, t);
  std::vector<ComparisonRow> rows{sg, measureOG(lane, base, ms.og, t),
                                  measureRA(lane, base, ms.sg, ra_divisor, t),
                                  measurePG(lane, base, ms.pg, t, planar_counts)};
  for (ComparisonRow& row : rows) {
    row.efficiency =
      sg.cells > 0
        ? 1.0 - static_cast<double>(row.cells) / static_cast<double>(sg.cells)
        : 0.0;
    row.error = sg.cells > 0
                  ? static_cast<double>(row.erroneous) / static_cast<double>(sg.cells)
                  : 0.0;
  }
  return rows;
}

} // namespace detail
} // namespace planar_grid
