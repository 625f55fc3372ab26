// SPDX-License-Identifier: BSD-3-Clause
// The memory estimate of a run against geometry computed by hand, the refusal, the
// size parser and the machine's limit.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <gtest/gtest.h>
#include <sys/resource.h>

#include <cmath>
#include <fstream>
#include <string>

#include "../test_constants.h"

using planar_grid::ExplicitSpaceGrid;
using planar_grid::MemoryEstimate;
using planar_grid::PinholeView;

namespace {

using planar_grid_test::SOURCE_DIR;

/** A camera whose frustum is a square-based pyramid: 100 x 100 px, f = 50 px, the
 * principal point in the middle, so that x and y both span [-z, z] (90 degrees). */
PinholeView
squareCamera()
{
  PinholeView view;
  view.width_px = 100;
  view.height_px = 100;
  view.fx_px = view.fy_px = 50.0;
  view.cx_px = view.cy_px = 49.5;
  return view;
}

/** The main job's configuration with the map at \a resolution_m and \a range_m. */
planar_grid::PipelineConfig
mainJob(double resolution_m, double range_m, double window_m = 0.0)
{
  auto config = planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/karlsruhe.yaml");
  for (auto& stage : config.stages)
    if (stage.type == "map_integration") {
      stage.params.set("resolution_m", resolution_m);
      stage.params.set("max_range_m", range_m);
      stage.params.set("window_radius_m", window_m);
    }
  return config;
}

} // namespace

TEST(MemoryEstimate, FrustumVolumeIsThePyramidsWithoutMargin)
{
  // x and y each span [-z, z]: the pyramid of height R over a 2R x 2R square,
  // (2R)^2 R / 3 = 4 R^3 / 3; for R = 3 m, 36 m^3.
  EXPECT_NEAR(planar_grid::pinholeFrustumVolume(squareCamera(), 3.0, 0.0), 36.0, 1e-9);
  // The Karlsruhe camera (1344 x 372 px, f = 645.24 px) to 25 m: R^3 / 3 W H / f^2.
  PinholeView k;
  k.width_px = 1344;
  k.height_px = 372;
  k.fx_px = k.fy_px = 645.2401;
  k.cx_px = 635.9587;
  k.cy_px = 194.1291;
  EXPECT_NEAR(planar_grid::pinholeFrustumVolume(k, 25.0, 0.0),
              25.0 * 25.0 * 25.0 / 3.0 * 1344.0 * 372.0 / (645.2401 * 645.2401), 1e-6);
}

TEST(MemoryEstimate, FrustumMarginContainsTheDilatedPyramid)
{
  // With a margin d the bound must hold the pyramid grown by d in every direction:
  // at least the pyramid of range R + d plus its sides moved out, and it grows with d.
  const PinholeView view = squareCamera();
  const double d = 0.5, r = 3.0;
  const double grown = planar_grid::pinholeFrustumVolume(view, r, d);
  // Faces moved out by d sqrt(2) in x and y (the side planes' normals are at 45
  // degrees), z from -d to R + d: integral of (2 z + 2 sqrt(2) d)^2 over it.
  const double q = 2.0 * std::sqrt(2.0) * d;
  const auto f = [q](double z) {
    return 4.0 * z * z * z / 3.0 + 2.0 * q * z * z + q * q * z;
  };
  EXPECT_NEAR(grown, f(r + d) - f(-d), 1e-9);
  EXPECT_GT(grown, planar_grid::pinholeFrustumVolume(view, r + d, 0.0));
  EXPECT_LT(planar_grid::pinholeFrustumVolume(view, r, 0.25), grown);
}

TEST(MemoryEstimate, ViewBlocksAndBytesFollowTheFrustum)
{
  // 0.1 m voxels: blocks of 0.8 m; the view touches at most the frustum grown by a
  // block diagonal, over a block's volume.
  const auto config = mainJob(0.1, 3.0);
  const PinholeView camera = squareCamera();
  const planar_grid::Trajectory one(1, Eigen::Isometry3d::Identity());
  const MemoryEstimate e = planar_grid::estimateRunMemory(config, &camera, one, 1);
  ASSERT_TRUE(e.has_map);
  const double block = 0.8;
  const auto blocks = static_cast<std::uint64_t>(
    std::ceil(planar_grid::pinholeFrustumVolume(camera, 3.0, block * std::sqrt(3.0))
              / (block * block * block)));
  EXPECT_EQ(e.view_blocks, blocks);
  EXPECT_EQ(e.working_bytes, ExplicitSpaceGrid::workingBytesBound(blocks, 100 * 100));
  // One frame stores no more than one view touches.
  EXPECT_LE(e.map_blocks, blocks);
  EXPECT_EQ(e.total_bytes, e.map_bytes + e.working_bytes + MemoryEstimate::OTHER_BYTES);
  // Halving the cell multiplies the view's blocks by 8 less the margin's share, which
  // shrinks with the block: between 4 and 8 times at 30 m.
  const MemoryEstimate coarse =
    planar_grid::estimateRunMemory(mainJob(0.1, 30.0), &camera, one, 1);
  const MemoryEstimate fine =
    planar_grid::estimateRunMemory(mainJob(0.05, 30.0), &camera, one, 1);
  EXPECT_GT(fine.view_blocks, 4 * coarse.view_blocks);
  EXPECT_LE(fine.view_blocks, 8 * coarse.view_blocks);
}

TEST(MemoryEstimate, MapIsBoundedByFramesSweptPathAndWindow)
{
  const PinholeView camera = squareCamera();
  // 50 frames at one pose sweep one view's cells: no more than one frame's.
  const planar_grid::Trajectory still(50, Eigen::Isometry3d::Identity());
  const auto config = mainJob(0.1, 10.0);
  const MemoryEstimate one = planar_grid::estimateRunMemory(
    config, &camera, planar_grid::Trajectory(1, Eigen::Isometry3d::Identity()), 1);
  const MemoryEstimate same =
    planar_grid::estimateRunMemory(config, &camera, still, 50);
  EXPECT_EQ(same.map_blocks, one.map_blocks);
  EXPECT_NE(same.map_bound.find("swept path"), std::string::npos);
  // Without poses, 50 frames may each add a view.
  const MemoryEstimate unknown =
    planar_grid::estimateRunMemory(config, &camera, planar_grid::Trajectory(), 50);
  EXPECT_EQ(unknown.map_blocks, 50 * unknown.view_blocks);
  EXPECT_EQ(unknown.map_bound, "frames");
  // A drive of 1 km along x, looking along it: the window of 5 m keeps less.
  planar_grid::Trajectory drive;
  for (int i = 0; i < 200; ++i) {
    Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
    pose.linear() << 0, 0, 1, -1, 0, 0, 0, -1, 0; // camera z along world x
    pose.translation() = Eigen::Vector3d(5.0 * i, 0.0, 1.5);
    drive.push_back(pose);
  }
  const MemoryEstimate swept =
    planar_grid::estimateRunMemory(config, &camera, drive, 200);
  EXPECT_LT(swept.map_blocks, 200 * swept.view_blocks);
  const MemoryEstimate windowed =
    planar_grid::estimateRunMemory(mainJob(0.1, 10.0, 5.0), &camera, drive, 200);
  EXPECT_LT(windowed.map_blocks, swept.map_blocks);
  EXPECT_NE(windowed.map_bound.find("window"), std::string::npos);
}

TEST(MemoryEstimate, RefusalNamesTheKeyTheEstimateAndTheLimit)
{
  // The main job's file at 0.01 m: the error points at the top-level cell_size_m
  // every key of the cell follows, found here by reading the file (1-based line; the
  // value's column is 14).
  int resolution_line = 0;
  {
    std::ifstream file(SOURCE_DIR + "/config/karlsruhe.yaml");
    std::string line;
    for (int n = 1; std::getline(file, line) && resolution_line == 0; ++n)
      if (line.rfind("cell_size_m: ", 0) == 0)
        resolution_line = n;
  }
  ASSERT_GT(resolution_line, 0);
  const std::string position =
    "karlsruhe.yaml:" + std::to_string(resolution_line) + ":14";
  const auto config = mainJob(0.01, 25.0);
  PinholeView k;
  k.width_px = 1344;
  k.height_px = 372;
  k.fx_px = k.fy_px = 645.2401;
  k.cx_px = 635.9587;
  k.cy_px = 194.1291;
  const MemoryEstimate e =
    planar_grid::estimateRunMemory(config, &k, planar_grid::Trajectory(), 112);
  EXPECT_EQ(e.key, "cell_size_m");
  EXPECT_EQ(e.line, resolution_line);
  EXPECT_EQ(e.column, 14);
  // One view alone: the frustum (6253 m^3) in blocks of 0.08 m holds over 12 million.
  EXPECT_GT(e.view_blocks, 12000000u);
  planar_grid::MemoryLimit limit{std::uint64_t{4} << 30, "a test limit"};
  try {
    planar_grid::checkMemoryEstimate(e, limit);
    FAIL() << "not refused: " << e.summary();
  } catch (const planar_grid::ConfigError& error) {
    const std::string what = error.what();
    EXPECT_EQ(error.line(), resolution_line);
    EXPECT_NE(what.find(position), std::string::npos) << what;
    EXPECT_NE(what.find("4 GiB (a test limit)"), std::string::npos) << what;
    EXPECT_NE(what.find("--memory-limit"), std::string::npos) << what;
    EXPECT_NE(what.find(planar_grid::formatBytes(e.total_bytes)), std::string::npos);
  }
  // No limit refuses nothing; the main job at 0.1 m fits in 4 GiB.
  EXPECT_NO_THROW(planar_grid::checkMemoryEstimate(e, {0, "none"}));
  const MemoryEstimate main_job = planar_grid::estimateRunMemory(
    mainJob(0.1, 25.0), &k, planar_grid::Trajectory(), 112);
  EXPECT_NO_THROW(planar_grid::checkMemoryEstimate(main_job, limit))
    << main_job.summary();
}

TEST(MemoryEstimate, ParsesSizes)
{
  EXPECT_EQ(planar_grid::parseMemorySize("123"), 123u);
  EXPECT_EQ(planar_grid::parseMemorySize("512M"), std::uint64_t{512} << 20);
  EXPECT_EQ(planar_grid::parseMemorySize("1.5G"), std::uint64_t{3} << 29);
  EXPECT_EQ(planar_grid::parseMemorySize("2K"), 2048u);
  EXPECT_EQ(planar_grid::parseMemorySize("0"), 0u);
  EXPECT_EQ(planar_grid::parseMemorySize("none"), 0u);
  for (const char* bad : {"", "-1G", "12X", "G", "1G2", "lots"})
    EXPECT_THROW(planar_grid::parseMemorySize(bad), planar_grid::Exception) << bad;
}

TEST(MemoryEstimate, LimitIsTheSmallestOfMemoryAndProcessLimits)
{
  constexpr std::uint64_t GIB = std::uint64_t{1} << 30;
  const auto physical = planar_grid::smallestMemoryLimit(24 * GIB, 0, 0);
  EXPECT_EQ(physical.bytes, 24 * GIB);
  EXPECT_NE(physical.source.find("MemTotal"), std::string::npos) << physical.source;
  const auto address_space =
    planar_grid::smallestMemoryLimit(24 * GIB, 4 * GIB, 8 * GIB);
  EXPECT_EQ(address_space.bytes, 4 * GIB);
  EXPECT_NE(address_space.source.find("RLIMIT_AS"), std::string::npos);
  const auto data = planar_grid::smallestMemoryLimit(24 * GIB, 32 * GIB, 2 * GIB);
  EXPECT_EQ(data.bytes, 2 * GIB);
  EXPECT_NE(data.source.find("RLIMIT_DATA"), std::string::npos);
  EXPECT_EQ(planar_grid::smallestMemoryLimit(0, 0, 0).bytes, 0u);
  EXPECT_EQ(planar_grid::smallestMemoryLimit(0, 0, 3 * GIB).bytes, 3 * GIB);
}

TEST(MemoryEstimate, MachineLimitReadsThisProcess)
{
  // The process's own limits, read here independently: the machine's MemTotal and
  // the soft RLIMIT_AS / RLIMIT_DATA (the sanitizers need an unlimited address space,
  // so no limit is set in this test).
  std::ifstream meminfo("/proc/meminfo");
  std::string name;
  std::uint64_t kib = 0;
  std::uint64_t physical = 0;
  while (meminfo >> name >> kib && physical == 0) {
    if (name == "MemTotal:")
      physical = kib * 1024;
    meminfo.ignore(1 << 20, '\n');
  }
  ASSERT_GT(physical, 0u);
  const auto soft = [](int resource) -> std::uint64_t {
    rlimit rl{};
    EXPECT_EQ(::getrlimit(resource, &rl), 0);
    return rl.rlim_cur == RLIM_INFINITY ? 0 : static_cast<std::uint64_t>(rl.rlim_cur);
  };
  const auto expected =
    planar_grid::smallestMemoryLimit(physical, soft(RLIMIT_AS), soft(RLIMIT_DATA));
  const auto limit = planar_grid::machineMemoryLimit();
  EXPECT_EQ(limit.bytes, expected.bytes);
  EXPECT_EQ(limit.source, expected.source);
}
