// SPDX-License-Identifier: BSD-3-Clause
// The paper's comparison (Sec. IV-B, Figs. 12-14): SG, OG, RA and PG on the same frames
// at several minimum cell sizes, in one process.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/eval/standard_voxel_grid.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/common/transforms.h>
#include <pcl/io/pcd_io.h>

#include <octomap/octomap.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <iterator>
#include <limits>
#include <map>
#include <memory>
#include <set>
#include <sstream>
#include <utility>
#include <vector>

#include "map_comparison_impl.h"
#include "map_comparison_lane.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using detail::buildTruth;
using detail::isFrontEnd;
using detail::Lane;
using detail::MappedViews;
using detail::measureLane;
using detail::MethodTimes;
using detail::msSince;
using detail::rangeView;
using detail::ReferenceVoxels;

/** Writes \a points to \a path as a binary compressed PCD, atomically (a failed
 * write leaves no half file). \throws planar_grid::IOError naming the file */
void
savePointsAtomically(const std::string& path,
                     const pcl::PointCloud<pcl::PointXYZ>& points)
{
  writeFileAtomically(path, [&points](const std::string& temporary) {
    return pcl::io::savePCDFileBinaryCompressed(temporary, points) == 0;
  });
}

/** The pipeline of \a ds with its front-end stages (\a front true) or its mapping
 * stages (false) only, at cell size \a r. */
PipelineConfig
pipelinePart(const DatasetConfig& ds, bool front, double r)
{
  PipelineConfig part = ds.pipeline;
  part.stages.clear();
  // The file's stages are at its own cell_size_m when it has one.
  const double from = ds.pipeline.cell_size_m > 0.0 ? ds.pipeline.cell_size_m : 0.1;
  for (const auto& sc : ds.pipeline.stages)
    if (isFrontEnd(sc.type) == front)
      part.stages.push_back(stageAtCellSize(sc, r, from));
  return part;
}

/** Appends the valid points of \a cloud, moved by \a world_T, to \a out. */
void
appendWorldPoints(const Frame::Cloud& cloud,
                  const Eigen::Matrix4f& world_T,
                  pcl::PointCloud<pcl::PointXYZ>& out)
{
  out.reserve(out.size() + cloud.size());
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector4f q = world_T * Eigen::Vector4f(p.x, p.y, p.z, 1.0f);
    out.push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
  }
}

/** The valid points of \a cloud in the world frame (transformed by the frame's pose
 * when the cloud is still in the camera frame). */
pcl::PointCloud<pcl::PointXYZ>
worldPoints(const Frame& frame)
{
  pcl::PointCloud<pcl::PointXYZ> out;
  if (!frame.cloud)
    return out;
  Eigen::Matrix4f world_T = Eigen::Matrix4f::Identity();
  if (!frame.cloud_in_world_frame)
    world_T = frame.world_T_camera.matrix().cast<float>();
  appendWorldPoints(*frame.cloud, world_T, out);
  return out;
}

/** The places of \a frames processed frames: \a places of them evenly spaced, the
 * last at the last frame; place k is after processed frame floor((k + 1) n / P) - 1. */
std::vector<std::size_t>
placeFrames(std::size_t frames, std::size_t places)
{
  std::vector<std::size_t> out;
  const std::size_t p = std::min(frames, places);
  for (std::size_t k = 0; k < p; ++k)
    out.push_back((k + 1) * frames / p - 1);
  return out;
}

/** Inserts the world-frame points of \a frame (the cloud PG's approximation gets, and
 * the far points range_adaptive_cells maps) into the SG and OG maps of \a lane and
 * counts their times. */
void
insertBaselines(Lane& lane, const Frame& frame)
{
  using Clock = std::chrono::steady_clock;
  pcl::PointCloud<pcl::PointXYZ> points = worldPoints(frame);
  if (frame.far_cloud) // in the camera frame
    appendWorldPoints(*frame.far_cloud, frame.world_T_camera.matrix().cast<float>(),
                      points);
  const Eigen::Vector3f origin = frame.world_T_camera.translation().cast<float>();
  auto t = Clock::now();
  lane.sg->insertPointCloud(points, origin);
  lane.frame_ms.sg += msSince(t);
  t = Clock::now();
  octomap::Pointcloud scan;
  scan.reserve(points.size());
  for (const auto& p : points.points)
    scan.push_back(p.x, p.y, p.z);
  lane.og->insertPointCloud(scan, octomap::point3d(origin.x(), origin.y(), origin.z()));
  lane.frame_ms.og += msSince(t);
  lane.inserted = true;
}

} // namespace

double
mappedRange(const PipelineConfig& pipeline, const StereoCalibration& calibration)
{
  double range_m = std::numeric_limits<double>::infinity();
  bool range_adaptive = false;
  for (const auto& sc : pipeline.stages)
    range_adaptive = range_adaptive || sc.type == "range_adaptive_cells";
  for (const auto& sc : pipeline.stages) {
    if (sc.type == "stereo_disparity" || sc.type == "map_integration") {
      range_m = std::min(range_m, sc.params.getDouble("max_range_m"));
    } else if (sc.type == "depth_error_filter") {
      // Eq. 4: Delta z = z^2 Delta d / (B f) <= max  <=>  z <= sqrt(max / Delta z(1
      // m)), as the stage computes it; the points up to the plane bound may still make
      // planar cells.
      const double error_at_1m =
        calibration.depthError(1.0, sc.params.getDouble("disparity_error_px"));
      // range_adaptive_cells maps the far levels' points up to 2^far_levels times the
      // bound's error.
      const double far_scale =
        range_adaptive ? std::ldexp(1.0, sc.params.getInt("far_levels")) : 1.0;
      const double max_error_m =
        std::max(sc.params.getDouble("max_depth_error_m") * far_scale,
                 sc.params.getDouble("max_plane_depth_error_m"));
      if (std::isfinite(error_at_1m) && error_at_1m > 0.0)
        range_m = std::min(range_m, std::sqrt(max_error_m / error_at_1m));
    }
  }
  return range_m;
}

namespace {

/** \brief \a front with every frame dense (stereo_disparity's every_n_frames 1, no
 * keyframe selection): the reference describes the scene, whichever frames a method
 * maps. \a thinned says whether \a front skips dense frames. */
PipelineConfig
everyFrameDense(const PipelineConfig& front, bool& thinned)
{
  PipelineConfig all = front;
  thinned = false;
  for (auto& sc : all.stages)
    if (sc.type == "stereo_disparity"
        && (sc.params.getInt("every_n_frames") != 1
            || sc.params.getChoice("frame_selection") != "every_n_frames")) {
      thinned = true;
      sc.params.set("every_n_frames", 1);
      sc.params.set("frame_selection", std::string("every_n_frames"));
    }
  return all;
}

} // namespace

namespace {

/** \brief One lane per cell size of \a config: the mapping stages of \a ds at that
 * size (SG and OG get the cloud PG's approximation gets, or with range_adaptive_cells
 * the far points it maps; PG's time is its stages' but the accumulated cloud's), and
 * SG's and OG's maps. */
std::vector<Lane>
makeLanes(const ComparisonConfig& config, const DatasetConfig& ds)
{
  std::vector<Lane> lanes(config.resolutions_m.size());
  for (std::size_t k = 0; k < lanes.size(); ++k) {
    Lane& lane = lanes[k];
    lane.resolution_m = config.resolutions_m[k];
    const PipelineConfig mapping = pipelinePart(ds, false, lane.resolution_m);
    for (const auto& sc : mapping.stages)
      lane.types.push_back(sc.type);
    lane.pipeline =
      std::make_unique<PipelineRunner>(mapping, PipelineRunner::FrameSupply::CALLER);
    const bool range_adaptive =
      std::find(lane.types.begin(), lane.types.end(), "range_adaptive_cells")
      != lane.types.end();
    const std::string baseline_stage =
      range_adaptive ? "range_adaptive_cells" : "planar_cuboid_approximation";
    lane.pipeline->setStageCallback(
      [&lane, baseline_stage](std::size_t s, Frame& frame) {
        if (lane.types[s] == baseline_stage)
          insertBaselines(lane, frame);
      });
    lane.pipeline->setFrameCallback(
      [&lane](std::size_t, Frame&, const std::vector<double>& stage_ms) {
        for (std::size_t s = 0; s < stage_ms.size(); ++s)
          if (lane.types[s] != "accumulate")
            lane.frame_ms.pg += stage_ms[s];
      });
    StandardVoxelGrid::Params sg;
    sg.resolution_m = lane.resolution_m;
    lane.sg = std::make_unique<StandardVoxelGrid>(sg);
    lane.og = std::make_unique<octomap::OcTree>(lane.resolution_m);
  }
  return lanes;
}

/** \brief Maps \a frame (after the front end) at every cell size: the mapping stages,
 * then SG and OG when no stage gave them the cloud; \a kl_ms, the KL filter's time,
 * is PG's work too. */
void
mapFrameInLanes(std::vector<Lane>& lanes,
                const Frame& frame,
                double kl_ms,
                const std::string& dataset)
{
  for (Lane& lane : lanes) {
    Frame f = frame;
    if (frame.cloud)
      f.cloud.reset(new Frame::Cloud(*frame.cloud));
    lane.frame_ms = MethodTimes();
    lane.frame_ms.pg = kl_ms;
    lane.inserted = false;
    try {
      lane.pipeline->processFrame(f);
    } catch (const Exception& e) {
      throw Exception("dataset " + dataset + ", cell size "
                      + std::to_string(lane.resolution_m) + " m: " + e.what());
    }
    if (!lane.inserted)
      insertBaselines(lane, f);
    lane.pg_ms += lane.frame_ms.pg;
    lane.sg_ms += lane.frame_ms.sg;
    lane.og_ms += lane.frame_ms.og;
  }
}

/** \brief The row every measurement of \a ds at cell size \a r starts from. */
ComparisonRow
baseRow(const ComparisonConfig& config,
        const DatasetConfig& ds,
        double r,
        std::size_t frames,
        const std::string& truth_kind)
{
  ComparisonRow base;
  base.dataset = ds.name;
  base.environment = config.environment;
  base.resolution_m = r;
  base.frames = frames;
  base.tilt_deg = ds.tilt_deg;
  base.truth_kind = truth_kind;
  return base;
}

/** \brief The progress line of a lane's whole-map rows (SG, OG, RA, PG). */
std::string
progressLine(const std::string& dataset,
             const Lane& lane,
             std::size_t frames,
             const std::vector<ComparisonRow>& measured,
             const std::pair<std::size_t, std::size_t>& planar_counts,
             const std::string& saved)
{
  const ComparisonRow& sg = measured[0];
  const ComparisonRow& pg = measured[3];
  std::ostringstream line;
  line << std::fixed << std::setprecision(2) << dataset << " @ " << lane.resolution_m
       << " m, " << frames << " frames: cells SG " << sg.cells << ", OG "
       << measured[1].cells << ", RA " << measured[2].cells << ", PG " << pg.cells
       << " (of " << pg.all_cells << "; planar " << planar_counts.first << ", occupied "
       << planar_counts.second << "); error SG " << sg.error << ", PG " << pg.error
       << " (planar "
       << static_cast<double>(pg.planar_erroneous)
            / static_cast<double>(std::max<std::size_t>(sg.cells, 1))
       << "); completeness SG " << sg.completeness << ", OG "
       << measured[1].completeness << ", RA " << measured[2].completeness << ", PG "
       << pg.completeness << " cuboids, " << pg.map_completeness << " whole map (of "
       << sg.truth_voxels << " truth voxels); PG planar share " << pg.planar_share
       << " (of " << pg.nonground_voxels << " non-ground), " << pg.range_planar_share
       << " within the mapped " << pg.mapped_range_m << " m (of "
       << pg.range_nonground_voxels << "; SG's non-ground completeness there "
       << sg.range_nonground_completeness << "); own error SG " << sg.own_error
       << ", OG " << measured[1].own_error << ", RA " << measured[2].own_error
       << ", PG " << pg.own_error << "; PG plane precision " << pg.plane_precision
       << " (of " << pg.plane_area_m2 << " m2; no truth " << pg.plane_no_truth_share
       << ", not a surface " << pg.plane_not_surface_share << ", misoriented "
       << pg.plane_misoriented_share << "); completeness measured in "
       << std::setprecision(2) << lane.completeness_ms / 1000.0
       << " s, plane precision in " << lane.plane_precision_ms / 1000.0 << " s";
  if (!saved.empty())
    line << "; PG map " << saved;
  return line.str();
}

/** \brief Saves \a lane's PG map, and SG's occupied voxels beside it (to compare
 * the two maps point by point); returns the map's path. */
std::string
saveLaneMaps(const ComparisonConfig& config, const std::string& dataset, Lane& lane)
{
  std::error_code ec;
  fs::create_directories(config.output_folder, ec);
  const std::string saved =
    (fs::path(config.output_folder) / mapComparisonFile(dataset, lane.resolution_m))
      .string();
  lane.pipeline->state().map->save(saved);
  pcl::PointCloud<pcl::PointXYZ> sg_centres;
  lane.sg->getOccupiedCentres(sg_centres);
  savePointsAtomically(
    (fs::path(config.output_folder) / sgComparisonFile(dataset, lane.resolution_m))
      .string(),
    sg_centres);
  return saved;
}

/** \brief Every method at every cell size of one dataset: the places while the
 * frames run, then the whole maps after the last frame. */
void
compareDataset(const ComparisonConfig& config,
               const DatasetConfig& ds,
               const std::function<void(const std::string&)>& progress,
               std::vector<ComparisonRow>& rows)
{
  // The front end has no size parameter; it is configured at the first cell size.
  const PipelineConfig front_config =
    pipelinePart(ds, true, config.resolutions_m.front());
  PipelineRunner front(front_config);
  const std::size_t end =
    ds.frame_count > 0 ? std::min(front.frameCount(), ds.first_frame + ds.frame_count)
                       : front.frameCount();
  if (ds.first_frame >= end)
    throw Exception("dataset " + ds.name + ": no frames in the range");
  const std::size_t total = (end - ds.first_frame + ds.frame_step - 1) / ds.frame_step;
  const std::vector<std::size_t> places = placeFrames(total, ds.places);
  // One frame at a time: the methods' times are measured without a second thread.
  front.setFrameRange(ds.first_frame, end, ds.frame_step);
  front.setFrameOverlap(false);
  std::vector<Lane> lanes = makeLanes(config, ds);

  // The places are measured while the frames run, so a reference built from all
  // frames must exist first: a pass of a second front end over the frames builds it
  // (the same deterministic stages give the same points). A front end that maps
  // only every n-th frame densely gets its reference from a pass over every frame.
  ReferenceVoxels reference(ds.truth.leaf_size_m, ds.truth.max_range_m);
  bool thinned = false;
  const PipelineConfig reference_config = everyFrameDense(front_config, thinned);
  const bool reference_first =
    ds.truth.type == TruthConfig::Type::REFERENCE && (!places.empty() || thinned);
  if (reference_first) {
    PipelineRunner pre(reference_config);
    pre.setFrameRange(ds.first_frame, end, ds.frame_step);
    pre.setFrameOverlap(false);
    pre.setFrameCallback(
      [&reference](std::size_t, Frame& frame, const std::vector<double>&) {
        reference.addFrame(worldPoints(frame),
                           frame.world_T_camera.translation().cast<float>());
      });
    pre.run();
    if (progress)
      progress(ds.name + ": reference of " + std::to_string(total)
               + " frames built for the places");
  }

  for (auto& lane : lanes)
    lane.pipeline->start();

  std::unique_ptr<GroundTruthSurface> truth;
  std::string truth_kind;
  Frame first_frame;
  MappedViews mapped;
  std::size_t frames = 0;
  std::size_t next_place = 0;
  // Each frame, after the front end: the mapping stages and SG and OG at every cell
  // size, then the place it may be.
  front.setFrameCallback([&](std::size_t i, Frame& frame,
                             const std::vector<double>& front_ms) {
    double kl_ms = 0.0;
    for (std::size_t st = 0; st < front_ms.size(); ++st)
      if (front_config.stages[st].type == "kl_occupancy_filter")
        kl_ms += front_ms[st]; // the occupancy of the features is PG's work
    if (frames == 0) {
      first_frame = frame;
      mapped.max_depth_m = mappedRange(ds.pipeline, frame.calibration);
    }
    mapped.views.push_back(rangeView(frame));
    if (ds.truth.type == TruthConfig::Type::REFERENCE && !reference_first)
      reference.addFrame(worldPoints(frame),
                         frame.world_T_camera.translation().cast<float>());
    mapFrameInLanes(lanes, frame, kl_ms, ds.name);

    // A place (paper Sec. IV-B): the cells near the camera, this frame's times.
    if (next_place < places.size() && places[next_place] == frames) {
      if (!truth)
        truth = buildTruth(ds, first_frame, reference, truth_kind);
      MappingErrorRegion region;
      region.centre_m = frame.world_T_camera.translation().cast<float>();
      region.max_distance_m = ds.place_radius_m;
      for (Lane& lane : lanes) {
        ComparisonRow base =
          baseRow(config, ds, lane.resolution_m, frames + 1, truth_kind);
        base.place = static_cast<int>(next_place);
        base.frame = i;
        base.region_radius_m = ds.place_radius_m;
        std::pair<std::size_t, std::size_t> planar_counts;
        for (const auto& row : measureLane(lane, base, *truth, mapped,
                                           config.tolerance_cells * lane.resolution_m,
                                           ds.place_radius_m > 0.0 ? &region : nullptr,
                                           lane.frame_ms, 1.0, planar_counts))
          rows.push_back(row);
      }
      ++next_place;
    }
    ++frames;
  });
  front.run();
  for (auto& lane : lanes)
    lane.pipeline->finish();
  if (!truth)
    truth = buildTruth(ds, first_frame, reference, truth_kind);
  if (config.save_maps) {
    std::error_code ec;
    fs::create_directories(config.output_folder, ec);
    const std::string truth_file =
      (fs::path(config.output_folder) / ("truth_" + ds.name + ".pcd")).string();
    savePointsAtomically(truth_file, *truth->getPoints());
    if (progress)
      progress(ds.name + ": " + truth_kind + " points in " + truth_file);
  }

  // The whole map after the last frame; times are means per frame.
  for (auto& lane : lanes) {
    const double r = lane.resolution_m;
    const auto n = static_cast<double>(frames);
    ComparisonRow base = baseRow(config, ds, r, frames, truth_kind);
    base.frame = ds.first_frame + (frames - 1) * ds.frame_step;
    MethodTimes mean;
    mean.sg = lane.sg_ms / n;
    mean.og = lane.og_ms / n;
    mean.pg = lane.pg_ms / n;
    std::pair<std::size_t, std::size_t> planar_counts;
    const std::vector<ComparisonRow> measured =
      measureLane(lane, base, *truth, mapped, config.tolerance_cells * r, nullptr, mean,
                  n, planar_counts);
    rows.insert(rows.end(), measured.begin(), measured.end());
    std::string saved;
    if (config.save_maps && lane.pipeline->state().map)
      saved = saveLaneMaps(config, ds.name, lane);
    if (progress)
      progress(progressLine(ds.name, lane, frames, measured, planar_counts, saved));
  }
}

} // namespace

std::vector<ComparisonRow>
runComparison(const ComparisonConfig& config,
              const std::function<void(const std::string&)>& progress)
{
  std::vector<ComparisonRow> rows;
  for (const auto& ds : config.datasets)
    compareDataset(config, ds, progress, rows);
  return rows;
}

} // namespace planar_grid
