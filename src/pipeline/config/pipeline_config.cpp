// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <initializer_list>
#include <set>
#include <sstream>
#include <utility>

#include "pipeline_config_parse.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using Reader = YamlReader;
using config_parse::parseInput;
using config_parse::parseOutput;

/** The longest pipeline accepted: each stage type but the filters may appear once, so
 * a real pipeline has about a dozen stages; a list of thousands is a generated or
 * corrupt file. */
constexpr std::size_t MAX_STAGES = 256;

/** The `--set NAME=VALUE` of \a overrides that set \a name (STAGE.KEY, or a top-level
 * key) (the last one), or empty. */
std::string
overrideOf(const std::vector<std::string>& overrides, const std::string& name)
{
  std::string found;
  const std::string prefix = name + "=";
  for (const auto& assignment : overrides)
    if (assignment.compare(0, prefix.size(), prefix) == 0)
      found = assignment;
  return found;
}

/** Applies sharedStageParams(): a key the taking stage leaves out takes the other
 * stage's value; two values set apart are an error at the taking stage's key (at its
 * `--set` when \a overrides set it: its node's place is not in the file). */
void
shareStageParams(const YamlReader& r,
                 const YAML::Node& stage_nodes,
                 std::vector<StageConfig>& stages,
                 const std::vector<std::string>& overrides)
{
  const auto find = [&stages](const std::string& type) -> std::ptrdiff_t {
    for (std::size_t i = 0; i < stages.size(); ++i)
      if (stages[i].type == type)
        return static_cast<std::ptrdiff_t>(i);
    return -1;
  };
  for (const SharedStageParam& shared : sharedStageParams()) {
    const std::ptrdiff_t from = find(shared.from_stage);
    const std::ptrdiff_t to = find(shared.stage);
    if (from < 0 || to < 0)
      continue;
    const YAML::Node from_params =
      stage_nodes[static_cast<std::size_t>(from)]["params"];
    const YAML::Node to_params = stage_nodes[static_cast<std::size_t>(to)]["params"];
    StageConfig& from_stage = stages[static_cast<std::size_t>(from)];
    StageConfig& to_stage = stages[static_cast<std::size_t>(to)];
    const double from_value = from_stage.params.getDouble(shared.from_key);
    const bool to_set = to_params && to_params.IsMap() && to_params[shared.key];
    if (!to_set) {
      to_stage.params.set(shared.key, from_value);
      continue;
    }
    const double to_value = to_stage.params.getDouble(shared.key);
    if (std::abs(to_value - from_value) > 1e-9 * std::max(1.0, std::abs(from_value))) {
      const bool from_set =
        from_params && from_params.IsMap() && from_params[shared.from_key];
      const std::string from_override =
        overrideOf(overrides, shared.from_stage + "." + shared.from_key);
      const std::string message =
        shared.stage + ": " + shared.key + " " + to_stage.params.toString(shared.key)
        + " differs from " + shared.from_stage + "'s " + shared.from_key + " "
        + from_stage.params.toString(shared.from_key)
        + (!from_override.empty() ? " (--set " + from_override + ")"
           : from_set
             ? " (line " + std::to_string(from_params[shared.from_key].Mark().line + 1)
                 + ")"
             : " (its default)")
        + ": " + shared.reason;
      const std::string to_override =
        overrideOf(overrides, shared.stage + "." + shared.key);
      if (!to_override.empty())
        throw ConfigError("--set " + to_override, 0, 0, message);
      r.fail(to_params[shared.key], message);
    }
  }
}

/** What the input gives the first stage: stereo images (and their calibration), or a
 * cloud; poses when input.poses reads them from a file. */
std::vector<StageData>
inputData(const InputConfig& input)
{
  std::vector<StageData> given;
  given.push_back(input.type == InputConfig::Type::STEREO_SEQUENCE
                    ? StageData::STEREO_IMAGES
                    : StageData::CLOUD);
  if (input.poses_format != PoseFormat::NONE
      && input.poses_format != PoseFormat::ODOMETRY)
    given.push_back(StageData::POSES);
  return given;
}

/** Checks, in list order, that every stage's needs are given by the input or an
 * earlier stage, and that only repeatable stages are listed twice; the error is at the
 * stage's type and names what is missing and which stage produces it. */
void
checkDataFlow(const Reader& r,
              const YAML::Node& stage_nodes,
              const PipelineConfig& config)
{
  const std::vector<StageData> from_input = inputData(config.input);
  std::vector<StageData> available = from_input;
  const auto has = [](const std::vector<StageData>& list, StageData d) {
    return std::find(list.begin(), list.end(), d) != list.end();
  };
  const bool stereo = config.input.type == InputConfig::Type::STEREO_SEQUENCE;
  const std::string input_kind = stereo ? "a stereo_sequence" : "a pcd_files";
  for (std::size_t i = 0; i < config.stages.size(); ++i) {
    const StageConfig& sc = config.stages[i];
    const StageInfo& info = *findStage(sc.type);
    const YAML::Node type_node = stage_nodes[i]["type"];
    if (!info.repeatable)
      for (std::size_t k = 0; k < i; ++k)
        if (config.stages[k].type == sc.type) {
          std::string repeatable;
          for (const auto& other : stageRegistry())
            if (other.repeatable)
              repeatable += (repeatable.empty() ? "" : ", ") + other.type;
          r.fail(type_node, "stage '" + sc.type + "' is listed twice (first at line "
                              + std::to_string(config.stages[k].line)
                              + "): the later one would overwrite the earlier one's "
                                "result; only these stages may repeat: "
                              + repeatable);
        }
    // What the input can never give comes first (a missing stage of the same
    // pipeline is the lesser error); then the order.
    const std::vector<StageNeed> needs = stageNeeds(info, sc.params);
    const YAML::Node params_node = stage_nodes[i]["params"];
    for (const bool input_only : {true, false})
      for (const StageNeed& stage_need : needs) {
        const StageData need = stage_need.data;
        if (has(available, need))
          continue;
        // A need a parameter's value makes is reported at that parameter, with the
        // value that has none.
        YAML::Node where = type_node;
        std::string hint;
        if (!stage_need.param.empty()) {
          if (params_node && params_node.IsMap() && params_node[stage_need.param])
            where = params_node[stage_need.param];
          hint = "; or use " + stage_need.param + ": " + stage_need.alternative;
        }
        const std::string what = "stage '" + sc.type + "' needs " + stageDataName(need);
        if (need == StageData::STEREO_IMAGES)
          r.fail(type_node, what + ": it needs a stereo_sequence input (" + input_kind
                              + " input has none)");
        if (need == StageData::POSES && config.input.poses_format == PoseFormat::NONE)
          r.fail(type_node, what + "; set input.poses (format and file)");
        // The stages that produce it, whether one could run on this input at all, and
        // whether one is listed later (the wrong order).
        std::string producers, later;
        bool possible = false;
        for (const auto& other : stageRegistry()) {
          if (!has(other.produces, need))
            continue;
          producers += (producers.empty() ? "'" : " or '") + other.type + "'";
          possible = possible || stereo || !has(other.needs, StageData::STEREO_IMAGES);
          for (std::size_t k = i + 1; k < config.stages.size() && later.empty(); ++k)
            if (config.stages[k].type == other.type)
              later = "'" + other.type + "' is listed after it (line "
                      + std::to_string(config.stages[k].line) + "); ";
        }
        if (!possible)
          r.fail(where, what + ", which only " + producers
                          + " produces, from stereo images: " + input_kind
                          + " input cannot give it" + hint);
        if (!input_only)
          r.fail(where, what + ", which no earlier stage produces: " + later + "put "
                          + producers + " before it" + hint);
      }
    for (const StageData d : info.produces)
      if (!has(available, d))
        available.push_back(d);
  }
}

/** Sets the stages' keys of the minimum cell from the top-level cell_size_m \a cell
 * (stageAtCellSize()). A key that takes the cell size set apart in the file (or by
 * `--set`) to another value is an error at that key; a scaled key that leaves its
 * range is an error at cell_size_m. */
void
applyCellSize(const Reader& r,
              const YAML::Node& cell,
              const YAML::Node& stage_nodes,
              PipelineConfig& config,
              const std::vector<std::string>& overrides)
{
  const double cell_size_m = r.realValue(cell, CELL_SIZE_RANGE, "m", "cell_size_m");
  const std::string from_set = overrideOf(overrides, "cell_size_m");
  const std::string at =
    "cell_size_m " + formatParamNumber(cell_size_m) + " ("
    + (from_set.empty() ? "line " + std::to_string(cell.Mark().line + 1)
                        : "--set " + from_set)
    + ")";
  for (std::size_t i = 0; i < config.stages.size(); ++i) {
    StageConfig& stage = config.stages[i];
    const StageInfo* info = findStage(stage.type);
    const YAML::Node params = stage_nodes[i]["params"];
    for (const ParamSpec& spec : info->params) {
      if (spec.cell_size_scaling != ParamSpec::CellSizeScaling::CELL_SIZE)
        continue;
      const double value = stage.params.getDouble(spec.key);
      if (std::abs(value - cell_size_m) <= 1e-9 * std::max(1.0, cell_size_m))
        continue;
      const std::string message =
        stage.type + ": " + spec.key + " " + stage.params.toString(spec.key)
        + " differs from " + at
        + ": the keys of the minimum cell take cell_size_m; leave the key out";
      const std::string override_text =
        overrideOf(overrides, stage.type + "." + spec.key);
      if (!override_text.empty())
        throw ConfigError("--set " + override_text, 0, 0, message);
      if (params && params.IsMap() && params[spec.key])
        r.fail(params[spec.key], message);
    }
    stage = stageAtCellSize(stage, cell_size_m);
    for (const ParamSpec& spec : info->params) {
      if (spec.cell_size_scaling == ParamSpec::CellSizeScaling::NONE)
        continue;
      const double value = spec.type == ParamSpec::Type::INT
                             ? static_cast<double>(stage.params.getInt(spec.key))
                             : stage.params.getDouble(spec.key);
      if (!spec.range.contains(value))
        r.fail(cell, at + " makes " + stage.type + "." + spec.key + " "
                       + stage.params.toString(spec.key) + ", outside "
                       + formatParamRange(spec.range, spec.unit));
    }
  }
  config.cell_size_m = cell_size_m;
  if (from_set.empty()) {
    config.cell_size_line = cell.Mark().line + 1;
    config.cell_size_column = cell.Mark().column + 1;
  }
}

/** Parses the stage list `pipeline:` of \a root into \a config's stages and checks
 * them against \a config's input (what it gives the first stage, the poses). */
void
parseStages(const Reader& r,
            const YAML::Node& root,
            PipelineConfig& config,
            const std::vector<std::string>& overrides)
{
  const std::string& source = config.source_file;
  const YAML::Node stages = root["pipeline"];
  if (!stages)
    r.fail(root, "the top level needs the key 'pipeline' (a list of {type, params})");
  if (!stages.IsSequence() || stages.size() == 0)
    r.fail(stages, "pipeline must be a non-empty list of {type, params}");
  if (stages.size() > MAX_STAGES)
    r.fail(stages, "pipeline lists " + std::to_string(stages.size())
                     + " stages; at most " + std::to_string(MAX_STAGES)
                     + " are accepted (each stage type but the filters may appear "
                       "once; a pipeline has about a dozen)");
  for (const auto& stage : stages) {
    r.checkKeys(stage, {"type", "params"}, "a pipeline stage");
    StageConfig sc;
    sc.type = r.string(stage, "type", "a pipeline stage");
    sc.line = stage.Mark().line + 1;
    sc.column = stage.Mark().column + 1;
    const StageInfo* info = findStage(sc.type);
    if (!info)
      r.fail(stage["type"],
             "unknown stage type '" + sc.type + "'; known types: " + knownStageTypes());
    const bool odometry = config.input.poses_format == PoseFormat::ODOMETRY;
    if (sc.type == "visual_odometry" && !odometry)
      r.fail(stage["type"],
             "stage 'visual_odometry' makes the poses: set input.poses.format to "
             "odometry");
    sc.params = parseParams(stage["params"], info->params, source, sc.type);
    if (const YAML::Node params = stage["params"]; params && params.IsMap())
      for (const auto& entry : params)
        sc.param_marks[entry.first.as<std::string>()] = {
          entry.second.Mark().line + 1, entry.second.Mark().column + 1};
    // Key features come from stereo matching or from cloud_features: the planes of a
    // point-cloud input are hypothesised on the cloud itself unless the file asks for
    // features (checkDataFlow() then requires a stage before it that gives them).
    if (sc.type == "multi_plane_segmentation"
        && config.input.type != InputConfig::Type::STEREO_SEQUENCE) {
      const YAML::Node params = stage["params"];
      if (!(params && params.IsMap() && params["sample"]))
        sc.params.set("sample", std::string("cloud"));
    }
    if (sc.type == "stereo_disparity"
        && sc.params.getChoice("frame_selection") == "keyframes"
        && sc.params.getInt("every_n_frames") != 1) {
      const YAML::Node params = stage["params"];
      r.fail(params && params.IsMap() && params["every_n_frames"]
               ? params["every_n_frames"]
               : stage["type"],
             "stereo_disparity: every_n_frames applies to frame_selection "
             "every_n_frames; with keyframes the keyframe_* parameters choose the "
             "dense frames");
    }
    config.stages.push_back(std::move(sc));
  }
  checkDataFlow(r, stages, config);
  shareStageParams(r, stages, config.stages, overrides);
  if (const YAML::Node cell = root["cell_size_m"])
    applyCellSize(r, cell, stages, config, overrides);
}

PipelineConfig
parseRoot(const YAML::Node& root,
          const std::string& source,
          const std::string& base,
          const std::vector<std::string>& overrides)
{
  const Reader r(source, base);
  if (!root || root.IsNull())
    throw ConfigError(source, 0, 0,
                      "the file is empty; expected input:, pipeline:, output:");
  r.checkKeys(root, {"input", "cell_size_m", "pipeline", "output"}, "the top level");
  PipelineConfig config;
  config.source_file = source;

  const YAML::Node input = root["input"];
  if (!input)
    r.fail(root, "the top level needs the key 'input'");
  r.requireMap(input, "input");
  config.input = parseInput(r, input);

  parseStages(r, root, config, overrides);

  if (const YAML::Node output = root["output"])
    config.output = parseOutput(r, output, config.input);
  return config;
}

/** The stages of a document holding only `pipeline:`, checked as a file's are
 * against the frames a Mapper takes: stereo pairs when a stage reads stereo images,
 * else point clouds, each with its pose unless a visual_odometry stage makes it. */
MapperConfig
parseMapperRoot(const YAML::Node& root,
                const std::string& source,
                const std::string& base,
                const std::vector<std::string>& overrides)
{
  const Reader r(source, base);
  if (!root || root.IsNull())
    throw ConfigError(source, 0, 0, "the stages are empty; expected pipeline:");
  r.checkKeys(root, {"cell_size_m", "pipeline"}, "a mapper's stages");
  PipelineConfig config;
  config.source_file = source;
  bool stereo = false, odometry = false;
  if (const YAML::Node stages = root["pipeline"]; stages && stages.IsSequence())
    for (const auto& stage : stages) {
      // Malformed entries are reported by parseStages().
      if (!stage.IsMap() || !stage["type"] || !stage["type"].IsScalar())
        continue;
      const StageInfo* info = findStage(stage["type"].Scalar());
      stereo = stereo
               || (info
                   && std::find(info->needs.begin(), info->needs.end(),
                                StageData::STEREO_IMAGES)
                        != info->needs.end());
      odometry = odometry || stage["type"].Scalar() == "visual_odometry";
    }
  config.input.type =
    stereo ? InputConfig::Type::STEREO_SEQUENCE : InputConfig::Type::PCD_FILES;
  // The caller gives each frame's pose (as a tf chain would: from outside the
  // pipeline), unless the visual_odometry stage estimates it.
  config.input.poses_format = odometry ? PoseFormat::ODOMETRY : PoseFormat::TF;
  parseStages(r, root, config, overrides);
  return toMapperConfig(config);
}

/** Puts `STAGE.KEY=VALUE` into the params of the one stage of that type under \a
 * root's pipeline, after checking the value against the stage's table. */
void
applyOverride(YAML::Node& root, const std::string& assignment)
{
  const std::string where = "--set " + assignment;
  const std::size_t dot = assignment.find('.');
  const std::size_t equals = assignment.find('=');
  if (equals != std::string::npos
      && assignment.compare(0, equals, "cell_size_m") == 0) {
    // The one top-level key --set takes: checked here, where its text is.
    const std::string value = assignment.substr(equals + 1);
    double cell_size_m = 0.0;
    std::istringstream in(value);
    if (!(in >> cell_size_m) || !(in >> std::ws).eof()
        || !CELL_SIZE_RANGE.contains(cell_size_m))
      throw ConfigError(where, 0, 0,
                        "cell_size_m must be a number in "
                          + formatParamRange(CELL_SIZE_RANGE, "m") + ", got '" + value
                          + "'");
    root["cell_size_m"] = cell_size_m;
    return;
  }
  if (dot == std::string::npos || equals == std::string::npos || dot == 0
      || equals < dot + 2)
    throw ConfigError(where, 0, 0,
                      "expected STAGE.KEY=VALUE, e.g. "
                      "stereo_disparity.num_disparities_px=96, or cell_size_m=R");
  const std::string type = assignment.substr(0, dot);
  const std::string key = assignment.substr(dot + 1, equals - dot - 1);
  const std::string value = assignment.substr(equals + 1);
  const StageInfo* info = findStage(type);
  if (!info)
    throw ConfigError(where, 0, 0,
                      "unknown stage type '" + type + "'; known: " + knownStageTypes());
  // The value is checked as the file's would be: a one-key params map.
  YAML::Node params;
  try {
    params = YAML::Load(key + ": " + value);
  } catch (const YAML::Exception& e) {
    throw ConfigError(where, 0, 0, "the value '" + value + "' is not YAML: " + e.msg);
  }
  if (!params.IsMap() || params.size() != 1)
    throw ConfigError(where, 0, 0, "the value '" + value + "' must be one scalar");
  try {
    parseParams(params, info->params, where, type);
  } catch (const ConfigError& e) {
    // Its line:col would point into "KEY: VALUE", not into a file.
    throw ConfigError(where, 0, 0, e.message());
  }
  YAML::Node pipeline = root["pipeline"];
  YAML::Node target;
  std::size_t found = 0;
  if (pipeline && pipeline.IsSequence())
    for (std::size_t i = 0; i < pipeline.size(); ++i) {
      YAML::Node stage = pipeline[i];
      if (stage.IsMap() && stage["type"] && stage["type"].IsScalar()
          && stage["type"].Scalar() == type) {
        target = stage;
        ++found;
      }
    }
  if (found != 1)
    throw ConfigError(where, 0, 0,
                      found == 0 ? "the pipeline has no stage '" + type + "'"
                                 : "the pipeline lists stage '" + type + "' "
                                     + std::to_string(found)
                                     + " times; --set needs exactly one");
  if (!target["params"] || target["params"].IsNull())
    target["params"] = YAML::Node(YAML::NodeType::Map);
  target["params"][key] = params[key];
}

} // namespace

PipelineConfig
parsePipelineConfig(const std::string& yaml_text,
                    const std::string& source_name,
                    const std::string& base_folder,
                    const std::vector<std::string>& overrides)
{
  YAML::Node root = loadYamlDocument(yaml_text, source_name);
  if (root.IsMap()) // otherwise parseRoot() names what the file lacks
    for (const auto& assignment : overrides)
      applyOverride(root, assignment);
  try {
    return parseRoot(root, source_name, base_folder, overrides);
  } catch (const YAML::Exception& e) {
    // A conversion the schema checks did not foresee (found by fuzz_pipeline_config):
    // still an error at the node's line:col, never a yaml-cpp exception.
    throw ConfigError(source_name, e.mark.is_null() ? 0 : e.mark.line + 1,
                      e.mark.is_null() ? 0 : e.mark.column + 1, e.msg);
  }
}

MapperConfig
parseMapperConfig(const std::string& yaml_text,
                  const std::string& source_name,
                  const std::string& base_folder)
{
  const YAML::Node root = loadYamlDocument(yaml_text, source_name);
  try {
    return parseMapperRoot(root, source_name, base_folder, {});
  } catch (const YAML::Exception& e) {
    throw ConfigError(source_name, e.mark.is_null() ? 0 : e.mark.line + 1,
                      e.mark.is_null() ? 0 : e.mark.column + 1, e.msg);
  }
}

PipelineConfig
loadPipelineConfig(const std::string& path)
{
  return loadPipelineConfig(path, {});
}

PipelineConfig
loadPipelineConfig(const std::string& path, const std::vector<std::string>& overrides)
{
  const std::string text = readConfigFile(path);
  const fs::path p(path);
  const std::string base =
    p.has_parent_path() ? p.parent_path().string() : std::string(".");
  return parsePipelineConfig(text, path, base, overrides);
}

StageConfig
stageAtCellSize(const StageConfig& stage, double cell_size_m, double from_cell_size_m)
{
  const StageInfo* info = findStage(stage.type);
  if (!info)
    throw Exception("unknown stage type '" + stage.type + "'");
  const double ratio = cell_size_m / from_cell_size_m;
  StageConfig scaled = stage;
  ParamValues& params = scaled.params;
  for (const ParamSpec& spec : info->params)
    switch (spec.cell_size_scaling) {
      case ParamSpec::CellSizeScaling::NONE:
        break;
      case ParamSpec::CellSizeScaling::CELL_SIZE:
        params.set(spec.key, cell_size_m);
        break;
      case ParamSpec::CellSizeScaling::POINTS_PER_AREA: {
        // The same surface area: the voxel count falls with the square of the size.
        const double count = params.getInt(spec.key) / (ratio * ratio);
        params.set(spec.key, std::max(10, static_cast<int>(std::lround(count))));
        break;
      }
      case ParamSpec::CellSizeScaling::LENGTH:
        params.set(spec.key, params.getDouble(spec.key) * ratio);
        break;
    }
  return scaled;
}

const std::vector<SharedStageParam>&
sharedStageParams()
{
  static const std::string reason =
    "the map's raster and the cells share the paper's minimum cell; leave the map's "
    "key out to take the cells' value";
  static const std::vector<SharedStageParam> shared{
    {"map_integration", "resolution_m", "planar_cuboid_approximation",
     "min_cell_size_m", reason},
    {"map_integration", "thickness_m", "planar_cuboid_approximation", "thickness_m",
     reason},
    {"multi_plane_segmentation", "min_sensor_height_m", "ground_removal",
     "min_sensor_height_m",
     "the segmentation spares as terrain the level planes the ground removal can "
     "take as ground, those at least this far below the sensor; leave the "
     "segmentation's key out to take the ground removal's value"},
    {"map_integration", "terrain_plane_tile_m", "ground_removal",
     "terrain_plane_tile_m",
     "the map bounds its level planes to the tiles the ground removal splits the "
     "terrain at; leave the map's key out to take the ground removal's value"},
  };
  return shared;
}

MapperConfig
toMapperConfig(const PipelineConfig& config)
{
  MapperConfig mapper;
  mapper.name = config.source_file;
  for (const StageConfig& sc : config.stages)
    mapper.stages.push_back({sc.type, sc.params, sc.line, sc.column});
  return mapper;
}

MapperConfig
loadMapperConfig(const std::string& path)
{
  return toMapperConfig(loadPipelineConfig(path));
}

} // namespace planar_grid
