// SPDX-License-Identifier: BSD-3-Clause
// Inputs a mapping run meets on a robot, each with a clear error naming the
// file (IOError / ConfigError) or a documented result; the table is in
// docs/RELIABILITY.md.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/stereo/calibration_io.h>

#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <limits>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace fs = std::filesystem;
using planar_grid::parsePipelineConfig;
using planar_grid::PipelineRunner;

namespace {

/** A fresh temporary folder per test with PCD inputs written into it. */
class ReliabilityTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_reliability_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** A 1 m x 1 m wall of 21 x 21 points at z = 2 m (441 finite points), saved as
   * binary PCD. */
  static pcl::PointCloud<pcl::PointXYZ> wall()
  {
    pcl::PointCloud<pcl::PointXYZ> cloud;
    for (int i = 0; i <= 20; ++i)
      for (int j = 0; j <= 20; ++j)
        cloud.push_back(pcl::PointXYZ(0.05f * static_cast<float>(i),
                                      0.05f * static_cast<float>(j), 2.0f));
    return cloud;
  }

  std::string save(const std::string& name,
                   const pcl::PointCloud<pcl::PointXYZ>& cloud) const
  {
    const std::string path = (dir_ / name).string();
    EXPECT_EQ(pcl::io::savePCDFileBinary(path, cloud), 0);
    return path;
  }

  /** A config reading \a files (a YAML list body) through voxel_grid (0.1 m). */
  static std::string pcdConfig(const std::string& files, const std::string& poses = "")
  {
    return "input:\n  type: pcd_files\n  files: [" + files + "]\n" + poses
           + "pipeline:\n  - type: voxel_grid\n    params: {leaf_size_m: 0.1}\n";
  }

  /** The message of the planar_grid::Exception that running \a yaml throws ("" when
   * it runs). */
  static std::string runError(const std::string& yaml)
  {
    try {
      PipelineRunner runner(parsePipelineConfig(yaml, "t.yaml", "/"));
      runner.run();
    } catch (const planar_grid::Exception& e) {
      return e.what();
    }
    return "";
  }

  fs::path dir_;
};

/** The ConfigError of parsing \a yaml (fails the test when it parses). */
planar_grid::ConfigError
configErrorOf(const std::string& yaml)
{
  try {
    parsePipelineConfig(yaml, "t.yaml", "/");
  } catch (const planar_grid::ConfigError& e) {
    return e;
  }
  ADD_FAILURE() << "expected a ConfigError for:\n" << yaml;
  return planar_grid::ConfigError("", 0, 0, "");
}

} // namespace

TEST_F(ReliabilityTest, TruncatedPCDNamesTheFile)
{
  const std::string path = save("cut.pcd", wall());
  fs::resize_file(path, fs::file_size(path) / 2); // header intact, half of the data
  const std::string what = runError(pcdConfig(path));
  EXPECT_NE(what.find("cut.pcd"), std::string::npos) << what;
}

TEST_F(ReliabilityTest, CorruptPCDNamesTheFile)
{
  std::ofstream(dir_ / "garbage.pcd") << "# .PCD v0.7\nFIELDS x y z\nSIZE 4 4\n@@@\n";
  std::ofstream(dir_ / "empty_file.pcd");
  for (const char* name : {"garbage.pcd", "empty_file.pcd"}) {
    const std::string what = runError(pcdConfig((dir_ / name).string()));
    EXPECT_NE(what.find(name), std::string::npos) << what;
  }
}

namespace {

/** Runs \a yaml and returns each frame's Frame::no_points_stage ("" for a frame that
 * kept points). */
std::vector<std::string>
stagesFindingNoPoints(const std::string& yaml)
{
  PipelineRunner runner(parsePipelineConfig(yaml, "t.yaml", "/"));
  std::vector<std::string> stages;
  runner.setFrameCallback(
    [&stages](std::size_t, planar_grid::Frame& frame, const std::vector<double>&) {
      stages.push_back(frame.no_points_stage);
    });
  EXPECT_EQ(runner.run().frames, runner.frameCount());
  return stages;
}

} // namespace

TEST_F(ReliabilityTest, EmptyCloudIsPassedOnNamingTheStage)
{
  // A frame with no point adds nothing; the run goes on (an empty map is a result).
  EXPECT_EQ(stagesFindingNoPoints(
              pcdConfig(save("empty.pcd", pcl::PointCloud<pcl::PointXYZ>()))),
            std::vector<std::string>{"voxel_grid"});
}

TEST_F(ReliabilityTest, PosesFileMustHaveOnePosePerPCDFile)
{
  // Pose i belongs to the i-th file: with scan_1.pcd missing, the third pose would have
  // moved scan_2 to where scan_3 was taken. More or fewer poses than files are refused.
  const std::string a = save("scan_0.pcd", wall());
  const std::string b = save("scan_2.pcd", wall());
  std::ofstream(dir_ / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n"
                                       "1 0 0 1 0 1 0 0 0 0 1 0\n"
                                       "1 0 0 2 0 1 0 0 0 0 1 0\n";
  const std::string poses =
    "  poses: {format: kitti, file: " + (dir_ / "poses.txt").string() + "}\n";
  std::string what = runError(pcdConfig(a + ", " + b, poses));
  EXPECT_NE(what.find("poses.txt: has 3 poses, but there are 2 PCD files"),
            std::string::npos)
    << what;
  what = runError(pcdConfig(a, poses)); // one file
  EXPECT_NE(what.find("has 3 poses, but there are 1 PCD files"), std::string::npos)
    << what;
  save("scan_1.pcd", wall());
  EXPECT_EQ(runError(pcdConfig((dir_ / "scan_*.pcd").string(), poses)), "");
}

TEST_F(ReliabilityTest, NaNAndInfPointsAreDropped)
{
  // The wall plus 3 non-finite points (a PCD with is_dense false): voxel_grid keeps
  // the 11 x 11 voxels of the wall and nothing else (HugeCoordinatesDoNotCrash has the
  // same shape).
  auto cloud = wall();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  cloud.push_back(pcl::PointXYZ(nan, nan, nan));
  cloud.push_back(pcl::PointXYZ(inf, 0.0f, 1.0f));
  cloud.push_back(pcl::PointXYZ(0.0f, -inf, 1.0f));
  cloud.is_dense = false;
  PipelineRunner runner(
    parsePipelineConfig(pcdConfig(save("nan.pcd", cloud))
                          + "  - type: transform_to_world\n  - type: accumulate\n",
                        "t.yaml", "/"));
  const auto report = runner.run();
  ASSERT_GE(report.stages.size(), 1u);
  // The 3 non-finite points never reach the first stage: 441 finite ones do.
  EXPECT_EQ(report.stages[0].points_in, 441u);
  const auto& world = *runner.state().world_cloud;
  ASSERT_FALSE(world.empty());
  for (const auto& p : world)
    EXPECT_TRUE(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z));
}

TEST_F(ReliabilityTest, OnlyNonFinitePointsArePassedOnNamingTheStage)
{
  pcl::PointCloud<pcl::PointXYZ> cloud;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (int i = 0; i < 10; ++i)
    cloud.push_back(pcl::PointXYZ(nan, nan, nan));
  cloud.is_dense = false;
  EXPECT_EQ(stagesFindingNoPoints(pcdConfig(save("all_nan.pcd", cloud))),
            std::vector<std::string>{"voxel_grid"});
}

TEST_F(ReliabilityTest, HugeCoordinatesDoNotCrash)
{
  // Points 1e30 m away: too many voxels for VoxelGrid's integer indices. The run must
  // finish (PCL warns and passes the cloud through) or stop with a clear error; it
  // must never crash or allocate without bound.
  auto cloud = wall();
  cloud.push_back(pcl::PointXYZ(1e30f, -1e30f, 1e30f));
  cloud.push_back(pcl::PointXYZ(-3e38f, 3e38f, 0.0f));
  const std::string yaml = pcdConfig(save("huge.pcd", cloud))
                           + "  - type: transform_to_world\n  - type: accumulate\n";
  try {
    PipelineRunner runner(parsePipelineConfig(yaml, "t.yaml", "/"));
    runner.run();
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("huge.pcd"), std::string::npos) << e.what();
  }
}

TEST_F(ReliabilityTest, PCDFilesRunInNameOrderWithinAPattern)
{
  // Frames are the files sorted by name within each pattern, patterns in the order
  // given (config/example.yaml): with the VIEWPOINT x of a.pcd = 0 and of b.pcd = 5,
  // "*.pcd" runs a then b, and the list [b.pcd, a.pcd] runs b then a. The VIEWPOINT
  // is in PCL's y-up world, whose x (right) is the z-up world's -y.
  auto cloud = wall();
  save("a.pcd", cloud);
  cloud.sensor_origin_ = Eigen::Vector4f(5, 0, 0, 1);
  save("b.pcd", cloud);
  const std::string world = "  - type: transform_to_world\n";
  for (const auto& [files, first_x] :
       {std::pair<std::string, double>{(dir_ / "*.pcd").string(), 0.0},
        std::pair<std::string, double>{
          (dir_ / "b.pcd").string() + ", " + (dir_ / "a.pcd").string(), 5.0}}) {
    PipelineRunner runner(parsePipelineConfig(pcdConfig(files) + world, "t.yaml", "/"));
    runner.run();
    ASSERT_EQ(runner.trajectory().size(), 2u) << files;
    EXPECT_NEAR(runner.trajectory()[0].translation().y(), -first_x, 1e-6) << files;
    EXPECT_NEAR(runner.trajectory()[1].translation().y(), first_x - 5.0, 1e-6) << files;
  }
}

TEST_F(ReliabilityTest, RepeatedInputRunsEveryPassWithOffsetPoses)
{
  // input.repeat (the long-run test): 2 files x 3 passes = 6 frames in order, pass k's
  // poses offset by k x offset_m; a bad repeat block is a ConfigError at its line.
  auto cloud = wall();
  save("a.pcd", cloud);
  cloud.sensor_origin_ = Eigen::Vector4f(5, 0, 0, 1);
  save("b.pcd", cloud);
  const std::string input = "input:\n  type: pcd_files\n  files: ["
                            + (dir_ / "*.pcd").string()
                            + "]\n  repeat: {count: 3, offset_m: [0, 100, 0]}\n";
  PipelineRunner runner(parsePipelineConfig(
    input + "pipeline:\n  - type: transform_to_world\n", "t.yaml", "/"));
  ASSERT_EQ(runner.frameCount(), 6u);
  const auto report = runner.run();
  EXPECT_EQ(report.frames, 6u);
  ASSERT_EQ(runner.trajectory().size(), 6u);
  // b.pcd's VIEWPOINT x = 5 (PCL's y-up world) is the z-up world's y = -5.
  for (std::size_t i = 0; i < 6; ++i) {
    EXPECT_NEAR(runner.trajectory()[i].translation().x(), 0.0, 1e-6);
    EXPECT_NEAR(runner.trajectory()[i].translation().y(),
                (i % 2 == 0 ? 0.0 : -5.0) + 100.0 * static_cast<double>(i / 2), 1e-6);
  }
  // 20 memory samples at most, the last after the last frame.
  ASSERT_FALSE(report.rss_samples.empty());
  EXPECT_EQ(report.rss_samples.back().first, 5u);
  EXPECT_GT(report.peak_rss_bytes, 0u);
  const auto zero = configErrorOf(
    "input:\n  type: pcd_files\n  files: [a.pcd]\n  repeat: {count: 0}\n");
  EXPECT_EQ(zero.line(), 4) << zero.what();
  const auto offset = configErrorOf("input:\n  type: pcd_files\n  files: [a.pcd]\n  "
                                    "repeat: {count: 2, offset_m: [1, 2]}\n");
  EXPECT_EQ(offset.line(), 4) << offset.what();
}

TEST_F(ReliabilityTest, PoseFileShorterThanThePCDFilesIsAnError)
{
  save("a.pcd", wall());
  save("b.pcd", wall());
  std::ofstream(dir_ / "poses.txt") << "1 0 0 0 0 1 0 0 0 0 1 0\n"; // one pose, 2 files
  const std::string poses =
    "  poses: {format: kitti, file: " + (dir_ / "poses.txt").string() + "}\n";
  const std::string what = runError(pcdConfig((dir_ / "*.pcd").string(), poses));
  EXPECT_NE(what.find("poses.txt"), std::string::npos) << what;
  EXPECT_NE(what.find("1 poses"), std::string::npos) << what;
}

TEST_F(ReliabilityTest, MissingPCDFileNamesThePattern)
{
  const std::string what = runError(pcdConfig((dir_ / "none_*.pcd").string()));
  EXPECT_NE(what.find("none_*.pcd"), std::string::npos) << what;
}

TEST(ReliabilityConfig, AbsurdValuesAreErrorsAtTheirLine)
{
  const std::string head = "input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n";
  // Each value sits on line 7 of head + the stage.
  for (const char* stage : {
         "  - type: voxel_grid\n    params:\n      leaf_size_m: 1e9\n",
         "  - type: voxel_grid\n    params:\n      leaf_size_m: .nan\n",
         "  - type: voxel_grid\n    params:\n      leaf_size_m: -.inf\n",
         "  - type: voxel_grid\n    params:\n      leaf_size_m: 0\n",
         "  - type: voxel_grid\n    params:\n      leaf_size_m: [0.1]\n",
         "  - type: voxel_grid\n    params:\n      min_points_per_voxel: -1\n",
         "  - type: voxel_grid\n    params:\n      min_points_per_voxel: 1e12\n",
         "  - type: voxel_grid\n    params:\n      min_points_per_voxel: 99999999999\n",
         "  - type: voxel_grid\n    params:\n      leaf_size_m: true\n",
       }) {
    const auto e = configErrorOf(head + std::string(stage));
    EXPECT_EQ(e.line(), 7) << stage << e.what();
    EXPECT_NE(std::string(e.what()).find("t.yaml:7:"), std::string::npos) << e.what();
  }
}

TEST(ReliabilityConfig, NonScalarKeysAreConfigErrors)
{
  // Found by fuzz_pipeline_config: a key that is a list or a map made yaml-cpp's
  // conversion throw YAML::TypedBadConversion out of the loader. Now a ConfigError at
  // the key, at the top level, in a block and among a stage's parameters.
  const auto top = configErrorOf("? [a, b]\n: 1\n");
  EXPECT_EQ(top.line(), 1) << top.what();
  EXPECT_NE(std::string(top.what()).find("plain name"), std::string::npos)
    << top.what();
  const auto input = configErrorOf("input:\n  ? {x: 1}\n  : pcd_files\n");
  EXPECT_EQ(input.line(), 2) << input.what();
  const auto params = configErrorOf(
    "input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n  - type: voxel_grid\n"
    "    params:\n      ? [leaf_size_m]\n      : 0.1\n");
  EXPECT_EQ(params.line(), 7) << params.what();
  // The fuzzer's input itself (tests/fuzz/corpus/fuzz_pipeline_config/).
  std::ifstream in(
    std::string(PLANAR_GRID_SOURCE_DIR)
    + "/tests/fuzz/corpus/fuzz_pipeline_config/crash_non_scalar_key.yaml");
  const std::string text((std::istreambuf_iterator<char>(in)),
                         std::istreambuf_iterator<char>());
  ASSERT_FALSE(text.empty());
  EXPECT_THROW(parsePipelineConfig(text, "crash.yaml", "/"), planar_grid::ConfigError);
}

TEST(ReliabilityConfig, DuplicateKeyIsAnError)
{
  // yaml-cpp keeps one of two equal keys silently; the strict loader must not.
  const std::string yaml = "input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n"
                           "  - type: voxel_grid\n    params:\n"
                           "      leaf_size_m: 0.1\n      leaf_size_m: 0.2\n";
  const auto e = configErrorOf(yaml);
  EXPECT_NE(std::string(e.what()).find("leaf_size_m"), std::string::npos) << e.what();
  EXPECT_EQ(e.line(), 8) << e.what();
  // The same in a section of the file.
  const auto f = configErrorOf("input:\n  type: pcd_files\n  files: [a.pcd]\n"
                               "  files: [b.pcd]\npipeline:\n  - type: voxel_grid\n");
  EXPECT_NE(std::string(f.what()).find("twice"), std::string::npos) << f.what();
}

TEST(ReliabilityConfig, WrongTypesForBlocksAreErrors)
{
  for (const std::string& yaml : {
         std::string("input: 5\npipeline:\n  - type: voxel_grid\n"),
         std::string("input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n"
                     "  type: voxel_grid\n"),
         std::string("input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n"
                     "  - voxel_grid\n"),
         std::string("input:\n  type: pcd_files\n  files: [a.pcd]\npipeline:\n"
                     "  - type: voxel_grid\n    params: 0.1\n"),
         std::string("[1, 2]\n"),
         std::string("just text\n"),
       }) {
    const auto e = configErrorOf(yaml);
    EXPECT_GT(e.line(), 0) << yaml << e.what();
  }
}

namespace {

/** EuRoC sensor.yaml files derived from the real left camera's, in a temporary folder.
 */
class ReliabilityCalibration : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ = fs::temp_directory_path()
           / ("planar_grid_reliability_calibration_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
    std::ifstream in(std::string(PLANAR_GRID_DATA_DIR)
                     + "/euroc_v1_01_pairs/sensorLeft.yaml");
    left_text_.assign(std::istreambuf_iterator<char>(in),
                      std::istreambuf_iterator<char>());
    ASSERT_FALSE(left_text_.empty());
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** The left camera's file with \a from replaced by \a to, saved as \a name. */
  std::string
  variant(const std::string& name, const std::string& from, const std::string& to) const
  {
    std::string text = left_text_;
    const auto at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    if (at != std::string::npos)
      text.replace(at, from.size(), to);
    const std::string path = (dir_ / name).string();
    std::ofstream(path) << text;
    return path;
  }

  /** The IOError message of loading the EuRoC pair (fails the test when it loads). */
  static std::string errorOf(const std::string& left, const std::string& right)
  {
    try {
      planar_grid::loadStereoCalibration(planar_grid::CalibrationFormat::EUROC, left,
                                         right);
    } catch (const planar_grid::IOError& e) {
      return e.what();
    }
    ADD_FAILURE() << "expected an IOError for " << left << ", " << right;
    return "";
  }

  fs::path dir_;
  std::string left_text_;
};

} // namespace

TEST_F(ReliabilityCalibration, EuRoCPairWithZeroBaselineIsAnIOError)
{
  // Both cameras at one place (found by fuzz_calibration: OpenCV's stereoRectify
  // asserted and a cv::Exception escaped).
  const std::string left = variant("left.yaml", "camera_id", "camera_id");
  const std::string what = errorOf(left, left);
  EXPECT_NE(what.find("left.yaml"), std::string::npos) << what;
  EXPECT_NE(what.find("baseline"), std::string::npos) << what;
}

TEST_F(ReliabilityCalibration, EuRoCFileThatIsNotAYamlMapIsAnIOError)
{
  // Found by fuzz_calibration: a file whose top level is a scalar (a stray first line)
  // made yaml-cpp throw on the first field lookup, and the exception ended the process.
  const std::string right =
    std::string(PLANAR_GRID_DATA_DIR) + "/euroc_v1_01_pairs/sensorRight.yaml";
  for (const char* text : {"just a sentence\n", "- 1\n- 2\n"}) {
    const std::string left = (dir_ / "not_a_map.yaml").string();
    std::ofstream(left) << text;
    const std::string what = errorOf(left, right);
    EXPECT_NE(what.find("not_a_map.yaml: not a YAML map"), std::string::npos) << what;
  }
}

TEST_F(ReliabilityCalibration, EuRoCNonFiniteOrHugeValuesAreIOErrors)
{
  const std::string right =
    std::string(PLANAR_GRID_DATA_DIR) + "/euroc_v1_01_pairs/sensorRight.yaml";
  EXPECT_NE(errorOf(variant("nan.yaml", "458.654", ".nan"), right).find("non-finite"),
            std::string::npos);
  EXPECT_NE(
    errorOf(variant("inf.yaml", "0.999557249008", ".inf"), right).find("non-finite"),
    std::string::npos);
  EXPECT_NE(errorOf(variant("huge.yaml", "[752, 480]", "[752000000, 480]"), right)
              .find("resolution"),
            std::string::npos);
  EXPECT_NE(errorOf(variant("zero_focal.yaml", "458.654", "0"), right).find("focal"),
            std::string::npos);
}

namespace {

/** Replaces the first \a from in the file at \a path by \a to (header edits). */
void
replaceInFile(const std::string& path, const std::string& from, const std::string& to)
{
  std::ifstream in(path, std::ios::binary);
  std::string bytes((std::istreambuf_iterator<char>(in)),
                    std::istreambuf_iterator<char>());
  in.close();
  const auto at = bytes.find(from);
  ASSERT_NE(at, std::string::npos) << from;
  bytes.replace(at, from.size(), to);
  std::ofstream(path, std::ios::binary | std::ios::trunc) << bytes;
}

} // namespace

TEST_F(ReliabilityTest, PCDDeclaringFewerPointsThanItHoldsIsRefused)
{
  // 441 points written; the header says 400 (PCL would read 400 and drop the rest).
  const std::string binary = save("binary.pcd", wall());
  const std::string ascii = (dir_ / "ascii.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileASCII(ascii, wall()), 0);
  for (const std::string& path : {binary, ascii}) {
    replaceInFile(path, "WIDTH 441", "WIDTH 400");
    replaceInFile(path, "POINTS 441", "POINTS 400");
  }
  std::string what = runError(pcdConfig(binary));
  EXPECT_NE(
    what.find("binary.pcd: the binary data hold 441 points of 12 bytes, but the "
              "header declares 400 points"),
    std::string::npos)
    << what;
  what = runError(pcdConfig(ascii));
  EXPECT_NE(what.find("ascii.pcd: the ASCII data hold 441 points (lines), but the "
                      "header declares 400 points"),
            std::string::npos)
    << what;
  // And more declared than held: truncated, before PCL sizes its buffer.
  replaceInFile(ascii, "WIDTH 400", "WIDTH 900");
  replaceInFile(ascii, "POINTS 400", "POINTS 900");
  what = runError(pcdConfig(ascii));
  EXPECT_NE(what.find("the file is truncated"), std::string::npos) << what;
}

TEST_F(ReliabilityTest, PCDWithoutXYZIsRefused)
{
  // Colour only: PCL would place every point at the origin.
  const fs::path path = dir_ / "rgba_only.pcd";
  std::ofstream(path)
    << "# .PCD v0.7\nVERSION 0.7\nFIELDS rgba\nSIZE 4\nTYPE U\nCOUNT 1\n"
       "WIDTH 2\nHEIGHT 1\nVIEWPOINT 0 0 0 1 0 0 0\nPOINTS 2\n"
       "DATA ascii\n4278190335\n4278255360\n";
  const std::string what = runError(pcdConfig(path.string()));
  EXPECT_NE(what.find("rgba_only.pcd: has no x, y, z fields (its fields: rgba)"),
            std::string::npos)
    << what;
}

TEST_F(ReliabilityTest, NonFiniteViewpointIsRefusedNamingTheFile)
{
  const std::string path = save("nan_viewpoint.pcd", wall());
  replaceInFile(path, "VIEWPOINT 0 0 0 1 0 0 0", "VIEWPOINT nan 0 0 1 0 0 0");
  // As a frame, and as the pose of a frame (PCL's reader took it as the identity).
  for (const std::string poses : {"", "  poses: {format: viewpoint}\n"}) {
    const std::string what = runError(pcdConfig(path, poses));
    EXPECT_NE(what.find("nan_viewpoint.pcd: VIEWPOINT 'nan 0 0 1 0 0 0' is not a valid "
                        "pose: 'nan' is not a finite number"),
              std::string::npos)
      << what;
  }
}

TEST_F(ReliabilityTest, CorruptCompressedSizesAreRefusedBeforePCLAllocates)
{
  // A compressed PCD whose header and uncompressed size agree on 100 million points
  // (1.2 GB) while the file holds a few hundred compressed bytes: PCL would allocate
  // the 1.2 GB first.
  const std::string path = (dir_ / "huge.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileBinaryCompressed(path, wall()), 0);
  replaceInFile(path, "WIDTH 441", "WIDTH 100000000");
  replaceInFile(path, "POINTS 441", "POINTS 100000000");
  {
    std::fstream file(path, std::ios::in | std::ios::out | std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(file)),
                      std::istreambuf_iterator<char>());
    const std::string data_line = "DATA binary_compressed\n";
    const auto data = bytes.find(data_line) + data_line.size();
    const std::uint32_t unpacked = 1200000000u; // 100 million points of 12 bytes
    file.seekp(static_cast<std::streamoff>(data + 4));
    file.write(reinterpret_cast<const char*>(&unpacked), 4);
  }
  // Refused from the header, before PCL's header reader allocates the declared points.
  const std::string what = runError(pcdConfig(path));
  EXPECT_NE(what.find("huge.pcd: the header declares more points (POINTS '100000000', "
                      "WIDTH '100000000', HEIGHT '1') than a file of"),
            std::string::npos)
    << what;
}

TEST_F(ReliabilityTest, FilterStagesDoNotKeepTheirInputCloud)
{
  // A filter that kept its input alive until the next frame held one whole cloud per
  // listed stage: a generated file listing thousands of filters grew by a cloud per
  // stage.
  const auto config = parsePipelineConfig(
    "input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n  - type: voxel_grid\n"
    "  - type: statistical_outlier_removal\n",
    "t.yaml", "/");
  for (const auto& sc : config.stages) {
    const auto stage = planar_grid::findStage(sc.type)->create(sc.params);
    planar_grid::Frame frame;
    frame.cloud.reset(new planar_grid::Frame::Cloud);
    pcl::copyPointCloud(wall(), *frame.cloud);
    const std::weak_ptr<const planar_grid::Frame::Cloud> input = frame.cloud;
    planar_grid::PipelineState state;
    stage->process(frame, state);
    EXPECT_GT(frame.cloud->size(), 0u) << sc.type;
    EXPECT_TRUE(input.expired()) << sc.type << " keeps its input cloud";
  }
}

TEST_F(ReliabilityTest, ResumeWithAnotherRangeStartIsRefused)
{
  for (const char* name : {"a.pcd", "b.pcd", "c.pcd"})
    save(name, wall());
  std::ofstream(dir_ / "poses.txt")
    << "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 1 0 1 0 0 0 0 1 0\n"
       "1 0 0 2 0 1 0 0 0 0 1 0\n";
  const auto config = parsePipelineConfig(
    pcdConfig((dir_ / "*.pcd").string(), "  poses: {format: kitti, file: "
                                           + (dir_ / "poses.txt").string() + "}\n"),
    "t.yaml", "/");
  const std::string checkpoint = (dir_ / "checkpoint.pgck").string();
  {
    PipelineRunner runner(config);
    runner.setFrameRange(1, 2);
    runner.setCheckpoint(checkpoint, 1);
    runner.run();
  }
  // The checkpoint's run started at frame 1: a range from 0 would report 0:3 and map
  // 1:3.
  PipelineRunner other(config);
  other.setFrameRange(0, 3);
  try {
    other.resumeFrom(checkpoint);
    ADD_FAILURE() << "no exception";
  } catch (const planar_grid::IOError& e) {
    EXPECT_NE(
      std::string(e.what()).find(
        "checkpoint.pgck: written by a run that started at frame position 1, "
        "but this run's range starts at 0: resume with the range it was written "
        "with (--frames 1:END)"),
      std::string::npos)
      << e.what();
  }
  // The same start, a later end: the run continues.
  PipelineRunner longer(config);
  longer.setFrameRange(1, 3);
  EXPECT_EQ(longer.resumeFrom(checkpoint), 2u);
  EXPECT_EQ(longer.run().frames, 2u);
}

TEST_F(ReliabilityTest, PCDHeaderPCLCannotReadIsAnIOErrorNamingTheFile)
{
  // Found by fuzz_pcd_frame: PCL's header reader allocated the declared points' bytes
  // (std::length_error, or gigabytes), and indexed the SIZE list by the FIELDS
  // (std::out_of_range); both escaped as exceptions naming no file.
  const fs::path huge = dir_ / "huge_points.pcd";
  std::ofstream(huge)
    << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\nCOUNT 1 1 1\n"
       "WIDTH 999999999999\nHEIGHT 1\nPOINTS 999999999999\n"
       "DATA ascii\n0 0 1\n";
  std::string what = runError(pcdConfig(huge.string()));
  EXPECT_NE(what.find("huge_points.pcd: the header declares more points"),
            std::string::npos)
    << what;
  const fs::path short_size = dir_ / "short_size.pcd";
  std::ofstream(short_size) << "VERSION 0.7\nFIELDS x y z\nSIZE 4\nTYPE F F F\n"
                               "COUNT 1 1 1\nWIDTH 1\nHEIGHT 1\nPOINTS 1\nDATA ascii\n"
                               "0 0 1\n";
  what = runError(pcdConfig(short_size.string()));
  EXPECT_NE(what.find("short_size.pcd: "), std::string::npos) << what;
}

TEST_F(ReliabilityTest, PCDLayoutLineAfterPointsIsAnIOErrorBeforePCLReadsIt)
{
  // Found by fuzz_pcd_frame (ASan's allocator found its chunk headers overwritten;
  // valgrind names the write): PCL's header reader sizes the points' buffer at POINTS,
  // and a COUNT or SIZE line after it grows the point, so that its ASCII reader wrote
  // the points past that buffer (a heap overflow inside libpcl_io).
  const std::string head = "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                           "COUNT 1 1 1\nWIDTH 2\nHEIGHT 1\nPOINTS 2\n";
  const fs::path count_after = dir_ / "count_after_points.pcd";
  std::ofstream(count_after) << head << "COUNT 1 1 2\nDATA ascii\n0 0 0 1\n0 0 0 1\n";
  std::string what = runError(pcdConfig(count_after.string()));
  EXPECT_NE(
    what.find("count_after_points.pcd: its header has a COUNT line after POINTS"),
    std::string::npos)
    << what;
  const fs::path size_after = dir_ / "size_after_points.pcd";
  std::ofstream(size_after) << head << "SIZE 4 4 8\nDATA ascii\n0 0 0\n0 0 0\n";
  EXPECT_THROW(planar_grid::checkPCDFile(size_after.string()), planar_grid::IOError);
  // The same points with the header in the PCD order are read.
  const fs::path ordered = dir_ / "ordered.pcd";
  std::ofstream(ordered) << "VERSION 0.7\nFIELDS x y z\nSIZE 4 4 4\nTYPE F F F\n"
                            "COUNT 1 1 2\nWIDTH 2\nHEIGHT 1\nPOINTS 2\nDATA ascii\n"
                            "0 0 0 1\n0 0 0 1\n";
  EXPECT_EQ(planar_grid::checkPCDFile(ordered.string()).points, 2u);
}

TEST_F(ReliabilityTest, PCDDataPCLReadsShortOfItsHeightIsAnIOErrorNamingTheFile)
{
  // Found by fuzz_pcd_frame: an organized ASCII file (WIDTH 4, HEIGHT 2) whose header
  // lines repeat inside the data. PCL's reader kept fewer points than width x height
  // said, and the conversion to points read past its data (heap-buffer-overflow).
  const fs::path bad = dir_ / "short_rows.pcd";
  fs::copy_file(std::string(PLANAR_GRID_SOURCE_DIR)
                  + "/tests/fuzz/corpus/fuzz_pcd_frame/"
                    "crash_ascii_rows_short_of_height.pcd",
                bad);
  const std::string what = runError(pcdConfig(bad.string()));
  EXPECT_NE(what.find("short_rows.pcd: "), std::string::npos) << what;
}
