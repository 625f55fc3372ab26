// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/output_transaction.h>
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

#include "input_formats.h"
#include "ros_bag_input.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using Reader = YamlReader;

/** The longest pipeline accepted: each stage type but the filters may appear once, so
 * a real pipeline has about a dozen stages; a list of thousands is a generated or
 * corrupt file. */
constexpr std::size_t MAX_STAGES = 256;

std::array<double, 3>
vector3(const Reader& r, const YAML::Node& node, const std::string& what);
double norm(const std::array<double, 3>& v);

InputConfig
parseInput(const Reader& r, const YAML::Node& node)
{
  InputConfig input;
  const std::string type = r.string(node, "type", "input");
  // A bag's own schema: its topics, and poses from /tf.
  if (type == "ros_bag")
    return parseRosBagInput(r, node);
  if (type == "stereo_sequence") {
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
  } else if (type == "pcd_files") {
    r.checkKeys(node, {"type", "files", "poses", "repeat", "sensor_up"},
                "input (pcd_files)");
    input.type = InputConfig::Type::PCD_FILES;
    input.poses_format = PoseFormat::VIEWPOINT;
    const YAML::Node files = node["files"];
    if (!files)
      r.fail(node,
             "input needs the key 'files' (a list of PCD files or glob patterns)");
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
  } else
    r.fail(node["type"],
           "input.type '" + type
             + "' is unknown; expected stereo_sequence, pcd_files or ros_bag");

  if (const YAML::Node repeat = node["repeat"]) {
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

  if (const YAML::Node poses = node["poses"]) {
    r.checkKeys(poses,
                {"format", "file", "camera_height_m", "camera_pitch_rad", "leaf_size_m",
                 "max_correspondence_distance_m", "feature_initial_guess",
                 "max_residual_m"},
                "input.poses");
    using P = PoseFormat;
    input.poses_format = readPoseFormat(
      r, poses,
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
    input.registration_max_correspondence_distance_m = r.real(
      poses, "max_correspondence_distance_m",
      input.registration_max_correspondence_distance_m, 0.01, 10.0, "input.poses");
    input.registration_max_residual_m =
      r.real(poses, "max_residual_m", input.registration_max_residual_m, 0.001, 10.0,
             "input.poses");
    input.registration_feature_initial_guess =
      r.boolean(poses, "feature_initial_guess",
                input.registration_feature_initial_guess, "input.poses");
    input.camera_height_m =
      r.real(poses, "camera_height_m", 0.0, 0.0, 10.0, "input.poses");
    input.camera_pitch_rad =
      r.real(poses, "camera_pitch_rad", 0.0, -1.5, 1.5, "input.poses");
  }
  // Poses from a file fix the up direction themselves.
  if (input.has_sensor_up && input.poses_format != PoseFormat::VIEWPOINT
      && input.poses_format != PoseFormat::REGISTRATION)
    r.fail(node["sensor_up"], "input.sensor_up is only used with input.poses.format "
                              "viewpoint or registration (poses that do not fix up)");
  return input;
}

/** \brief Three finite numbers in [-1e6, 1e6] from the list \a node. */
std::array<double, 3>
vector3(const Reader& r, const YAML::Node& node, const std::string& what)
{
  if (!node.IsSequence() || node.size() != 3)
    r.fail(node, what + " must be a list [x, y, z]");
  std::array<double, 3> v{};
  for (std::size_t k = 0; k < 3; ++k)
    v[k] = r.realValue(node[k], -1e6, 1e6, what + " entries");
  return v;
}

double
norm(const std::array<double, 3>& v)
{
  return std::sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
}

StreetViewConfig
parseStreetView(const Reader& r, const YAML::Node& node)
{
  const std::string what = "output.street_view";
  r.requireMap(node, what);
  r.checkKeys(node,
              {"pose_fraction", "pitch_rad", "look_ahead_m", "view_angle_deg", "up",
               "position_m", "focal_point_m"},
              what);
  StreetViewConfig view;
  view.view_angle_deg =
    r.real(node, "view_angle_deg", view.view_angle_deg, 5.0, 120.0, what);
  if (const YAML::Node up = node["up"]) {
    view.up = vector3(r, up, what + ".up");
    if (!(norm(view.up) > 0.0))
      r.fail(up, what + ".up must not be zero");
  }
  const YAML::Node position = node["position_m"];
  const YAML::Node focal_point = node["focal_point_m"];
  if (position || focal_point) {
    // A fixed camera: the keys that place a following camera have no meaning.
    if (!position || !focal_point)
      r.fail(position ? position : focal_point,
             what + ": a fixed camera needs both position_m and focal_point_m");
    for (const char* key : {"pose_fraction", "pitch_rad", "look_ahead_m"})
      if (node[key])
        r.fail(node[key], what + "." + key
                            + " is not used by a fixed camera (position_m, "
                              "focal_point_m); give one or the other");
    view.fixed = true;
    view.position_m = vector3(r, position, what + ".position_m");
    view.focal_point_m = vector3(r, focal_point, what + ".focal_point_m");
    const Eigen::Vector3d direction = Eigen::Vector3d(view.focal_point_m.data())
                                      - Eigen::Vector3d(view.position_m.data());
    const Eigen::Vector3d up(view.up.data());
    if (!(direction.norm() > 1e-6))
      r.fail(focal_point, what + ".focal_point_m must differ from position_m");
    if (up.normalized().cross(direction.normalized()).norm() < 1e-6)
      r.fail(node["up"] ? node["up"] : focal_point,
             what
               + ".up must not be parallel to the viewing direction "
                 "(focal_point_m - position_m)");
    return view;
  }
  view.pose_fraction =
    r.real(node, "pose_fraction", view.pose_fraction, 0.0, 1.0, what);
  view.look_ahead_m =
    r.real(node, "look_ahead_m", view.look_ahead_m, 1.0, 1000.0, what);
  view.pitch_rad = r.real(node, "pitch_rad", view.pitch_rad, 0.0, 1.6, what);
  // The image's top edge must look down at the street and its bottom edge forwards.
  const double half_view_rad = 0.5 * view.view_angle_deg * M_PI / 180.0;
  if (!(view.pitch_rad > half_view_rad
        && view.pitch_rad < 0.5 * M_PI - half_view_rad)) {
    std::ostringstream msg;
    msg << what << ".pitch_rad = " << view.pitch_rad << " must be in (" << half_view_rad
        << ", " << 0.5 * M_PI - half_view_rad << ") for view_angle_deg "
        << view.view_angle_deg
        << ": more than half the view angle (the top of the image looks down) and "
           "less than pi/2 minus half of it (the bottom looks forwards)";
    r.fail(node["pitch_rad"] ? node["pitch_rad"] : node, msg.str());
  }
  return view;
}

OccupancyGrid2DParams
parseGrid2DBand(const Reader& r, const YAML::Node& node)
{
  const std::string what = "output.map_grid_2d_band";
  r.requireMap(node, what);
  r.checkKeys(node,
              {"z_ref_m", "z_min_m", "z_max_m", "above_terrain", "terrain_tile_m",
               "resolution_m", "max_slope_deg", "terrain_max_angle_deg"},
              what);
  OccupancyGrid2DParams band;
  constexpr double DEG = M_PI / 180.0;
  band.z_ref_m = r.real(node, "z_ref_m", band.z_ref_m, -1e4, 1e4, what);
  band.z_min_m = r.real(node, "z_min_m", band.z_min_m, -1e3, 1e3, what);
  band.z_max_m = r.real(node, "z_max_m", band.z_max_m, -1e3, 1e3, what);
  if (!(band.z_max_m > band.z_min_m))
    r.fail(node["z_max_m"] ? node["z_max_m"] : node["z_min_m"],
           what + ".z_max_m must be above z_min_m");
  band.above_terrain = r.boolean(node, "above_terrain", band.above_terrain, what);
  band.terrain_tile_m =
    r.real(node, "terrain_tile_m", band.terrain_tile_m, 0.01, 100.0, what);
  band.resolution_m = r.real(node, "resolution_m", band.resolution_m, 0.0, 100.0, what);
  if (band.resolution_m > 0.0 && band.resolution_m < 0.001)
    r.fail(node["resolution_m"],
           what + ".resolution_m must be 0 (the map's) or >= 0.001");
  band.max_slope_rad =
    r.real(node, "max_slope_deg", band.max_slope_rad / DEG, 0.0, 90.0, what) * DEG;
  band.terrain_max_angle_rad = r.real(node, "terrain_max_angle_deg",
                                      band.terrain_max_angle_rad / DEG, 0.0, 90.0, what)
                               * DEG;
  return band;
}

OutputConfig
parseOutput(const Reader& r, const YAML::Node& node, const InputConfig& input)
{
  OutputConfig out;
  r.checkKeys(node,
              {"folder",
               "cloud",
               "planes",
               "report",
               "trajectory",
               "snapshot",
               "planes_snapshot",
               "cuboids_snapshot",
               "cuboids_street_snapshot",
               "snapshot_camera",
               "street_view",
               "snapshot_size_px",
               "map",
               "map_octomap",
               "map_mesh",
               "map_grid_2d",
               "map_grid_2d_band",
               "map_snapshot",
               "checkpoint",
               "checkpoint_every_n_frames"},
              "output");
  out.folder = r.optionalString(node, "folder", out.folder, "output");
  {
    // Known now, not after the last frame (the tool checks a --output folder the same
    // way when it opens the output set, still before the first frame).
    std::error_code ec;
    // An empty name would write the outputs into the current folder.
    if (node["folder"] && out.folder.empty())
      r.fail(node["folder"], "output.folder is empty: name the folder to write the "
                             "outputs into");
    if (node["folder"] && fs::exists(out.folder, ec)
        && !fs::is_directory(out.folder, ec))
      r.fail(node["folder"], "output.folder '" + out.folder
                               + "' is a file, not a folder: the outputs cannot be "
                                 "written there");
  }
  out.cloud = r.optionalString(node, "cloud", out.cloud, "output");
  out.report = r.optionalString(node, "report", out.report, "output");
  out.trajectory = r.optionalString(node, "trajectory", out.trajectory, "output");
  out.snapshot = r.optionalString(node, "snapshot", out.snapshot, "output");
  out.planes = r.optionalString(node, "planes", out.planes, "output");
  out.planes_snapshot =
    r.optionalString(node, "planes_snapshot", out.planes_snapshot, "output");
  out.cuboids_snapshot =
    r.optionalString(node, "cuboids_snapshot", out.cuboids_snapshot, "output");
  out.map = r.optionalString(node, "map", out.map, "output");
  out.map_octomap = r.optionalString(node, "map_octomap", out.map_octomap, "output");
  out.map_mesh = r.optionalString(node, "map_mesh", out.map_mesh, "output");
  out.map_grid_2d = r.optionalString(node, "map_grid_2d", out.map_grid_2d, "output");
  if (const YAML::Node band = node["map_grid_2d_band"]) {
    if (out.map_grid_2d.empty())
      r.fail(band, "output.map_grid_2d_band is not used: set output.map_grid_2d");
    out.map_grid_2d_band = parseGrid2DBand(r, band);
  }
  out.map_snapshot = r.optionalString(node, "map_snapshot", out.map_snapshot, "output");
  out.snapshot_camera =
    r.optionalString(node, "snapshot_camera", out.snapshot_camera, "output");
  if (out.snapshot_camera != "top" && out.snapshot_camera != "oblique"
      && out.snapshot_camera != "street")
    r.fail(node["snapshot_camera"],
           "output.snapshot_camera must be top, oblique or street");
  out.cuboids_street_snapshot = r.optionalString(node, "cuboids_street_snapshot",
                                                 out.cuboids_street_snapshot, "output");
  if (const YAML::Node view = node["street_view"])
    out.street_view = parseStreetView(r, view);
  // The street camera is used by the street snapshot, and by all of them with
  // snapshot_camera: street; street_view is then its camera, otherwise unused.
  const bool street_used =
    !out.cuboids_street_snapshot.empty() || out.snapshot_camera == "street";
  if (node["street_view"] && !street_used)
    r.fail(node["street_view"],
           "output.street_view is not used: it is the camera of "
           "output.cuboids_street_snapshot and of snapshot_camera: street");
  // Following the trajectory needs one; without poses the clouds stay in the camera
  // frame, where no up direction is known.
  if (street_used && !out.street_view.fixed && input.poses_format == PoseFormat::NONE)
    r.fail(!out.cuboids_street_snapshot.empty() ? node["cuboids_street_snapshot"]
                                                : node["snapshot_camera"],
           "the street camera follows the trajectory, and input.poses is none: set "
           "input.poses or a fixed camera (output.street_view.position_m and "
           "focal_point_m)");
  if (out.report.empty())
    r.fail(node["report"], "output.report must name a file");
  // A name leaving the folder would fail only after the last frame; the extension
  // chooses the format, or is the one the programs that read the file expect.
  struct OutputName {
    const char* key;
    const std::string* name;
    std::vector<std::string> extensions; // empty: any name
  };
  for (const OutputName& o :
       {OutputName{"cloud", &out.cloud, {".pcd", ".ply"}},
        OutputName{"planes", &out.planes, {".pcd", ".ply"}},
        OutputName{"report", &out.report, {}},
        OutputName{"trajectory", &out.trajectory, {}},
        OutputName{"snapshot", &out.snapshot, {".png"}},
        OutputName{"planes_snapshot", &out.planes_snapshot, {".png"}},
        OutputName{"cuboids_snapshot", &out.cuboids_snapshot, {".png"}},
        OutputName{"cuboids_street_snapshot", &out.cuboids_street_snapshot, {".png"}},
        OutputName{"map", &out.map, {".pgmap"}},
        OutputName{"map_octomap", &out.map_octomap, {".bt", ".ot"}},
        OutputName{"map_mesh", &out.map_mesh, {".ply", ".vtk"}},
        OutputName{"map_grid_2d", &out.map_grid_2d, {".yaml"}}, // the .pgm beside it
        OutputName{"map_snapshot", &out.map_snapshot, {".png"}}}) {
    if (o.name->empty())
      continue;
    if (!OutputTransaction::isOutputName(*o.name))
      r.fail(node[o.key], "output." + std::string(o.key) + " '" + *o.name
                            + "' must be a file name inside output.folder (a relative "
                              "path without '..', not starting with '.planar_grid_')");
    if (!o.extensions.empty()
        && std::none_of(o.extensions.begin(), o.extensions.end(),
                        [&o](const std::string& e) { return endsWith(*o.name, e); })) {
      std::string allowed;
      for (const std::string& e : o.extensions)
        allowed += (allowed.empty() ? "" : " or ") + e;
      r.fail(node[o.key], "output." + std::string(o.key) + " must end in " + allowed);
    }
  }
  out.checkpoint = r.optionalString(node, "checkpoint", out.checkpoint, "output");
  if (const YAML::Node every = node["checkpoint_every_n_frames"]) {
    long long v = -1;
    try {
      v = every.as<long long>();
    } catch (const YAML::BadConversion&) {
      r.fail(every, "output.checkpoint_every_n_frames must be an integer");
    }
    if (v < 0 || v > 1000000)
      r.fail(every, "output.checkpoint_every_n_frames must be in [0, 1000000]");
    out.checkpoint_every_n_frames = static_cast<std::size_t>(v);
    if (v > 0 && out.checkpoint.empty())
      r.fail(every,
             "output.checkpoint_every_n_frames needs output.checkpoint (a file)");
  }
  if (const YAML::Node size = node["snapshot_size_px"]) {
    if (!size.IsSequence() || size.size() != 2)
      r.fail(size, "output.snapshot_size_px must be [width, height]");
    for (std::size_t i = 0; i < 2; ++i) {
      int v = 0;
      try {
        v = size[i].as<int>();
      } catch (const YAML::BadConversion&) {
        r.fail(size[i], "output.snapshot_size_px entries must be integers");
      }
      if (v < 16 || v > 8192)
        r.fail(size[i], "output.snapshot_size_px entries must be in [16, 8192]");
      out.snapshot_size_px[i] = v;
    }
  }
  return out;
}

/** Applies sharedStageParams(): a key the taking stage leaves out takes the other
 * stage's value; two values set apart are an error at the taking stage's key. */
void
shareStageParams(const YamlReader& r,
                 const YAML::Node& stage_nodes,
                 std::vector<StageConfig>& stages)
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
      r.fail(
        to_params[shared.key],
        shared.stage + ": " + shared.key + " " + to_stage.params.toString(shared.key)
          + " differs from " + shared.from_stage + "'s " + shared.from_key + " "
          + from_stage.params.toString(shared.from_key)
          + (from_set
               ? " (line "
                   + std::to_string(from_params[shared.from_key].Mark().line + 1) + ")"
               : " (its default)")
          + ": " + shared.reason);
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

/** A stage's need; a need that comes from a parameter's value names the parameter and
 * a value without the need (for the error's location and hint). */
struct StageNeed {
  StageData data;
  std::string param;
  std::string alternative;
};

/** The stage's needs with its parameters: planes hypothesised from the key features
 * need them. */
std::vector<StageNeed>
stageNeeds(const StageInfo& info, const StageConfig& sc)
{
  std::vector<StageNeed> needs;
  for (const StageData d : info.needs)
    needs.push_back({d, "", ""});
  if (sc.type == "multi_plane_segmentation"
      && sc.params.getChoice("sample") == "features")
    needs.push_back({StageData::FEATURES, "sample", "cloud"});
  return needs;
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
    const std::vector<StageNeed> needs = stageNeeds(info, sc);
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

PipelineConfig
parseRoot(const YAML::Node& root, const std::string& source, const std::string& base)
{
  const Reader r(source, base);
  if (!root || root.IsNull())
    throw ConfigError(source, 0, 0,
                      "the file is empty; expected input:, pipeline:, output:");
  r.checkKeys(root, {"input", "pipeline", "output"}, "the top level");
  PipelineConfig config;
  config.source_file = source;

  const YAML::Node input = root["input"];
  if (!input)
    r.fail(root, "the top level needs the key 'input'");
  r.requireMap(input, "input");
  config.input = parseInput(r, input);

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
    config.stages.push_back(std::move(sc));
  }
  checkDataFlow(r, stages, config);
  shareStageParams(r, stages, config.stages);

  if (const YAML::Node output = root["output"])
    config.output = parseOutput(r, output, config.input);
  return config;
}

} // namespace

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

namespace {

/** Puts `STAGE.KEY=VALUE` into the params of the one stage of that type under \a
 * root's pipeline, after checking the value against the stage's table. */
void
applyOverride(YAML::Node& root, const std::string& assignment)
{
  const std::string where = "--set " + assignment;
  const std::size_t dot = assignment.find('.');
  const std::size_t equals = assignment.find('=');
  if (dot == std::string::npos || equals == std::string::npos || dot == 0
      || equals < dot + 2)
    throw ConfigError(where, 0, 0,
                      "expected STAGE.KEY=VALUE, e.g. "
                      "stereo_disparity.num_disparities_px=96");
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
    return parseRoot(root, source_name, base_folder);
  } catch (const YAML::Exception& e) {
    // A conversion the schema checks did not foresee (found by fuzz_pipeline_config):
    // still an error at the node's line:col, never a yaml-cpp exception.
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
  };
  return shared;
}

} // namespace planar_grid
