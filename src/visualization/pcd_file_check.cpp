// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/pcd_file_check.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/io/pcd_io.h>

#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>

namespace planar_grid {

namespace {

/** The first line of a planar grid map file (PlanarGridMap::save()). */
constexpr const char* MAP_MAGIC_LINE = "# Planar grid map file";
/** A PCD header line is short; a longer "line" is binary data, not a header. */
constexpr std::size_t MAX_HEADER_LINE = 4096;

/** The first line of \a in that is not a comment, at most MAX_HEADER_LINE bytes; sets
 * \a first_line to the very first line. */
std::string
firstHeaderLine(std::istream& in, std::string& first_line)
{
  std::string line;
  bool first = true;
  while (true) {
    line.clear();
    char c = 0;
    while (in.get(c) && c != '\n' && line.size() < MAX_HEADER_LINE)
      line.push_back(c);
    if (first)
      first_line = line;
    first = false;
    if (!in || line.size() >= MAX_HEADER_LINE)
      return line;
    if (!line.empty() && line[0] != '#')
      return line;
  }
}

} // namespace

void
checkPCDFile(const std::string& path)
{
  namespace fs = std::filesystem;
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw IOError(path + ": no such file");
  if (!fs::is_regular_file(path, ec))
    throw IOError(path + ": not a regular file");
  const std::uintmax_t file_size = fs::file_size(path, ec);
  if (ec)
    throw IOError(path + ": cannot read its size: " + ec.message());
  if (file_size == 0)
    throw IOError(path + ": not a PCD file: the file is empty (0 bytes)");

  {
    std::ifstream in(path, std::ios::binary);
    if (!in)
      throw IOError(path + ": cannot be opened: " + std::strerror(errno));
    std::string first_line;
    const std::string line = firstHeaderLine(in, first_line);
    if (first_line == MAP_MAGIC_LINE)
      throw IOError(path
                    + ": not a PCD file: it is a planar grid map (.pgmap) file; "
                      "give it the .pgmap extension to view it as a map");
    const std::string keyword = line.substr(0, line.find(' '));
    if (keyword != "VERSION" && keyword != "FIELDS")
      throw IOError(path
                    + ": not a PCD file: its header does not start with VERSION "
                      "or FIELDS");
  }

  pcl::PCDReader reader;
  pcl::PCLPointCloud2 header;
  Eigen::Vector4f origin;
  Eigen::Quaternionf orientation;
  int pcd_version = 0, data_type = 0;
  unsigned int data_idx = 0;
  if (reader.readHeader(path, header, origin, orientation, pcd_version, data_type,
                        data_idx)
      < 0)
    throw IOError(path + ": not a readable PCD file (bad header)");
  if (header.fields.empty())
    throw IOError(path + ": not a PCD file: the header has no FIELDS");
  std::uint64_t point_bytes = 0;
  for (const auto& field : header.fields) {
    const int size = pcl::getFieldSize(field.datatype);
    if (size <= 0 || field.count == 0)
      throw IOError(path + ": field '" + field.name
                    + "' has an unknown type or a count of 0");
    point_bytes += static_cast<std::uint64_t>(size) * field.count;
  }
  const std::uint64_t points = static_cast<std::uint64_t>(header.width) * header.height;
  const std::uint64_t data_bytes = points * point_bytes;
  // ASCII: PCL reads it line by line and stops at the end of the file; no points: no
  // data to check.
  if (data_type == 0 || points == 0)
    return;
  if (data_idx > file_size)
    throw IOError(path + ": truncated: the header ends past the end of the file");
  const std::uint64_t after_header = file_size - data_idx;
  if (data_type == 1) {
    if (data_bytes > after_header)
      throw IOError(path + ": truncated: the header declares " + std::to_string(points)
                    + " points of " + std::to_string(point_bytes) + " bytes ("
                    + std::to_string(data_bytes) + " bytes), the file has "
                    + std::to_string(after_header) + " bytes of data");
    return;
  }
  // Binary compressed: two little-endian uint32 (compressed, uncompressed size), then
  // the LZF-compressed data.
  std::uint32_t sizes[2] = {0, 0};
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(data_idx));
  if (after_header < sizeof(sizes)
      || !in.read(reinterpret_cast<char*>(sizes), sizeof(sizes)))
    throw IOError(path + ": truncated: no compressed data sizes after the header");
  if (sizes[0] > after_header - sizeof(sizes))
    throw IOError(path + ": truncated: the compressed data are "
                  + std::to_string(sizes[0]) + " bytes, the file has "
                  + std::to_string(after_header - sizeof(sizes)) + " after the header");
  if (sizes[1] != data_bytes)
    throw IOError(path + ": the compressed data unpack to " + std::to_string(sizes[1])
                  + " bytes, but the header declares " + std::to_string(points)
                  + " points of " + std::to_string(point_bytes) + " bytes ("
                  + std::to_string(data_bytes) + " bytes)");
}

} // namespace planar_grid
