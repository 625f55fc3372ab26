// SPDX-License-Identifier: BSD-3-Clause
// The memory a run needs, bounded before its first frame, and the machine's limit.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/map_stage_params.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/param_table.h>

#include <sys/resource.h>
#include <unistd.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <utility>
#include <vector>

namespace planar_grid {

namespace {

constexpr double SQRT3 = 1.7320508075688772;

/** Blocks of edge \a block_m meeting a body, at most: the volume within a block
 * diagonal of it over a block's volume (each such block lies wholly inside that
 * dilation, and blocks do not overlap). */
std::uint64_t
blocksIn(double dilated_volume_m3, double block_m)
{
  const double n = std::ceil(dilated_volume_m3 / (block_m * block_m * block_m));
  return n >= 1.8e19 ? std::numeric_limits<std::uint64_t>::max()
                     : static_cast<std::uint64_t>(n);
}

double
ballVolume(double radius_m)
{
  return 4.0 / 3.0 * M_PI * radius_m * radius_m * radius_m;
}

std::uint64_t
saturatingMul(std::uint64_t a, std::uint64_t b)
{
  if (a != 0 && b > std::numeric_limits<std::uint64_t>::max() / a)
    return std::numeric_limits<std::uint64_t>::max();
  return a * b;
}

std::uint64_t
saturatingAdd(std::uint64_t a, std::uint64_t b)
{
  return a > std::numeric_limits<std::uint64_t>::max() - b
           ? std::numeric_limits<std::uint64_t>::max()
           : a + b;
}

/** One view's region in the world: a pinhole frustum (depth 0 to range) or a ball of
 * the range around the sensor. */
struct ViewRegion {
  bool pinhole{false};
  PinholeView camera;
  double range_m{0.0};

  /** Inward unit normals of the frustum's side planes (through the camera centre), in
   * the camera frame, as the integration's rejection test uses them. */
  std::array<Eigen::Vector3d, 4> sideNormals() const
  {
    const double u_end = camera.width_px - 0.5, v_end = camera.height_px - 0.5;
    return {Eigen::Vector3d(camera.fx_px, 0.0, camera.cx_px + 0.5).normalized(),
            Eigen::Vector3d(-camera.fx_px, 0.0, u_end - camera.cx_px).normalized(),
            Eigen::Vector3d(0.0, camera.fy_px, camera.cy_px + 0.5).normalized(),
            Eigen::Vector3d(0.0, -camera.fy_px, v_end - camera.cy_px).normalized()};
  }

  /** The world box holding the view from \a pose. */
  void
  bounds(const Eigen::Isometry3d& pose, Eigen::Vector3d& lo, Eigen::Vector3d& hi) const
  {
    lo = hi = pose.translation();
    if (!pinhole) {
      lo.array() -= range_m;
      hi.array() += range_m;
      return;
    }
    for (const double u : {-0.5, camera.width_px - 0.5})
      for (const double v : {-0.5, camera.height_px - 0.5}) {
        const Eigen::Vector3d p =
          pose
          * Eigen::Vector3d((u - camera.cx_px) / camera.fx_px * range_m,
                            (v - camera.cy_px) / camera.fy_px * range_m, range_m);
        lo = lo.cwiseMin(p);
        hi = hi.cwiseMax(p);
      }
  }
};

/** Cells of edge \a cell_m (a power-of-two multiple of the block, aligned with the
 * blocks) meeting the union of the views from \a poses: a cell is kept unless its
 * circumscribed sphere lies wholly outside one face of a view, so every cell holding a
 * block a view touches is kept. Returns false when the cells' indices would not fit. */
bool
unionCells(const ViewRegion& view,
           const Trajectory& poses,
           double cell_m,
           std::vector<std::uint64_t>& cells,
           int& z_min,
           int& z_max)
{
  constexpr int BITS = 21;
  constexpr long long HALF = 1LL << (BITS - 1);
  const double rho = cell_m * SQRT3 / 2.0;
  const auto normals = view.sideNormals();
  cells.clear();
  z_min = std::numeric_limits<int>::max();
  z_max = std::numeric_limits<int>::min();
  for (const auto& pose : poses) {
    Eigen::Vector3d lo, hi;
    view.bounds(pose, lo, hi);
    const Eigen::Matrix3d r_cw = pose.linear().transpose();
    const Eigen::Vector3d t = pose.translation();
    std::array<long long, 3> a{}, b{};
    for (int k = 0; k < 3; ++k) {
      a[static_cast<std::size_t>(k)] =
        static_cast<long long>(std::floor(lo[k] / cell_m));
      b[static_cast<std::size_t>(k)] =
        static_cast<long long>(std::floor(hi[k] / cell_m));
      if (a[static_cast<std::size_t>(k)] < -HALF
          || b[static_cast<std::size_t>(k)] >= HALF)
        return false;
    }
    for (long long z = a[2]; z <= b[2]; ++z)
      for (long long y = a[1]; y <= b[1]; ++y)
        for (long long x = a[0]; x <= b[0]; ++x) {
          const Eigen::Vector3d centre((static_cast<double>(x) + 0.5) * cell_m,
                                       (static_cast<double>(y) + 0.5) * cell_m,
                                       (static_cast<double>(z) + 0.5) * cell_m);
          bool inside = true;
          if (view.pinhole) {
            const Eigen::Vector3d p = r_cw * (centre - t);
            inside = p.z() >= -rho && p.z() <= view.range_m + rho;
            for (const auto& n : normals)
              inside = inside && n.dot(p) >= -rho;
          } else {
            inside = (centre - t).norm() <= view.range_m + rho;
          }
          if (!inside)
            continue;
          cells.push_back(static_cast<std::uint64_t>(x + HALF)
                          | (static_cast<std::uint64_t>(y + HALF) << BITS)
                          | (static_cast<std::uint64_t>(z + HALF) << (2 * BITS)));
          z_min = std::min(z_min, static_cast<int>(z));
          z_max = std::max(z_max, static_cast<int>(z));
        }
    // Keeps the list at the union's size rather than the sum of the views'.
    if (cells.size() > (std::size_t{1} << 22)) {
      std::sort(cells.begin(), cells.end());
      cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
    }
  }
  std::sort(cells.begin(), cells.end());
  cells.erase(std::unique(cells.begin(), cells.end()), cells.end());
  return true;
}

/** Distinct cells of the next coarser levels: \a shift halvings of each index. */
std::uint64_t
coarserCells(std::vector<std::uint64_t> cells, int shift)
{
  constexpr int BITS = 21;
  constexpr std::uint64_t MASK = (std::uint64_t{1} << BITS) - 1;
  for (auto& c : cells)
    c = ((c & MASK) >> shift) | ((((c >> BITS) & MASK) >> shift) << BITS)
        | ((((c >> (2 * BITS)) & MASK) >> shift) << (2 * BITS));
  std::sort(cells.begin(), cells.end());
  return static_cast<std::uint64_t>(std::unique(cells.begin(), cells.end())
                                    - cells.begin());
}

} // namespace

double
pinholeFrustumVolume(const PinholeView& view, double max_range_m, double margin_m)
{
  // The pyramid |x| within [-a1 z, a2 z], y within [-c1 z, c2 z], z in [0, R]; each
  // face moved out by d: z in [-d, R + d], widths (a1 + a2) z + d (sqrt(1 + a1^2) +
  // sqrt(1 + a2^2)) and likewise in y. The volume is the integral over z of the two
  // widths' product (both linear and positive on the interval).
  const double a1 = (view.cx_px + 0.5) / view.fx_px;
  const double a2 = (view.width_px - 0.5 - view.cx_px) / view.fx_px;
  const double c1 = (view.cy_px + 0.5) / view.fy_px;
  const double c2 = (view.height_px - 0.5 - view.cy_px) / view.fy_px;
  const double d = margin_m;
  const double p = a1 + a2, q = d * (std::sqrt(1 + a1 * a1) + std::sqrt(1 + a2 * a2));
  const double s = c1 + c2, t = d * (std::sqrt(1 + c1 * c1) + std::sqrt(1 + c2 * c2));
  // integral of (p z + q)(s z + t) = p s z^3 / 3 + (p t + q s) z^2 / 2 + q t z
  const auto primitive = [&](double z) {
    return p * s * z * z * z / 3.0 + (p * t + q * s) * z * z / 2.0 + q * t * z;
  };
  return primitive(max_range_m + d) - primitive(-d);
}

std::string
MemoryEstimate::summary() const
{
  std::ostringstream text;
  text << formatBytes(total_bytes);
  if (!has_map) {
    text << " (no map_integration stage: the fixed allowance for the process)";
    return text.str();
  }
  text << " = map " << formatBytes(map_bytes) << " (at most " << map_blocks
       << " blocks of 8^3 voxels of " << resolution_m << " m, bounded by the "
       << map_bound << ") + one view's working memory " << formatBytes(working_bytes)
       << " (" << view_blocks << " blocks, " << sensor << " to max_range_m "
       << max_range_m << " m) + " << formatBytes(other_bytes)
       << " for the rest of the process";
  return text.str();
}

namespace {

/** \brief Lowers \a estimate's bound of the map's blocks (map_bound, map_blocks,
 * map_super_blocks), set to every frame's view, to the union of the views at the
 * known \a poses (the frames' cells, rasterised), or to the rolling window's box of
 * half-size \a window (m, 0: none), where either is smaller. */
void
boundByPoses(const ViewRegion& view,
             const Trajectory& poses,
             std::size_t frames,
             double block_m,
             double window,
             MemoryEstimate& estimate)
{
  if (poses.empty())
    return;
  // Cells of 2^k blocks, k chosen so that the frames' boxes hold at most about 4
  // million cells to test.
  double box_volume = 0.0;
  for (const auto& pose : poses) {
    Eigen::Vector3d lo, hi;
    view.bounds(pose, lo, hi);
    box_volume += (hi - lo).array().abs().prod();
  }
  int k = 0;
  while (k < 20 && box_volume / std::pow(block_m * std::ldexp(1.0, k), 3.0) > 4.0e6)
    ++k;
  const double cell_m = block_m * std::ldexp(1.0, k);
  std::vector<std::uint64_t> union_cells;
  int z_min = 0, z_max = 0;
  if (unionCells(view, poses, cell_m, union_cells, z_min, z_max)
      && !union_cells.empty()) {
    const std::uint64_t blocks_per_cell = std::uint64_t{1} << (3 * k);
    const std::uint64_t blocks = saturatingMul(union_cells.size(), blocks_per_cell);
    const std::uint64_t supers =
      k >= 3 ? saturatingMul(union_cells.size(), std::uint64_t{1} << (3 * (k - 3)))
             : coarserCells(union_cells, 3 - k);
    if (blocks < estimate.map_blocks) {
      estimate.map_bound = "swept path of the " + std::to_string(frames) + " poses";
      estimate.map_blocks = blocks;
      estimate.map_super_blocks = std::min(supers, blocks);
    }
    if (window > 0.0) {
      // The window keeps a box of 2 window_radius_m in x and y, every height the
      // views reach.
      const auto across =
        static_cast<std::uint64_t>(std::ceil(2.0 * window / cell_m)) + 1;
      const auto high = static_cast<std::uint64_t>(z_max - z_min + 1);
      const std::uint64_t window_cells = saturatingMul(across * across, high);
      const std::uint64_t window_blocks = saturatingMul(window_cells, blocks_per_cell);
      if (window_blocks < estimate.map_blocks) {
        estimate.map_bound = "window (window_radius_m " + std::to_string(window) + ")";
        estimate.map_blocks = window_blocks;
        estimate.map_super_blocks = std::min(
          window_blocks,
          k >= 3 ? saturatingMul(window_cells, std::uint64_t{1} << (3 * (k - 3)))
                 : window_cells);
      }
    }
  }
}

} // namespace

MemoryEstimate
estimateRunMemory(const PipelineConfig& config,
                  const PinholeView* camera,
                  const Trajectory& poses,
                  std::size_t frames)
{
  MemoryEstimate estimate;
  estimate.frames = frames;
  estimate.file = config.source_file;
  const StageConfig* map = nullptr;
  const StageConfig* cells = nullptr;
  for (const auto& stage : config.stages) {
    if (stage.type == "map_integration")
      map = &stage;
    if (stage.type == "planar_cuboid_approximation")
      cells = &stage;
  }
  if (map == nullptr)
    return estimate;
  estimate.has_map = true;
  // The map's and the stage's parameters as the stage reads them.
  PlanarGridMap::Params map_params;
  assignParams(PlanarGridMap::getParamDeclarations(), map->params, map_params);
  stages::MapStageParams stage_params;
  assignParams(stages::mapStageParamDeclarations(), map->params, stage_params);
  estimate.resolution_m = map_params.resolution_m;
  estimate.max_range_m = map_params.space.max_range_m;
  // The key that set the cell size: the file's cell_size_m, else the map's own, else
  // the cells' it took.
  const auto mark = [&](const StageConfig& stage, const std::string& key) {
    const auto it = stage.param_marks.find(key);
    if (it == stage.param_marks.end())
      return false;
    estimate.key = stage.type + "." + key;
    estimate.line = it->second.first;
    estimate.column = it->second.second;
    return true;
  };
  if (config.cell_size_m > 0.0) {
    estimate.key = "cell_size_m";
    estimate.line = config.cell_size_line;
    estimate.column = config.cell_size_column;
  } else if (!mark(*map, "resolution_m")
             && !(cells && mark(*cells, "min_cell_size_m"))) {
    estimate.key = "map_integration.resolution_m";
    estimate.line = map->line;
    estimate.column = map->column;
  }

  const double r = estimate.resolution_m;
  const double block_m = r * ExplicitSpaceGrid::BLOCK_EDGE_VOXELS;
  const double super_m = block_m * 8.0;
  const double range = estimate.max_range_m;
  // The view's model, as map_integration chooses it.
  const stages::SensorModel model = stage_params.sensor_model;
  const bool stereo = config.input.type == InputConfig::Type::STEREO_SEQUENCE;
  ViewRegion view;
  view.range_m = range;
  if (model == stages::SensorModel::PINHOLE && !stereo) {
    view.pinhole = true;
    view.camera.width_px = stage_params.depth_width_px;
    view.camera.height_px = stage_params.depth_height_px;
    view.camera.fx_px = view.camera.fy_px = stage_params.depth_focal_length_px;
    view.camera.cx_px = 0.5 * view.camera.width_px;
    view.camera.cy_px = 0.5 * view.camera.height_px;
  } else if (model != stages::SensorModel::RAYS && stereo && camera != nullptr
             && camera->width_px > 0 && camera->height_px > 0 && camera->fx_px > 0.0
             && camera->fy_px > 0.0) {
    view.pinhole = true;
    view.camera = *camera;
  }
  std::uint64_t pixels = 0;
  double view_volume = 0.0, view_super_volume = 0.0;
  if (view.pinhole) {
    pixels = static_cast<std::uint64_t>(view.camera.width_px)
             * static_cast<std::uint64_t>(view.camera.height_px);
    view_volume = pinholeFrustumVolume(view.camera, range, block_m * SQRT3);
    view_super_volume = pinholeFrustumVolume(view.camera, range, super_m * SQRT3);
    std::ostringstream text;
    text << "pinhole " << view.camera.width_px << "x" << view.camera.height_px
         << " px, f " << view.camera.fx_px << " px,";
    estimate.sensor = text.str();
  } else {
    // Rays reach max_range_m in any direction; a camera whose image size is not known
    // before the first frame sees less than that ball's half.
    view_volume = ballVolume(range + block_m * SQRT3);
    view_super_volume = ballVolume(range + super_m * SQRT3);
    estimate.sensor = "the ball of max_range_m";
  }
  estimate.view_blocks = blocksIn(view_volume, block_m);
  estimate.working_bytes =
    ExplicitSpaceGrid::workingBytesBound(estimate.view_blocks, pixels);

  // The map: every frame's view, or the union of the views where the poses are known
  // (the frames' cells, rasterised), or the rolling window's box.
  estimate.map_bound = "frames";
  estimate.map_blocks = saturatingMul(estimate.view_blocks, frames);
  estimate.map_super_blocks = std::min(
    estimate.map_blocks, saturatingMul(blocksIn(view_super_volume, super_m), frames));
  boundByPoses(view, poses, frames, block_m, stage_params.window_radius_m, estimate);
  // Beyond 2^50 blocks the bytes would overflow: far beyond any limit anyway.
  estimate.map_bytes = estimate.map_blocks >= (std::uint64_t{1} << 50)
                         ? std::numeric_limits<std::uint64_t>::max()
                         : ExplicitSpaceGrid::storageBytesBound(
                           estimate.map_blocks, estimate.map_super_blocks);
  if (estimate.view_blocks >= (std::uint64_t{1} << 50))
    estimate.working_bytes = std::numeric_limits<std::uint64_t>::max();
  estimate.total_bytes = saturatingAdd(
    saturatingAdd(estimate.map_bytes, estimate.working_bytes), estimate.other_bytes);
  return estimate;
}

MemoryLimit
machineMemoryLimit()
{
  // Physical memory: MemTotal, not MemAvailable. What is available changes from one
  // second to the next (page cache, other jobs) and would make the same run pass or
  // fail by chance; a run larger than the machine's memory fails in any case.
  std::uint64_t physical = 0;
  std::ifstream meminfo("/proc/meminfo");
  std::string name;
  std::uint64_t kib = 0;
  while (meminfo >> name >> kib) {
    if (name == "MemTotal:") {
      physical = kib * 1024;
      break;
    }
    meminfo.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  }
  if (physical == 0) {
    const long pages = ::sysconf(_SC_PHYS_PAGES);
    const long page = ::sysconf(_SC_PAGESIZE);
    if (pages > 0 && page > 0)
      physical = static_cast<std::uint64_t>(pages) * static_cast<std::uint64_t>(page);
  }
  const auto soft_limit = [](int resource) -> std::uint64_t {
    rlimit rl{};
    if (::getrlimit(resource, &rl) != 0 || rl.rlim_cur == RLIM_INFINITY)
      return 0;
    return static_cast<std::uint64_t>(rl.rlim_cur);
  };
  return smallestMemoryLimit(physical, soft_limit(RLIMIT_AS), soft_limit(RLIMIT_DATA));
}

MemoryLimit
smallestMemoryLimit(std::uint64_t physical_bytes,
                    std::uint64_t address_space_bytes,
                    std::uint64_t data_bytes)
{
  MemoryLimit limit;
  for (const auto& [bytes, what] :
       {std::pair<std::uint64_t, const char*>{physical_bytes,
                                              "the machine's memory (MemTotal of "
                                              "/proc/meminfo)"},
        std::pair<std::uint64_t, const char*>{address_space_bytes,
                                              "the address space limit (RLIMIT_AS, "
                                              "ulimit -v)"},
        std::pair<std::uint64_t, const char*>{data_bytes,
                                              "the data segment limit (RLIMIT_DATA, "
                                              "ulimit -d)"}}) {
    if (bytes > 0 && (limit.bytes == 0 || bytes < limit.bytes)) {
      limit.bytes = bytes;
      limit.source = what;
    }
  }
  return limit;
}

std::uint64_t
parseMemorySize(const std::string& text)
{
  if (text == "none")
    return 0;
  std::istringstream in(text);
  double value = -1.0;
  if (!(in >> value) || !(value >= 0.0))
    throw Exception(
      "memory size '" + text
      + "' must be a non-negative number of bytes with an optional K, M, G "
        "or T suffix (powers of 1024), or 0 / none for no limit");
  std::string suffix;
  in >> suffix;
  char extra = 0;
  double scale = 1.0;
  if (suffix == "K" || suffix == "k")
    scale = 1024.0;
  else if (suffix == "M" || suffix == "m")
    scale = 1024.0 * 1024.0;
  else if (suffix == "G" || suffix == "g")
    scale = 1024.0 * 1024.0 * 1024.0;
  else if (suffix == "T" || suffix == "t")
    scale = 1024.0 * 1024.0 * 1024.0 * 1024.0;
  else if (!suffix.empty() || (in >> extra))
    throw Exception(
      "memory size '" + text
      + "': unknown suffix; use bytes or K, M, G, T (powers of 1024), or 0 "
        "/ none for no limit");
  const double bytes = value * scale;
  if (bytes >= 1.8e19)
    throw Exception("memory size '" + text + "' is too large");
  return static_cast<std::uint64_t>(bytes);
}

std::string
formatBytes(std::uint64_t bytes)
{
  if (bytes == std::numeric_limits<std::uint64_t>::max())
    return "more than 16 EiB";
  const char* units[] = {"B", "KiB", "MiB", "GiB", "TiB", "PiB", "EiB"};
  double value = static_cast<double>(bytes);
  int u = 0;
  while (value >= 1024.0 && u < 6) {
    value /= 1024.0;
    ++u;
  }
  std::ostringstream text;
  text.precision(value < 10.0 && u > 0 ? 3 : 4);
  text << value << " " << units[u];
  return text.str();
}

void
checkMemoryEstimate(const MemoryEstimate& estimate, const MemoryLimit& limit)
{
  if (limit.bytes == 0 || estimate.total_bytes <= limit.bytes)
    return;
  std::ostringstream text;
  text << "the run needs up to " << formatBytes(estimate.total_bytes)
       << " of memory, more than the limit of " << formatBytes(limit.bytes) << " ("
       << limit.source
       << "); refused before the first frame. Estimate: " << estimate.summary();
  if (!estimate.has_map) {
    text << ". Change the limit with --memory-limit SIZE (0 or none: no check)";
    throw ConfigError(estimate.file, 0, 0, text.str());
  }
  text << ". The map's memory grows as (1 / " << estimate.key << ")^3: raise "
       << estimate.key << " (now " << estimate.resolution_m
       << " m), lower map_integration.max_range_m, run fewer frames (--frames), set "
          "map_integration.window_radius_m, or change the limit with --memory-limit "
          "SIZE (0 or none: no check)";
  throw ConfigError(estimate.file, estimate.line, estimate.column, text.str());
}

} // namespace planar_grid
