// SPDX-License-Identifier: BSD-3-Clause
// The `output:` section of a pipeline configuration (parsePipelineConfig()).
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <Eigen/Geometry>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <set>
#include <string>

#include "pipeline_config_parse.h"

namespace planar_grid {
namespace config_parse {

using Reader = YamlReader;

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

namespace {

namespace fs = std::filesystem;

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
  namespace ranges = occupancy_grid_2d_ranges;
  constexpr double DEG = M_PI / 180.0;
  // The angles are given in degrees: their range converted.
  constexpr ParamRange ANGLE_DEG{ranges::ANGLE.min / DEG, ranges::ANGLE.max / DEG,
                                 ranges::ANGLE.min_open, ranges::ANGLE.max_open};
  band.z_ref_m = r.real(node, "z_ref_m", band.z_ref_m, ranges::Z_REF, "m", what);
  band.z_min_m = r.real(node, "z_min_m", band.z_min_m, ranges::Z_BAND, "m", what);
  band.z_max_m = r.real(node, "z_max_m", band.z_max_m, ranges::Z_BAND, "m", what);
  if (!(band.z_max_m > band.z_min_m))
    r.fail(node["z_max_m"] ? node["z_max_m"] : node["z_min_m"],
           what + ".z_max_m must be above z_min_m");
  band.above_terrain = r.boolean(node, "above_terrain", band.above_terrain, what);
  band.terrain_tile_m = r.real(node, "terrain_tile_m", band.terrain_tile_m,
                               ranges::TERRAIN_TILE, "m", what);
  band.resolution_m =
    r.real(node, "resolution_m", band.resolution_m, 0.0, ranges::RESOLUTION.max, what);
  if (band.resolution_m != 0.0 && !ranges::RESOLUTION.contains(band.resolution_m))
    r.fail(node["resolution_m"], what + ".resolution_m must be 0 (the map's) or in "
                                   + formatParamRange(ranges::RESOLUTION, "m"));
  // Within ANGLE_DEG, the angle in radians is within ANGLE up to rounding: clamped.
  band.max_slope_rad = std::min(
    r.real(node, "max_slope_deg", band.max_slope_rad / DEG, ANGLE_DEG, "deg", what)
      * DEG,
    ranges::ANGLE.max);
  band.terrain_max_angle_rad =
    std::min(r.real(node, "terrain_max_angle_deg", band.terrain_max_angle_rad / DEG,
                    ANGLE_DEG, "deg", what)
               * DEG,
             ranges::ANGLE.max);
  return band;
}

/** \brief output.folder checked now, not after the last frame (the tool checks a
 * --output folder the same way when it opens the output set, still before the first
 * frame): not empty, nothing for a shell to expand, not a file. */
void
checkOutputFolder(const Reader& r, const YAML::Node& node, const OutputConfig& out)
{
  std::error_code ec;
  // An empty name would write the outputs into the current folder.
  if (node["folder"] && out.folder.empty())
    r.fail(node["folder"], "output.folder is empty: name the folder to write the "
                           "outputs into");
  // A shell expands these; a YAML file does not, and the run would create a folder
  // named "~" or "$HOME" in the working folder.
  if (node["folder"] && needsShellExpansion(out.folder))
    r.fail(node["folder"], "output.folder '" + out.folder
                             + "': a configuration does not expand '~' or $VARIABLES "
                               "as a shell does; give the path itself");
  if (node["folder"] && fs::exists(out.folder, ec) && !fs::is_directory(out.folder, ec))
    r.fail(node["folder"], "output.folder '" + out.folder
                             + "' is a file, not a folder: the outputs cannot be "
                               "written there");
}

/** \brief The snapshots' camera: snapshot_camera, the street snapshot and its camera
 * (street_view, used only by a street camera, which follows the trajectory unless
 * fixed). */
void
parseSnapshotCameras(const Reader& r,
                     const YAML::Node& node,
                     const InputConfig& input,
                     OutputConfig& out)
{
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
}

/** \brief Every output's name is a file name inside output.folder with an extension
 * its format allows: a name leaving the folder would fail only after the last frame;
 * the extension chooses the format, or is the one the programs that read the file
 * expect. */
void
checkOutputNames(const Reader& r, const YAML::Node& node, const OutputConfig& out)
{
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
}

/** \brief output.checkpoint_every_n_frames, in [0, 1000000], with a checkpoint file
 * when not 0. */
void
parseCheckpointEvery(const Reader& r, const YAML::Node& node, OutputConfig& out)
{
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
}

/** \brief output.snapshot_size_px: [width, height], each in [16, 8192]. */
void
parseSnapshotSize(const Reader& r, const YAML::Node& node, OutputConfig& out)
{
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
}

} // namespace

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
  checkOutputFolder(r, node, out);
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
  parseSnapshotCameras(r, node, input, out);
  if (out.report.empty())
    r.fail(node["report"], "output.report must name a file");
  checkOutputNames(r, node, out);
  out.checkpoint = r.optionalString(node, "checkpoint", out.checkpoint, "output");
  parseCheckpointEvery(r, node, out);
  parseSnapshotSize(r, node, out);
  return out;
}

} // namespace config_parse

bool
needsShellExpansion(const std::string& path)
{
  return (!path.empty() && path.front() == '~') || path.find('$') != std::string::npos;
}

} // namespace planar_grid
