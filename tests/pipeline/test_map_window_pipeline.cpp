// SPDX-License-Identifier: BSD-3-Clause
// The map_integration and accumulate stages' rolling window (window_radius_m) on the
// main job's frames driven several times, 100 m apart: the map's memory stays flat
// with it and grows with every pass without it, and the accumulated cloud keeps only
// what lies around the sensor.
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstddef>
#include <limits>
#include <string>
#include <vector>

#include "main_job_stages.h"

namespace {

constexpr int FRAMES_PER_PASS = 2; // few, so that the test stays short under ASan
constexpr int PASSES = 3;          // each 100 m further along x than the one before
constexpr double WINDOW_M = 30.0;  // beyond max_range_m (25 m): a view's reach

struct WindowRun {
  /** The map's bytes after the last frame of each pass. */
  std::vector<std::size_t> bytes_after_pass;
  /** The space layer's stored bounds after the run, meters (x, y), and the last
   * sensor position. */
  Eigen::Vector2f space_min{Eigen::Vector2f::Zero()},
    space_max{Eigen::Vector2f::Zero()};
  Eigen::Vector2f sensor{Eigen::Vector2f::Zero()};
  /** The accumulated world cloud's smallest x after the run, meters, and its points. */
  float cloud_min_x{0.0f};
  std::size_t cloud_points{0};
};

/** Runs the main job's stages over FRAMES_PER_PASS frames x PASSES passes, with
 * window_radius_m \a window_m (0: none). */
WindowRun
run(double window_m)
{
  std::string stages = planar_grid_test::mainJobStages();
  const std::string map_stage = "  - type: map_integration\n    params:\n";
  const std::size_t at = stages.find(map_stage);
  EXPECT_NE(at, std::string::npos) << "the main job has no map_integration params";
  if (window_m > 0.0 && at != std::string::npos)
    stages.insert(at + map_stage.size(),
                  "      window_radius_m: " + std::to_string(window_m) + "\n");
  const std::string accumulate_stage = "  - type: accumulate\n    params:\n";
  const std::size_t at_accumulate = stages.find(accumulate_stage);
  EXPECT_NE(at_accumulate, std::string::npos)
    << "the main job has no accumulate params";
  if (window_m > 0.0 && at_accumulate != std::string::npos)
    stages.insert(at_accumulate + accumulate_stage.size(),
                  "      window_radius_m: " + std::to_string(window_m) + "\n");
  const std::string yaml = planar_grid_test::mainJobImageInput(0, FRAMES_PER_PASS)
                           + "  repeat: {count: " + std::to_string(PASSES)
                           + ", offset_m: [100, 0, 0]}\n" + stages;
  planar_grid::PipelineRunner runner(
    planar_grid::parsePipelineConfig(yaml, "t.yaml", "/"));
  WindowRun result;
  runner.setFrameCallback(
    [&](std::size_t i, planar_grid::Frame& frame, const std::vector<double>&) {
      if ((i + 1) % FRAMES_PER_PASS == 0)
        result.bytes_after_pass.push_back(runner.state().map->getMemory().total_bytes);
      result.sensor = frame.world_T_camera.translation().head<2>().cast<float>();
    });
  const auto report = runner.run();
  EXPECT_EQ(report.frames, static_cast<std::size_t>(FRAMES_PER_PASS * PASSES));
  result.cloud_points = runner.state().world_cloud->size();
  result.cloud_min_x = std::numeric_limits<float>::infinity();
  for (const auto& p : runner.state().world_cloud->points)
    result.cloud_min_x = std::min(result.cloud_min_x, p.x);
  const planar_grid::ExplicitSpaceGrid& space = runner.state().map->getSpaceLayer();
  planar_grid::ExplicitSpaceGrid::VoxelKey lo, hi;
  if (space.getBounds(lo, hi)) {
    const auto r = static_cast<float>(space.getParams().resolution_m);
    result.space_min = lo.head<2>().cast<float>() * r;
    result.space_max = (hi.head<2>().cast<float>() + Eigen::Vector2f::Ones()) * r;
  }
  return result;
}

TEST(MapWindowPipelineTest, WindowKeepsTheMapMemoryFlatOverRepeatedPasses)
{
  const WindowRun windowed = run(WINDOW_M);
  const WindowRun unbounded = run(0.0);
  ASSERT_EQ(windowed.bytes_after_pass.size(), static_cast<std::size_t>(PASSES));
  ASSERT_EQ(unbounded.bytes_after_pass.size(), static_cast<std::size_t>(PASSES));
  const auto first = static_cast<double>(windowed.bytes_after_pass.front());
  ASSERT_GT(first, 0.0);
  for (int p = 1; p < PASSES; ++p) {
    const auto bytes = static_cast<double>(windowed.bytes_after_pass[p]);
    EXPECT_LE(bytes, 1.1 * first) << "pass " << p;
    EXPECT_GE(bytes, 0.9 * first) << "pass " << p;
  }
  // The first pass is the same map either way (the window reaches past the views).
  EXPECT_EQ(unbounded.bytes_after_pass.front(), windowed.bytes_after_pass.front());
  // Without the window every pass adds a map as large as the first.
  EXPECT_GT(static_cast<double>(unbounded.bytes_after_pass.back()),
            0.9 * PASSES * static_cast<double>(unbounded.bytes_after_pass.front()));
  // The space layer's blocks (8 voxels, 0.8 m) lie around the last pose.
  const float reach = static_cast<float>(WINDOW_M) + 0.8f;
  EXPECT_GE(windowed.space_min.x(), windowed.sensor.x() - reach);
  EXPECT_GE(windowed.space_min.y(), windowed.sensor.y() - reach);
  EXPECT_LE(windowed.space_max.x(), windowed.sensor.x() + reach);
  EXPECT_LE(windowed.space_max.y(), windowed.sensor.y() + reach);
  EXPECT_LT(unbounded.space_min.x(), windowed.sensor.x() - 100.0f);
  // The accumulated cloud, cropped at its downsampling (every 5 frames: the first
  // frame of the last pass) to the window around the sensor, plus the last frame's
  // points (within the stereo's 30 m range); unbounded it keeps the first pass's.
  ASSERT_GT(windowed.cloud_points, 0u);
  EXPECT_GE(windowed.cloud_min_x,
            windowed.sensor.x() - static_cast<float>(WINDOW_M) - 2.0f);
  EXPECT_LT(unbounded.cloud_min_x, windowed.sensor.x() - 150.0f);
  EXPECT_LT(windowed.cloud_points, unbounded.cloud_points);
}

} // namespace
