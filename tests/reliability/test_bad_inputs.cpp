// SPDX-License-Identifier: BSD-3-Clause
// Inputs (and output names) of the pipeline tool that used to be mapped silently,
// wrongly or failed late: each is refused with an error naming the file and the cause,
// before the first frame where that can be known, and the tool exits non-zero without
// writing outputs; or, when the input is valid (PCD coordinates that are not floats),
// it is read correctly.
// The table is in docs/RELIABILITY.md.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>
#include <planar_grid/stereo/calibration_io.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <sys/stat.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <functional>
#include <iterator>
#include <string>
#include <vector>

#include "karlsruhe_job.h"

namespace fs = std::filesystem;

namespace {

/** The exit code and the merged stdout and stderr of one tool run. */
struct ToolRun {
  int exit_code{-1};
  std::string output;
};

/** A temporary folder per test holding a small synthetic rectified stereo sequence:
 * random texture, the right image the left one shifted by 4 px, a Karlsruhe-format
 * calibration (f = 100 px, principal point at the image centre, B = 0.5 m). */
class BadStereoInputTest : public ::testing::Test {
protected:
  static constexpr int WIDTH = 96;
  static constexpr int HEIGHT = 64;

  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_bad_inputs_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_ / "left");
    fs::create_directories(dir_ / "right");
    writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0",
                     "100 0 48 -50 0 100 32 0 0 0 1 0");
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** Writes calib.txt with the rows P1_roi: \a left and P2_roi: \a right. */
  void writeCalibration(const std::string& left, const std::string& right) const
  {
    std::ofstream(dir_ / "calib.txt")
      << "P1_roi: " << left << "\nP2_roi: " << right << "\n";
  }

  static std::string leftName(int index)
  {
    std::array<char, 32> name{};
    std::snprintf(name.data(), name.size(), "I1_%06d.png", index);
    return name.data();
  }

  static std::string rightName(int index)
  {
    std::array<char, 32> name{};
    std::snprintf(name.data(), name.size(), "I2_%06d.png", index);
    return name.data();
  }

  /** Writes the pairs 0 .. \a count - 1, \a width x \a height pixels (seeded texture).
   */
  void writePairs(int count, int width = WIDTH, int height = HEIGHT) const
  {
    for (int i = 0; i < count; ++i)
      writePair(i, width, height, width, height);
  }

  /** Writes pair \a index, the left image \a lw x \a lh and the right \a rw x \a rh. */
  void writePair(int index, int lw, int lh, int rw, int rh) const
  {
    cv::Mat texture(std::max(lh, rh), std::max(lw, rw) + 4, CV_8UC1);
    cv::RNG rng(static_cast<std::uint64_t>(index + 1));
    rng.fill(texture, cv::RNG::UNIFORM, 0, 256);
    ASSERT_TRUE(cv::imwrite((dir_ / "left" / leftName(index)).string(),
                            texture(cv::Rect(4, 0, lw, lh))));
    ASSERT_TRUE(cv::imwrite((dir_ / "right" / rightName(index)).string(),
                            texture(cv::Rect(0, 0, rw, rh))));
  }

  /** A stereo configuration of the sequence in dir_ through stereo_disparity, outputs
   * in dir_/out. */
  std::string config(int frame_count = 0) const
  {
    return "input:\n  type: stereo_sequence\n  left_images: " + (dir_ / "left").string()
           + "/I1_%06d.png\n  right_images: " + (dir_ / "right").string()
           + "/I2_%06d.png\n  frame_count: " + std::to_string(frame_count)
           + "\n  calibration: {format: karlsruhe, file: "
           + (dir_ / "calib.txt").string()
           + "}\npipeline:\n  - type: stereo_disparity\n"
             "    params: {num_disparities_px: 16, max_range_m: 30.0}\n"
             "output:\n  folder: "
           + (dir_ / "out").string() + "\n";
  }

  /** The message of the planar_grid::Exception that creating a runner for \a yaml
   * throws ("" when none): the runner reads no frame before run(). */
  static std::string setupError(const std::string& yaml)
  {
    try {
      planar_grid::PipelineRunner runner(
        planar_grid::parsePipelineConfig(yaml, "t.yaml", "/"));
    } catch (const planar_grid::Exception& e) {
      return e.what();
    }
    return "";
  }

  /** Runs planar_grid_pipeline on \a yaml (written to dir_/run.yaml) with \a args. */
  ToolRun runTool(const std::string& yaml,
                  const std::string& args = "",
                  const std::string& environment = "") const
  {
    const fs::path path = dir_ / "run.yaml";
    std::ofstream(path) << yaml;
    const std::string command =
      environment + " " + std::string(PLANAR_GRID_PIPELINE_TOOL) + " --config '"
      + path.string() + "' --no-snapshot --sequential " + args + " 2>&1";
    ToolRun run;
    std::fflush(nullptr);
    FILE* pipe = ::popen(command.c_str(), "r");
    if (!pipe) {
      ADD_FAILURE() << "cannot start " << command;
      return run;
    }
    std::array<char, 4096> buffer{};
    std::size_t n = 0;
    while ((n = std::fread(buffer.data(), 1, buffer.size(), pipe)) > 0)
      run.output.append(buffer.data(), n);
    const int status = ::pclose(pipe);
    run.exit_code = WIFEXITED(status) ? WEXITSTATUS(status) : 128;
    return run;
  }

  /** True when the tool wrote nothing into dir_/out (no folder, or an empty one but for
   * the run lock). */
  bool noOutputs() const
  {
    if (!fs::exists(dir_ / "out"))
      return true;
    for (const auto& entry : fs::directory_iterator(dir_ / "out"))
      if (entry.path().filename().string().find("lock") == std::string::npos)
        return false;
    return true;
  }

  fs::path dir_;
};

#define EXPECT_CONTAINS(text, part)                          \
  EXPECT_NE(std::string(text).find(part), std::string::npos) \
    << "expected '" << (part) << "' in: " << (text)

} // namespace

TEST_F(BadStereoInputTest, LeftImageMissingInTheMiddleIsRefusedBeforeTheFirstFrame)
{
  // Frames 0-5 with the left image of frame 3 removed: "every frame present" would
  // have mapped frames 0-2 and ended there.
  writePairs(6);
  fs::remove(dir_ / "left" / leftName(3));
  const std::string what = setupError(config(0));
  EXPECT_CONTAINS(what, leftName(3));
  EXPECT_CONTAINS(what, "not found");
  EXPECT_CONTAINS(what, leftName(5)); // where the sequence goes on to
  // With a frame count the same image is named.
  EXPECT_CONTAINS(setupError(config(6)), leftName(3));
  // Without the gap the sequence loads: 6 frames.
  writePair(3, WIDTH, HEIGHT, WIDTH, HEIGHT);
  EXPECT_EQ(setupError(config(0)), "");
}

TEST_F(BadStereoInputTest, RightImageMissingIsRefusedBeforeTheFirstFrame)
{
  writePairs(5);
  fs::remove(dir_ / "right" / rightName(2));
  for (const int frame_count : {0, 5}) {
    const std::string what = setupError(config(frame_count));
    EXPECT_CONTAINS(what, rightName(2));
    EXPECT_CONTAINS(what, "right image not found");
  }
}

TEST_F(BadStereoInputTest, ImageThatIsAPipeFolderOrEmptyIsRefusedBeforeTheFirstFrame)
{
  // A pipe would block the reader for ever; a folder or an empty file is no image.
  writePairs(5);
  const fs::path image = dir_ / "right" / rightName(3);
  const std::vector<std::pair<std::function<void()>, std::string>> cases = {
    {[&image] { ASSERT_EQ(::mkfifo(image.c_str(), 0600), 0); },
     "is not a regular file (a device, pipe or socket)"},
    {[&image] { fs::create_directory(image); }, "is a folder, not a file"},
    {[&image] { std::ofstream(image).close(); }, "is empty (0 bytes)"}};
  for (const auto& [make, cause] : cases) {
    fs::remove(image);
    make();
    const std::string what = setupError(config(0));
    EXPECT_CONTAINS(what, image.string() + ": the right image " + cause);
  }
  const ToolRun run = runTool(config(0));
  EXPECT_EQ(run.exit_code, 4) << run.output;
  EXPECT_TRUE(noOutputs()) << run.output;
}

TEST_F(BadStereoInputTest, FramesWithoutPointsAreWarnedAboutAndTheRunCompletes)
{
  // Dark pairs (a lens cap, a tunnel) give no disparity, so no points: each such
  // frame is named once, adds nothing, and the run writes its outputs. Frame 2 is
  // dark first, then every frame.
  std::string yaml = config(0);
  yaml.replace(yaml.find("output:"), 0,
               "  - type: voxel_grid\n    params: {leaf_size_m: 0.05}\n"
               "  - type: statistical_outlier_removal\n");
  yaml += "  report: report.json\n";
  writePairs(5);
  const auto darken = [this](int index) {
    const cv::Mat dark = cv::Mat::zeros(HEIGHT, WIDTH, CV_8UC1);
    ASSERT_TRUE(cv::imwrite((dir_ / "left" / leftName(index)).string(), dark));
    ASSERT_TRUE(cv::imwrite((dir_ / "right" / rightName(index)).string(), dark));
  };
  darken(2);
  // In the sanitizer build LeakSanitizer's tracer crashes at this run's exit (the
  // stereo matcher's worker threads still winding down; scripts/run_tests.sh) and turns
  // exit 0 into 1: the status is what this test checks, so the tool runs without the
  // leak check here (the library's leak check is in the in-process tests).
  const std::string no_leak_check = "ASAN_OPTIONS=detect_leaks=0";
  ToolRun run = runTool(yaml, "", no_leak_check);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "frame " + leftName(2)
                                + " (2): no points reached stage 'voxel_grid'");
  EXPECT_EQ(run.output.find("frame " + leftName(1) + " (1): no points"),
            std::string::npos)
    << run.output;
  EXPECT_EQ(run.output.find("'statistical_outlier_removal'; the frame"),
            std::string::npos)
    << run.output; // once per frame
  ASSERT_TRUE(fs::exists(dir_ / "out" / "report.json")) << run.output;
  for (int i = 0; i < 5; ++i)
    darken(i);
  run = runTool(yaml, "", no_leak_check);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "frame " + leftName(4) + " (4): no points");
  std::ifstream report(dir_ / "out" / "report.json");
  const std::string text((std::istreambuf_iterator<char>(report)),
                         std::istreambuf_iterator<char>());
  EXPECT_CONTAINS(text, "\"frames\": 5");
}

TEST_F(BadStereoInputTest, ToolExitsNonZeroOnAGapAndWritesNothing)
{
  writePairs(6);
  fs::remove(dir_ / "left" / leftName(3));
  const ToolRun run = runTool(config(0));
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, leftName(3));
  EXPECT_TRUE(noOutputs()) << run.output;
}

TEST_F(BadStereoInputTest, FirstFrameOfAnotherSizeIsRefusedBeforeTheRun)
{
  // The first pair's right image is 100x64, its left 96x64.
  writePairs(3);
  writePair(0, WIDTH, HEIGHT, 100, HEIGHT);
  const std::string what = setupError(config(0));
  EXPECT_CONTAINS(what, rightName(0));
  EXPECT_CONTAINS(what, "100x64");
  EXPECT_CONTAINS(what, "96x64");
  const ToolRun run = runTool(config(0));
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, rightName(0));
  EXPECT_TRUE(noOutputs()) << run.output;
}

TEST_F(BadStereoInputTest, LaterFrameOfAnotherSizeIsRefusedWhenRead)
{
  // Frames 0-3 at 96x64, frame 2 at 96x80 (both images): Karlsruhe rows give no image
  // size, so the first frame's is the size of every frame.
  writePairs(4);
  writePair(2, WIDTH, 80, WIDTH, 80);
  const ToolRun run = runTool(config(0));
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, leftName(2)
                                + ": size 96x80 px differs from the first "
                                  "frame's");
  EXPECT_CONTAINS(run.output, "96x64");
  EXPECT_TRUE(noOutputs()) << run.output;
}

TEST_F(BadStereoInputTest, PrincipalPointOutsideTheImagesIsRefused)
{
  // The calibration's cx = 480 px does not fit 96 px wide images: not the images the
  // calibration was made for.
  writePairs(2);
  writeCalibration("100 0 480 0 0 100 32 0 0 0 1 0",
                   "100 0 480 -50 0 100 32 0 0 0 1 0");
  const std::string what = setupError(config(0));
  EXPECT_CONTAINS(what, leftName(0));
  EXPECT_CONTAINS(what, "principal point");
}

TEST_F(BadStereoInputTest, ImagesNotTheCalibrationsSizeAreRefused)
{
  // The indoor pair's ROS camera_info files say 640x480; the images are 96x64.
  writePairs(2);
  const std::string data = std::string(PLANAR_GRID_DATA_DIR) + "/rtabmap_stereo_rect/";
  std::string yaml = config(0);
  const std::string karlsruhe =
    "{format: karlsruhe, file: " + (dir_ / "calib.txt").string() + "}";
  yaml.replace(yaml.find(karlsruhe), karlsruhe.size(),
               "{format: ros_camera_info, file: " + data
                 + "stereo_left.yaml, right_file: " + data + "stereo_right.yaml}");
  const std::string what = setupError(yaml);
  EXPECT_CONTAINS(what, leftName(0) + ": size 96x64 px differs from the calibration's");
  EXPECT_CONTAINS(what, "640x480");
}

namespace {

/** The IOError message of loading a calibration (fails the test when it loads). */
std::string
calibrationError(planar_grid::CalibrationFormat format,
                 const std::string& path,
                 const std::string& right_path = "")
{
  try {
    planar_grid::loadStereoCalibration(format, path, right_path);
  } catch (const planar_grid::IOError& e) {
    return e.what();
  }
  ADD_FAILURE() << "expected an IOError for " << path;
  return "";
}

} // namespace

TEST_F(BadStereoInputTest, RealCalibrationsOfEveryFormatStillLoad)
{
  using planar_grid::CalibrationFormat;
  const std::string data = std::string(PLANAR_GRID_DATA_DIR) + "/";
  // Karlsruhe: f = 645.2401 px, B = 368.2632 / 645.2401 m (the data's README).
  const auto karlsruhe = planar_grid::loadStereoCalibration(
    CalibrationFormat::KARLSRUHE, data + "karlsruhe_2010_03_09_drive_0023/calib.txt");
  EXPECT_NEAR(karlsruhe.calibration.focal_length_px, 645.2401, 1e-9);
  EXPECT_NEAR(karlsruhe.calibration.baseline_m, 368.2632 / 645.2401, 1e-9);
  const auto kitti = planar_grid::loadStereoCalibration(
    CalibrationFormat::KITTI, data + "kitti_odometry_snippet_2/calib.txt");
  EXPECT_NEAR(kitti.calibration.baseline_m, 386.1448 / 718.856, 1e-9);
  const auto indoor = planar_grid::loadStereoCalibration(
    CalibrationFormat::ROS_CAMERA_INFO, data + "rtabmap_stereo_rect/stereo_left.yaml",
    data + "rtabmap_stereo_rect/stereo_right.yaml");
  EXPECT_NEAR(indoor.calibration.baseline_m, 0.11969, 1e-5);
  // EuRoC's raw cameras differ (fu 458.654 and 457.587 px): it is rectified here, and
  // the rectified pair shares one focal length.
  const auto euroc = planar_grid::loadStereoCalibration(
    CalibrationFormat::EUROC, data + "euroc_v1_01_pairs/sensorLeft.yaml",
    data + "euroc_v1_01_pairs/sensorRight.yaml");
  EXPECT_NEAR(euroc.calibration.baseline_m, 0.1101, 1e-3);
}

TEST_F(BadStereoInputTest, RightCameraWithOtherIntrinsicsIsRefusedAtLoad)
{
  using planar_grid::CalibrationFormat;
  const std::string path = (dir_ / "calib.txt").string();
  // The right focal length 101 px against the left's 100 px (1 %).
  writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0", "101 0 48 -50 0 101 32 0 0 0 1 0");
  std::string what = calibrationError(CalibrationFormat::KARLSRUHE, path);
  EXPECT_CONTAINS(what, "calib.txt:2");
  EXPECT_CONTAINS(what, "focal length fx");
  EXPECT_CONTAINS(what, "101 px");
  EXPECT_CONTAINS(what, "100 px");
  // The right principal point 2 px to the right.
  writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0", "100 0 50 -50 0 100 32 0 0 0 1 0");
  what = calibrationError(CalibrationFormat::KARLSRUHE, path);
  EXPECT_CONTAINS(what, "principal point cx");
  // Only cy differs, in a KITTI file of bare rows.
  std::ofstream(path) << "100 0 48 0 0 100 32 0 0 0 1 0\n"
                      << "100 0 48 -50 0 100 33 0 0 0 1 0\n";
  what = calibrationError(CalibrationFormat::KITTI, path);
  EXPECT_CONTAINS(what, "calib.txt:2");
  EXPECT_CONTAINS(what, "principal point cy");
  // Within the tolerance (1e-4 of the value) a pair loads: 100.005 px against 100 px.
  writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0",
                   "100.005 0 48 -50 0 100.005 32 0 0 0 1 0");
  EXPECT_NO_THROW(
    planar_grid::loadStereoCalibration(CalibrationFormat::KARLSRUHE, path));
  // ROS camera_info: the indoor pair's right file with cx 318.11621 -> 320.
  const std::string data = std::string(PLANAR_GRID_DATA_DIR) + "/rtabmap_stereo_rect/";
  std::ifstream in(data + "stereo_right.yaml");
  std::string text((std::istreambuf_iterator<char>(in)),
                   std::istreambuf_iterator<char>());
  const std::string cx = "3.1811621093750000e+02";
  const auto at = text.find(cx, text.find("projection_matrix"));
  ASSERT_NE(at, std::string::npos);
  text.replace(at, cx.size(), "320.0");
  const std::string right = (dir_ / "stereo_right.yaml").string();
  std::ofstream(right) << text;
  what = calibrationError(CalibrationFormat::ROS_CAMERA_INFO, data + "stereo_left.yaml",
                          right);
  EXPECT_CONTAINS(what, right);
  EXPECT_CONTAINS(what, "principal point cx");
}

TEST_F(BadStereoInputTest, NonFiniteCalibrationValueIsNamedWithFileAndLine)
{
  using planar_grid::CalibrationFormat;
  const std::string path = (dir_ / "calib.txt").string();
  for (const std::string value : {"nan", "inf", "-inf", "1e999"}) {
    writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0",
                     "100 0 48 " + value + " 0 100 32 0 0 0 1 0");
    const std::string what = calibrationError(CalibrationFormat::KARLSRUHE, path);
    EXPECT_CONTAINS(what, "calib.txt:2: row 'P2_roi:' value 4, '" + value
                            + "', is not a finite number");
    EXPECT_EQ(what.find("must hold 12 numbers"), std::string::npos) << what;
  }
  // A KITTI file of bare rows.
  std::ofstream(path) << "NaN 0 48 0 0 100 32 0 0 0 1 0\n"
                      << "100 0 48 -50 0 100 32 0 0 0 1 0\n";
  EXPECT_CONTAINS(calibrationError(CalibrationFormat::KITTI, path),
                  "calib.txt:1: value 1 of the row, 'NaN', is not a finite number");
  // A row short of a number still says so.
  writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0", "100 0 48 -50 0 100 32 0 0 0 1");
  EXPECT_CONTAINS(calibrationError(CalibrationFormat::KARLSRUHE, path),
                  "must hold 12 numbers");
}

// --set: a wrong stage, key or value is a configuration error (exit 3) before anything
// is written; a right one is applied (the report names the value the stage ran with).
TEST_F(BadStereoInputTest, CommandLineParameterOverridesAreChecked)
{
  writePairs(2);
  for (const char* bad : {"voxel_grid.leaf_size_m=-1", "voxel_grid.leaf=0.1",
                          "no_such_stage.x=1", "voxel_grid"}) {
    const ToolRun run = runTool(config(0), std::string("--set ") + bad);
    EXPECT_EQ(run.exit_code, 3) << bad << ": " << run.output;
    EXPECT_CONTAINS(run.output, std::string("--set ") + bad);
    EXPECT_TRUE(noOutputs()) << run.output;
  }
  const ToolRun none = runTool(config(0), "--set voxel_grid");
  EXPECT_CONTAINS(none.output, "STAGE.KEY=VALUE");
  const ToolRun good =
    runTool(config(0), "--set stereo_disparity.num_disparities_px=32");
  EXPECT_EQ(good.exit_code, 0) << good.output;
  EXPECT_CONTAINS(good.output, "num_disparities_px=32");
}

TEST_F(BadStereoInputTest, EmptyOutputFolderIsRefused)
{
  writePairs(2);
  // --output '' (an unset variable in a script) would write into output.folder of the
  // YAML, here dir_/out.
  const ToolRun run = runTool(config(0), "--output ''");
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "--output '' is empty");
  EXPECT_TRUE(noOutputs()) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "report.json"));
  // output.folder "" in the YAML would write into the current folder.
  std::string yaml = config(0);
  const std::string folder = "folder: " + (dir_ / "out").string();
  yaml.replace(yaml.find(folder), folder.size(), "folder: \"\"");
  const std::string what = setupError(yaml);
  EXPECT_CONTAINS(what, "t.yaml:");
  EXPECT_CONTAINS(what, "output.folder is empty");
}

TEST_F(BadStereoInputTest, UnexpandedHomeOrVariableInTheOutputFolderIsRefused)
{
  writePairs(2);
  // A configuration is no shell: "~/maps" or "$HOME/maps" would create folders of those
  // literal names in the working folder.
  for (const std::string folder : {"~/maps", "$HOME/maps", "maps/${RUN}"}) {
    std::string yaml = config(0);
    const std::string line = "folder: " + (dir_ / "out").string();
    yaml.replace(yaml.find(line), line.size(), "folder: \"" + folder + "\"");
    const std::string what = setupError(yaml);
    EXPECT_CONTAINS(what, "t.yaml:");
    EXPECT_CONTAINS(what, "does not expand '~' or $VARIABLES");
  }
  const ToolRun run = runTool(config(0), "--output '~/maps'");
  EXPECT_NE(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output,
                  "--output '~/maps': '~' or a $VARIABLE the shell did not");
  EXPECT_TRUE(noOutputs()) << run.output;
  EXPECT_FALSE(fs::exists("~")) << "a folder named ~ in the working folder";
}

namespace {

/** The 21 x 21 points of a wall, x and y = (0, 5, ..., 100 plus \a offset) times \a
 * unit, z = 200 times \a unit, as a PCD blob whose x, y, z are of type T (PCL datatype
 * \a datatype). */
template <typename T>
pcl::PCLPointCloud2
wallBlob(std::uint8_t datatype, double unit, double offset = 0.0)
{
  pcl::PCLPointCloud2 blob;
  for (const char* name : {"x", "y", "z"}) {
    pcl::PCLPointField field;
    field.name = name;
    field.offset = static_cast<std::uint32_t>(blob.fields.size() * sizeof(T));
    field.datatype = datatype;
    field.count = 1;
    blob.fields.push_back(field);
  }
  blob.point_step = static_cast<std::uint32_t>(3 * sizeof(T));
  blob.height = 1;
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j) {
      const T xyz[3] = {static_cast<T>((5 * i + offset) * unit),
                        static_cast<T>((5 * j + offset) * unit),
                        static_cast<T>(200 * unit)};
      const auto* bytes = reinterpret_cast<const std::uint8_t*>(xyz);
      blob.data.insert(blob.data.end(), bytes, bytes + sizeof(xyz));
      ++blob.width;
    }
  blob.row_step = blob.point_step * blob.width;
  blob.is_dense = true;
  return blob;
}

} // namespace

using BadPCDInputTest = BadStereoInputTest;

TEST_F(BadPCDInputTest, NonFloatCoordinatesAreConvertedToFloat)
{
  // double x, y, z in metres (the wall 1 m x 1 m at z = 2 m, the points 2.5 cm off
  // the 0.1 m voxel borders) and int16 ones (100 x 100 at z = 200). PCL's conversion
  // matches fields by datatype too: both used to become 441 points at the origin, one
  // voxel.
  struct Case {
    std::string name;
    pcl::PCLPointCloud2 blob;
    std::size_t voxels; // voxel_grid at 0.1: 11 x 11 of the 1 m wall, 441 of the other
    float max_x;
    bool compressed;
  };
  const std::vector<Case> cases{
    {"double.pcd", wallBlob<double>(pcl::PCLPointField::FLOAT64, 0.01, 2.5), 121,
     1.025f, true},
    {"int16.pcd", wallBlob<std::int16_t>(pcl::PCLPointField::INT16, 1.0), 441, 100.0f,
     false}};
  for (const auto& c : cases) {
    const std::string path = (dir_ / c.name).string();
    // Compressed binary and ASCII, two of PCL's readers. PCL 1.13's uncompressed
    // PCDWriter::writeBinary() of a blob leaves about 4 KB of zero bytes after the
    // points, which checkPCDFile() refuses as points the header does not declare.
    ASSERT_EQ(c.compressed ? pcl::PCDWriter().writeBinaryCompressed(path, c.blob)
                           : pcl::PCDWriter().writeASCII(path, c.blob),
              0);
    planar_grid::PipelineRunner runner(planar_grid::parsePipelineConfig(
      "input:\n  type: pcd_files\n  files: [" + path
        + "]\npipeline:\n  - type: voxel_grid\n    params: {leaf_size_m: 0.1}\n"
          "  - type: transform_to_world\n  - type: accumulate\n",
      "t.yaml", "/"));
    const auto report = runner.run();
    ASSERT_GE(report.stages.size(), 1u);
    EXPECT_EQ(report.stages[0].points_in, 441u) << c.name;
    EXPECT_EQ(report.stages[0].points_out, c.voxels) << c.name;
    float max_x = -1.0f;
    for (const auto& p : *runner.state().world_cloud)
      max_x = std::max(max_x, p.x);
    EXPECT_NEAR(max_x, c.max_x, 0.06f * c.max_x) << c.name;
  }
}

TEST_F(BadPCDInputTest, FieldConversionKeepsValuesAndRefusesWhatItCannotRead)
{
  pcl::PCLPointCloud2 blob = wallBlob<double>(pcl::PCLPointField::FLOAT64, 0.01);
  planar_grid::convertFieldsToFloat(blob, {"x", "y", "z"}, "wall.pcd");
  ASSERT_EQ(blob.point_step, 12u);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  pcl::fromPCLPointCloud2(blob, cloud);
  ASSERT_EQ(cloud.size(), 441u);
  // Point 21 * 20 + 20 is the corner (1 m, 1 m, 2 m).
  EXPECT_FLOAT_EQ(cloud[440].x, 1.0f);
  EXPECT_FLOAT_EQ(cloud[440].y, 1.0f);
  EXPECT_FLOAT_EQ(cloud[440].z, 2.0f);
  // Two int16 values or three floats per point in x cannot be one coordinate (a float
  // needs no conversion, and PCL would read the first as x).
  const auto refused = [](pcl::PCLPointCloud2 counted, std::uint32_t count,
                          const std::string& name) {
    const std::uint32_t size = pcl::getFieldSize(counted.fields[0].datatype);
    counted.fields[0].count = count;
    counted.fields[1].offset = count * size;
    counted.fields[2].offset = (count + 1) * size;
    counted.point_step = (count + 2) * size;
    counted.data.resize(counted.width * counted.point_step);
    counted.row_step = counted.width * counted.point_step;
    try {
      planar_grid::convertFieldsToFloat(counted, {"x", "y", "z"}, name);
      ADD_FAILURE() << name << ": a field of COUNT " << count << " was accepted";
    } catch (const planar_grid::IOError& e) {
      EXPECT_CONTAINS(std::string(e.what()), name + ": the field 'x' holds "
                                               + std::to_string(count) + " values");
    }
  };
  refused(wallBlob<std::int16_t>(pcl::PCLPointField::INT16, 1.0), 2, "pairs.pcd");
  refused(wallBlob<float>(pcl::PCLPointField::FLOAT32, 1.0), 3, "triples.pcd");
}

TEST_F(BadStereoInputTest, RunWhoseMapHasNoCuboidsWritesItsOutputsAndExitsZero)
{
  // One Karlsruhe frame through the paper pipeline with the map, and a cell needing a
  // million points: the map ends with no cuboid. An empty map is a result: every output
  // but the cuboid mesh (a mesh of no cuboid) is written, and the run says why.
  std::string yaml = planar_grid::test::karlsruheJob(1, dir_ / "out", "");
  const std::string stage = "  - type: planar_cuboid_approximation\n";
  ASSERT_NE(yaml.find(stage), std::string::npos);
  yaml.replace(yaml.find(stage), stage.size(),
               stage + "    params: {min_points_per_cell: 1000000}\n");
  const ToolRun run = runTool(yaml);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "the map is empty");
  EXPECT_CONTAINS(run.output, "map_cuboids.ply");
  for (const char* name :
       {"map.pgmap", "map.bt", "report.json", "trajectory.txt", "world_cloud.pcd"})
    EXPECT_TRUE(fs::exists(dir_ / "out" / name)) << name << "\n" << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "map_cuboids.ply"));
}

TEST_F(BadStereoInputTest, RunOfDarkFramesWritesAnEmptyMapAndExitsZero)
{
  // Karlsruhe's frames 10 and 11 made dark: no disparity, so no points and no observed
  // space. Every stage passes the empty frames on; the outputs that need an extent or a
  // cuboid (the 2D grid, the mesh) are left out with a reason, the rest is written.
  std::string yaml = planar_grid::test::karlsruheJob(
    2, dir_ / "out", "  map_grid_2d: map_2d.yaml\n  map_mesh: map_cuboids.ply\n");
  for (const auto& [folder, image] :
       {std::pair<std::string, std::string>{"left", "I1"}, {"right", "I2"}}) {
    const std::string pattern = "/" + folder + "/" + image + "_%06d.png";
    const std::size_t at = yaml.find(pattern);
    ASSERT_NE(at, std::string::npos) << yaml;
    const std::size_t start = yaml.rfind(' ', at) + 1;
    yaml.replace(start, at - start, dir_.string());
    for (const int index : {10, 11}) {
      std::array<char, 32> name{};
      std::snprintf(name.data(), name.size(), "%s_%06d.png", image.c_str(), index);
      ASSERT_TRUE(cv::imwrite((dir_ / folder / name.data()).string(),
                              cv::Mat::zeros(372, 1344, CV_8UC1)));
    }
  }
  const ToolRun run = runTool(yaml);
  EXPECT_EQ(run.exit_code, 0) << run.output;
  EXPECT_CONTAINS(run.output, "(0): no points reached stage");
  EXPECT_CONTAINS(run.output, "(1): no points reached stage");
  EXPECT_CONTAINS(run.output, "map_2d.yaml is not written: the map is empty");
  EXPECT_CONTAINS(run.output, "map_cuboids.ply is not written: the map is empty");
  for (const char* name : {"map.pgmap", "report.json", "trajectory.txt"})
    EXPECT_TRUE(fs::exists(dir_ / "out" / name)) << name << "\n" << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "map_2d.yaml"));
  const planar_grid::PlanarGridMap map =
    planar_grid::PlanarGridMap::load((dir_ / "out" / "map.pgmap").string());
  EXPECT_EQ(map.getSurfaceLayer().getCuboidCount(), 0u);
}

TEST_F(BadStereoInputTest, OutputNameOutsideTheFolderIsRefusedAtLoad)
{
  // Found only when the outputs were written, after the last frame.
  for (const std::string& name :
       {std::string("../escaped.pgmap"), std::string("/tmp/x.pgmap"),
        std::string("sub/../../escaped.pgmap")}) {
    const std::string what = setupError(config(0) + "  map: " + name + "\n");
    EXPECT_CONTAINS(what, "t.yaml:");
    EXPECT_CONTAINS(what, "output.map '" + name + "' must be a file name inside");
  }
  // A name in a subfolder stays inside.
  writePairs(1);
  EXPECT_EQ(setupError(config(0) + "  map: maps/run.pgmap\n"), "");
}

TEST_F(BadStereoInputTest, CheckpointThatIsAFolderIsRefusedBeforeTheFirstFrame)
{
  writePairs(3);
  fs::create_directories(dir_ / "out" / "checkpoint.pgck");
  const ToolRun run = runTool(config(0), "--checkpoint-every 1");
  EXPECT_EQ(run.exit_code, 5) << run.output;
  EXPECT_CONTAINS(run.output, (dir_ / "out" / "checkpoint.pgck").string()
                                + ": the checkpoint (output.checkpoint) is a folder");
  // No frame ran: the progress line of the first frame is not there.
  EXPECT_EQ(run.output.find("frame 1/"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "report.json"));
}

namespace {

/** The whole content of \a path ("" when it cannot be read). */
std::string
contentOf(const fs::path& path)
{
  std::ifstream in(path, std::ios::binary);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

/** The message of the planar_grid::IOError that checkOutputPaths() throws for \a
 * config's outputs against its runner's inputs ("" when none). */
std::string
outputPathError(const planar_grid::PipelineConfig& config, bool with_checkpoint = false)
{
  try {
    const planar_grid::PipelineRunner runner(config);
    planar_grid::checkOutputPaths(config.output, runner.inputFiles(), with_checkpoint);
  } catch (const planar_grid::IOError& e) {
    return e.what();
  }
  return "";
}

/** KITTI rows of \a count poses, pose i at x = \a step_m * i. */
std::string
kittiPoses(int count, double step_m)
{
  std::string rows;
  for (int i = 0; i < count; ++i)
    rows += "1 0 0 " + std::to_string(step_m * i) + " 0 1 0 0 0 0 1 0\n";
  return rows;
}

/** \a yaml (a configuration of the fixture's) with the KITTI poses file \a poses added
 * to its input block. */
std::string
withKittiPoses(std::string yaml, const fs::path& poses)
{
  yaml.replace(yaml.find("}\npipeline:"), 2,
               "}\n  poses: {format: kitti, file: " + poses.string() + "}\n");
  return yaml;
}

} // namespace

TEST_F(BadStereoInputTest, OutputThatWouldOverwriteAnInputIsRefusedBeforeTheFirstFrame)
{
  // `trajectory: insdata.txt` with the output folder where the poses file lives: the
  // run read the poses, then replaced them with its trajectory.
  writePairs(3);
  std::ofstream(dir_ / "poses.txt") << kittiPoses(3, 0.1);
  std::string yaml = withKittiPoses(config(0), dir_ / "poses.txt");
  const std::string poses_before = contentOf(dir_ / "poses.txt");
  const ToolRun run =
    runTool(yaml + "  trajectory: poses.txt\n", "--output '" + dir_.string() + "'");
  EXPECT_EQ(run.exit_code, 5) << run.output;
  EXPECT_CONTAINS(run.output, (dir_ / "poses.txt").string()
                                + ": output.trajectory 'poses.txt' would overwrite the "
                                  "poses file (input.poses.file)");
  // Refused before the first frame: nothing read further, nothing written.
  EXPECT_EQ(run.output.find("frame 1/"), std::string::npos) << run.output;
  EXPECT_EQ(contentOf(dir_ / "poses.txt"), poses_before);
  EXPECT_FALSE(fs::exists(dir_ / "report.json"));

  // Every kind of input, through the check the tool runs. The config file is one
  // when the configuration was loaded from a file.
  const fs::path yaml_path = dir_ / "run.yaml";
  std::ofstream(yaml_path) << yaml;
  const auto with = [&](const std::string& folder, const std::string& key,
                        const std::string& name) {
    planar_grid::PipelineConfig config =
      planar_grid::loadPipelineConfig(yaml_path.string());
    config.output.folder = folder;
    if (key == "cloud")
      config.output.cloud = name;
    else if (key == "map")
      config.output.map = name;
    else if (key == "report")
      config.output.report = name;
    else if (key == "checkpoint")
      config.output.checkpoint = name;
    return config;
  };
  EXPECT_CONTAINS(outputPathError(with(dir_.string(), "map", "calib.txt")),
                  "output.map 'calib.txt' would overwrite the calibration "
                  "(input.calibration.file), "
                    + (dir_ / "calib.txt").string() + ", which this run reads");
  EXPECT_CONTAINS(outputPathError(with((dir_ / "left").string(), "cloud", leftName(2))),
                  "would overwrite a left image (input.left_images)");
  EXPECT_CONTAINS(outputPathError(with((dir_ / "right").string(), "map", rightName(0))),
                  "would overwrite a right image (input.right_images)");
  EXPECT_CONTAINS(outputPathError(with(dir_.string(), "report", "run.yaml")),
                  "would overwrite the configuration file");
  // Another spelling of the folder: a symbolic link to it, and "..".
  fs::create_directory_symlink(dir_, dir_ / "alias");
  EXPECT_CONTAINS(outputPathError(with((dir_ / "alias").string(), "map", "calib.txt")),
                  "would overwrite the calibration");
  EXPECT_CONTAINS(
    outputPathError(with((dir_ / "left" / "..").string(), "map", "poses.txt")),
    "would overwrite the poses file");
  // A hard link is the same file under another name.
  fs::create_directories(dir_ / "out");
  fs::create_hard_link(dir_ / "poses.txt", dir_ / "out" / "linked.txt");
  EXPECT_CONTAINS(outputPathError(with((dir_ / "out").string(), "map", "linked.txt")),
                  "would overwrite the poses file");
  // The checkpoint counts when the run writes it.
  EXPECT_EQ(outputPathError(with(dir_.string(), "checkpoint", "poses.txt"), false), "");
  EXPECT_CONTAINS(outputPathError(with(dir_.string(), "checkpoint", "poses.txt"), true),
                  "output.checkpoint 'poses.txt' would overwrite the poses file");
  // The same names in another folder are fine.
  EXPECT_EQ(outputPathError(with((dir_ / "out").string(), "map", "calib.txt")), "");
}

TEST_F(BadStereoInputTest, TwoOutputsOfOneNameAreRefusedBeforeTheFirstFrame)
{
  // The trajectory and the report in one file: the report, written last, would replace
  // the trajectory.
  writePairs(2);
  const ToolRun run = runTool(config(0) + "  trajectory: run.txt\n  report: run.txt\n");
  EXPECT_EQ(run.exit_code, 5) << run.output;
  EXPECT_CONTAINS(run.output, (dir_ / "out" / "run.txt").string()
                                + ": output.trajectory 'run.txt' is the file of "
                                  "output.report too");
  EXPECT_EQ(run.output.find("frame 1/"), std::string::npos) << run.output;
  EXPECT_FALSE(fs::exists(dir_ / "out" / "run.txt"));
}

TEST_F(BadStereoInputTest, OutputNameThatIsAFolderIsRefusedBeforeTheFirstFrame)
{
  // A folder where an output goes failed the commit after the last frame, part way
  // through the renames: some outputs new, some old.
  writePairs(2);
  const ToolRun first = runTool(config(0));
  ASSERT_EQ(first.exit_code, 0) << first.output;
  const std::string report_before = contentOf(dir_ / "out" / "report.json");
  ASSERT_FALSE(report_before.empty());
  // A folder where a new output goes (map.bt is not written by this pipeline, but
  // named), and one where an old output was.
  const fs::path map_bt = dir_ / "out" / "map.bt";
  fs::create_directories(map_bt / "inside");
  ToolRun run = runTool(config(0));
  EXPECT_EQ(run.exit_code, 5) << run.output;
  EXPECT_CONTAINS(run.output, map_bt.string()
                                + ": output.map_octomap 'map.bt' names an existing "
                                  "folder, and a file cannot replace a folder");
  EXPECT_EQ(run.output.find("frame 1/"), std::string::npos) << run.output;
  EXPECT_EQ(contentOf(dir_ / "out" / "report.json"), report_before);
  fs::remove_all(map_bt);
  fs::remove(dir_ / "out" / "report.json");
  fs::create_directories(dir_ / "out" / "report.json" / "inside");
  run = runTool(config(0));
  EXPECT_EQ(run.exit_code, 5) << run.output;
  EXPECT_CONTAINS(run.output, "output.report 'report.json' names an existing folder");
  fs::remove_all(dir_ / "out" / "report.json");
  // The other outputs are the first run's; without the folder the run writes again.
  const ToolRun again = runTool(config(0));
  EXPECT_EQ(again.exit_code, 0) << again.output;
}

TEST_F(BadStereoInputTest, FolderInAnOutputsPlaceAtTheCommitKeepsTheOldSet)
{
  // The same folder made while the run ran (after the check before its first frame):
  // before the commit journal the commit is refused and the old set stays; after the
  // journal the renames are refused before the first one, and the next transaction
  // completes them once the folder is gone, as the message says.
  const fs::path out = dir_ / "out";
  const auto writeSet = [&out](const std::string& text, bool commit,
                               const std::function<void(const std::string&)>& step) {
    planar_grid::OutputTransaction transaction(out.string());
    transaction.setStepCallback(step);
    for (const char* name : {"a.txt", "b.txt", "c.txt"})
      transaction.write(
        name, [&text](const std::string& path) { std::ofstream(path) << text; });
    if (commit)
      transaction.commit();
  };
  writeSet("old", true, nullptr);
  const auto oldSet = [&out] {
    return contentOf(out / "a.txt") == "old" && contentOf(out / "c.txt") == "old";
  };
  ASSERT_TRUE(oldSet());

  // Before the journal.
  fs::remove(out / "b.txt");
  fs::create_directories(out / "b.txt" / "inside");
  try {
    writeSet("new", true, nullptr);
    FAIL() << "the commit over a folder succeeded";
  } catch (const planar_grid::IOError& e) {
    EXPECT_CONTAINS(e.what(), (out / "b.txt").string() + ": is a folder");
    EXPECT_CONTAINS(e.what(), "no output in " + out.string() + " was replaced");
  }
  EXPECT_TRUE(oldSet());
  EXPECT_FALSE(fs::exists(out / planar_grid::OutputTransaction::JOURNAL));

  // After the journal: the folder appears between the commit point and the renames.
  fs::remove_all(out / "b.txt");
  try {
    writeSet("new", true, [&out](const std::string& step) {
      if (step == "journal")
        fs::create_directories(out / "b.txt" / "inside");
    });
    FAIL() << "the renames over a folder succeeded";
  } catch (const planar_grid::IOError& e) {
    EXPECT_CONTAINS(e.what(), (out / "b.txt").string() + ": is a folder");
    EXPECT_CONTAINS(e.what(),
                    "the next run into " + out.string() + " then completes the commit");
  }
  // Not a mix: no file was moved, and the journal is kept.
  EXPECT_TRUE(oldSet());
  EXPECT_TRUE(fs::exists(out / planar_grid::OutputTransaction::JOURNAL));
  // While the folder is there, the next run is refused with the same message.
  EXPECT_THROW(planar_grid::OutputTransaction{out.string()}, planar_grid::IOError);
  EXPECT_TRUE(oldSet());
  // Without it, the next run completes the commit: the new set.
  fs::remove_all(out / "b.txt");
  {
    planar_grid::OutputTransaction recovered(out.string());
  }
  for (const char* name : {"a.txt", "b.txt", "c.txt"})
    EXPECT_EQ(contentOf(out / name), "new") << name;
  EXPECT_FALSE(fs::exists(out / planar_grid::OutputTransaction::JOURNAL));
}

TEST_F(BadStereoInputTest, ResumeRefusesAnInputFileThatChangedSinceTheCheckpoint)
{
  // A changed calibration was refused ("a different pipeline"), a changed poses file
  // accepted: the resumed run mapped its frames at other poses than the first part.
  writePairs(3);
  std::ofstream(dir_ / "poses.txt") << kittiPoses(3, 0.1);
  std::string yaml = withKittiPoses(config(0), dir_ / "poses.txt");
  const fs::path yaml_path = dir_ / "run.yaml";
  std::ofstream(yaml_path) << yaml;
  const std::string checkpoint = (dir_ / "out" / "checkpoint.pgck").string();
  {
    planar_grid::PipelineRunner first(
      planar_grid::loadPipelineConfig(yaml_path.string()));
    first.setFrameRange(0, 1);
    first.setCheckpoint(checkpoint, 1);
    ASSERT_EQ(first.run().checkpoints_written, 1u);
  }
  const auto resumeError = [&]() -> std::string {
    planar_grid::PipelineRunner runner(
      planar_grid::loadPipelineConfig(yaml_path.string()));
    try {
      EXPECT_EQ(runner.resumeFrom(checkpoint), 1u);
    } catch (const planar_grid::IOError& e) {
      return e.what();
    }
    return "";
  };
  // Unchanged inputs resume.
  EXPECT_EQ(resumeError(), "");

  // The poses file: one pose moved by 1 cm, the same size.
  const std::string poses = kittiPoses(3, 0.1);
  const std::string moved = poses.substr(0, poses.rfind('\n', poses.size() - 2) + 1)
                            + "1 0 0 0.210000 0 1 0 0 0 0 1 0\n";
  ASSERT_EQ(moved.size(), poses.size());
  std::ofstream(dir_ / "poses.txt") << moved;
  std::string what = resumeError();
  EXPECT_CONTAINS(what, "checkpoint " + checkpoint);
  EXPECT_CONTAINS(what, "the poses file (input.poses.file) "
                          + (dir_ / "poses.txt").string()
                          + " changed since the checkpoint was written");
  EXPECT_CONTAINS(what, "start a new run without --resume");
  std::ofstream(dir_ / "poses.txt") << poses;
  EXPECT_EQ(resumeError(), "");

  // The calibration: now named, not "a different pipeline".
  const std::string calibration = contentOf(dir_ / "calib.txt");
  writeCalibration("100 0 48 0 0 100 32 0 0 0 1 0", "100 0 48 -51 0 100 32 0 0 0 1 0");
  what = resumeError();
  EXPECT_CONTAINS(what, "the calibration (input.calibration.file) "
                          + (dir_ / "calib.txt").string() + " changed since");
  std::ofstream(dir_ / "calib.txt") << calibration;
  EXPECT_EQ(resumeError(), "");

  // The configuration file, even where only a comment changed.
  std::ofstream(yaml_path) << yaml << "# edited\n";
  EXPECT_CONTAINS(resumeError(),
                  "the configuration file " + yaml_path.string() + " changed since");
  std::ofstream(yaml_path) << yaml;
  EXPECT_EQ(resumeError(), "");

  // An image of a frame before the checkpoint (the map holds what it held); an image
  // of a frame after it is read by the resumed run and changes nothing.
  const std::string image = contentOf(dir_ / "right" / rightName(0));
  cv::Mat other = cv::imread((dir_ / "right" / rightName(1)).string());
  ASSERT_TRUE(cv::imwrite((dir_ / "right" / rightName(0)).string(), other));
  what = resumeError();
  EXPECT_CONTAINS(what, "the right image (input.right_images) of frame 0 "
                          + (dir_ / "right" / rightName(0)).string()
                          + " changed since the checkpoint was written");
  std::ofstream(dir_ / "right" / rightName(0), std::ios::binary) << image;
  EXPECT_EQ(resumeError(), "");
  cv::Mat later = cv::imread((dir_ / "left" / leftName(1)).string());
  ASSERT_TRUE(cv::imwrite((dir_ / "left" / leftName(2)).string(), later));
  EXPECT_EQ(resumeError(), "");
}

TEST_F(BadStereoInputTest, NonRegularFilesAreRefusedBeforeTheyAreRead)
{
  // /dev/zero never ends: read whole into memory, it took all of it.
  for (const std::string& path : {std::string("/dev/zero"), dir_.string()}) {
    try {
      planar_grid::loadPipelineConfig(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const planar_grid::IOError& e) {
      EXPECT_CONTAINS(e.what(), path + ": not a regular file");
    }
    try {
      (void)planar_grid::PlanarGridMap::load(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const planar_grid::IOError& e) {
      EXPECT_CONTAINS(e.what(), path + ": not a regular file");
    }
    // Calibration and pose files: the cause, not a parse error of what was read.
    const std::string cause =
      path == dir_.string() ? ": a folder, not a file" : ": not a regular file";
    const std::string calib = (dir_ / "left.yaml").string();
    std::ofstream(calib) << "image_width: 640\n";
    for (const auto& [left, right] :
         {std::pair<std::string, std::string>{path, ""}, {calib, path}}) {
      try {
        (void)planar_grid::loadStereoCalibration(
          right.empty() ? planar_grid::CalibrationFormat::KARLSRUHE
                        : planar_grid::CalibrationFormat::ROS_CAMERA_INFO,
          left, right);
        ADD_FAILURE() << "no error for " << left << " " << right;
      } catch (const planar_grid::IOError& e) {
        EXPECT_CONTAINS(e.what(), path + cause);
      }
    }
    try {
      (void)planar_grid::loadKarlsruheInsData(path);
      ADD_FAILURE() << "no error for " << path;
    } catch (const planar_grid::IOError& e) {
      EXPECT_CONTAINS(e.what(), path + cause);
    }
  }
  // A configuration of gigabytes is not one: a sparse 17 MB file.
  const fs::path big = dir_ / "big.yaml";
  std::ofstream(big) << "# ";
  fs::resize_file(big, 17u << 20);
  try {
    planar_grid::loadPipelineConfig(big.string());
    ADD_FAILURE() << "no error for " << big;
  } catch (const planar_grid::IOError& e) {
    EXPECT_CONTAINS(e.what(),
                    big.string() + ": the configuration file is 17825792 bytes");
  }
  // The tool exits at once with the status of an input error.
  const std::string command =
    std::string(PLANAR_GRID_PIPELINE_TOOL) + " --config /dev/zero > /dev/null 2>&1";
  const int status = std::system(command.c_str());
  EXPECT_TRUE(WIFEXITED(status) && WEXITSTATUS(status) == 4) << status;
}
