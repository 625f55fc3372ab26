// SPDX-License-Identifier: BSD-3-Clause
// Running one stage on one frame and building the stages, for Mapper, which runs the
// stages of the live calls and of PipelineRunner (internal to the engine).
#pragma once

#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/stage_report.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {
namespace stages {

/** \brief Called right before a stage processes a frame: the stage's index and the
 * frame as the stages before it left it. */
using StageCallback = Mapper::StageCallback;

/** \brief The count of the valid points of the cloud a stage left behind. */
using CloudCount = StageProgress::CloudCount;

/** \brief Runs stage \a s (\a stage, of type \a type) on \a frame, after \a callback
 * when it is set, and appends its time, points and counters to \a progress; failures
 * name the frame, its position \a i and the stage. */
void runStage(Stage& stage,
              std::size_t s,
              const std::string& type,
              const StageCallback& callback,
              Frame& frame,
              PipelineState& state,
              std::size_t i,
              StageProgress& progress);

/** \brief Builds a stage of type \a type from its parameters.
 * \throws planar_grid::ConfigError at \a source, \a line, \a column for an unknown
 * type or parameters the stage rejects */
std::unique_ptr<Stage> createStage(const std::string& type,
                                   const ParamValues& params,
                                   const std::string& source,
                                   int line,
                                   int column);

} // namespace stages
} // namespace planar_grid
