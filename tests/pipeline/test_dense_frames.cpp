// SPDX-License-Identifier: BSD-3-Clause
// stereo_disparity's every_n_frames: dense stereo on every n-th frame, key features on
// all of them.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

const std::string KARLSRUHE =
  std::string(PLANAR_GRID_DATA_DIR) + "/karlsruhe_2010_03_09_drive_0023";

/** Karlsruhe frames 10-15 (sequence numbers 0-5) with the INS poses, through stereo
 * (every \a every_n_frames frames), ORB features, the voxel grid and the accumulated
 * world cloud. */
planar_grid::PipelineConfig
denseEvery(int every_n_frames)
{
  const std::string yaml =
    "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE
    + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE
    + "/right/I2_%06d.png\n  first_index: 10\n  frame_count: 6\n"
    + "  calibration: {format: karlsruhe, file: " + KARLSRUHE + "/calib.txt}\n"
    + "  poses: {format: karlsruhe_insdata, file: " + KARLSRUHE
    + "/insdata.txt, camera_height_m: 1.57, camera_pitch_rad: 0.09}\n" + "pipeline:\n"
    + "  - type: stereo_disparity\n"
    + "    params: {algorithm: sgbm_3way, num_disparities_px: 128, max_range_m: 30.0, "
    + "every_n_frames: " + std::to_string(every_n_frames) + "}\n"
    + "  - type: feature_matching\n"
    + "    params: {feature_type: orb_grid, max_features: 1000}\n"
    + "  - type: voxel_grid\n" + "    params: {leaf_size_m: 0.2}\n"
    + "  - type: transform_to_world\n" + "  - type: accumulate\n"
    + "    params: {leaf_size_m: 0.2}\n";
  return planar_grid::parsePipelineConfig(yaml, "dense.yaml", "/");
}

const planar_grid::StageReport&
stage(const planar_grid::RunReport& report, const std::string& type)
{
  const auto it =
    std::find_if(report.stages.begin(), report.stages.end(),
                 [&type](const planar_grid::StageReport& s) { return s.type == type; });
  if (it == report.stages.end())
    throw std::runtime_error("no stage " + type);
  return *it;
}

double
counter(const planar_grid::StageReport& s, const std::string& name)
{
  for (const auto& [key, value] : s.counters)
    if (key == name)
      return value;
  return -1.0;
}

} // namespace

TEST(DenseFrames, EveryThirdFrameGivesTheCloudsOfARunOverThoseFramesAlone)
{
  // Dense stereo on sequence numbers 0 and 3 of six frames, key features on all six.
  planar_grid::PipelineRunner every_third(denseEvery(3));
  const planar_grid::RunReport a = every_third.run();
  // The same two frames alone, each dense.
  planar_grid::PipelineRunner alone(denseEvery(1));
  alone.setFrameRange(0, 6, 3);
  const planar_grid::RunReport b = alone.run();

  ASSERT_EQ(a.frames, 6u);
  ASSERT_EQ(b.frames, 2u);
  // The stereo points are those of the two dense frames, and they reach the world.
  const auto& stereo_a = stage(a, "stereo_disparity");
  const auto& stereo_b = stage(b, "stereo_disparity");
  EXPECT_GT(stereo_b.points_out, 2u * 100000u);
  EXPECT_EQ(stereo_a.points_out, stereo_b.points_out);
  EXPECT_EQ(stage(a, "voxel_grid").points_out, stage(b, "voxel_grid").points_out);
  const auto& cloud_a = *every_third.state().world_cloud;
  const auto& cloud_b = *alone.state().world_cloud;
  ASSERT_GT(cloud_b.size(), 1000u);
  ASSERT_EQ(cloud_a.size(), cloud_b.size());
  for (std::size_t i = 0; i < cloud_a.size(); ++i) {
    ASSERT_EQ(cloud_a[i].x, cloud_b[i].x) << i;
    ASSERT_EQ(cloud_a[i].y, cloud_b[i].y) << i;
    ASSERT_EQ(cloud_a[i].z, cloud_b[i].z) << i;
  }
  // Every frame still gets its key features: six frames' worth against two.
  const double features_a = counter(stage(a, "feature_matching"), "features");
  const double features_b = counter(stage(b, "feature_matching"), "features");
  ASSERT_GT(features_b, 2 * 100.0);
  EXPECT_GT(features_a, 2.5 * features_b);
  // Every frame has its pose in the trajectory.
  EXPECT_EQ(every_third.trajectory().size(), 6u);
}

TEST(DenseFrames, EveryFrameIsTheDefaultAndZeroIsRefused)
{
  planar_grid::PipelineRunner every(denseEvery(1));
  const planar_grid::RunReport r = every.run();
  ASSERT_EQ(r.frames, 6u);
  // Six dense frames: more stereo points than any two of them could give.
  EXPECT_GT(stage(r, "stereo_disparity").points_out, 6u * 100000u);
  EXPECT_THROW(denseEvery(0), planar_grid::ConfigError);
}
