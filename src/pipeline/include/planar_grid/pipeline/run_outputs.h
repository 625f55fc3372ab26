// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <string>

namespace planar_grid {

/** \brief Writes what a run produced into \a output.folder (created if needed): the
 * world cloud as binary-compressed PCD and the trajectory in KITTI format, each to a
 * temporary file renamed into place, and records them in \a report.outputs. The report
 * itself is written by writeRunReport(), last, so that it lists every output. \throws
 * planar_grid::IOError naming the file that could not be written \ingroup pipeline */
void writeRunOutputs(const OutputConfig& output,
                     const PipelineRunner& runner,
                     RunReport& report);

/** \brief Writes report.json (RunReport::toJson()) atomically and records its path. */
void writeRunReport(const OutputConfig& output, RunReport& report);

/** \brief \a output.folder / \a name. */
std::string outputPath(const OutputConfig& output, const std::string& name);

} // namespace planar_grid
