// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <rosbag/bag.h>

#include <map>
#include <string>

namespace planar_grid {

/** \brief One ROS 1 bag opened for reading, with the message type of each of its
 * topics, so that a reader checks a topic's presence and type before it reads a
 * message. Errors name the bag and the input key that names the topic.
 *
 * Including this header needs the ROS bag headers (rosbag/bag.h and the ones it
 * includes: pluginlib, class_loader, rcpputils, rcutils, ament_index_cpp).
 * \ingroup ros_bag */
class RosBagFile {
public:
  /** \brief Opens \a path for reading and lists its topics.
   * \param[in] path the bag file
   * \throws planar_grid::IOError naming the file when rosbag cannot read it */
  explicit RosBagFile(const std::string& path);

  /** \brief The bag's file name, as given, for messages. */
  const std::string& path() const { return path_; }

  /** \brief The open bag, for rosbag::View queries. */
  rosbag::Bag& bag() { return bag_; }

  /** \brief True when the bag has a connection on \a topic. */
  [[nodiscard]] bool has(const std::string& topic) const
  {
    return types_.count(topic) > 0;
  }

  /** \brief Checks that \a topic is in the bag with messages of \a type.
   * \param[in] topic the topic, e.g. /camera/left/image_rect
   * \param[in] type the message type, e.g. sensor_msgs/Image
   * \param[in] key the input key that names the topic, for the message
   * \throws planar_grid::IOError listing the bag's topics when \a topic is not in it,
   * or naming both types when it holds another one */
  void require(const std::string& topic,
               const std::string& type,
               const std::string& key) const;

private:
  /** \brief The bag's file name. */
  std::string path_;
  /** \brief The open bag. */
  rosbag::Bag bag_;
  /** \brief Message type of each topic. */
  std::map<std::string, std::string> types_;
};

} // namespace planar_grid
