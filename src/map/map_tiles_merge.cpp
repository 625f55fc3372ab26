// SPDX-License-Identifier: BSD-3-Clause
// Tile sets merged by region: the same tile key of several sets merged into one tile
// file, so that the work of merging maps is split by tile and no step holds a whole
// map.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>

#include <algorithm>
#include <charconv>
#include <filesystem>
#include <map>
#include <set>
#include <string>
#include <utility>

#include "map_tiles_format.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

using map_tiles_detail::loadTileFile;

/** Shortest text of a value that reads back to the same value. */
std::string
numberText(double value)
{
  char buffer[64];
  const auto result = std::to_chars(buffer, buffer + sizeof(buffer), value);
  return std::string(buffer, result.ptr);
}

/** The indices of \a folders, each checked to agree with the first one's
 * (resolution_m, tile_size_m, prior). */
std::vector<MapTileIndex>
readAgreeingIndices(const std::vector<std::string>& folders, const std::string& caller)
{
  if (folders.empty())
    throw Exception(caller + ": no tile folder given");
  // A set merged with itself would count every observation twice.
  std::map<fs::path, std::string> seen;
  for (const std::string& folder : folders) {
    std::error_code ec;
    fs::path resolved = fs::weakly_canonical(fs::path(folder), ec);
    if (ec)
      resolved = fs::absolute(fs::path(folder)).lexically_normal();
    const auto [at, inserted] = seen.emplace(resolved, folder);
    if (!inserted)
      throw Exception(caller + ": tile folder " + folder + " is given twice (also as "
                      + at->second
                      + "): a set merged with itself counts its "
                        "observations twice");
  }
  std::vector<MapTileIndex> indices;
  for (const std::string& folder : folders) {
    MapTileIndex index = readTileIndex(folder);
    if (!indices.empty()) {
      const MapTileIndex& first = indices.front();
      std::string differences;
      const auto differ = [&](const std::string& key, const std::string& mine,
                              const std::string& theirs) {
        if (mine != theirs)
          differences += " " + key + " " + mine + " (not " + theirs + ")";
      };
      differ("resolution_m", numberText(index.resolution_m),
             numberText(first.resolution_m));
      differ("tile_size_m", numberText(index.tile_size_m),
             numberText(first.tile_size_m));
      differ("prior", index.prior, first.prior);
      if (!differences.empty())
        throw Exception(caller + ": tile folder " + folder
                        + " does not match the first folder " + folders.front() + ":"
                        + differences);
    }
    indices.push_back(std::move(index));
  }
  return indices;
}

/** Merges \a map (file \a name of \a folder) into \a merged with the identity; a
 * refused merge (parameters that differ) names the folder. */
void
mergeNaming(PlanarGridMap& merged,
            const PlanarGridMap& map,
            const std::string& folder,
            const std::string& name,
            const std::string& caller)
{
  try {
    merged.merge(map, Eigen::Isometry3d::Identity());
  } catch (const IOError&) {
    throw;
  } catch (const Exception& e) {
    throw Exception(caller + ": tile folder " + folder + " (" + name
                    + ") does not match the first folder: " + e.what());
  }
}

/** Creates \a folder when missing. */
void
makeFolder(const std::string& folder)
{
  std::error_code ec;
  fs::create_directories(folder, ec);
  if (ec || !fs::is_directory(folder))
    throw IOError("tile folder " + folder + ": cannot be made (" + ec.message() + ")");
}

/** mergeTile() on indices already read and checked. */
MapTile
mergeTileOf(const std::vector<std::string>& folders,
            const std::vector<MapTileIndex>& indices,
            std::int64_t key_x,
            std::int64_t key_y,
            const std::string& output_folder,
            std::uint64_t generation)
{
  const std::string caller = "mergeTile";
  if (generation == 0)
    throw Exception(caller + ": generation must be >= 1");
  PlanarGridMap merged(map_tiles_detail::tileMergeParams(
    loadTileFile(folders.front(), indices.front().base_file,
                 indices.front().base_file_bytes, indices.front())));
  bool found = false;
  for (std::size_t f = 0; f < folders.size(); ++f) {
    const auto& tiles = indices[f].tiles;
    const auto tile = std::find_if(tiles.begin(), tiles.end(), [&](const MapTile& t) {
      return t.key_x == key_x && t.key_y == key_y;
    });
    if (tile == tiles.end())
      continue;
    found = true;
    mergeNaming(merged,
                loadTileFile(folders[f], tile->file, tile->file_bytes, indices[f]),
                folders[f], tile->file, caller);
  }
  if (!found)
    throw Exception(caller + ": no tile folder holds tile " + std::to_string(key_x)
                    + " " + std::to_string(key_y));
  makeFolder(output_folder);
  MapTile out;
  out.key_x = key_x;
  out.key_y = key_y;
  out.file = map_tiles_detail::tileFileName(generation, key_x, key_y);
  out.bounds = map_tiles_detail::contentBounds(merged);
  const std::string path = (fs::path(output_folder) / out.file).string();
  merged.save(path);
  out.file_bytes = fs::file_size(path);
  return out;
}

} // namespace

MapTileIndex
prepareTileMerge(const std::vector<std::string>& folders,
                 const std::string& output_folder)
{
  const std::string caller = "prepareTileMerge";
  const std::vector<MapTileIndex> indices = readAgreeingIndices(folders, caller);
  PlanarGridMap base(map_tiles_detail::tileMergeParams(
    loadTileFile(folders.front(), indices.front().base_file,
                 indices.front().base_file_bytes, indices.front())));
  for (std::size_t f = 0; f < folders.size(); ++f)
    mergeNaming(base,
                loadTileFile(folders[f], indices[f].base_file,
                             indices[f].base_file_bytes, indices[f]),
                folders[f], indices[f].base_file, caller);

  makeFolder(output_folder);
  MapTileIndex index;
  index.resolution_m = indices.front().resolution_m;
  index.tile_size_m = indices.front().tile_size_m;
  index.prior = indices.front().prior;
  std::vector<std::string> old_files;
  // (An unreadable index is warned about once, by writeTileIndex().)
  index.generation =
    map_tiles_detail::previousGeneration(output_folder, old_files, nullptr) + 1;
  index.base_file = map_tiles_detail::baseFileName(index.generation);
  const std::string path = (fs::path(output_folder) / index.base_file).string();
  base.save(path);
  index.base_file_bytes = fs::file_size(path);
  return index;
}

MapTile
mergeTile(const std::vector<std::string>& folders,
          std::int64_t key_x,
          std::int64_t key_y,
          const std::string& output_folder,
          std::uint64_t generation)
{
  return mergeTileOf(folders, readAgreeingIndices(folders, "mergeTile"), key_x, key_y,
                     output_folder, generation);
}

MapTileIndex
mergeTileSets(const std::vector<std::string>& folders, const std::string& output_folder)
{
  MapTileIndex index = prepareTileMerge(folders, output_folder);
  const std::vector<MapTileIndex> indices =
    readAgreeingIndices(folders, "mergeTileSets");
  std::set<std::pair<std::int64_t, std::int64_t>> keys;
  for (const MapTileIndex& set : indices)
    for (const MapTile& t : set.tiles)
      keys.insert({t.key_x, t.key_y});
  for (const auto& key : keys)
    index.tiles.push_back(mergeTileOf(folders, indices, key.first, key.second,
                                      output_folder, index.generation));
  return writeTileIndex(output_folder, index);
}

} // namespace planar_grid
