// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_write_stereo_bag: writes the first frames of a stereo sequence
// configuration to a ROS 1 bag, as a rectified stereo camera driver and a localisation
// would publish them (the ROS node's test plays it; docs/ROS.md):
//   /stereo/left/image_rect, /stereo/right/image_rect   sensor_msgs/Image, mono8
//   /stereo/left/camera_info, /stereo/right/camera_info sensor_msgs/CameraInfo, P with
//                                                       Tx = -f B in the right one
//   /tf                                                 world -> camera, the input's
//   pose
// Frame k is stamped t0 + k / rate; the two images of a pair share their stamp.
//   planar_grid_write_stereo_bag --config C.yaml --frames N --output out.bag [--rate
//   HZ]
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <rosbag/bag.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdlib>
#include <iostream>
#include <string>

namespace {

/** The stamp of the first frame: the Karlsruhe recording's day, seconds. */
constexpr double T0 = 1268149800.0;

sensor_msgs::Image
imageMessage(const cv::Mat& grey, const ros::Time& stamp)
{
  sensor_msgs::Image image;
  image.header.stamp = stamp;
  image.header.frame_id = "camera";
  image.height = static_cast<std::uint32_t>(grey.rows);
  image.width = static_cast<std::uint32_t>(grey.cols);
  image.encoding = "mono8";
  image.step = image.width;
  const cv::Mat packed = grey.isContinuous() ? grey : grey.clone();
  image.data.assign(packed.datastart, packed.dataend);
  return image;
}

sensor_msgs::CameraInfo
cameraInfo(const planar_grid::StereoCalibration& c, double tx, const ros::Time& stamp)
{
  sensor_msgs::CameraInfo info;
  info.header.stamp = stamp;
  info.header.frame_id = "camera";
  info.width = static_cast<std::uint32_t>(c.width);
  info.height = static_cast<std::uint32_t>(c.height);
  info.P = {c.focal_length_px, 0.0, c.cx_px, tx,  0.0, c.focal_length_px,
            c.cy_px,           0.0, 0.0,     0.0, 1.0, 0.0};
  return info;
}

tf2_msgs::TFMessage
poseMessage(const Eigen::Isometry3d& world_T_camera, const ros::Time& stamp)
{
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = "world";
  t.child_frame_id = "camera";
  const Eigen::Quaterniond q(world_T_camera.linear());
  t.transform.rotation.w = q.w();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  t.transform.translation.x = world_T_camera.translation().x();
  t.transform.translation.y = world_T_camera.translation().y();
  t.transform.translation.z = world_T_camera.translation().z();
  tf2_msgs::TFMessage message;
  message.transforms.push_back(t);
  return message;
}

} // namespace

int
main(int argc, char** argv)
{
  std::string config_path, output;
  long frames = 0;
  double rate_hz = 9.4;
  for (int i = 1; i + 1 < argc; i += 2) {
    const std::string key = argv[i];
    if (key == "--config")
      config_path = argv[i + 1];
    else if (key == "--frames")
      frames = std::strtol(argv[i + 1], nullptr, 10);
    else if (key == "--output")
      output = argv[i + 1];
    else if (key == "--rate")
      rate_hz = std::strtod(argv[i + 1], nullptr);
    else {
      std::cerr << "planar_grid_write_stereo_bag: unknown option " << key << "\n";
      return 2;
    }
  }
  if (config_path.empty() || output.empty() || frames <= 0 || !(rate_hz > 0.0)) {
    std::cerr << "usage: planar_grid_write_stereo_bag --config C.yaml --frames N "
                 "--output out.bag [--rate HZ]\n";
    return 2;
  }
  try {
    const auto config = planar_grid::loadPipelineConfig(config_path);
    const auto source = planar_grid::createFrameSource(config.input);
    if (static_cast<std::size_t>(frames) > source->size())
      throw planar_grid::Exception(config_path + " has only "
                                   + std::to_string(source->size()) + " frames");
    rosbag::Bag bag(output, rosbag::bagmode::Write);
    for (long k = 0; k < frames; ++k) {
      planar_grid::Frame frame;
      source->load(static_cast<std::size_t>(k), frame);
      if (!frame.has_pose)
        throw planar_grid::Exception(config_path + ": frame " + std::to_string(k)
                                     + " has no pose");
      const auto& c = frame.calibration;
      const ros::Time stamp(T0 + static_cast<double>(k) / rate_hz);
      bag.write("/tf", stamp, poseMessage(frame.world_T_camera, stamp));
      bag.write("/stereo/left/camera_info", stamp, cameraInfo(c, 0.0, stamp));
      bag.write("/stereo/right/camera_info", stamp,
                cameraInfo(c, -c.focal_length_px * c.baseline_m, stamp));
      bag.write("/stereo/left/image_rect", stamp, imageMessage(frame.left, stamp));
      bag.write("/stereo/right/image_rect", stamp, imageMessage(frame.right, stamp));
    }
    bag.close();
  } catch (const std::exception& e) {
    std::cerr << "planar_grid_write_stereo_bag: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
