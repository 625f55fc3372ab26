// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/ros_bag/ros_bag_file.h>

#include <rosbag/view.h>

namespace planar_grid {

RosBagFile::RosBagFile(const std::string& path) : path_(path)
{
  try {
    bag_.open(path, rosbag::bagmode::Read);
  } catch (const rosbag::BagException& e) {
    throw IOError(path + ": cannot read the ROS bag (" + e.what() + ")");
  }
  rosbag::View all(bag_);
  for (const rosbag::ConnectionInfo* c : all.getConnections())
    types_[c->topic] = c->datatype;
}

void
RosBagFile::require(const std::string& topic,
                    const std::string& type,
                    const std::string& key) const
{
  const auto found = types_.find(topic);
  if (found == types_.end()) {
    std::string topics;
    for (const auto& [name, datatype] : types_)
      topics += (topics.empty() ? "" : ", ") + name + " (" + datatype + ")";
    throw IOError(path_ + ": topic '" + topic + "' (" + key
                  + ") is not in the bag; its topics: "
                  + (topics.empty() ? "none" : topics));
  }
  if (found->second != type)
    throw IOError(path_ + ": topic '" + topic + "' (" + key + ") holds " + found->second
                  + " messages; " + type + " is needed");
}

} // namespace planar_grid
