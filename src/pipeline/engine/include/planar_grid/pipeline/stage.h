// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/map/plane_registry.h>
#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/param_table.h>

#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief What the stages share across frames: the accumulated world cloud, the
 * run-wide planes, the cells and the map.
 * \ingroup pipeline */
struct PipelineState {
  /** \brief The accumulated cloud in the world frame (accumulate stage). */
  Frame::Cloud::Ptr world_cloud{new Frame::Cloud};
  /** \brief The run-wide planes (accumulate stage, which sets their parameters): the
   * non-ground planes of every frame associated into one set, world frame, with their
   * inlier counts and their accumulated inliers labelled with the run-wide plane id. */
  PlaneRegistry::Ptr planes{std::make_shared<PlaneRegistry>()};
  /** \brief The accumulated cells of every frame in the world frame as produced;
   * plane_id is the run-wide plane id (-1 non-planar). Only filled when no
   * map_integration stage keeps a map (which merges cells across frames instead). */
  PlanarCuboids cuboids;
  /** \brief The map (map_integration stage; null without it). */
  std::shared_ptr<PlanarGridMap> map;
};

/** \brief One step of the pipeline, applied to every frame in order. \ingroup pipeline
 */
class Stage {
public:
  virtual ~Stage() = default;

  /** \brief Processes one frame.
   * \throws planar_grid::Exception when the frame cannot be processed (e.g. the stage
   *         receives 0 points: a result made of nothing would hide the cause); the
   *         run stops with a message naming the frame */
  virtual void process(Frame& frame, PipelineState& state) = 0;

  /** \brief Called once before the first frame (e.g. to create shared state). */
  virtual void start(PipelineState& /*state*/) {}

  /** \brief Called once after the last frame. */
  virtual void finish(PipelineState& /*state*/) {}

  /** \brief Named per-frame figures of the last processed frame (e.g. "planes"), summed
   * over the run into the report. */
  virtual void counters(const Frame& /*frame*/,
                        std::vector<std::pair<std::string, double>>& /*values*/) const
  {}

  /** \brief Reads back the parameter values the stage's objects hold, through their
   * getters, under the keys of the stage's table (a test checks that a stage made from
   * its table's defaults holds them). Keys whose value no object exposes are left out;
   * stages without parameters add nothing.
   * \param[out] values the keys the stage exposes, set (others untouched) */
  virtual void getParameters(ParamValues& values) const { static_cast<void>(values); }

  /** \brief Points this stage measures in and out of each frame (for the report): the
   * working cloud's valid points by default. */
  virtual bool countsCloudPoints() const { return true; }

  /** \brief Whether process() reads and writes only the frame and the stage's own
   * members, never PipelineState. The runner runs the leading frame-local stages of a
   * pipeline up to two frames ahead on a second thread, one frame after the other in
   * input order (PipelineRunner::setFrameOverlap()), so a member carried from frame to
   * frame sees the frames in order, but ahead of the mapping stages; false by
   * default. */
  virtual bool isFrameLocal() const { return false; }

  /** \brief Whether a checkpoint can hold this stage's state across frames, so that a
   * resumed run continues exactly as an uninterrupted one (true for stages without
   * such state, which is the default). */
  virtual bool supportsCheckpoint() const { return true; }

  /** \brief Appends the state the stage carries from one frame to the next (a
   * checkpoint); stages without such state append nothing.
   * \param[out] bytes appended to */
  virtual void saveState(std::vector<std::uint8_t>& bytes) const { (void)bytes; }

  /** \brief Restores what saveState() wrote (exactly \a size bytes), after start().
   * \throws planar_grid::IOError on invalid data */
  virtual void loadState(const std::uint8_t* /*data*/, std::size_t size)
  {
    if (size != 0)
      throw IOError("checkpoint: " + std::to_string(size)
                    + " bytes of state for a stage that keeps none");
  }
};

/** \brief What a stage reads from its frame (or the run) and what it adds: the
 * loader checks, before the first frame, that every stage's needs are given by the
 * input or by an earlier stage (PipelineConfig). \ingroup pipeline */
enum class StageData {
  /** \brief The rectified left and right images and their calibration (a
   * stereo_sequence input). */
  STEREO_IMAGES,
  /** \brief The working cloud (a pcd_files input, or stereo_disparity). */
  CLOUD,
  /** \brief The disparity image (stereo_disparity). */
  DISPARITY,
  /** \brief The 3D key features (feature_matching from stereo, cloud_features from a
   * point cloud). */
  FEATURES,
  /** \brief The features' occupancy probabilities and track ids
   * (kl_occupancy_filter). */
  FEATURE_OCCUPANCY,
  /** \brief The camera pose of every frame (input.poses, or visual_odometry). */
  POSES,
  /** \brief The working cloud in the world frame (transform_to_world). */
  WORLD_FRAME,
  /** \brief The frame's planes (multi_plane_segmentation). */
  PLANES,
  /** \brief The frame's cells (planar_cuboid_approximation). */
  CUBOIDS,
  /** \brief The run's map (map_integration). */
  MAP,
  /** \brief The accumulated world cloud (accumulate). */
  WORLD_CLOUD,
};

/** \brief The words for \a data in messages and in --list-stages ("stereo key
 * features", "planes"). */
std::string stageDataName(StageData data);

/** \brief The words for a list of stage data, comma-separated ("nothing" when empty).
 */
std::string stageDataNames(const std::vector<StageData>& data);

/** \brief Where a stage sits in the pipeline: in the front end, which works on the
 * stereo images and their key features and never reads the map's minimum cell size,
 * or in the mapping part, from the working cloud to the map, whose parameters may
 * follow the cell size. A tool that maps the same frames at several cell sizes
 * (planar_grid_eval, paper Sec. IV-B) runs the front end once per frame and the
 * mapping stages once per size. \ingroup pipeline */
enum class StageRole {
  /** \brief Disparity, key features, their occupancy and the visual odometry: the
   * same result at every cell size. */
  FRONT_END,
  /** \brief The working cloud's filters, planes, cells, the map and what is
   * accumulated from them. */
  MAPPING,
};

/** \brief A stage type: its name, what it does, its role, its parameter table and a
 * factory. \ingroup pipeline */
struct StageInfo {
  /** \brief The stage type, as written in the YAML `type:` key. */
  std::string type;
  /** \brief One line on what the stage does. */
  std::string description;
  /** \brief The parameter table (keys with units, defaults, ranges). */
  std::vector<ParamSpec> params;
  /** \brief Needs camera poses (a summary for --list-stages; the loader checks
   * `needs`). */
  bool needs_poses{false};
  /** \brief Needs stereo images, not a PCD input (a summary for --list-stages; the
   * loader checks `needs`). */
  bool needs_stereo{false};
  /** \brief What the stage needs from the input or an earlier stage, whatever its
   * parameters (the registry declares it; stageNeeds() adds what parameter values
   * need). */
  std::vector<StageData> needs;
  /** \brief What the stage adds for the later ones. */
  std::vector<StageData> produces;
  /** \brief Front end or mapping stage (the registry declares it). */
  StageRole role{StageRole::MAPPING};
  /** \brief Whether the stage may be listed more than once (filters of the working
   * cloud); any other stage listed twice is a configuration error. */
  bool repeatable{false};
  /** \brief Builds the stage from its parsed parameters. */
  std::function<std::unique_ptr<Stage>(const ParamValues&)> create;
};

/** \brief Every stage type, in a fixed order (the registry: one explicit list, no
 * registration by static initialisers, whose order across files is unspecified). */
const std::vector<StageInfo>& stageRegistry();

/** \brief The registry entry of \a type, or nullptr. */
const StageInfo* findStage(const std::string& type);

/** \brief The known stage types, comma-separated (for error messages). */
std::string knownStageTypes();

/** \brief One thing a configured stage needs from the frames or an earlier stage.
 * \ingroup pipeline */
struct StageNeed {
  /** \brief The data needed. */
  StageData data;
  /** \brief The parameter whose value makes the need (empty: the stage type's own
   * need, StageInfo::needs). */
  std::string param;
  /** \brief A value of \a param without the need (for the error's hint). */
  std::string alternative;
};

/** \brief What stage \a info needs with its parameters \a params (every key of its
 * table present): StageInfo::needs, and the needs parameter values make
 * (multi_plane_segmentation with `sample: features` needs the key features;
 * stereo_disparity with `frame_selection: keyframes` needs the poses). The pipeline
 * loader and Mapper check a stage list's data flow with it. */
std::vector<StageNeed> stageNeeds(const StageInfo& info, const ParamValues& params);

/** \brief The reference page of every stage and parameter, in Markdown
 * (docs/STAGES.md): for each stage of stageRegistry() its description, role, needs and
 * products, and a table of its parameters (key, type, default, range, unit, meaning),
 * all from the stage tables. `planar_grid_pipeline --stage-reference` prints it. */
std::string stageReferenceMarkdown();

} // namespace planar_grid
