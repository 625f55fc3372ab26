// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap's projection over a height band into a 2D occupancy grid and its
// ROS map_server files (PGM + YAML).
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/map/planar_grid_map.h>

#include <sys/stat.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace planar_grid {

std::size_t
OccupancyGrid2D::count(std::int8_t value) const
{
  return static_cast<std::size_t>(std::count(cells.begin(), cells.end(), value));
}

namespace {

/** \brief The interval of the vertical line through (x, y) inside cuboid \a c, as
 * heights [t0, t1]; false when the line misses it. */
bool
columnInterval(const PlanarCuboid& c, double x, double y, double& t0, double& t1)
{
  const Eigen::Vector3d axes[3] = {c.horizontal_axis.cast<double>(),
                                   c.verticalAxis().cast<double>(),
                                   c.normal.cast<double>()};
  const double half[3] = {0.5 * c.width_m, 0.5 * c.height_m, 0.5 * c.thickness_m};
  const Eigen::Vector3d d(x - c.centre.x(), y - c.centre.y(), -c.centre.z());
  t0 = -std::numeric_limits<double>::infinity();
  t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    // |axes[k] . (d + t e_z)| <= half[k]
    const double q = axes[k].dot(d), a = axes[k].z();
    if (std::abs(a) < 1e-12) {
      if (std::abs(q) > half[k])
        return false;
      continue;
    }
    double lo = (-half[k] - q) / a, hi = (half[k] - q) / a;
    if (lo > hi)
      std::swap(lo, hi);
    t0 = std::max(t0, lo);
    t1 = std::min(t1, hi);
  }
  return t0 <= t1;
}

void
validate(const OccupancyGrid2DParams& p)
{
  const auto fail = [](const std::string& what) {
    throw Exception("PlanarGridMap::computeOccupancyGrid2D: " + what);
  };
  namespace ranges = occupancy_grid_2d_ranges;
  const auto check = [&fail](const char* name, double value, const ParamRange& range,
                             const char* unit) {
    if (!range.contains(value))
      fail(paramRangeMessage(name, range, unit) + ", got " + std::to_string(value));
  };
  if (p.resolution_m != 0.0)
    check("resolution_m (when not 0, the map's)", p.resolution_m, ranges::RESOLUTION,
          "m");
  check("z_ref_m", p.z_ref_m, ranges::Z_REF, "m");
  check("z_min_m", p.z_min_m, ranges::Z_BAND, "m");
  check("z_max_m", p.z_max_m, ranges::Z_BAND, "m");
  if (!(p.z_max_m > p.z_min_m))
    fail("the band needs z_min_m < z_max_m, got z_min_m " + std::to_string(p.z_min_m)
         + ", z_max_m " + std::to_string(p.z_max_m));
  check("terrain_max_angle_rad", p.terrain_max_angle_rad, ranges::ANGLE, "rad");
  check("terrain_tile_m", p.terrain_tile_m, ranges::TERRAIN_TILE, "m");
  check("max_slope_rad", p.max_slope_rad, ranges::ANGLE, "rad");
  if (p.use_bounds
      && (!p.min_xy.allFinite() || !p.max_xy.allFinite()
          || !(p.max_xy.array() > p.min_xy.array()).all()))
    fail("bounds need finite min_xy < max_xy");
  if (!(p.free_thresh > 0.0 && p.free_thresh < p.occupied_thresh
        && p.occupied_thresh < 1.0))
    fail("thresholds need 0 < free_thresh < occupied_thresh < 1, got "
         + std::to_string(p.free_thresh) + ", " + std::to_string(p.occupied_thresh));
}

/** \brief The cells of a 2D grid over the map: which cells a cuboid's or a voxel's
 * footprint covers. */
struct GridCells {
  const OccupancyGrid2D& grid;
  /** \brief The grid's cell edge, meters. */
  double r;
  /** \brief The voxels' edge, meters. */
  double vr;

  std::size_t index(int col, int row) const
  {
    return static_cast<std::size_t>(row) * static_cast<std::size_t>(grid.width)
           + static_cast<std::size_t>(col);
  }

  /** \brief Calls f(col, row, x, y) for every cell whose centre lies in the XY
   * bounding box of cuboid \a c. */
  template <typename F> void forCellsOf(const PlanarCuboid& c, F&& f) const
  {
    Eigen::Vector2d blo = Eigen::Vector2d::Constant(std::numeric_limits<double>::max());
    Eigen::Vector2d bhi = -blo;
    for (const auto& corner : c.corners()) {
      blo = blo.cwiseMin(corner.head<2>().cast<double>());
      bhi = bhi.cwiseMax(corner.head<2>().cast<double>());
    }
    const int c0 =
      std::max(0, static_cast<int>(std::ceil((blo.x() - grid.origin.x()) / r - 0.5)));
    const int c1 =
      std::min(grid.width - 1,
               static_cast<int>(std::floor((bhi.x() - grid.origin.x()) / r - 0.5)));
    const int r0 =
      std::max(0, static_cast<int>(std::ceil((blo.y() - grid.origin.y()) / r - 0.5)));
    const int r1 =
      std::min(grid.height - 1,
               static_cast<int>(std::floor((bhi.y() - grid.origin.y()) / r - 0.5)));
    for (int row = r0; row <= r1; ++row)
      for (int col = c0; col <= c1; ++col)
        f(col, row, grid.origin.x() + (col + 0.5) * r,
          grid.origin.y() + (row + 0.5) * r);
  }

  /** \brief Calls f(cell index) for every cell whose square meets voxel \a key's
   * footprint. */
  template <typename F>
  void forFootprint(const ExplicitSpaceGrid::VoxelKey& key, F&& f) const
  {
    const double x0 = key.x() * vr, y0 = key.y() * vr;
    const double eps = 1e-6;
    const int c0 =
      std::max(0, static_cast<int>(std::floor((x0 - grid.origin.x()) / r + eps)));
    const int c1 =
      std::min(grid.width - 1,
               static_cast<int>(std::ceil((x0 + vr - grid.origin.x()) / r - eps)) - 1);
    const int r0 =
      std::max(0, static_cast<int>(std::floor((y0 - grid.origin.y()) / r + eps)));
    const int r1 =
      std::min(grid.height - 1,
               static_cast<int>(std::ceil((y0 + vr - grid.origin.y()) / r - eps)) - 1);
    for (int row = r0; row <= r1; ++row)
      for (int col = c0; col <= c1; ++col)
        f(index(col, row));
  }
};

/** \brief The grid over \a params' bounds, or over the map's (its voxels' and
 * cuboids' XY extent) without them, every cell unknown.
 * \throws Exception for an empty map without bounds, or over 1e8 cells. */
OccupancyGrid2D
emptyGrid(const OccupancyGrid2DParams& params,
          double r,
          double vr,
          const ExplicitSpaceGrid& space,
          const PlanarCuboids& cuboids)
{
  Eigen::Vector2d lo = params.min_xy, hi = params.max_xy;
  if (!params.use_bounds) {
    lo.setConstant(std::numeric_limits<double>::infinity());
    hi = -lo;
    ExplicitSpaceGrid::VoxelKey klo, khi;
    if (space.getBounds(klo, khi)) {
      lo = lo.cwiseMin(klo.head<2>().cast<double>() * vr);
      hi = hi.cwiseMax((khi.head<2>().cast<double>() + Eigen::Vector2d::Ones()) * vr);
    }
    for (const PlanarCuboid& c : cuboids) {
      for (const auto& corner : c.corners()) {
        lo = lo.cwiseMin(corner.head<2>().cast<double>());
        hi = hi.cwiseMax(corner.head<2>().cast<double>());
      }
    }
    if (!(hi.array() > lo.array()).all())
      throw Exception("PlanarGridMap::computeOccupancyGrid2D: the map is empty; give "
                      "bounds (use_bounds)");
  }
  OccupancyGrid2D grid;
  grid.resolution_m = r;
  // The origin sits on the grid of cell edges through 0, so that cells of the map's
  // resolution line up with the voxels' columns.
  grid.origin = (lo / r).array().floor().matrix() * r;
  const Eigen::Vector2d cells = ((hi - grid.origin) / r).array().ceil().matrix();
  if (!(cells.x() * cells.y() <= 1e8))
    throw Exception("PlanarGridMap::computeOccupancyGrid2D: "
                    + std::to_string(cells.x()) + " x " + std::to_string(cells.y())
                    + " cells is over the limit of 1e8; give bounds or a coarser "
                      "resolution_m");
  grid.width = std::max(1, static_cast<int>(cells.x()));
  grid.height = std::max(1, static_cast<int>(cells.y()));
  grid.cells.assign(static_cast<std::size_t>(grid.width) * grid.height,
                    OccupancyGrid2D::UNKNOWN);
  return grid;
}

/** \brief What the projection knows per cell before the cells get their value. */
struct CellMarks {
  /** \brief Height of the terrain under the cell, meters (NaN: none known). */
  std::vector<float> terrain;
  std::vector<std::uint8_t> steep, seen_free, occupied;

  explicit CellMarks(std::size_t n) :
      terrain(n, std::numeric_limits<float>::quiet_NaN()), steep(n, 0), seen_free(n, 0),
      occupied(n, 0)
  {}
};

/** \brief Terrain: planar cuboids within terrain_max_angle_rad of horizontal that
 * reach below the band of the fixed reference. A walkable one (within max_slope_rad)
 * marks its cells free and raises their terrain to its top; a steeper one marks them
 * steep. Returns which cuboids are terrain. */
std::vector<std::uint8_t>
markTerrainCuboids(const OccupancyGrid2DParams& params,
                   const PlanarCuboids& cuboids,
                   const GridCells& cells,
                   CellMarks& marks)
{
  const double cos_terrain = std::cos(params.terrain_max_angle_rad);
  const double cos_slope = std::cos(params.max_slope_rad);
  const double fixed_lo = params.z_ref_m + params.z_min_m;
  std::vector<std::uint8_t> is_terrain(cuboids.size(), 0);
  for (std::size_t i = 0; i < cuboids.size(); ++i) {
    const PlanarCuboid& c = cuboids[i];
    const double nz = std::abs(static_cast<double>(c.normal.z()));
    if (!c.is_planar || nz < cos_terrain)
      continue;
    is_terrain[i] = 1;
    const bool walkable = nz >= cos_slope;
    cells.forCellsOf(c, [&](int col, int row, double x, double y) {
      double t0, t1;
      if (!columnInterval(c, x, y, t0, t1) || t0 > fixed_lo)
        return;
      const std::size_t k = cells.index(col, row);
      if (walkable) {
        marks.seen_free[k] = 1;
        if (!(marks.terrain[k] >= t1))
          marks.terrain[k] = static_cast<float>(t1);
      } else {
        marks.steep[k] = 1;
      }
    });
  }
  return is_terrain;
}

/** \brief The terrain the space layer saw, where no walkable terrain cuboid is: per
 * tile of terrain_tile_m, the 20th percentile of the tops of the occupied voxels with
 * free space above them, for the tile's cells without terrain. */
void
fillTerrainFromVoxels(const OccupancyGrid2DParams& params,
                      const ExplicitSpaceGrid& space,
                      const GridCells& cells,
                      std::vector<float>& terrain)
{
  const OccupancyGrid2D& grid = cells.grid;
  std::vector<float> seen(terrain.size(), std::numeric_limits<float>::quiet_NaN());
  // An occupied voxel with free space above it: within a vertical run of occupied
  // voxels only the run's top one can be.
  space.forEachVoxelRun(
    [&](const ExplicitSpaceGrid::VoxelKey& key, int length, SpaceState state) {
      if (state != SpaceState::OCCUPIED)
        return;
      const int top_z = key.z() + length - 1;
      if (space.getState(ExplicitSpaceGrid::VoxelKey(key.x(), key.y(), top_z + 1))
          != SpaceState::FREE)
        return;
      const auto top = static_cast<float>((top_z + 1) * cells.vr);
      cells.forFootprint(key, [&](std::size_t k) {
        if (!(seen[k] <= top))
          seen[k] = top;
      });
    });
  const int tile =
    std::max(1, static_cast<int>(std::lround(params.terrain_tile_m / cells.r)));
  std::vector<float> values;
  for (int row0 = 0; row0 < grid.height; row0 += tile)
    for (int col0 = 0; col0 < grid.width; col0 += tile) {
      values.clear();
      const int row1 = std::min(grid.height, row0 + tile);
      const int col1 = std::min(grid.width, col0 + tile);
      for (int row = row0; row < row1; ++row)
        for (int col = col0; col < col1; ++col)
          if (std::isfinite(seen[cells.index(col, row)]))
            values.push_back(seen[cells.index(col, row)]);
      if (values.empty())
        continue;
      auto pick = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 5);
      std::nth_element(values.begin(), pick, values.end());
      for (int row = row0; row < row1; ++row)
        for (int col = col0; col < col1; ++col)
          if (!std::isfinite(terrain[cells.index(col, row)]))
            terrain[cells.index(col, row)] = *pick;
    }
}

} // namespace

OccupancyGrid2D
PlanarGridMap::computeOccupancyGrid2D(const OccupancyGrid2DParams& params) const
{
  validate(params);
  const double r =
    params.resolution_m > 0.0 ? params.resolution_m : params_.resolution_m;
  const double vr = params_.resolution_m;
  const PlanarCuboids cuboids = surface_.getCuboids();
  OccupancyGrid2D grid = emptyGrid(params, r, vr, space_, cuboids);
  const std::size_t n = grid.cells.size();
  const GridCells cells{grid, r, vr};
  CellMarks marks(n);
  const std::vector<std::uint8_t> is_terrain =
    markTerrainCuboids(params, cuboids, cells, marks);
  if (params.above_terrain)
    fillTerrainFromVoxels(params, space_, cells, marks.terrain);
  const auto band = [&](std::size_t k, double& b0, double& b1) {
    const double ref = params.above_terrain && std::isfinite(marks.terrain[k])
                         ? static_cast<double>(marks.terrain[k])
                         : params.z_ref_m;
    b0 = ref + params.z_min_m;
    b1 = ref + params.z_max_m;
  };

  const double fixed_lo = params.z_ref_m + params.z_min_m;
  const auto thres = static_cast<float>(surface_.getParams().occupancy_thres);
  for (std::size_t i = 0; i < cuboids.size(); ++i) {
    const PlanarCuboid& c = cuboids[i];
    if (!(c.probability >= thres))
      continue;
    // A terrain cuboid below the band is floor, not an obstacle.
    cells.forCellsOf(c, [&](int col, int row, double x, double y) {
      double t0, t1, b0, b1;
      if (!columnInterval(c, x, y, t0, t1))
        return;
      const std::size_t k = cells.index(col, row);
      band(k, b0, b1);
      if (is_terrain[i] && t0 <= fixed_lo && t1 < b0)
        return;
      if (t1 >= b0 && t0 <= b1)
        marks.occupied[k] = 1;
    });
  }

  // Voxels: every cell whose square meets the voxel's footprint, one vertical run of
  // voxels in one state at a time.
  space_.forEachVoxelRun(
    [&](const ExplicitSpaceGrid::VoxelKey& key, int length, SpaceState s) {
      if (s == SpaceState::UNKNOWN)
        return;
      std::vector<std::uint8_t>& mark =
        s == SpaceState::OCCUPIED ? marks.occupied : marks.seen_free;
      cells.forFootprint(key, [&](std::size_t k) {
        if (mark[k])
          return;
        double b0, b1;
        band(k, b0, b1);
        for (int dz = 0; dz < length; ++dz) {
          const double z0 = (key.z() + dz) * vr;
          if (!(z0 + vr < b0 || z0 > b1)) {
            mark[k] = 1;
            return;
          }
        }
      });
    });

  for (std::size_t k = 0; k < n; ++k) {
    if (marks.occupied[k] || marks.steep[k])
      grid.cells[k] = OccupancyGrid2D::OCCUPIED;
    else if (marks.seen_free[k])
      grid.cells[k] = OccupancyGrid2D::FREE;
  }
  return grid;
}

OccupancyGrid2D
PlanarGridMap::exportOccupancyGrid2D(const std::string& yaml_path,
                                     const OccupancyGrid2DParams& params) const
{
  // a name, not only the extension
  const auto named = [&](const std::string& suffix) {
    return yaml_path.size() > suffix.size() && endsWith(yaml_path, suffix);
  };
  if (!named(".yaml") && !named(".yml"))
    throw IOError(yaml_path
                  + ": a map_server map is named by its YAML file (\".yaml\" "
                    "or \".yml\")");
  const std::size_t slash = yaml_path.find_last_of('/');
  const std::string folder =
    slash == std::string::npos ? "." : yaml_path.substr(0, slash + 1);
  struct stat st {};
  if (::stat(folder.c_str(), &st) != 0 || !S_ISDIR(st.st_mode))
    throw IOError(yaml_path + ": the folder " + folder + " does not exist");
  const std::string stem = yaml_path.substr(0, yaml_path.find_last_of('.'));
  const std::string pgm_path = stem + ".pgm";
  const std::string pgm_name =
    slash == std::string::npos ? pgm_path : pgm_path.substr(slash + 1);

  const OccupancyGrid2D grid = computeOccupancyGrid2D(params);
  writeOccupancyGrid2DImage(grid, pgm_path);
  writeOccupancyGrid2DYaml(grid, yaml_path, pgm_name, params.occupied_thresh,
                           params.free_thresh);
  return grid;
}

void
writeOccupancyGrid2DImage(const OccupancyGrid2D& grid, const std::string& pgm_path)
{
  std::string pgm = "P5\n# PlanarGrid occupancy grid, "
                    + std::to_string(grid.resolution_m) + " m/pixel\n"
                    + std::to_string(grid.width) + " " + std::to_string(grid.height)
                    + "\n255\n";
  const std::size_t header = pgm.size();
  pgm.resize(header + grid.cells.size());
  // map_server reads the top image row as the largest y.
  for (int row = 0; row < grid.height; ++row)
    for (int col = 0; col < grid.width; ++col) {
      const std::int8_t v = grid.at(col, row);
      const auto px = static_cast<char>(
        static_cast<unsigned char>(v == OccupancyGrid2D::OCCUPIED ? 0
                                   : v == OccupancyGrid2D::FREE   ? 254
                                                                  : 205));
      pgm[header + static_cast<std::size_t>(grid.height - 1 - row) * grid.width + col] =
        px;
    }
  writeFileAtomically(pgm_path, [&](const std::string& tmp) {
    std::ofstream out(tmp, std::ios::binary);
    out.write(pgm.data(), static_cast<std::streamsize>(pgm.size()));
    out.close();
    return static_cast<bool>(out);
  });
}

void
writeOccupancyGrid2DYaml(const OccupancyGrid2D& grid,
                         const std::string& yaml_path,
                         const std::string& image_name,
                         double occupied_thresh,
                         double free_thresh)
{
  std::ostringstream yaml;
  yaml.precision(9);
  yaml << "image: " << image_name << "\n"
       << "mode: trinary\n"
       << "resolution: " << grid.resolution_m << "\n"
       << "origin: [" << grid.origin.x() << ", " << grid.origin.y() << ", 0.0]\n"
       << "negate: 0\n"
       << "occupied_thresh: " << occupied_thresh << "\n"
       << "free_thresh: " << free_thresh << "\n";
  writeTextFileAtomically(yaml_path, yaml.str());
}

} // namespace planar_grid
