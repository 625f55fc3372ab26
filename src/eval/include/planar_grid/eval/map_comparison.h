// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Where the ground truth of a dataset's mapping error comes from.
 * \ingroup eval */
struct TruthConfig {
  /** \brief The kinds of ground truth. */
  enum class Type {
    /** A PCD of points sampled densely on the true surfaces (world frame, meters),
     * e.g. the synthetic scene's truth.pcd. */
    POINTS,
    /** A ground-truth disparity image of the first frame (8-bit PNG, pixels, 0 =
     * unknown, e.g. Middlebury's), converted with the frame's calibration and pose. */
    DISPARITY,
    /** A reference built from all frames of the dataset at fine resolution: every
     * frame's dense stereo (or PCD) points in the world frame, in voxels of
     * leaf_size_m; a voxel is kept (at the mean of its points) when min_views frames
     * saw a point in it, so that one frame's stereo artifacts are not in it.
     * Agreement with it, not truth: stated as such in the results. */
    REFERENCE
  };
  Type type{Type::REFERENCE};
  /** \brief The file (POINTS, DISPARITY). */
  std::string file;
  /** \brief Voxel size of the REFERENCE cloud, meters. */
  double leaf_size_m{0.05};
  /** \brief Farthest distance from its frame's camera of a point the REFERENCE
   * takes, meters (+inf: every point). Stereo depth error grows with the square of the
   * depth (eq. 4), so a shorter range gives a thinner reference of the surfaces the
   * camera passed near. */
  double max_range_m{std::numeric_limits<double>::infinity()};
  /** \brief Frames that must see a REFERENCE voxel (1: every point counts). */
  std::size_t min_views{2};
};

/** \brief One dataset of an evaluation: a pipeline configuration (its input and stages)
 * and a ground truth. \ingroup eval */
struct DatasetConfig {
  /** \brief Name in the tables and plots. */
  std::string name;
  /** \brief The pipeline configuration file (input and stages; its output is unused).
   */
  std::string pipeline_file;
  /** \brief The pipeline configuration, loaded. */
  PipelineConfig pipeline;
  /** \brief Frames [first_frame, first_frame + frame_count) every frame_step (0 count:
   * to the end). */
  std::size_t first_frame{0};
  std::size_t frame_count{0};
  std::size_t frame_step{1};
  /** \brief Where the mapping error's truth comes from. */
  TruthConfig truth;
  /** \brief Angle of the scene's surfaces to the map axes, degrees (a tag for the tilt
   * plot; negative: none). */
  double tilt_deg{-1.0};
  /** \brief The dataset's places and their radius (ComparisonConfig::places and
   * place_radius_m unless the dataset gives its own: a single view, say, whose whole
   * map is near the camera). */
  std::size_t places{0};
  double place_radius_m{0.0};
};

/** \brief An evaluation (planar_grid_eval --config): datasets of one environment, each
 * mapped by SG, OG, RA and PG at several minimum cell sizes in one process.
 * \ingroup eval */
struct ComparisonConfig {
  /** \brief The file it was read from. */
  std::string source_file;
  /** \brief "indoor" or "outdoor" (the plots' title). */
  std::string environment{"indoor"};
  /** \brief The minimum cell sizes, meters (the paper: 0.1 to 0.5). */
  std::vector<double> resolutions_m{0.1, 0.2, 0.3, 0.4, 0.5};
  /** \brief A cell sample is erroneous farther than this many cell sizes from the
   * truth. */
  double tolerance_cells{1.0};
  /** \brief The paper's places (Sec. IV-B, Figs. 10-14: "10 places along the robot
   * motion path"): up to this many frames of each dataset, evenly spaced, the last at
   * its last frame, are measured while the frames run (0: none, only the whole map at
   * the end). */
  std::size_t places{0};
  /** \brief At a place, cells and error count only within this distance of the camera
   * ("the occupied grid in a small range near the robot"), meters; 0: the whole map. */
  double place_radius_m{0.0};
  /** \brief The datasets. */
  std::vector<DatasetConfig> datasets;
  /** \brief Output folder (CSV, plots). */
  std::string output_folder{"output/eval"};
  /** \brief Also write PG's whole map of every dataset and cell size into
   * output_folder as pg_DATASET_Rm.pgmap (PlanarGridMap::save), for the viewer and
   * the Python bindings. */
  bool save_maps{false};
};

/** \brief The figures of one method on one dataset at one cell size (a row of the CSV).
 * \ingroup eval */
struct ComparisonRow {
  std::string dataset;
  std::string environment;
  double resolution_m{0.0};
  /** \brief SG, OG, RA or PG. */
  std::string method;
  /** \brief Frames mapped. */
  std::size_t frames{0};
  /** \brief Occupied cells (SG occupied voxels, OG occupied leaves, RA occupied boxes,
   * PG occupied cuboids). */
  std::size_t cells{0};
  /** \brief All cells held (with free ones: RA free boxes, PG cuboids below the
   * occupancy threshold; SG and OG: observed voxels / leaves). */
  std::size_t all_cells{0};
  /** \brief Combination efficiency against SG, eta = 1 - cells / SG cells (paper,
   * Fig. 12). */
  double efficiency{0.0};
  /** \brief Memory held by the method's map, bytes (SG hash map, OG memoryUsage(), RA
   * boxes, PG PlanarGridMap::getMemory()). */
  std::uint64_t memory_bytes{0};
  /** \brief Mean time per frame of the method's own work, milliseconds. */
  double ms_per_frame{0.0};
  /** \brief Occupied volume in samples of one cell size (mapping error). */
  std::size_t samples{0};
  /** \brief Samples farther than the tolerance from the truth. */
  std::size_t erroneous{0};
  /** \brief Mapping error e = erroneous / SG cells (paper, Fig. 13). */
  double error{0.0};
  /** \brief The method's own error erroneous / samples in [0, 1]: the share of its
   * own occupied samples (voxels of the cell size) off the truth
   * (MappingError::ownError()), which mapping less volume does not lower; NaN without
   * samples. */
  double own_error{std::numeric_limits<double>::quiet_NaN()};
  /** \brief PG only: the samples and erroneous samples of its planar cuboids (the
   * rest are the non-planar boxes of Fig. 7). */
  std::size_t planar_samples{0};
  std::size_t planar_erroneous{0};
  /** \brief The dataset's tilt tag, degrees (negative: none). */
  double tilt_deg{-1.0};
  /** \brief "truth" or "reference" (agreement with a reference, not truth). */
  std::string truth_kind;
  /** \brief -1: the whole map after the last frame (ms_per_frame is the mean); k >= 0:
   * the k-th place (ComparisonConfig::places): the map as it stood after \a frame,
   * cells, samples, erroneous, efficiency and error within region_radius_m of the
   * camera (MappingError::cells), all_cells and memory_bytes of the whole map,
   * ms_per_frame of that frame alone (RA: SG's plus a merge of the whole grid). */
  int place{-1};
  /** \brief Sequence number of the frame the row describes (the last one for place -1).
   */
  std::size_t frame{0};
  /** \brief The places' radius, meters (0: the whole map). */
  double region_radius_m{0.0};
  /** \brief Truth voxels counted by the completeness: the truth points voxelized at
   * the cell size (TruthVoxels); at a place those within region_radius_m of the
   * camera. */
  std::size_t truth_voxels{0};
  /** \brief Of them, those whose centre lies within the tolerance (tolerance_cells x
   * the cell size) of an occupied cell of the method (evaluateCompleteness()). */
  std::size_t covered_voxels{0};
  /** \brief Completeness covered_voxels / truth_voxels in [0, 1]: the share of the
   * truth the method's occupied cells reach (it falls when a method drops data, which
   * lowers the error); NaN without truth voxels. */
  double completeness{std::numeric_limits<double>::quiet_NaN()};
  /** \brief The non-ground truth voxels (TruthVoxels::isGround; at a place, within
   * the radius). */
  std::size_t nonground_voxels{0};
  /** \brief Of them, those within the tolerance of an occupied cell of the method
   * (Completeness::nonground_covered). */
  std::size_t nonground_covered_voxels{0};
  /** \brief Non-ground completeness nonground_covered_voxels / nonground_voxels in
   * [0, 1]: how much of the truth above the ground the method's cells reach. SG's is
   * what every point the mapping stages keep reaches: the bound of PG's planar share
   * for cells made from those points. NaN without non-ground truth voxels. */
  double nonground_completeness{std::numeric_limits<double>::quiet_NaN()};
  /** \brief PG only: of them, those within the tolerance of an occupied planar cuboid
   * (evaluatePlanarShare()). */
  std::size_t planar_covered_voxels{0};
  /** \brief PG only: planar share planar_covered_voxels / nonground_voxels in [0, 1],
   * how much of the truth above the ground PG's planar cells explain; NaN for SG, OG
   * and RA and without non-ground truth voxels. */
  double planar_share{std::numeric_limits<double>::quiet_NaN()};
  /** \brief Of the truth voxels counted, those within the tolerance of what the
   * method's whole map holds occupied: for PG what PlanarGridMap::getState() reads
   * OCCUPIED, its occupied cuboids and the space layer's occupied voxels
   * (evaluateMapCompleteness()); for SG, OG and RA, whose maps are their occupied
   * cells alone, covered_voxels. */
  std::size_t map_covered_voxels{0};
  /** \brief Whole-map completeness map_covered_voxels / truth_voxels in [0, 1]; NaN
   * without truth voxels. For PG, completeness is its cuboids' alone. */
  double map_completeness{std::numeric_limits<double>::quiet_NaN()};
  /** \brief The depth the pipeline maps to, meters (mappedRange()): the truth voxels
   * in the view of a frame mapped so far within this depth are in the mapped range
   * (TruthVoxels::addView()). */
  double mapped_range_m{std::numeric_limits<double>::infinity()};
  /** \brief The non-ground truth voxels in the mapped range (at a place, within the
   * radius too). */
  std::size_t range_nonground_voxels{0};
  /** \brief Of them, those within the tolerance of an occupied cell of the method. */
  std::size_t range_nonground_covered_voxels{0};
  /** \brief range_nonground_covered_voxels / range_nonground_voxels in [0, 1]: SG's is
   * the bound of PG's planar share within the range; NaN without such voxels. */
  double range_nonground_completeness{std::numeric_limits<double>::quiet_NaN()};
  /** \brief PG only: of the non-ground truth voxels in the mapped range, those within
   * the tolerance of an occupied planar cuboid. */
  std::size_t range_planar_covered_voxels{0};
  /** \brief PG only: planar share within the mapped range,
   * range_planar_covered_voxels / range_nonground_voxels in [0, 1]; NaN for SG, OG and
   * RA and without such voxels. */
  double range_planar_share{std::numeric_limits<double>::quiet_NaN()};
  /** \brief PG only: the face area of its occupied planar cuboids, square meters (at a
   * place, of the face samples within region_radius_m of the camera). */
  double plane_area_m2{0.0};
  /** \brief PG only: plane precision in [0, 1], the share of that face area where the
   * truth points form a surface within PLANE_PRECISION_MAX_ANGLE_DEG of the cell's
   * normal (evaluatePlanePrecision()); NaN for SG, OG and RA and without planar
   * cells. */
  double plane_precision{std::numeric_limits<double>::quiet_NaN()};
  /** \brief PG only: the rest of that face area by cause, shares in [0, 1] that sum
   * to 1 - plane_precision (PlanePrecision): no truth around the sample (a cell in
   * space the truth does not hold), truth that is not a surface (a corner, clutter),
   * and a truth surface tilted beyond PLANE_PRECISION_MAX_ANGLE_DEG from the cell;
   * NaN where plane_precision is. */
  double plane_no_truth_share{std::numeric_limits<double>::quiet_NaN()};
  double plane_not_surface_share{std::numeric_limits<double>::quiet_NaN()};
  double plane_misoriented_share{std::numeric_limits<double>::quiet_NaN()};
};

/** \brief The depth to which the stages of \a pipeline make cells, meters: the
 * smallest of stereo_disparity's max_range_m, depth_error_filter's bound of eq. 4
 * (the depth z whose error z^2 disparity_error_px / (B f) reaches the larger of its
 * max_depth_error_m and max_plane_depth_error_m, with \a calibration's f and B) and
 * map_integration's max_range_m, for the stages present (+inf with none; the depth
 * bound needs a calibration with f, B > 0).
 * \ingroup eval */
double mappedRange(const PipelineConfig& pipeline,
                   const StereoCalibration& calibration);

/** \brief Runs every dataset of \a config (rows of its places as the frames run, then
 * of the whole map at the end). The pipeline's own runner (PipelineRunner) runs the
 * frames once through the front-end stages (StageRole::FRONT_END: stereo, features,
 * occupancy filter, odometry), and its frame callback feeds each frame, for each cell
 * size r, to a runner of the mapping stages with every size parameter set to r
 * (voxel_grid leaf, cuboid minimum cell and thickness, map resolution; min_inliers
 * scaled by (0.1 / r)^2); that runner's stage callback inserts the cloud PG's
 * approximation receives (world frame, after ground removal) into SG and OG at r. RA
 * is merged from SG at each place and at the end. With places and a REFERENCE truth,
 * a first pass of a second front end over the frames builds the reference, since the
 * places need it while the frames run.
 * With ComparisonConfig::save_maps, PG's whole map of each dataset and cell size is
 * saved in the output folder as it is measured (mapComparisonFile names it), with
 * SG's occupied voxel centres beside it (sgComparisonFile, binary compressed PCD);
 * every file is written atomically.
 * \param[in] progress called with a line of text per dataset and cell size
 * \return per dataset: the place rows (place >= 0; per place, cell size and method),
 * then one row per cell size and method for the whole map (place = -1)
 * \throws planar_grid::Exception on failure */
std::vector<ComparisonRow>
runComparison(const ComparisonConfig& config,
              const std::function<void(const std::string&)>& progress);

/** \brief The file name of PG's map of \a dataset at cell size \a resolution_m
 * (ComparisonConfig::save_maps): "pg_DATASET_Rm.pgmap", characters other than
 * letters, digits, '-', '_' and '.' in the dataset's name replaced by '_'. */
std::string mapComparisonFile(const std::string& dataset, double resolution_m);

/** \brief The file name of SG's occupied voxel centres of \a dataset at cell size \a
 * resolution_m (ComparisonConfig::save_maps): "sg_DATASET_Rm.pcd", the dataset's name
 * as mapComparisonFile() writes it. */
std::string sgComparisonFile(const std::string& dataset, double resolution_m);

/** \brief Writes the rows as CSV (header line, one row per line), atomically.
 * \throws planar_grid::IOError */
void saveComparisonCsv(const std::vector<ComparisonRow>& rows, const std::string& path);

/** \brief The rows as a Markdown table (for docs/EVALUATION.md). */
std::string comparisonMarkdown(const std::vector<ComparisonRow>& rows);

} // namespace planar_grid
