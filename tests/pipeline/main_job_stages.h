// SPDX-License-Identifier: BSD-3-Clause
// The main job's stages (config/karlsruhe.yaml), for tests that run them on a few
// frames of another input.
#pragma once

#include <planar_grid/pipeline/pipeline_config.h>

#include <gtest/gtest.h>

#include <fstream>
#include <sstream>
#include <string>

#include "../test_constants.h"

namespace planar_grid_test {

/** The `pipeline:` block of config/karlsruhe.yaml as written there (from its
 * "pipeline:" line up to its "output:" line), so that the tests follow the main job. */
inline std::string
mainJobStages()
{
  const std::string path =
    std::string(PLANAR_GRID_SOURCE_DIR) + "/config/karlsruhe.yaml";
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  const std::string yaml = text.str();
  const std::size_t begin = yaml.find("\npipeline:\n");
  const std::size_t end = yaml.find("\noutput:\n");
  if (begin == std::string::npos || end == std::string::npos || end < begin) {
    ADD_FAILURE() << path << ": no 'pipeline:' block followed by 'output:'";
    return "";
  }
  return yaml.substr(begin + 1, end - begin);
}

/** The main job's input (the Karlsruhe PNG pairs, calib.txt and the insdata poses with
 * config/karlsruhe.yaml's camera mount) limited to \a frame_count frames from \a
 * first_index. */
inline std::string
mainJobImageInput(int first_index, int frame_count)
{
  const planar_grid::InputConfig main_job =
    planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                    + "/config/karlsruhe.yaml")
      .input;
  std::ostringstream mount;
  mount.precision(17);
  mount << "camera_height_m: " << main_job.camera_height_m
        << ", camera_pitch_rad: " << main_job.camera_pitch_rad;
  return "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE_DIR
         + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE_DIR
         + "/right/I2_%06d.png\n  first_index: " + std::to_string(first_index)
         + "\n  frame_count: " + std::to_string(frame_count)
         + "\n  calibration: {format: karlsruhe, file: " + KARLSRUHE_DIR
         + "/calib.txt}\n  poses: {format: karlsruhe_insdata, file: " + KARLSRUHE_DIR
         + "/insdata.txt, " + mount.str() + "}\n";
}

} // namespace planar_grid_test
