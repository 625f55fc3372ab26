// SPDX-License-Identifier: BSD-3-Clause
// stereo_disparity's dense frames: every n-th frame, or keyframes chosen by the
// camera's motion; key features on all of them.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <stdexcept>
#include <string>
#include <vector>

#include "../test_constants.h"

namespace {

using planar_grid_test::KARLSRUHE_DIR;

/** Karlsruhe frames \a first to \a first + \a frame_count - 1 (sequence numbers from 0)
 * with the INS poses, through stereo (with the stereo_disparity parameters
 * \a selection, YAML flow-map entries), ORB features, the voxel grid and the
 * accumulated world cloud. */
planar_grid::PipelineConfig
denseFrames(const std::string& selection, int frame_count = 6, int first = 10)
{
  const std::string yaml =
    "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE_DIR
    + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE_DIR
    + "/right/I2_%06d.png\n  first_index: " + std::to_string(first)
    + "\n  frame_count: " + std::to_string(frame_count) + "\n"
    + "  calibration: {format: karlsruhe, file: " + KARLSRUHE_DIR + "/calib.txt}\n"
    + "  poses: {format: karlsruhe_insdata, file: " + KARLSRUHE_DIR
    + "/insdata.txt, camera_height_m: 1.57, camera_pitch_rad: 0.09}\n" + "pipeline:\n"
    + "  - type: stereo_disparity\n"
    + "    params: {algorithm: sgbm_3way, num_disparities_px: 128, max_range_m: 30.0, "
    + selection + "}\n" + "  - type: feature_matching\n"
    + "    params: {feature_type: orb_grid, max_features: 1000}\n"
    + "  - type: voxel_grid\n" + "    params: {leaf_size_m: 0.2}\n"
    + "  - type: transform_to_world\n" + "  - type: accumulate\n"
    + "    params: {leaf_size_m: 0.2}\n";
  return planar_grid::parsePipelineConfig(yaml, "dense.yaml", "/");
}

/** denseFrames() over frames 10-15, dense every \a every_n_frames frames. */
planar_grid::PipelineConfig
denseEvery(int every_n_frames)
{
  return denseFrames("every_n_frames: " + std::to_string(every_n_frames));
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

/** Runs \a runner sequentially and returns the sequence numbers of its dense frames
 * (those stereo_disparity gave a disparity image), read before stage \a after_stereo.
 */
std::vector<std::size_t>
denseSequenceNumbers(planar_grid::PipelineRunner& runner, std::size_t after_stereo = 1)
{
  std::vector<std::size_t> dense;
  runner.setFrameOverlap(false);
  runner.setStageCallback(
    [&dense, after_stereo](std::size_t s, planar_grid::Frame& frame) {
      if (s == after_stereo && !frame.disparity.empty())
        dense.push_back(frame.sequence_number);
    });
  runner.run();
  return dense;
}

} // namespace

TEST(DenseFrames, KeyframesAreTheFramesThatMovedOrTurnedFarEnoughFromTheLastOne)
{
  struct Rule {
    double translation_m, rotation_rad;
    int max_gap;
  };
  // By distance (with a gap), by the turn alone (frames 60-79 are the drive's turn,
  // about 0.04 rad a frame), and both.
  for (const Rule rule :
       {Rule{1.5, 3.0, 4}, Rule{1000.0, 0.1, 100}, Rule{2.5, 0.12, 6}}) {
    const std::string name = std::to_string(rule.translation_m) + " m, "
                             + std::to_string(rule.rotation_rad) + " rad";
    planar_grid::PipelineRunner runner(
      denseFrames("frame_selection: keyframes, keyframe_translation_m: "
                    + std::to_string(rule.translation_m)
                    + ", keyframe_rotation_rad: " + std::to_string(rule.rotation_rad)
                    + ", keyframe_max_gap_frames: " + std::to_string(rule.max_gap),
                  20, 60));
    const std::vector<std::size_t> dense = denseSequenceNumbers(runner);
    const planar_grid::Trajectory& poses = runner.trajectory();
    ASSERT_EQ(poses.size(), 20u) << name;

    // The rule applied by hand to the poses the run used.
    std::vector<std::size_t> expected{0};
    for (std::size_t i = 1; i < poses.size(); ++i) {
      const Eigen::Isometry3d motion = poses[expected.back()].inverse() * poses[i];
      if (motion.translation().norm() >= rule.translation_m
          || Eigen::AngleAxisd(motion.rotation()).angle() >= rule.rotation_rad
          || i - expected.back() >= static_cast<std::size_t>(rule.max_gap))
        expected.push_back(i);
    }
    EXPECT_EQ(dense, expected) << name;
    // Some frames are dense and some are not.
    EXPECT_GE(expected.size(), 3u) << name;
    EXPECT_LT(expected.size(), 15u) << name;
    EXPECT_EQ(counter(stage(runner.report(), "stereo_disparity"), "dense_frames"),
              static_cast<double>(dense.size()))
      << name;
  }
}

TEST(DenseFrames, AKeyframeComesAtTheLongestGapWhateverTheMotion)
{
  planar_grid::PipelineRunner runner(
    denseFrames("frame_selection: keyframes, keyframe_translation_m: 1000, "
                "keyframe_rotation_rad: 3.14, keyframe_max_gap_frames: 3",
                8));
  EXPECT_EQ(denseSequenceNumbers(runner), (std::vector<std::size_t>{0, 3, 6}));
  // A second run of the same runner starts again with a keyframe.
  std::vector<std::size_t> again = denseSequenceNumbers(runner);
  EXPECT_EQ(again, (std::vector<std::size_t>{0, 3, 6}));
}

TEST(DenseFrames, KeyframesNeedThePoseBeforeTheStereoStageAndNoEveryNFrames)
{
  // every_n_frames belongs to the other selection.
  try {
    denseFrames("frame_selection: keyframes, every_n_frames: 2");
    FAIL() << "keyframes with every_n_frames 2 were accepted";
  } catch (const planar_grid::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("every_n_frames"), std::string::npos)
      << e.what();
  }
  // Poses from visual odometry listed after the stereo stage come too late.
  const std::string yaml =
    "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE_DIR
    + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE_DIR
    + "/right/I2_%06d.png\n  first_index: 10\n  frame_count: 3\n"
    + "  calibration: {format: karlsruhe, file: " + KARLSRUHE_DIR + "/calib.txt}\n"
    + "  poses: {format: odometry}\n" + "pipeline:\n" + "  - type: stereo_disparity\n"
    + "    params: {num_disparities_px: 128, frame_selection: keyframes}\n"
    + "  - type: feature_matching\n" + "  - type: visual_odometry\n"
    + "  - type: transform_to_world\n" + "  - type: accumulate\n";
  try {
    planar_grid::parsePipelineConfig(yaml, "late_poses.yaml", "/");
    FAIL() << "keyframes before visual_odometry were accepted";
  } catch (const planar_grid::ConfigError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("late_poses.yaml:"), std::string::npos) << what;
    EXPECT_NE(what.find("visual_odometry"), std::string::npos) << what;
    EXPECT_NE(what.find("frame_selection: every_n_frames"), std::string::npos) << what;
  }
  // Listed after visual_odometry, the stage has the pose it needs.
  std::string reordered = yaml;
  const std::string stereo =
    "  - type: stereo_disparity\n"
    "    params: {num_disparities_px: 128, frame_selection: keyframes}\n";
  reordered.erase(reordered.find(stereo), stereo.size());
  reordered.insert(reordered.find("  - type: transform_to_world"), stereo);
  planar_grid::PipelineRunner runner(
    planar_grid::parsePipelineConfig(reordered, "vo_first.yaml", "/"));
  const std::vector<std::size_t> dense = denseSequenceNumbers(runner, 3);
  ASSERT_FALSE(dense.empty());
  EXPECT_EQ(dense.front(), 0u);
  EXPECT_EQ(runner.trajectory().size(), 3u);
}

TEST(DenseFrames, KeyframeRunsRefuseCheckpoints)
{
  planar_grid::PipelineRunner runner(denseFrames("frame_selection: keyframes"));
  EXPECT_THROW(runner.setCheckpoint("/tmp/planar_grid_keyframes.pgck", 2),
               planar_grid::ConfigError);
}

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
