// SPDX-License-Identifier: BSD-3-Clause
// ROS 1 bags as input: bags written here with rosbag_storage from the real Karlsruhe
// images and PCL clouds must give the frames the same data read directly gives.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/run_outputs.h>
#include <planar_grid/ros_bag/ros_messages.h>
#include <planar_grid/stereo/calibration_io.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/io/pcd_io.h>

#include <gtest/gtest.h>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>
#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>

#include "../test_constants.h"
#include "main_job_stages.h"

namespace fs = std::filesystem;
using planar_grid::parsePipelineConfig;

namespace {

using planar_grid_test::DATA;
using planar_grid_test::KARLSRUHE_DIR;
const std::string ROOM_SCAN = DATA + "/pcl_clouds/room_scan1.pcd";
/** The stamp of the first frame, seconds. */
constexpr double T0 = 1268149800.0;

const std::string STAGES = R"(pipeline:
  - type: stereo_disparity
    params: {num_disparities_px: 128, max_range_m: 30.0}
  - type: voxel_grid
    params: {leaf_size_m: 0.2}
  - type: transform_to_world
  - type: accumulate
    params: {leaf_size_m: 0.2}
)";

sensor_msgs::Image
imageMessage(const std::string& path, double stamp, const std::string& frame_id)
{
  const cv::Mat grey = cv::imread(path, cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(grey.empty()) << path;
  return planar_grid::ros_messages::monoImage(grey, ros::Time(stamp), frame_id);
}

/** The CameraInfo of a rectified camera: P = [f 0 cx Tx; 0 f cy 0; 0 0 1 0]. */
sensor_msgs::CameraInfo
cameraInfo(const planar_grid::StereoCalibration& c, double tx, double stamp)
{
  return planar_grid::ros_messages::cameraInfo(c, tx, ros::Time(stamp), "");
}

geometry_msgs::TransformStamped
transform(const std::string& parent,
          const std::string& child,
          const Eigen::Isometry3d& pose,
          double stamp)
{
  return planar_grid::ros_messages::transformStamped(pose, parent, child,
                                                     ros::Time(stamp));
}

sensor_msgs::PointCloud2
cloudMessage(const pcl::PCLPointCloud2& blob, double stamp)
{
  sensor_msgs::PointCloud2 msg;
  msg.header.stamp = ros::Time(stamp);
  msg.header.frame_id = "lidar";
  msg.height = blob.height;
  msg.width = blob.width;
  for (const auto& f : blob.fields) {
    sensor_msgs::PointField field;
    field.name = f.name;
    field.offset = f.offset;
    field.datatype = f.datatype;
    field.count = f.count;
    msg.fields.push_back(field);
  }
  msg.is_bigendian = blob.is_bigendian;
  msg.point_step = blob.point_step;
  msg.row_step = blob.row_step;
  msg.data = blob.data;
  msg.is_dense = blob.is_dense;
  return msg;
}

Eigen::Isometry3d
yawAndShift(double yaw_rad, const Eigen::Vector3d& shift)
{
  Eigen::Isometry3d pose(Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ()));
  pose.translation() = shift;
  return pose;
}

class RosBagInputTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_ros_bag_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
    model_ = planar_grid::loadStereoCalibration(
      planar_grid::CalibrationFormat::KARLSRUHE, KARLSRUHE_DIR + "/calib.txt");
    const cv::Mat first = cv::imread(KARLSRUHE_DIR + "/left/I1_000010.png");
    model_.calibration.width = first.cols;
    model_.calibration.height = first.rows;
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** The Karlsruhe pairs 10 and 11 at T0 and T0 + 0.1 s (right stamps 2 ms later),
   * their CameraInfo, and world_T_camera as world -> base (moving, /tf) -> camera
   * (static, /tf_static). \a poses are world_T_camera at the two frames. */
  std::string writeStereoBag(const planar_grid::Trajectory& poses,
                             bool with_right_info = true,
                             const std::string& name = "stereo.bag") const
  {
    const std::string path = (dir_ / name).string();
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    const Eigen::Isometry3d base_T_camera =
      yawAndShift(-0.5 * M_PI, Eigen::Vector3d(0.3, 0.0, 1.2));
    tf2_msgs::TFMessage fixed;
    fixed.transforms.push_back(transform("base", "camera", base_T_camera, T0));
    bag.write("/tf_static", ros::Time(T0), fixed);
    const auto& c = model_.calibration;
    for (int k = 0; k < 2; ++k) {
      const double t = T0 + 0.1 * k;
      char index[32];
      std::snprintf(index, sizeof(index), "%06d.png", 10 + k);
      bag.write("/left/camera_info", ros::Time(t), cameraInfo(c, 0.0, t));
      if (with_right_info)
        bag.write("/right/camera_info", ros::Time(t),
                  cameraInfo(c, -c.focal_length_px * c.baseline_m, t));
      bag.write("/left/image_rect", ros::Time(t),
                imageMessage(KARLSRUHE_DIR + "/left/I1_" + index, t, "camera"));
      bag.write(
        "/right/image_rect", ros::Time(t + 0.002),
        imageMessage(KARLSRUHE_DIR + "/right/I2_" + index, t + 0.002, "camera"));
      if (!poses.empty()) {
        tf2_msgs::TFMessage tf;
        tf.transforms.push_back(
          transform("world", "base", poses[k] * base_T_camera.inverse(), t));
        bag.write("/tf", ros::Time(t), tf);
      }
    }
    bag.close();
    return path;
  }

  std::string stereoInput(const std::string& bag, const std::string& poses) const
  {
    return "input:\n  type: ros_bag\n  file: " + bag
           + "\n  left_image: /left/image_rect\n  right_image: /right/image_rect\n"
             "  left_camera_info: /left/camera_info\n"
             "  right_camera_info: /right/camera_info\n"
             "  max_pair_time_difference_s: 0.005\n"
           + poses;
  }

  /** The room scan twice, at T0 + 1 and T0 + 2, and world -> lidar on /tf at T0 + 0.5,
   * + 1.5 and + 2.5: each frame lies halfway between two samples. */
  std::string writeCloudBag() const
  {
    pcl::PCLPointCloud2 blob;
    EXPECT_EQ(pcl::io::loadPCDFile(ROOM_SCAN, blob), 0);
    const std::string path = (dir_ / "clouds.bag").string();
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    for (int k = 0; k < 3; ++k) {
      tf2_msgs::TFMessage tf;
      tf.transforms.push_back(transform(
        "world", "lidar", yawAndShift(0.2 * k, Eigen::Vector3d(1.0 * k, 0.0, 0.5)),
        T0 + 0.5 + k));
      bag.write("/tf", ros::Time(T0 + 0.5 + k), tf);
    }
    for (int k = 1; k <= 2; ++k)
      bag.write("/points", ros::Time(T0 + k), cloudMessage(blob, T0 + k));
    bag.close();
    return path;
  }

  /** The message of the IOError that making the frame source of \a yaml throws, ""
   * when it is made. */
  std::string sourceErrorOrEmpty(const std::string& yaml) const
  {
    try {
      planar_grid::createFrameSource(parsePipelineConfig(yaml, "t.yaml", "/").input);
    } catch (const planar_grid::IOError& e) {
      return e.what();
    }
    return "";
  }

  /** The message of the IOError that making the frame source of \a yaml throws. */
  std::string sourceError(const std::string& yaml) const
  {
    try {
      planar_grid::createFrameSource(parsePipelineConfig(yaml, "t.yaml", "/").input);
    } catch (const planar_grid::IOError& e) {
      return e.what();
    }
    ADD_FAILURE() << "no IOError for\n" << yaml;
    return "";
  }

  fs::path dir_;
  planar_grid::StereoCameraModel model_;
};

TEST_F(RosBagInputTest, StereoBagGivesTheFramesOfTheImageFiles)
{
  // The directory run: the same pairs, the insdata poses.
  const std::string files_input =
    "input:\n  type: stereo_sequence\n  left_images: " + KARLSRUHE_DIR
    + "/left/I1_%06d.png\n  right_images: " + KARLSRUHE_DIR
    + "/right/I2_%06d.png\n  first_index: 10\n  frame_count: 2\n"
      "  calibration: {format: karlsruhe, file: "
    + KARLSRUHE_DIR + "/calib.txt}\n  poses: {format: karlsruhe_insdata, file: "
    + KARLSRUHE_DIR + "/insdata.txt, camera_height_m: 1.57, camera_pitch_rad: 0.09}\n";
  planar_grid::PipelineRunner files(
    parsePipelineConfig(files_input + STAGES, "t.yaml", "/"));
  files.run();
  ASSERT_EQ(files.trajectory().size(), 2u);

  // The bag carries the same images and those poses through the tf chain.
  const std::string bag = writeStereoBag(files.trajectory());
  const std::string bag_input = stereoInput(
    bag, "  poses: {format: tf, parent_frame: world, child_frame: camera}\n");

  const auto from_files = planar_grid::createFrameSource(
    parsePipelineConfig(files_input + STAGES, "t.yaml", "/").input);
  const auto from_bag = planar_grid::createFrameSource(
    parsePipelineConfig(bag_input + STAGES, "t.yaml", "/").input);
  ASSERT_EQ(from_bag->size(), 2u);
  for (std::size_t i = 0; i < 2; ++i) {
    planar_grid::Frame a, b;
    from_files->load(i, a);
    from_bag->load(i, b);
    ASSERT_EQ(a.left.size(), b.left.size());
    EXPECT_EQ(cv::norm(a.left, b.left, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(a.right, b.right, cv::NORM_INF), 0.0);
    EXPECT_DOUBLE_EQ(b.calibration.focal_length_px, a.calibration.focal_length_px);
    EXPECT_DOUBLE_EQ(b.calibration.cx_px, a.calibration.cx_px);
    EXPECT_DOUBLE_EQ(b.calibration.cy_px, a.calibration.cy_px);
    EXPECT_NEAR(b.calibration.baseline_m, a.calibration.baseline_m, 1e-12);
    ASSERT_TRUE(b.has_pose);
    EXPECT_LT(
      (b.world_T_camera.matrix() - a.world_T_camera.matrix()).cwiseAbs().maxCoeff(),
      1e-9);
  }

  planar_grid::PipelineRunner run(
    parsePipelineConfig(bag_input + STAGES, "t.yaml", "/"));
  run.run();
  ASSERT_EQ(run.trajectory().size(), 2u);
  for (std::size_t i = 0; i < 2; ++i)
    EXPECT_LT((run.trajectory()[i].matrix() - files.trajectory()[i].matrix())
                .cwiseAbs()
                .maxCoeff(),
              1e-9);
  ASSERT_GT(files.state().world_cloud->size(), 1000u);
  EXPECT_EQ(run.state().world_cloud->size(), files.state().world_cloud->size());
}

/** The bytes of the file at \a path. */
std::string
fileBytes(const fs::path& path)
{
  std::ifstream in(path, std::ios::binary);
  EXPECT_TRUE(in) << path;
  return std::string(std::istreambuf_iterator<char>(in), {});
}

TEST_F(RosBagInputTest, MainJobMapFromBagEqualsMapFromImageFiles)
{
  // Frames 0-9 of the main job's input through its stages, once from the PNG files and
  // calib.txt with the insdata poses, once from a bag of the same images (mono8), their
  // CameraInfo and those poses on /tf (world -> camera).
  constexpr int FRAMES = 10;
  const std::string stages = planar_grid_test::mainJobStages();
  const auto output = [this](const std::string& name) {
    return "output:\n  folder: " + (dir_ / name).string() + "\n  map: map.pgmap\n";
  };
  const std::string files_yaml =
    planar_grid_test::mainJobImageInput(0, FRAMES) + stages + output("files");
  const auto files_config = parsePipelineConfig(files_yaml, "t.yaml", "/");
  const auto files_source = planar_grid::createFrameSource(files_config.input);
  ASSERT_EQ(files_source->size(), static_cast<std::size_t>(FRAMES));

  const std::string path = (dir_ / "main_job.bag").string();
  {
    rosbag::Bag bag(path, rosbag::bagmode::Write);
    for (int k = 0; k < FRAMES; ++k) {
      planar_grid::Frame frame;
      files_source->load(static_cast<std::size_t>(k), frame);
      ASSERT_TRUE(frame.has_pose);
      const auto& c = frame.calibration;
      const double t = T0 + 0.1 * k;
      char index[32];
      std::snprintf(index, sizeof(index), "%06d.png", k);
      bag.write("/left/camera_info", ros::Time(t), cameraInfo(c, 0.0, t));
      bag.write("/right/camera_info", ros::Time(t),
                cameraInfo(c, -c.focal_length_px * c.baseline_m, t));
      bag.write("/left/image_rect", ros::Time(t),
                imageMessage(KARLSRUHE_DIR + "/left/I1_" + index, t, "camera"));
      bag.write(
        "/right/image_rect", ros::Time(t + 0.002),
        imageMessage(KARLSRUHE_DIR + "/right/I2_" + index, t + 0.002, "camera"));
      tf2_msgs::TFMessage tf;
      tf.transforms.push_back(transform("world", "camera", frame.world_T_camera, t));
      bag.write("/tf", ros::Time(t), tf);
    }
    bag.close();
  }
  const std::string bag_yaml =
    stereoInput(path,
                "  poses: {format: tf, parent_frame: world, child_frame: camera}\n")
    + stages + output("bag");
  const auto bag_config = parsePipelineConfig(bag_yaml, "t.yaml", "/");

  for (const auto* config : {&files_config, &bag_config}) {
    planar_grid::PipelineRunner runner(*config);
    planar_grid::RunReport report = runner.run();
    ASSERT_EQ(report.frames, static_cast<std::size_t>(FRAMES));
    ASSERT_TRUE(runner.state().map);
    ASSERT_GT(runner.state().map->getSurfaceLayer().getCuboids().size(), 0u);
    planar_grid::writeRunOutputs(config->output, runner, report);
  }
  const std::string from_files = fileBytes(dir_ / "files" / "map.pgmap");
  const std::string from_bag = fileBytes(dir_ / "bag" / "map.pgmap");
  ASSERT_GT(from_files.size(), 1000u);
  EXPECT_EQ(from_bag.size(), from_files.size());
  EXPECT_TRUE(from_bag == from_files)
    << "map.pgmap from the bag differs from the files'";
}

TEST_F(RosBagInputTest, CloudBagGivesThePCDCloudAndInterpolatedTfPoses)
{
  const std::string bag = writeCloudBag();
  const std::string yaml =
    "input:\n  type: ros_bag\n  file: " + bag
    + "\n  cloud: /points\n  poses: {format: tf, parent_frame: world, child_frame: "
      "lidar}\npipeline:\n  - type: voxel_grid\n    params: {leaf_size_m: 0.05}\n"
      "  - type: transform_to_world\n";
  const auto config = parsePipelineConfig(yaml, "t.yaml", "/");
  EXPECT_EQ(config.input.type, planar_grid::InputConfig::Type::PCD_FILES);
  const auto source = planar_grid::createFrameSource(config.input);
  ASSERT_EQ(source->size(), 2u);
  const auto pcd = planar_grid::createFrameSource(
    parsePipelineConfig(
      "input:\n  type: pcd_files\n  files: " + ROOM_SCAN
        + "\n  poses: {format: none}\npipeline:\n  - type: voxel_grid\n",
      "t.yaml", "/")
      .input);
  planar_grid::Frame direct;
  pcd->load(0, direct);
  for (std::size_t i = 0; i < 2; ++i) {
    planar_grid::Frame frame;
    source->load(i, frame);
    ASSERT_TRUE(frame.cloud);
    ASSERT_EQ(frame.cloud->size(), direct.cloud->size());
    for (std::size_t p = 0; p < direct.cloud->size(); p += 997) {
      EXPECT_EQ((*frame.cloud)[p].x, (*direct.cloud)[p].x);
      EXPECT_EQ((*frame.cloud)[p].z, (*direct.cloud)[p].z);
      EXPECT_EQ((*frame.cloud)[p].intensity, (*direct.cloud)[p].intensity);
    }
    // Halfway between the samples k and k + 1: x = k + 0.5, yaw 0.2 k + 0.1.
    ASSERT_TRUE(frame.has_pose);
    const auto& pose = frame.world_T_camera;
    EXPECT_NEAR(pose.translation().x(), i + 0.5, 1e-6);
    EXPECT_NEAR(pose.translation().z(), 0.5, 1e-9);
    EXPECT_NEAR(std::atan2(pose.linear()(1, 0), pose.linear()(0, 0)), 0.2 * i + 0.1,
                1e-6);
  }
  planar_grid::PipelineRunner runner(config);
  runner.run();
  EXPECT_EQ(runner.trajectory().size(), 2u);
}

/** A PointCloud2 of \a points whose x, y, z are of \a datatype (FLOAT64, FLOAT32, or
 * else INT16; scaled by \a scale before the cast, as a driver with integer millimetres
 * does) and whose intensity is a float. */
sensor_msgs::PointCloud2
typedCloudMessage(const pcl::PointCloud<pcl::PointXYZI>& points,
                  std::uint8_t datatype,
                  double scale)
{
  const std::uint32_t size = pcl::getFieldSize(datatype);
  sensor_msgs::PointCloud2 msg;
  msg.header.frame_id = "lidar";
  msg.height = 1;
  msg.width = static_cast<std::uint32_t>(points.size());
  const char* names[] = {"x", "y", "z", "intensity"};
  for (std::uint32_t i = 0; i < 4; ++i) {
    sensor_msgs::PointField field;
    field.name = names[i];
    field.offset = i * size;
    field.datatype =
      i < 3 ? datatype : static_cast<std::uint8_t>(sensor_msgs::PointField::FLOAT32);
    field.count = 1;
    msg.fields.push_back(field);
  }
  msg.point_step = 3 * size + 4;
  msg.row_step = msg.point_step * msg.width;
  msg.data.resize(msg.row_step);
  for (std::size_t p = 0; p < points.size(); ++p) {
    std::uint8_t* point = msg.data.data() + p * msg.point_step;
    const float xyz[3] = {points[p].x, points[p].y, points[p].z};
    for (int i = 0; i < 3; ++i) {
      const double value = scale * xyz[i];
      if (datatype == sensor_msgs::PointField::FLOAT64)
        std::memcpy(point + i * size, &value, size);
      else if (datatype == sensor_msgs::PointField::FLOAT32) {
        const auto single = static_cast<float>(value);
        std::memcpy(point + i * size, &single, size);
      } else {
        const auto rounded = static_cast<std::int16_t>(std::lround(value));
        std::memcpy(point + i * size, &rounded, size);
      }
    }
    std::memcpy(point + 3 * size, &points[p].intensity, 4);
  }
  msg.is_dense = true;
  return msg;
}

TEST(RosMessagesTest, PointCloud2OfDoubleOrIntegerCoordinatesKeepsItsPoints)
{
  planar_grid::Frame direct;
  planar_grid::createFrameSource(
    parsePipelineConfig(
      "input:\n  type: pcd_files\n  files: " + ROOM_SCAN
        + "\n  poses: {format: none}\npipeline:\n  - type: voxel_grid\n",
      "t.yaml", "/")
      .input)
    ->load(0, direct);
  ASSERT_GT(direct.cloud->size(), 1000u);
  // Double coordinates: a float survives the double exactly.
  planar_grid::Frame::Cloud cloud;
  planar_grid::ros_messages::cloudFromMessage(
    typedCloudMessage(*direct.cloud, sensor_msgs::PointField::FLOAT64, 1.0), "/points",
    cloud);
  ASSERT_EQ(cloud.size(), direct.cloud->size());
  for (std::size_t p = 0; p < cloud.size(); p += 101) {
    EXPECT_EQ(cloud[p].x, (*direct.cloud)[p].x);
    EXPECT_EQ(cloud[p].y, (*direct.cloud)[p].y);
    EXPECT_EQ(cloud[p].z, (*direct.cloud)[p].z);
    EXPECT_EQ(cloud[p].intensity, (*direct.cloud)[p].intensity);
  }
  // int16 millimetres: the driver's values, within half a unit of the points.
  planar_grid::ros_messages::cloudFromMessage(
    typedCloudMessage(*direct.cloud, sensor_msgs::PointField::INT16, 1000.0), "/points",
    cloud);
  ASSERT_EQ(cloud.size(), direct.cloud->size());
  float extent = 0.0f;
  for (std::size_t p = 0; p < cloud.size(); ++p) {
    EXPECT_NEAR(cloud[p].x, 1000.0f * (*direct.cloud)[p].x, 0.5f) << p;
    EXPECT_NEAR(cloud[p].z, 1000.0f * (*direct.cloud)[p].z, 0.5f) << p;
    extent = std::max(extent, std::abs(cloud[p].x));
  }
  EXPECT_GT(extent, 1000.0f); // not collapsed to the origin
  // Three values per coordinate are not a point's x, double or float (a float needs no
  // conversion, and PCL read the first of three as x).
  for (const std::uint8_t datatype :
       {static_cast<std::uint8_t>(sensor_msgs::PointField::FLOAT64),
        static_cast<std::uint8_t>(sensor_msgs::PointField::FLOAT32)}) {
    auto counted = typedCloudMessage(*direct.cloud, datatype, 1.0);
    const std::uint32_t size = pcl::getFieldSize(datatype);
    counted.fields[0].count = 3;
    counted.fields[1].offset = 3 * size;
    counted.fields[2].offset = 4 * size;
    counted.fields[3].offset = 5 * size;
    counted.point_step = 5 * size + 4;
    counted.row_step = counted.point_step * counted.width;
    counted.data.resize(counted.row_step);
    try {
      planar_grid::ros_messages::cloudFromMessage(counted, "/points", cloud);
      ADD_FAILURE() << "a 3-count x of datatype " << int(datatype) << " was accepted";
    } catch (const planar_grid::IOError& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find("/points"), std::string::npos) << what;
      EXPECT_NE(what.find("'x' holds 3 values"), std::string::npos) << what;
    }
  }
}

TEST_F(RosBagInputTest, BadBagsNameTheFileAndTopic)
{
  const std::string bag = writeStereoBag({}, true, "full.bag");
  const std::string no_info = writeStereoBag({}, false, "no_right_info.bag");
  const std::string stages = "pipeline:\n  - type: stereo_disparity\n";
  // A topic the bag does not have.
  std::string what = sourceError(stereoInput(no_info, "") + stages);
  EXPECT_NE(what.find(no_info), std::string::npos) << what;
  EXPECT_NE(what.find("'/right/camera_info'"), std::string::npos) << what;
  EXPECT_NE(what.find("not in the bag"), std::string::npos) << what;
  // A topic of the wrong message type.
  what =
    sourceError("input:\n  type: ros_bag\n  file: " + bag
                + "\n  cloud: /left/image_rect\npipeline:\n  - type: voxel_grid\n");
  EXPECT_NE(what.find("'/left/image_rect'"), std::string::npos) << what;
  EXPECT_NE(what.find("holds sensor_msgs/Image"), std::string::npos) << what;
  EXPECT_NE(what.find("sensor_msgs/PointCloud2"), std::string::npos) << what;
  // A CameraInfo topic that holds images.
  what = sourceError("input:\n  type: ros_bag\n  file: " + bag
                     + "\n  left_image: /left/image_rect\n  right_image: "
                       "/right/image_rect\n  left_camera_info: /left/camera_info\n"
                       "  right_camera_info: /right/image_rect\n"
                       "  max_pair_time_difference_s: 0.005\n"
                     + stages);
  EXPECT_NE(what.find("sensor_msgs/CameraInfo"), std::string::npos) << what;
  // Equal stamps asked for, the right images 2 ms late: no pair.
  what = sourceError("input:\n  type: ros_bag\n  file: " + bag
                     + "\n  left_image: /left/image_rect\n  right_image: "
                       "/right/image_rect\n  left_camera_info: /left/camera_info\n"
                       "  right_camera_info: /right/camera_info\n"
                     + stages);
  EXPECT_NE(what.find("no stereo pair"), std::string::npos) << what;
  // Poses from /tf, which the bag does not have.
  what = sourceError(
    stereoInput(bag,
                "  poses: {format: tf, parent_frame: world, child_frame: camera}\n")
    + stages);
  EXPECT_NE(what.find(bag), std::string::npos) << what;
  EXPECT_NE(what.find("'/tf'"), std::string::npos) << what;
  EXPECT_NE(what.find("not in the bag"), std::string::npos) << what;
  // Not a bag.
  const std::string text = (dir_ / "not_a.bag").string();
  {
    std::ofstream(text) << "not a bag\n";
  }
  what = sourceError("input:\n  type: ros_bag\n  file: " + text
                     + "\n  cloud: /points\npipeline:\n  - type: voxel_grid\n");
  EXPECT_NE(what.find(text), std::string::npos) << what;
}

TEST_F(RosBagInputTest, SwappedImageTopicsAreRefusedBeforeTheFirstFrame)
{
  const std::string bag = writeStereoBag({});
  std::string yaml = stereoInput(bag, "") + "pipeline:\n  - type: stereo_disparity\n";
  const std::string topics =
    "left_image: /left/image_rect\n  right_image: /right/image_rect";
  ASSERT_NE(yaml.find(topics), std::string::npos);
  EXPECT_EQ(sourceErrorOrEmpty(yaml), "");
  yaml.replace(yaml.find(topics), topics.size(),
               "left_image: /right/image_rect\n  right_image: /left/image_rect");
  const std::string what = sourceError(yaml);
  EXPECT_NE(
    what.find(bag + ": /right/image_rect: the left and right images look swapped"),
    std::string::npos)
    << what;
}

TEST_F(RosBagInputTest, TfChainThatDoesNotReachTheFrameIsAnError)
{
  const std::string bag = writeCloudBag();
  const std::string what =
    sourceError("input:\n  type: ros_bag\n  file: " + bag
                + "\n  cloud: /points\n  poses: {format: tf, parent_frame: map, "
                  "child_frame: lidar}\npipeline:\n  - type: voxel_grid\n");
  EXPECT_NE(what.find(bag), std::string::npos) << what;
  EXPECT_NE(what.find("no chain of transforms from 'map' to 'lidar'"),
            std::string::npos)
    << what;
  EXPECT_NE(what.find("world -> lidar"), std::string::npos) << what;
}

TEST_F(RosBagInputTest, ConfigErrorsAtTheirLine)
{
  const auto error = [](const std::string& yaml) {
    try {
      parsePipelineConfig(yaml, "t.yaml", "/");
    } catch (const planar_grid::ConfigError& e) {
      return std::string(e.what());
    }
    ADD_FAILURE() << "no ConfigError for\n" << yaml;
    return std::string();
  };
  const std::string stages = "pipeline:\n  - type: voxel_grid\n";
  std::string what = error("input:\n  type: ros_bag\n  file: a.bag\n  cloud: /p\n"
                           "  left_image: /l\n"
                           + stages);
  EXPECT_NE(what.find("t.yaml:4:"), std::string::npos) << what;
  EXPECT_NE(what.find("not both"), std::string::npos) << what;
  what = error("input:\n  type: ros_bag\n  file: a.bag\n  left_image: /l\n"
               "  right_image: /r\n  left_camera_info: /li\n"
               + stages);
  EXPECT_NE(what.find("'right_camera_info'"), std::string::npos) << what;
  what = error("input:\n  type: ros_bag\n  file: a.bag\n  cloud: /p\n"
               "  poses: {format: odometry}\n"
               + stages);
  EXPECT_NE(what.find("t.yaml:5:"), std::string::npos) << what;
  EXPECT_NE(what.find("expected one of: tf, none"), std::string::npos) << what;
  what = error("input:\n  type: ros_bag\n  file: a.bag\n  cloud: /p\n"
               "  poses: {format: tf, parent_frame: world}\n"
               + stages);
  EXPECT_NE(what.find("child_frame"), std::string::npos) << what;
  // A cloud bag input has no stereo images for stereo_disparity.
  what = error("input:\n  type: ros_bag\n  file: a.bag\n  cloud: /p\n"
               "pipeline:\n  - type: stereo_disparity\n");
  EXPECT_NE(what.find("t.yaml:6:"), std::string::npos) << what;
}

TEST(RosBagExampleConfig, Parses)
{
  const auto config = planar_grid::loadPipelineConfig(
    std::string(PLANAR_GRID_SOURCE_DIR) + "/config/ros_bag_example.yaml");
  EXPECT_EQ(config.input.type, planar_grid::InputConfig::Type::STEREO_SEQUENCE);
  EXPECT_EQ(config.input.ros_bag.left_info_topic, "/stereo/left/camera_info");
  EXPECT_EQ(config.input.poses_format, planar_grid::PoseFormat::TF);
}

} // namespace
