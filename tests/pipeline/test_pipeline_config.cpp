// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <gtest/gtest.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iomanip>
#include <sstream>
#include <string>
#include <utility>

#include "../test_constants.h"

using planar_grid::ConfigError;
using planar_grid::parsePipelineConfig;

namespace {

using planar_grid_test::SOURCE_DIR;

// A valid stereo input block; the tests append a pipeline to it.
const std::string INPUT = R"(input:
  type: stereo_sequence
  left_images: left/%06d.png
  right_images: right/%06d.png
  calibration:
    format: karlsruhe
    file: calib.txt
)";

/** Parses \a yaml and returns the ConfigError it raises (fails the test if none). */
ConfigError
errorOf(const std::string& yaml)
{
  try {
    parsePipelineConfig(yaml, "test.yaml", "/base");
  } catch (const ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "no ConfigError for:\n" << yaml;
  return ConfigError("", 0, 0, "");
}

} // namespace

TEST(PipelineConfig, ExampleAndMainJobLoad)
{
  // The documented schema and the main job must always load.
  for (const char* name : {"example.yaml", "karlsruhe.yaml", "karlsruhe_live.yaml",
                           "karlsruhe_odometry.yaml"}) {
    const auto config = planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/" + name);
    EXPECT_FALSE(config.stages.empty()) << name;
  }
  const auto k = planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/karlsruhe.yaml");
  EXPECT_EQ(k.input.calibration_format, planar_grid::CalibrationFormat::KARLSRUHE);
  EXPECT_EQ(k.input.poses_format, planar_grid::PoseFormat::KARLSRUHE_INSDATA);
  ASSERT_EQ(k.stages.size(), 12u);
  EXPECT_EQ(k.stages.front().type, "stereo_disparity");
  EXPECT_EQ(k.stages.front().params.getInt("num_disparities_px"), 128);
  EXPECT_EQ(k.stages.back().type, "accumulate");
}

TEST(PipelineConfig, TheLiveMainJobIsTheMainJobWithKeyframes)
{
  const auto main_job =
    planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/karlsruhe.yaml");
  auto live =
    planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/karlsruhe_live.yaml");
  ASSERT_EQ(live.stages.front().type, "stereo_disparity");
  EXPECT_EQ(live.stages.front().params.getChoice("frame_selection"), "keyframes");
  EXPECT_EQ(live.output.folder, "output/karlsruhe_live");
  // Back to every frame and the main job's folder, the two files describe one run.
  const planar_grid::ParamValues defaults =
    planar_grid::defaultStageConfig("stereo_disparity").params;
  for (const char* key : {"frame_selection", "keyframe_translation_m",
                          "keyframe_rotation_rad", "keyframe_max_gap_frames"})
    live.stages.front().params.set(key, defaults.values().at(key));
  live.output.folder = main_job.output.folder;
  live.source_file = main_job.source_file;
  EXPECT_EQ(planar_grid::pipelineConfigToYaml(live),
            planar_grid::pipelineConfigToYaml(main_job));
}

TEST(PipelineConfig, MapGrid2DOutputAndItsBand)
{
  const auto k = planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/karlsruhe.yaml");
  EXPECT_EQ(k.output.map_grid_2d, "map_2d.yaml");
  EXPECT_TRUE(k.output.map_grid_2d_band.above_terrain);
  EXPECT_DOUBLE_EQ(k.output.map_grid_2d_band.z_min_m, 0.3);
  const std::string stages = "pipeline:\n  - type: stereo_disparity\n";
  const auto c =
    parsePipelineConfig(INPUT + stages
                          + "output:\n  map_grid_2d: grid.yaml\n  map_grid_2d_band: "
                            "{z_min_m: 0.1, z_max_m: "
                            "1.2, max_slope_deg: 30, terrain_tile_m: 1.5}\n",
                        "t", "/");
  EXPECT_EQ(c.output.map_grid_2d, "grid.yaml");
  EXPECT_DOUBLE_EQ(c.output.map_grid_2d_band.z_max_m, 1.2);
  EXPECT_NEAR(c.output.map_grid_2d_band.max_slope_rad, 30.0 * M_PI / 180.0, 1e-12);
  EXPECT_DOUBLE_EQ(c.output.map_grid_2d_band.terrain_tile_m, 1.5);
  EXPECT_NE(
    std::string(errorOf(INPUT + stages + "output:\n  map_grid_2d: grid.pgm\n").what())
      .find(".yaml"),
    std::string::npos);
  EXPECT_NE(
    std::string(
      errorOf(INPUT + stages + "output:\n  map_grid_2d_band: {z_min_m: 0.1}\n").what())
      .find("map_grid_2d"),
    std::string::npos);
  EXPECT_NE(std::string(errorOf(INPUT + stages
                                + "output:\n  map_grid_2d: g.yaml\n  map_grid_2d_band: "
                                  "{z_min_m: 1.0, z_max_m: 0.5}\n")
                          .what())
              .find("z_max_m"),
            std::string::npos);
  EXPECT_NE(std::string(errorOf(INPUT + stages
                                + "output:\n  map_grid_2d: g.yaml\n  map_grid_2d_band: "
                                  "{bogus: 1}\n")
                          .what())
              .find("bogus"),
            std::string::npos);
}

// The band's keys and computeOccupancyGrid2D() take the same ranges
// (occupancy_grid_2d_ranges): a value just outside is refused by both, the edges are
// accepted by both.
TEST(PipelineConfig, MapGrid2DBandRangesAreTheMapsOwn)
{
  namespace ranges = planar_grid::occupancy_grid_2d_ranges;
  const std::string head =
    INPUT + "pipeline:\n  - type: stereo_disparity\noutput:\n  map_grid_2d: g.yaml\n"
    + "  map_grid_2d_band: {";
  const planar_grid::PlanarGridMap map{planar_grid::PlanarGridMap::Params()};
  const auto map_accepts = [&map](planar_grid::OccupancyGrid2DParams p) {
    // An empty map needs the grid's extent.
    p.use_bounds = true;
    p.min_xy.setZero();
    p.max_xy.setOnes();
    try {
      map.computeOccupancyGrid2D(p);
      return true;
    } catch (const planar_grid::Exception&) {
      return false;
    }
  };
  const auto config_accepts = [&head](const std::string& key, double value) {
    std::ostringstream yaml;
    yaml << std::setprecision(17) << head << key << ": " << value << "}\n";
    try {
      parsePipelineConfig(yaml.str(), "t", "/");
      return true;
    } catch (const planar_grid::ConfigError&) {
      return false;
    }
  };
  // A tile of 0 m, the edge and above.
  planar_grid::OccupancyGrid2DParams p;
  for (const double tile :
       {0.0, ranges::TERRAIN_TILE.max, ranges::TERRAIN_TILE.max + 1.0}) {
    p.terrain_tile_m = tile;
    EXPECT_EQ(config_accepts("terrain_tile_m", tile), map_accepts(p)) << tile;
    EXPECT_EQ(map_accepts(p), ranges::TERRAIN_TILE.contains(tile)) << tile;
  }
  p = planar_grid::OccupancyGrid2DParams();
  // Degrees in the configuration, radians in the map: 90 degrees is the edge.
  for (const double degrees : {0.0, 90.0, 90.001, -0.001}) {
    p.max_slope_rad = degrees * M_PI / 180.0;
    EXPECT_EQ(config_accepts("max_slope_deg", degrees), map_accepts(p)) << degrees;
  }
  EXPECT_TRUE(config_accepts("max_slope_deg", 90.0));
  p = planar_grid::OccupancyGrid2DParams();
  for (const double z : {ranges::Z_REF.min - 1.0, ranges::Z_REF.max}) {
    p.z_ref_m = z;
    EXPECT_EQ(config_accepts("z_ref_m", z), map_accepts(p)) << z;
  }
  p = planar_grid::OccupancyGrid2DParams();
  for (const double r :
       {0.0, 0.0005, ranges::RESOLUTION.min, ranges::RESOLUTION.max + 1.0}) {
    p.resolution_m = r;
    EXPECT_EQ(config_accepts("resolution_m", r), map_accepts(p)) << r;
  }
}

TEST(PipelineConfig, RelativePathsResolveAgainstTheFileFolder)
{
  const auto c = parsePipelineConfig(INPUT + "pipeline:\n  - type: stereo_disparity\n",
                                     "test.yaml", "/base/config");
  EXPECT_EQ(c.input.left_images, "/base/config/left/%06d.png");
  EXPECT_EQ(c.input.calibration_file, "/base/config/calib.txt");
}

TEST(PipelineConfig, DefaultsFillMissingParams)
{
  const auto c = parsePipelineConfig(
    INPUT
      + "pipeline:\n  - type: stereo_disparity\n  - type: voxel_grid\n    params: "
        "{leaf_size_m: 0.2}\n",
    "t", "/");
  ASSERT_EQ(c.stages.size(), 2u);
  EXPECT_DOUBLE_EQ(c.stages[1].params.getDouble("leaf_size_m"), 0.2);
  EXPECT_EQ(c.stages[1].params.getInt("min_points_per_voxel"), 1); // the table default
}

// --set: the named stage's parameter takes the value, others keep the file's; the
// value is checked against the stage's table; the stage must be listed exactly once.
TEST(PipelineConfig, OverridesReplaceOneStageParameterAndAreChecked)
{
  const std::string yaml =
    INPUT
    + "pipeline:\n  - type: stereo_disparity\n  - type: voxel_grid\n"
      "    params: {leaf_size_m: 0.2, min_points_per_voxel: 2}\n";
  const auto c = parsePipelineConfig(
    yaml, "t", "/",
    {"voxel_grid.leaf_size_m=0.05", "stereo_disparity.row_downscale=2"});
  EXPECT_DOUBLE_EQ(c.stages[1].params.getDouble("leaf_size_m"), 0.05);
  EXPECT_EQ(c.stages[1].params.getInt("min_points_per_voxel"), 2);
  EXPECT_EQ(c.stages[0].params.getInt("row_downscale"), 2);
  // A stage without a params map gets one.
  const auto d = parsePipelineConfig(INPUT + "pipeline:\n  - type: stereo_disparity\n",
                                     "t", "/", {"stereo_disparity.block_size_px=3"});
  EXPECT_EQ(d.stages[0].params.getInt("block_size_px"), 3);

  const auto message = [&](const std::string& assignment) {
    try {
      parsePipelineConfig(yaml, "t", "/", {assignment});
    } catch (const ConfigError& e) {
      EXPECT_EQ(e.file(), "--set " + assignment);
      return std::string(e.what());
    }
    ADD_FAILURE() << "no ConfigError for --set " << assignment;
    return std::string();
  };
  EXPECT_NE(message("voxel_grid.leaf_size_m=-1").find("out of range"),
            std::string::npos);
  EXPECT_NE(message("voxel_grid.leaf=0.1").find("unknown parameter 'leaf'"),
            std::string::npos);
  EXPECT_NE(message("voxel_grid.leaf_size_m=abc").find("must be"), std::string::npos);
  EXPECT_NE(message("ground_removal.eps_angle_rad=0.1").find("has no stage"),
            std::string::npos);
  EXPECT_NE(message("no_such_stage.x=1").find("unknown stage type"), std::string::npos);
  EXPECT_NE(message("voxel_grid").find("STAGE.KEY=VALUE"), std::string::npos);
  EXPECT_NE(message("voxel_grid.=1").find("STAGE.KEY=VALUE"), std::string::npos);
  EXPECT_NE(parsePipelineConfig(INPUT
                                  + "pipeline:\n  - type: stereo_disparity\n"
                                    "  - type: voxel_grid\n  - type: voxel_grid\n",
                                "t", "/", {})
              .stages.size(),
            0u);
  try {
    parsePipelineConfig(INPUT
                          + "pipeline:\n  - type: stereo_disparity\n"
                            "  - type: voxel_grid\n  - type: voxel_grid\n",
                        "t", "/", {"voxel_grid.leaf_size_m=0.1"});
    ADD_FAILURE() << "a stage listed twice took --set";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("2 times"), std::string::npos) << e.what();
  }
}

TEST(PipelineConfig, UnknownTopLevelKeyHasLineAndColumn)
{
  const auto e = errorOf(INPUT + "pipeline:\n  - type: voxel_grid\nbogus: 1\n");
  // INPUT has 7 lines, pipeline 2 more: "bogus" is on line 10, column 1.
  EXPECT_EQ(e.line(), 10);
  EXPECT_EQ(e.column(), 1);
  EXPECT_NE(std::string(e.what()).find("test.yaml:10:1"), std::string::npos)
    << e.what();
  EXPECT_NE(std::string(e.what()).find("bogus"), std::string::npos);
}

TEST(PipelineConfig, UnknownStageTypeListsKnownTypes)
{
  const auto e = errorOf(INPUT + "pipeline:\n  - type: voxel_gird\n");
  EXPECT_EQ(e.line(), 9);
  EXPECT_EQ(e.column(), 11);
  const std::string what = e.what();
  EXPECT_NE(what.find("voxel_gird"), std::string::npos);
  for (const auto& info : planar_grid::stageRegistry())
    EXPECT_NE(what.find(info.type), std::string::npos) << "missing " << info.type;
}

TEST(PipelineConfig, UnknownParamKeyIsAnError)
{
  const auto e = errorOf(
    INPUT + "pipeline:\n  - type: voxel_grid\n    params:\n      leaf_size: 0.1\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_EQ(e.column(), 7);
  EXPECT_NE(std::string(e.what()).find("leaf_size_m"), std::string::npos)
    << "the message should list the known key: " << e.what();
}

TEST(PipelineConfig, WrongTypeIsAnError)
{
  const auto e = errorOf(INPUT
                         + "pipeline:\n  - type: stereo_disparity\n    params:\n      "
                           "block_size_px: five\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_EQ(e.column(), 22);
  EXPECT_NE(std::string(e.what()).find("integer"), std::string::npos) << e.what();
  // A fraction is not an integer either.
  const auto f = errorOf(
    INPUT
    + "pipeline:\n  - type: stereo_disparity\n    params:\n      block_size_px: 5.5\n");
  EXPECT_EQ(f.line(), 11);
}

TEST(PipelineConfig, OutOfRangeAndNegativeSizesAreErrors)
{
  const auto e = errorOf(
    INPUT + "pipeline:\n  - type: voxel_grid\n    params:\n      leaf_size_m: -0.1\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_NE(std::string(e.what()).find("out of range"), std::string::npos) << e.what();
  const auto r = errorOf(
    INPUT + "pipeline:\n  - type: feature_matching\n    params:\n      ratio: 1.5\n");
  EXPECT_EQ(r.line(), 11);
  const auto c = errorOf(
    INPUT
    + "pipeline:\n  - type: feature_matching\n    params:\n      feature_type: surf\n");
  EXPECT_NE(std::string(c.what()).find("sift"), std::string::npos) << c.what();
}

TEST(PipelineConfig, StagesNeedingPosesNeedPoses)
{
  const auto e = errorOf(INPUT + "pipeline:\n  - type: transform_to_world\n");
  EXPECT_EQ(e.line(), 9);
  EXPECT_NE(std::string(e.what()).find("poses"), std::string::npos);
  // With poses it loads.
  const std::string with_poses =
    INPUT
    + "  poses: {format: kitti, file: poses.txt}\npipeline:\n"
      "  - type: stereo_disparity\n  - type: transform_to_world\n";
  EXPECT_NO_THROW(parsePipelineConfig(with_poses, "t", "/"));
}

TEST(PipelineConfig, OdometryPosesNeedTheVisualOdometryStageFirst)
{
  const std::string input = INPUT + "  poses: {format: odometry}\n";
  // transform_to_world without visual_odometry before it: no poses to use.
  auto e = errorOf(
    input + "pipeline:\n  - type: stereo_disparity\n  - type: transform_to_world\n");
  EXPECT_NE(std::string(e.what()).find("visual_odometry"), std::string::npos);
  // In the right order it loads.
  EXPECT_NO_THROW(parsePipelineConfig(
    input
      + "pipeline:\n  - type: stereo_disparity\n  - type: feature_matching\n"
        "  - type: visual_odometry\n  - type: transform_to_world\n",
    "t", "/"));
  // visual_odometry with poses from a file would fight over the poses.
  e = errorOf(INPUT
              + "  poses: {format: kitti, file: p.txt}\npipeline:\n"
                "  - type: visual_odometry\n");
  EXPECT_NE(std::string(e.what()).find("odometry"), std::string::npos);
}

TEST(PipelineConfig, FormatsAreReadByTheirEnumsParsers)
{
  using planar_grid::CalibrationFormat;
  using planar_grid::PoseFormat;
  // Each name reads back as its enum, and each enum writes the name the file uses.
  for (const PoseFormat format :
       {PoseFormat::NONE, PoseFormat::ODOMETRY, PoseFormat::KARLSRUHE_INSDATA,
        PoseFormat::KITTI, PoseFormat::EUROC_GROUNDTRUTH, PoseFormat::VIEWPOINT,
        PoseFormat::REGISTRATION, PoseFormat::TF})
    EXPECT_EQ(planar_grid::poseFormatFromString(planar_grid::poseFormatName(format)),
              format);
  EXPECT_EQ(planar_grid::poseFormatName(PoseFormat::EUROC_GROUNDTRUTH),
            "euroc_groundtruth");
  EXPECT_THROW(planar_grid::poseFormatFromString("KITTI"), planar_grid::Exception);
  for (const CalibrationFormat format :
       {CalibrationFormat::KARLSRUHE, CalibrationFormat::KITTI,
        CalibrationFormat::ROS_CAMERA_INFO, CalibrationFormat::EUROC})
    EXPECT_EQ(planar_grid::calibrationFormatFromString(
                planar_grid::calibrationFormatName(format)),
              format);
  EXPECT_EQ(planar_grid::knownCalibrationFormats(),
            "karlsruhe, kitti, ros_camera_info, euroc");

  // The loader stores the enums, and its messages keep the value's line:col and the
  // names this input accepts.
  const std::string kitti_yaml = INPUT + "  poses: {format: kitti, file: p.txt}\n"
                                 + "pipeline:\n  - type: stereo_disparity\n";
  const auto kitti = parsePipelineConfig(kitti_yaml, "t", "/");
  EXPECT_EQ(kitti.input.calibration_format, CalibrationFormat::KARLSRUHE);
  EXPECT_EQ(kitti.input.poses_format, PoseFormat::KITTI);
  const auto calib = errorOf("input:\n  type: stereo_sequence\n  left_images: a%d.png\n"
                             "  right_images: b%d.png\n"
                             "  calibration:\n    format: middlebury\n    file: c\n"
                             "pipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(calib.line(), 6);
  EXPECT_EQ(calib.column(), 13);
  EXPECT_NE(std::string(calib.what())
              .find("input.calibration.format 'middlebury' is unknown; expected one "
                    "of: karlsruhe, kitti, ros_camera_info, euroc"),
            std::string::npos)
    << calib.what();
  // A pose format of another kind of input is refused as unknown for this one.
  const auto pose = errorOf(
    INPUT + "  poses:\n    format: viewpoint\npipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(pose.line(), 9);
  EXPECT_EQ(pose.column(), 13);
  EXPECT_NE(std::string(pose.what())
              .find("input.poses.format 'viewpoint' is unknown for this input; "
                    "expected one of: odometry, karlsruhe_insdata, kitti, "
                    "euroc_groundtruth, none"),
            std::string::npos)
    << pose.what();
}

TEST(PipelineConfig, BadInputBlocksAreErrors)
{
  // Missing calibration.
  auto e = errorOf("input:\n  type: stereo_sequence\n  left_images: a%d.png\n"
                   "  right_images: b%d.png\npipeline:\n  - type: voxel_grid\n");
  EXPECT_NE(std::string(e.what()).find("calibration"), std::string::npos);
  // Unknown calibration format, at its value.
  e = errorOf("input:\n  type: stereo_sequence\n  left_images: a%d.png\n"
              "  right_images: b%d.png\n  calibration: {format: middlebury, file: c}\n"
              "pipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 5);
  EXPECT_NE(std::string(e.what()).find("karlsruhe"), std::string::npos);
  // A pattern without an index field.
  e = errorOf("input:\n  type: stereo_sequence\n  left_images: left.png\n"
              "  right_images: b%d.png\n  calibration: {format: kitti, file: c}\n"
              "pipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 3);
  // Negative frame count.
  e = errorOf(INPUT + "  frame_count: -3\npipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 8);
  // Unknown input type.
  e = errorOf("input:\n  type: rosbag\npipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 2);
  // Stereo stages on PCD input.
  e = errorOf("input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n"
              "  - type: stereo_disparity\n");
  EXPECT_EQ(e.line(), 5);
}

TEST(PipelineConfig, EurocGroundTruthPoses)
{
  const std::string input = "input:\n  type: stereo_sequence\n  left_images: l%d.png\n"
                            "  right_images: r%d.png\n  calibration:\n"
                            "    format: euroc\n    file: l.yaml\n"
                            "    right_file: r.yaml\n";
  // Stereo input: accepted with a file, resolved against the config's folder.
  const auto config = parsePipelineConfig(
    input
      + "  poses: {format: euroc_groundtruth, file: gt_body_poses.txt}\n"
        "pipeline:\n  - type: stereo_disparity\n",
    "test.yaml", "/base");
  EXPECT_EQ(config.input.poses_format, planar_grid::PoseFormat::EUROC_GROUNDTRUTH);
  EXPECT_EQ(config.input.poses_file, "/base/gt_body_poses.txt");
  // It needs the file.
  auto e = errorOf(input
                   + "  poses: {format: euroc_groundtruth}\n"
                     "pipeline:\n  - type: stereo_disparity\n");
  EXPECT_EQ(e.line(), 9);
  EXPECT_NE(std::string(e.what()).find("file"), std::string::npos) << e.what();
  // Karlsruhe's mounting keys are not for it.
  e = errorOf(input
              + "  poses: {format: euroc_groundtruth, file: gt.txt, camera_height_m: "
                "1}\npipeline:\n  - type: stereo_disparity\n");
  EXPECT_EQ(e.line(), 9);
  // The camera's pose needs the EuRoC extrinsics, which only the euroc calibration has.
  e = errorOf(INPUT
              + "  poses: {format: euroc_groundtruth, file: gt.txt}\n"
                "pipeline:\n  - type: stereo_disparity\n");
  EXPECT_EQ(e.line(), 8);
  EXPECT_NE(std::string(e.what()).find("calibration.format euroc"), std::string::npos)
    << e.what();
  // PCD input has no stereo calibration to take the camera's T_BS from.
  e = errorOf("input:\n  type: pcd_files\n  files: [a.pcd]\n"
              "  poses: {format: euroc_groundtruth, file: gt.txt}\n"
              "pipeline:\n  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 4);

  // The EuRoC evaluation config uses it.
  const auto euroc =
    planar_grid::loadPipelineConfig(SOURCE_DIR + "/config/eval/euroc.yaml");
  EXPECT_EQ(euroc.input.calibration_format, planar_grid::CalibrationFormat::EUROC);
  EXPECT_EQ(euroc.input.poses_format, planar_grid::PoseFormat::EUROC_GROUNDTRUTH);
  EXPECT_EQ(euroc.input.first_index, 2);
  EXPECT_EQ(euroc.input.frame_count, 2);
}

TEST(PipelineConfig, EmptyOrMalformedYaml)
{
  auto e = errorOf("");
  EXPECT_NE(std::string(e.what()).find("empty"), std::string::npos);
  e = errorOf("input: [unclosed\n");
  EXPECT_GT(e.line(), 0) << "a YAML syntax error carries its place: " << e.what();
  e = errorOf(INPUT + "pipeline: []\n");
  EXPECT_NE(std::string(e.what()).find("non-empty"), std::string::npos);
  EXPECT_THROW(planar_grid::loadPipelineConfig("/nonexistent/config.yaml"),
               planar_grid::IOError);
}

TEST(PipelineConfig, OutputBlock)
{
  const auto c = parsePipelineConfig(
    INPUT
      + "pipeline:\n  - type: stereo_disparity\noutput:\n  folder: out\n"
        "  snapshot_size_px: [800, 600]\n  snapshot_camera: oblique\n",
    "t", "/");
  EXPECT_EQ(c.output.folder, "out");
  EXPECT_EQ(c.output.snapshot_size_px[0], 800);
  EXPECT_EQ(c.output.snapshot_camera, "oblique");
  const auto e = errorOf(
    INPUT
    + "pipeline:\n  - type: stereo_disparity\noutput:\n  snapshot_size_px: [0, 600]\n");
  EXPECT_EQ(e.line(), 11);
}

TEST(PipelineConfig, StreetView)
{
  // INPUT with poses (line 8): the street camera follows them. Lines 9-11 are
  // pipeline:, the stage and output:; the street keys start at line 12.
  const std::string head = INPUT
                           + "  poses: {format: karlsruhe_insdata, file: ins.txt}\n"
                             "pipeline:\n  - type: stereo_disparity\noutput:\n";
  // Defaults: no street snapshot, the camera a third of the way along, 0.5 rad down.
  auto c = parsePipelineConfig(head + "  folder: out\n", "t", "/");
  EXPECT_TRUE(c.output.cuboids_street_snapshot.empty());
  EXPECT_DOUBLE_EQ(c.output.street_view.pose_fraction, 1.0 / 3.0);
  EXPECT_DOUBLE_EQ(c.output.street_view.pitch_rad, 0.5);
  EXPECT_DOUBLE_EQ(c.output.street_view.look_ahead_m, 40.0);
  EXPECT_DOUBLE_EQ(c.output.street_view.view_angle_deg, 45.0);
  EXPECT_EQ(c.output.street_view.up, (std::array<double, 3>{{0.0, 0.0, 1.0}}));
  EXPECT_FALSE(c.output.street_view.fixed);

  // Following the trajectory, every key given.
  c = parsePipelineConfig(head
                            + "  cuboids_street_snapshot: street.png\n"
                              "  street_view:\n"
                              "    pose_fraction: 0\n"
                              "    pitch_rad: 0.5\n"
                              "    look_ahead_m: 60\n"
                              "    view_angle_deg: 40\n"
                              "    up: [0, -1, 0]\n",
                          "t", "/");
  EXPECT_EQ(c.output.cuboids_street_snapshot, "street.png");
  EXPECT_DOUBLE_EQ(c.output.street_view.pose_fraction, 0.0);
  EXPECT_DOUBLE_EQ(c.output.street_view.pitch_rad, 0.5);
  EXPECT_DOUBLE_EQ(c.output.street_view.look_ahead_m, 60.0);
  EXPECT_DOUBLE_EQ(c.output.street_view.view_angle_deg, 40.0);
  EXPECT_EQ(c.output.street_view.up, (std::array<double, 3>{{0.0, -1.0, 0.0}}));

  // A fixed camera, and every snapshot along the street.
  c = parsePipelineConfig(head
                            + "  snapshot_camera: street\n"
                              "  street_view:\n"
                              "    position_m: [-10, 0, 12]\n"
                              "    focal_point_m: [20, 0, 1.5]\n"
                              "    up: [0, 0, 1]\n",
                          "t", "/");
  EXPECT_EQ(c.output.snapshot_camera, "street");
  EXPECT_TRUE(c.output.street_view.fixed);
  EXPECT_EQ(c.output.street_view.position_m,
            (std::array<double, 3>{{-10.0, 0.0, 12.0}}));
  EXPECT_EQ(c.output.street_view.focal_point_m,
            (std::array<double, 3>{{20.0, 0.0, 1.5}}));
  // A fixed camera needs no poses.
  c = parsePipelineConfig(INPUT
                            + "pipeline:\n  - type: stereo_disparity\noutput:\n"
                              "  cuboids_street_snapshot: street.png\n"
                              "  street_view: {position_m: [0, 0, 5], "
                              "focal_point_m: [0, 10, 0]}\n",
                          "t", "/");
  EXPECT_TRUE(c.output.street_view.fixed);
}

TEST(PipelineConfig, StreetViewErrorsNameLineAndColumn)
{
  const std::string head = INPUT
                           + "  poses: {format: karlsruhe_insdata, file: ins.txt}\n"
                             "pipeline:\n  - type: stereo_disparity\noutput:\n"
                             "  cuboids_street_snapshot: street.png\n"
                             "  street_view:\n";
  // Each case: the body of street_view (from line 14), the line:col and the words the
  // message must hold.
  const auto expect = [&](const std::string& body, int line, int column,
                          const std::string& words) {
    const ConfigError e = errorOf(head + body);
    EXPECT_EQ(e.file(), "test.yaml");
    EXPECT_EQ(e.line(), line) << e.what();
    EXPECT_EQ(e.column(), column) << e.what();
    EXPECT_NE(std::string(e.what()).find(words), std::string::npos) << e.what();
  };
  expect("    pose_fraction: 1.5\n", 14, 20,
         "pose_fraction = 1.5 is out of range [0, 1]");
  expect("    pose_fraction: third\n", 14, 20, "pose_fraction must be a number");
  expect("    look_ahead_m: 0\n", 14, 19, "look_ahead_m = 0 is out of range");
  expect("    view_angle_deg: 170\n", 14, 21, "view_angle_deg = 170 is out of range");
  // Below half the 45 degree view angle (0.39 rad) the top of the image looks up;
  // above pi/2 minus that (1.18 rad) the bottom looks backwards.
  expect("    pitch_rad: 0.2\n", 14, 16, "more than half the view angle");
  expect("    pitch_rad: 1.4\n", 14, 16, "less than pi/2 minus half");
  // A wider view needs a steeper pitch: 0.45 rad is less than half of 60 degrees.
  expect("    view_angle_deg: 60\n    pitch_rad: 0.45\n", 15, 16, "pitch_rad");
  expect("    up: [0, 0, 0]\n", 14, 9, "up must not be zero");
  expect("    up: [0, 1]\n", 14, 9, "up must be a list [x, y, z]");
  expect("    up: [0, x, 1]\n", 14, 13, "up entries must be a number");
  expect("    pitch: 0.5\n", 14, 5, "pitch");
  expect("    position_m: [0, 0, 10]\n", 14, 17,
         "needs both position_m and focal_point_m");
  expect("    position_m: [0, 0, 10]\n    focal_point_m: [0, 0, 10]\n", 15, 20,
         "must differ from position_m");
  expect("    position_m: [0, 0, 10]\n    focal_point_m: [0, 0, 0]\n", 15, 20,
         "not be parallel to the viewing direction");
  expect("    position_m: [0, 0, 10]\n    focal_point_m: [10, 0, 0]\n"
         "    pitch_rad: 0.5\n",
         16, 16, "not used by a fixed camera");
  expect("    position_m: [0, 0, 1e9]\n    focal_point_m: [10, 0, 0]\n", 14, 24,
         "out of range");
  expect("    pose_fraction: [0.5]\n", 14, 20, "must be a number");

  // snapshot_camera names a known camera.
  auto e = errorOf(INPUT
                   + "pipeline:\n  - type: stereo_disparity\noutput:\n"
                     "  snapshot_camera: side\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_EQ(e.column(), 20);
  EXPECT_NE(std::string(e.what()).find("top, oblique or street"), std::string::npos);
  // Following the trajectory needs poses.
  e = errorOf(INPUT
              + "pipeline:\n  - type: stereo_disparity\noutput:\n"
                "  cuboids_street_snapshot: street.png\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_EQ(e.column(), 28);
  EXPECT_NE(std::string(e.what()).find("input.poses is none"), std::string::npos);
  e = errorOf(INPUT
              + "pipeline:\n  - type: stereo_disparity\noutput:\n"
                "  snapshot_camera: street\n");
  EXPECT_EQ(e.line(), 11);
  // A street_view no snapshot uses is an error, not silently ignored.
  e = errorOf(INPUT
              + "  poses: {format: karlsruhe_insdata, file: ins.txt}\n"
                "pipeline:\n  - type: stereo_disparity\noutput:\n"
                "  street_view: {pitch_rad: 0.5}\n");
  EXPECT_EQ(e.line(), 12);
  EXPECT_EQ(e.column(), 16);
  EXPECT_NE(std::string(e.what()).find("street_view is not used"), std::string::npos);
}

TEST(ParamTable, EveryDefaultIsInsideItsRange)
{
  // The tables drive both the parser and --list-stages; a default outside its own range
  // would make the documented default unusable.
  for (const auto& info : planar_grid::stageRegistry()) {
    for (const auto& spec : info.params) {
      if (spec.type == planar_grid::ParamSpec::Type::DOUBLE
          || spec.type == planar_grid::ParamSpec::Type::INT) {
        const double d = std::stod(spec.default_value);
        EXPECT_TRUE(spec.range.contains(d)) << info.type << "." << spec.key;
      }
      if (spec.type == planar_grid::ParamSpec::Type::CHOICE) {
        EXPECT_NE(
          std::find(spec.choices.begin(), spec.choices.end(), spec.default_value),
          spec.choices.end());
      }
      // Dimensional keys carry their unit, so that a file says what its numbers mean.
      if (spec.unit == "m") {
        EXPECT_EQ(spec.key.substr(spec.key.size() - 2), "_m") << spec.key;
      }
      if (spec.unit == "px") {
        EXPECT_EQ(spec.key.substr(spec.key.size() - 3), "_px") << spec.key;
      }
    }
    // Every stage builds from its defaults.
    EXPECT_NO_THROW(info.create(planar_grid::defaultParams(info.params))) << info.type;
  }
}

TEST(ParamTable, DumpAndReloadGivesTheSameValues)
{
  // YAML load, dump, load again gives the same.
  const auto* info = planar_grid::findStage("stereo_disparity");
  ASSERT_NE(info, nullptr);
  const YAML::Node node =
    YAML::Load("{num_disparities_px: 64, max_range_m: 12.5, full_dp: true}");
  const auto a = planar_grid::parseParams(node, info->params, "t", info->type);
  YAML::Node dumped;
  for (const auto& spec : info->params)
    dumped[spec.key] = a.toString(spec.key);
  const auto b = planar_grid::parseParams(YAML::Load(YAML::Dump(dumped)), info->params,
                                          "t", info->type);
  for (const auto& spec : info->params)
    EXPECT_EQ(a.toString(spec.key), b.toString(spec.key)) << spec.key;
  EXPECT_EQ(b.getInt("num_disparities_px"), 64);
  EXPECT_DOUBLE_EQ(b.getDouble("max_range_m"), 12.5);
  EXPECT_TRUE(b.getBool("full_dp"));
}

TEST(YamlReader, ErrorsNameTheNodeAndWhatWasExpected)
{
  const planar_grid::YamlReader reader("conf.yaml", "/data/configs");
  // line:col of the failing node, 1-based, and the message's expectation.
  const auto where = [&](const std::function<void()>& read, const std::string& expect) {
    try {
      read();
    } catch (const ConfigError& e) {
      EXPECT_NE(std::string(e.what()).find("conf.yaml"), std::string::npos);
      EXPECT_NE(std::string(e.what()).find(expect), std::string::npos) << e.what();
      return std::make_pair(e.line(), e.column());
    }
    ADD_FAILURE() << "no ConfigError, expected: " << expect;
    return std::make_pair(-1, -1);
  };
  const YAML::Node twice = YAML::Load("a: 1\nb: 2\na: 3\n");
  EXPECT_EQ(where(
              [&] {
                reader.checkKeys(twice, {"a", "b"}, "top");
              },
              "given twice"),
            std::make_pair(3, 1));
  const YAML::Node unknown = YAML::Load("a: 1\n  \nc: 2\n");
  EXPECT_EQ(where(
              [&] {
                reader.checkKeys(unknown, {"a", "b"}, "top");
              },
              "expected one of: a, b"),
            std::make_pair(3, 1));
  const YAML::Node list_key = YAML::Load("[x]: 1\n");
  EXPECT_EQ(
    where([&] { reader.checkKeys(list_key, {"a"}, "top"); }, "plain name").first, 1);
  const YAML::Node values = YAML::Load("r: 2.5\nn: 1.5\ns: [1]\nbig: 7\n");
  EXPECT_DOUBLE_EQ(reader.real(values, "r", 0.0, 0.0, 3.0, "top"), 2.5);
  EXPECT_DOUBLE_EQ(reader.real(values, "absent", 9.0, 0.0, 3.0, "top"), 9.0);
  EXPECT_EQ(where([&] { reader.real(values, "r", 0.0, 0.0, 2.0, "top"); },
                  "top.r = 2.5 is out of range [0, 2]"),
            std::make_pair(1, 4));
  EXPECT_EQ(where([&] { reader.integer(values, "n", 0, 0, 9, "top"); },
                  "top.n must be an integer"),
            std::make_pair(2, 4));
  EXPECT_EQ(where([&] { reader.string(values, "s", "top"); }, "top.s must be a string"),
            std::make_pair(3, 4));
  EXPECT_EQ(where([&] { reader.integerValue(values["big"], 0, 5, "big"); },
                  "big = 7 is out of range [0, 5]"),
            std::make_pair(4, 6));
  EXPECT_EQ(where([&] { reader.string(values, "missing", "top"); },
                  "top needs the key 'missing'")
              .first,
            1);
  EXPECT_EQ(reader.resolve("left/%d.png"), "/data/configs/left/%d.png");
  EXPECT_EQ(reader.resolve("../x.yaml"), "/data/x.yaml");
  EXPECT_EQ(reader.resolve("/abs/x.yaml"), "/abs/x.yaml");
  EXPECT_EQ(reader.resolve(""), "");
}

TEST(PipelineConfig, FeatureSampleOnPCDInputNeedsAFeatureStageBeforeIt)
{
  const std::string pcd = "input:\n  type: pcd_files\n  files: [a.pcd]\n";
  // Asked for explicitly: an error at the key's line.
  const auto e = errorOf(pcd
                         + "pipeline:\n  - type: multi_plane_segmentation\n"
                           "    params: {sample: features}\n");
  EXPECT_EQ(e.line(), 6) << e.what();
  EXPECT_NE(std::string(e.what()).find("sample: cloud"), std::string::npos) << e.what();
  // With key features from the cloud before it: accepted as asked.
  const auto with_features = parsePipelineConfig(
    pcd
      + "pipeline:\n  - type: cloud_features\n  - type: multi_plane_segmentation\n"
        "    params: {sample: features}\n",
    "t.yaml", "/");
  ASSERT_EQ(with_features.stages.size(), 2u);
  EXPECT_EQ(with_features.stages[1].params.getChoice("sample"), "features");
  // Features after the segmentation do not count.
  EXPECT_EQ(errorOf(pcd
                    + "pipeline:\n  - type: multi_plane_segmentation\n"
                      "    params: {sample: features}\n  - type: cloud_features\n")
              .line(),
            6);
  // Left at its default: the planes are hypothesised on the cloud.
  const auto config = parsePipelineConfig(
    pcd + "pipeline:\n  - type: multi_plane_segmentation\n", "t.yaml", "/");
  ASSERT_EQ(config.stages.size(), 1u);
  EXPECT_EQ(config.stages[0].params.getChoice("sample"), "cloud");
  // Stereo input keeps the paper's default.
  const auto stereo =
    parsePipelineConfig(INPUT
                          + "pipeline:\n  - type: stereo_disparity\n  - type: "
                            "feature_matching\n  - type: multi_plane_segmentation\n",
                        "t.yaml", "/");
  EXPECT_EQ(stereo.stages[2].params.getChoice("sample"), "features");
  // The feature occupancy needs a stage giving the features (cloud_features).
  const auto kl =
    errorOf(pcd + "pipeline:\n  - type: voxel_grid\n  - type: kl_occupancy_filter\n");
  EXPECT_EQ(kl.line(), 6) << kl.what();
}

TEST(PipelineConfig, RegistrationPosesAndSensorUp)
{
  const std::string pcd = "input:\n  type: pcd_files\n  files: [a.pcd, b.pcd]\n";
  const std::string stages = "pipeline:\n  - type: voxel_grid\n";
  const auto config = parsePipelineConfig(
    pcd
      + "  sensor_up: [0, 0, 2]\n  poses: {format: registration, leaf_size_m: 0.1, "
        "max_correspondence_distance_m: 1.0, feature_initial_guess: false, "
        "max_residual_m: 0.02}\n"
      + stages,
    "t.yaml", "/");
  EXPECT_EQ(config.input.poses_format, planar_grid::PoseFormat::REGISTRATION);
  EXPECT_TRUE(config.input.has_sensor_up);
  EXPECT_EQ(config.input.sensor_up[2], 2.0);
  EXPECT_EQ(config.input.registration_leaf_size_m, 0.1);
  EXPECT_EQ(config.input.registration_max_correspondence_distance_m, 1.0);
  EXPECT_FALSE(config.input.registration_feature_initial_guess);
  EXPECT_EQ(config.input.registration_max_residual_m, 0.02);
  // Each error at its line: a zero up, a registration key with another format, an
  // out-of-range leaf, sensor_up with poses from a file, registration on stereo input.
  EXPECT_EQ(errorOf(pcd + "  sensor_up: [0, 0, 0]\n" + stages).line(), 4);
  EXPECT_EQ(errorOf(pcd + "  sensor_up: [0, 1]\n" + stages).line(), 4);
  EXPECT_EQ(
    errorOf(pcd + "  poses: {format: viewpoint, leaf_size_m: 0.1}\n" + stages).line(),
    4);
  EXPECT_EQ(
    errorOf(pcd + "  poses: {format: registration, leaf_size_m: 0}\n" + stages).line(),
    4);
  EXPECT_EQ(errorOf(pcd + "  sensor_up: [0, 0, 1]\n  poses: {format: kitti, file: p}\n"
                    + stages)
              .line(),
            4);
  const auto stereo = errorOf(INPUT + "  poses: {format: registration}\n" + stages);
  EXPECT_NE(std::string(stereo.what()).find("unknown for this input"),
            std::string::npos)
    << stereo.what();
}

TEST(PipelineConfig, TheCellsAndTheMapShareTheMinimumCell)
{
  // A PCD input with poses, the cloud in the world frame and its planes (lines 1-8).
  const std::string head = "input:\n  type: pcd_files\n  files: [a.pcd]\n"
                           "  poses: {format: kitti, file: poses.txt}\npipeline:\n"
                           "  - type: transform_to_world\n"
                           "  - type: multi_plane_segmentation\n"
                           "  - type: planar_cuboid_approximation\n"
                           "    params: {min_cell_size_m: 0.2, thickness_m: 0.15}\n";
  // The map stage without the keys takes the cells' values.
  const auto c = parsePipelineConfig(head + "  - type: map_integration\n", "t", "/");
  ASSERT_EQ(c.stages.size(), 4u);
  EXPECT_DOUBLE_EQ(c.stages[3].params.getDouble("resolution_m"), 0.2);
  EXPECT_DOUBLE_EQ(c.stages[3].params.getDouble("thickness_m"), 0.15);
  // The same value twice is fine; another one is an error at the map's key.
  EXPECT_NO_THROW(parsePipelineConfig(
    head + "  - type: map_integration\n    params: {resolution_m: 0.2}\n", "t", "/"));
  const auto e =
    errorOf(head + "  - type: map_integration\n    params:\n      resolution_m: 0.1\n");
  EXPECT_EQ(e.line(), 12);
  EXPECT_EQ(e.column(), 21);
  EXPECT_NE(std::string(e.what()).find("min_cell_size_m"), std::string::npos)
    << e.what();
  const auto t =
    errorOf(head + "  - type: map_integration\n    params: {thickness_m: 0.3}\n");
  EXPECT_NE(std::string(t.what()).find("thickness_m"), std::string::npos) << t.what();
  // A value given by --set has no place in the file: the error names the --set, on
  // either side.
  const auto setError = [&](const std::string& map_stage,
                            const std::vector<std::string>& overrides) {
    try {
      parsePipelineConfig(head + map_stage, "t", "/", overrides);
    } catch (const planar_grid::ConfigError& error) {
      return error;
    }
    ADD_FAILURE() << "accepted";
    return planar_grid::ConfigError("", 0, 0, "");
  };
  const auto by_set =
    setError("  - type: map_integration\n", {"map_integration.resolution_m=0.1"});
  EXPECT_EQ(by_set.file(), "--set map_integration.resolution_m=0.1");
  EXPECT_EQ(by_set.line(), 0);
  EXPECT_NE(std::string(by_set.what()).find("min_cell_size_m 0.2 (line 9)"),
            std::string::npos)
    << by_set.what();
  const auto against_set =
    setError("  - type: map_integration\n    params:\n      resolution_m: 0.2\n",
             {"planar_cuboid_approximation.min_cell_size_m=0.3"});
  EXPECT_EQ(against_set.line(), 12);
  EXPECT_NE(std::string(against_set.what())
              .find("(--set planar_cuboid_approximation.min_cell_size_m=0.3)"),
            std::string::npos)
    << against_set.what();
}

TEST(PipelineConfig, OneCellSizeKeySetsEveryKeyOfTheMinimumCell)
{
  // A PCD input with poses and every stage with keys that follow the cell size.
  const std::string stages = "pipeline:\n"
                             "  - type: voxel_grid\n"
                             "  - type: transform_to_world\n"
                             "  - type: multi_plane_segmentation\n"
                             "  - type: planar_cuboid_approximation\n"
                             "  - type: map_integration\n"
                             "  - type: accumulate\n";
  const std::string head = "input:\n  type: pcd_files\n  files: [a.pcd]\n"
                           "  poses: {format: kitti, file: poses.txt}\n";
  const auto base = parsePipelineConfig(head + stages, "t", "/");
  const auto c = parsePipelineConfig(head + "cell_size_m: 0.2\n" + stages, "t", "/");
  EXPECT_DOUBLE_EQ(base.cell_size_m, 0.0);
  EXPECT_DOUBLE_EQ(c.cell_size_m, 0.2);
  ASSERT_EQ(c.stages.size(), base.stages.size());
  // Every key of every stage, against the rule: the cell's keys take 0.2, lengths
  // double, counts per area fall to a quarter (at least 10); the rest is unchanged.
  int followed = 0;
  for (std::size_t i = 0; i < c.stages.size(); ++i) {
    const planar_grid::StageInfo* info = planar_grid::findStage(c.stages[i].type);
    ASSERT_NE(info, nullptr);
    for (const auto& spec : info->params) {
      const auto& got = c.stages[i].params;
      const auto& was = base.stages[i].params;
      const std::string where = c.stages[i].type + "." + spec.key;
      using Scaling = planar_grid::ParamSpec::CellSizeScaling;
      switch (spec.cell_size_scaling) {
        case Scaling::CELL_SIZE:
          EXPECT_DOUBLE_EQ(got.getDouble(spec.key), 0.2) << where;
          ++followed;
          break;
        case Scaling::LENGTH:
          EXPECT_DOUBLE_EQ(got.getDouble(spec.key), 2.0 * was.getDouble(spec.key))
            << where;
          ++followed;
          break;
        case Scaling::POINTS_PER_AREA:
          EXPECT_EQ(
            got.getInt(spec.key),
            std::max(10, static_cast<int>(std::lround(was.getInt(spec.key) / 4.0))))
            << where;
          ++followed;
          break;
        case Scaling::NONE:
          EXPECT_EQ(got.toString(spec.key), was.toString(spec.key)) << where;
          break;
      }
    }
  }
  EXPECT_GE(followed, 10);
  // Known values: the map and the cells at 0.2 m, 500 inliers a quarter.
  EXPECT_DOUBLE_EQ(c.stages[4].params.getDouble("resolution_m"), 0.2);
  EXPECT_DOUBLE_EQ(c.stages[3].params.getDouble("min_cell_size_m"), 0.2);
  EXPECT_EQ(c.stages[2].params.getInt("min_inliers"), 125);
  // The same value given for a key of the cell is fine; another one is an error at
  // that key (line 8: voxel_grid's params), or at its --set.
  const std::string with_leaf = "pipeline:\n  - type: voxel_grid\n"
                                "    params: {leaf_size_m: LEAF}\n"
                                "  - type: transform_to_world\n";
  const auto leaf = [&](const std::string& value) {
    std::string text = with_leaf;
    text.replace(text.find("LEAF"), 4, value);
    return head + "cell_size_m: 0.2\n" + text;
  };
  EXPECT_NO_THROW(parsePipelineConfig(leaf("0.2"), "t", "/"));
  const auto e = errorOf(leaf("0.05"));
  EXPECT_EQ(e.line(), 8);
  EXPECT_NE(std::string(e.what()).find("differs from cell_size_m 0.2 (line 5)"),
            std::string::npos)
    << e.what();
  try {
    parsePipelineConfig(head + "cell_size_m: 0.2\n" + stages, "t", "/",
                        {"map_integration.resolution_m=0.1"});
    ADD_FAILURE() << "a --set against cell_size_m was accepted";
  } catch (const ConfigError& error) {
    EXPECT_EQ(error.file(), "--set map_integration.resolution_m=0.1");
  }
  // --set cell_size_m=R: the same as the file's key, checked where it is written.
  const auto by_set = parsePipelineConfig(head + stages, "t", "/", {"cell_size_m=0.2"});
  for (std::size_t i = 0; i < c.stages.size(); ++i)
    for (const auto& spec : planar_grid::findStage(c.stages[i].type)->params)
      EXPECT_EQ(by_set.stages[i].params.toString(spec.key),
                c.stages[i].params.toString(spec.key))
        << c.stages[i].type << "." << spec.key;
  for (const std::string bad : {"cell_size_m=0", "cell_size_m=x", "cell_size_m="}) {
    try {
      parsePipelineConfig(head + stages, "t", "/", {bad});
      ADD_FAILURE() << bad << " was accepted";
    } catch (const ConfigError& error) {
      EXPECT_EQ(error.file(), "--set " + bad);
    }
  }
  // Out of its range, or not a number: an error at the key.
  for (const std::string bad : {"0", "-0.1", "11", "fine"}) {
    const auto b = errorOf(head + "cell_size_m: " + bad + "\n" + stages);
    EXPECT_EQ(b.line(), 5) << bad;
    EXPECT_NE(std::string(b.what()).find("cell_size_m"), std::string::npos) << b.what();
  }
  // A mapper's stages take it too.
  const auto mapper =
    planar_grid::parseMapperConfig("cell_size_m: 0.3\n" + stages, "t", "/");
  ASSERT_EQ(mapper.stages.size(), 6u);
  EXPECT_DOUBLE_EQ(mapper.stages[4].params.getDouble("resolution_m"), 0.3);
}

TEST(PipelineConfig, TheSegmentationSparesTheGroundRemovalsTerrain)
{
  // The segmentation spares as terrain the level planes at least ground_removal's
  // min_sensor_height_m below the sensor: left out, its key takes that value.
  const std::string head = "input:\n  type: pcd_files\n  files: [a.pcd]\n"
                           "  poses: {format: kitti, file: poses.txt}\npipeline:\n"
                           "  - type: transform_to_world\n";
  const std::string ground = "  - type: ground_removal\n"
                             "    params: {min_sensor_height_m: 0.7}\n";
  const auto c = parsePipelineConfig(
    head + "  - type: multi_plane_segmentation\n" + ground, "t", "/");
  ASSERT_EQ(c.stages.size(), 3u);
  EXPECT_DOUBLE_EQ(c.stages[1].params.getDouble("min_sensor_height_m"), 0.7);
  // By --set as well; and the ground removal's default when neither sets it.
  const auto by_set = parsePipelineConfig(
    head + "  - type: multi_plane_segmentation\n  - type: ground_removal\n", "t", "/",
    {"ground_removal.min_sensor_height_m=1.2"});
  EXPECT_DOUBLE_EQ(by_set.stages[1].params.getDouble("min_sensor_height_m"), 1.2);
  const auto neither = parsePipelineConfig(
    head + "  - type: multi_plane_segmentation\n  - type: ground_removal\n", "t", "/");
  EXPECT_DOUBLE_EQ(neither.stages[1].params.getDouble("min_sensor_height_m"),
                   neither.stages[2].params.getDouble("min_sensor_height_m"));
  EXPECT_GT(neither.stages[1].params.getDouble("min_sensor_height_m"), 0.0);
  // Without a ground removal the segmentation keeps its own value, 0 when set so
  // (every level plane below the sensor is terrain).
  const auto alone = parsePipelineConfig(head
                                           + "  - type: multi_plane_segmentation\n"
                                             "    params: {min_sensor_height_m: 0}\n",
                                         "t", "/");
  EXPECT_DOUBLE_EQ(alone.stages[1].params.getDouble("min_sensor_height_m"), 0.0);
  // Two values apart are an error at the segmentation's key (line 8).
  const auto e = errorOf(head
                         + "  - type: multi_plane_segmentation\n"
                           "    params: {min_sensor_height_m: 0.3}\n"
                         + ground);
  EXPECT_EQ(e.line(), 8);
  EXPECT_NE(std::string(e.what()).find("ground_removal's min_sensor_height_m 0.7"),
            std::string::npos)
    << e.what();
}

TEST(PipelineConfig, EveryShippedConfigLoads)
{
  // Every pipeline file in config/ and config/eval/ passes the loader's checks (stage
  // order, repeats); the evaluation files without a pipeline: key have their own
  // loader.
  std::size_t loaded = 0;
  for (const char* folder : {"/config", "/config/eval"})
    for (const auto& entry : std::filesystem::directory_iterator(SOURCE_DIR + folder)) {
      if (entry.path().extension() != ".yaml")
        continue;
      const YAML::Node root = YAML::LoadFile(entry.path().string());
      if (!root.IsMap() || !root["pipeline"])
        continue;
      ++loaded;
      if (root["input"] && root["input"]["type"]
          && root["input"]["type"].as<std::string>() == "ros_bag"
          && !planar_grid::rosBagSupported()) {
        // a build without rosbag_storage says so at the input's type
        EXPECT_THROW(planar_grid::loadPipelineConfig(entry.path().string()),
                     planar_grid::ConfigError)
          << entry.path();
        continue;
      }
      EXPECT_NO_THROW(planar_grid::loadPipelineConfig(entry.path().string()))
        << entry.path();
    }
  EXPECT_GE(loaded, 15u); // 10 in config/, 5 in config/eval/
}

TEST(PipelineConfig, EveryStageNeedIsProducedByTheInputOrAStage)
{
  using planar_grid::StageData;
  for (const auto& info : planar_grid::stageRegistry())
    for (const StageData need : info.needs) {
      const bool from_input = need == StageData::STEREO_IMAGES
                              || need == StageData::CLOUD || need == StageData::POSES;
      const bool from_stage = std::any_of(
        planar_grid::stageRegistry().begin(), planar_grid::stageRegistry().end(),
        [need](const planar_grid::StageInfo& other) {
          return std::find(other.produces.begin(), other.produces.end(), need)
                 != other.produces.end();
        });
      EXPECT_TRUE(from_input || from_stage)
        << info.type << " needs " << planar_grid::stageDataName(need);
    }
}

TEST(PipelineConfig, StageListedTwiceIsAnErrorAtItsLine)
{
  const std::string poses = "  poses: {format: kitti, file: p.txt}\n";
  const std::string head = INPUT + poses
                           + "pipeline:\n"                  // line 9
                             "  - type: stereo_disparity\n" // 10
                             "  - type: transform_to_world\n"
                             "  - type: multi_plane_segmentation\n"
                             "    params: {sample: cloud}\n"
                             "  - type: planar_cuboid_approximation\n"
                             "  - type: map_integration\n"; // 15
  auto e = errorOf(head + "  - type: map_integration\n");
  EXPECT_EQ(e.line(), 16);
  EXPECT_EQ(e.column(), 11);
  EXPECT_NE(std::string(e.what()).find("stage 'map_integration' is listed twice "
                                       "(first at line 15)"),
            std::string::npos)
    << e.what();
  // The filters may repeat: a coarse and a fine voxel grid.
  EXPECT_NO_THROW(parsePipelineConfig(head
                                        + "  - type: voxel_grid\n"
                                          "  - type: voxel_grid\n"
                                          "    params: {leaf_size_m: 0.2}\n"
                                          "  - type: statistical_outlier_removal\n"
                                          "  - type: statistical_outlier_removal\n",
                                      "t", "/"));
}

TEST(PipelineConfig, StageOrderIsCheckedAgainstWhatEachStageNeeds)
{
  const std::string stereo =
    INPUT + "  poses: {format: kitti, file: p.txt}\npipeline:\n";
  // The KL filter before the feature matching that gives it its features (line 10).
  auto e = errorOf(stereo
                   + "  - type: stereo_disparity\n  - type: kl_occupancy_filter\n"
                     "  - type: feature_matching\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_NE(std::string(e.what()).find(
              "stage 'kl_occupancy_filter' needs key features, which no earlier "
              "stage produces: 'feature_matching' is listed after it (line 12); put "
              "'feature_matching' or 'cloud_features' before it"),
            std::string::npos)
    << e.what();
  // Ground removal before the segmentation that finds the planes.
  e = errorOf(stereo
              + "  - type: stereo_disparity\n  - type: ground_removal\n"
                "  - type: multi_plane_segmentation\n    params: {sample: cloud}\n");
  EXPECT_EQ(e.line(), 11);
  EXPECT_NE(std::string(e.what()).find("'ground_removal' needs planes"),
            std::string::npos)
    << e.what();
  EXPECT_NE(std::string(e.what()).find("put 'multi_plane_segmentation' before it"),
            std::string::npos)
    << e.what();
  // A map without the cuboid stage: known before the first frame, not after the last.
  e = errorOf(stereo
              + "  - type: stereo_disparity\n  - type: transform_to_world\n"
                "  - type: multi_plane_segmentation\n    params: {sample: cloud}\n"
                "  - type: map_integration\n");
  EXPECT_EQ(e.line(), 14);
  EXPECT_NE(std::string(e.what()).find("'map_integration' needs cuboids, which no "
                                       "earlier stage produces: put "
                                       "'planar_cuboid_approximation' before it"),
            std::string::npos)
    << e.what();
  // The default plane sample is the key features.
  e = errorOf(stereo
              + "  - type: stereo_disparity\n  - type: multi_plane_segmentation\n");
  EXPECT_NE(std::string(e.what()).find("needs key features"), std::string::npos)
    << e.what();
  // The stereo stages on a PCD input, and what only they produce.
  const std::string pcd = "input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n";
  e = errorOf(pcd + "  - type: voxel_grid\n  - type: feature_matching\n");
  EXPECT_EQ(e.line(), 6);
  EXPECT_NE(
    std::string(e.what()).find("'feature_matching' needs stereo images: it needs "
                               "a stereo_sequence input (a pcd_files input has "
                               "none)"),
    std::string::npos)
    << e.what();
  // The feature occupancy on a point cloud takes its features from cloud_features.
  e = errorOf(pcd + "  - type: kl_occupancy_filter\n");
  EXPECT_NE(std::string(e.what()).find("needs key features, which no earlier stage "
                                       "produces: put 'feature_matching' or "
                                       "'cloud_features' before it"),
            std::string::npos)
    << e.what();
  // The right order loads.
  EXPECT_NO_THROW(parsePipelineConfig(stereo
                                        + "  - type: stereo_disparity\n"
                                          "  - type: feature_matching\n"
                                          "  - type: kl_occupancy_filter\n"
                                          "  - type: transform_to_world\n"
                                          "  - type: multi_plane_segmentation\n"
                                          "  - type: ground_removal\n"
                                          "  - type: planar_cuboid_approximation\n"
                                          "  - type: map_integration\n",
                                      "t", "/"));
}

TEST(PipelineConfig, AbsurdlyLongPipelineIsAnError)
{
  std::string yaml = "input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n";
  for (int i = 0; i < 19000; ++i)
    yaml += "  - type: voxel_grid\n";
  const auto e = errorOf(yaml);
  EXPECT_EQ(e.line(), 5);
  EXPECT_NE(std::string(e.what()).find("pipeline lists 19000 stages; at most 256"),
            std::string::npos)
    << e.what();
}

TEST(PipelineConfig, TabsAndDeepNestingAreClearErrors)
{
  // A tab in the indentation of line 3 (yaml-cpp says "end of map not found").
  auto e = errorOf("input:\n  type: pcd_files\n\tfiles: a.pcd\npipeline:\n"
                   "  - type: voxel_grid\n");
  EXPECT_EQ(e.line(), 3);
  EXPECT_EQ(e.column(), 1);
  EXPECT_NE(std::string(e.what()).find("tab character in the indentation: YAML indents "
                                       "with spaces"),
            std::string::npos)
    << e.what();
  e = errorOf("input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n"
              "  - type: voxel_grid\n    params:\n    \t leaf_size_m: 0.1\n");
  EXPECT_EQ(e.line(), 7);
  EXPECT_EQ(e.column(), 5);
  // A tab inside a value or after a comment is no indentation.
  EXPECT_NO_THROW(parsePipelineConfig("input:\n  type: pcd_files # a\tcomment\n"
                                      "\t# an indented comment\n  files: \"a\tb.pcd\"\n"
                                      "pipeline:\n  - type: voxel_grid\n",
                                      "t", "/"));
  // 40 nested lists on line 2: deeper than the 32 levels accepted.
  e = errorOf("input:\n  x: " + std::string(40, '[') + std::string(40, ']') + "\n");
  EXPECT_EQ(e.line(), 2);
  EXPECT_NE(std::string(e.what()).find("nests more than 32 levels"), std::string::npos)
    << e.what();
  // yaml-cpp's own guard ("bad file") at thousands of levels.
  e = errorOf("a: " + std::string(5000, '[') + "\n");
  EXPECT_NE(std::string(e.what()).find("levels deep here"), std::string::npos)
    << e.what();
  EXPECT_EQ(std::string(e.what()).find("bad file"), std::string::npos) << e.what();
}

TEST(PipelineConfig, OutputFolderThatIsAFileIsAnErrorAtItsLine)
{
  const auto file = std::filesystem::temp_directory_path()
                    / ("planar_grid_output_is_a_file_" + std::to_string(::getpid()));
  std::ofstream(file) << "x";
  const auto e = errorOf("input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n"
                         "  - type: voxel_grid\noutput:\n  folder: "
                         + file.string() + "\n");
  std::filesystem::remove(file);
  EXPECT_EQ(e.line(), 7);
  EXPECT_NE(std::string(e.what()).find("is a file, not a folder"), std::string::npos)
    << e.what();
}
