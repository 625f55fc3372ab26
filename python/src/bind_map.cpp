// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap: construction, the map file, merging, its cuboids, planes and memory,
// export; SpaceState as a Python IntEnum. Integration is bound in
// bind_map_integration.cpp, the queries in bind_map_queries.cpp.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pybind11/stl.h>

#include <algorithm>
#include <mutex>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "param_kwargs.h"
#include "planar_grid_python.h"

namespace planar_grid {
namespace python {

namespace {

/** The maps Mappers handed to Python, while they live. */
std::mutex mapper_maps_mutex;
std::vector<std::weak_ptr<const PlanarGridMap>> mapper_maps;

} // namespace

void
markMapperOwned(const std::shared_ptr<const PlanarGridMap>& map)
{
  const std::lock_guard<std::mutex> lock(mapper_maps_mutex);
  mapper_maps.erase(std::remove_if(mapper_maps.begin(), mapper_maps.end(),
                                   [](const auto& m) { return m.expired(); }),
                    mapper_maps.end());
  for (const auto& m : mapper_maps)
    if (m.lock() == map)
      return;
  mapper_maps.push_back(map);
}

void
requireWritable(const PlanarGridMap& map, const char* method)
{
  const std::lock_guard<std::mutex> lock(mapper_maps_mutex);
  for (const auto& m : mapper_maps)
    if (m.lock().get() == &map)
      throw Exception(
        std::string("PlanarGridMap.") + method
        + ": this map is a Mapper's (Mapper.map or Mapper.read_map()); it "
          "changes only through the Mapper's integrate_* calls, which "
          "hold its lock. Change a copy: pickle it, or save it and load it");
}

SpaceState
toSpaceState(const py::handle& state)
{
  if (py::isinstance<py::str>(state)) {
    try {
      return spaceStateFromString(state.cast<std::string>());
    } catch (const planar_grid::Exception& e) {
      throw py::value_error(e.what());
    }
  }
  const int value = state.cast<int>();
  if (value < 0 || value > 2)
    throw py::value_error(
      "state " + std::to_string(value)
      + " must be SpaceState.FREE (0), OCCUPIED (1) or UNKNOWN (2)");
  return static_cast<SpaceState>(value);
}

namespace {

using Map = PlanarGridMap;
using MapClass = py::class_<Map, std::shared_ptr<Map>>;

/** SpaceState, an IntEnum of the module. */
void
bindSpaceState(py::module_& m)
{
  py::object int_enum = py::module_::import("enum").attr("IntEnum");
  py::dict members;
  members["FREE"] = static_cast<int>(SpaceState::FREE);
  members["OCCUPIED"] = static_cast<int>(SpaceState::OCCUPIED);
  members["UNKNOWN"] = static_cast<int>(SpaceState::UNKNOWN);
  py::object space_state =
    int_enum("SpaceState", members, py::arg("module") = "planar_grid");
  space_state.attr("__doc__") =
    "State of a cell of the map, with the paper's 2-bit labels (Sec. IV): FREE = 0, "
    "OCCUPIED = 1, UNKNOWN = 2. An IntEnum, so it compares with the uint8 arrays of "
    "PlanarGridMap.get_state().";
  m.attr("SpaceState") = space_state;
}

/** The class docstring; its Parameters section is map_integration's table. */
const std::string&
mapClassDoc()
{
  // The keyword arguments are map_integration's keys: their descriptions, defaults
  // and ranges come from that stage's parameter table.
  static const std::string doc =
    R"doc(The planar grid map: plane-aligned cuboids and explicit free / occupied / unknown space.

planar_grid::PlanarGridMap (paper Sec. III-F, Fig. 5c, Sec. IV): a surface layer of
cuboids with occupancy probabilities, merged across frames, and an explicit space
layer of voxels of edge resolution_m. A point inside a cuboid takes the cuboid's
probability (occupied when >= occupancy_thres); elsewhere the voxel's state decides.

Parameters
----------
)doc"
    + declaredParameterDocs(Map::getParamDeclarations()) + R"doc(
The defaults are the pipeline's map_integration defaults (one Params struct); a map
built here with the keys of a configuration's map_integration stage matches the tool's.

Raises
------
ValueError
    For a parameter out of its range (the library's message).

Notes
-----
Maps are not copied (copy.copy raises); pickling goes through the map file format.
)doc";
  return doc;
}

/** The constructor: its keyword arguments, their types, defaults and conversion, and
 * its signature, all from the map's parameter table (PlanarGridMap::Params). */
void
bindMapConstructor(MapClass& cls)
{
  bindKeywordConstructor(
    cls, "PlanarGridMap", Map::getParamDeclarations(), {},
    [](const Map::Params& params, const std::vector<double>&) {
      try {
        return std::make_shared<Map>(params);
      } catch (const planar_grid::Exception& e) {
        throw py::value_error(std::string("PlanarGridMap: ") + e.what());
      }
    },
    wrapText("An empty map. Every keyword argument is a key of map_integration, with "
             "its default (the class's Parameters).",
             0, 88));
}

/** Reading and writing the map file. */
void
bindMapFile(MapClass& cls)
{
  cls
    .def_static(
      "load",
      [](const py::object& path) {
        const std::string file = toPath(path);
        py::gil_scoped_release release;
        return std::make_shared<Map>(Map::load(file));
      },
      py::arg("path"),
      R"doc(Reads a map file (.pgmap, written by save() or the pipeline).

Parameters
----------
path : str or os.PathLike

Returns
-------
PlanarGridMap

Raises
------
planar_grid.IOError
    (an OSError) for a missing, truncated or corrupt file, an unknown version or a bad
    header value; the message names the file and the cause.
)doc")
    .def(
      "save",
      [](const Map& self, const py::object& path) {
        const std::string file = toPath(path);
        py::gil_scoped_release release;
        self.save(file);
      },
      py::arg("path"),
      R"doc(Writes the map file, atomically (a temporary file renamed over path).

Raises
------
planar_grid.IOError
    When it cannot be written.
)doc");
}

/** Merging maps and the observation span that orders them. */
void
bindMapMerge(MapClass& cls)
{
  cls
    .def(
      "merge",
      [](Map& self, const Map& other, const DoubleArray& this_T_other) {
        requireWritable(self, "merge");
        Eigen::Isometry3d transform = toIsometry(this_T_other, "this_T_other");
        // toIsometry() accepts a rotation within 1e-3 of orthonormal (a float32
        // matrix, a pose read from text); merge() moves plane moments and raster
        // frames, which needs a rotation: the nearest one is used
        transform.linear() =
          Eigen::Quaterniond(transform.linear()).normalized().toRotationMatrix();
        py::gil_scoped_release release;
        self.merge(other, transform);
      },
      py::arg("other"), py::arg("this_T_other"),
      R"doc(Merges another map (another recording's, mapped on its own) into this one.

Planes: each plane of ``other`` joins the plane of this map that the association of
integrate_surface() matches (a wall seen in both maps becomes one plane, its evidence
added and refitted, the rasters re-projected into one frame, not two parallel planes);
planes without a match are added. Non-planar cells: both maps' are kept. Voxels: when
one map's observation_span lies wholly after the other's (segments of one recording,
as the pipeline notes its frames), the newer map's free or occupied observation wins
where both observed a voxel, as integration keeps the newest view; when the spans
overlap or one is None, occupied > free > unknown (occluded) > never observed (the
clamped log-odds of two independent observations added, as OctoMap fuses them:
occupied where the maps disagree). The merged span is the union. Merging a into b and
b into a give the same voxels, planes and cuboids up to their order (except where one
map holds a surface as several planes); merging an empty map changes nothing.
``other`` is not changed.

Parameters
----------
other : PlanarGridMap
    The map merged in (not this map).
this_T_other : array_like, shape (4, 4), float
    Rigid transform from ``other``'s world frame to this map's: rotation and
    translation in meters, last row 0 0 0 1 (the identity, ``np.eye(4)``, for maps
    whose poses share one world frame, such as GPS/INS poses). A rotation within 1e-3
    of orthonormal is replaced by the nearest rotation. Other than the identity, the
    voxels and raster cells of ``other`` are resampled to the nearest cell (whole-voxel
    translations move the voxels exactly).

Raises
------
ValueError
    For ``this_T_other`` not of shape (4, 4) or not a rigid transform.
planar_grid.Error
    When the maps' resolution_m, prior or any surface parameter (thickness_m,
    plane_merge_angle_rad, plane_merge_distance_m, occupancy_thres, feature_distance_m,
    close_gaps_cells, merge_rule, cover_density, absorb_distance_m,
    terrain_plane_tile_m) differ, naming
    them; or when ``other`` is this map. The map is then unchanged.
)doc")
    .def_property(
      "observation_span",
      [](const Map& self) -> py::object {
        const Map::ObservationSpan& span = self.getObservationSpan();
        if (span.empty())
          return py::none();
        return py::make_tuple(span.first, span.last);
      },
      [](Map& self, const py::object& value) {
        Map::ObservationSpan span;
        if (!value.is_none()) {
          const auto pair = value.cast<std::pair<double, double>>();
          if (!(pair.first <= pair.second))
            throw py::value_error("observation_span must be (first, last) with "
                                  "first <= last, or None");
          span.first = pair.first;
          span.last = pair.second;
        }
        self.setObservationSpan(span);
      },
      R"doc(tuple (first, last) of float, or None: the least and greatest order key of
the views the map holds (note_observation_order(); the pipeline notes each frame's index
in its recording), None when none was noted (a new map, a file written before the span
was stored). merge() lets the newer map's voxels win when one span lies wholly after
the other's. Settable (None empties it); planar_grid.Error for a non-finite bound.)doc")
    .def(
      "note_observation_order",
      [](Map& self, double order) {
        requireWritable(self, "note_observation_order");
        self.noteObservationOrder(order);
      },
      py::arg("order"),
      R"doc(Grows observation_span to include ``order``, a number that increases
with the time of the views (a frame index, a timestamp in seconds) and is comparable
between the maps that will be merged. planar_grid.Error for a non-finite order.)doc");
}

/** Read-only queries of the contents: cuboids, planes, parameters, memory, voxels. */
void
bindMapContents(MapClass& cls)
{
  cls
    .def_property_readonly(
      "cuboids",
      [](const Map& self) { return Cuboids{self.getSurfaceLayer().getCuboids()}; },
      "Cuboids: the merged cuboids, every map plane's rectangles (plane_ids index "
      "planes) "
      "then the non-planar cells (plane_id -1), with their probabilities.")
    .def_property_readonly(
      "planes",
      [](const Map& self) {
        const auto& planes = self.getSurfaceLayer().getPlanes();
        py::array_t<double> out(
          {static_cast<py::ssize_t>(planes.size()), py::ssize_t{4}});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t i = 0; i < planes.size(); ++i)
          for (py::ssize_t j = 0; j < 4; ++j)
            o(static_cast<py::ssize_t>(i), j) = planes[i][static_cast<int>(j)];
        return out;
      },
      "numpy.ndarray, shape (K, 4), float64: the map's planes [a, b, c, d] (unit "
      "normal, "
      "d in meters), world frame.")
    .def_property_readonly("resolution_m", &Map::getResolution,
                           "float: the minimum cell size, meters.")
    .def_property_readonly(
      "params",
      [](const Map& self) {
        return paramsDict(Map::getParamDeclarations(), self.getParams());
      },
      "dict: the parameters, by the constructor's keyword names.")
    .def_property_readonly(
      "memory",
      [](const Map& self) {
        const MapMemory memory = self.getMemory();
        py::dict out;
        out["surface_bytes"] = memory.surface_bytes;
        out["space_bytes"] = memory.space_bytes;
        out["total_bytes"] = memory.total_bytes;
        return out;
      },
      "dict: bytes held by the surface layer, the space layer and both (surface_bytes, "
      "space_bytes, total_bytes).")
    .def_property_readonly(
      "cell_count",
      [](const Map& self) { return self.getSurfaceLayer().getCellCount(); },
      "int: observed raster cells over all planes plus non-planar cells.")
    .def_property_readonly(
      "voxel_counts",
      [](const Map& self) {
        const auto& space = self.getSpaceLayer();
        py::dict out;
        for (const SpaceState s :
             {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
          out[py::str(toString(s))] = space.getVoxelCount(s);
        return out;
      },
      "dict: voxels per state ('free', 'occupied', 'unknown') that differ from the "
      "prior (0 for the prior's own state).")
    .def(
      "voxel_centres",
      [](const Map& self, const py::object& state) {
        const SpaceState wanted = toSpaceState(state);
        const auto& space = self.getSpaceLayer();
        std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> centres;
        space.forEachVoxel([&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState s) {
          if (s == wanted)
            centres.push_back(space.toCentre(key));
        });
        py::array_t<double> out(
          {static_cast<py::ssize_t>(centres.size()), py::ssize_t{3}});
        auto o = out.mutable_unchecked<2>();
        for (std::size_t i = 0; i < centres.size(); ++i)
          for (py::ssize_t k = 0; k < 3; ++k)
            o(static_cast<py::ssize_t>(i), k) = centres[i][static_cast<int>(k)];
        return out;
      },
      py::arg("state"),
      R"doc(Centres of the observed voxels in a state (never-observed space, which reads
as the prior, is not listed).

Parameters
----------
state : SpaceState, int or str

Returns
-------
numpy.ndarray, shape (N, 3), float64
    Voxel centres, meters (voxel edge resolution_m), in a deterministic order.
)doc");
}

/** Exports to other formats: ROS 2D occupancy grid, OctoMap, mesh. */
void
bindMapExport(MapClass& cls)
{
  cls
    .def(
      "export_occupancy_grid_2d",
      [](const Map& self, const py::object& path, double z_min_m, double z_max_m,
         double z_ref_m, bool above_terrain, double terrain_tile_m, double resolution_m,
         double max_slope_rad, double terrain_max_angle_rad, const py::object& bounds,
         double occupied_thresh, double free_thresh) {
        OccupancyGrid2DParams params;
        params.z_min_m = z_min_m;
        params.z_max_m = z_max_m;
        params.z_ref_m = z_ref_m;
        params.above_terrain = above_terrain;
        params.terrain_tile_m = terrain_tile_m;
        params.resolution_m = resolution_m;
        params.max_slope_rad = max_slope_rad;
        params.terrain_max_angle_rad = terrain_max_angle_rad;
        params.occupied_thresh = occupied_thresh;
        params.free_thresh = free_thresh;
        if (!bounds.is_none()) {
          const DoubleArray b = DoubleArray::ensure(bounds);
          if (b.size() != 4)
            throw py::value_error(
              "bounds must be (min_x, min_y, max_x, max_y), meters");
          params.use_bounds = true;
          params.min_xy = Eigen::Vector2d(b.data()[0], b.data()[1]);
          params.max_xy = Eigen::Vector2d(b.data()[2], b.data()[3]);
        }
        const std::string file = toPath(path);
        OccupancyGrid2D grid;
        {
          py::gil_scoped_release release;
          grid = self.exportOccupancyGrid2D(file, params);
        }
        py::array_t<std::int8_t> cells({static_cast<py::ssize_t>(grid.height),
                                        static_cast<py::ssize_t>(grid.width)});
        std::copy(grid.cells.begin(), grid.cells.end(), cells.mutable_data());
        py::dict out;
        out["cells"] = cells;
        out["origin"] = py::make_tuple(grid.origin.x(), grid.origin.y());
        out["resolution"] = grid.resolution_m;
        return out;
      },
      py::arg("path"), py::kw_only(), py::arg("z_min_m") = 0.2,
      py::arg("z_max_m") = 2.0, py::arg("z_ref_m") = 0.0,
      py::arg("above_terrain") = false, py::arg("terrain_tile_m") = 2.0,
      py::arg("resolution_m") = 0.0, py::arg("max_slope_rad") = 0.3490658503988659,
      py::arg("terrain_max_angle_rad") = 1.0471975511965976,
      py::arg("bounds") = py::none(), py::arg("occupied_thresh") = 0.65,
      py::arg("free_thresh") = 0.196,
      R"doc(Writes the map projected over a height band as a ROS map_server map.

A cell is occupied where an occupied cuboid or voxel meets its column inside the band
[z_ref_m + z_min_m, z_ref_m + z_max_m] (above the local terrain with above_terrain) or
terrain steeper than max_slope_rad covers it, free where the views saw free space in
the band or walkable terrain, unknown elsewhere. Writes ``path`` (YAML: image, mode,
resolution, origin, negate, occupied_thresh, free_thresh) and the PGM it names beside
it (0 occupied, 254 free, 205 unknown), atomically.

Parameters
----------
path : str or os.PathLike
    The YAML file, ending in ".yaml" or ".yml"; the image is the same name with ".pgm".
z_min_m, z_max_m, z_ref_m : float
    The band, meters.
above_terrain : bool
    Measure the band from the local terrain: the walkable terrain cuboids under a cell,
    else the surfaces the space layer saw from above (20th percentile per tile).
terrain_tile_m : float
    The tile of the space layer's terrain, meters.
resolution_m : float
    Cell edge, meters (0: the map's).
max_slope_rad, terrain_max_angle_rad : float
    Terrain (planar cuboids within terrain_max_angle_rad of horizontal) steeper than
    max_slope_rad is an obstacle.
bounds : array_like (min_x, min_y, max_x, max_y), optional
    The area, meters (default: the map's extent).
occupied_thresh, free_thresh : float
    Written to the YAML for map_server.

Returns
-------
dict
    ``cells`` (H, W) int8 (-1 unknown, 0 free, 100 occupied; row 0 at the lowest y),
    ``origin`` (x, y) of the lower-left corner, meters, and ``resolution``.
)doc")
    .def(
      "export_octomap",
      [](const Map& self, const py::object& path) {
        const planar_grid::OctoMapExportSummary s = self.exportOctoMap(toPath(path));
        py::dict out;
        out["nodes"] = s.nodes;
        out["leaf_nodes"] = s.leaf_nodes;
        out["occupied_leaves"] = s.occupied_leaves;
        out["free_leaves"] = s.free_leaves;
        out["occupied_voxels"] = s.occupied_voxels;
        out["free_voxels"] = s.free_voxels;
        out["skipped_voxels"] = s.skipped_voxels;
        return out;
      },
      py::arg("path"),
      "Writes the observed space and the cuboids as an OctoMap tree: .bt (binary: "
      "free / occupied per voxel) or .ot (full: each voxel's log-odds, a cuboid's "
      "from its occupancy); never-observed and occluded space are left out. Returns "
      "what was written, as liboctomap counts it: a dict of nodes, leaf_nodes, "
      "occupied_leaves, free_leaves, occupied_voxels, free_voxels (voxels of "
      "resolution_m under those leaves) and skipped_voxels (outside OctoMap's key "
      "range). Raises planar_grid.IOError when it cannot be written.")
    .def(
      "export_mesh",
      [](const Map& self, const py::object& path) { self.exportMesh(toPath(path)); },
      py::arg("path"),
      "Writes the cuboids as a mesh (.ply or .vtk), coloured by probability; raises "
      "planar_grid.IOError for another extension or a write error.");
}

/** Equality, copy refusal, repr and pickling. */
void
bindMapProtocol(MapClass& cls)
{
  cls
    .def(
      "__eq__",
      [](const Map& self, const py::object& other) {
        return py::isinstance<Map>(other) && self == *other.cast<Map*>();
      },
      py::arg("other"), "True when both layers are equal (parameters, cells, voxels).")
    .def("__ne__",
         [](const Map& self, const py::object& other) {
           return !(py::isinstance<Map>(other) && self == *other.cast<Map*>());
         })
    .def("__copy__",
         [](const Map&) -> std::shared_ptr<Map> {
           throw py::type_error(
             "PlanarGridMap is not copied (maps are heavy); save and "
             "load it, or pickle it");
         })
    .def("__repr__",
         [](const Map& self) {
           std::ostringstream text;
           text << "<planar_grid.PlanarGridMap: resolution " << self.getResolution()
                << " m, " << self.getSurfaceLayer().getCuboidCount() << " cuboids, "
                << self.getMemory().total_bytes << " bytes>";
           return text.str();
         })
    .def(py::pickle(
      [](const Map& self) {
        std::string bytes;
        self.serialize(bytes);
        return py::bytes(bytes);
      },
      [](const py::bytes& bytes) {
        return std::make_shared<Map>(Map::deserialize(bytes, "<pickle>"));
      }));
}

} // namespace

void
bindMap(py::module_& m)
{
  bindSpaceState(m);
  MapClass cls(m, "PlanarGridMap", mapClassDoc().c_str());
  bindMapConstructor(cls);
  bindMapFile(cls);
  bindMapMerge(cls);
  bindMapContents(cls);
  bindMapExport(cls);
  bindMapProtocol(cls);
}

} // namespace python
} // namespace planar_grid
