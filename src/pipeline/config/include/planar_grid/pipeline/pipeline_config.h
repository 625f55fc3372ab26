// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/map/map_queries.h>
#include <planar_grid/pipeline/input_config.h>
#include <planar_grid/pipeline/mapper_config.h>
#include <planar_grid/pipeline/param_table.h>

#include <array>
#include <cstddef>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {

/** \brief Parses a pose format's name as the configuration writes it ("none",
 * "odometry", "karlsruhe_insdata", "kitti", "euroc_groundtruth", "viewpoint",
 * "registration", "tf"). \throws planar_grid::Exception listing the known names for
 * any other. */
PoseFormat poseFormatFromString(const std::string& name);

/** \brief The name of \a format, as poseFormatFromString() reads it. */
std::string poseFormatName(PoseFormat format);

/** \brief Whether \a path starts with '~' or holds a '$': what a shell would expand
 * and a configuration (or a quoted option) does not, so that a run would create a
 * folder of that literal name. \ingroup pipeline */
bool needsShellExpansion(const std::string& path);

/** \brief One configured stage: its type, its parsed parameters, and where it was
 * given. \ingroup pipeline */
struct StageConfig {
  /** \brief Stage type, a name of the stage registry. */
  std::string type;
  /** \brief Parsed parameters, every key of the stage's table present. */
  ParamValues params;
  /** \brief 1-based line of the stage in the config file (0 when unknown). */
  int line{0};
  /** \brief 1-based column of the stage in the config file (0 when unknown). */
  int column{0};
  /** \brief 1-based line and column of the value of each key the file gives in the
   * stage's params (keys left at their defaults are absent). */
  std::map<std::string, std::pair<int, int>> param_marks;
};

/** \brief The camera of the street snapshots (output.street_view): either following
 * the trajectory from above and behind one of its poses, looking along the direction
 * of travel (planar_grid::streetCamera(), whose defaults these are), or fixed. All in
 * the world frame. \ingroup pipeline */
struct StreetViewConfig {
  /** \brief Which pose the camera follows, as a fraction of the trajectory, in [0, 1]
   * (pose index round(f * (n - 1)); 0 the first pose, 1 the last). */
  double pose_fraction{1.0 / 3.0};
  /** \brief Downward pitch of the view below the horizontal, radians; more than half
   * the view angle and less than pi/2 minus half of it. */
  double pitch_rad{0.5};
  /** \brief Street ahead of the pose in view (up to the image's top edge), metres. */
  double look_ahead_m{40.0};
  /** \brief Vertical field of view, degrees, in [5, 120]. */
  double view_angle_deg{45.0};
  /** \brief The world's up direction (non-zero; need not be unit); for a fixed camera
   * the up direction of the image. */
  std::array<double, 3> up{{0.0, 0.0, 1.0}};
  /** \brief True when position_m and focal_point_m were given: a fixed camera instead
   * of following the trajectory. */
  bool fixed{false};
  /** \brief Fixed camera: its position, metres. */
  std::array<double, 3> position_m{{0.0, 0.0, 0.0}};
  /** \brief Fixed camera: the point it looks at, metres (differs from position_m). */
  std::array<double, 3> focal_point_m{{0.0, 0.0, 0.0}};
};

/** \brief What the run writes, in `folder` (resolved against the current directory;
 * overridable with --output). \ingroup pipeline */
struct OutputConfig {
  /** \brief Output folder. */
  std::string folder{"output"};
  /** \brief Accumulated world cloud, binary-compressed PCD ("" = none). */
  std::string cloud{"world_cloud.pcd"};
  /** \brief Accumulated plane inliers with a `label` field (run-wide plane id),
   * binary-compressed PCD ("" = none; written when a segmentation stage ran). */
  std::string planes{"planes.pcd"};
  /** \brief PNG snapshot of the planes, one colour per plane ("" = none). */
  std::string planes_snapshot{"planes.png"};
  /** \brief PNG snapshot of the cuboid cells, coloured by plane ("" = none). */
  std::string cuboids_snapshot{"cuboids.png"};
  /** \brief PNG snapshot of the cuboid cells, coloured by plane, seen along the street
   * with the street_view camera ("" = none). */
  std::string cuboids_street_snapshot;
  /** \brief The map file (PlanarGridMap::save(); written when map_integration ran;
   * "" = none). */
  std::string map{"map.pgmap"};
  /** \brief The map's space layer as an OctoMap binary tree, .bt ("" = none). */
  std::string map_octomap{"map.bt"};
  /** \brief The map's cuboids as a mesh, .ply or .vtk ("" = none). */
  std::string map_mesh{"map_cuboids.ply"};
  /** \brief The map projected over a height band into a 2D occupancy grid for ROS
   * map_server (PlanarGridMap::computeOccupancyGrid2D()): the YAML file's name, .yaml;
   * the PGM image is written beside it under the same name with .pgm ("" = none). */
  std::string map_grid_2d;
  /** \brief The band, terrain rules and cell size of map_grid_2d
   * (output.map_grid_2d_band). */
  OccupancyGrid2DParams map_grid_2d_band;
  /** \brief PNG snapshot of the map: cuboids coloured by occupancy, unknown space
   * translucent ("" = none). */
  std::string map_snapshot{"map.png"};
  /** \brief The checkpoint file (PipelineRunner::setCheckpoint(); resumed with
   * planar_grid_pipeline --resume). */
  std::string checkpoint{"checkpoint.pgck"};
  /** \brief Write the checkpoint every this many frames (0 = never; the tool's
   * --checkpoint-every overrides it). */
  std::size_t checkpoint_every_n_frames{0};
  /** \brief Machine-readable report. */
  std::string report{"report.json"};
  /** \brief Camera poses used, KITTI format ("" = none). */
  std::string trajectory{"trajectory.txt"};
  /** \brief PNG snapshot of the result ("" = none). */
  std::string snapshot{"snapshot.png"};
  /** \brief Camera of snapshot, planes_snapshot, cuboids_snapshot and map_snapshot:
   * "top", "oblique" (both frame the whole scene) or "street" (street_view). */
  std::string snapshot_camera{"top"};
  /** \brief The camera of the street snapshots. */
  StreetViewConfig street_view;
  /** \brief Snapshot size in pixels. */
  std::array<int, 2> snapshot_size_px{{1600, 1000}};
};

/** \brief A stage parameter that takes another stage's value when the configuration
 * leaves it out; set in both to different values, it is a planar_grid::ConfigError at
 * its key. \ingroup pipeline */
struct SharedStageParam {
  /** \brief The stage that takes the value. */
  std::string stage;
  /** \brief Its key that takes the value. */
  std::string key;
  /** \brief The stage whose value is taken. */
  std::string from_stage;
  /** \brief Its key whose value is taken. */
  std::string from_key;
  /** \brief Why the two are one quantity, and what to do (ends an error message). */
  std::string reason;
};

/** \brief The parameters that follow another stage's: the paper's minimum cell is one
 * quantity, so map_integration's resolution_m and thickness_m take
 * planar_cuboid_approximation's min_cell_size_m and thickness_m. \ingroup pipeline */
const std::vector<SharedStageParam>& sharedStageParams();

/** \brief A whole pipeline configuration (schema in config/example.yaml).
 * \ingroup pipeline */
struct PipelineConfig {
  /** \brief The file it was loaded from. */
  std::string source_file;
  /** \brief Where frames come from. */
  InputConfig input;
  /** \brief The stages, in run order. */
  std::vector<StageConfig> stages;
  /** \brief What the run writes. */
  OutputConfig output;
  /** \brief The file's top-level cell_size_m, meters, which the stages' keys of the
   * minimum cell were set from (stageAtCellSize()); 0 when the file has none (each
   * stage's own values). */
  double cell_size_m{0.0};
  /** \brief 1-based line and column of cell_size_m's value in the file (0 when it
   * has none, or when `--set cell_size_m=...` gave it). */
  int cell_size_line{0};
  /** \brief See cell_size_line. */
  int cell_size_column{0};
};

/** \brief Valid range of a pipeline file's top-level cell_size_m, meters. */
inline constexpr ParamRange CELL_SIZE_RANGE = ParamRange::closed(0.01, 10.0);

/** \brief \a stage moved from the minimum cell \a from_cell_size_m to \a cell_size_m:
 * the keys its table marks CELL_SIZE take \a cell_size_m, those marked LENGTH are
 * scaled by cell_size_m / from_cell_size_m and those marked POINTS_PER_AREA by
 * (from_cell_size_m / cell_size_m)^2 (at least 10) (ParamSpec::CellSizeScaling). A
 * pipeline file's top-level cell_size_m moves its stages from the paper's 0.1 m cell
 * the defaults are tuned for; planar_grid_eval moves a pipeline to each of its cell
 * sizes.
 * \param[in] stage the stage, its params complete
 * \param[in] cell_size_m the cell, meters, in CELL_SIZE_RANGE
 * \param[in] from_cell_size_m the cell the stage's values are for, meters (> 0)
 * \return the stage with its keys set
 * \throws planar_grid::Exception for an unknown stage type \ingroup pipeline */
StageConfig stageAtCellSize(const StageConfig& stage,
                            double cell_size_m,
                            double from_cell_size_m = 0.1);

/** \brief Loads and validates a pipeline YAML file strictly: unknown keys,
 * unknown stage types (the message lists the known ones), wrong types and out-of-range
 * values are planar_grid::ConfigError with file:line:col. Relative input paths are
 * resolved against the file's folder. \throws planar_grid::ConfigError,
 * planar_grid::IOError */
PipelineConfig loadPipelineConfig(const std::string& path);

/** \brief As loadPipelineConfig(), with stage parameters replaced before the
 * validation, as the pipeline tool's `--set` gives them.
 * \param[in] path the YAML file
 * \param[in] overrides assignments `STAGE.KEY=VALUE`: the parameter KEY of the one
 *            stage of type STAGE in the pipeline takes VALUE (checked against the
 *            stage's table as a value in the file would be), in the given order
 * \throws planar_grid::ConfigError for a malformed assignment, a stage type the
 *         pipeline does not list or lists more than once, an unknown key or a bad
 *         value (file "--set STAGE.KEY=VALUE"); as loadPipelineConfig() otherwise */
PipelineConfig loadPipelineConfig(const std::string& path,
                                  const std::vector<std::string>& overrides);

/** \brief As loadPipelineConfig() from YAML text; \a source_name is used in messages
 * and \a base_folder to resolve relative paths; \a overrides as in
 * loadPipelineConfig(path, overrides). */
PipelineConfig parsePipelineConfig(const std::string& yaml_text,
                                   const std::string& source_name,
                                   const std::string& base_folder,
                                   const std::vector<std::string>& overrides = {});

/** \brief The stages of \a config as a Mapper takes them (Mapper::Mapper()): each
 * stage's type and parameters, and where the file gives it (for messages); the input
 * and output sections are left out. \ingroup pipeline */
MapperConfig toMapperConfig(const PipelineConfig& config);

/** \brief As toMapperConfig(loadPipelineConfig(path)): a live mapper of a pipeline
 * file, e.g. `Mapper mapper(loadMapperConfig("config/karlsruhe_live.yaml"))`. The
 * file's input section is checked as for a run, but none of its files is read.
 * \throws planar_grid::ConfigError, planar_grid::IOError as loadPipelineConfig() */
MapperConfig loadMapperConfig(const std::string& path);

/** \brief The stages of a YAML document holding only the key `pipeline` (the list of
 * {type, params} of a configuration file, checked as strictly): no input or output
 * section. The frames they take are stereo pairs when a stage reads stereo images and
 * point clouds otherwise, each with its pose unless a visual_odometry stage estimates
 * it; the stages' needs are checked against those, and a point-cloud pipeline's
 * multi_plane_segmentation samples the cloud unless it says otherwise, as in a file.
 * \param[in] yaml_text the document, e.g. `pipeline: [{type: stereo_disparity}, ...]`
 * \param[in] source_name names the document in messages (MapperConfig::name)
 * \param[in] base_folder resolves relative paths
 * \throws planar_grid::ConfigError at source_name:line:col for another top-level key
 * or a bad stage, as loadPipelineConfig() */
MapperConfig parseMapperConfig(const std::string& yaml_text,
                               const std::string& source_name,
                               const std::string& base_folder);

} // namespace planar_grid
