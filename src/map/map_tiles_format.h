// SPDX-License-Identifier: BSD-3-Clause
// What the writers and the readers of tile sets share: the index's first line and
// version, the names of a set's files, and the checked loading of a tile.
#pragma once

#include <planar_grid/map/map_tiles.h>

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace planar_grid {
namespace map_tiles_detail {

/** \brief The first line of a tile index. */
constexpr const char* INDEX_MAGIC = "# Planar grid map tiles";
/** \brief The index format's version. */
constexpr int INDEX_VERSION = 1;

/** \brief The name of the base map of set \a generation: base_g<N>.pgmap. */
std::string baseFileName(std::uint64_t generation);

/** \brief The name of tile (\a key_x, \a key_y) of set \a generation:
 * tile_g<N>_<i>_<j>.pgmap. */
std::string
tileFileName(std::uint64_t generation, std::int64_t key_x, std::int64_t key_y);

/** \brief Bounds of the map's content, meters: the stored voxel blocks and the
 * axis-aligned boxes of the cuboids; empty when the map is. */
Eigen::AlignedBox3f contentBounds(const PlanarGridMap& map);

/** \brief The generation of the set the index of \a folder names, or 0 when there is
 * none or it cannot be read (then warned, naming \a caller, unless it is null);
 * \a files receives the files it names. */
std::uint64_t previousGeneration(const std::string& folder,
                                 std::vector<std::string>& files,
                                 const char* caller);

/** \brief The file \a name of a set in \a folder as a map, checked against the index:
 * present, \a bytes long, readable (PlanarGridMap::load()), with the index's
 * resolution_m and prior.
 * \throws planar_grid::IOError naming the file otherwise */
PlanarGridMap loadTileFile(const std::string& folder,
                           const std::string& name,
                           std::uint64_t bytes,
                           const MapTileIndex& index);

/** \brief The parameters the tiles of a set are merged with: the base map's, without
 * the tidying of Params::planes_absorb_overlapping and
 * Params::planes_replace_non_planar. While a plane is in pieces its cover is cut at
 * the tile borders, and a tidying on such a cover would move or remove cells that the
 * whole map keeps. (Neither switch is stored in a map file: a tile written with these
 * parameters loads with the defaults.) */
PlanarGridMap::Params tileMergeParams(const PlanarGridMap& base);

} // namespace map_tiles_detail
} // namespace planar_grid
