// SPDX-License-Identifier: BSD-3-Clause
// The index of a tiled map, read strictly, and the loading of tiles by region.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>

#include <algorithm>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <set>
#include <sstream>
#include <utility>

#include "map_tiles_format.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using map_tiles_detail::INDEX_MAGIC;
using map_tiles_detail::INDEX_VERSION;
using map_tiles_detail::loadTileFile;
using map_tiles_detail::tileMergeParams;

/** Reads the index line by line; every error names the file and the line. */
class IndexReader {
public:
  explicit IndexReader(std::string path) : path_(std::move(path))
  {
    std::error_code ec;
    if (!fs::is_regular_file(path_, ec))
      throw IOError("tile index " + path_
                    + ": missing (not a tile folder, or a set whose writing did not "
                      "finish)");
    std::ifstream file(path_);
    if (!file)
      throw IOError("tile index " + path_ + ": cannot be opened for reading");
    std::string line;
    while (std::getline(file, line))
      lines_.push_back(line);
    if (file.bad())
      throw IOError("tile index " + path_ + ": read error");
  }

  [[noreturn]] void fail(const std::string& what) const
  {
    throw IOError("tile index " + path_ + ":" + std::to_string(line_) + ": " + what);
  }

  /** The next line, whole. */
  std::string nextLine()
  {
    if (line_ >= lines_.size()) {
      ++line_;
      fail("truncated (the index ends before its 'end' line)");
    }
    return lines_[line_++];
  }

  /** The next line as its words; its first word must be \a key and it must have
   * \a count words after it. */
  std::vector<std::string> next(const std::string& key, std::size_t count)
  {
    std::istringstream words(nextLine());
    std::vector<std::string> out;
    for (std::string w; words >> w;)
      out.push_back(w);
    if (out.empty() || out[0] != key)
      fail("expected '" + key + "'" + (out.empty() ? "" : ", found '" + out[0] + "'"));
    if (out.size() != count + 1)
      fail("'" + key + "' takes " + std::to_string(count) + " value(s), found "
           + std::to_string(out.size() - 1));
    out.erase(out.begin());
    return out;
  }

  /** \a text as a number of type T, whole. */
  template <typename T> T number(const std::string& text, const std::string& what)
  {
    T value{};
    const char* end = text.data() + text.size();
    const auto result = std::from_chars(text.data(), end, value);
    if (result.ec != std::errc() || result.ptr != end)
      fail(what + " '" + text + "' is not a number");
    if constexpr (std::is_floating_point_v<T>)
      if (!std::isfinite(value))
        fail(what + " '" + text + "' is not finite");
    return value;
  }

  /** \a text as a plain file name (no folder part). */
  std::string fileName(const std::string& text, const std::string& extension)
  {
    if (text.empty() || text.find('/') != std::string::npos
        || text.find('\\') != std::string::npos || text == "." || text == ".."
        || fs::path(text).extension() != extension)
      fail("file name '" + text + "' is not a plain " + extension + " name");
    return text;
  }

  bool atEnd() const { return line_ >= lines_.size(); }
  std::size_t line() const { return line_; }

private:
  std::string path_;
  std::vector<std::string> lines_;
  std::size_t line_{0};
};

/** Merges the tiles \a selected chooses into a map of the set's parameters, without
 * the planes' tidying (tileMergeParams(): the saved map was tidied when it was built).
 * The result goes through its file content, so that it has the parameters
 * PlanarGridMap::load() gives. */
PlanarGridMap
mergeTiles(const std::string& folder,
           const MapTileIndex& index,
           const std::function<bool(const MapTile&)>& selected)
{
  PlanarGridMap merged(tileMergeParams(
    loadTileFile(folder, index.base_file, index.base_file_bytes, index)));
  for (const MapTile& t : index.tiles)
    if (selected(t))
      merged.merge(loadTileFile(folder, t.file, t.file_bytes, index),
                   Eigen::Isometry3d::Identity());
  std::string bytes;
  merged.serialize(bytes);
  return PlanarGridMap::deserialize(bytes, folder);
}

} // namespace

namespace map_tiles_detail {

PlanarGridMap
loadTileFile(const std::string& folder,
             const std::string& name,
             std::uint64_t bytes,
             const MapTileIndex& index)
{
  const std::string path = (fs::path(folder) / name).string();
  std::error_code ec;
  if (!fs::is_regular_file(path, ec))
    throw IOError("map tile " + path + ": missing (the index "
                  + std::string(MAP_TILE_INDEX_NAME) + " names it)");
  const std::uintmax_t size = fs::file_size(path, ec);
  if (ec || size != bytes)
    throw IOError("map tile " + path + ": " + std::to_string(size)
                  + " bytes, the index says " + std::to_string(bytes)
                  + " (a tile of another set, or a changed file)");
  PlanarGridMap map = PlanarGridMap::load(path);
  if (map.getResolution() != index.resolution_m)
    throw IOError("map tile " + path + ": resolution_m "
                  + std::to_string(map.getResolution()) + ", the index says "
                  + std::to_string(index.resolution_m));
  if (toString(map.getParams().space.prior) != index.prior)
    throw IOError("map tile " + path + ": prior "
                  + toString(map.getParams().space.prior) + ", the index says "
                  + index.prior);
  return map;
}

PlanarGridMap::Params
tileMergeParams(const PlanarGridMap& base)
{
  PlanarGridMap::Params params = base.getParams();
  params.planes_absorb_overlapping = false;
  params.planes_replace_non_planar = false;
  return params;
}

} // namespace map_tiles_detail

MapTileIndex
readTileIndex(const std::string& folder)
{
  IndexReader in((fs::path(folder) / MAP_TILE_INDEX_NAME).string());
  if (in.nextLine() != INDEX_MAGIC)
    in.fail(std::string("not a tile index (first line must be '") + INDEX_MAGIC + "')");
  const auto version = in.number<int>(in.next("version", 1)[0], "version");
  if (version != INDEX_VERSION)
    in.fail("unknown version " + std::to_string(version) + " (this library reads "
            + std::to_string(INDEX_VERSION) + ")");
  if (in.next("id", 1)[0] != "PlanarGridMapTiles")
    in.fail("id must be PlanarGridMapTiles");

  MapTileIndex index;
  index.resolution_m = in.number<double>(in.next("resolution_m", 1)[0], "resolution_m");
  if (!(index.resolution_m > 0.0))
    in.fail("resolution_m must be > 0");
  index.tile_size_m = in.number<double>(in.next("tile_size_m", 1)[0], "tile_size_m");
  const double voxels = index.tile_size_m / index.resolution_m;
  if (!(index.tile_size_m > 0.0) || index.tile_size_m > 1e5
      || std::abs(voxels - std::round(voxels)) > 1e-6 * voxels)
    in.fail("tile_size_m must be in (0, 1e5] m and a whole number of voxels");
  index.prior = in.next("prior", 1)[0];
  if (index.prior != "free" && index.prior != "unknown")
    in.fail("prior must be free or unknown");
  index.generation =
    in.number<std::uint64_t>(in.next("generation", 1)[0], "generation");
  const auto base = in.next("base", 2);
  index.base_file = in.fileName(base[0], ".pgmap");
  index.base_file_bytes = in.number<std::uint64_t>(base[1], "base file size");
  const auto count = in.number<std::uint64_t>(in.next("tiles", 1)[0], "tiles");
  if (count > 10'000'000)
    in.fail("more than 10,000,000 tiles");

  std::set<std::pair<std::int64_t, std::int64_t>> keys;
  std::set<std::string> names{index.base_file};
  for (std::uint64_t k = 0; k < count; ++k) {
    const auto w = in.next("tile", 10);
    MapTile t;
    t.key_x = in.number<std::int64_t>(w[0], "tile key x");
    t.key_y = in.number<std::int64_t>(w[1], "tile key y");
    t.file = in.fileName(w[2], ".pgmap");
    t.file_bytes = in.number<std::uint64_t>(w[3], "tile file size");
    for (int a = 0; a < 3; ++a) {
      t.bounds.min()[a] = in.number<float>(w[4 + a], "bounds_m");
      t.bounds.max()[a] = in.number<float>(w[7 + a], "bounds_m");
    }
    if (t.bounds.isEmpty())
      in.fail("tile bounds with min > max");
    if (!keys.insert({t.key_x, t.key_y}).second)
      in.fail("tile key " + w[0] + " " + w[1] + " listed twice");
    if (!names.insert(t.file).second)
      in.fail("file " + t.file + " listed twice");
    index.tiles.push_back(std::move(t));
  }
  in.next("end", 0);
  while (!in.atEnd())
    if (!in.nextLine().empty())
      in.fail("text after the 'end' line");
  return index;
}

PlanarGridMap
loadTiles(const std::string& folder, const Eigen::AlignedBox3f& region, double margin_m)
{
  if (!(margin_m >= 0.0))
    throw Exception("loadTiles: margin_m must be >= 0");
  const MapTileIndex index = readTileIndex(folder);
  Eigen::AlignedBox3f grown = region;
  grown.min().head<2>().array() -= static_cast<float>(margin_m);
  grown.max().head<2>().array() += static_cast<float>(margin_m);
  return mergeTiles(folder, index,
                    [&grown](const MapTile& t) { return t.bounds.intersects(grown); });
}

PlanarGridMap
loadTiles(const std::string& folder,
          const Eigen::Vector3f& position,
          double radius_m,
          double margin_m)
{
  if (!(radius_m >= 0.0) || !(margin_m >= 0.0) || !position.allFinite())
    throw Exception("loadTiles: radius_m and margin_m must be >= 0 and the position "
                    "finite");
  const MapTileIndex index = readTileIndex(folder);
  const double reach = radius_m + margin_m;
  const Eigen::Vector2d p = position.head<2>().cast<double>();
  return mergeTiles(folder, index, [&p, reach](const MapTile& t) {
    // distance in x and y from the position to the tile's bounds
    const Eigen::Vector2d nearest =
      p.cwiseMax(t.bounds.min().head<2>().cast<double>())
        .cwiseMin(t.bounds.max().head<2>().cast<double>());
    return (p - nearest).norm() <= reach;
  });
}

} // namespace planar_grid
