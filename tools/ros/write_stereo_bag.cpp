// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_write_stereo_bag: writes the first frames of a stereo sequence
// configuration to a ROS 1 bag, as a rectified stereo camera driver and a localisation
// would publish them (the ROS node's test plays it; docs/ROS.md):
//   /stereo/left/image_rect, /stereo/right/image_rect   sensor_msgs/Image, mono8
//   /stereo/left/camera_info, /stereo/right/camera_info sensor_msgs/CameraInfo, P with
//                                                       Tx = -f B in the right one
//   /tf                                                 world -> camera, the input's
//   pose (--parent-frame names another frame than world; --no-tf writes no /tf, as a
//   stereo camera alone records, and needs no poses in the configuration)
// Frame k is stamped t0 + k / rate; the two images of a pair share their stamp.
//   planar_grid_write_stereo_bag --config C.yaml --frames N --output out.bag [--rate
//   HZ] [--parent-frame FRAME] [--no-tf]
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/ros_bag/ros_messages.h>

#include <rosbag/bag.h>
#include <tf2_msgs/TFMessage.h>

#include <cstdlib>
#include <iostream>
#include <string>

namespace {

namespace ros_messages = planar_grid::ros_messages;

/** The stamp of the first frame: the Karlsruhe recording's day, seconds. */
constexpr double T0 = 1268149800.0;

tf2_msgs::TFMessage
poseMessage(const Eigen::Isometry3d& world_T_camera,
            const std::string& parent_frame,
            const ros::Time& stamp)
{
  tf2_msgs::TFMessage message;
  message.transforms.push_back(planar_grid::ros_messages::transformStamped(
    world_T_camera, parent_frame, "camera", stamp));
  return message;
}

} // namespace

int
main(int argc, char** argv)
{
  std::string config_path, output;
  std::string parent_frame = "world";
  long frames = 0;
  double rate_hz = 9.4;
  bool write_tf = true;
  bool usage_error = false;
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (key == "--no-tf") {
      write_tf = false;
      continue;
    }
    if (i + 1 >= argc) {
      usage_error = true;
      break;
    }
    if (key == "--config")
      config_path = argv[i + 1];
    else if (key == "--frames")
      frames = std::strtol(argv[i + 1], nullptr, 10);
    else if (key == "--output")
      output = argv[i + 1];
    else if (key == "--rate")
      rate_hz = std::strtod(argv[i + 1], nullptr);
    else if (key == "--parent-frame")
      parent_frame = argv[i + 1];
    else {
      std::cerr << "planar_grid_write_stereo_bag: unknown option " << key << "\n";
      return 2;
    }
    ++i;
  }
  if (usage_error || config_path.empty() || output.empty() || frames <= 0
      || !(rate_hz > 0.0) || parent_frame.empty()) {
    std::cerr << "usage: planar_grid_write_stereo_bag --config C.yaml --frames N "
                 "--output out.bag [--rate HZ] [--parent-frame FRAME] [--no-tf]\n";
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
      if (write_tf && !frame.has_pose)
        throw planar_grid::Exception(config_path + ": frame " + std::to_string(k)
                                     + " has no pose");
      const auto& c = frame.calibration;
      const ros::Time stamp(T0 + static_cast<double>(k) / rate_hz);
      if (write_tf)
        bag.write("/tf", stamp, poseMessage(frame.world_T_camera, parent_frame, stamp));
      bag.write("/stereo/left/camera_info", stamp,
                ros_messages::cameraInfo(c, 0.0, stamp, "camera"));
      bag.write("/stereo/right/camera_info", stamp,
                ros_messages::cameraInfo(c, -c.focal_length_px * c.baseline_m, stamp,
                                         "camera"));
      bag.write("/stereo/left/image_rect", stamp,
                ros_messages::monoImage(frame.left, stamp, "camera"));
      bag.write("/stereo/right/image_rect", stamp,
                ros_messages::monoImage(frame.right, stamp, "camera"));
    }
    bag.close();
  } catch (const std::exception& e) {
    std::cerr << "planar_grid_write_stereo_bag: " << e.what() << "\n";
    return 1;
  }
  return 0;
}
