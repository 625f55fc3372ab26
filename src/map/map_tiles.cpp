// SPDX-License-Identifier: BSD-3-Clause
// A map stored as tiles (squares in x and y) with an index, loaded by region: the
// split by recursive halving with PlanarGridMap::removeOutside(), the index file, and
// the loading by merge.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <charconv>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <functional>
#include <limits>
#include <set>
#include <sstream>
#include <utility>

#include "map_tiles_format.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using map_tiles_detail::INDEX_MAGIC;
using map_tiles_detail::INDEX_VERSION;
constexpr float INF = std::numeric_limits<float>::infinity();

/** Shortest text of a value that reads back to the same value. */
template <typename T>
std::string
exactText(T value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** The tile folder's file \a name. */
std::string
inFolder(const std::string& folder, const std::string& name)
{
  return (fs::path(folder) / name).string();
}

/** The map's copy, through its file content (maps have no copy constructor). */
PlanarGridMap
copyOf(const PlanarGridMap& map)
{
  std::string bytes;
  map.serialize(bytes);
  return PlanarGridMap::deserialize(bytes, "tile copy");
}

/** True when the map holds no voxel, plane or non-planar cell. */
bool
isEmpty(const PlanarGridMap& map)
{
  ExplicitSpaceGrid::VoxelKey lo, hi;
  return !map.getSpaceLayer().getBounds(lo, hi)
         && map.getSurfaceLayer().getPlaneCount() == 0
         && map.getSurfaceLayer().getCellCount() == 0;
}

/** Splits tiles by their squares: the border between keys k - 1 and k lies at
 * k tile_size_m (in float, computed once, so that both sides use the same value). */
class TileSplitter {
public:
  TileSplitter(double tile_size_m,
               std::function<void(std::int64_t, std::int64_t, PlanarGridMap&)> emit) :
      tile_size_m_(tile_size_m),
      emit_(std::move(emit))
  {}

  /** Emits the tiles of \a map, whose content lies in keys [lo, hi] (x, y), by
   * halving the key range along its longer side until one tile is left; halves
   * without content are dropped. */
  void split(PlanarGridMap map,
             std::array<std::int64_t, 2> lo,
             std::array<std::int64_t, 2> hi)
  {
    if (isEmpty(map))
      return;
    if (lo == hi) {
      emit_(lo[0], lo[1], map);
      return;
    }
    const int axis = hi[0] - lo[0] >= hi[1] - lo[1] ? 0 : 1;
    const std::int64_t mid = lo[axis] + (hi[axis] - lo[axis] + 1) / 2;
    const float border = static_cast<float>(static_cast<double>(mid) * tile_size_m_);
    // The lower half keeps [-inf, border), the upper half [border, inf): the closed
    // box of removeOutside() ends one float below the border.
    Eigen::AlignedBox3f lower(Eigen::Vector3f::Constant(-INF),
                              Eigen::Vector3f::Constant(INF));
    Eigen::AlignedBox3f upper = lower;
    lower.max()[axis] = std::nextafter(border, -INF);
    upper.min()[axis] = border;
    PlanarGridMap lower_map = copyOf(map);
    lower_map.removeOutside(lower);
    map.removeOutside(upper);
    std::array<std::int64_t, 2> lower_hi = hi, upper_lo = lo;
    lower_hi[axis] = mid - 1;
    upper_lo[axis] = mid;
    split(std::move(lower_map), lo, lower_hi);
    split(std::move(map), upper_lo, hi);
  }

private:
  double tile_size_m_;
  std::function<void(std::int64_t, std::int64_t, PlanarGridMap&)> emit_;
};

/** The index file's text. */
std::string
indexText(const MapTileIndex& index)
{
  std::ostringstream out;
  out << INDEX_MAGIC << "\n"
      << "version " << INDEX_VERSION << "\n"
      << "id PlanarGridMapTiles\n"
      << "resolution_m " << exactText(index.resolution_m) << "\n"
      << "tile_size_m " << exactText(index.tile_size_m) << "\n"
      << "prior " << index.prior << "\n"
      << "generation " << index.generation << "\n"
      << "base " << index.base_file << " " << index.base_file_bytes << "\n"
      << "tiles " << index.tiles.size() << "\n";
  for (const MapTile& t : index.tiles) {
    out << "tile " << t.key_x << " " << t.key_y << " " << t.file << " " << t.file_bytes;
    for (int k = 0; k < 3; ++k)
      out << " " << exactText(t.bounds.min()[k]);
    for (int k = 0; k < 3; ++k)
      out << " " << exactText(t.bounds.max()[k]);
    out << "\n";
  }
  out << "end\n";
  return out.str();
}

/** Checks a tile size against a resolution; returns what is wrong, or "". */
std::string
tileSizeProblem(double tile_size_m, double resolution_m)
{
  if (!std::isfinite(tile_size_m) || tile_size_m <= 0.0 || tile_size_m > 1e5)
    return "tile_size_m " + exactText(tile_size_m) + " is not in (0, 1e5] m";
  const double voxels = tile_size_m / resolution_m;
  if (std::abs(voxels - std::round(voxels)) > 1e-6 * voxels)
    return "tile_size_m " + exactText(tile_size_m)
           + " is not a whole number of voxels of resolution_m "
           + exactText(resolution_m) + " (a voxel would straddle a tile border)";
  return "";
}

/** True for the names saveTiles() gives the files of a set: tile_g<N>_<i>_<j>.pgmap
 * and base_g<N>.pgmap. */
bool
isSetFileName(const std::string& name)
{
  const auto generation_at = [&name](std::size_t at) {
    std::size_t digits = 0;
    while (at + digits < name.size()
           && std::isdigit(static_cast<unsigned char>(name[at + digits])))
      ++digits;
    return digits;
  };
  const bool pgmap = name.size() > 6 && name.compare(name.size() - 6, 6, ".pgmap") == 0;
  if (!pgmap)
    return false;
  if (name.rfind("base_g", 0) == 0)
    return generation_at(6) > 0 && 6 + generation_at(6) == name.size() - 6;
  if (name.rfind("tile_g", 0) == 0) {
    const std::size_t digits = generation_at(6);
    return digits > 0 && name.size() > 6 + digits && name[6 + digits] == '_';
  }
  return false;
}

} // namespace

namespace map_tiles_detail {

std::string
baseFileName(std::uint64_t generation)
{
  return "base_g" + std::to_string(generation) + ".pgmap";
}

std::string
tileFileName(std::uint64_t generation, std::int64_t key_x, std::int64_t key_y)
{
  return "tile_g" + std::to_string(generation) + "_" + std::to_string(key_x) + "_"
         + std::to_string(key_y) + ".pgmap";
}

Eigen::AlignedBox3f
contentBounds(const PlanarGridMap& map)
{
  Eigen::AlignedBox3f box;
  ExplicitSpaceGrid::VoxelKey lo, hi;
  if (map.getSpaceLayer().getBounds(lo, hi)) {
    const double r = map.getResolution();
    box.extend((lo.cast<double>() * r).cast<float>());
    box.extend(((hi.cast<double>() + Eigen::Vector3d::Ones()) * r).cast<float>());
  }
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids()) {
    const Eigen::Vector3f half = 0.5f
                                 * (c.horizontal_axis.cwiseAbs() * c.width_m
                                    + c.verticalAxis().cwiseAbs() * c.height_m
                                    + c.normal.cwiseAbs() * c.thickness_m);
    box.extend(c.centre - half);
    box.extend(c.centre + half);
  }
  return box;
}

std::uint64_t
previousGeneration(const std::string& folder,
                   std::vector<std::string>& files,
                   const char* caller)
{
  files.clear();
  if (!fs::exists(inFolder(folder, MAP_TILE_INDEX_NAME)))
    return 0;
  try {
    const MapTileIndex old = readTileIndex(folder);
    files.push_back(old.base_file);
    for (const MapTile& t : old.tiles)
      files.push_back(t.file);
    return old.generation;
  } catch (const IOError& e) {
    if (caller != nullptr)
      PCL_WARN("[planar_grid::%s] The existing index is not read (%s); its files are "
               "left in place.\n",
               caller, e.what());
    return 0;
  }
}

} // namespace map_tiles_detail

MapTileIndex
writeTileIndex(const std::string& folder, const MapTileIndex& index)
{
  MapTileIndex sorted = index;
  std::sort(
    sorted.tiles.begin(), sorted.tiles.end(), [](const MapTile& a, const MapTile& b) {
      return std::make_pair(a.key_x, a.key_y) < std::make_pair(b.key_x, b.key_y);
    });
  if (!(index.resolution_m > 0.0) || !std::isfinite(index.resolution_m))
    throw Exception("writeTileIndex: resolution_m " + exactText(index.resolution_m)
                    + " is not > 0 m");
  const std::string problem = tileSizeProblem(index.tile_size_m, index.resolution_m);
  if (!problem.empty())
    throw Exception("writeTileIndex: " + problem);
  if (index.prior != "free" && index.prior != "unknown")
    throw Exception("writeTileIndex: prior must be free or unknown, not '" + index.prior
                    + "'");
  // Every file the index names is there with its size, and named once: an index that
  // loadTiles() would refuse is not written over a readable one.
  std::set<std::string> current;
  const auto check = [&](const std::string& name, std::uint64_t bytes) {
    std::error_code ec;
    const std::string path = inFolder(folder, name);
    if (name.empty() || fs::path(name).filename() != name
        || fs::path(name).extension() != ".pgmap")
      throw Exception("writeTileIndex: '" + name + "' is not a plain .pgmap name");
    if (!current.insert(name).second)
      throw Exception("writeTileIndex: " + name + " is named twice");
    const std::uintmax_t size = fs::file_size(path, ec);
    if (ec || size != bytes)
      throw IOError("map tile " + path + ": "
                    + (ec ? "missing" : std::to_string(size) + " bytes")
                    + ", the index to be written says " + std::to_string(bytes));
  };
  check(sorted.base_file, sorted.base_file_bytes);
  for (std::size_t k = 0; k < sorted.tiles.size(); ++k) {
    const MapTile& t = sorted.tiles[k];
    if (k > 0 && t.key_x == sorted.tiles[k - 1].key_x
        && t.key_y == sorted.tiles[k - 1].key_y)
      throw Exception("writeTileIndex: tile key " + std::to_string(t.key_x) + " "
                      + std::to_string(t.key_y) + " is listed twice");
    if (t.bounds.isEmpty() || !t.bounds.min().allFinite()
        || !t.bounds.max().allFinite())
      throw Exception("writeTileIndex: tile " + t.file
                      + " has empty or infinite bounds");
    check(t.file, t.file_bytes);
  }

  std::vector<std::string> old_files;
  map_tiles_detail::previousGeneration(folder, old_files, "writeTileIndex");
  // Until this rename, the folder's index names the previous set.
  writeTextFileAtomically(inFolder(folder, MAP_TILE_INDEX_NAME), indexText(sorted));

  // The previous set's files go, and the files a set whose writing did not finish
  // left: every file of the folder named like a set's file (tile_g<N>_... or
  // base_g<N>.pgmap) that the new index does not name.
  std::error_code ec;
  std::set<std::string> stale(old_files.begin(), old_files.end());
  for (const fs::directory_entry& entry : fs::directory_iterator(folder, ec))
    if (entry.is_regular_file(ec) && isSetFileName(entry.path().filename().string()))
      stale.insert(entry.path().filename().string());
  for (const std::string& name : stale)
    if (current.count(name) == 0 && !fs::remove(inFolder(folder, name), ec) && ec)
      PCL_WARN("[planar_grid::writeTileIndex] Could not remove the stale file %s: "
               "%s.\n",
               inFolder(folder, name).c_str(), ec.message().c_str());
  return sorted;
}

MapTileIndex
saveTiles(const PlanarGridMap& map, const std::string& folder, double tile_size_m)
{
  const std::string problem = tileSizeProblem(tile_size_m, map.getResolution());
  if (!problem.empty())
    throw Exception("saveTiles: " + problem);
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder))
    throw IOError("tile folder " + folder + ": cannot be made (" + ec.message() + ")");

  MapTileIndex index;
  index.resolution_m = map.getResolution();
  index.tile_size_m = tile_size_m;
  index.prior = toString(map.getParams().space.prior);
  // (An unreadable index is warned about once, by writeTileIndex().)
  std::vector<std::string> old_files;
  index.generation =
    map_tiles_detail::previousGeneration(folder, old_files, nullptr) + 1;

  // The base: the map with its parameters and no content.
  PlanarGridMap base = copyOf(map);
  base.removeOutside(Eigen::AlignedBox3f()); // an empty box keeps nothing
  index.base_file = map_tiles_detail::baseFileName(index.generation);
  base.save(inFolder(folder, index.base_file));
  index.base_file_bytes = fs::file_size(inFolder(folder, index.base_file));

  const Eigen::AlignedBox3f bounds = map_tiles_detail::contentBounds(map);
  if (!bounds.isEmpty()) {
    const auto key = [tile_size_m](float v) {
      return static_cast<std::int64_t>(
        std::floor(static_cast<double>(v) / tile_size_m));
    };
    TileSplitter splitter(
      tile_size_m, [&](std::int64_t kx, std::int64_t ky, PlanarGridMap& tile) {
        MapTile t;
        t.key_x = kx;
        t.key_y = ky;
        t.file = map_tiles_detail::tileFileName(index.generation, kx, ky);
        t.bounds = map_tiles_detail::contentBounds(tile);
        tile.save(inFolder(folder, t.file));
        t.file_bytes = fs::file_size(inFolder(folder, t.file));
        index.tiles.push_back(std::move(t));
      });
    splitter.split(copyOf(map), {key(bounds.min().x()), key(bounds.min().y())},
                   {key(bounds.max().x()), key(bounds.max().y())});
  }
  // The index last (writeTileIndex(): atomic, then the previous set's files go).
  return writeTileIndex(folder, index);
}

} // namespace planar_grid
