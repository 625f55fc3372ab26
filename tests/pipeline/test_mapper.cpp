// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <mutex>
#include <set>
#include <string>
#include <thread>
#include <utility>
#include <variant>
#include <vector>

namespace fs = std::filesystem;

namespace {

const std::string SOURCE = PLANAR_GRID_SOURCE_DIR;

/** The main job (config/karlsruhe.yaml) over its first \a frames frames. */
planar_grid::PipelineConfig
mainJob(int frames, const std::string& file = "karlsruhe.yaml")
{
  auto config = planar_grid::loadPipelineConfig(SOURCE + "/config/" + file);
  config.input.frame_count = frames;
  return config;
}

/** The main job over its first \a frames frames with the poses of the visual_odometry
 * stage of config/karlsruhe_odometry.yaml (after feature_matching) instead of the INS:
 * config/karlsruhe_odometry.yaml itself builds no map. */
planar_grid::PipelineConfig
odometryJob(int frames)
{
  auto config = mainJob(frames);
  const auto odometry = mainJob(frames, "karlsruhe_odometry.yaml");
  const auto vo = std::find_if(
    odometry.stages.begin(), odometry.stages.end(),
    [](const planar_grid::StageConfig& s) { return s.type == "visual_odometry"; });
  const auto matching = std::find_if(
    config.stages.begin(), config.stages.end(),
    [](const planar_grid::StageConfig& s) { return s.type == "feature_matching"; });
  if (vo == odometry.stages.end() || matching == config.stages.end())
    throw planar_grid::Exception("the odometry or main job config changed");
  config.stages.insert(matching + 1, *vo);
  config.input.poses_format = planar_grid::PoseFormat::ODOMETRY;
  config.input.poses_file.clear();
  return config;
}

/** Every frame of \a config's input, loaded. */
std::vector<planar_grid::Frame>
loadFrames(const planar_grid::PipelineConfig& config)
{
  const auto source = planar_grid::createFrameSource(config.input);
  std::vector<planar_grid::Frame> frames(source->size());
  for (std::size_t i = 0; i < frames.size(); ++i)
    source->load(i, frames[i]);
  return frames;
}

std::string
fileBytes(const fs::path& path)
{
  std::ifstream in(path, std::ios::binary);
  return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

/** Expects \a call to throw planar_grid::Exception whose message contains \a text. */
void
expectThrowWith(const std::function<void()>& call, const std::string& text)
{
  try {
    call();
    ADD_FAILURE() << "no exception; expected one with \"" << text << "\"";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find(text), std::string::npos) << e.what();
  }
}

/** A fresh temporary folder per test, removed afterwards. */
class MapperTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_mapper_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

} // namespace

TEST_F(MapperTest, KarlsruheFramesGiveThePipelineRunnersMapFile)
{
  // Two frames of the main job read by the project's frame source (poses from the
  // INS), fed one by one: the same map file, byte for byte, and the same poses as a
  // PipelineRunner run of the configuration over them.
  const auto config = mainJob(2);
  planar_grid::PipelineRunner runner(config);
  const planar_grid::RunReport report = runner.run();
  ASSERT_EQ(report.frames, 2u);
  runner.state().map->save((dir_ / "runner.pgmap").string());

  const auto source = planar_grid::createFrameSource(config.input);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
  std::vector<planar_grid::FrameStats> stats;
  for (std::size_t i = 0; i < source->size(); ++i) {
    planar_grid::Frame frame;
    source->load(i, frame);
    stats.push_back(mapper.integrateStereo(frame.left, frame.right, frame.calibration,
                                           frame.world_T_camera));
    EXPECT_EQ(stats.back().sequence_number, i);
    EXPECT_TRUE(stats.back().world_T_camera.matrix() == frame.world_T_camera.matrix());
    EXPECT_GT(stats.back().cuboids, 0u);
    EXPECT_GT(stats.back().map_cells, 0u);
    EXPECT_EQ(stats.back().map_cells,
              mapper.getMap()->getSurfaceLayer().getCellCount());
  }
  EXPECT_EQ(mapper.getFrameCount(), 2u);
  mapper.save((dir_ / "mapper.pgmap").string());
  const std::string expected = fileBytes(dir_ / "runner.pgmap");
  EXPECT_GT(expected.size(), 10000u);
  EXPECT_TRUE(fileBytes(dir_ / "mapper.pgmap") == expected)
    << "the mapper's map file differs from the runner's";
  ASSERT_EQ(mapper.getTrajectory().size(), 2u);
  for (std::size_t i = 0; i < 2; ++i)
    EXPECT_TRUE(mapper.getTrajectory()[i].matrix() == runner.trajectory()[i].matrix());

  // The per-frame figures add up to the run's: each stage's points and counters.
  ASSERT_EQ(stats[0].stages.size(), config.stages.size());
  for (std::size_t s = 0; s < config.stages.size(); ++s) {
    const auto& run_stage = report.stages[s];
    EXPECT_EQ(stats[0].stages[s].type, run_stage.type);
    EXPECT_EQ(stats[0].stages[s].points_in + stats[1].stages[s].points_in,
              run_stage.points_in)
      << run_stage.type;
    EXPECT_EQ(stats[0].stages[s].points_out + stats[1].stages[s].points_out,
              run_stage.points_out)
      << run_stage.type;
    ASSERT_EQ(stats[1].stages[s].counters.size(), run_stage.counters.size());
    for (std::size_t c = 0; c < run_stage.counters.size(); ++c)
      EXPECT_DOUBLE_EQ(stats[0].stages[s].counters[c].second
                         + stats[1].stages[s].counters[c].second,
                       run_stage.counters[c].second)
        << run_stage.type << " " << run_stage.counters[c].first;
  }
}

TEST_F(MapperTest, AReaderThreadSeesTheMapAfterWholeFramesOnly)
{
  // A reader serializes the map and queries it in a loop while two frames are
  // integrated. Every map it reads is the empty map or the map after frame 1 or
  // frame 2, never one in between.
  const auto config = mainJob(2);
  std::vector<planar_grid::Frame> frames = loadFrames(config);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));

  const auto serialized = [&mapper] {
    std::string bytes;
    mapper.readMap()->serialize(bytes);
    return bytes;
  };
  std::set<std::string> after_frames{serialized()};
  std::atomic<bool> done{false};
  std::vector<std::string> seen;
  std::size_t queries = 0;
  std::thread reader([&] {
    do {
      std::string bytes;
      const auto map = mapper.readMap();
      map->serialize(bytes);
      // A query beside the serialization, under the same lock.
      const bool known = map->getState(Eigen::Vector3f(5.0f, 0.0f, 1.0f))
                           != planar_grid::SpaceState::UNKNOWN
                         || map->getSurfaceLayer().getCuboidCount() > 0;
      queries += known ? 1u : 0u;
      if (seen.empty() || seen.back() != bytes)
        seen.push_back(std::move(bytes));
    } while (!done);
  });
  for (auto& frame : frames) {
    mapper.integrateStereo(frame.left, frame.right, frame.calibration,
                           frame.world_T_camera);
    after_frames.insert(serialized());
  }
  done = true;
  reader.join();
  EXPECT_EQ(after_frames.size(), 3u);
  EXPECT_GT(queries, 0u); // at least the last read holds cuboids
  ASSERT_FALSE(seen.empty());
  for (std::size_t k = 0; k < seen.size(); ++k)
    EXPECT_EQ(after_frames.count(seen[k]), 1u)
      << "read " << k << " (" << seen[k].size() << " bytes) is not a whole frame's map";
  // The last read came after the last frame.
  EXPECT_EQ(seen.back(), serialized());
}

TEST_F(MapperTest, BadInputThrowsWithAClearMessage)
{
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(mainJob(1)));
  const auto source = planar_grid::createFrameSource(mainJob(1).input);
  planar_grid::Frame frame;
  source->load(0, frame);
  const auto& calibration = frame.calibration;
  const Eigen::Isometry3d pose = frame.world_T_camera;

  expectThrowWith(
    [&] { mapper.integrateStereo(cv::Mat(), frame.right, calibration, pose); },
    "the left image is empty");
  const cv::Mat small(100, 120, CV_8UC1, cv::Scalar(0));
  // Karlsruhe's calibration gives no image size; its principal point is (635.96,
  // 194.13) px.
  expectThrowWith([&] { mapper.integrateStereo(small, small, calibration, pose); },
                  "the calibration's principal point (635.958700, 194.129100) px lies "
                  "outside the 120x100 px images");
  planar_grid::StereoCalibration sized = calibration;
  sized.width = 1344;
  sized.height = 372;
  expectThrowWith(
    [&] { mapper.integrateStereo(small, small, sized, pose); },
    "the images' size 120x100 px differs from the calibration's 1344x372");
  expectThrowWith([&] { mapper.integrateStereo(frame.left, small, calibration, pose); },
                  "the right image's size 120x100 px differs from the left image's");
  cv::Mat colour;
  cv::merge(std::vector<cv::Mat>{frame.left, frame.left, frame.left}, colour);
  expectThrowWith([&] { mapper.integrateStereo(colour, colour, calibration, pose); },
                  "8-bit grey");
  planar_grid::StereoCalibration no_baseline = calibration;
  no_baseline.baseline_m = 0.0;
  expectThrowWith(
    [&] { mapper.integrateStereo(frame.left, frame.right, no_baseline, pose); },
    "Mapper::integrateStereo: the calibration");
  // Held to the file readers' rules: a baseline of 1e6 m would map every pixel free.
  planar_grid::StereoCalibration huge_baseline = calibration;
  huge_baseline.baseline_m = 1e6;
  expectThrowWith(
    [&] { mapper.integrateStereo(frame.left, frame.right, huge_baseline, pose); },
    "the baseline is 1e+06 m, outside [0.001, 100] m for a stereo rig");
  // No pose, and the main job's poses come from the input, not visual_odometry.
  expectThrowWith([&] { mapper.integrateStereo(frame.left, frame.right, calibration); },
                  "has no visual_odometry stage to estimate it: pass world_T_camera");
  // The first pair the wrong way round, or one image twice.
  expectThrowWith(
    [&] { mapper.integrateStereo(frame.right, frame.left, calibration, pose); },
    "the left and right images look swapped");
  expectThrowWith(
    [&] { mapper.integrateStereo(frame.left, frame.left.clone(), calibration, pose); },
    "the right image is the left image");
  planar_grid::Mapper::PointCloud cloud;
  cloud.push_back(pcl::PointXYZ(1.0f, 0.0f, 2.0f));
  expectThrowWith(
    [&] { mapper.integrateCloud(cloud, pose); },
    "takes stereo pairs (a stage of it reads stereo images), not point clouds");
  // None of them changed the map.
  EXPECT_EQ(mapper.getFrameCount(), 0u);
  EXPECT_EQ(mapper.readMap()->getSurfaceLayer().getCuboidCount(), 0u);

  // A pipeline whose visual_odometry stage estimates the poses refuses a given one.
  planar_grid::Mapper odometry(planar_grid::toMapperConfig(odometryJob(1)));
  expectThrowWith(
    [&] { odometry.integrateStereo(frame.left, frame.right, calibration, pose); },
    "estimates the poses (visual_odometry stage)");

  // A pipeline without a map.
  auto no_map = mainJob(1);
  while (!no_map.stages.empty() && no_map.stages.back().type != "map_integration")
    no_map.stages.pop_back();
  no_map.stages.pop_back();
  expectThrowWith([&] { planar_grid::Mapper m(planar_grid::toMapperConfig(no_map)); },
                  "has no map_integration stage");
}

TEST_F(MapperTest, VisualOdometryGivesThePoseWhenNoneIsGiven)
{
  // One frame of the main job with visual_odometry, without a pose: the stage puts the
  // first camera at its initial_height_m (1.57 m) above the world origin, looking
  // along world +x (camera z) and pitched down by initial_pitch_rad (0.09 rad).
  const auto config = odometryJob(1);
  const auto source = planar_grid::createFrameSource(config.input);
  planar_grid::Frame frame;
  source->load(0, frame);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
  const auto stats = mapper.integrateStereo(frame.left, frame.right, frame.calibration);
  EXPECT_TRUE(stats.world_T_camera.translation().isApprox(Eigen::Vector3d(0, 0, 1.57)));
  const Eigen::Vector3d forward = stats.world_T_camera.linear().col(2);
  EXPECT_NEAR(forward.x(), std::cos(0.09), 1e-9);
  EXPECT_NEAR(forward.z(), -std::sin(0.09), 1e-9);
  ASSERT_EQ(mapper.getTrajectory().size(), 1u);
  EXPECT_TRUE(mapper.getTrajectory()[0].matrix() == stats.world_T_camera.matrix());
  EXPECT_GT(mapper.readMap()->getSurfaceLayer().getCuboidCount(), 0u);
}

TEST_F(MapperTest, ACloudGivesThePipelineRunnersMap)
{
  // A real Kinect scan (office1.pcd, its colour as intensity) through a short cloud
  // pipeline, fed as a point cloud with the pose the frame source gives it (levelled on
  // its floor): the same map as the runner's.
  const std::string yaml =
    "input:\n  type: pcd_files\n  files: " + std::string(PLANAR_GRID_DATA_DIR)
    + R"(/pcl_clouds/office1.pcd
  poses: {format: viewpoint}
pipeline:
  - type: cloud_features
    params: {feature_type: orb_grid, max_features: 500}
  - type: kl_occupancy_filter
    params: {range_error_model: depth_quadratic, depth_error_coefficient_per_m: 0.0016,
             neighbourhood_size_m: 0.1}
  - type: voxel_grid
    params: {leaf_size_m: 0.05}
  - type: transform_to_world
  - type: multi_plane_segmentation
    params: {distance_threshold_m: 0.03, max_planes: 4, min_inliers: 300}
  - type: planar_cuboid_approximation
    params: {min_cell_size_m: 0.1, thickness_m: 0.1}
  - type: map_integration
)";
  const auto config = planar_grid::parsePipelineConfig(yaml, "cloud.yaml", "/");
  planar_grid::PipelineRunner runner(config);
  runner.run();
  const auto source = planar_grid::createFrameSource(config.input);
  planar_grid::Frame frame;
  source->load(0, frame);
  ASSERT_TRUE(frame.cloud && frame.has_pose);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
  const auto stats = mapper.integrateCloud(*frame.cloud, frame.world_T_camera);
  EXPECT_GT(stats.cuboids, 0u);
  std::string a, b;
  runner.state().map->serialize(a);
  mapper.readMap()->serialize(b);
  EXPECT_TRUE(a == b) << "the mapper's map differs from the runner's";
  // A stereo call on a cloud pipeline, and an empty cloud, are refused.
  expectThrowWith(
    [&] {
      mapper.integrateStereo(cv::Mat(2, 2, CV_8UC1), cv::Mat(2, 2, CV_8UC1),
                             planar_grid::StereoCalibration(), frame.world_T_camera);
    },
    "takes point clouds (no stage of it reads stereo images), not stereo pairs");
  expectThrowWith(
    [&] {
      mapper.integrateCloud(planar_grid::Mapper::PointCloud(), frame.world_T_camera);
    },
    "the cloud is empty");
}

namespace {

/** The stages of depthPipeline(), as its `pipeline:` section. */
std::string
depthStages(int width, int height, double focal)
{
  return R"(pipeline:
  - type: voxel_grid
    params: {leaf_size_m: 0.05}
  - type: transform_to_world
  - type: multi_plane_segmentation
    params: {distance_threshold_m: 0.03, max_planes: 4, min_inliers: 300}
  - type: planar_cuboid_approximation
    params: {min_cell_size_m: 0.1, thickness_m: 0.1}
  - type: map_integration
    params: {prior: unknown, sensor_model: pinhole, depth_width_px: )"
         + std::to_string(width) + ", depth_height_px: " + std::to_string(height)
         + ", depth_focal_length_px: " + std::to_string(focal) + "}\n";
}

/** A point-cloud pipeline on office1.pcd whose map sees point clouds through a
 * virtual pinhole camera of \a width x \a height px, focal length \a focal px and its
 * principal point in the image's centre (map_integration's depth_* keys). */
planar_grid::PipelineConfig
depthPipeline(int width, int height, double focal)
{
  return planar_grid::parsePipelineConfig(
    "input:\n  type: pcd_files\n  files: " + std::string(PLANAR_GRID_DATA_DIR)
      + "/pcl_clouds/office1.pcd\n" + depthStages(width, height, focal),
    "depth.yaml", "/");
}

} // namespace

namespace {

/** A stage of \a type with the parameters \a params, the others at their defaults. */
planar_grid::StageSpec
stageSpec(
  const std::string& type,
  const std::vector<
    std::pair<std::string, std::variant<double, int, bool, std::string>>>& params = {})
{
  planar_grid::StageSpec spec;
  spec.type = type;
  for (const auto& [key, value] : params)
    spec.params.set(key, value);
  return spec;
}

} // namespace

TEST_F(MapperTest, AMapperIsBuiltFromStagesWithoutAConfigurationFile)
{
  // depthPipeline()'s stages written in code, the keys the file leaves out at their
  // defaults (the loader's defaults for a point-cloud input and the map's cell size
  // taken from planar_cuboid_approximation written out): the same map from the same
  // depth image.
  planar_grid::MapperConfig stages;
  stages.stages = {
    stageSpec("voxel_grid", {{"leaf_size_m", 0.05}}), stageSpec("transform_to_world"),
    stageSpec("multi_plane_segmentation", {{"distance_threshold_m", 0.03},
                                           {"max_planes", 4},
                                           {"min_inliers", 300},
                                           {"sample", std::string("cloud")}}),
    stageSpec("planar_cuboid_approximation",
              {{"min_cell_size_m", 0.1}, {"thickness_m", 0.1}}),
    stageSpec("map_integration", {{"resolution_m", 0.1},
                                  {"thickness_m", 0.1},
                                  {"prior", std::string("unknown")},
                                  {"sensor_model", std::string("pinhole")},
                                  {"depth_width_px", 640},
                                  {"depth_height_px", 480},
                                  {"depth_focal_length_px", 525.0}})};
  planar_grid::Mapper from_code(stages);
  planar_grid::Mapper from_file(
    planar_grid::toMapperConfig(depthPipeline(640, 480, 525.0)));
  // The file's stages alone, without its input section.
  planar_grid::Mapper from_stages(
    planar_grid::parseMapperConfig(depthStages(640, 480, 525.0), "stages.yaml", "/"));
  EXPECT_EQ(from_stages.getConfig().name, "stages.yaml");
  EXPECT_FALSE(from_code.takesStereo());
  EXPECT_TRUE(from_code.getConfig().name.empty());
  ASSERT_EQ(from_code.getConfig().stages.size(), 5u);
  // The keys left out hold their defaults.
  EXPECT_EQ(from_code.getConfig().stages[1].params.values().size(),
            planar_grid::findStage("transform_to_world")->params.size());
  const planar_grid::PinholeView camera{640, 480, 525.0, 525.0, 320.0, 240.0};
  const cv::Mat wall(480, 640, CV_16UC1, cv::Scalar(2000));
  for (planar_grid::Mapper* mapper : {&from_code, &from_file, &from_stages})
    mapper->integrateDepth(wall, camera, Eigen::Isometry3d::Identity());
  std::string a, b, c;
  from_code.readMap()->serialize(a);
  from_file.readMap()->serialize(b);
  from_stages.readMap()->serialize(c);
  EXPECT_TRUE(c == b) << "the file's stages alone map otherwise than the file";
  EXPECT_GT(from_code.readMap()->getSurfaceLayer().getCuboidCount(), 0u);
  EXPECT_TRUE(a == b) << "the stages written in code map otherwise than the file's";
  ASSERT_EQ(from_code.getStageReports().size(), 5u);
  EXPECT_EQ(from_code.getStageReports()[4].type, "map_integration");
  EXPECT_EQ(from_code.getStageReports()[4].frames, 1u);

  // What cannot be built is refused, naming the stage.
  const auto refused = [](std::vector<planar_grid::StageSpec> specs,
                          const std::string& text) {
    planar_grid::MapperConfig config;
    config.stages = std::move(specs);
    expectThrowWith([&] { planar_grid::Mapper m(config); }, text);
  };
  refused({stageSpec("no_such_stage")}, "unknown stage type 'no_such_stage'");
  refused({stageSpec("voxel_grid", {{"leaf_size", 0.05}})},
          "stage 'voxel_grid' has no parameter 'leaf_size'");
  refused({stageSpec("map_integration")},
          "stage 'map_integration' needs a world-frame cloud");
  refused({stageSpec("voxel_grid")}, "the mapper's pipeline has no map_integration");
  // A need a parameter's value makes is checked too: planes hypothesised from the key
  // features need feature_matching before them.
  refused(
    {stageSpec("stereo_disparity"),
     stageSpec("multi_plane_segmentation", {{"sample", std::string("features")}})},
    "stage 'multi_plane_segmentation' needs key features, which neither the "
    "frames nor an earlier stage give; or use sample: cloud");
  // A stage list is checked as a file's stages are, and holds nothing else.
  expectThrowWith(
    [] {
      planar_grid::parseMapperConfig("pipeline:\n  - type: map_integration\n", "s",
                                     "/");
    },
    "s:2:11: stage 'map_integration' needs");
  expectThrowWith(
    [&] {
      planar_grid::parseMapperConfig(depthStages(640, 480, 525.0) + "input: {}\n", "s",
                                     "/");
    },
    "'input'");
  try {
    planar_grid::MapperConfig config;
    config.name = "live.yaml";
    config.stages = {stageSpec("no_such_stage")};
    config.stages[0].line = 7;
    config.stages[0].column = 5;
    planar_grid::Mapper m(config);
    ADD_FAILURE() << "an unknown stage type was accepted";
  } catch (const planar_grid::ConfigError& e) {
    EXPECT_EQ(e.file(), "live.yaml");
    EXPECT_EQ(e.line(), 7);
    EXPECT_EQ(e.column(), 5);
  }
}

TEST_F(MapperTest, ADepthImageIsMappedThroughItsOwnCamera)
{
  // A fronto-parallel wall 2 m ahead filling a 640 x 480 depth image (f = 525 px, so
  // 2.44 m x 1.83 m), in millimeters, seen from the origin looking along world z: the
  // wall's cells are occupied, the space in front of it free, behind it unknown.
  const auto config = depthPipeline(640, 480, 525.0);
  const planar_grid::PinholeView camera{640, 480, 525.0, 525.0, 320.0, 240.0};
  const Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  planar_grid::Mapper wall(planar_grid::toMapperConfig(config));
  const auto stats =
    wall.integrateDepth(cv::Mat(480, 640, CV_16UC1, cv::Scalar(2000)), camera, pose);
  EXPECT_GT(stats.cuboids, 0u);
  {
    const auto map = wall.readMap();
    for (const float x : {-0.8f, 0.0f, 0.8f})
      EXPECT_EQ(map->getState(Eigen::Vector3f(x, 0.3f, 2.0f)),
                planar_grid::SpaceState::OCCUPIED)
        << x;
    EXPECT_EQ(map->getState(Eigen::Vector3f(0.0f, 0.0f, 1.0f)),
              planar_grid::SpaceState::FREE);
    EXPECT_EQ(map->getState(Eigen::Vector3f(0.0f, 0.0f, 3.0f)),
              planar_grid::SpaceState::UNKNOWN);
    // Outside the camera's view (x / z beyond 320 / 525): never seen.
    EXPECT_EQ(map->getState(Eigen::Vector3f(1.2f, 0.0f, 1.0f)),
              planar_grid::SpaceState::UNKNOWN);
  }

  // A real depth image (office1's depths at half resolution, NaN where the Kinect saw
  // nothing) in meters, from a 320 x 240 camera of f = 262.5 px, mapped by the pipeline
  // above (whose virtual camera is another): the same map as its cloud back-projected
  // through that camera, mapped with the pipeline's virtual camera set to it.
  const auto source = planar_grid::createFrameSource(config.input);
  planar_grid::Frame frame;
  source->load(0, frame);
  ASSERT_TRUE(frame.cloud && frame.cloud->isOrganized());
  ASSERT_EQ(frame.cloud->width, 640u);
  const planar_grid::PinholeView half{320, 240, 262.5, 262.5, 160.0, 120.0};
  cv::Mat depth(240, 320, CV_32FC1);
  planar_grid::Frame::Cloud cloud(320, 240);
  cloud.is_dense = false;
  std::size_t valid = 0;
  for (int v = 0; v < 240; ++v)
    for (int u = 0; u < 320; ++u) {
      const float z = frame.cloud->at(2 * u, 2 * v).z;
      depth.at<float>(v, u) = z;
      auto& p = cloud.at(u, v);
      p.intensity = 0.0f;
      if (std::isfinite(z) && z > 0.0f) {
        p.x = (static_cast<float>(u) - 160.0f) * z / 262.5f;
        p.y = (static_cast<float>(v) - 120.0f) * z / 262.5f;
        p.z = z;
        ++valid;
      } else {
        p.x = p.y = p.z = std::numeric_limits<float>::quiet_NaN();
      }
    }
  ASSERT_GT(valid, 25000u);
  planar_grid::Mapper from_depth(planar_grid::toMapperConfig(config));
  planar_grid::Mapper from_cloud(
    planar_grid::toMapperConfig(depthPipeline(320, 240, 262.5)));
  from_depth.integrateDepth(depth, half, frame.world_T_camera);
  from_cloud.integrateCloud(cloud, frame.world_T_camera);
  std::string a, b;
  from_depth.readMap()->serialize(a);
  from_cloud.readMap()->serialize(b);
  EXPECT_GT(from_depth.readMap()->getSurfaceLayer().getCuboidCount(), 10u);
  EXPECT_TRUE(a == b) << "the depth image's map differs from its cloud's";

  // Bad images and cameras are refused; so is a depth image on a stereo pipeline.
  expectThrowWith([&] { from_depth.integrateDepth(cv::Mat(), camera, pose); },
                  "the depth image is empty");
  expectThrowWith(
    [&] { from_depth.integrateDepth(cv::Mat(480, 640, CV_8UC1), camera, pose); },
    "must be CV_16UC1 (millimeters) or CV_32FC1 (meters)");
  expectThrowWith([&] { from_depth.integrateDepth(depth, camera, pose); },
                  "the depth image is 320 x 240 px, the camera 640 x 480 px");
  expectThrowWith(
    [&] {
      from_depth.integrateDepth(depth, planar_grid::PinholeView{320, 240, 0.0, 262.5},
                                pose);
    },
    "focal lengths must be positive");
  expectThrowWith(
    [&] {
      from_depth.integrateDepth(cv::Mat(480, 640, CV_32FC1, cv::Scalar(0.0f)), camera,
                                pose);
    },
    "no valid pixel");
  planar_grid::Mapper stereo(planar_grid::toMapperConfig(mainJob(1)));
  expectThrowWith([&] { stereo.integrateDepth(depth, camera, pose); },
                  "takes stereo pairs");
}

TEST_F(MapperTest, CallsFromTwoThreadsRunOneFrameAtATime)
{
  // Two threads integrate the same three frames at once, a third resets the map in
  // between: each call runs whole, so nothing crashes or deadlocks, and the map after
  // a reset and one more frame is that frame's map alone.
  const auto config = mainJob(3);
  std::vector<planar_grid::Frame> frames = loadFrames(config);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
  const auto integrate_all = [&] {
    for (const auto& frame : frames)
      mapper.integrateStereo(frame.left, frame.right, frame.calibration,
                             frame.world_T_camera);
  };
  std::thread a(integrate_all), b(integrate_all);
  a.join();
  b.join();
  EXPECT_EQ(mapper.getFrameCount(), 6u);
  EXPECT_EQ(mapper.getTrajectory().size(), 6u);

  std::atomic<bool> integrating{true};
  std::thread c([&] {
    integrate_all();
    integrating = false;
  });
  int resets = 0;
  while (integrating) {
    mapper.reset();
    ++resets;
    std::this_thread::sleep_for(std::chrono::milliseconds(50));
  }
  c.join();
  EXPECT_GE(resets, 1);
  EXPECT_LE(mapper.getFrameCount(), 3u);

  mapper.reset();
  mapper.integrateStereo(frames[0].left, frames[0].right, frames[0].calibration,
                         frames[0].world_T_camera);
  planar_grid::Mapper fresh(planar_grid::toMapperConfig(config));
  fresh.integrateStereo(frames[0].left, frames[0].right, frames[0].calibration,
                        frames[0].world_T_camera);
  std::string after_reset, alone;
  mapper.readMap()->serialize(after_reset);
  fresh.readMap()->serialize(alone);
  EXPECT_EQ(after_reset, alone);
}

TEST_F(MapperTest, ReadersInALoopDelayAFrameByAtMostTheReadsUnderWay)
{
  // Two reader threads whose reads (a query, then 30 ms holding the lock) overlap all
  // the time: the frame's map_integration waits only for the reads under way when it
  // comes, not for every read that starts while it waits.
  const auto config = mainJob(2);
  std::vector<planar_grid::Frame> frames = loadFrames(config);
  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
  std::atomic<bool> stop{false};
  const auto read_loop = [&] {
    const auto give_up = std::chrono::steady_clock::now() + std::chrono::seconds(60);
    while (!stop && std::chrono::steady_clock::now() < give_up) {
      const auto map = mapper.readMap();
      static_cast<void>(map->getState(Eigen::Vector3f(5.0f, 0.0f, 1.0f)));
      std::this_thread::sleep_for(std::chrono::milliseconds(30));
    }
  };
  std::thread r1(read_loop), r2(read_loop);
  std::vector<double> waits;
  for (const auto& frame : frames)
    waits.push_back(mapper
                      .integrateStereo(frame.left, frame.right, frame.calibration,
                                       frame.world_T_camera)
                      .lock_wait_ms);
  stop = true;
  r1.join();
  r2.join();
  // One 30 ms read under way, with a wide margin for a loaded machine; readers that
  // kept starting while the frame waited would hold it until they gave up (60 s).
  for (const double w : waits)
    EXPECT_LT(w, 1000.0);
}

TEST_F(MapperTest, ThePipelineRunnerDrivesAMapper)
{
  // Three frames of the main job run by a PipelineRunner, its two leading frame-local
  // stages (stereo_disparity, feature_matching) a frame or two ahead on the second
  // thread: every frame goes through the runner's Mapper, whose own sums then equal
  // the run's report, and a Mapper fed the same frames through the same engine calls
  // on one thread gives the same map file, byte for byte.
  const auto config = mainJob(3);
  planar_grid::PipelineRunner runner(config);
  ASSERT_EQ(runner.frameLocalPrefix(), 2u);
  const planar_grid::RunReport report = runner.run();
  ASSERT_EQ(report.frames, 3u);
  const planar_grid::Mapper& driven = runner.mapper();
  EXPECT_EQ(driven.getFrameCount(), 3u);
  EXPECT_EQ(driven.getTrajectory().size(), 3u);
  ASSERT_EQ(driven.getStageReports().size(), report.stages.size());
  for (std::size_t s = 0; s < report.stages.size(); ++s) {
    const auto& mapped = driven.getStageReports()[s];
    EXPECT_EQ(mapped.type, report.stages[s].type);
    EXPECT_EQ(mapped.frames, 3u) << mapped.type;
    EXPECT_EQ(mapped.points_in, report.stages[s].points_in) << mapped.type;
    EXPECT_EQ(mapped.points_out, report.stages[s].points_out) << mapped.type;
    EXPECT_EQ(mapped.counters, report.stages[s].counters) << mapped.type;
  }
  ASSERT_TRUE(driven.getMap());
  driven.getMap()->save((dir_ / "runner.pgmap").string());

  planar_grid::Mapper mapper(planar_grid::toMapperConfig(config),
                             planar_grid::Mapper::StageChecks::PIPELINE);
  ASSERT_EQ(mapper.getFrameLocalStageCount(), 2u);
  std::vector<planar_grid::Frame> frames = loadFrames(config);
  ASSERT_EQ(frames.size(), 3u);
  // The stages have not started: a frame is refused until reset().
  planar_grid::StageProgress refused;
  expectThrowWith([&] { mapper.integrateFrame(frames[0], refused, {}); },
                  "call reset() before the first frame");
  mapper.reset();
  std::vector<std::size_t> stages_seen;
  const planar_grid::Mapper::StageCallback record = [&](std::size_t s,
                                                        planar_grid::Frame&) {
    stages_seen.push_back(s);
  };
  for (std::size_t i = 0; i < frames.size(); ++i) {
    frames[i].sequence_number = i;
    planar_grid::StageProgress progress;
    // A stage that keeps state across frames never runs ahead.
    expectThrowWith([&] { mapper.prepareFrame(frames[i], 3, progress, record); },
                    "past the 2 leading frame-local stages");
    mapper.prepareFrame(frames[i], 2, progress, record);
    ASSERT_EQ(progress.stages.size(), 2u);
    EXPECT_EQ(progress.stages[0].type, "stereo_disparity");
    EXPECT_EQ(mapper.getFrameCount(), i) << "prepareFrame() counted the frame";
    mapper.integrateFrame(frames[i], progress, record);
    EXPECT_EQ(progress.stages.size(), config.stages.size());
    EXPECT_EQ(mapper.getFrameCount(), i + 1);
  }
  // Each stage ran once per frame, in order.
  ASSERT_EQ(stages_seen.size(), 3 * config.stages.size());
  for (std::size_t k = 0; k < stages_seen.size(); ++k)
    EXPECT_EQ(stages_seen[k], k % config.stages.size());
  mapper.save((dir_ / "mapper.pgmap").string());
  const std::string expected = fileBytes(dir_ / "runner.pgmap");
  EXPECT_GT(expected.size(), 10000u);
  EXPECT_TRUE(fileBytes(dir_ / "mapper.pgmap") == expected)
    << "the engine-fed mapper's map file differs from the runner's";
  ASSERT_EQ(mapper.getTrajectory().size(), 3u);
  for (std::size_t i = 0; i < 3; ++i)
    EXPECT_TRUE(mapper.getTrajectory()[i].matrix()
                == driven.getTrajectory()[i].matrix());
  // Stage finish() times, one per stage.
  EXPECT_EQ(mapper.finish().size(), config.stages.size());
}
