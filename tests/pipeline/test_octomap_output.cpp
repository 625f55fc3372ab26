// SPDX-License-Identifier: BSD-3-Clause
// The run's OctoMap output: the main job's stages on the first Karlsruhe frames write
// map.bt and report.json; liboctomap reads the .bt back and counts what the report
// says.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>

#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>

#include "main_job_stages.h"

namespace fs = std::filesystem;

namespace {

/** Frames 0-2: the first frame's cuboids and free space, and two updates of them. */
constexpr int FRAMES = 3;

class OctoMapOutputTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ = fs::temp_directory_path()
           / ("planar_grid_octomap_output_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

TEST_F(OctoMapOutputTest, MainJobBtCountsAgreeWithReport)
{
  const std::string yaml =
    planar_grid_test::mainJobImageInput(0, FRAMES) + planar_grid_test::mainJobStages()
    + "output:\n  folder: " + dir_.string()
    + "\n  report: report.json\n  map: map.pgmap\n  map_octomap: map.bt\n";
  const auto config = planar_grid::parsePipelineConfig(yaml, "t.yaml", "/");
  planar_grid::PipelineRunner runner(config);
  planar_grid::RunReport report = runner.run();
  planar_grid::writeRunOutputs(config.output, runner, report);
  planar_grid::writeRunReport(config.output, report);

  nlohmann::json json;
  std::ifstream(dir_ / "report.json") >> json;
  ASSERT_TRUE(json.contains("map_octomap")) << json.dump(2);
  const auto& written = json["map_octomap"];
  const auto count = [&written](const char* name) {
    EXPECT_TRUE(written.at(name).is_number_integer()) << name;
    return written.at(name).get<std::uint64_t>();
  };

  // liboctomap's own reading and counting of the file.
  octomap::OcTree tree(0.1);
  ASSERT_TRUE(tree.readBinary((dir_ / "map.bt").string()));
  std::uint64_t leaves = 0, occupied_leaves = 0, free_leaves = 0;
  std::uint64_t occupied_voxels = 0, free_voxels = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    ++leaves;
    // A leaf above the voxel depth stands for the 8^(16 - depth) voxels below it.
    const std::uint64_t voxels = std::uint64_t{1}
                                 << (3 * (tree.getTreeDepth() - it.getDepth()));
    if (tree.isNodeOccupied(*it)) {
      ++occupied_leaves;
      occupied_voxels += voxels;
    } else {
      ++free_leaves;
      free_voxels += voxels;
    }
  }
  EXPECT_EQ(tree.getNumLeafNodes(), count("leaf_nodes"));
  EXPECT_EQ(leaves, count("leaf_nodes"));
  EXPECT_EQ(tree.size(), count("nodes"));
  EXPECT_EQ(occupied_leaves, count("occupied_leaves"));
  EXPECT_EQ(free_leaves, count("free_leaves"));
  EXPECT_EQ(occupied_voxels, count("occupied_voxels"));
  EXPECT_EQ(free_voxels, count("free_voxels"));
  EXPECT_EQ(count("skipped_voxels"), 0u);

  // The map behind it: observed free space and occupied voxels, and cuboids.
  const planar_grid::PlanarGridMap& map = *runner.state().map;
  const auto& map_figures = json["map"];
  ASSERT_GT(map.getSurfaceLayer().getCuboids().size(), 0u);
  ASSERT_GT(map_figures.at("free_voxels").get<double>(), 0.0);
  ASSERT_GT(map_figures.at("occupied_voxels").get<double>(), 0.0);
  // The file holds every observed voxel of the space layer and the voxels of the
  // cuboids (some over unknown space), nothing else; with the prior `unknown` the
  // space layer has no voxel in state unknown to leave out.
  EXPECT_GE(static_cast<double>(free_voxels + occupied_voxels),
            map_figures.at("free_voxels").get<double>()
              + map_figures.at("occupied_voxels").get<double>());
  // The oracle, voxel by voxel: every voxel under a leaf has the map's state there
  // (a cuboid's probability against occupancy_thres, else the space layer's).
  std::uint64_t map_occupied = 0, map_free = 0, map_other = 0;
  const double res = tree.getResolution();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const int side = 1 << (tree.getTreeDepth() - it.getDepth());
    const double corner = -0.5 * it.getSize() + 0.5 * res;
    for (int z = 0; z < side; ++z)
      for (int y = 0; y < side; ++y)
        for (int x = 0; x < side; ++x) {
          const Eigen::Vector3f centre(
            static_cast<float>(it.getX() + corner + x * res),
            static_cast<float>(it.getY() + corner + y * res),
            static_cast<float>(it.getZ() + corner + z * res));
          switch (map.getState(centre)) {
            case planar_grid::SpaceState::OCCUPIED:
              ++map_occupied;
              break;
            case planar_grid::SpaceState::FREE:
              ++map_free;
              break;
            default:
              ++map_other;
          }
        }
  }
  EXPECT_EQ(map_occupied, occupied_voxels);
  EXPECT_EQ(map_free, free_voxels);
  EXPECT_EQ(map_other, 0u);
  // What the run printed and wrote agree.
  EXPECT_NE(report.timingTable().find("map_octomap: nodes "
                                      + std::to_string(tree.size()) + " leaf_nodes "
                                      + std::to_string(tree.getNumLeafNodes())),
            std::string::npos)
    << report.timingTable();
}

TEST_F(OctoMapOutputTest, CloudOutputsTakeTheFormatOfTheirExtension)
{
  // An extension the writers do not have is refused with the configuration.
  const std::string head =
    planar_grid_test::mainJobImageInput(0, 2) + planar_grid_test::mainJobStages()
    + "output:\n  folder: " + dir_.string() + "\n  report: report.json\n";
  for (const char* bad :
       {"  cloud: world.xyz\n", "  planes: planes.txt\n", "  map_octomap: map.abc\n",
        "  map: map.txt\n", "  map_snapshot: map.jpg\n"}) {
    try {
      planar_grid::parsePipelineConfig(head + bad, "t.yaml", "/");
      ADD_FAILURE() << bad << " was accepted";
    } catch (const planar_grid::ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("must end in"), std::string::npos)
        << e.what();
    }
  }
  // .ply is written as PLY (PCL reads it back point for point), .pcd as PCD.
  const auto config = planar_grid::parsePipelineConfig(
    head + "  cloud: world.pcd\n  planes: planes.ply\n", "t.yaml", "/");
  planar_grid::PipelineRunner runner(config);
  planar_grid::RunReport report = runner.run();
  planar_grid::writeRunOutputs(config.output, runner, report);
  const auto& planes = runner.state().planes->getInlierCloud();
  ASSERT_GT(planes.size(), 100u);
  pcl::PointCloud<pcl::PointXYZL> from_ply;
  ASSERT_EQ(pcl::io::loadPLYFile((dir_ / "planes.ply").string(), from_ply), 0);
  std::ifstream ply(dir_ / "planes.ply");
  std::string magic;
  std::getline(ply, magic);
  EXPECT_EQ(magic, "ply");
  ASSERT_EQ(from_ply.size(), planes.size());
  for (std::size_t i = 0; i < planes.size(); ++i) {
    ASSERT_EQ(from_ply[i].x, planes[i].x) << i;
    ASSERT_EQ(from_ply[i].z, planes[i].z) << i;
    ASSERT_EQ(from_ply[i].label, planes[i].label) << i;
  }
  pcl::PointCloud<pcl::PointXYZI> from_pcd;
  ASSERT_EQ(pcl::io::loadPCDFile((dir_ / "world.pcd").string(), from_pcd), 0);
  EXPECT_EQ(from_pcd.size(), runner.state().world_cloud->size());
}

} // namespace
