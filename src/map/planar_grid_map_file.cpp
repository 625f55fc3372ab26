// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap's map file (.pgmap): the text header with its checksum, then the space
// and surface layers' streams; serialize() and save(), load() and deserialize().
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/console/print.h>

#include <charconv>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <map>
#include <set>
#include <sstream>
#include <string>
#include <tuple>
#include <utility>
#include <vector>

namespace planar_grid {

namespace {

constexpr const char* MAGIC_LINE = "# Planar grid map file";
/** Version 3: the space layer's stream keeps observed free space apart from the free
 * prior (ExplicitSpaceGrid::STREAM_VERSION). Version 2: the checksum covers the header
 * lines before it as well as the data. Versions 1 (the checksum covers the data only)
 * and 2 are still read. */
constexpr std::uint64_t FORMAT_VERSION = ExplicitSpaceGrid::STREAM_VERSION;
/** The oldest version read. */
constexpr std::uint64_t OLDEST_FORMAT_VERSION = 1;

/** CRC-32 of \a header_size header bytes followed by \a data_size data bytes (version
 * 2); of the data alone with \a header_size 0 (version 1). */
std::string
checksumText(const char* header,
             std::size_t header_size,
             const std::uint8_t* data,
             std::size_t data_size)
{
  boost::crc_32_type crc;
  crc.process_bytes(header, header_size);
  crc.process_bytes(data, data_size);
  char text[16];
  std::snprintf(text, sizeof(text), "0x%08x", crc.checksum());
  return text;
}
/** The text header is small; anything longer is not a map file. */
constexpr std::size_t MAX_HEADER_BYTES = 64 * 1024;

/** Shortest text of a double that reads back to the same value (std::to_chars). */
std::string
exact(double value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** The "key value..." lines of a map file header. */
class HeaderReader {
public:
  HeaderReader(std::string path, std::map<std::string, std::string> values) :
      path_(std::move(path)), values_(std::move(values))
  {}

  double number(const std::string& key)
  {
    std::istringstream in(require(key));
    double value = 0.0;
    std::string rest;
    if (!(in >> value) || (in >> rest) || !std::isfinite(value))
      fail("'" + key + "' must be one finite number, got '" + values_.at(key) + "'");
    return value;
  }

  std::uint64_t count(const std::string& key) { return parseCount(key, require(key)); }

  /** True when the header has a \a key line. */
  bool has(const std::string& key) const { return values_.count(key) > 0; }

  /** Two finite numbers, the first not above the second. */
  std::pair<double, double> orderedPair(const std::string& key)
  {
    std::istringstream in(require(key));
    double a = 0.0, b = 0.0;
    std::string rest;
    if (!(in >> a >> b) || (in >> rest) || !std::isfinite(a) || !std::isfinite(b)
        || a > b) {
      const std::string what = "' must be two finite numbers, the first not above "
                               "the second, got '";
      fail("'" + key + what + values_.at(key) + "'");
    }
    return {a, b};
  }

  std::vector<std::uint64_t> counts(const std::string& key, std::size_t n)
  {
    std::istringstream in(require(key));
    std::vector<std::uint64_t> out;
    std::string word;
    while (in >> word)
      out.push_back(parseCount(key, word));
    if (out.size() != n)
      fail("'" + key + "' must hold " + std::to_string(n) + " integers");
    return out;
  }

  const std::string& require(const std::string& key)
  {
    const auto it = values_.find(key);
    if (it == values_.end())
      fail("the header has no '" + key + "' line");
    used_.insert(key);
    return it->second;
  }

  void warnUnused() const
  {
    for (const auto& kv : values_)
      if (!used_.count(kv.first))
        PCL_WARN("[planar_grid::PlanarGridMap::load] %s: unknown header key '%s' "
                 "ignored.\n",
                 path_.c_str(), kv.first.c_str());
  }

  /** One non-negative integer of \a key's value (at most 19 digits: fits 64 bits). */
  std::uint64_t parseCount(const std::string& key, const std::string& text) const
  {
    if (text.empty() || text.find_first_not_of("0123456789") != std::string::npos
        || text.size() > 19)
      fail("'" + key + "' must hold non-negative integers, got '" + text + "'");
    return std::stoull(text);
  }

  [[noreturn]] void fail(const std::string& what) const
  {
    throw IOError("map file " + path_ + ": " + what);
  }

private:
  std::string path_;
  std::map<std::string, std::string> values_;
  std::set<std::string> used_;
};

} // namespace

void
PlanarGridMap::serialize(std::string& bytes) const
{
  std::vector<std::uint8_t> data;
  space_.serialize(data);
  const std::size_t space_bytes = data.size();
  surface_.serialize(data);
  const std::size_t surface_bytes = data.size() - space_bytes;

  ExplicitSpaceGrid::VoxelKey min_key, max_key;
  Eigen::Vector3d min_m = Eigen::Vector3d::Zero(), max_m = Eigen::Vector3d::Zero();
  const double res = getResolution();
  if (space_.getBounds(min_key, max_key)) {
    min_m = min_key.cast<double>() * res;
    max_m = (max_key.cast<double>() + Eigen::Vector3d::Ones()) * res;
  }

  const auto& sp = params_.space;
  const auto& su = params_.surface;
  std::ostringstream header;
  header << MAGIC_LINE << "\n"
         << "version " << FORMAT_VERSION << "\n"
         << "id PlanarGridMap\n"
         << "resolution_m " << exact(res) << "\n"
         << "max_range_m " << exact(sp.max_range_m) << "\n"
         << "surface_margin_m " << exact(sp.surface_margin_m) << "\n"
         << "prior " << toString(sp.prior) << "\n"
         << "thickness_m " << exact(su.thickness_m) << "\n"
         << "plane_merge_angle_rad " << exact(su.plane_merge_angle_rad) << "\n"
         << "plane_merge_distance_m " << exact(su.plane_merge_distance_m) << "\n"
         << "occupancy_thres " << exact(su.occupancy_thres) << "\n"
         << "feature_distance_m " << exact(su.feature_distance_m) << "\n"
         << "bounds_m " << exact(min_m.x()) << " " << exact(min_m.y()) << " "
         << exact(min_m.z()) << " " << exact(max_m.x()) << " " << exact(max_m.y())
         << " " << exact(max_m.z()) << "\n"
         << "voxels " << space_.getVoxelCount(SpaceState::FREE) << " "
         << space_.getVoxelCount(SpaceState::OCCUPIED) << " "
         << space_.getVoxelCount(SpaceState::UNKNOWN) << "\n"
         << "planes " << surface_.getPlaneCount() << "\n"
         << "cuboids " << surface_.getCuboidCount() << "\n"
         << "space_bytes " << space_bytes << "\n"
         << "surface_bytes " << surface_bytes << "\n";
  if (!observation_span_.empty())
    header << "observation_span " << exact(observation_span_.first) << " "
           << exact(observation_span_.last) << "\n";
  // The checksum covers every header byte before its own line, then the data: a
  // changed header value (resolution_m) is refused like a changed data byte.
  bytes = header.str();
  bytes += "checksum_crc32 "
           + checksumText(bytes.data(), bytes.size(), data.data(), data.size()) + "\n"
           + "data\n";
  bytes.append(reinterpret_cast<const char*>(data.data()), data.size());
}

void
PlanarGridMap::save(const std::string& path) const
{
  std::string bytes;
  serialize(bytes);
  writeFileAtomically(path, [&](const std::string& temporary) {
    std::ofstream out(temporary, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    out.close();
    return static_cast<bool>(out);
  });
}

PlanarGridMap
PlanarGridMap::load(const std::string& path)
{
  // A device such as /dev/zero never ends: reading it would take all the memory.
  std::error_code ec;
  if (std::filesystem::exists(path, ec) && !std::filesystem::is_regular_file(path, ec))
    throw IOError("map file " + path
                  + ": not a regular file (a device, pipe or folder); a map is read "
                    "from a .pgmap file");
  std::ifstream file(path, std::ios::binary);
  if (!file)
    throw IOError("map file " + path + ": cannot be opened for reading");
  std::ostringstream content;
  content << file.rdbuf();
  if (file.bad())
    throw IOError("map file " + path + ": read error");
  return deserialize(content.str(), path);
}

PlanarGridMap
PlanarGridMap::deserialize(const std::string& bytes, const std::string& path)
{
  std::istringstream in(bytes);
  const auto file_size = static_cast<std::uint64_t>(bytes.size());

  // The text header, line by line, up to "data".
  std::string line;
  if (!std::getline(in, line) || line != MAGIC_LINE)
    throw IOError("map file " + path + ": not a planar grid map (first line must be '"
                  + std::string(MAGIC_LINE) + "')");
  std::map<std::string, std::string> values;
  std::uint64_t header_bytes = line.size() + 1;
  bool found_data = false;
  int line_number = 1;
  // Where the checksum line starts and its line number: in version 2 it is the last
  // line before "data" and covers the header bytes before it.
  std::uint64_t checksum_line_start = 0;
  int checksum_line = 0;
  while (std::getline(in, line)) {
    ++line_number;
    if (line.rfind("checksum_crc32 ", 0) == 0) {
      checksum_line_start = header_bytes;
      checksum_line = line_number;
    }
    header_bytes += line.size() + 1;
    if (header_bytes > MAX_HEADER_BYTES)
      throw IOError("map file " + path + ": no 'data' line in the first "
                    + std::to_string(MAX_HEADER_BYTES) + " bytes");
    if (line == "data") {
      found_data = true;
      break;
    }
    if (line.empty() || line[0] == '#')
      continue;
    const auto space = line.find(' ');
    const std::string key = line.substr(0, space);
    const std::string value = space == std::string::npos ? "" : line.substr(space + 1);
    if (!values.emplace(key, value).second)
      throw IOError("map file " + path + ":" + std::to_string(line_number)
                    + ": header key '" + key + "' given twice");
  }
  if (!found_data)
    throw IOError("map file " + path + ": truncated header (no 'data' line)");

  HeaderReader header(path, std::move(values));
  const auto version = header.count("version");
  if (version < OLDEST_FORMAT_VERSION || version > FORMAT_VERSION)
    header.fail("version " + std::to_string(version)
                + " is not supported (this reader knows versions "
                + std::to_string(OLDEST_FORMAT_VERSION) + " to "
                + std::to_string(FORMAT_VERSION) + ")");
  if (version >= 2 && checksum_line != line_number - 1)
    header.fail("the checksum_crc32 line must be the last line before 'data'");
  if (version < 2)
    PCL_WARN("[planar_grid::PlanarGridMap::load] %s: a version %d map file, whose "
             "checksum covers the data only; saving it again writes version %d, which "
             "covers the header too.\n",
             path.c_str(), static_cast<int>(version), static_cast<int>(FORMAT_VERSION));
  if (header.require("id") != "PlanarGridMap")
    header.fail("id must be 'PlanarGridMap'");
  const bool old_free_prior = version < 3 && header.require("prior") == "free";

  Params params;
  params.resolution_m = header.number("resolution_m");
  if (!(params.resolution_m > 0.0))
    header.fail("resolution_m must be > 0");
  params.space.max_range_m = header.number("max_range_m");
  params.space.surface_margin_m = header.number("surface_margin_m");
  try {
    params.space.prior = spaceStateFromString(header.require("prior"));
  } catch (const Exception& e) {
    header.fail(std::string("prior: ") + e.what());
  }
  params.surface.thickness_m = header.number("thickness_m");
  params.surface.plane_merge_angle_rad = header.number("plane_merge_angle_rad");
  params.surface.plane_merge_distance_m = header.number("plane_merge_distance_m");
  params.surface.occupancy_thres = header.number("occupancy_thres");
  params.surface.feature_distance_m = header.number("feature_distance_m");
  header.require("bounds_m"); // informative; the layers carry their own extent
  const auto voxels = header.counts("voxels", 3);
  const auto planes = header.count("planes");
  const auto cuboids = header.count("cuboids");
  const auto space_bytes = header.count("space_bytes");
  const auto surface_bytes = header.count("surface_bytes");
  // Optional: files written before the span was stored have none (an empty span).
  ObservationSpan span;
  if (header.has("observation_span"))
    std::tie(span.first, span.last) = header.orderedPair("observation_span");
  const std::string crc_text = header.require("checksum_crc32");
  header.warnUnused();

  // Sizes against the file length before allocating anything.
  const std::uint64_t remaining = file_size - header_bytes;
  if (space_bytes > remaining || surface_bytes > remaining - space_bytes)
    header.fail("truncated: the header announces " + std::to_string(space_bytes) + " + "
                + std::to_string(surface_bytes) + " data bytes, the file has "
                + std::to_string(remaining));
  if (space_bytes + surface_bytes != remaining)
    header.fail(std::to_string(remaining - space_bytes - surface_bytes)
                + " bytes of trailing data after the announced sections");
  std::vector<std::uint8_t> data(static_cast<std::size_t>(remaining));
  if (!data.empty()
      && !in.read(reinterpret_cast<char*>(data.data()),
                  static_cast<std::streamsize>(data.size())))
    header.fail("could not read the data section");
  const std::string expected = checksumText(
    bytes.data(), version >= 2 ? checksum_line_start : 0, data.data(), data.size());
  if (crc_text != expected)
    header.fail("checksum mismatch (file " + crc_text + ", content " + expected
                + "): the file is corrupt");

  PlanarGridMap map = [&]() {
    try {
      PlanarGridMap decoded(params);
      decoded.space_.deserialize(data.data(), static_cast<std::size_t>(space_bytes),
                                 static_cast<unsigned>(version));
      decoded.surface_.deserialize(data.data() + space_bytes,
                                   static_cast<std::size_t>(surface_bytes));
      // The surface section carries all of its layer's parameters, the header only
      // some of them (close_gaps_cells and merge_rule are in the section alone).
      decoded.params_.surface = decoded.surface_.getParams();
      decoded.observation_span_ = span;
      return decoded;
    } catch (const Exception& e) {
      header.fail(e.what());
    }
  }();
  // The map has one cell size: the surface section's must be the header's.
  if (map.params_.surface.resolution_m != params.resolution_m)
    header.fail("the surface section's resolution_m "
                + exact(map.params_.surface.resolution_m)
                + " differs from the header's " + exact(params.resolution_m));
  if (map.space_.getVoxelCount(SpaceState::FREE) != voxels[0]
      || map.space_.getVoxelCount(SpaceState::OCCUPIED) != voxels[1]
      || map.space_.getVoxelCount(SpaceState::UNKNOWN) != voxels[2])
    header.fail("the decoded voxel counts differ from the header's 'voxels'");
  if (map.surface_.getPlaneCount() != planes
      || map.surface_.getCuboidCount() != cuboids)
    header.fail("the decoded plane or cuboid count differs from the header's");
  if (old_free_prior)
    PCL_WARN("[planar_grid::PlanarGridMap::load] %s: a version %d map with the free "
             "prior does not tell observed free space from space never observed; both "
             "read as never observed (free by the prior, absent from OctoMap exports). "
             "Map the data again for observed free space.\n",
             path.c_str(), static_cast<int>(version));
  return map;
}

} // namespace planar_grid
