// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/pcd_file_check.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types_conversion.h>

#include <algorithm>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <sstream>
#include <vector>

namespace planar_grid {

namespace {

/** The first line of a planar grid map file (PlanarGridMap::save()). */
constexpr const char* MAP_MAGIC_LINE = "# Planar grid map file";
/** A PCD header line is short; a longer "line" is binary data, not a header. */
constexpr std::size_t MAX_HEADER_LINE = 4096;
/** Bytes after the DATA line still searched for size keywords (see readHeaderText()).
 */
constexpr std::uint64_t MAX_SCAN_AFTER_DATA = 4096;
/** A PCD header has about a dozen lines; more is not a header. */
constexpr int MAX_HEADER_LINES = 1000;
/** LZF codes a back-reference of at most 264 bytes in 3 bytes: compressed data cannot
 * unpack to more than about 88 times their size. */
constexpr std::uint64_t MAX_LZF_RATIO = 100;

/** One line of \a in, at most MAX_HEADER_LINE bytes (more sets \a too_long). */
bool
readLine(std::istream& in, std::string& line, bool& too_long)
{
  line.clear();
  too_long = false;
  char c = 0;
  bool any = false;
  while (in.get(c)) {
    any = true;
    if (c == '\n')
      return true;
    if (line.size() >= MAX_HEADER_LINE) {
      too_long = true;
      return true;
    }
    line.push_back(c);
  }
  return any;
}

/** The header as this check reads it: the first line, the first keyword line, the
 * VIEWPOINT values as written, and the offset just after the DATA line. */
struct HeaderText {
  std::string first_line;
  std::string first_keyword_line;
  std::string viewpoint;
  bool has_viewpoint{false};
  /** The values of WIDTH, HEIGHT, POINTS, SIZE and COUNT as written (the last line of
   * each; every line counts for declaredBytes()). */
  std::string width, height, points, sizes, counts;
  std::vector<std::string> all_width, all_height, all_points, all_sizes, all_counts;
  std::uint64_t data_offset{0};
  bool has_data_line{false};
  /** The first FIELDS, SIZE, TYPE or COUNT line after a POINTS line ("" if none):
   * pcl::PCDReader sizes the points' buffer at POINTS with the point as declared so
   * far, and its ASCII reader writes the points as declared at the end. */
  std::string layout_after_points;
};

HeaderText
readHeaderText(std::istream& in)
{
  HeaderText header;
  std::string line;
  bool too_long = false;
  for (int n = 0; n < MAX_HEADER_LINES && readLine(in, line, too_long); ++n) {
    if (n == 0)
      header.first_line = line;
    if (too_long)
      break;
    if (!line.empty() && line.back() == '\r')
      line.pop_back();
    if (line.empty() || line[0] == '#')
      continue;
    if (header.first_keyword_line.empty())
      header.first_keyword_line = line;
    std::istringstream words(line);
    std::string word;
    words >> word;
    // PCL matches a header keyword as the start of the line's first word ("POINTSx" is
    // POINTS to it).
    std::string keyword;
    for (const char* k : {"VIEWPOINT", "WIDTH", "HEIGHT", "POINTS", "FIELDS", "SIZE",
                          "TYPE", "COUNT", "DATA"})
      if (word.rfind(k, 0) == 0)
        keyword = k;
    if ((keyword == "FIELDS" || keyword == "SIZE" || keyword == "TYPE"
         || keyword == "COUNT")
        && !header.all_points.empty() && header.layout_after_points.empty())
      header.layout_after_points = keyword;
    if (keyword == "VIEWPOINT" && !header.has_data_line) {
      header.has_viewpoint = true;
      std::getline(words, header.viewpoint);
      header.viewpoint.erase(0, header.viewpoint.find_first_not_of(' '));
    } else if (keyword == "WIDTH" || keyword == "HEIGHT" || keyword == "POINTS"
               || keyword == "SIZE" || keyword == "COUNT") {
      std::string values;
      std::getline(words, values);
      values.erase(0, values.find_first_not_of(' '));
      (keyword == "WIDTH"    ? header.width
       : keyword == "HEIGHT" ? header.height
       : keyword == "POINTS" ? header.points
       : keyword == "SIZE"   ? header.sizes
                             : header.counts) = values;
      (keyword == "WIDTH"    ? header.all_width
       : keyword == "HEIGHT" ? header.all_height
       : keyword == "POINTS" ? header.all_points
       : keyword == "SIZE"   ? header.all_sizes
                             : header.all_counts)
        .push_back(values);
    } else if (keyword == "DATA" && !header.has_data_line) {
      header.has_data_line = true;
      header.data_offset = static_cast<std::uint64_t>(in.tellg());
    }
    // PCL's reader does not always stop at the first DATA line (a malformed one): the
    // size keywords are collected over the first kilobytes after it too.
    if (header.has_data_line
        && static_cast<std::uint64_t>(in.tellg())
             > header.data_offset + MAX_SCAN_AFTER_DATA)
      break;
  }
  return header;
}

/** The seven numbers of a VIEWPOINT line (tx ty tz qw qx qy qz): PCL parses them with a
 * stream that stops at "nan" or a word and leaves the identity, so they are checked
 * here. */
void
checkViewpoint(const std::string& path, const std::string& text)
{
  std::istringstream words(text);
  std::string word;
  double values[7];
  int count = 0;
  while (words >> word) {
    if (count == 7) {
      count = 8;
      break;
    }
    char* end = nullptr;
    errno = 0;
    values[count] = std::strtod(word.c_str(), &end);
    if (end == word.c_str() || *end != '\0' || !std::isfinite(values[count]))
      throw IOError(path + ": VIEWPOINT '" + text + "' is not a valid pose: '" + word
                    + "' is not a finite number (expected tx ty tz qw qx qy qz)");
    ++count;
  }
  if (count != 7)
    throw IOError(path + ": VIEWPOINT '" + text
                  + "' is not a valid pose: expected 7 numbers (tx ty tz qw qx qy qz)");
  const double norm = std::sqrt(values[3] * values[3] + values[4] * values[4]
                                + values[5] * values[5] + values[6] * values[6]);
  if (norm < 1e-6)
    throw IOError(path + ": VIEWPOINT '" + text
                  + "' is not a valid pose: its quaternion is zero");
}

/** The most bytes pcl::PCDReader::readHeader() may allocate for the header \a text
 * before it reads any data: the points (POINTS, or WIDTH * HEIGHT) times the bytes of a
 * point (the SIZEs times the COUNTs), the largest over repeated lines; a number too
 * large to read counts as infinite. */
long double
declaredBytes(const HeaderText& text)
{
  const auto numbers = [](const std::string& line) {
    std::vector<long double> values;
    std::istringstream words(line);
    std::string word;
    while (words >> word) {
      errno = 0;
      char* end = nullptr;
      const unsigned long long v = std::strtoull(word.c_str(), &end, 10);
      if (end == word.c_str())
        break;
      values.push_back(errno == ERANGE || word[0] == '-'
                         ? std::numeric_limits<long double>::infinity()
                         : static_cast<long double>(v));
    }
    return values;
  };
  // The largest first number over the lines of a keyword.
  const auto largest = [&numbers](const std::vector<std::string>& lines,
                                  long double fallback) {
    long double result = lines.empty() ? fallback : 0.0L;
    for (const auto& line : lines) {
      const auto values = numbers(line);
      result = std::max(result, values.empty() ? fallback : values.front());
    }
    return result;
  };
  const long double points =
    std::max(largest(text.all_points, 0.0L),
             largest(text.all_width, 0.0L) * largest(text.all_height, 1.0L));
  const std::vector<std::string> count_lines =
    text.all_counts.empty() ? std::vector<std::string>{""} : text.all_counts;
  long double point_bytes = 0.0L;
  for (const auto& size_line : text.all_sizes)
    for (const auto& count_line : count_lines) {
      const auto sizes = numbers(size_line);
      const auto counts = numbers(count_line);
      long double bytes = 0.0L;
      for (std::size_t i = 0; i < sizes.size(); ++i)
        bytes += sizes[i] * (i < counts.size() ? counts[i] : 1.0L);
      point_bytes = std::max(point_bytes, bytes);
    }
  return points * std::max(point_bytes, 1.0L);
}

/** Non-empty lines from \a offset to the end of the file (ASCII points). */
std::uint64_t
countDataLines(const std::string& path, std::uint64_t offset)
{
  std::ifstream in(path, std::ios::binary);
  in.seekg(static_cast<std::streamoff>(offset));
  std::uint64_t lines = 0;
  bool blank = true;
  char buffer[1 << 16];
  while (in.read(buffer, sizeof(buffer)) || in.gcount() > 0) {
    const std::streamsize n = in.gcount();
    for (std::streamsize i = 0; i < n; ++i) {
      const char c = buffer[i];
      if (c == '\n') {
        lines += !blank;
        blank = true;
      } else if (c != ' ' && c != '\t' && c != '\r')
        blank = false;
    }
  }
  return lines + !blank;
}

/** \brief The header's text checked before PCL reads it: not a map file, a PCD
 * header with a DATA line, a valid viewpoint, no layout line after POINTS, and no
 * more points declared than a file of \a file_size bytes can hold. */
void
checkHeaderText(const std::string& path,
                const HeaderText& text,
                std::uintmax_t file_size)
{
  if (text.first_line == MAP_MAGIC_LINE)
    throw IOError(path
                  + ": not a PCD file: it is a planar grid map (.pgmap) file; "
                    "give it the .pgmap extension to view it as a map");
  const std::string keyword =
    text.first_keyword_line.substr(0, text.first_keyword_line.find(' '));
  if (keyword != "VERSION" && keyword != "FIELDS")
    throw IOError(path
                  + ": not a PCD file: its header does not start with VERSION "
                    "or FIELDS");
  if (!text.has_data_line)
    throw IOError(path + ": not a PCD file: its header has no DATA line");
  if (text.has_viewpoint)
    checkViewpoint(path, text.viewpoint);
  // The PCD header's order is FIELDS, SIZE, TYPE, COUNT, ..., POINTS: a point that
  // grows after POINTS would be written past PCL's buffer (a heap overflow in PCL).
  if (!text.layout_after_points.empty())
    throw IOError(path + ": its header has a " + text.layout_after_points
                  + " line after POINTS (the order is FIELDS, SIZE, TYPE, COUNT, "
                    "WIDTH, HEIGHT, VIEWPOINT, POINTS, DATA): PCL's reader would write "
                    "the points past the buffer it sized at POINTS");
  // PCL's header reader allocates the declared points' bytes: no file holds more than
  // its size in binary data, about 88 times it compressed, less as ASCII text.
  if (declaredBytes(text)
      > static_cast<long double>(MAX_LZF_RATIO) * file_size + 1024.0L)
    throw IOError(path + ": the header declares more points (POINTS '" + text.points
                  + "', WIDTH '" + text.width + "', HEIGHT '" + text.height
                  + "') than a file of " + std::to_string(file_size)
                  + " bytes can hold");
}

/** \brief The fields of the header PCL read into \a info: each of a known type and a
 * non-zero count, inside the point, adding up to the point; x, y and z among them. */
void
checkFields(const std::string& path,
            const pcl::PCLPointCloud2& header,
            PCDFileInfo& info)
{
  if (header.fields.empty())
    throw IOError(path + ": not a PCD file: the header has no FIELDS");
  for (const auto& field : header.fields) {
    const int size = pcl::getFieldSize(field.datatype);
    if (size <= 0 || field.count == 0)
      throw IOError(path + ": field '" + field.name
                    + "' has an unknown type or a count of 0");
    info.fields.push_back(field.name);
    const std::uint64_t bytes = static_cast<std::uint64_t>(size) * field.count;
    // PCL's conversion copies each field from its offset: it must lie in the point.
    if (field.offset + bytes > header.point_step)
      throw IOError(path + ": field '" + field.name
                    + "' lies outside the point (its SIZE, TYPE and COUNT disagree)");
    info.point_bytes += bytes;
  }
  if (info.point_bytes != header.point_step)
    throw IOError(path + ": the fields' sizes do not add up to the point's "
                  + std::to_string(header.point_step)
                  + " bytes (its SIZE, TYPE and COUNT disagree)");
  const auto has_field = [&info](const char* name) {
    return std::find(info.fields.begin(), info.fields.end(), name) != info.fields.end();
  };
  if (!has_field("x") || !has_field("y") || !has_field("z")) {
    std::string list;
    for (const auto& name : info.fields)
      list += (list.empty() ? "" : " ") + name;
    throw IOError(path + ": has no x, y, z fields (its fields: " + list
                  + "): its points have no position");
  }
}

/** \brief Binary compressed data: two little-endian uint32 (compressed, uncompressed
 * size), then the LZF-compressed data. PCL allocates the uncompressed size before it
 * reads: the sizes must fit the file, the points and LZF's ratio. \a declared is the
 * header's declaration with the point size, for the messages. */
void
checkCompressedSizes(const std::string& path,
                     std::uint64_t data_idx,
                     std::uint64_t after_header,
                     const PCDFileInfo& info,
                     const std::string& declared)
{
  const std::uint64_t points = info.points;
  const std::uint64_t point_bytes = info.point_bytes;
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
  if (points > 0 && static_cast<std::uint64_t>(sizes[1]) / point_bytes != points)
    throw IOError(path + ": the compressed data unpack to " + std::to_string(sizes[1])
                  + " bytes, but " + declared);
  if (points > 0 && sizes[1] % point_bytes != 0)
    throw IOError(path + ": the compressed data unpack to " + std::to_string(sizes[1])
                  + " bytes, not a whole number of " + std::to_string(point_bytes)
                  + "-byte points");
  if (static_cast<std::uint64_t>(sizes[1]) > MAX_LZF_RATIO * sizes[0] + 1024)
    throw IOError(path + ": corrupt compressed data: " + std::to_string(sizes[0])
                  + " compressed bytes cannot unpack to the " + std::to_string(sizes[1])
                  + " bytes the file declares (LZF packs at most about 88:1)");
}

} // namespace

PCDFileInfo
checkPCDFile(const std::string& path)
{
  const std::uintmax_t file_size = checkInputFile(path, "a PCD file");

  HeaderText text;
  {
    std::ifstream in(path, std::ios::binary);
    if (!in)
      throw IOError(path + ": cannot be opened: " + std::strerror(errno));
    text = readHeaderText(in);
  }
  checkHeaderText(path, text, file_size);

  pcl::PCDReader reader;
  pcl::PCLPointCloud2 header;
  PCDFileInfo info;
  int pcd_version = 0;
  unsigned int data_idx = 0;
  int read = -1;
  try {
    read = reader.readHeader(path, header, info.sensor_origin, info.sensor_orientation,
                             pcd_version, info.data_type, data_idx);
  } catch (const std::exception& e) {
    // PCL's reader indexes and converts the header's words unchecked
    // (std::out_of_range, std::invalid_argument, std::length_error).
    throw IOError(path + ": not a readable PCD file (bad header: " + e.what() + ")");
  }
  if (read < 0)
    throw IOError(path + ": not a readable PCD file (bad header)");
  checkFields(path, header, info);
  info.points = static_cast<std::uint64_t>(header.width) * header.height;
  const std::uint64_t points = info.points;
  const std::uint64_t point_bytes = info.point_bytes;
  // "the header declares N points[ of B bytes] (WIDTH w * HEIGHT h)"
  const auto declared = [&](bool with_bytes) {
    return "the header declares " + std::to_string(points) + " points"
           + (with_bytes ? " of " + std::to_string(point_bytes) + " bytes" : "")
           + " (WIDTH " + std::to_string(header.width) + " * HEIGHT "
           + std::to_string(header.height) + ")";
  };

  if (info.data_type == 0) {
    // ASCII: one non-empty line per point. PCL sizes its buffer from the header before
    // it reads a line, and stops after the declared points.
    const std::uint64_t lines = countDataLines(path, text.data_offset);
    if (lines != points)
      throw IOError(
        path + ": the ASCII data hold " + std::to_string(lines)
        + " points (lines), but " + declared(false)
        + (lines < points ? ": the file is truncated" : ": the rest would be ignored"));
    return info;
  }
  if (data_idx > file_size)
    throw IOError(path + ": truncated: the header ends past the end of the file");
  const std::uint64_t after_header = file_size - data_idx;
  if (info.data_type == 1) {
    // Compared by division: points * point_bytes may not fit in 64 bits.
    const std::uint64_t held = after_header / point_bytes;
    if (held < points)
      throw IOError(path + ": truncated: " + declared(true) + ", the file has "
                    + std::to_string(after_header) + " bytes of data ("
                    + std::to_string(held) + " points)");
    if (held > points)
      throw IOError(path + ": the binary data hold " + std::to_string(held)
                    + " points of " + std::to_string(point_bytes) + " bytes, but "
                    + declared(false) + ": the rest would be ignored");
    return info;
  }
  checkCompressedSizes(path, data_idx, after_header, info, declared(true));
  return info;
}

void
checkPointCloudBlob(const pcl::PCLPointCloud2& blob, const std::string& where)
{
  if (blob.point_step == 0
      || blob.row_step < static_cast<std::uint64_t>(blob.width) * blob.point_step
      || blob.data.size() < static_cast<std::uint64_t>(blob.row_step) * blob.height)
    throw IOError(where + ": the cloud declares " + std::to_string(blob.width) + " x "
                  + std::to_string(blob.height) + " points of "
                  + std::to_string(blob.point_step) + " bytes but holds "
                  + std::to_string(blob.data.size()) + " bytes");
  for (const auto& field : blob.fields) {
    const std::uint64_t end =
      static_cast<std::uint64_t>(field.offset)
      + static_cast<std::uint64_t>(pcl::getFieldSize(field.datatype))
          * std::max<std::uint64_t>(field.count, 1);
    if (end > blob.point_step)
      throw IOError(where + ": the field '" + field.name + "' lies outside its point ("
                    + std::to_string(end) + " of " + std::to_string(blob.point_step)
                    + " bytes)");
  }
}

namespace {

/** \brief The value of datatype \a datatype at \a bytes as a float; false for a
 * datatype PCL does not define. */
bool
readAsFloat(const std::uint8_t* bytes, std::uint8_t datatype, float& value)
{
  const auto read = [bytes, &value](auto typed) {
    std::memcpy(&typed, bytes, sizeof(typed));
    value = static_cast<float>(typed);
    return true;
  };
  switch (datatype) {
    case pcl::PCLPointField::BOOL:
      // Any non-zero byte is true (a byte read as bool must be 0 or 1).
      value = bytes[0] != 0 ? 1.0f : 0.0f;
      return true;
    case pcl::PCLPointField::INT8:
      return read(std::int8_t{});
    case pcl::PCLPointField::UINT8:
      return read(std::uint8_t{});
    case pcl::PCLPointField::INT16:
      return read(std::int16_t{});
    case pcl::PCLPointField::UINT16:
      return read(std::uint16_t{});
    case pcl::PCLPointField::INT32:
      return read(std::int32_t{});
    case pcl::PCLPointField::UINT32:
      return read(std::uint32_t{});
    case pcl::PCLPointField::INT64:
      return read(std::int64_t{});
    case pcl::PCLPointField::UINT64:
      return read(std::uint64_t{});
    case pcl::PCLPointField::FLOAT32:
      return read(float{});
    case pcl::PCLPointField::FLOAT64:
      return read(double{});
    default:
      return false;
  }
}

} // namespace

void
convertFieldsToFloat(pcl::PCLPointCloud2& blob,
                     const std::vector<std::string>& names,
                     const std::string& where)
{
  const auto converted = [&names](const pcl::PCLPointField& field) {
    return field.datatype != pcl::PCLPointField::FLOAT32
           && std::find(names.begin(), names.end(), field.name) != names.end();
  };
  // A named field holds one number per point whatever its datatype: PCL would read
  // the first of several as the value (an x of COUNT 3 read as x alone).
  for (const auto& field : blob.fields)
    if (field.count > 1
        && std::find(names.begin(), names.end(), field.name) != names.end())
      throw IOError(where + ": the field '" + field.name + "' holds "
                    + std::to_string(field.count)
                    + " values per point (COUNT); one number is needed");
  bool any = false;
  for (const auto& field : blob.fields) {
    if (!converted(field))
      continue;
    float probe = 0.0f;
    const std::uint8_t zero[8] = {};
    if (!readAsFloat(zero, field.datatype, probe))
      throw IOError(where + ": the field '" + field.name + "' has the datatype "
                    + std::to_string(field.datatype)
                    + ", which PCL does not define; it cannot be read as a number");
    any = true;
  }
  if (!any)
    return;
  // The new layout: the fields in their order, packed, the converted ones 4 bytes.
  std::vector<pcl::PCLPointField> fields = blob.fields;
  std::vector<std::uint32_t> bytes(fields.size());
  std::uint32_t step = 0;
  for (std::size_t k = 0; k < fields.size(); ++k) {
    const bool to_float = converted(fields[k]);
    bytes[k] =
      to_float
        ? 4u
        : static_cast<std::uint32_t>(pcl::getFieldSize(fields[k].datatype)
                                     * std::max<std::uint32_t>(fields[k].count, 1));
    if (to_float)
      fields[k].datatype = pcl::PCLPointField::FLOAT32;
    fields[k].offset = step;
    step += bytes[k];
  }
  const std::size_t points = static_cast<std::size_t>(blob.width) * blob.height;
  std::vector<std::uint8_t> data(points * step);
  for (std::uint32_t row = 0; row < blob.height; ++row)
    for (std::uint32_t col = 0; col < blob.width; ++col) {
      const std::uint8_t* from = blob.data.data()
                                 + static_cast<std::size_t>(row) * blob.row_step
                                 + static_cast<std::size_t>(col) * blob.point_step;
      std::uint8_t* to =
        data.data() + (static_cast<std::size_t>(row) * blob.width + col) * step;
      for (std::size_t k = 0; k < fields.size(); ++k) {
        const pcl::PCLPointField& old = blob.fields[k];
        if (converted(old)) {
          float value = 0.0f;
          readAsFloat(from + old.offset, old.datatype, value);
          std::memcpy(to + fields[k].offset, &value, sizeof(value));
        } else
          std::memcpy(to + fields[k].offset, from + old.offset, bytes[k]);
      }
    }
  blob.fields = std::move(fields);
  blob.point_step = step;
  blob.row_step = step * blob.width;
  blob.data = std::move(data);
}

void
intensityCloudFromBlob(const pcl::PCLPointCloud2& blob,
                       pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  cloud.clear();
  // PCL's conversion indexes point 0 even of an empty cloud (UB that UBSan reports).
  if (static_cast<std::size_t>(blob.width) * blob.height == 0)
    return;
  const auto has = [&blob](const std::string& name) {
    return std::any_of(blob.fields.begin(), blob.fields.end(),
                       [&name](const pcl::PCLPointField& f) { return f.name == name; });
  };
  if (has("intensity"))
    pcl::fromPCLPointCloud2(blob, cloud);
  else if (has("rgb") || has("rgba")) {
    pcl::PointCloud<pcl::PointXYZRGB> colour;
    pcl::fromPCLPointCloud2(blob, colour);
    cloud.resize(colour.size());
    for (std::size_t i = 0; i < colour.size(); ++i)
      pcl::PointXYZRGBtoXYZI(colour[i], cloud[i]);
    cloud.width = colour.width;
    cloud.height = colour.height;
    cloud.is_dense = colour.is_dense;
  } else {
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::fromPCLPointCloud2(blob, xyz);
    pcl::copyPointCloud(xyz, cloud);
  }
}

} // namespace planar_grid
