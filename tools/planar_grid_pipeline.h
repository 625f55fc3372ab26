// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of planar_grid_pipeline: the run's options from the command
// line (planar_grid_pipeline_options.cpp), the snapshots
// (planar_grid_pipeline_snapshots.cpp) and the run (planar_grid_pipeline.cpp).
#pragma once

#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/console/print.h>

#include <cstddef>
#include <string>

namespace pipeline_tool {

/** pcl::console::print_value() at the info level: PCL's prints whatever the
 * verbosity, which --quiet must silence. */
inline void
printValue(const std::string& text)
{
  if (pcl::console::isVerbosityLevelEnabled(pcl::console::L_INFO))
    pcl::console::print_value("%s", text.c_str());
}

/** Exit statuses by class of failure (printHelp(), docs/OUTPUTS.md). */
constexpr int EXIT_USAGE = 2;
constexpr int EXIT_CONFIG = 3;
constexpr int EXIT_INPUT = 4;
constexpr int EXIT_OUTPUT = 5;

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

/** \brief The informational options (--help, --list-stages, --stage-reference,
 * --print-default-pipeline): true with the exit status in \a status when one was
 * given (or no argument at all). */
bool informationalRequest(int argc, char** argv, int& status);

/** \brief The run's options from the command line. Every argument must be a known
 * option: a typo is an error, not a default. \throws UsageError, or the
 * configuration's errors. */
RunOptions parseRunOptions(int argc, char** argv);

/** \brief The frame range of --frames (all frames without it) set on \a runner. */
void setFrames(const RunOptions& options,
               planar_grid::PipelineRunner& runner,
               std::size_t& begin,
               std::size_t& end);

#ifdef PLANAR_GRID_WITH_VIEWER
/** Renders the configured snapshots (planar_grid_pipeline_snapshots.cpp). */
void saveSnapshots(const planar_grid::PipelineConfig& config,
                   const std::string& config_path,
                   const planar_grid::PipelineRunner& runner,
                   planar_grid::RunReport& report,
                   planar_grid::OutputTransaction& outputs);
#endif

} // namespace pipeline_tool
