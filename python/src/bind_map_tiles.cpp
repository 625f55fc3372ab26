// SPDX-License-Identifier: BSD-3-Clause
// Tiled maps: save_tiles, load_tiles and read_tile_index (on PlanarGridMap and the
// module), and the merge of tile sets by region (merge_tile_sets, prepare_tile_merge,
// merge_tile, write_tile_index).
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pybind11/stl.h>

#include <string>
#include <vector>

#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

using Map = PlanarGridMap;
using MapClass = py::class_<Map, std::shared_ptr<Map>>;

/** One tile of an index as a dict. */
py::dict
tileDict(const MapTile& t)
{
  py::dict tile;
  tile["key"] = py::make_tuple(t.key_x, t.key_y);
  tile["file"] = t.file;
  tile["file_bytes"] = t.file_bytes;
  tile["bounds_min"] = toArray(t.bounds.min());
  tile["bounds_max"] = toArray(t.bounds.max());
  return tile;
}

/** A dict of tileDict()'s form as a tile. */
MapTile
tileFromDict(const py::handle& item)
{
  const auto d = item.cast<py::dict>();
  MapTile t;
  const py::tuple key = d["key"].cast<py::tuple>();
  if (key.size() != 2)
    throw py::value_error("a tile's key must be (i, j)");
  t.key_x = key[0].cast<std::int64_t>();
  t.key_y = key[1].cast<std::int64_t>();
  t.file = d["file"].cast<std::string>();
  t.file_bytes = d["file_bytes"].cast<std::uint64_t>();
  t.bounds.min() = toVector3f(d["bounds_min"].cast<DoubleArray>(), "bounds_min");
  t.bounds.max() = toVector3f(d["bounds_max"].cast<DoubleArray>(), "bounds_max");
  return t;
}

/** The index of a tile folder as a dict. */
py::dict
tileIndexDict(const MapTileIndex& index)
{
  py::list tiles;
  for (const MapTile& t : index.tiles)
    tiles.append(tileDict(t));
  py::dict out;
  out["resolution_m"] = index.resolution_m;
  out["tile_size_m"] = index.tile_size_m;
  out["prior"] = index.prior;
  out["generation"] = index.generation;
  out["base_file"] = index.base_file;
  out["base_file_bytes"] = index.base_file_bytes;
  out["tiles"] = tiles;
  return out;
}

constexpr const char* TILE_INDEX_DOC = R"doc(The index as a dict: resolution_m (m),
tile_size_m (m), prior, generation, base_file, base_file_bytes and tiles, a list of
dicts with key (i, j): the tile holds x in [i, i + 1) and y in [j, j + 1) times
tile_size_m; file (a name in the folder), file_bytes, bounds_min and bounds_max
(numpy arrays, shape (3,), meters: the content's bounds, cuboids included).)doc";

/** save_tiles, load_tiles and read_tile_index, on the class and the module. */
void
bindSaveLoadTiles(py::module_& m, MapClass& cls)
{
  const auto save = [](const Map& self, const py::object& folder, double tile_size_m) {
    const std::string path = toPath(folder);
    MapTileIndex index;
    {
      py::gil_scoped_release release;
      index = saveTiles(self, path, tile_size_m);
    }
    return tileIndexDict(index);
  };
  const std::string save_doc =
    std::string(
      R"doc(Writes the map as tiles: squares of tile_size_m in x and y (world z up, every height),
each a .pgmap file, and an index (index.pgtiles) written last, so that a half-written
set is never read (the previous set stays readable until the new index replaces it).

A voxel goes to the tile holding its centre, a plane's raster cell to the tile holding
its face centre, a non-planar cell to the tile holding its centre; a plane crossing
tile borders is stored in each tile it reaches, with its whole fit, and is one plane
again when those tiles are loaded.

Parameters
----------
map : PlanarGridMap
    The map (unchanged).
folder : str or os.PathLike
    The tile folder (created when missing).
tile_size_m : float
    Edge of a tile, meters: > 0, at most 1e5 and a whole number of voxels
    (resolution_m).

Returns
-------
dict
    )doc")
    + TILE_INDEX_DOC + R"doc(

Raises
------
planar_grid.Error
    For an invalid tile_size_m.
planar_grid.IOError
    When a file cannot be written (the message names it).
)doc";
  cls.def("save_tiles", save, py::arg("folder"), py::arg("tile_size_m"),
          save_doc.c_str());
  m.def("save_tiles", save, py::arg("map"), py::arg("folder"), py::arg("tile_size_m"),
        save_doc.c_str());

  const auto load = [](const py::object& folder, const DoubleArray& first,
                       const py::object& second, double margin_m) {
    const std::string path = toPath(folder);
    const Eigen::Vector3f a = toVector3f(first, "box_min / position");
    if (py::isinstance<py::float_>(second) || py::isinstance<py::int_>(second)) {
      const double radius_m = second.cast<double>();
      py::gil_scoped_release release;
      return std::make_shared<Map>(loadTiles(path, a, radius_m, margin_m));
    }
    const Eigen::Vector3f b = toVector3f(second.cast<DoubleArray>(), "box_max");
    py::gil_scoped_release release;
    return std::make_shared<Map>(loadTiles(path, Eigen::AlignedBox3f(a, b), margin_m));
  };
  const char* load_doc =
    R"doc(Loads the tiles of a folder written by save_tiles() that a region reaches and merges
them (merge() with the identity) into one map; the pieces of a plane split over tiles
become one plane again. Two forms: given box_min and box_max, the tiles whose content
bounds meet the box; given position and radius_m (a number as the third argument), the
tiles within radius_m of position in x and y (every height). With every tile (box_min
-inf, box_max inf) the map equals the saved one. The map holds whole tiles.

Parameters
----------
folder : str or os.PathLike
    The tile folder.
box_min, box_max : array_like, shape (3,), meters
    The region's corners (world frame; a bound may be +-inf).
position : array_like, shape (3,), meters
    The centre (its z is not used).
radius_m : float
    Radius in x and y, meters, >= 0.
margin_m : float, optional
    Tiles within this distance of the region in x and y are loaded too, meters, >= 0
    (default 0): a plane's cuboids are covered from the loaded cells, so a margin keeps
    the cut away from the region.

Returns
-------
PlanarGridMap

Raises
------
ValueError
    For a corner or position not of shape (3,).
planar_grid.Error
    For a negative radius_m or margin_m.
planar_grid.IOError
    For a missing or malformed index (the message names index.pgtiles and the line), a
    missing tile, a tile whose size differs from the index, a corrupt tile, or a tile
    of another resolution or prior (the message names the tile).
)doc";
  cls.def_static("load_tiles", load, py::arg("folder"), py::arg("box_min"),
                 py::arg("box_max"), py::arg("margin_m") = 0.0, load_doc);
  m.def("load_tiles", load, py::arg("folder"), py::arg("box_min"), py::arg("box_max"),
        py::arg("margin_m") = 0.0, load_doc);
  m.def(
    "read_tile_index",
    [](const py::object& folder) {
      return tileIndexDict(readTileIndex(toPath(folder)));
    },
    py::arg("folder"),
    (std::string(
       "Reads and checks the index of a tile folder (the tiles are not "
       "opened); raises planar_grid.IOError naming index.pgtiles and the "
       "line for anything that does not match.\n\nReturns\n-------\ndict\n    ")
     + TILE_INDEX_DOC)
      .c_str());
}

/** A dict of tileIndexDict()'s form as an index. */
MapTileIndex
tileIndexFromDict(const py::dict& d)
{
  MapTileIndex index;
  index.resolution_m = d["resolution_m"].cast<double>();
  index.tile_size_m = d["tile_size_m"].cast<double>();
  index.prior = d["prior"].cast<std::string>();
  index.generation = d["generation"].cast<std::uint64_t>();
  index.base_file = d["base_file"].cast<std::string>();
  index.base_file_bytes = d["base_file_bytes"].cast<std::uint64_t>();
  for (const py::handle item : d["tiles"])
    index.tiles.push_back(tileFromDict(item));
  return index;
}

/** The paths of a list of folders. */
std::vector<std::string>
toPaths(const py::iterable& folders)
{
  std::vector<std::string> out;
  for (const py::handle folder : folders)
    out.push_back(toPath(folder));
  return out;
}

/** \brief What merge_tile_sets() and merge_tile() do where the maps disagree. */
constexpr const char* TILE_MERGE_ORDER_DOC = R"doc(
Where the maps disagree: in the space layer, when one tile's observation span (its
frames) lies wholly after the others', its observations win voxel by voxel; otherwise
occupied > free > unknown > never observed. In the surface layer, a plane of a later
folder joins the plane the association matches (one plane, refitted), else is added;
non-planar cells of all are kept. The planes' tidying after a merge
(planes_absorb_overlapping, planes_replace_non_planar) is skipped, as load_tiles()
skips it: tile covers are cut at the borders.)doc";

/** \brief merge_tile_sets: one call merges whole folders of tiles. */
void
bindMergeTileSets(py::module_& m)
{
  m.def(
    "merge_tile_sets",
    [](const py::iterable& folders, const py::object& output_folder) {
      const std::vector<std::string> paths = toPaths(folders);
      const std::string out = toPath(output_folder);
      MapTileIndex index;
      {
        py::gil_scoped_release release;
        index = mergeTileSets(paths, out);
      }
      return tileIndexDict(index);
    },
    py::arg("folders"), py::arg("output_folder"),
    (std::string(
       R"doc(Merges tile sets (save_tiles()) tile by tile into output_folder: for every key any
folder holds, the tiles of that key (folders without it skipped) are merged with the
identity in the order of folders and written as one tile, then the index is written
(atomically; until then output_folder reads as its previous set, whose files are then
removed). load_tiles() of the result gives the maps merged whole and saved as tiles:
the same voxels and planes, the same cuboids except near tile borders where a plane
met another map's plane in some tiles only, and without the planes' tidying.)doc")
     + TILE_MERGE_ORDER_DOC + R"doc(

Parameters
----------
folders : list of str or os.PathLike
    The tile folders, in merge order (of one recording: earliest frames first), with
    equal resolution_m, tile_size_m, prior and surface parameters.
output_folder : str or os.PathLike
    The merged set's folder (created when missing; may be one of folders).

Returns
-------
dict
    )doc"
     + TILE_INDEX_DOC + R"doc(

Raises
------
planar_grid.Error
    For no folder, or naming the folder whose parameters differ from the first's.
planar_grid.IOError
    For a bad index or tile, or a file that cannot be written (the message names it).
)doc")
      .c_str());
}

/** \brief prepare_tile_merge and merge_tile: a merge tile by tile, for many workers. */
void
bindTileByTileMerge(py::module_& m)
{
  m.def(
    "prepare_tile_merge",
    [](const py::iterable& folders, const py::object& output_folder) {
      const std::vector<std::string> paths = toPaths(folders);
      const std::string out = toPath(output_folder);
      MapTileIndex index;
      {
        py::gil_scoped_release release;
        index = prepareTileMerge(paths, out);
      }
      return tileIndexDict(index);
    },
    py::arg("folders"), py::arg("output_folder"),
    (std::string(
       R"doc(The first step of merge_tile_sets(), for a merge split into tasks: checks that the
sets agree, chooses the output's generation (its index's + 1, or 1) and writes the
merged base map into output_folder. Then merge_tile() for each key, then
write_tile_index() with the tiles added.

Returns
-------
dict
    The merged set's index without tiles: )doc")
     + TILE_INDEX_DOC + R"doc(

Raises
------
planar_grid.Error, planar_grid.IOError
    As merge_tile_sets().
)doc")
      .c_str());
  m.def(
    "merge_tile",
    [](const py::iterable& folders, const py::sequence& key,
       const py::object& output_folder, std::uint64_t generation) {
      if (key.size() != 2)
        throw py::value_error("key must be (i, j)");
      const std::vector<std::string> paths = toPaths(folders);
      const std::string out = toPath(output_folder);
      const auto kx = key[0].cast<std::int64_t>(), ky = key[1].cast<std::int64_t>();
      MapTile tile;
      {
        py::gil_scoped_release release;
        tile = mergeTile(paths, kx, ky, out, generation);
      }
      return tileDict(tile);
    },
    py::arg("folders"), py::arg("key"), py::arg("output_folder"), py::arg("generation"),
    (std::string(
       R"doc(Merges tile key (i, j) of several tile sets into one tile file of output_folder,
named as save_tiles() names the tiles of set generation; the index is not touched.
The tiles of the folders that hold the key are merged with the identity, in the order
of folders, into an empty map of the first folder's parameters.)doc")
     + TILE_MERGE_ORDER_DOC + R"doc(

Parameters
----------
folders : list of str or os.PathLike
    The tile folders, in merge order (earliest frames first).
key : sequence of 2 int
    (i, j): the tile holds x in [i, i + 1) and y in [j, j + 1) times tile_size_m.
output_folder : str or os.PathLike
    The merged set's folder.
generation : int
    The merged set's generation (prepare_tile_merge()), >= 1.

Returns
-------
dict
    The tile as the index lists it: key, file, file_bytes, bounds_min and bounds_max
    (meters).

Raises
------
planar_grid.Error
    For a key no folder holds, generation 0, or folders that do not match.
planar_grid.IOError
    For a bad index or tile, or a file that cannot be written.
)doc")
      .c_str());
}

/** \brief write_tile_index. */
void
bindWriteTileIndex(py::module_& m)
{
  m.def(
    "write_tile_index",
    [](const py::object& folder, const py::dict& index) {
      const std::string path = toPath(folder);
      const MapTileIndex parsed = tileIndexFromDict(index);
      MapTileIndex written;
      {
        py::gil_scoped_release release;
        written = writeTileIndex(path, parsed);
      }
      return tileIndexDict(written);
    },
    py::arg("folder"), py::arg("index"),
    (std::string(
       R"doc(Writes index (a dict as read_tile_index() returns) as the index of folder, atomically
(a temporary file renamed over the old index), then removes the previous set's files
and any file named like a set's file that the index does not name. Every file it
names must be in folder with its file_bytes; the tiles may come in any order.

Returns
-------
dict
    The index written, its tiles sorted by key: )doc")
     + TILE_INDEX_DOC + R"doc(

Raises
------
planar_grid.Error
    For an index that breaks the format's rules (a key twice, a bad tile size).
planar_grid.IOError
    For a named file that is missing or of another length, or a failed write; the
    folder is then unchanged.
)doc")
      .c_str());
}

/** merge_tile_sets, prepare_tile_merge, merge_tile and write_tile_index. */
void
bindTileMerge(py::module_& m)
{
  bindMergeTileSets(m);
  bindTileByTileMerge(m);
  bindWriteTileIndex(m);
}

} // namespace

void
bindMapTiles(py::module_& m)
{
  // The class is registered by bindMap(); the tile methods are added to it here.
  auto cls = py::reinterpret_borrow<MapClass>(m.attr("PlanarGridMap"));
  bindSaveLoadTiles(m, cls);
  bindTileMerge(m);
}

} // namespace python
} // namespace planar_grid
