// SPDX-License-Identifier: BSD-3-Clause
// The `input:` section of a pipeline configuration (stereo sequences, PCD files, the
// repeat and the poses), and the names of the pose formats.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <initializer_list>
#include <string>
#include <utility>
#include <vector>

#include "input_formats.h"
#include "pipeline_config_parse.h"
#include "ros_bag_input.h"

namespace planar_grid {

namespace {

using Reader = YamlReader;
using config_parse::norm;
using config_parse::vector3;

/** \brief A stereo_sequence input's keys: the image patterns (each with one index
 * field), the frames, the calibration (format, file, and right_file for the formats
 * of two files). */
void
parseStereoSequence(const Reader& r, const YAML::Node& node, InputConfig& input)
{
  r.checkKeys(node,
              {"type", "left_images", "right_images", "first_index", "frame_count",
               "calibration", "poses", "repeat"},
              "input (stereo_sequence)");
  input.type = InputConfig::Type::STEREO_SEQUENCE;
  input.left_images = r.path(node, "left_images", "input");
  input.right_images = r.path(node, "right_images", "input");
  input.first_index = r.integer(node, "first_index", 0, 0, 100000000, "input");
  input.frame_count = r.integer(node, "frame_count", 0, 0, 100000000, "input");
  const YAML::Node calib = node["calibration"];
  if (!calib)
    r.fail(node, "input needs the key 'calibration' (format and file)");
  r.checkKeys(calib, {"format", "file", "right_file"}, "input.calibration");
  const std::string format = r.string(calib, "format", "input.calibration");
  try {
    input.calibration_format = calibrationFormatFromString(format);
  } catch (const Exception&) {
    r.fail(calib["format"],
           "input.calibration.format '" + format
             + "' is unknown; expected one of: " + knownCalibrationFormats());
  }
  input.calibration_file = r.path(calib, "file", "input.calibration");
  const bool pair = input.calibration_format == CalibrationFormat::ROS_CAMERA_INFO
                    || input.calibration_format == CalibrationFormat::EUROC;
  if (pair)
    input.calibration_right_file = r.path(calib, "right_file", "input.calibration");
  else if (calib["right_file"])
    r.fail(calib["right_file"],
           "input.calibration.right_file is only for ros_camera_info and euroc");
  for (const auto* key : {"left_images", "right_images"}) {
    const std::string pattern = node[key].as<std::string>();
    if (pattern.find('%') == std::string::npos)
      r.fail(node[key], std::string("input.") + key
                          + " needs one index field such as %06d in the file name");
  }
}

/** \brief A pcd_files input's keys: the files (a string or a list; glob patterns
 * allowed) and the optional sensor_up. */
void
parsePcdFiles(const Reader& r, const YAML::Node& node, InputConfig& input)
{
  r.checkKeys(node, {"type", "files", "poses", "repeat", "sensor_up"},
              "input (pcd_files)");
  input.type = InputConfig::Type::PCD_FILES;
  input.poses_format = PoseFormat::VIEWPOINT;
  const YAML::Node files = node["files"];
  if (!files)
    r.fail(node, "input needs the key 'files' (a list of PCD files or glob patterns)");
  if (files.IsScalar())
    input.pcd_files.push_back(r.resolve(files.as<std::string>()));
  else if (files.IsSequence()) {
    for (const auto& f : files) {
      if (!f.IsScalar())
        r.fail(f, "input.files entries must be strings");
      input.pcd_files.push_back(r.resolve(f.as<std::string>()));
    }
  } else
    r.fail(files, "input.files must be a string or a list of strings");
  if (input.pcd_files.empty())
    r.fail(files, "input.files is empty");
  if (const YAML::Node up = node["sensor_up"]) {
    input.sensor_up = vector3(r, up, "input.sensor_up");
    if (!(norm(input.sensor_up) > 1e-9))
      r.fail(up, "input.sensor_up must not be zero");
    input.has_sensor_up = true;
  }
}

/** \brief input.repeat: the count and the offset between copies, meters. */
void
parseRepeat(const Reader& r, const YAML::Node& repeat, InputConfig& input)
{
  r.checkKeys(repeat, {"count", "offset_m"}, "input.repeat");
  input.repeat_count = r.integer(repeat, "count", 1, 1, 10000, "input.repeat");
  if (const YAML::Node offset = repeat["offset_m"]) {
    if (!offset.IsSequence() || offset.size() != 3)
      r.fail(offset, "input.repeat.offset_m must be [x, y, z] in meters");
    for (std::size_t k = 0; k < 3; ++k) {
      double v = 0.0;
      try {
        v = offset[k].as<double>();
      } catch (const YAML::BadConversion&) {
        r.fail(offset[k], "input.repeat.offset_m entries must be numbers");
      }
      if (!std::isfinite(v) || std::abs(v) > 1e5)
        r.fail(offset[k], "input.repeat.offset_m entries must be in [-1e5, 1e5] m");
      input.repeat_offset_m[k] = v;
    }
  }
}

/** \brief input.poses: the format (those the input type allows) and each format's
 * own keys. */
void
parsePoses(const Reader& r, const YAML::Node& poses, InputConfig& input)
{
  r.checkKeys(poses,
              {"format", "file", "camera_height_m", "camera_pitch_rad", "leaf_size_m",
               "max_correspondence_distance_m", "feature_initial_guess",
               "max_residual_m"},
              "input.poses");
  using P = PoseFormat;
  input.poses_format =
    readPoseFormat(r, poses,
                   input.type == InputConfig::Type::PCD_FILES
                     ? std::vector<P>{P::VIEWPOINT, P::REGISTRATION, P::KITTI, P::NONE}
                     : std::vector<P>{P::ODOMETRY, P::KARLSRUHE_INSDATA, P::KITTI,
                                      P::EUROC_GROUNDTRUTH, P::NONE},
                   "input");
  // The ground truth is the body's pose: the camera's comes from the EuRoC T_BS and
  // rectification, which only the euroc calibration gives.
  if (input.poses_format == P::EUROC_GROUNDTRUTH
      && input.calibration_format != CalibrationFormat::EUROC)
    r.fail(poses["format"], "input.poses.format euroc_groundtruth needs "
                            "input.calibration.format euroc (the cameras' T_BS)");
  const bool needs_file = input.poses_format == P::KARLSRUHE_INSDATA
                          || input.poses_format == P::KITTI
                          || input.poses_format == P::EUROC_GROUNDTRUTH;
  if (needs_file)
    input.poses_file = r.path(poses, "file", "input.poses");
  else if (poses["file"])
    r.fail(poses["file"], "input.poses.file is not used by format "
                            + poseFormatName(input.poses_format));
  for (const char* key : {"camera_height_m", "camera_pitch_rad"})
    if (poses[key] && input.poses_format != P::KARLSRUHE_INSDATA)
      r.fail(poses[key],
             std::string("input.poses.") + key + " is only for karlsruhe_insdata");
  for (const char* key : {"leaf_size_m", "max_correspondence_distance_m",
                          "feature_initial_guess", "max_residual_m"})
    if (poses[key] && input.poses_format != P::REGISTRATION)
      r.fail(poses[key],
             std::string("input.poses.") + key + " is only for registration");
  input.registration_leaf_size_m = r.real(
    poses, "leaf_size_m", input.registration_leaf_size_m, 0.005, 2.0, "input.poses");
  input.registration_max_correspondence_distance_m =
    r.real(poses, "max_correspondence_distance_m",
           input.registration_max_correspondence_distance_m, 0.01, 10.0, "input.poses");
  input.registration_max_residual_m =
    r.real(poses, "max_residual_m", input.registration_max_residual_m, 0.001, 10.0,
           "input.poses");
  input.registration_feature_initial_guess =
    r.boolean(poses, "feature_initial_guess", input.registration_feature_initial_guess,
              "input.poses");
  input.camera_height_m =
    r.real(poses, "camera_height_m", 0.0, 0.0, 10.0, "input.poses");
  input.camera_pitch_rad =
    r.real(poses, "camera_pitch_rad", 0.0, -1.5, 1.5, "input.poses");
}

} // namespace

namespace config_parse {

InputConfig
parseInput(const YamlReader& r, const YAML::Node& node)
{
  InputConfig input;
  const std::string type = r.string(node, "type", "input");
  // A bag's own schema: its topics, and poses from /tf.
  if (type == "ros_bag")
    return parseRosBagInput(r, node);
  if (type == "stereo_sequence")
    parseStereoSequence(r, node, input);
  else if (type == "pcd_files")
    parsePcdFiles(r, node, input);
  else
    r.fail(node["type"],
           "input.type '" + type
             + "' is unknown; expected stereo_sequence, pcd_files or ros_bag");

  if (const YAML::Node repeat = node["repeat"])
    parseRepeat(r, repeat, input);

  if (const YAML::Node poses = node["poses"])
    parsePoses(r, poses, input);
  // Poses from a file fix the up direction themselves.
  if (input.has_sensor_up && input.poses_format != PoseFormat::VIEWPOINT
      && input.poses_format != PoseFormat::REGISTRATION)
    r.fail(node["sensor_up"], "input.sensor_up is only used with input.poses.format "
                              "viewpoint or registration (poses that do not fix up)");
  return input;
}

} // namespace config_parse

namespace {

/** Every pose format with its name in the configuration. */
const std::pair<PoseFormat, const char*> POSE_FORMATS[] = {
  {PoseFormat::NONE, "none"},
  {PoseFormat::ODOMETRY, "odometry"},
  {PoseFormat::KARLSRUHE_INSDATA, "karlsruhe_insdata"},
  {PoseFormat::KITTI, "kitti"},
  {PoseFormat::EUROC_GROUNDTRUTH, "euroc_groundtruth"},
  {PoseFormat::VIEWPOINT, "viewpoint"},
  {PoseFormat::REGISTRATION, "registration"},
  {PoseFormat::TF, "tf"},
};

} // namespace

PoseFormat
poseFormatFromString(const std::string& name)
{
  std::string known;
  for (const auto& [format, format_name] : POSE_FORMATS) {
    if (name == format_name)
      return format;
    known += (known.empty() ? "" : ", ") + std::string(format_name);
  }
  throw Exception("unknown pose format '" + name + "'; known formats: " + known);
}

std::string
poseFormatName(PoseFormat format)
{
  for (const auto& [known, format_name] : POSE_FORMATS)
    if (known == format)
      return format_name;
  return "?";
}

PoseFormat
readPoseFormat(const YamlReader& r,
               const YAML::Node& poses,
               const std::vector<PoseFormat>& allowed,
               const std::string& input_kind)
{
  const std::string name = r.string(poses, "format", "input.poses");
  std::string list;
  for (const PoseFormat format : allowed)
    list += (list.empty() ? "" : ", ") + poseFormatName(format);
  const auto unknown = [&]() {
    r.fail(poses["format"], "input.poses.format '" + name + "' is unknown for this "
                              + input_kind + "; expected one of: " + list);
  };
  PoseFormat format = PoseFormat::NONE;
  try {
    format = poseFormatFromString(name);
  } catch (const Exception&) {
    unknown();
  }
  if (std::find(allowed.begin(), allowed.end(), format) == allowed.end())
    unknown();
  return format;
}

} // namespace planar_grid
