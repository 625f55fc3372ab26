// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_viewer: shows PCD clouds, planar grid maps (.pgmap), PLY meshes and
// OctoMap octrees (.bt, .ot) interactively or renders them to a PNG snapshot.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/map/map_tiles.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/visualization/mesh_file.h>
#include <planar_grid/visualization/octomap_file.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/street_camera.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/console/parse.h>
#include <pcl/console/print.h>
#include <pcl/console/time.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <charconv>
#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <limits>
#include <set>
#include <sstream>
#include <string>
#include <system_error>
#include <vector>

#include "cli.h"

using pcl::console::print_error;
using pcl::console::print_highlight;
using pcl::console::print_info;
using pcl::console::print_value;

namespace {

// Defaults, printed by the help.
constexpr int DEFAULT_WIDTH_PX = 1600;
constexpr int DEFAULT_HEIGHT_PX = 1000;
constexpr double DEFAULT_POINT_SIZE_PX = 2.0;
const char* const DEFAULT_CAMERA = "oblique";
const char* const DEFAULT_COLOR = "height";
/** \brief The street camera's defaults are the library's. */
const planar_grid::StreetCameraParameters DEFAULT_STREET;

/** \brief The effective options. */
struct ViewerOptions {
  std::vector<std::string> clouds;
  std::vector<std::string> maps;
  std::vector<std::string> meshes;
  std::vector<std::string> octrees;
  std::string snapshot;
  std::string camera_name{DEFAULT_CAMERA};
  bool explicit_camera{false};
  planar_grid::CameraParameters camera;
  planar_grid::CameraPreset preset{planar_grid::CameraPreset::OBLIQUE};
  /** \brief --camera street: the camera follows the --trajectory. */
  bool street_camera{false};
  planar_grid::StreetCameraParameters street{DEFAULT_STREET};
  std::string trajectory;
  int width_px{DEFAULT_WIDTH_PX};
  int height_px{DEFAULT_HEIGHT_PX};
  std::string color_name{DEFAULT_COLOR};
  planar_grid::ColorMode color{planar_grid::ColorMode::HEIGHT};
  /** \brief The cuboids of the maps: by occupancy unless --color label or solid. */
  planar_grid::CuboidColorMode map_color{planar_grid::CuboidColorMode::OCCUPANCY};
  double point_size_px{DEFAULT_POINT_SIZE_PX};
};

void
printHelp(const char* program)
{
  print_info(
    "Shows PCD point clouds, planar grid maps (.pgmap, written by the pipeline's "
    "map_integration), PLY meshes (e.g. the pipeline's map_cuboids.ply) and OctoMap "
    "octrees (.bt, .ot) with VTK, or renders them offscreen to a PNG. A map shows its "
    "cuboids coloured by occupancy (blue 0, green 0.5, red 1), its other occupied "
    "voxels grey and its unknown space translucent violet; a mesh has its vertex "
    "colours (else colours by height); an octree's occupied leaves are boxes coloured "
    "by occupancy.\n\n");
  print_info(
    "Syntax is: %s <cloud.pcd | map.pgmap | tile folder | mesh.ply | octree.bt | "
    "octree.ot> [more "
    "...] <options>\n",
    program);
  print_info("  where options are:\n");
  print_info(
    "    --snapshot <out.png>  render offscreen and write a PNG instead of opening "
    "a window (default: open a window)\n");
  print_info("    --camera <c>          top | oblique | street | "
             "px,py,pz,fx,fy,fz,ux,uy,uz (position, focal point, view up; metres) "
             "(default: ");
  print_value("%s", DEFAULT_CAMERA);
  print_info(")\n");
  print_info("                          street: from above and behind a pose of the "
             "--trajectory, looking along the direction of travel\n");
  print_info("    --trajectory <poses.txt>  camera poses, KITTI format (the pipeline's "
             "trajectory.txt), drawn as a red line; needed by --camera street "
             "(default: none)\n");
  print_info(
    "    --pose-fraction <f>   street: the pose followed, as a fraction of the "
    "trajectory in [0, 1] (0 first, 1 last) (default: ");
  print_value("%.3f", DEFAULT_STREET.pose_fraction);
  print_info(")\n");
  print_info("    --pitch-rad <a>       street: downward pitch of the view, rad "
             "(default: ");
  print_value("%g", DEFAULT_STREET.pitch_rad);
  print_info(")\n");
  print_info("    --look-ahead-m <d>    street: street in view ahead of the pose, m "
             "(default: ");
  print_value("%g", DEFAULT_STREET.look_ahead_m);
  print_info(")\n");
  print_info("    --up <x,y,z>          street: the world's up direction (default: ");
  print_value("%g,%g,%g", DEFAULT_STREET.world_up.x(), DEFAULT_STREET.world_up.y(),
              DEFAULT_STREET.world_up.z());
  print_info("; every pose reader gives a z-up world)\n");
  print_info("    --size <W>x<H>        image or window size, px (default: ");
  print_value("%dx%d", DEFAULT_WIDTH_PX, DEFAULT_HEIGHT_PX);
  print_info(")\n");
  print_info("    --color <mode>        height | intensity | solid | label (default: ");
  print_value("%s", DEFAULT_COLOR);
  print_info(");\n                          a .pgmap's cuboids: occupancy (default), "
             "label (one colour per plane, non-planar grey) or solid\n");
  print_info("    --point-size <N>      point size, px, > 0 (default: ");
  print_value("%g", DEFAULT_POINT_SIZE_PX);
  print_info(")\n");
  print_info("    -h, --help            this help\n");
  print_info("    --version             print the name and version\n\n");
  print_info("Snapshots need an X server (Debian's VTK 9.1); without one the viewer "
             "starts its own Xvfb (when xvfb is installed), which ends with it.\n");
}

/** \brief Parses "<W>x<H>" (both positive integers, nothing else). */
bool
parseSize(const std::string& text, int& width_px, int& height_px)
{
  const char* const end = text.data() + text.size();
  const auto w = std::from_chars(text.data(), end, width_px);
  if (w.ec != std::errc() || w.ptr == end || *w.ptr != 'x')
    return false;
  const auto h = std::from_chars(w.ptr + 1, end, height_px);
  return h.ec == std::errc() && h.ptr == end && width_px > 0 && height_px > 0;
}

/** \brief Parses comma-separated numbers, each complete ("1,2,x" and "1,,2" fail).
 * pcl::console::parse_x_arguments would turn junk into 0 with atof. */
bool
parseNumbers(const std::string& text, std::vector<double>& values)
{
  values.clear();
  const char* p = text.data();
  const char* const end = text.data() + text.size();
  while (true) {
    double value = 0.0;
    const auto result = std::from_chars(p, end, value);
    if (result.ec != std::errc() || !std::isfinite(value))
      return false;
    values.push_back(value);
    if (result.ptr == end)
      return true;
    if (*result.ptr != ',')
      return false;
    p = result.ptr + 1;
  }
}

/** \brief The command line's arguments, with the indices accounted for; anything
 * else is an unknown argument. */
struct Arguments {
  int argc;
  char** argv;
  std::set<int> used;

  /** \brief Whether option \a name is given; it must have a value. */
  bool withValue(const char* name)
  {
    const int index = pcl::console::find_argument(argc, argv, name);
    if (index < 0)
      return false;
    if (index + 1 >= argc)
      throw planar_grid::Exception(std::string(name) + " needs a value");
    used.insert(index);
    used.insert(index + 1);
    return true;
  }

  /** \brief The value of option \a name (given). */
  std::string valueOf(const char* name) const
  {
    return argv[pcl::console::find_argument(argc, argv, name) + 1];
  }

  /** \brief The arguments ending in \a extension, accounted for. */
  std::vector<std::string> filesEndingIn(const char* extension)
  {
    std::vector<std::string> files;
    for (const int index :
         pcl::console::parse_file_extension_argument(argc, argv, extension)) {
      files.emplace_back(argv[index]);
      used.insert(index);
    }
    return files;
  }
};

/** \brief --camera: a preset (top, oblique), the street camera, or 9 numbers
 * (position, focal point, view up). */
void
parseCamera(Arguments& args, ViewerOptions& options)
{
  using planar_grid::Exception;
  if (!args.withValue("--camera"))
    return;
  options.camera_name = args.valueOf("--camera");
  if (options.camera_name == "top") {
    options.preset = planar_grid::CameraPreset::TOP;
  } else if (options.camera_name == "oblique") {
    options.preset = planar_grid::CameraPreset::OBLIQUE;
  } else if (options.camera_name == "street") {
    options.street_camera = true;
  } else {
    std::vector<double> values;
    if (!parseNumbers(options.camera_name, values) || values.size() != 9)
      throw Exception("--camera expects top, oblique, street or 9 comma-separated "
                      "numbers "
                      "px,py,pz,fx,fy,fz,ux,uy,uz; got '"
                      + options.camera_name + "'");
    options.explicit_camera = true;
    options.camera.position = Eigen::Vector3d(values[0], values[1], values[2]);
    options.camera.focal_point = Eigen::Vector3d(values[3], values[4], values[5]);
    options.camera.view_up = Eigen::Vector3d(values[6], values[7], values[8]);
  }
}

/** \brief The street camera's placement: each option only with --camera street, where
 * it is used, so that a forgotten --camera street is not silently ignored. */
void
parseStreetCamera(Arguments& args, ViewerOptions& options)
{
  using planar_grid::Exception;
  const auto street_option = [&](const char* name, double& value, double min,
                                 double max) {
    if (!args.withValue(name))
      return;
    const std::string text = args.valueOf(name);
    std::vector<double> values;
    if (!parseNumbers(text, values) || values.size() != 1 || !(values[0] >= min)
        || !(values[0] <= max)) {
      std::ostringstream message;
      message << name << " expects a number in [" << min << ", " << max << "]; got '"
              << text << "'";
      throw Exception(message.str());
    }
    if (!options.street_camera)
      throw Exception(std::string(name) + " is only used with --camera street");
    value = values[0];
  };
  street_option("--pose-fraction", options.street.pose_fraction, 0.0, 1.0);
  street_option("--pitch-rad", options.street.pitch_rad, 0.0, 1.6);
  street_option("--look-ahead-m", options.street.look_ahead_m, 1.0, 1000.0);
  if (args.withValue("--up")) {
    const std::string text = args.valueOf("--up");
    std::vector<double> values;
    if (!parseNumbers(text, values) || values.size() != 3
        || Eigen::Vector3d(values[0], values[1], values[2]).norm() == 0.0)
      throw Exception("--up expects 3 comma-separated numbers, not all 0; got '" + text
                      + "'");
    if (!options.street_camera)
      throw Exception("--up is only used with --camera street");
    options.street.world_up = Eigen::Vector3d(values[0], values[1], values[2]);
  }
  if (options.street_camera && options.trajectory.empty())
    throw Exception("--camera street needs --trajectory <poses.txt> (KITTI format, "
                    "e.g. the pipeline's trajectory.txt)");
}

/** \brief --color: the clouds' and the maps' colouring; false when not given. */
bool
parseColor(Arguments& args, ViewerOptions& options)
{
  if (!args.withValue("--color"))
    return false;
  options.color_name = args.valueOf("--color");
  if (options.color_name == "height")
    options.color = planar_grid::ColorMode::HEIGHT;
  else if (options.color_name == "intensity")
    options.color = planar_grid::ColorMode::INTENSITY;
  else if (options.color_name == "solid") {
    options.color = planar_grid::ColorMode::SOLID;
    options.map_color = planar_grid::CuboidColorMode::SOLID;
  } else if (options.color_name == "label") {
    options.color = planar_grid::ColorMode::LABEL;
    options.map_color = planar_grid::CuboidColorMode::PLANE;
  } else if (options.color_name == "occupancy")
    options.map_color = planar_grid::CuboidColorMode::OCCUPANCY;
  else
    throw planar_grid::Exception(
      "--color expects height, intensity, solid, label or occupancy; got '"
      + options.color_name + "'");
  return true;
}

/** \brief The tile folders among the remaining arguments (a folder holding the tile
 * index opens as one map); then no argument may remain, some input must be given,
 * and a given colouring must apply to one of the inputs. */
void
checkInputs(Arguments& args, ViewerOptions& options, bool color_given)
{
  using planar_grid::Exception;
  for (int i = 1; i < args.argc; ++i) {
    std::error_code ec;
    if (args.used.count(i) == 0
        && std::filesystem::is_regular_file(
          std::filesystem::path(args.argv[i]) / planar_grid::MAP_TILE_INDEX_NAME, ec)) {
      options.maps.emplace_back(args.argv[i]);
      args.used.insert(i);
    }
  }
  for (int i = 1; i < args.argc; ++i)
    if (args.used.count(i) == 0)
      throw Exception(std::string("unknown argument '") + args.argv[i]
                      + "' (inputs must be .pcd, .pgmap, .ply, .bt or .ot files; see "
                        "--help)");
  if (options.clouds.empty() && options.maps.empty() && options.meshes.empty()
      && options.octrees.empty())
    throw Exception("no input given (expected .pcd clouds, .pgmap maps, .ply meshes or "
                    ".bt / .ot octrees)");
  // A colouring that none of the inputs takes would silently do nothing.
  const bool cloud_mode =
    options.color_name == "height" || options.color_name == "intensity";
  if (color_given && cloud_mode && options.clouds.empty())
    throw Exception("--color " + options.color_name
                    + " colours point clouds, and no .pcd is given; a map's cuboids "
                      "take occupancy (the default), label (by plane) or solid");
  if (color_given && options.color_name == "occupancy" && options.maps.empty())
    throw Exception("--color occupancy colours the cuboids of .pgmap maps, and none is "
                    "given; point clouds take height, intensity, solid or label");
}

/** \brief Reads every option; throws planar_grid::Exception on a malformed one
 * (a malformed number is an error, never 0).
 * \param[out] help set when -h/--help was given */
ViewerOptions
parseOptions(int argc, char** argv, bool& help)
{
  using planar_grid::Exception;
  ViewerOptions options;
  help = pcl::console::find_switch(argc, argv, "-h")
         || pcl::console::find_switch(argc, argv, "--help");
  if (help)
    return options;
  Arguments args{argc, argv, {}};
  options.clouds = args.filesEndingIn(".pcd");
  options.maps = args.filesEndingIn(".pgmap");
  options.meshes = args.filesEndingIn(".ply");
  for (const char* extension : {".bt", ".ot"})
    for (const std::string& file : args.filesEndingIn(extension))
      options.octrees.push_back(file);
  if (args.withValue("--snapshot")) {
    options.snapshot = args.valueOf("--snapshot");
    if (std::filesystem::path(options.snapshot).extension() != ".png")
      throw Exception("--snapshot expects a .png file, got '" + options.snapshot + "'");
  }
  parseCamera(args, options);
  if (args.withValue("--trajectory"))
    options.trajectory = args.valueOf("--trajectory");
  parseStreetCamera(args, options);
  if (args.withValue("--size")) {
    const std::string size = args.valueOf("--size");
    if (!parseSize(size, options.width_px, options.height_px))
      throw Exception("--size expects <W>x<H> with positive integers in px (e.g. "
                      "1600x1000); got '"
                      + size + "'");
  }
  const bool color_given = parseColor(args, options);
  if (args.withValue("--point-size")) {
    // parse_argument returns -1 for a value with junk in it ("2px") or out of range.
    if (pcl::console::parse_argument(argc, argv, "--point-size", options.point_size_px)
          < 0
        || !(options.point_size_px > 0.0))
      throw Exception(std::string("--point-size expects a number > 0 (px); got '")
                      + args.valueOf("--point-size") + "'");
  }
  checkInputs(args, options, color_given);
  return options;
}

/** \brief Loads one PCD as PointXYZI (clouds without intensity get intensity 0).
 * \throws planar_grid::IOError when the file cannot be read or has no x, y, z */
pcl::PointCloud<pcl::PointXYZI>
loadCloud(const std::string& path)
{
  pcl::console::TicToc timer;
  timer.tic();
  print_highlight("Loading ");
  print_value("%s ", path.c_str());
  pcl::PCLPointCloud2 blob;
  planar_grid::checkPCDFile(path); // PCL's reader crashes on files that are not PCD
  if (pcl::io::loadPCDFile(path, blob) < 0) {
    print_info("[failed]\n");
    throw planar_grid::IOError(path + ": cannot load the PCD file");
  }
  planar_grid::checkPointCloudBlob(blob, path);
  // PCL leaves a field of another datatype than the point type's at 0: double or
  // integer coordinates would all become the origin.
  planar_grid::convertFieldsToFloat(blob, {"x", "y", "z", "intensity"}, path);
  if (pcl::getFieldIndex(blob, "x") < 0 || pcl::getFieldIndex(blob, "y") < 0
      || pcl::getFieldIndex(blob, "z") < 0) {
    print_info("[failed]\n");
    throw planar_grid::IOError(path + ": the PCD file has no x, y, z fields");
  }
  pcl::PointCloud<pcl::PointXYZI> cloud;
  if (pcl::getFieldIndex(blob, "intensity") >= 0) {
    pcl::fromPCLPointCloud2(blob, cloud);
  } else if (pcl::getFieldIndex(blob, "label") >= 0) {
    // A labelled cloud (e.g. the pipeline's planes.pcd): the label goes into intensity,
    // which --color label draws.
    pcl::PointCloud<pcl::PointXYZL> labelled;
    pcl::fromPCLPointCloud2(blob, labelled);
    cloud.resize(labelled.size());
    for (std::size_t i = 0; i < labelled.size(); ++i) {
      cloud[i].getVector3fMap() = labelled[i].getVector3fMap();
      cloud[i].intensity = static_cast<float>(labelled[i].label);
    }
    cloud.width = labelled.width;
    cloud.height = labelled.height;
    cloud.is_dense = labelled.is_dense;
  } else {
    // Not an error: intensity is 0 (and fromPCLPointCloud2 would warn about the field).
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::fromPCLPointCloud2(blob, xyz);
    pcl::copyPointCloud(xyz, cloud);
  }
  print_info("[done, ");
  print_value("%g", timer.toc());
  print_info(" ms : ");
  print_value("%zu", static_cast<std::size_t>(cloud.size()));
  print_info(" points]\n");
  return cloud;
}

int
run(int argc, char** argv)
{
  bool help = false;
  const ViewerOptions options = parseOptions(argc, argv, help);
  if (help) {
    printHelp(argv[0]);
    return EXIT_SUCCESS;
  }
  // Bad input files fail before a window or an X server is started.
  for (const auto& path : options.clouds)
    planar_grid::checkPCDFile(path);
  for (const auto& path : options.meshes)
    planar_grid::checkPLYFile(path);
  for (const auto& path : options.octrees)
    planar_grid::checkOctoMapFile(path);
  // Before loading anything: this may start an Xvfb for the snapshot.
  if (!options.snapshot.empty()) {
    planar_grid::ensureDisplay(argc, argv);
    planar_grid::cli::preferLowMemorySoftwareRendering();
  } else if (!planar_grid::hasDisplay())
    throw planar_grid::Exception(
      "no X display for the interactive window (DISPLAY is unset or does not answer); "
      "to render a picture without a screen use --snapshot out.png");

  print_info("Camera: ");
  print_value("%s", options.camera_name.c_str());
  print_info(", size: ");
  print_value("%dx%d", options.width_px, options.height_px);
  print_info(" px, color: ");
  print_value("%s", options.color_name.c_str());
  print_info(", point size: ");
  print_value("%g", options.point_size_px);
  print_info(" px\n");

  planar_grid::SceneRenderer renderer;
  // The camera first: an invalid explicit camera fails before any loading; presets
  // frame the clouds at render time.
  if (options.explicit_camera)
    renderer.setCamera(options.camera);
  else
    renderer.setCamera(options.preset);
  if (!options.trajectory.empty()) {
    print_highlight("Loading ");
    print_value("%s ", options.trajectory.c_str());
    const planar_grid::Trajectory trajectory =
      planar_grid::loadKittiPoses(options.trajectory);
    print_info("[done : ");
    print_value("%zu", trajectory.size());
    print_info(" poses]\n");
    std::vector<Eigen::Vector3d> positions;
    for (const auto& pose : trajectory)
      positions.push_back(pose.translation());
    renderer.addTrajectory(positions);
    if (options.street_camera) {
      if (trajectory.empty())
        throw planar_grid::IOError(options.trajectory
                                   + ": no pose for --camera street to follow");
      const planar_grid::CameraParameters camera =
        planar_grid::streetCamera(trajectory, options.street);
      print_info("Street camera behind pose ");
      print_value("%zu", planar_grid::streetCameraPoseIndex(
                           trajectory.size(), options.street.pose_fraction));
      print_info(": position ");
      print_value("(%.2f, %.2f, %.2f)", camera.position.x(), camera.position.y(),
                  camera.position.z());
      print_info(" m, focal point ");
      print_value("(%.2f, %.2f, %.2f)", camera.focal_point.x(), camera.focal_point.y(),
                  camera.focal_point.z());
      print_info(" m\n");
      renderer.setCamera(camera);
    }
  }
  for (const auto& path : options.clouds)
    renderer.addPointCloud(loadCloud(path), options.color, options.point_size_px);
  for (const auto& path : options.maps) {
    pcl::console::TicToc timer;
    timer.tic();
    print_highlight("Loading ");
    print_value("%s ", path.c_str());
    // a tile folder: every tile, merged into one map
    const float inf = std::numeric_limits<float>::infinity();
    const auto map = std::filesystem::is_directory(path)
                       ? planar_grid::loadTiles(
                         path, Eigen::AlignedBox3f(Eigen::Vector3f::Constant(-inf),
                                                   Eigen::Vector3f::Constant(inf)))
                       : planar_grid::PlanarGridMap::load(path);
    const auto drawn = renderer.addMap(map, options.map_color);
    print_info("[done, ");
    print_value("%g", timer.toc());
    const char* coloured =
      options.map_color == planar_grid::CuboidColorMode::PLANE   ? "by plane"
      : options.map_color == planar_grid::CuboidColorMode::SOLID ? "solid"
                                                                 : "by occupancy";
    print_info(" ms : %zu cuboids (%s), %zu occupied voxels outside them, %zu unknown "
               "boxes]\n",
               drawn.cuboids, coloured, drawn.occupied_voxel_boxes,
               drawn.unknown_boxes);
  }

  for (const auto& path : options.meshes) {
    pcl::console::TicToc timer;
    timer.tic();
    print_highlight("Loading ");
    print_value("%s ", path.c_str());
    const pcl::PolygonMesh mesh = planar_grid::loadPLYMesh(path);
    const std::size_t faces = renderer.addPolygonMesh(mesh);
    print_info("[done, ");
    print_value("%g", timer.toc());
    print_info(" ms : %zu vertices, %zu faces]\n",
               static_cast<std::size_t>(mesh.cloud.width) * mesh.cloud.height, faces);
  }
  for (const auto& path : options.octrees) {
    pcl::console::TicToc timer;
    timer.tic();
    print_highlight("Loading ");
    print_value("%s ", path.c_str());
    const planar_grid::OctoMapLeaves leaves = planar_grid::loadOctoMapLeaves(path);
    renderer.addCuboids(leaves.occupied, planar_grid::CuboidColorMode::OCCUPANCY);
    print_info("[done, ");
    print_value("%g", timer.toc());
    print_info(" ms : resolution %g m, %zu occupied voxels in %zu boxes, %zu free "
               "voxels]\n",
               leaves.resolution_m, leaves.occupied_voxels, leaves.occupied.size(),
               leaves.free_voxels);
  }

  if (!options.snapshot.empty()) {
    pcl::console::TicToc timer;
    timer.tic();
    print_highlight("Rendering ");
    print_value("%s ", options.snapshot.c_str());
    renderer.saveSnapshot(options.snapshot, options.width_px, options.height_px);
    print_info("[done, ");
    print_value("%g", timer.toc());
    print_info(" ms]\n");
  } else {
    renderer.show(options.width_px, options.height_px);
  }
  return EXIT_SUCCESS;
}

} // namespace

int
main(int argc, char** argv)
{
  return planar_grid::cli::runMain("planar_grid_viewer", run, argc, argv);
}
