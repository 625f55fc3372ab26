// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/visualization/mesh_file.h>

#include <pcl/common/io.h>
#include <pcl/io/ply_io.h>

#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <map>
#include <sstream>
#include <vector>

namespace planar_grid {

namespace {

/** A header is a few hundred bytes; anything longer is not a PLY header. */
constexpr std::size_t MAX_PLY_HEADER_BYTES = 64 * 1024;

/** Bytes of a PLY scalar type, 0 for an unknown name (both spellings of the spec). */
std::size_t
typeBytes(const std::string& type)
{
  static const std::map<std::string, std::size_t> sizes{
    {"char", 1},  {"uchar", 1},   {"int8", 1},   {"uint8", 1},
    {"short", 2}, {"ushort", 2},  {"int16", 2},  {"uint16", 2},
    {"int", 4},   {"uint", 4},    {"int32", 4},  {"uint32", 4},
    {"float", 4}, {"float32", 4}, {"double", 8}, {"float64", 8}};
  const auto it = sizes.find(type);
  return it == sizes.end() ? 0 : it->second;
}

/** One "element" of the header: its count and the least bytes one instance takes. */
struct Element {
  std::string name;
  std::uint64_t count{0};
  std::uint64_t min_bytes{0};
  std::uint64_t values{0};
  bool x{false}, y{false}, z{false};
};

} // namespace

void
checkPLYFile(const std::string& path)
{
  const std::uintmax_t file_size = checkInputFile(path, "a PLY file");
  std::ifstream in(path, std::ios::binary);
  if (!in)
    throw IOError(path + ": cannot be opened: " + std::strerror(errno));

  std::string header(
    static_cast<std::size_t>(std::min<std::uintmax_t>(file_size, MAX_PLY_HEADER_BYTES)),
    '\0');
  in.read(header.data(), static_cast<std::streamsize>(header.size()));
  header.resize(static_cast<std::size_t>(in.gcount()));
  const std::size_t end = header.find("end_header");
  if (header.rfind("ply", 0) != 0
      || (header.size() > 3 && header[3] != '\n' && header[3] != '\r'))
    throw IOError(path + ": not a PLY file: the first line is not 'ply'");
  if (end == std::string::npos)
    throw IOError(path + ": not a PLY file: no 'end_header' line in the first "
                  + std::to_string(MAX_PLY_HEADER_BYTES) + " bytes");
  std::size_t data_offset = header.find('\n', end);
  data_offset = data_offset == std::string::npos ? header.size() : data_offset + 1;

  std::istringstream lines(header.substr(0, end));
  std::string line, format;
  std::vector<Element> elements;
  int line_number = 0;
  while (std::getline(lines, line)) {
    ++line_number;
    if (line_number == 1)
      continue;
    std::istringstream words(line);
    std::string keyword;
    if (!(words >> keyword) || keyword == "comment" || keyword == "obj_info")
      continue;
    const auto fail = [&](const std::string& what) {
      throw IOError(path + ":" + std::to_string(line_number)
                    + ": not a PLY file: " + what);
    };
    if (keyword == "format") {
      std::string version;
      words >> format >> version;
      if (format != "ascii" && format != "binary_little_endian"
          && format != "binary_big_endian")
        fail("unknown format '" + format + "'");
    } else if (keyword == "element") {
      Element element;
      long long count = -1;
      if (!(words >> element.name >> count) || count < 0)
        fail("an element needs a name and a count >= 0");
      element.count = static_cast<std::uint64_t>(count);
      elements.push_back(element);
    } else if (keyword == "property") {
      if (elements.empty())
        fail("a property before any element");
      std::string type, name;
      words >> type;
      std::size_t bytes = 0;
      if (type == "list") {
        std::string count_type, item_type;
        words >> count_type >> item_type >> name;
        bytes = typeBytes(count_type); // a list of no entries: its count alone
        if (bytes == 0 || typeBytes(item_type) == 0)
          fail("unknown list type '" + count_type + " " + item_type + "'");
      } else {
        words >> name;
        bytes = typeBytes(type);
        if (bytes == 0)
          fail("unknown property type '" + type + "'");
      }
      Element& element = elements.back();
      element.min_bytes += bytes;
      element.values += 1;
      element.x = element.x || name == "x";
      element.y = element.y || name == "y";
      element.z = element.z || name == "z";
    } else {
      fail("unknown header keyword '" + keyword + "'");
    }
  }
  if (format.empty())
    throw IOError(path + ": not a PLY file: the header has no 'format' line");
  const Element* vertex = nullptr;
  for (const auto& element : elements)
    if (element.name == "vertex")
      vertex = &element;
  if (vertex == nullptr || !vertex->x || !vertex->y || !vertex->z)
    throw IOError(path + ": the PLY file has no vertex element with x, y and z");

  // The least data the header declares (ASCII: a digit and a separator per value).
  const std::uint64_t data_bytes = file_size - data_offset;
  std::uint64_t needed = 0;
  for (const auto& element : elements) {
    const std::uint64_t each =
      format == "ascii" ? 2 * element.values : element.min_bytes;
    if (each > 0 && element.count > (data_bytes - needed) / each)
      throw IOError(path + ": truncated: the header declares "
                    + std::to_string(element.count) + " " + element.name
                    + " elements, the file has " + std::to_string(data_bytes)
                    + " bytes of data");
    needed += element.count * each;
  }
}

pcl::PolygonMesh
loadPLYMesh(const std::string& path)
{
  checkPLYFile(path);
  pcl::PolygonMesh mesh;
  if (pcl::io::loadPLYFile(path, mesh) < 0)
    throw IOError(path + ": cannot load the PLY file");
  if (pcl::getFieldIndex(mesh.cloud, "x") < 0 || pcl::getFieldIndex(mesh.cloud, "y") < 0
      || pcl::getFieldIndex(mesh.cloud, "z") < 0)
    throw IOError(path + ": the PLY mesh has no x, y, z vertex fields");
  const std::uint64_t n_vertices =
    static_cast<std::uint64_t>(mesh.cloud.width) * mesh.cloud.height;
  for (std::size_t k = 0; k < mesh.polygons.size(); ++k) {
    const auto& vertices = mesh.polygons[k].vertices;
    if (vertices.size() < 3)
      throw IOError(path + ": face " + std::to_string(k) + " has "
                    + std::to_string(vertices.size()) + " vertices (at least 3)");
    for (const auto index : vertices)
      if (index < 0 || static_cast<std::uint64_t>(index) >= n_vertices)
        throw IOError(path + ": face " + std::to_string(k) + " refers to vertex "
                      + std::to_string(index) + " of " + std::to_string(n_vertices));
  }
  return mesh;
}

} // namespace planar_grid
