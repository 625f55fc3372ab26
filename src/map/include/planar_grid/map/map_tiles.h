// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/map/planar_grid_map.h>

#include <Eigen/Geometry>

#include <cstdint>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief One tile of a tiled map, as its index lists it. \ingroup map */
struct MapTile {
  /** \brief Tile key along x: the tile holds x in [key_x, key_x + 1) tile_size_m. */
  std::int64_t key_x{0};
  /** \brief Tile key along y: the tile holds y in [key_y, key_y + 1) tile_size_m. */
  std::int64_t key_y{0};
  /** \brief The tile's .pgmap file, a plain name inside the tile folder. */
  std::string file;
  /** \brief Length of that file, bytes. */
  std::uint64_t file_bytes{0};
  /** \brief Bounds of the tile's content, meters, world frame: its stored voxel blocks
   * (block-aligned, 8 voxels) and the axis-aligned boxes of its cuboids. Cuboids reach
   * past the tile's square by up to half a cuboid. */
  Eigen::AlignedBox3f bounds;
};

/** \brief The index of a tiled map (the file MAP_TILE_INDEX_NAME in the tile folder).
 * \ingroup map */
struct MapTileIndex {
  /** \brief The map's resolution_m, meters. */
  double resolution_m{0.0};
  /** \brief Edge of a tile's square in x and y, meters (a whole number of voxels). */
  double tile_size_m{0.0};
  /** \brief The space layer's prior ("free" or "unknown"). */
  std::string prior;
  /** \brief Counts the sets written into the folder; the files of a set carry it in
   * their names, so that a new set never overwrites the files of the set the index
   * names until the new index has replaced it. */
  std::uint64_t generation{0};
  /** \brief The map with no content (its parameters only), a plain name in the folder:
   * what loadTiles() merges the tiles into. */
  std::string base_file;
  /** \brief Length of base_file, bytes. */
  std::uint64_t base_file_bytes{0};
  /** \brief The tiles, sorted by (key_x, key_y); tiles without content are not
   * written. */
  std::vector<MapTile> tiles;
};

/** \brief Name of the index file in a tile folder. */
constexpr const char* MAP_TILE_INDEX_NAME = "index.pgtiles";

/** \brief Writes \a map as tiles: squares of tile_size_m x tile_size_m in x and y
 * (world z up, every height), each a .pgmap file written by PlanarGridMap::save(), and
 * an index (text, MAP_TILE_INDEX_NAME; format in docs/MAP.md, "Tiles").
 *
 * Where things go (the square of tile (i, j) is [i, i + 1) x [j, j + 1) times
 * tile_size_m, half-open, so every point is in exactly one square):
 * - a space layer voxel goes to the tile whose square holds its centre (voxels never
 *   straddle a border: tile_size_m is a whole number of voxels);
 * - a plane's raster cell goes to the tile whose square holds the centre of its face
 *   (as PlanarGridMap::removeOutside() decides); a plane crossing borders is stored in
 *   every tile holding some of its cells, each copy with the plane's whole fit
 *   (moments), and its cuboids are covered per tile from the tile's cells (a
 *   rectangle crossing a border is cut there; loading both tiles joins the plane again
 *   and covers its cells as before);
 * - a non-planar cell goes to the tile whose square holds its centre.
 * Nothing is lost or stored twice, except the plane fits a crossing plane repeats.
 *
 * The set is written so that a half-written set is never read: the tiles and the base
 * map first, under names carrying a new generation number, then the index (written to
 * a temporary file and renamed over the old one). Until that rename the folder's index
 * names the previous set, whose files are untouched; after it, the previous set's
 * files are removed, and every file named like a set's file (tile_g<N>_...,
 * base_g<N>.pgmap) that the new index does not name (left by a save that did not
 * finish). Other files in the folder are left alone.
 * \param[in] map the map (unchanged)
 * \param[in] folder the tile folder (created when missing)
 * \param[in] tile_size_m edge of a tile, meters: > 0, finite, a whole number of
 * map voxels (resolution_m), at most 1e5
 * \return the index written
 * \throws planar_grid::Exception for an invalid tile_size_m; planar_grid::IOError
 * naming the file when a file cannot be written */
MapTileIndex
saveTiles(const PlanarGridMap& map, const std::string& folder, double tile_size_m);

/** \brief Reads and checks the index of a tile folder: the magic line, version 1, id,
 * each key in order (resolution_m > 0, tile_size_m a whole number of voxels, prior,
 * generation, base, tiles), each tile line (key, plain file name, file size, bounds
 * with min <= max), keys and file names unique, the end line and nothing after it.
 * The tiles themselves are not opened.
 * \param[in] folder the tile folder
 * \throws planar_grid::IOError naming the index file and the line for a missing
 * index or anything that does not match */
MapTileIndex readTileIndex(const std::string& folder);

/** \brief Loads the tiles of \a folder whose content bounds meet \a region, grown by
 * \a margin_m in x and y, and merges them (PlanarGridMap::merge() with the identity,
 * in key order) into an empty map of the set's parameters. The pieces of a plane split
 * over tiles join into one plane. The merges skip the planes' tidying
 * (Params::planes_absorb_overlapping, planes_replace_non_planar: the saved map was
 * tidied, and a tidying on covers cut at tile borders would move or remove cells the
 * whole map keeps); the map returned has the parameters PlanarGridMap::load() gives.
 * It holds whole tiles (call removeOutside() to cut it to the region).
 *
 * A plane in N tiles comes back with N times its fit's moments (each piece carries the
 * whole fit): the same plane and cuboids, but N times the weight when it is later
 * merged with another map or compared by evidence, so operator== with the saved map
 * is false for a map with planes across tiles.
 *
 * With every tile loaded, the map equals the saved one: the same getState()
 * everywhere, the same cuboids up to order, the same planes. Inside a region, the
 * space layer and the non-planar cells are exact; a plane's cuboids are covered from
 * the cells of the loaded tiles, so where a rectangle of the saved map reaches past
 * them it is cut and its cells re-covered (as by removeOutside()), and the density
 * cover (merge_rule density) may choose other rectangles near the cut. A margin
 * keeps such cuts away from the region. docs/MAP.md, "Tiles", gives the figures.
 * \param[in] folder the tile folder
 * \param[in] region box, meters, world frame; a bound may be infinite (every tile:
 * an unbounded box)
 * \param[in] margin_m tiles within this distance of the region in x and y are loaded
 * too, meters, >= 0
 * \return the merged map
 * \throws planar_grid::Exception for a negative or NaN margin_m;
 * planar_grid::IOError naming the file for a bad index (readTileIndex()), a missing
 * tile, a tile whose size differs from the index, a corrupt tile
 * (PlanarGridMap::load()), or a tile whose resolution_m or prior differ from the index
 */
PlanarGridMap loadTiles(const std::string& folder,
                        const Eigen::AlignedBox3f& region,
                        double margin_m = 0.0);

/** \brief loadTiles() for the tiles whose content bounds lie within radius_m +
 * margin_m of \a position in x and y (distance from the point to the bounds'
 * rectangle), at every height.
 * \param[in] folder the tile folder
 * \param[in] position centre, meters, world frame (its z is not used)
 * \param[in] radius_m radius in x and y, meters, >= 0
 * \param[in] margin_m added to the radius, meters, >= 0
 * \throws as the box variant, and planar_grid::Exception for a negative or NaN
 * radius_m or a non-finite position */
PlanarGridMap loadTiles(const std::string& folder,
                        const Eigen::Vector3f& position,
                        double radius_m,
                        double margin_m = 0.0);

/** \brief Writes \a index as the index of \a folder, so that a half-written set is
 * never read: the text goes to a temporary file renamed over the old index; until
 * that rename the folder reads as the previous set. Then the previous set's files are
 * removed, with every file named like a set's file (tile_g<N>_..., base_g<N>.pgmap)
 * that \a index does not name (left by a writing that did not finish); other files in
 * the folder are left alone. saveTiles() and mergeTileSets() end with it.
 * \param[in] folder the tile folder, which holds the files \a index names
 * \param[in] index the set: resolution_m > 0, tile_size_m a whole number of voxels in
 * (0, 1e5] m, prior "free" or "unknown", the base and tile files (plain .pgmap names,
 * each named once), tile keys unique, tile bounds finite with min <= max; the tiles
 * may come in any order
 * \return the index written (its tiles sorted by (key_x, key_y))
 * \throws planar_grid::Exception for an index that breaks the rules above;
 * planar_grid::IOError naming the file for a file it names that is missing or of
 * another length, or for an index that cannot be written. The folder is then
 * unchanged. */
MapTileIndex writeTileIndex(const std::string& folder, const MapTileIndex& index);

/** \brief Starts a merge of tile sets into \a output_folder by region (the first step
 * of mergeTileSets(); mergeTile() then writes each tile, writeTileIndex() the index):
 * checks that the sets agree, chooses the output's generation (its current index's
 * + 1, or 1) and writes the output's base map, the merge of the sets' base maps (their
 * parameters; its observation span is the union of theirs).
 * \param[in] folders the tile folders (saveTiles()), at least one; \a output_folder may
 * be one of them (its current set stays readable until the new index is written)
 * \param[in] output_folder the folder of the merged set (created when missing)
 * \return the merged set's index without its tiles: the sets' resolution_m,
 * tile_size_m and prior, the new generation, the base file written
 * \throws planar_grid::Exception for no folder, or naming the folder whose
 * resolution_m, tile_size_m, prior or surface layer parameters differ from the first
 * folder's; planar_grid::IOError naming the file for a bad index or base map
 * (readTileIndex(), loadTiles()) or an output that cannot be written */
MapTileIndex prepareTileMerge(const std::vector<std::string>& folders,
                              const std::string& output_folder);

/** \brief Merges tile (\a key_x, \a key_y) of several tile sets into one tile file of
 * \a output_folder, named as saveTiles() names the tiles of set \a generation
 * (tile_g<N>_<i>_<j>.pgmap, written atomically; the output's index is not touched).
 *
 * The tile is merged as loadTiles() merges tiles: the tiles of the folders that hold
 * the key, in the order of \a folders (folders without it are skipped), are merged
 * with PlanarGridMap::merge() and the identity into an empty map of the first folder's
 * parameters, without the planes' tidying (Params::planes_absorb_overlapping,
 * planes_replace_non_planar; loadTiles() says why). Where the tiles disagree:
 * - space layer: when the observation span of the tile merged in lies wholly after
 *   that of the tiles merged so far (or wholly before), the newer observation of a
 *   voxel wins; otherwise occupied > free > unknown > never observed. Folders of
 *   segments of one recording, given in the order of their frames, thus give each
 *   voxel the state of the last segment that observed it;
 * - surface layer: a plane of a later folder joins the plane the association matches
 *   (moments added, refitted), else is added; non-planar cells of all are kept.
 * Each tile of a set holds the whole fit of a plane crossing its borders, so the
 * pieces of a plane merge as the whole planes would, and loadTiles() of the merged set
 * joins them again. Where a plane of one set meets a plane of another in some tiles
 * only, its pieces end with different fits; loadTiles() then joins them by the
 * association (as merge() joins planes), and the cover near those borders may differ
 * from that of the whole maps merged.
 * \param[in] folders the tile folders (saveTiles()), in the order their maps are
 * merged: of one recording, earliest frames first
 * \param[in] key_x the tile key along x (the tile holds x in [key_x, key_x + 1)
 * tile_size_m)
 * \param[in] key_y the tile key along y
 * \param[in] output_folder the folder of the merged set (created when missing)
 * \param[in] generation the merged set's generation (prepareTileMerge()), >= 1
 * \return the tile as the merged index will list it: key, file, its length in bytes
 * and the bounds of its content, meters
 * \throws planar_grid::Exception for no folder, generation 0, a key no folder holds,
 * or naming the folder whose resolution_m, tile_size_m, prior or surface layer
 * parameters differ from the first folder's; planar_grid::IOError naming the file for
 * a bad index or tile (readTileIndex(), loadTiles()) or a file that cannot be
 * written */
MapTile mergeTile(const std::vector<std::string>& folders,
                  std::int64_t key_x,
                  std::int64_t key_y,
                  const std::string& output_folder,
                  std::uint64_t generation);

/** \brief Merges tile sets by region: prepareTileMerge(), then mergeTile() for every
 * key any folder holds, one after another in key order, then writeTileIndex(). The
 * merged set loads (loadTiles()) as the maps merged whole in the order of \a folders
 * and saved as tiles would: the same space layer, voxel for voxel, and the same planes
 * and cuboids, except near tile borders where a plane met another map's plane in some
 * tiles only, and the planes' tidying after the merge, which is skipped (mergeTile()).
 * A set without tiles (an empty map's) changes nothing. While it runs, the output
 * folder reads as its previous set.
 * \param[in] folders the tile folders, in merge order (earliest frames first)
 * \param[in] output_folder the folder of the merged set (created when missing; may be
 * one of \a folders)
 * \return the index written
 * \throws as prepareTileMerge(), mergeTile() and writeTileIndex() */
MapTileIndex mergeTileSets(const std::vector<std::string>& folders,
                           const std::string& output_folder);

} // namespace planar_grid
