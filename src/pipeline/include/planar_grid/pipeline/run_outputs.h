// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <string>

namespace planar_grid {

/** \brief Stages what a run produced in \a transaction (see OutputTransaction): the
 * world cloud and the planes as binary-compressed PCD, the map (.pgmap), its OctoMap
 * (.bt) and mesh (.ply) exports and the trajectory in KITTI format, each under its name
 * in \a output, and records their final paths in \a report.outputs. Nothing in the
 * output folder changes until transaction.commit(). The report itself is staged by
 * writeRunReport(), last, so that it lists every output.
 * \throws planar_grid::IOError naming the output file (its final path) and the cause
 * of a failed write (a full disk, the file size limit, ...); the previous outputs stay
 * \ingroup pipeline */
void writeRunOutputs(const OutputConfig& output,
                     const PipelineRunner& runner,
                     RunReport& report,
                     OutputTransaction& transaction);

/** \brief Stages report.json (RunReport::toJson()) in \a transaction and records its
 * final path. \throws planar_grid::IOError as writeRunOutputs() */
void writeRunReport(const OutputConfig& output,
                    RunReport& report,
                    OutputTransaction& transaction);

/** \brief Writes the same files as the transaction overload straight into \a
 * output.folder (created if needed), each replaced atomically on its own: a failure
 * part way leaves the earlier files new and the later ones old. Prefer the
 * transaction overload for a folder a reader must find consistent.
 * \throws planar_grid::IOError naming the file that could not be written and the
 * cause */
void writeRunOutputs(const OutputConfig& output,
                     const PipelineRunner& runner,
                     RunReport& report);

/** \brief Writes report.json (RunReport::toJson()) atomically and records its path. */
void writeRunReport(const OutputConfig& output, RunReport& report);

/** \brief \a output.folder / \a name. */
std::string outputPath(const OutputConfig& output, const std::string& name);

} // namespace planar_grid
