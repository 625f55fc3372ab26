// SPDX-License-Identifier: BSD-3-Clause
// The folders and constants that several test files use.
#pragma once

#include <string>

namespace planar_grid_test {

constexpr double PI = 3.14159265358979323846;

/** The repository's root (its config/ and docs/). */
inline const std::string SOURCE_DIR = PLANAR_GRID_SOURCE_DIR;
/** The test data (PLANAR_GRID_DATA_DIR). */
inline const std::string DATA = PLANAR_GRID_DATA_DIR;
/** PCL's sample clouds in the test data. */
inline const std::string CLOUDS = DATA + "/pcl_clouds";
/** The Karlsruhe stereo sequence the main job maps. */
inline const std::string KARLSRUHE_DIR = DATA + "/karlsruhe_2010_03_09_drive_0023";
/** Its rig, rounded from its calibration: focal length (px) and baseline (m). */
constexpr double KARLSRUHE_FOCAL_PX = 645.24;
constexpr double KARLSRUHE_BASELINE_M = 0.5707;

} // namespace planar_grid_test
