// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_octomap_check: rebuilds the trees of serialized octomap_msgs/Octomap
// messages with liboctomap, as a subscriber such as MoveIt or octomap_rviz_plugins does
// (octomap_msgs' conversions.h: binaryMsgToMap, fullMsgToMap), and counts them beside
// an OctoMap .bt file, for the ROS node's test (test_ros_node.py, docs/ROS.md).
//   planar_grid_octomap_check [--binary-msg FILE] [--full-msg FILE] [--bt FILE]
//                             [--occupancy-thres P]
// FILE of a message: its ROS serialization (what a subscriber receives, without the
// length prefix). Prints one JSON object: per input its header, id, resolution and the
// tree's nodes, leaves and occupied / free leaves and voxels, as liboctomap counts
// them; for the full message also the same counts after its conversion to maximum
// likelihood at P (the map's occupancy_thres, default 0.5) and complete pruning, which
// is what the binary format keeps; "binary_data_equals_bt": whether the binary
// message's data are the .bt file's data section byte for byte.
#include <nlohmann/json.hpp>
#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>
#include <octomap_msgs/Octomap.h>
#include <ros/serialization.h>

#include <algorithm>
#include <cstdint>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <iterator>
#include <memory>
#include <sstream>
#include <stdexcept>
#include <string>
#include <vector>

namespace {

/** The whole content of \a path. \throws std::runtime_error when it cannot be read */
std::string
readFile(const std::string& path)
{
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw std::runtime_error("cannot open " + path);
  return std::string(std::istreambuf_iterator<char>(in),
                     std::istreambuf_iterator<char>());
}

/** The message serialized in \a path, deserialized by roscpp's generated serializer. */
octomap_msgs::Octomap
readMessage(const std::string& path)
{
  std::string bytes = readFile(path);
  octomap_msgs::Octomap msg;
  ros::serialization::IStream stream(reinterpret_cast<std::uint8_t*>(bytes.data()),
                                     static_cast<std::uint32_t>(bytes.size()));
  ros::serialization::deserialize(stream, msg);
  return msg;
}

/** Collapses every node of \a node's subtree whose eight children are leaves of one
 * value, bottom-up (OctoMap's pruning at every depth). */
void
pruneSubtree(octomap::OcTree& tree, octomap::OcTreeNode* node)
{
  if (!tree.nodeHasChildren(node))
    return;
  for (unsigned child = 0; child < 8; ++child)
    if (tree.nodeChildExists(node, child))
      pruneSubtree(tree, tree.getNodeChild(node, child));
  tree.pruneNode(node);
}

/** Nodes, leaves, occupied / free leaves and voxels of \a tree (a leaf at depth d
 * holds 8^(tree depth - d) voxels; occupied at the tree's occupancy threshold). */
nlohmann::ordered_json
counts(const octomap::OcTree& tree)
{
  std::size_t occupied_leaves = 0, free_leaves = 0;
  std::uint64_t occupied_voxels = 0, free_voxels = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    const std::uint64_t voxels = std::uint64_t{1}
                                 << (3 * (tree.getTreeDepth() - it.getDepth()));
    if (tree.isNodeOccupied(*it)) {
      ++occupied_leaves;
      occupied_voxels += voxels;
    } else {
      ++free_leaves;
      free_voxels += voxels;
    }
  }
  nlohmann::ordered_json j;
  j["nodes"] = tree.size();
  j["leaf_nodes"] = tree.getNumLeafNodes();
  j["occupied_leaves"] = occupied_leaves;
  j["free_leaves"] = free_leaves;
  j["occupied_voxels"] = occupied_voxels;
  j["free_voxels"] = free_voxels;
  return j;
}

/** The message's fields but its data. */
nlohmann::ordered_json
describe(const octomap_msgs::Octomap& msg)
{
  nlohmann::ordered_json j;
  j["frame_id"] = msg.header.frame_id;
  j["stamp"] = msg.header.stamp.toSec();
  j["binary"] = static_cast<bool>(msg.binary);
  j["id"] = msg.id;
  j["resolution"] = msg.resolution;
  j["data_bytes"] = msg.data.size();
  return j;
}

/** The message's data as a stream, as conversions.h reads them. */
std::stringstream
dataStream(const octomap_msgs::Octomap& msg)
{
  std::stringstream data;
  data.write(reinterpret_cast<const char*>(msg.data.data()),
             static_cast<std::streamsize>(msg.data.size()));
  return data;
}

} // namespace

int
main(int argc, char** argv)
{
  std::string binary_path, full_path, bt_path;
  double occupancy_thres = 0.5;
  for (int i = 1; i < argc; ++i) {
    const std::string key = argv[i];
    if (i + 1 >= argc) {
      std::cerr << "planar_grid_octomap_check: " << key << " needs a value\n";
      return EXIT_FAILURE;
    }
    const std::string value = argv[++i];
    if (key == "--binary-msg")
      binary_path = value;
    else if (key == "--full-msg")
      full_path = value;
    else if (key == "--bt")
      bt_path = value;
    else if (key == "--occupancy-thres")
      occupancy_thres = std::stod(value);
    else {
      std::cerr << "planar_grid_octomap_check: unknown option " << key << "\n";
      return EXIT_FAILURE;
    }
  }
  try {
    nlohmann::ordered_json out = nlohmann::ordered_json::object();
    octomap_msgs::Octomap binary_msg;
    if (!binary_path.empty()) {
      // conversions.h's binaryMsgToMap: an OcTree of the message's resolution reads
      // the data with readBinaryData.
      binary_msg = readMessage(binary_path);
      if (!binary_msg.binary || binary_msg.id != "OcTree")
        throw std::runtime_error(binary_path + ": not a binary OcTree message");
      octomap::OcTree tree(binary_msg.resolution);
      std::stringstream data = dataStream(binary_msg);
      tree.readBinaryData(data);
      auto& j = out["binary"] = describe(binary_msg);
      j.update(counts(tree));
    }
    if (!full_path.empty()) {
      // conversions.h's fullMsgToMap: AbstractOcTree::createTree(id, resolution), then
      // readData.
      const octomap_msgs::Octomap msg = readMessage(full_path);
      if (msg.binary)
        throw std::runtime_error(full_path + ": a binary message, not a full one");
      std::unique_ptr<octomap::AbstractOcTree> created(
        octomap::AbstractOcTree::createTree(msg.id, msg.resolution));
      auto* tree = dynamic_cast<octomap::OcTree*>(created.get());
      if (tree == nullptr)
        throw std::runtime_error(full_path + ": id '" + msg.id + "' is no OcTree");
      std::stringstream data = dataStream(msg);
      tree->readData(data);
      auto& j = out["full"] = describe(msg);
      j.update(counts(*tree));
      tree->setOccupancyThres(occupancy_thres);
      tree->toMaxLikelihood();
      tree->updateInnerOccupancy();
      if (tree->getRoot() != nullptr)
        pruneSubtree(*tree, tree->getRoot());
      out["full_max_likelihood"] = counts(*tree);
    }
    if (!bt_path.empty()) {
      octomap::OcTree tree(0.1);
      if (!tree.readBinary(bt_path))
        throw std::runtime_error("liboctomap cannot read " + bt_path);
      auto& j = out["bt"] = nlohmann::ordered_json::object();
      j["resolution"] = tree.getResolution();
      j.update(counts(tree));
      if (!binary_path.empty()) {
        // The .bt file: a text header up to the line "data", then writeBinaryData().
        const std::string file = readFile(bt_path);
        const std::size_t start = file.find("\ndata\n");
        const std::string section =
          start == std::string::npos ? std::string() : file.substr(start + 6);
        out["binary_data_equals_bt"] =
          section.size() == binary_msg.data.size()
          && std::equal(
            section.begin(), section.end(), binary_msg.data.begin(),
            [](char a, std::int8_t b) { return a == static_cast<char>(b); });
      }
    }
    std::cout << out.dump() << std::endl;
  } catch (const std::exception& e) {
    std::cerr << "planar_grid_octomap_check: " << e.what() << "\n";
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
