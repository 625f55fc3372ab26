// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/visualization/octomap_file.h>

#include <octomap/AbstractOcTree.h>
#include <octomap/OcTree.h>

#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <memory>
#include <sstream>
#include <vector>

namespace planar_grid {

namespace {

/** First lines of liboctomap's two formats (AbstractOccupancyOcTree::binaryFileHeader,
 * AbstractOcTree::fileHeader). */
constexpr const char* BINARY_HEADER = "# Octomap OcTree binary file";
constexpr const char* FULL_HEADER = "# Octomap OcTree file";
/** OctoMap's tree depth: leaves at depth 16 below the root. */
constexpr int TREE_DEPTH = 16;
/** The header is a few short lines; a longer one is not an OctoMap file. */
constexpr std::size_t MAX_OCTOMAP_HEADER_BYTES = 64 * 1024;

/** The parsed header and where the node stream starts. */
struct Header {
  bool binary{false};
  std::string id;
  std::uint64_t size{0};
  double resolution_m{0.0};
  std::size_t data_offset{0};
};

/** Walks the node stream from \a offset: throws on a truncated stream, a node below
 * depth 16, a non-finite log-odds; returns the offset after the last node. */
class NodeWalker {
public:
  NodeWalker(const std::string& path, const std::vector<char>& bytes, bool binary) :
      path_(path), bytes_(bytes), binary_(binary)
  {}

  std::size_t walk(std::size_t offset)
  {
    offset_ = offset;
    node(0);
    return offset_;
  }

private:
  void need(std::size_t n)
  {
    if (bytes_.size() - offset_ < n)
      throw IOError(path_ + ": truncated: the octree's node stream ends at byte "
                    + std::to_string(bytes_.size()) + " inside a node");
  }

  void node(int depth)
  {
    if (binary_) {
      // Two bytes: 2 bits per child (10 free leaf, 01 occupied leaf, 11 inner node, 00
      // none), children 0-3 in the first byte; the inner children follow in order.
      need(2);
      const auto a = static_cast<std::uint8_t>(bytes_[offset_]);
      const auto b = static_cast<std::uint8_t>(bytes_[offset_ + 1]);
      offset_ += 2;
      const std::uint16_t bits = static_cast<std::uint16_t>(a | (b << 8));
      for (int child = 0; child < 8; ++child)
        if (((bits >> (2 * child)) & 3u) == 3u)
          inner(depth);
      return;
    }
    // A float log-odds, then an 8-bit mask of the children that follow in order.
    need(5);
    float log_odds = 0.0f;
    std::memcpy(&log_odds, bytes_.data() + offset_, sizeof(float));
    if (!std::isfinite(log_odds))
      throw IOError(path_ + ": corrupt: a non-finite log-odds at byte "
                    + std::to_string(offset_));
    const auto mask = static_cast<std::uint8_t>(bytes_[offset_ + 4]);
    offset_ += 5;
    for (int child = 0; child < 8; ++child)
      if ((mask >> child) & 1u)
        inner(depth);
  }

  /** A child of a node at \a depth that has a node record of its own. */
  void inner(int depth)
  {
    // A binary inner child has children; a full-format child is any node. Either is
    // at depth + 1, and only a binary inner child must be above the leaves' depth.
    if (depth + 1 > TREE_DEPTH || (binary_ && depth + 1 == TREE_DEPTH))
      throw IOError(path_ + ": corrupt: the octree is deeper than OctoMap's "
                    + std::to_string(TREE_DEPTH) + " levels (byte "
                    + std::to_string(offset_) + ")");
    node(depth + 1);
  }

  const std::string& path_;
  const std::vector<char>& bytes_;
  bool binary_;
  std::size_t offset_{0};
};

Header
readHeader(const std::string& path, const std::vector<char>& bytes)
{
  Header header;
  std::size_t pos = 0;
  const auto nextLine = [&]() {
    const std::size_t end = std::min(bytes.size(), MAX_OCTOMAP_HEADER_BYTES);
    std::string line;
    while (pos < end && bytes[pos] != '\n')
      line.push_back(bytes[pos++]);
    if (pos >= end)
      throw IOError(path + ": not an OctoMap file: no 'data' line ends its header");
    ++pos;
    return line;
  };
  const std::string first = nextLine();
  if (first.rfind(BINARY_HEADER, 0) == 0)
    header.binary = true;
  else if (first.rfind(FULL_HEADER, 0) != 0)
    throw IOError(path + ": not an OctoMap file: the first line is not '"
                  + BINARY_HEADER + "' (.bt) or '" + FULL_HEADER + "' (.ot)");
  bool has_size = false, has_res = false;
  while (true) {
    std::istringstream in(nextLine());
    std::string key;
    if (!(in >> key) || key[0] == '#')
      continue;
    if (key == "data")
      break;
    if (key == "id") {
      in >> header.id;
    } else if (key == "size") {
      long long size = -1;
      if (!(in >> size) || size < 0)
        throw IOError(path + ": not an OctoMap file: 'size' must be a count of nodes");
      header.size = static_cast<std::uint64_t>(size);
      has_size = true;
    } else if (key == "res") {
      if (!(in >> header.resolution_m) || !std::isfinite(header.resolution_m)
          || !(header.resolution_m > 0.0))
        throw IOError(path + ": not an OctoMap file: 'res' must be a resolution > 0");
      has_res = true;
    }
  }
  if (header.id != "OcTree")
    throw IOError(path + ": id '" + header.id
                  + "' is not an occupancy octree: the viewer reads id OcTree (what "
                    "octomap::OcTree and planar_grid_pipeline write)");
  if (!has_size || !has_res)
    throw IOError(path + ": not an OctoMap file: the header needs 'size' and 'res'");
  header.data_offset = pos;
  return header;
}

std::vector<char>
readAll(const std::string& path)
{
  checkInputFile(path, "an OctoMap file");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw IOError(path + ": cannot be opened: " + std::strerror(errno));
  std::vector<char> bytes{std::istreambuf_iterator<char>(in),
                          std::istreambuf_iterator<char>()};
  if (in.bad())
    throw IOError(path + ": read error");
  if (bytes.empty())
    throw IOError(path + ": not an OctoMap file: the file is empty (0 bytes)");
  return bytes;
}

Header
checkBytes(const std::string& path, const std::vector<char>& bytes)
{
  const Header header = readHeader(path, bytes);
  std::size_t end = header.data_offset;
  if (header.size > 0)
    end = NodeWalker(path, bytes, header.binary).walk(header.data_offset);
  if (end != bytes.size())
    throw IOError(path + ": corrupt: " + std::to_string(bytes.size() - end)
                  + " bytes of trailing data after the octree");
  return header;
}

} // namespace

void
checkOctoMapFile(const std::string& path)
{
  checkBytes(path, readAll(path));
}

OctoMapLeaves
loadOctoMapLeaves(const std::string& path, std::size_t max_boxes)
{
  const std::vector<char> bytes = readAll(path);
  const Header header = checkBytes(path, bytes);
  std::unique_ptr<octomap::OcTree> tree;
  std::istringstream in(std::string(bytes.begin(), bytes.end()), std::ios::binary);
  if (header.binary) {
    tree = std::make_unique<octomap::OcTree>(header.resolution_m);
    if (!tree->readBinary(in))
      throw IOError(path + ": liboctomap could not read the binary octree");
  } else {
    tree.reset(dynamic_cast<octomap::OcTree*>(octomap::AbstractOcTree::read(in)));
    if (!tree)
      throw IOError(path + ": liboctomap could not read the octree");
  }
  OctoMapLeaves leaves;
  leaves.resolution_m = tree->getResolution();
  for (auto it = tree->begin_leafs(); it != tree->end_leafs(); ++it) {
    const auto voxels = std::size_t{1}
                        << (3 * (TREE_DEPTH - static_cast<int>(it.getDepth())));
    if (!tree->isNodeOccupied(*it)) {
      leaves.free_voxels += voxels;
      continue;
    }
    leaves.occupied_voxels += voxels;
    if (leaves.occupied.size() >= max_boxes)
      continue;
    PlanarCuboid box;
    const octomap::point3d c = it.getCoordinate();
    box.centre = Eigen::Vector3f(c.x(), c.y(), c.z());
    box.normal = Eigen::Vector3f::UnitZ();
    box.horizontal_axis = Eigen::Vector3f::UnitX();
    box.width_m = box.height_m = box.thickness_m = static_cast<float>(it.getSize());
    box.probability = static_cast<float>(it->getOccupancy());
    leaves.occupied.push_back(box);
  }
  return leaves;
}

} // namespace planar_grid
