// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_render_scene: renders a synthetic stereo sequence with known surfaces (a
// corridor or a room) and writes it with its calibration, poses, ground truth
// and a pipeline configuration.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/synthetic_stereo_scene.h>

#include <pcl/console/parse.h>
#include <pcl/console/print.h>
#include <pcl/console/time.h>

#include <cmath>
#include <cstdlib>
#include <exception>
#include <filesystem>
#include <set>
#include <string>

#include "cli.h"

using pcl::console::print_error;
using pcl::console::print_highlight;
using pcl::console::print_info;
using pcl::console::print_value;

namespace {

// Defaults, printed by the help.
const char* const DEFAULT_SCENE = "corridor";
constexpr int DEFAULT_FRAMES = 20;
constexpr double DEFAULT_YAW_DEG = 0.0;
constexpr double DEFAULT_LEAN_DEG = 0.0;
constexpr double DEFAULT_STEP_M = 0.15;
constexpr long DEFAULT_SEED = 1;

/** \brief The effective options. */
struct RenderOptions {
  std::string scene{DEFAULT_SCENE};
  int frames{DEFAULT_FRAMES};
  double yaw_deg{DEFAULT_YAW_DEG};
  double lean_deg{DEFAULT_LEAN_DEG};
  double step_m{DEFAULT_STEP_M};
  long seed{DEFAULT_SEED};
  std::string output;
};

void
printHelp(const char* program)
{
  print_info(
    "Renders a synthetic stereo sequence whose surfaces are known exactly (a "
    "corridor or a room of textured planes, rendered with VTK offscreen at the "
    "Karlsruhe calibration 1344x372 px, f = 645.24 px, B = 0.5707 m) and "
    "writes left/%%06d.png, right/%%06d.png, calib.txt (Karlsruhe format), "
    "poses.txt (KITTI), truth.pcd (surface samples every 0.02 m), scene.json "
    "(plane coefficients) and pipeline.yaml (run it with planar_grid_pipeline "
    "--config DIR/pipeline.yaml).\n\n");
  print_info("Syntax is: %s --output DIR <options>\n", program);
  print_info("  where options are:\n");
  print_info("    --output DIR      the folder to write (created; required)\n");
  print_info("    --scene S         corridor | room (default: ");
  print_value("%s", DEFAULT_SCENE);
  print_info(")\n");
  print_info("    --frames N        number of frames, >= 1 (default: ");
  print_value("%d", DEFAULT_FRAMES);
  print_info("); the path must end 3 m before the far wall\n");
  print_info(
    "    --yaw-deg A       turn the scene and the camera path about the vertical, "
    "degrees (default: ");
  print_value("%g", DEFAULT_YAW_DEG);
  print_info(")\n");
  print_info(
    "    --lean-deg L      lean of the leaning wall from vertical, degrees, in "
    "[-30, 30], positive away from the path (default: ");
  print_value("%g", DEFAULT_LEAN_DEG);
  print_info(")\n");
  print_info("    --step-m S        camera motion per frame, metres, >= 0 (default: ");
  print_value("%g", DEFAULT_STEP_M);
  print_info(")\n");
  print_info("    --seed S          texture seed, >= 0 (default: ");
  print_value("%ld", DEFAULT_SEED);
  print_info(")\n");
  print_info("    -h, --help        this help\n");
  print_info("    --version         print the name and version\n\n");
  print_info(
    "Rendering needs an X server (Debian's VTK 9.1); without one the tool starts its "
    "own Xvfb (when xvfb is installed), which ends with it.\n");
}

/** \brief Reads every option; throws planar_grid::Exception on a malformed one
 * (a malformed number is an error, never 0).
 * \param[out] help set when -h/--help was given */
RenderOptions
parseOptions(int argc, char** argv, bool& help)
{
  using pcl::console::find_argument;
  using pcl::console::parse_argument;
  using planar_grid::Exception;
  RenderOptions options;
  help = pcl::console::find_switch(argc, argv, "-h")
         || pcl::console::find_switch(argc, argv, "--help");
  if (help)
    return options;

  // argv indices accounted for; anything else is an unknown argument.
  std::set<int> used;
  const auto option_with_value = [&](const char* name) {
    const int index = find_argument(argc, argv, name);
    if (index < 0)
      return false;
    if (index + 1 >= argc)
      throw Exception(std::string(name) + " needs a value");
    used.insert(index);
    used.insert(index + 1);
    return true;
  };
  const auto value_of = [&](const char* name) {
    return std::string(argv[find_argument(argc, argv, name) + 1]);
  };
  // parse_argument returns -1 for a value with junk in it ("2m") or out of range.
  const auto number = [&](const char* name, double& value, const char* expected) {
    if (option_with_value(name)
        && (parse_argument(argc, argv, name, value) < 0 || !std::isfinite(value)))
      throw Exception(std::string(name) + " expects " + expected + "; got '"
                      + value_of(name) + "'");
  };

  if (option_with_value("--output"))
    parse_argument(argc, argv, "--output", options.output);
  if (option_with_value("--scene")) {
    parse_argument(argc, argv, "--scene", options.scene);
    if (options.scene != "corridor" && options.scene != "room")
      throw Exception("--scene expects corridor or room; got '" + options.scene + "'");
  }
  if (option_with_value("--frames")
      && (parse_argument(argc, argv, "--frames", options.frames) < 0
          || options.frames < 1))
    throw Exception("--frames expects an integer >= 1; got '" + value_of("--frames")
                    + "'");
  number("--yaw-deg", options.yaw_deg, "a number of degrees");
  number("--lean-deg", options.lean_deg, "a number of degrees in [-30, 30]");
  if (std::abs(options.lean_deg) > 30.0)
    throw Exception("--lean-deg expects a number of degrees in [-30, 30]; got "
                    + value_of("--lean-deg"));
  number("--step-m", options.step_m, "a number of metres >= 0");
  if (options.step_m < 0.0)
    throw Exception("--step-m expects a number of metres >= 0; got "
                    + value_of("--step-m"));
  if (option_with_value("--seed")
      && (parse_argument(argc, argv, "--seed", options.seed) < 0 || options.seed < 0))
    throw Exception("--seed expects an integer >= 0; got '" + value_of("--seed") + "'");

  for (int i = 1; i < argc; ++i)
    if (used.count(i) == 0)
      throw Exception(std::string("unknown argument '") + argv[i] + "' (see --help)");
  if (options.output.empty())
    throw Exception("--output DIR is required (see --help)");
  return options;
}

int
run(int argc, char** argv)
{
  bool help = false;
  const RenderOptions options = parseOptions(argc, argv, help);
  if (help) {
    printHelp(argv[0]);
    return EXIT_SUCCESS;
  }

  planar_grid::SyntheticStereoScene::Params params;
  params.kind = planar_grid::syntheticSceneKindFromString(options.scene);
  params.frame_count = options.frames;
  params.scene_yaw_rad = options.yaw_deg * M_PI / 180.0;
  params.wall_lean_rad = options.lean_deg * M_PI / 180.0;
  params.step_m = options.step_m;
  params.seed = static_cast<std::uint64_t>(options.seed);
  // The scene checks its parameters (the path must fit) before any rendering.
  planar_grid::SyntheticStereoScene scene(params);

  // Before rendering: VTK needs an X server; start an Xvfb if there is none.
  planar_grid::ensureDisplay(argc, argv);

  print_info("Scene: ");
  print_value("%s", options.scene.c_str());
  print_info(", frames: ");
  print_value("%d", options.frames);
  print_info(", step: ");
  print_value("%g", options.step_m);
  print_info(" m, yaw: ");
  print_value("%g", options.yaw_deg);
  print_info(" deg, lean: ");
  print_value("%g", options.lean_deg);
  print_info(" deg, seed: ");
  print_value("%ld", options.seed);
  print_info(", %zu planes\n", scene.getPlanes().size());
  const auto& calibration = scene.getCalibration();
  print_info("Calibration: %dx%d px, f = %g px, cx = %g px, cy = %g px, B = %g m\n",
             calibration.width, calibration.height, calibration.focal_length_px,
             calibration.cx_px, calibration.cy_px, calibration.baseline_m);

  pcl::console::TicToc timer;
  timer.tic();
  print_highlight("Writing ");
  print_value("%s ", options.output.c_str());
  scene.writeSequence(options.output);
  print_info("[done, ");
  print_value("%g", timer.toc());
  print_info(" ms : %d stereo pairs]\n", options.frames);
  print_info("Run the pipeline with: planar_grid_pipeline --config %s\n",
             (std::filesystem::path(options.output) / "pipeline.yaml").c_str());
  return EXIT_SUCCESS;
}

} // namespace

int
main(int argc, char** argv)
{
  return planar_grid::cli::runMain("planar_grid_render_scene", run, argc, argv);
}
