// SPDX-License-Identifier: BSD-3-Clause
#include "ros_bag_input.h"

#include <planar_grid/core/exceptions.h>

#include <algorithm>
#include <vector>

#include "input_formats.h"

namespace planar_grid {

InputConfig
parseRosBagInput(const YamlReader& r, const YAML::Node& node)
{
  if (!rosBagSupported())
    r.fail(
      node["type"],
      "input.type ros_bag: this build of PlanarGrid has no ROS bag support (Debian's "
      "librosbag-storage-dev, libsensor-msgs-dev and libtf2-msgs-dev were not found "
      "when it was configured; scripts/install_deps.sh installs them)");
  r.checkKeys(node,
              {"type", "file", "left_image", "right_image", "left_camera_info",
               "right_camera_info", "max_pair_time_difference_s", "cloud",
               "frame_count", "poses"},
              "input (ros_bag)");
  InputConfig input;
  InputConfig::RosBag& bag = input.ros_bag;
  bag.file = r.path(node, "file", "input");
  input.frame_count = r.integer(node, "frame_count", 0, 0, 100000000, "input");

  const std::vector<std::string> stereo_keys{"left_image", "right_image",
                                             "left_camera_info", "right_camera_info"};
  const bool stereo = std::any_of(stereo_keys.begin(), stereo_keys.end(),
                                  [&node](const std::string& k) { return node[k]; });
  if (stereo && node["cloud"])
    r.fail(node["cloud"], "input (ros_bag): give either the stereo topics (left_image, "
                          "right_image, left_camera_info, right_camera_info) or cloud, "
                          "not both");
  if (!stereo && !node["cloud"])
    r.fail(node, "input (ros_bag) needs the stereo topics (left_image, right_image, "
                 "left_camera_info, right_camera_info) or a cloud topic");
  if (stereo) {
    input.type = InputConfig::Type::STEREO_SEQUENCE;
    for (const auto& key : stereo_keys)
      if (!node[key])
        r.fail(node, "input (ros_bag) needs the key '" + key
                       + "': a stereo bag input names all four topics (left_image, "
                         "right_image, left_camera_info, right_camera_info)");
    bag.left_image_topic = r.string(node, "left_image", "input");
    bag.right_image_topic = r.string(node, "right_image", "input");
    bag.left_info_topic = r.string(node, "left_camera_info", "input");
    bag.right_info_topic = r.string(node, "right_camera_info", "input");
    bag.pair_tolerance_s =
      r.real(node, "max_pair_time_difference_s", 0.0, 0.0, 10.0, "input");
  } else {
    input.type = InputConfig::Type::PCD_FILES;
    if (node["max_pair_time_difference_s"])
      r.fail(node["max_pair_time_difference_s"],
             "input.max_pair_time_difference_s is only for stereo topics");
    bag.cloud_topic = r.string(node, "cloud", "input");
  }

  if (const YAML::Node poses = node["poses"]) {
    r.requireMap(poses, "input.poses");
    r.checkKeys(poses,
                {"format", "topic", "static_topic", "parent_frame", "child_frame",
                 "max_time_difference_s"},
                "input.poses (ros_bag)");
    using P = PoseFormat;
    input.poses_format =
      readPoseFormat(r, poses,
                     stereo ? std::vector<P>{P::TF, P::ODOMETRY, P::NONE}
                            : std::vector<P>{P::TF, P::NONE},
                     "ros_bag input");
    if (input.poses_format == P::TF) {
      bag.parent_frame = r.string(poses, "parent_frame", "input.poses");
      bag.child_frame = r.string(poses, "child_frame", "input.poses");
      if (bag.parent_frame == bag.child_frame)
        r.fail(poses["child_frame"],
               "input.poses.child_frame must differ from parent_frame");
      bag.tf_topic = r.optionalString(poses, "topic", bag.tf_topic, "input.poses");
      bag.tf_static_topic =
        r.optionalString(poses, "static_topic", bag.tf_static_topic, "input.poses");
      bag.tf_tolerance_s = r.real(poses, "max_time_difference_s", bag.tf_tolerance_s,
                                  0.0, 10.0, "input.poses");
    } else
      for (const char* key : {"topic", "static_topic", "parent_frame", "child_frame",
                              "max_time_difference_s"})
        if (poses[key])
          r.fail(poses[key],
                 std::string("input.poses.") + key + " is only for format tf");
  }
  return input;
}

} // namespace planar_grid
