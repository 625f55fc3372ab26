// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_pipeline: runs a YAML-configured PlanarGrid pipeline over a stereo
// sequence or PCD files and writes the world cloud, trajectory, report.json and a
// snapshot.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>
#include <planar_grid/pipeline/stage.h>

#include "cli.h"
#ifdef PLANAR_GRID_WITH_VIEWER
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/street_camera.h>
#endif

#include <pcl/console/parse.h>
#include <pcl/console/print.h>

#include <signal.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <functional>
#include <iostream>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

using namespace pcl::console;

namespace {

/** pcl::console::print_value() at the info level: PCL's prints whatever the
 * verbosity, which --quiet must silence. */
void
printValue(const std::string& text)
{
  if (isVerbosityLevelEnabled(L_INFO))
    print_value("%s", text.c_str());
}

void
printHelp(const char* program)
{
  print_info("Syntax: %s --config FILE.yaml [options]\n", program);
  print_info(
    "  Runs the pipeline a YAML file describes (schema: config/example.yaml).\n");
  print_info("  Options:\n");
  print_info("    --config FILE.yaml   the pipeline configuration (required)\n");
  print_info("    --set STAGE.KEY=VALUE\n"
             "                         replace a parameter of the YAML's one stage of\n"
             "                         that type (repeatable; checked as the file's\n"
             "                         values are: exit 3 when wrong), e.g.\n"
             "                         --set stereo_disparity.row_downscale=2\n");
  print_info(
    "    --frames A:B         run frames A..B-1 (0-based positions in the input);\n"
    "                         A: or :B leave a side open (default: all frames)\n");
  print_info(
    "    --output DIR         write outputs here (default: output.folder of the "
    "YAML)\n");
  print_info(
    "    --no-snapshot        do not render the PNG snapshots (default: render "
    "those output names: snapshot, planes_snapshot, cuboids_snapshot,\n"
    "                         cuboids_street_snapshot, map_snapshot)\n");
  print_info(
    "    --checkpoint-every N write the checkpoint (output.checkpoint) every N "
    "frames;\n"
    "                         0 = never (default: output.checkpoint_every_n_frames)\n");
  print_info(
    "    --resume             continue from the checkpoint in the output folder: the\n"
    "                         same map as an uninterrupted run (same configuration)\n");
  print_info(
    "    --sequential         run every frame start to end on one thread (default: "
    "the\n"
    "                         leading frame-local stages, e.g. stereo_disparity and\n"
    "                         feature_matching, run up to two frames ahead on a second "
    "thread;\n"
    "                         the results are the same)\n");
  print_info(
    "    --memory-limit SIZE  refuse, before the first frame, a run whose memory\n"
    "                         estimate exceeds SIZE (bytes, or with a K, M, G, T\n"
    "                         suffix, powers of 1024; 0 or none: no check). The\n"
    "                         estimate bounds the map's explicit space layer from\n"
    "                         resolution_m, max_range_m, the camera and the frames'\n"
    "                         poses, plus 512 MiB for the rest (docs/RELIABILITY.md).\n"
    "                         Default: the machine's memory (MemTotal), or the\n"
    "                         process's limit where smaller (ulimit -v, ulimit -d)\n");
  print_info("    --list-stages        print every stage type with its parameters, "
             "defaults, units and ranges, then exit\n");
  print_info(
    "    --stage-reference    print the same as a Markdown page (docs/STAGES.md), "
    "then exit\n");
  print_info(
    "    --print-default-pipeline\n"
    "                         print, as commented YAML, a pipeline: section with\n"
    "                         every stage type and every parameter at its default\n"
    "                         (the stage list of config/example.yaml), then exit\n");
  print_info(
    "    --log-level LEVEL    what is printed: error, warn, info (default) or\n"
    "                         debug (also PCL's debug output)\n");
  print_info("    -q, --quiet          errors only (--log-level error): no progress,\n"
             "                         no configuration, timing or output list\n");
  print_info("    -v                   verbose (--log-level debug)\n");
  print_info("    -h, --help           this help\n");
  print_info("    --version            print the name and version\n");
  print_info(
    "  Exit status: 0 success; 2 command line (unknown option, bad value);\n"
    "    3 configuration (the YAML: planar_grid::ConfigError, also a run refused by\n"
    "    --memory-limit, at the cell size's key); 4 input (a file\n"
    "    that cannot be read: the YAML itself, calibration, images, clouds);\n"
    "    5 output (the output folder, a file in it or the checkpoint cannot be\n"
    "    written, or an output name would overwrite an input or names a folder);\n"
    "    130 / 143 stopped by SIGINT (Ctrl-C) / SIGTERM: the frame under way is\n"
    "    finished (and checkpointed when checkpoints are on), nothing else is\n"
    "    written and the previous outputs stay; a second signal ends it at once;\n"
    "    1 anything else (e.g. a stage failing on a frame)\n"
    "  NO_COLOR (any value): messages without colour.\n");
}

void
listStages()
{
  std::ostringstream out;
  out << "Stage types (use as `- type: NAME` with `params:` in the pipeline list):\n";
  for (const auto& info : planar_grid::stageRegistry()) {
    out << "\n  " << info.type << (info.needs_poses ? "   [needs input poses]" : "")
        << (info.needs_stereo ? "   [needs stereo input]" : "") << "\n      "
        << info.description << "\n";
    out << "      "
        << (info.role == planar_grid::StageRole::FRONT_END ? "front end" : "mapping")
        << " stage; needs " << planar_grid::stageDataNames(info.needs) << "; produces "
        << planar_grid::stageDataNames(info.produces) << "\n";
    out << planar_grid::describeParams(info.params);
  }
  std::cout << out.str();
}

/** Parses "A:B", "A:" or ":B" against n frames into [begin, end). */
void
parseFrameRange(const std::string& text,
                std::size_t n,
                std::size_t& begin,
                std::size_t& end)
{
  const auto colon = text.find(':');
  if (colon == std::string::npos)
    throw planar_grid::cli::UsageError("--frames '" + text + "' must be A:B");
  const auto parse_side = [&text](const std::string& side, std::size_t fallback) {
    if (side.empty())
      return fallback;
    std::istringstream in(side);
    long long v = -1;
    char extra = 0;
    if (!(in >> v) || (in >> extra) || v < 0)
      throw planar_grid::cli::UsageError("--frames '" + text
                                         + "' must be A:B with non-negative integers");
    return static_cast<std::size_t>(v);
  };
  begin = parse_side(text.substr(0, colon), 0);
  end = parse_side(text.substr(colon + 1), n);
}

class ProgressBar {
public:
  explicit ProgressBar(bool interactive) : interactive_(interactive) {}

  void update(std::size_t done, std::size_t total, double seconds)
  {
    const double fps = seconds > 0.0 ? static_cast<double>(done) / seconds : 0.0;
    const double eta = fps > 0.0 ? static_cast<double>(total - done) / fps : 0.0;
    if (interactive_) {
      const int width = 30;
      const int filled =
        static_cast<int>(width * done / std::max<std::size_t>(total, 1));
      std::fprintf(stderr, "\r[%s%s] %zu/%zu  %.2f frames/s  ETA %.0f s ",
                   std::string(static_cast<std::size_t>(filled), '#').c_str(),
                   std::string(static_cast<std::size_t>(width - filled), ' ').c_str(),
                   done, total, fps, eta);
      if (done == total)
        std::fprintf(stderr, "\n");
    } else {
      // Not a terminal (CI, a log file): one line per 10 % instead of redrawing.
      const std::size_t step = std::max<std::size_t>(total / 10, 1);
      if (done % step == 0 || done == total)
        std::fprintf(stderr, "frame %zu/%zu  %.2f frames/s  ETA %.0f s\n", done, total,
                     fps, eta);
    }
    std::fflush(stderr);
  }

private:
  bool interactive_;
};

#ifdef PLANAR_GRID_WITH_VIEWER
/** The street camera of output.street_view: fixed, or following \a trajectory. Nothing,
 * with a warning, when it follows the trajectory and there is no pose. \a description
 * says where it is, for the snapshots' labels. */
std::optional<planar_grid::CameraParameters>
streetViewCamera(const planar_grid::StreetViewConfig& view,
                 const planar_grid::Trajectory& trajectory,
                 std::string& description)
{
  const Eigen::Vector3d up(view.up[0], view.up[1], view.up[2]);
  std::ostringstream text;
  text.precision(3);
  if (view.fixed) {
    planar_grid::CameraParameters camera;
    camera.position = Eigen::Vector3d(view.position_m.data());
    camera.focal_point = Eigen::Vector3d(view.focal_point_m.data());
    camera.view_up = up;
    camera.view_angle_deg = view.view_angle_deg;
    text << "fixed camera at (" << camera.position.transpose() << ") m";
    description = text.str();
    return camera;
  }
  if (trajectory.empty()) {
    print_warn("No camera pose for the street view (no frame had a pose): the street "
               "snapshots are skipped.\n");
    return std::nullopt;
  }
  planar_grid::StreetCameraParameters parameters;
  parameters.pose_fraction = view.pose_fraction;
  parameters.pitch_rad = view.pitch_rad;
  parameters.look_ahead_m = view.look_ahead_m;
  parameters.view_angle_deg = view.view_angle_deg;
  parameters.world_up = up;
  const std::size_t index =
    planar_grid::streetCameraPoseIndex(trajectory.size(), view.pose_fraction);
  text << "street view from behind pose " << index << " of " << trajectory.size()
       << ", " << view.pitch_rad * 180.0 / M_PI << " deg down, " << view.look_ahead_m
       << " m ahead";
  description = text.str();
  return planar_grid::streetCamera(trajectory, parameters);
}

/** Renders the configured snapshots: the world cloud by height with the trajectory, the
 * planes one colour each over the world cloud in grey, the cuboids by plane (also seen
 * along the street) and the map by occupancy. */
void
saveSnapshots(const planar_grid::PipelineConfig& config,
              const std::string& config_path,
              const planar_grid::PipelineRunner& runner,
              planar_grid::RunReport& report,
              planar_grid::OutputTransaction& outputs)
{
  const auto& state = runner.state();
  const auto preset = config.output.snapshot_camera == "oblique"
                        ? planar_grid::CameraPreset::OBLIQUE
                        : planar_grid::CameraPreset::TOP;
  // The cells: the map's merged cuboids when a map was built (built here), else every
  // frame's (used in place).
  planar_grid::PlanarCuboids map_cuboids;
  if (state.map)
    map_cuboids = state.map->getSurfaceLayer().getCuboids();
  const planar_grid::PlanarCuboids& cuboids = state.map ? map_cuboids : state.cuboids;
  std::optional<planar_grid::CameraParameters> street;
  std::string street_description;
  if (config.output.snapshot_camera == "street"
      || (!config.output.cuboids_street_snapshot.empty() && !cuboids.empty())) {
    street = streetViewCamera(config.output.street_view, runner.trajectory(),
                              street_description);
    if (street) {
      print_info("Street camera: ");
      printValue(street_description);
      print_info(": position (%.2f, %.2f, %.2f) m, focal point (%.2f, %.2f, %.2f) m\n",
                 street->position.x(), street->position.y(), street->position.z(),
                 street->focal_point.x(), street->focal_point.y(),
                 street->focal_point.z());
    } else if (config.output.snapshot_camera == "street") {
      print_warn("snapshot_camera street without a pose: the snapshots use top.\n");
    }
  }
  const bool all_street = config.output.snapshot_camera == "street" && street;
  std::vector<Eigen::Vector3d> positions;
  for (const auto& pose : runner.trajectory())
    positions.push_back(pose.translation());
  const Eigen::Vector3d grey(0.8, 0.8, 0.8), dark(0.1, 0.1, 0.1);
  // One snapshot: white background, the content, the trajectory, a label, the preset
  // camera or, when \a along_street, the street camera; \a add_content draws the
  // content and returns the label.
  const auto render =
    [&](const std::string& name, const std::string& kind, bool along_street,
        const std::function<std::string(planar_grid::SceneRenderer&)>& add_content) {
      if (name.empty())
        return;
      {
        planar_grid::SceneRenderer renderer;
        renderer.setBackground(Eigen::Vector3d(1.0, 1.0, 1.0));
        const std::string label = add_content(renderer);
        if (positions.size() > 1)
          renderer.addTrajectory(positions);
        renderer.addText(config_path + ": " + label, dark);
        if (along_street) {
          renderer.addText(street_description, dark);
          renderer.setCamera(*street);
        } else {
          renderer.setCamera(preset);
        }
        report.outputs.emplace_back(
          kind, outputs.write(name, [&](const std::string& path) {
            renderer.saveSnapshot(path, config.output.snapshot_size_px[0],
                                  config.output.snapshot_size_px[1]);
          }));
      }
      // VTK's buffers of this snapshot go back to the kernel before the next one.
      planar_grid::cli::releaseFreedMemory();
    };
  const std::string frames_and_points = std::to_string(report.frames) + " frames, "
                                        + std::to_string(report.world_cloud_points)
                                        + " points";

  render(config.output.snapshot, "snapshot", all_street,
         [&](planar_grid::SceneRenderer& r) {
           if (!state.world_cloud->empty())
             r.addPointCloud(*state.world_cloud, planar_grid::ColorMode::HEIGHT, 2.0);
           return frames_and_points;
         });

  if (!state.plane_cloud->empty())
    render(
      config.output.planes_snapshot, "planes_snapshot", all_street,
      [&](planar_grid::SceneRenderer& r) {
        if (!state.world_cloud->empty())
          r.addPointCloud(*state.world_cloud, planar_grid::ColorMode::SOLID, 1.0, grey);
        // Colour the largest run-wide planes (by inliers merged over the run), one
        // colour each; smaller ones (car sides, bushes) stay grey so the facades
        // stand out.
        constexpr std::size_t COLOURED_PLANES = 24;
        std::vector<std::size_t> order(state.plane_inlier_counts.size());
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&state](std::size_t a, std::size_t b) {
          return state.plane_inlier_counts[a] > state.plane_inlier_counts[b];
        });
        std::vector<int> colour_of(order.size(), -1);
        for (std::size_t k = 0; k < std::min(order.size(), COLOURED_PLANES); ++k)
          colour_of[order[k]] = static_cast<int>(k);
        pcl::PointCloud<pcl::PointXYZI> labelled;
        labelled.reserve(state.plane_cloud->size());
        for (const auto& p : state.plane_cloud->points) {
          if (p.label >= colour_of.size() || colour_of[p.label] < 0)
            continue;
          pcl::PointXYZI q;
          q.getVector3fMap() = p.getVector3fMap();
          q.intensity = static_cast<float>(colour_of[p.label]);
          labelled.push_back(q);
        }
        r.addPointCloud(labelled, planar_grid::ColorMode::LABEL, 2.0);
        return frames_and_points + ", " + std::to_string(state.plane_models.size())
               + " planes (the 24 largest coloured)";
      });

  const auto add_cuboids = [&](planar_grid::SceneRenderer& r) {
    r.addCuboids(cuboids);
    std::size_t planar = 0;
    for (const auto& c : cuboids)
      planar += c.is_planar;
    return std::to_string(cuboids.size()) + (state.map ? " map" : "") + " cuboids ("
           + std::to_string(planar) + " planar, coloured by plane; non-planar grey)";
  };
  if (!cuboids.empty()) {
    render(config.output.cuboids_snapshot, "cuboids_snapshot", all_street, add_cuboids);
    if (street)
      render(config.output.cuboids_street_snapshot, "cuboids_street_snapshot", true,
             add_cuboids);
  }

  if (state.map)
    render(config.output.map_snapshot, "map_snapshot", all_street,
           [&](planar_grid::SceneRenderer& r) {
             const auto drawn = r.addMap(*state.map);
             return std::to_string(drawn.cuboids)
                    + " cuboids coloured by occupancy (blue 0, green 0.5, red 1), "
                    + std::to_string(drawn.occupied_voxel_boxes)
                    + " other occupied voxels grey, "
                    + (drawn.unknown_boxes > 0
                         ? std::string("occluded (unknown) space violet")
                         : std::string("space never measured free or occupied is "
                                       "unknown (prior), not drawn"));
           });
}
#endif

/** Exit statuses by class of failure (printHelp(), docs/OUTPUTS.md). */
constexpr int EXIT_USAGE = 2;
constexpr int EXIT_CONFIG = 3;
constexpr int EXIT_INPUT = 4;
constexpr int EXIT_OUTPUT = 5;

/** Set by run() while it opens the output set and from the first output written on: an
 * IOError then is an output error, otherwise an input error. */
bool writing_outputs = false;

/** Set by SIGINT and SIGTERM: the run stops after the frame under way. */
std::atomic<bool> stop_requested{false};
/** The signal that set it. */
volatile std::sig_atomic_t stop_signal = 0;

extern "C" void
onStopSignal(int signal)
{
  stop_signal = signal;
  stop_requested.store(true);
}

/** The exit status of the exception \a e that ended run(). */
int
exitStatus(const std::exception& e)
{
  if (dynamic_cast<const planar_grid::cli::UsageError*>(&e))
    return EXIT_USAGE;
  if (dynamic_cast<const planar_grid::ConfigError*>(&e))
    return EXIT_CONFIG;
  if (dynamic_cast<const planar_grid::OutputError*>(&e))
    return EXIT_OUTPUT;
  if (dynamic_cast<const planar_grid::IOError*>(&e))
    return writing_outputs ? EXIT_OUTPUT : EXIT_INPUT;
  if (dynamic_cast<const planar_grid::Interrupted*>(&e))
    return 128 + static_cast<int>(stop_signal); // as the shell reports a signal
  return EXIT_FAILURE;
}

/** SIGINT and SIGTERM stop the run between frames; the handler is reset by its first
 * signal, so a second one ends the process at once. Interrupted system calls restart.
 */
void
installStopHandlers()
{
  struct sigaction action {};
  action.sa_handler = onStopSignal;
  sigemptyset(&action.sa_mask);
  action.sa_flags = SA_RESETHAND | SA_RESTART;
  for (const int signal : {SIGINT, SIGTERM})
    if (::sigaction(signal, &action, nullptr) != 0)
      throw planar_grid::Exception("cannot install the handler of signal "
                                   + std::to_string(signal));
}

/** The verbosity of --log-level / --quiet / -v. */
VERBOSITY_LEVEL
logLevel(int argc, char** argv)
{
  VERBOSITY_LEVEL level = L_INFO;
  std::string text;
  if (parse_argument(argc, argv, "--log-level", text) >= 0) {
    if (text == "error")
      level = L_ERROR;
    else if (text == "warn")
      level = L_WARN;
    else if (text == "info")
      level = L_INFO;
    else if (text == "debug")
      level = L_DEBUG;
    else
      throw planar_grid::cli::UsageError("--log-level '" + text
                                         + "': one of error, warn, info, debug");
  }
  const bool quiet =
    find_switch(argc, argv, "-q") || find_switch(argc, argv, "--quiet");
  const bool verbose = find_switch(argc, argv, "-v");
  if (quiet && verbose)
    throw planar_grid::cli::UsageError("--quiet and -v contradict each other");
  if (quiet)
    level = L_ERROR;
  if (verbose)
    level = L_DEBUG;
  return level;
}

/** \brief The informational options (--help, --list-stages, --stage-reference,
 * --print-default-pipeline): true with the exit status in \a status when one was
 * given (or no argument at all). */
bool
informationalRequest(int argc, char** argv, int& status)
{
  status = EXIT_SUCCESS;
  if (argc < 2 || find_switch(argc, argv, "-h") || find_switch(argc, argv, "--help")) {
    printHelp(argv[0]);
    status = argc < 2 ? EXIT_USAGE : EXIT_SUCCESS;
    return true;
  }
  if (find_switch(argc, argv, "--list-stages")) {
    listStages();
    return true;
  }
  if (find_switch(argc, argv, "--stage-reference")) {
    std::cout << planar_grid::stageReferenceMarkdown();
    return true;
  }
  if (find_switch(argc, argv, "--print-default-pipeline")) {
    std::cout << planar_grid::defaultPipelineYaml();
    return true;
  }
  return false;
}

/** \brief A run as the command line asks for it: the configuration with the
 * command line's overrides, the frames, the memory limit and the switches. */
struct RunOptions {
  std::string config_path;
  std::string frames_text;
  planar_grid::PipelineConfig config;
  planar_grid::MemoryLimit memory_limit;
  bool resume{false};
  bool sequential{false};
  bool show_info{false};
};

/** \brief The output folder of --output, checked; false when the option is not
 * given. \throws UsageError for an empty or unexpanded folder. */
bool
outputFolderOption(int argc, char** argv, std::string& folder)
{
  if (parse_argument(argc, argv, "--output", folder) < 0)
    return false;
  // An empty folder name (an unset shell variable in a script) would otherwise fall
  // back to the YAML's output.folder and replace the outputs there.
  if (folder.empty())
    throw planar_grid::cli::UsageError("--output '' is empty: give the folder to write "
                                       "the outputs into (or leave the option out to "
                                       "use output.folder of the YAML)");
  if (planar_grid::needsShellExpansion(folder))
    throw planar_grid::cli::UsageError("--output '" + folder
                                       + "': '~' or a $VARIABLE the shell did not "
                                         "expand (quoted?); give the path itself");
  return true;
}

/** \brief Clears the snapshots --no-snapshot turns off, or that a build without the
 * viewer cannot take; with snapshots to take, makes sure of a display first (VTK
 * needs an X server; an Xvfb is started if there is none). */
void
settleSnapshots(int argc, char** argv, planar_grid::OutputConfig& output)
{
  // Every PNG snapshot the output block names.
  std::vector<std::string*> snapshots{
    &output.snapshot, &output.planes_snapshot, &output.cuboids_snapshot,
    &output.cuboids_street_snapshot, &output.map_snapshot};
  const auto any_snapshot = [&snapshots] {
    return std::any_of(snapshots.begin(), snapshots.end(),
                       [](const std::string* name) { return !name->empty(); });
  };
  if (find_switch(argc, argv, "--no-snapshot"))
    for (std::string* name : snapshots)
      name->clear();
#ifdef PLANAR_GRID_WITH_VIEWER
  if (any_snapshot())
    planar_grid::ensureDisplay(argc, argv);
#else
  if (any_snapshot()) {
    print_warn(
      "Built without the viewer (PLANAR_GRID_BUILD_VIEWER=OFF): no snapshot.\n");
    for (std::string* name : snapshots)
      name->clear();
  }
#endif
}

/** \brief The run's options from the command line. Every argument must be a known
 * option: a typo is an error, not a default. \throws UsageError, or the
 * configuration's errors. */
RunOptions
parseRunOptions(int argc, char** argv)
{
  const std::vector<std::string> with_value{
    "--config",       "--frames",    "--output", "--checkpoint-every",
    "--memory-limit", "--log-level", "--set"};
  const std::vector<std::string> switches{
    "--no-snapshot", "--resume", "--sequential", "-v", "-q", "--quiet"};
  planar_grid::cli::checkArguments(argc, argv, with_value, switches);
  setVerbosityLevel(logLevel(argc, argv));
  RunOptions options;
  options.show_info = isVerbosityLevelEnabled(L_INFO);
  if (parse_argument(argc, argv, "--config", options.config_path) < 0
      || options.config_path.empty())
    throw planar_grid::cli::UsageError("--config FILE.yaml is required (see --help)");
  parse_argument(argc, argv, "--frames", options.frames_text);
  std::string output_folder;
  const bool output_given = outputFolderOption(argc, argv, output_folder);

  std::vector<std::string> overrides; // every --set, in order
  for (int i = 1; i + 1 < argc; ++i)
    if (std::string(argv[i]) == "--set")
      overrides.emplace_back(argv[++i]);
  options.config = planar_grid::loadPipelineConfig(options.config_path, overrides);
  planar_grid::PipelineConfig& config = options.config;
  if (output_given)
    config.output.folder = output_folder;
  std::string every_text;
  if (parse_argument(argc, argv, "--checkpoint-every", every_text) >= 0) {
    std::istringstream in(every_text);
    long long every = -1;
    char extra = 0;
    if (!(in >> every) || (in >> extra) || every < 0)
      throw planar_grid::cli::UsageError("--checkpoint-every '" + every_text
                                         + "' must be a non-negative integer");
    config.output.checkpoint_every_n_frames = static_cast<std::size_t>(every);
  }
  options.memory_limit = planar_grid::machineMemoryLimit();
  std::string limit_text;
  if (parse_argument(argc, argv, "--memory-limit", limit_text) >= 0) {
    try {
      options.memory_limit.bytes = planar_grid::parseMemorySize(limit_text);
    } catch (const planar_grid::Exception& e) {
      throw planar_grid::cli::UsageError(std::string("--memory-limit: ") + e.what());
    }
    options.memory_limit.source = "--memory-limit " + limit_text;
  }
  options.resume = find_switch(argc, argv, "--resume");
  options.sequential = find_switch(argc, argv, "--sequential");
  // Before the long run.
  settleSnapshots(argc, argv, config.output);
  return options;
}

/** \brief Prints the configuration's stages and their parameters (info level). */
void
printConfiguration(const RunOptions& options)
{
  print_info("Configuration: ");
  printValue(options.config_path);
  print_info(" (%zu stages)\n", options.config.stages.size());
  for (const auto& sc : options.config.stages) {
    std::string params;
    for (const auto& [key, value] : sc.params.values())
      params += (params.empty() ? "" : ", ") + key + "=" + sc.params.toString(key);
    print_info("  %-28s %s\n", sc.type.c_str(), params.c_str());
  }
}

/** \brief The frame range of --frames (all frames without it) set on \a runner. */
void
setFrames(const RunOptions& options,
          planar_grid::PipelineRunner& runner,
          std::size_t& begin,
          std::size_t& end)
{
  begin = 0;
  end = runner.frameCount();
  if (options.frames_text.empty())
    return;
  parseFrameRange(options.frames_text, runner.frameCount(), begin, end);
  try {
    runner.setFrameRange(begin, end);
  } catch (const planar_grid::Exception& e) { // empty or past the input's end
    throw planar_grid::cli::UsageError(e.what());
  }
}

/** \brief Refuses a run whose memory estimate exceeds the limit, before anything is
 * written or mapped. */
void
checkMemory(const RunOptions& options, planar_grid::PipelineRunner& runner)
{
  const planar_grid::MemoryEstimate estimate = runner.estimateMemory();
  const planar_grid::MemoryLimit& limit = options.memory_limit;
  print_info("Memory estimate: ");
  printValue(estimate.summary());
  print_info(
    "; limit %s\n",
    limit.bytes == 0
      ? "none"
      : (planar_grid::formatBytes(limit.bytes) + " (" + limit.source + ")").c_str());
  planar_grid::checkMemoryEstimate(estimate, limit);
  runner.setMemoryLimit({}); // checked here; run() need not estimate again
}

/** \brief The checkpoint: checked to be a file name now (not at the first checkpoint,
 * after the frames before it ran), resumed from with --resume, and written every
 * output.checkpoint_every_n_frames frames. */
void
setCheckpoint(const RunOptions& options, planar_grid::PipelineRunner& runner)
{
  const planar_grid::OutputConfig& output = options.config.output;
  const std::string checkpoint_path =
    output.checkpoint.empty() ? std::string()
                              : planar_grid::outputPath(output, output.checkpoint);
  std::error_code ec;
  if ((options.resume || output.checkpoint_every_n_frames > 0)
      && !checkpoint_path.empty() && std::filesystem::is_directory(checkpoint_path, ec))
    throw planar_grid::OutputError(
      checkpoint_path
      + ": the checkpoint (output.checkpoint) is a folder, "
        "not a file: it cannot be written or read there");
  if (options.resume) {
    if (checkpoint_path.empty())
      throw planar_grid::Exception("--resume needs output.checkpoint (a file name)");
    const std::size_t next = runner.resumeFrom(checkpoint_path);
    print_info("Resuming from ");
    printValue(checkpoint_path);
    print_info(" at frame position %zu\n", next);
  }
  if (output.checkpoint_every_n_frames > 0) {
    runner.setCheckpoint(checkpoint_path, output.checkpoint_every_n_frames);
    print_info("Checkpoint every %zu frames: ", output.checkpoint_every_n_frames);
    printValue(checkpoint_path + "\n");
  }
}

/** \brief Prints the input's kind, the frames and the read-ahead (info level). */
void
printInput(const planar_grid::PipelineConfig& config,
           const planar_grid::PipelineRunner& runner,
           std::size_t begin,
           std::size_t end)
{
  const bool stereo =
    config.input.type == planar_grid::InputConfig::Type::STEREO_SEQUENCE;
  const char* input_kind =
    !config.input.ros_bag.file.empty()
      ? (stereo ? "ROS bag, stereo pairs" : "ROS bag, point clouds")
      : (stereo ? "stereo sequence" : "PCD files");
  print_info("Input: %s; running frames %zu:%zu\n", input_kind, begin, end);
  if (const std::size_t ahead = runner.frameLocalPrefix(); ahead > 0)
    print_info(
      "  loading and up to the first %zu stages run up to two frames ahead on a "
      "second thread (as many as balance the threads' measured times)\n",
      ahead);
}

/** \brief Runs the frames and writes the outputs as one set into the output folder
 * (replacing the previous ones only when all are written). */
void
runAndWrite(const RunOptions& options, planar_grid::PipelineRunner& runner)
{
  const planar_grid::PipelineConfig& config = options.config;
  // The outputs replace the previous ones in the folder as one set (staged, then
  // committed); opening the set here also finishes a commit a killed run left, removes
  // its leftovers, and finds an unwritable folder before the first frame.
  writing_outputs = true;
  planar_grid::OutputTransaction outputs(config.output.folder);
  writing_outputs = false;

  ProgressBar bar(::isatty(STDERR_FILENO) != 0);
  if (options.show_info)
    runner.setProgressCallback([&bar](std::size_t done, std::size_t total, double s) {
      bar.update(done, total, s);
    });
  installStopHandlers();
  runner.setStopFlag(&stop_requested);
  planar_grid::RunReport report;
  try {
    report = runner.run();
  } catch (const planar_grid::Interrupted& e) {
    throw planar_grid::Interrupted(
      std::string(stop_signal == SIGTERM ? "SIGTERM" : "SIGINT") + ": " + e.what()
      + "; no output was written, the previous outputs in " + config.output.folder
      + " are as they were");
  }

  planar_grid::cli::releaseFreedMemory();
  writing_outputs = true;
  planar_grid::writeRunOutputs(config.output, runner, report, outputs);
  planar_grid::cli::releaseFreedMemory();
#ifdef PLANAR_GRID_WITH_VIEWER
  planar_grid::cli::preferLowMemorySoftwareRendering();
  saveSnapshots(config, options.config_path, runner, report, outputs);
#endif
  planar_grid::writeRunReport(config.output, report, outputs);
  outputs.commit();

  if (stop_requested.load())
    print_warn(
      "A stop signal came after the last frame: the outputs were completed.\n");
  if (options.show_info) {
    std::cout << "\n" << report.timingTable() << "\nOutputs:\n";
    for (const auto& [kind, path] : report.outputs)
      std::cout << "  " << kind << ": " << path << "\n";
  }
}

int
run(int argc, char** argv)
{
  int status = EXIT_SUCCESS;
  if (informationalRequest(argc, argv, status))
    return status;
  const RunOptions options = parseRunOptions(argc, argv);
  printConfiguration(options);
  planar_grid::PipelineRunner runner(options.config);
  runner.setFrameOverlap(!options.sequential);
  std::size_t begin = 0, end = 0;
  setFrames(options, runner, begin, end);
  checkMemory(options, runner);
  setCheckpoint(options, runner);
  printInput(options.config, runner, begin, end);
  // An output that would replace a file the run reads, or that names a folder, is
  // found now rather than after the last frame.
  planar_grid::checkOutputPaths(options.config.output, runner.inputFiles(),
                                options.config.output.checkpoint_every_n_frames > 0);
  runAndWrite(options, runner);
  return EXIT_SUCCESS;
}

} // namespace

int
main(int argc, char** argv)
{
  return planar_grid::cli::runMain("planar_grid_pipeline", run, argc, argv, exitStatus);
}
