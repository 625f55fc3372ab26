// SPDX-License-Identifier: BSD-3-Clause
// pipelineConfigToYaml: what it writes loads back as the configuration it was given,
// with the defaults left out, and what the loader would refuse is refused when written.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>

#include <gtest/gtest.h>

#include <string>

#include "../test_constants.h"

using planar_grid::PipelineConfig;
using planar_grid::pipelineConfigToYaml;

namespace {

using planar_grid_test::SOURCE_DIR;

/** Expects \a a and \a b to be the same configuration, field by field. */
void
expectSameConfig(const PipelineConfig& a, const PipelineConfig& b)
{
  const auto& ia = a.input;
  const auto& ib = b.input;
  EXPECT_EQ(ia.type, ib.type);
  EXPECT_EQ(ia.left_images, ib.left_images);
  EXPECT_EQ(ia.right_images, ib.right_images);
  EXPECT_EQ(ia.first_index, ib.first_index);
  EXPECT_EQ(ia.frame_count, ib.frame_count);
  EXPECT_EQ(ia.calibration_format, ib.calibration_format);
  EXPECT_EQ(ia.calibration_file, ib.calibration_file);
  EXPECT_EQ(ia.calibration_right_file, ib.calibration_right_file);
  EXPECT_EQ(ia.poses_format, ib.poses_format);
  EXPECT_EQ(ia.poses_file, ib.poses_file);
  EXPECT_EQ(ia.camera_height_m, ib.camera_height_m);
  EXPECT_EQ(ia.camera_pitch_rad, ib.camera_pitch_rad);
  EXPECT_EQ(ia.repeat_count, ib.repeat_count);
  EXPECT_EQ(ia.repeat_offset_m, ib.repeat_offset_m);

  ASSERT_EQ(a.stages.size(), b.stages.size());
  for (std::size_t i = 0; i < a.stages.size(); ++i) {
    EXPECT_EQ(a.stages[i].type, b.stages[i].type) << "stage " << i;
    ASSERT_EQ(a.stages[i].params.values().size(), b.stages[i].params.values().size());
    for (const auto& [key, value] : a.stages[i].params.values())
      EXPECT_EQ(value, b.stages[i].params.values().at(key))
        << a.stages[i].type << "." << key;
  }

  const auto& oa = a.output;
  const auto& ob = b.output;
  EXPECT_EQ(oa.folder, ob.folder);
  EXPECT_EQ(oa.cloud, ob.cloud);
  EXPECT_EQ(oa.planes, ob.planes);
  EXPECT_EQ(oa.planes_snapshot, ob.planes_snapshot);
  EXPECT_EQ(oa.cuboids_snapshot, ob.cuboids_snapshot);
  EXPECT_EQ(oa.cuboids_street_snapshot, ob.cuboids_street_snapshot);
  EXPECT_EQ(oa.map, ob.map);
  EXPECT_EQ(oa.map_octomap, ob.map_octomap);
  EXPECT_EQ(oa.map_mesh, ob.map_mesh);
  EXPECT_EQ(oa.map_grid_2d, ob.map_grid_2d);
  EXPECT_DOUBLE_EQ(oa.map_grid_2d_band.z_ref_m, ob.map_grid_2d_band.z_ref_m);
  EXPECT_DOUBLE_EQ(oa.map_grid_2d_band.z_min_m, ob.map_grid_2d_band.z_min_m);
  EXPECT_DOUBLE_EQ(oa.map_grid_2d_band.z_max_m, ob.map_grid_2d_band.z_max_m);
  EXPECT_EQ(oa.map_grid_2d_band.above_terrain, ob.map_grid_2d_band.above_terrain);
  EXPECT_DOUBLE_EQ(oa.map_grid_2d_band.terrain_tile_m,
                   ob.map_grid_2d_band.terrain_tile_m);
  EXPECT_DOUBLE_EQ(oa.map_grid_2d_band.resolution_m, ob.map_grid_2d_band.resolution_m);
  EXPECT_NEAR(oa.map_grid_2d_band.max_slope_rad, ob.map_grid_2d_band.max_slope_rad,
              1e-12);
  EXPECT_NEAR(oa.map_grid_2d_band.terrain_max_angle_rad,
              ob.map_grid_2d_band.terrain_max_angle_rad, 1e-12);
  EXPECT_EQ(oa.map_snapshot, ob.map_snapshot);
  EXPECT_EQ(oa.checkpoint, ob.checkpoint);
  EXPECT_EQ(oa.checkpoint_every_n_frames, ob.checkpoint_every_n_frames);
  EXPECT_EQ(oa.report, ob.report);
  EXPECT_EQ(oa.trajectory, ob.trajectory);
  EXPECT_EQ(oa.snapshot, ob.snapshot);
  EXPECT_EQ(oa.snapshot_camera, ob.snapshot_camera);
  EXPECT_EQ(oa.snapshot_size_px, ob.snapshot_size_px);
  EXPECT_EQ(oa.street_view.fixed, ob.street_view.fixed);
  EXPECT_EQ(oa.street_view.pose_fraction, ob.street_view.pose_fraction);
  EXPECT_EQ(oa.street_view.pitch_rad, ob.street_view.pitch_rad);
  EXPECT_EQ(oa.street_view.look_ahead_m, ob.street_view.look_ahead_m);
  EXPECT_EQ(oa.street_view.view_angle_deg, ob.street_view.view_angle_deg);
  EXPECT_EQ(oa.street_view.up, ob.street_view.up);
}

/** A stereo sequence through the main stages, every parameter at its default. */
PipelineConfig
smallConfig()
{
  PipelineConfig config;
  config.input.left_images = "/data/left/%06d.png";
  config.input.right_images = "/data/right/%06d.png";
  config.input.frame_count = 3;
  config.input.calibration_file = "/data/calib.txt";
  config.input.poses_format = planar_grid::PoseFormat::KITTI;
  config.input.poses_file = "/data/poses.txt";
  for (const char* type :
       {"stereo_disparity", "feature_matching", "voxel_grid", "transform_to_world",
        "multi_plane_segmentation", "planar_cuboid_approximation", "map_integration"})
    config.stages.push_back(planar_grid::defaultStageConfig(type));
  config.output.folder = "/tmp/out";
  return config;
}

} // namespace

TEST(PipelineConfigWriter, MainJobsLoadBackTheSame)
{
  // The project's stereo configurations, written and loaded again (their paths are
  // absolute once loaded, so the folder the text is loaded from does not matter).
  for (const char* name : {"karlsruhe.yaml", "karlsruhe_odometry.yaml",
                           "karlsruhe_long.yaml", "example.yaml"}) {
    SCOPED_TRACE(name);
    const auto config = planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/" + name);
    const std::string yaml = pipelineConfigToYaml(config);
    expectSameConfig(config, planar_grid::parsePipelineConfig(yaml, "w.yaml", "/x"));
  }
}

TEST(PipelineConfigWriter, WritesOnlyWhatDiffersFromTheDefaults)
{
  PipelineConfig config = smallConfig();
  config.input.repeat_count = 2;
  config.input.repeat_offset_m = {{0.5, 0.0, -0.25}};
  config.stages[0].params.set("num_disparities_px", 256);
  config.stages[5].params.set("min_cell_size_m", 0.2);
  config.output.snapshot_camera = "street";
  config.output.street_view.pitch_rad = 0.6;
  config.output.snapshot_size_px = {{800, 600}};
  config.output.cloud = "";
  const std::string yaml =
    pipelineConfigToYaml(config, "A test configuration\nof two lines.");
  EXPECT_EQ(yaml.rfind("# A test configuration\n# of two lines.\n", 0), 0u) << yaml;
  // Defaults are left out: voxel_grid has no params, the output no map key.
  EXPECT_NE(yaml.find("- type: voxel_grid\n  - type"), std::string::npos) << yaml;
  EXPECT_EQ(yaml.find("map:"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("num_disparities_px: 256"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("cloud: \"\""), std::string::npos) << yaml;

  const PipelineConfig loaded = planar_grid::parsePipelineConfig(yaml, "w.yaml", "/x");
  // The map's resolution_m was left at its default, so it follows the cells' 0.2 m
  // when loaded, as in a hand-written file.
  EXPECT_EQ(loaded.stages[6].params.getDouble("resolution_m"), 0.2);
  config.stages[6].params.set("resolution_m", 0.2);
  config.stages[6].params.set("thickness_m",
                              config.stages[5].params.getDouble("thickness_m"));
  expectSameConfig(config, loaded);
}

TEST(PipelineConfigWriter, RefusesWhatTheLoaderWouldRefuse)
{
  PipelineConfig config = smallConfig();
  config.stages[0].params.set("num_disparities", 64); // no unit: not a key
  try {
    pipelineConfigToYaml(config);
    ADD_FAILURE() << "an unknown parameter was written";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("'num_disparities'"), std::string::npos);
    EXPECT_NE(std::string(e.what()).find("num_disparities_px"), std::string::npos);
  }

  config = smallConfig();
  config.stages[0].params.set("num_disparities_px", 8); // below the range [16, 512]
  EXPECT_THROW(pipelineConfigToYaml(config), planar_grid::ConfigError);

  config = smallConfig();
  config.input.type = planar_grid::InputConfig::Type::PCD_FILES;
  EXPECT_THROW(pipelineConfigToYaml(config), planar_grid::Exception);

  EXPECT_THROW(planar_grid::defaultStageConfig("no_such_stage"),
               planar_grid::Exception);
}
