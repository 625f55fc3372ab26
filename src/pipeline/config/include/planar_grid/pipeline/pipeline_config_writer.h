// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/pipeline_config.h>

#include <string>

namespace planar_grid {

/** \brief A stage of the registry with every parameter at its default, for building a
 * configuration in code: change its parameters with `params.set(key, value)`, then
 * write the configuration with pipelineConfigToYaml().
 * \param[in] type a stage type of the registry (`planar_grid_pipeline --list-stages`)
 * \return the stage, with line and column 0
 * \throws planar_grid::Exception listing the known types when \a type is not one
 * \ingroup pipeline */
StageConfig defaultStageConfig(const std::string& type);

/** \brief Writes a pipeline configuration as YAML in the schema loadPipelineConfig()
 * reads (documented in config/example.yaml), so that code which prepares a run (a
 * synthetic sequence, a tool) does not spell the schema itself.
 *
 * What is written: the input (type stereo_sequence: image patterns, first_index,
 * frame_count, calibration, poses when a format is set, repeat when it is not a
 * single pass); the stages in order, each with the parameters whose value differs
 * from the stage's default (the others take their defaults when loaded, so a
 * map_integration resolution_m left at its default still follows the cuboid stage's
 * min_cell_size_m); the output folder and every output field that differs from
 * OutputConfig's default (street_view only when a street snapshot uses it). Paths
 * are written as given: relative ones are resolved against the file's folder when it
 * is loaded. Real numbers are written in their shortest form that reads back exactly.
 *
 * The text is loaded again before it is returned, so a configuration that the loader
 * would refuse is refused here, at the writer's call.
 * \param[in] config the configuration; its input must be a stereo_sequence (not a ROS
 *            bag)
 * \param[in] comment text written at the top as `#` comment lines, one per line of
 *            the text ("" = none)
 * \return the YAML text; loadPipelineConfig() on it gives \a config back, with the
 *         relative paths resolved
 * \throws planar_grid::Exception for a pcd_files or ros_bag input, or a parameter
 *         that the stage's table does not have (the message lists the stage's keys);
 *         planar_grid::ConfigError (line:col of the generated text) for a value the
 *         loader refuses, e.g. out of its range
 * \ingroup pipeline */
std::string pipelineConfigToYaml(const PipelineConfig& config,
                                 const std::string& comment = "");

/** \brief The `pipeline:` section of a configuration that lists every stage type of the
 * registry, in its order, with every parameter at its default, each documented by
 * comments from the stage's table: the stage's description, role and data flow, and
 * for each parameter its description, type, range and unit. Written by
 * `planar_grid_pipeline --print-default-pipeline`; config/example.yaml holds it, and a
 * test fails when the two differ.
 *
 * The text begins with a comment line naming the command and ends with a comment line
 * that closes the section, so that it can be found and replaced in a file. It loads
 * as the pipeline of a stereo_sequence input whose poses come from visual_odometry.
 * \return the YAML text, lines of at most 88 characters where the words allow
 * \ingroup pipeline */
std::string defaultPipelineYaml();

} // namespace planar_grid
