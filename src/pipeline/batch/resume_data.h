// SPDX-License-Identifier: BSD-3-Clause
// Private to the batch library: the decoded content of a checkpoint
// (pipeline_checkpoint.cpp), applied by PipelineRunner::run() (pipeline_runner.cpp).
#pragma once

#include <planar_grid/pipeline/pipeline_runner.h>

#include <cstdint>
#include <vector>

namespace planar_grid {

/** \brief What a checkpoint holds: the frame positions, the report so far, the
 * trajectory, the shared state and each stage's state bytes. */
struct PipelineRunner::ResumeData {
  /** First frame position of the run that wrote the checkpoint. */
  std::size_t first_frame{0};
  /** The frame position the run continues at. */
  std::size_t next_frame{0};
  /** The report up to the checkpoint. */
  RunReport report;
  /** The poses up to the checkpoint. */
  Trajectory trajectory;
  /** The shared state (clouds, planes, cuboids, map). */
  PipelineState state;
  /** Stage::saveState() of each stage, in order. */
  std::vector<std::vector<std::uint8_t>> stage_states;
  /** The frame files' stamps the checkpoint recorded (version 3), all checked. */
  std::vector<InputStamp> frame_stamps;
};

} // namespace planar_grid
