// SPDX-License-Identifier: BSD-3-Clause
// The real job the reliability tests run and interrupt: Karlsruhe frames from 10
// through the paper pipeline with the map.
#pragma once

#include <filesystem>
#include <string>

namespace planar_grid {
namespace test {

/** \brief The Karlsruhe sequence in the shared data. */
inline const std::string KARLSRUHE =
  std::string(PLANAR_GRID_DATA_DIR) + "/karlsruhe_2010_03_09_drive_0023";

/** \brief A pipeline configuration: \a frame_count Karlsruhe frames from frame 10 with
 * the GPS/INS poses, stereo, features, KL filter, voxel grid, planes, ground, cuboids,
 * map (prior free) and accumulate; outputs in \a output, with \a output_keys (YAML
 * lines, each indented by two spaces) added to the output block. The features are the
 * main job's ORB grid (config/karlsruhe.yaml): under the sanitizers SIFT takes half of
 * a frame's time, and these tests run the tool on many frames. */
inline std::string
karlsruheJob(int frame_count,
             const std::filesystem::path& output,
             const std::string& output_keys)
{
  return "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE
         + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE
         + "/right/I2_%06d.png\n  first_index: 10\n  frame_count: "
         + std::to_string(frame_count)
         + "\n"
           "  calibration: {format: karlsruhe, file: "
         + KARLSRUHE
         + "/calib.txt}\n  poses: {format: karlsruhe_insdata, file: " + KARLSRUHE
         + "/insdata.txt, camera_height_m: 1.57, camera_pitch_rad: 0.09}\n"
           "pipeline:\n"
           "  - type: stereo_disparity\n"
           "    params: {num_disparities_px: 128, max_range_m: 30.0}\n"
           "  - type: feature_matching\n"
           "    params: {feature_type: orb_grid, max_features: 2000, "
           "max_disparity_px: 128, max_range_m: 30.0}\n"
           "  - type: kl_occupancy_filter\n"
           "  - type: voxel_grid\n    params: {leaf_size_m: 0.1}\n"
           "  - type: transform_to_world\n"
           "  - type: multi_plane_segmentation\n"
           "    params: {min_inliers: 300, sample: features}\n"
           "  - type: ground_removal\n"
           "  - type: planar_cuboid_approximation\n"
           "  - type: map_integration\n    params: {prior: free}\n"
           "  - type: accumulate\n"
           "output:\n  folder: "
         + output.string() + "\n" + output_keys;
}

} // namespace test
} // namespace planar_grid
