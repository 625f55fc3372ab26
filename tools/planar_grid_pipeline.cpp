// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_pipeline: runs a YAML-configured PlanarGrid pipeline over a stereo
// sequence or PCD files and writes the world cloud, trajectory, report.json and a
// snapshot.
// The command line is read in planar_grid_pipeline_options.cpp, the snapshots are
// rendered in planar_grid_pipeline_snapshots.cpp.

#include "planar_grid_pipeline.h"

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>

#include <pcl/console/print.h>

#include <signal.h>
#include <unistd.h>
#ifdef __GLIBC__
#include <malloc.h>
#endif

#include <algorithm>
#include <atomic>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <iostream>
#include <string>
#include <vector>

#include "cli.h"

using namespace pcl::console;

namespace {

using namespace pipeline_tool;

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

/** One malloc arena for the whole run, unless the environment chooses one
 * (MALLOC_ARENA_MAX, or glibc.malloc.arena_max in GLIBC_TUNABLES). The read-ahead
 * thread allocates each frame's images, disparity and clouds and the mapping thread
 * frees them; with an arena per thread glibc keeps the freed blocks of both resident,
 * which raises the run's peak resident memory. The main job's frame rate is the same
 * with one arena, on one core and on two (docs/BENCHMARKS.md, "One malloc arena"). */
void
useOneMallocArena()
{
#ifdef __GLIBC__
  const char* tunables = std::getenv("GLIBC_TUNABLES");
  if (std::getenv("MALLOC_ARENA_MAX") == nullptr
      && (tunables == nullptr || std::strstr(tunables, "arena_max") == nullptr))
    mallopt(M_ARENA_MAX, 1);
#endif
}

} // namespace

int
main(int argc, char** argv)
{
  useOneMallocArena();
  return planar_grid::cli::runMain("planar_grid_pipeline", run, argc, argv, exitStatus);
}
