// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <string>
#include <vector>

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

/** \brief Checks, before the first frame, that every output the run will write can
 * take its place in \a output.folder: none of them (nor the checkpoint, with \a
 * with_checkpoint) is a file the run reads, such as `trajectory: insdata.txt` in the
 * folder of the poses file, which the run would replace with its own output (the paths
 * are compared canonical, and as the same file when both exist, so that a symbolic or
 * hard link is found too); and none names an existing folder, which a file cannot
 * replace, so that the run would fail after its last frame.
 * \param[in] output the output block (its folder as the run uses it, --output applied)
 * \param[in] inputs every file the run reads (PipelineRunner::inputFiles())
 * \param[in] with_checkpoint whether the run writes its checkpoint
 * \throws planar_grid::IOError naming the output's path and key, and the input file
 * and what it is, or the folder
 * \ingroup pipeline */
void checkOutputPaths(const OutputConfig& output,
                      const std::vector<InputFile>& inputs,
                      bool with_checkpoint);

/** \brief \a output.folder / \a name. */
std::string outputPath(const OutputConfig& output, const std::string& name);

} // namespace planar_grid
