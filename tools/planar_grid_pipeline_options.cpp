// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_pipeline's command line: --help, the informational options, and the
// run's options (the configuration with the command line's overrides, the frames, the
// memory limit, the switches and the snapshots).

#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>

#include "cli.h"
#include "planar_grid_pipeline.h"
#ifdef PLANAR_GRID_WITH_VIEWER
#include <planar_grid/visualization/scene_renderer.h>
#endif

#include <pcl/console/parse.h>
#include <pcl/console/print.h>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <sstream>
#include <string>
#include <vector>

using namespace pcl::console;

namespace pipeline_tool {

namespace {

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
             "                         --set stereo_disparity.row_downscale=2;\n"
             "                         --set cell_size_m=0.2 sets the top-level\n"
             "                         minimum cell every cell-size key follows\n");
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

} // namespace

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

} // namespace pipeline_tool
