// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/pipeline/stage.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <sstream>
#include <string>
#include <type_traits>
#include <variant>

namespace planar_grid {

namespace {

/** \brief The shortest text that reads back as exactly \a value. */
std::string
shortest(double value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** \brief A parameter value as the YAML scalar the loader reads. */
std::string
scalar(const std::variant<double, int, bool, std::string>& value)
{
  return std::visit(
    [](const auto& v) -> std::string {
      using V = std::decay_t<decltype(v)>;
      if constexpr (std::is_same_v<V, std::string>)
        return v;
      else if constexpr (std::is_same_v<V, bool>)
        return v ? "true" : "false";
      else if constexpr (std::is_same_v<V, int>)
        return std::to_string(v);
      else
        return shortest(v);
    },
    value);
}

/** \brief Writes `key: [x, y, z]`. */
void
emitVector(YAML::Emitter& out, const char* key, const std::array<double, 3>& v)
{
  out << YAML::Key << key << YAML::Value << YAML::Flow << YAML::BeginSeq;
  for (const double x : v)
    out << shortest(x);
  out << YAML::EndSeq;
}

void
emitInput(YAML::Emitter& out, const InputConfig& input)
{
  if (!input.ros_bag.file.empty() || input.type != InputConfig::Type::STEREO_SEQUENCE)
    throw Exception("pipelineConfigToYaml: only a stereo_sequence input is written, "
                    "not a pcd_files or ros_bag input");
  out << YAML::Key << "input" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << "stereo_sequence";
  out << YAML::Key << "left_images" << YAML::Value << input.left_images;
  out << YAML::Key << "right_images" << YAML::Value << input.right_images;
  out << YAML::Key << "first_index" << YAML::Value << input.first_index;
  out << YAML::Key << "frame_count" << YAML::Value << input.frame_count;

  out << YAML::Key << "calibration" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "format" << YAML::Value
      << calibrationFormatName(input.calibration_format);
  out << YAML::Key << "file" << YAML::Value << input.calibration_file;
  if (input.calibration_format == CalibrationFormat::ROS_CAMERA_INFO
      || input.calibration_format == CalibrationFormat::EUROC)
    out << YAML::Key << "right_file" << YAML::Value << input.calibration_right_file;
  out << YAML::EndMap;

  if (input.poses_format != PoseFormat::NONE) {
    out << YAML::Key << "poses" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "format" << YAML::Value << poseFormatName(input.poses_format);
    if (input.poses_format == PoseFormat::KARLSRUHE_INSDATA
        || input.poses_format == PoseFormat::KITTI
        || input.poses_format == PoseFormat::EUROC_GROUNDTRUTH)
      out << YAML::Key << "file" << YAML::Value << input.poses_file;
    if (input.poses_format == PoseFormat::KARLSRUHE_INSDATA) {
      out << YAML::Key << "camera_height_m" << YAML::Value
          << shortest(input.camera_height_m);
      out << YAML::Key << "camera_pitch_rad" << YAML::Value
          << shortest(input.camera_pitch_rad);
    }
    out << YAML::EndMap;
  }

  const InputConfig defaults;
  if (input.repeat_count != defaults.repeat_count
      || input.repeat_offset_m != defaults.repeat_offset_m) {
    out << YAML::Key << "repeat" << YAML::Value << YAML::BeginMap;
    out << YAML::Key << "count" << YAML::Value << input.repeat_count;
    emitVector(out, "offset_m", input.repeat_offset_m);
    out << YAML::EndMap;
  }
  out << YAML::EndMap;
}

void
emitStage(YAML::Emitter& out, const StageConfig& stage)
{
  const StageInfo* info = findStage(stage.type);
  if (!info)
    throw Exception("pipelineConfigToYaml: unknown stage type '" + stage.type
                    + "'; known types: " + knownStageTypes());
  const ParamValues defaults = defaultParams(info->params);
  for (const auto& entry : stage.params.values()) {
    if (defaults.values().count(entry.first) == 0) {
      std::string keys;
      for (const auto& spec : info->params)
        keys += (keys.empty() ? "" : ", ") + spec.key;
      throw Exception("pipelineConfigToYaml: stage " + stage.type
                      + " has no parameter '" + entry.first
                      + "'; its parameters: " + keys);
    }
  }
  out << YAML::BeginMap;
  out << YAML::Key << "type" << YAML::Value << stage.type;
  bool any = false;
  // In the table's order, as --list-stages shows them.
  for (const auto& spec : info->params) {
    const auto it = stage.params.values().find(spec.key);
    if (it == stage.params.values().end())
      continue;
    const std::string text = scalar(it->second);
    if (text == scalar(defaults.values().at(spec.key)))
      continue;
    if (!any)
      out << YAML::Key << "params" << YAML::Value << YAML::BeginMap;
    any = true;
    out << YAML::Key << spec.key << YAML::Value << text;
  }
  if (any)
    out << YAML::EndMap;
  out << YAML::EndMap;
}

void
emitStreetView(YAML::Emitter& out, const StreetViewConfig& view)
{
  const StreetViewConfig defaults;
  out << YAML::Key << "street_view" << YAML::Value << YAML::BeginMap;
  if (view.view_angle_deg != defaults.view_angle_deg)
    out << YAML::Key << "view_angle_deg" << YAML::Value
        << shortest(view.view_angle_deg);
  if (view.up != defaults.up)
    emitVector(out, "up", view.up);
  if (view.fixed) {
    emitVector(out, "position_m", view.position_m);
    emitVector(out, "focal_point_m", view.focal_point_m);
  } else {
    if (view.pose_fraction != defaults.pose_fraction)
      out << YAML::Key << "pose_fraction" << YAML::Value
          << shortest(view.pose_fraction);
    if (view.pitch_rad != defaults.pitch_rad)
      out << YAML::Key << "pitch_rad" << YAML::Value << shortest(view.pitch_rad);
    if (view.look_ahead_m != defaults.look_ahead_m)
      out << YAML::Key << "look_ahead_m" << YAML::Value << shortest(view.look_ahead_m);
  }
  out << YAML::EndMap;
}

void
emitOutput(YAML::Emitter& out, const OutputConfig& output)
{
  const OutputConfig defaults;
  out << YAML::Key << "output" << YAML::Value << YAML::BeginMap;
  out << YAML::Key << "folder" << YAML::Value << output.folder;
  const auto text = [&](const char* key, const std::string OutputConfig::*field) {
    if (output.*field != defaults.*field)
      out << YAML::Key << key << YAML::Value << output.*field;
  };
  text("cloud", &OutputConfig::cloud);
  text("planes", &OutputConfig::planes);
  text("report", &OutputConfig::report);
  text("trajectory", &OutputConfig::trajectory);
  text("snapshot", &OutputConfig::snapshot);
  text("planes_snapshot", &OutputConfig::planes_snapshot);
  text("cuboids_snapshot", &OutputConfig::cuboids_snapshot);
  text("cuboids_street_snapshot", &OutputConfig::cuboids_street_snapshot);
  text("snapshot_camera", &OutputConfig::snapshot_camera);
  // The loader refuses a street_view that no snapshot uses.
  if (!output.cuboids_street_snapshot.empty() || output.snapshot_camera == "street")
    emitStreetView(out, output.street_view);
  if (output.snapshot_size_px != defaults.snapshot_size_px)
    out << YAML::Key << "snapshot_size_px" << YAML::Value << YAML::Flow
        << YAML::BeginSeq << output.snapshot_size_px[0] << output.snapshot_size_px[1]
        << YAML::EndSeq;
  text("map", &OutputConfig::map);
  text("map_octomap", &OutputConfig::map_octomap);
  text("map_mesh", &OutputConfig::map_mesh);
  text("map_grid_2d", &OutputConfig::map_grid_2d);
  if (!output.map_grid_2d.empty()) {
    const OccupancyGrid2DParams& band = output.map_grid_2d_band;
    const OccupancyGrid2DParams unset;
    constexpr double DEG = M_PI / 180.0;
    out << YAML::Key << "map_grid_2d_band" << YAML::Value << YAML::BeginMap;
    const auto real = [&](const char* key, double value, double fallback) {
      if (value != fallback)
        out << YAML::Key << key << YAML::Value << shortest(value);
    };
    real("z_ref_m", band.z_ref_m, unset.z_ref_m);
    real("z_min_m", band.z_min_m, unset.z_min_m);
    real("z_max_m", band.z_max_m, unset.z_max_m);
    if (band.above_terrain != unset.above_terrain)
      out << YAML::Key << "above_terrain" << YAML::Value << band.above_terrain;
    real("terrain_tile_m", band.terrain_tile_m, unset.terrain_tile_m);
    real("resolution_m", band.resolution_m, unset.resolution_m);
    real("max_slope_deg", band.max_slope_rad / DEG, unset.max_slope_rad / DEG);
    real("terrain_max_angle_deg", band.terrain_max_angle_rad / DEG,
         unset.terrain_max_angle_rad / DEG);
    out << YAML::EndMap;
  }
  text("map_snapshot", &OutputConfig::map_snapshot);
  text("checkpoint", &OutputConfig::checkpoint);
  if (output.checkpoint_every_n_frames != defaults.checkpoint_every_n_frames)
    out << YAML::Key << "checkpoint_every_n_frames" << YAML::Value
        << std::to_string(output.checkpoint_every_n_frames);
  out << YAML::EndMap;
}

/** \brief \a text as `#` comment lines of at most \a width characters (a longer word
 * stays whole), each starting with \a indent, then `# `, then \a hang after the
 * first line. */
std::string
commentLines(const std::string& text,
             const std::string& indent,
             const std::string& hang = "",
             std::size_t width = 88)
{
  std::istringstream words(text);
  std::string word;
  std::string line;
  std::string out;
  const std::string first = indent + "# ";
  const std::string next = first + hang;
  while (words >> word) {
    const std::string& start = out.empty() ? first : next;
    if (!line.empty() && (start + line + " " + word).size() > width) {
      out += start + line + "\n";
      line.clear();
    }
    line += (line.empty() ? "" : " ") + word;
  }
  if (!line.empty())
    out += (out.empty() ? first : next) + line + "\n";
  return out;
}

/** \brief What a parameter accepts, in words: its type, range and unit. */
std::string
acceptedValues(const ParamSpec& spec)
{
  const std::string range = formatParamRange(spec);
  if (range.empty())
    return formatParamType(spec, " | ");
  const std::string unit = spec.unit.empty() ? "" : ", " + spec.unit;
  return formatParamType(spec, " | ") + " in " + range + unit;
}

} // namespace

std::string
defaultPipelineYaml()
{
  std::string out =
    "# Generated by `planar_grid_pipeline --print-default-pipeline` from the stage "
    "tables\n"
    "# that the loader checks against: every stage type, in pipeline order, with "
    "every\n"
    "# parameter at its default. Keep the stages a run needs, in this order.\n"
    "pipeline:\n";
  for (const StageInfo& info : stageRegistry()) {
    out += "\n" + commentLines(info.type + ": " + info.description, "  ", "  ");
    out += commentLines(
      std::string(info.role == StageRole::FRONT_END ? "Front end" : "Mapping")
        + " stage" + (info.needs_poses ? " [needs input poses]" : "")
        + (info.needs_stereo ? " [needs stereo input]" : "") + "; needs "
        + stageDataNames(info.needs) + "; produces " + stageDataNames(info.produces)
        + (info.repeatable ? "; may be listed twice." : "."),
      "  ", "  ");
    out += "  - type: " + info.type + "\n";
    if (info.params.empty())
      continue;
    out += "    params:\n";
    for (const ParamSpec& spec : info.params) {
      const auto shared =
        std::find_if(sharedStageParams().begin(), sharedStageParams().end(),
                     [&](const SharedStageParam& p) {
                       return p.stage == info.type && p.key == spec.key;
                     });
      std::string text = spec.description;
      if (shared != sharedStageParams().end())
        // Left out, it follows the other stage's value, which a reader may change.
        text += " Left out (as here), it is " + shared->from_stage + "'s "
                + shared->from_key + "; set in both, the two must be equal.";
      out += commentLines(text, "      ");
      out += "      # " + acceptedValues(spec) + "\n";
      out += std::string(shared != sharedStageParams().end() ? "      # " : "      ")
             + spec.key + ": " + spec.default_value + "\n";
    }
  }
  out += "# End of the generated stage list.\n";
  return out;
}

StageConfig
defaultStageConfig(const std::string& type)
{
  const StageInfo* info = findStage(type);
  if (!info)
    throw Exception("defaultStageConfig: unknown stage type '" + type
                    + "'; known types: " + knownStageTypes());
  StageConfig stage;
  stage.type = type;
  stage.params = defaultParams(info->params);
  return stage;
}

std::string
pipelineConfigToYaml(const PipelineConfig& config, const std::string& comment)
{
  YAML::Emitter out;
  if (!comment.empty())
    out << YAML::Comment(comment) << YAML::Newline;
  out << YAML::BeginMap;
  emitInput(out, config.input);
  out << YAML::Key << "pipeline" << YAML::Value << YAML::BeginSeq;
  for (const auto& stage : config.stages)
    emitStage(out, stage);
  out << YAML::EndSeq;
  emitOutput(out, config.output);
  out << YAML::EndMap;
  if (!out.good())
    throw Exception("pipelineConfigToYaml: the YAML emitter failed: "
                    + out.GetLastError());
  std::string text = std::string(out.c_str()) + "\n";
  // Refused here rather than when the file is run.
  parsePipelineConfig(text, "the generated pipeline configuration", ".");
  return text;
}

} // namespace planar_grid
