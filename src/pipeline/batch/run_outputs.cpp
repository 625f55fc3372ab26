// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/run_outputs.h>

#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/io/ply_io.h>

#include <sys/stat.h>

#include <filesystem>
#include <utility>

namespace planar_grid {

std::string
outputPath(const OutputConfig& output, const std::string& name)
{
  return (std::filesystem::path(output.folder) / name).string();
}

namespace {
namespace fs = std::filesystem;

/** \a path made absolute with every symbolic link of its existing part resolved, so
 * that two spellings of one file compare equal. */
fs::path
resolvedPath(const std::string& path)
{
  std::error_code ec;
  fs::path resolved = fs::weakly_canonical(path, ec);
  if (ec)
    resolved = fs::absolute(path, ec).lexically_normal();
  return resolved;
}
} // namespace

void
checkOutputPaths(const OutputConfig& output,
                 const std::vector<InputFile>& inputs,
                 bool with_checkpoint)
{
  std::vector<std::pair<std::string, std::string>> names{
    {"cloud", output.cloud},
    {"planes", output.planes},
    {"report", output.report},
    {"trajectory", output.trajectory},
    {"snapshot", output.snapshot},
    {"planes_snapshot", output.planes_snapshot},
    {"cuboids_snapshot", output.cuboids_snapshot},
    {"cuboids_street_snapshot", output.cuboids_street_snapshot},
    {"map", output.map},
    {"map_octomap", output.map_octomap},
    {"map_mesh", output.map_mesh},
    {"map_grid_2d", output.map_grid_2d},
    {"map_snapshot", output.map_snapshot}};
  // The 2D grid's image is written beside its YAML file, under the same name.
  if (output.map_grid_2d.size() > 5)
    names.emplace_back("map_grid_2d",
                       output.map_grid_2d.substr(0, output.map_grid_2d.size() - 5)
                         + ".pgm");
  if (with_checkpoint)
    names.emplace_back("checkpoint", output.checkpoint);

  // Each input once: its canonical path and, when it exists, its device and inode
  // (a hard link has another path).
  struct Input {
    fs::path resolved;
    bool exists;
    struct stat status;
    const InputFile* file;
  };
  std::vector<Input> resolved_inputs;
  resolved_inputs.reserve(inputs.size());
  for (const auto& file : inputs) {
    Input in{resolvedPath(file.path), false, {}, &file};
    in.exists = ::stat(file.path.c_str(), &in.status) == 0;
    resolved_inputs.push_back(in);
  }

  // Each output's own file: two keys naming one file would leave only the last one
  // written.
  std::vector<std::pair<fs::path, std::string>> taken;
  for (const auto& [key, name] : names) {
    if (name.empty())
      continue;
    const std::string path = outputPath(output, name);
    const fs::path resolved = resolvedPath(path);
    for (const auto& [other_path, other_key] : taken)
      if (other_path == resolved)
        throw OutputError(path + ": output." + key + " '" + name
                          + "' is the file of output." + other_key
                          + " too, and one would replace the other: give "
                            "each output its own name");
    taken.emplace_back(resolved, key);
    struct stat status {};
    const bool exists = ::stat(path.c_str(), &status) == 0;
    for (const auto& in : resolved_inputs) {
      const bool same_file = exists && in.exists && in.status.st_dev == status.st_dev
                             && in.status.st_ino == status.st_ino;
      if (in.resolved == resolved || same_file)
        throw OutputError(path + ": output." + key + " '" + name + "' would overwrite "
                          + in.file->what + ", " + in.file->path
                          + ", which this run reads: choose another output name or "
                            "output folder");
    }
    std::error_code ec;
    if (fs::is_directory(fs::symlink_status(path, ec)))
      throw OutputError(path + ": output." + key + " '" + name
                        + "' names an existing folder, and a file cannot replace a "
                          "folder: remove or rename the folder, or choose another "
                          "output name");
  }
}

namespace {
void
createFolder(const std::string& folder)
{
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec || !std::filesystem::is_directory(folder))
    throw OutputError(folder + ": cannot create the output folder: " + ec.message());
}

/** Writes the output \a name with a function given the path to write; returns the
 * path to report. */
using OutputWriter =
  std::function<std::string(const std::string& name,
                            const std::function<void(const std::string&)>& write)>;

/** A cloud as a binary PLY when \a path ends in .ply (pcl::PLYWriter), else as a
 * binary-compressed PCD (pcl::PCDWriter); the configuration allows only these two. */
template <typename PointT>
void
writeCloudFile(const std::string& path, const pcl::PointCloud<PointT>& cloud)
{
  const bool ply = endsWith(path, ".ply");
  writeFileAtomically(path, [&cloud, ply](const std::string& tmp) {
    if (ply)
      return pcl::PLYWriter().write(tmp, cloud, true, false) == 0;
    return pcl::PCDWriter().writeBinaryCompressed(tmp, cloud) == 0;
  });
}

void
writeOutputs(const OutputConfig& output,
             const PipelineRunner& runner,
             RunReport& report,
             const OutputWriter& write)
{
  if (!output.cloud.empty()) {
    const auto& cloud = runner.state().world_cloud;
    if (cloud && !cloud->empty())
      report.outputs.emplace_back(
        "cloud", write(output.cloud, [&cloud](const std::string& path) {
          writeCloudFile(path, *cloud);
        }));
  }
  if (!output.planes.empty()) {
    const auto& planes = runner.state().planes;
    if (planes && !planes->getInlierCloud().empty())
      report.outputs.emplace_back(
        "planes", write(output.planes, [&planes](const std::string& path) {
          writeCloudFile(path, planes->getInlierCloud());
        }));
  }
  if (const auto& map = runner.state().map) {
    if (!output.map.empty())
      report.outputs.emplace_back(
        "map", write(output.map, [&map](const std::string& path) { map->save(path); }));
    if (!output.map_octomap.empty()) {
      OctoMapExportSummary written;
      report.outputs.emplace_back(
        "map_octomap",
        write(output.map_octomap, [&map, &written](const std::string& path) {
          written = map->exportOctoMap(path);
        }));
      report.map_octomap_summary = {
        {"nodes", static_cast<double>(written.nodes)},
        {"leaf_nodes", static_cast<double>(written.leaf_nodes)},
        {"occupied_leaves", static_cast<double>(written.occupied_leaves)},
        {"free_leaves", static_cast<double>(written.free_leaves)},
        {"occupied_voxels", static_cast<double>(written.occupied_voxels)},
        {"free_voxels", static_cast<double>(written.free_voxels)},
        {"skipped_voxels", static_cast<double>(written.skipped_voxels)},
      };
    }
    ExplicitSpaceGrid::VoxelKey lo, hi;
    const bool no_extent = !output.map_grid_2d_band.use_bounds
                           && map->getSurfaceLayer().getCuboidCount() == 0
                           && !map->getSpaceLayer().getBounds(lo, hi);
    if (!output.map_grid_2d.empty() && no_extent)
      PCL_WARN("[planar_grid::writeRunOutputs] %s is not written: the map is empty (no "
               "cuboid, no observed space), so the grid has no extent. The other "
               "outputs are written.\n",
               output.map_grid_2d.c_str());
    else if (!output.map_grid_2d.empty()) {
      // Two files, each its own output of the set: the image, then the YAML naming it.
      const OccupancyGrid2D grid = map->computeOccupancyGrid2D(output.map_grid_2d_band);
      const std::string& yaml = output.map_grid_2d;
      const std::string image = yaml.substr(0, yaml.size() - 5) + ".pgm";
      const std::string image_name = std::filesystem::path(image).filename().string();
      report.outputs.emplace_back("map_grid_2d_image",
                                  write(image, [&grid](const std::string& path) {
                                    writeOccupancyGrid2DImage(grid, path);
                                  }));
      report.outputs.emplace_back(
        "map_grid_2d", write(yaml, [&](const std::string& path) {
          writeOccupancyGrid2DYaml(grid, path, image_name,
                                   output.map_grid_2d_band.occupied_thresh,
                                   output.map_grid_2d_band.free_thresh);
        }));
    }
    if (!output.map_mesh.empty()) {
      // A map without cuboids is a valid result (nothing was seen often or densely
      // enough), but a mesh needs a vertex: PCL's PLY writer refuses an empty one.
      if (map->getSurfaceLayer().getCuboidCount() == 0)
        PCL_WARN("[planar_grid::writeRunOutputs] %s is not written: the map is empty "
                 "(no cuboid), and a mesh needs at least one. The map file and the "
                 "other outputs are written.\n",
                 output.map_mesh.c_str());
      else
        report.outputs.emplace_back(
          "map_mesh", write(output.map_mesh, [&map](const std::string& path) {
            map->exportMesh(path);
          }));
    }
  }
  if (!output.trajectory.empty() && !runner.trajectory().empty())
    report.outputs.emplace_back(
      "trajectory", write(output.trajectory, [&runner](const std::string& path) {
        saveKittiPoses(path, runner.trajectory());
      }));
}
} // namespace

void
writeRunOutputs(const OutputConfig& output,
                const PipelineRunner& runner,
                RunReport& report)
{
  createFolder(output.folder);
  writeOutputs(output, runner, report,
               [&output](const std::string& name,
                         const std::function<void(const std::string&)>& write) {
                 const std::string path = outputPath(output, name);
                 write(path);
                 return path;
               });
}

void
writeRunOutputs(const OutputConfig& output,
                const PipelineRunner& runner,
                RunReport& report,
                OutputTransaction& transaction)
{
  writeOutputs(output, runner, report,
               [&transaction](const std::string& name,
                              const std::function<void(const std::string&)>& write) {
                 return transaction.write(name, write);
               });
}

void
writeRunReport(const OutputConfig& output, RunReport& report)
{
  createFolder(output.folder);
  const std::string path = outputPath(output, output.report);
  report.outputs.emplace_back("report", path);
  writeTextFileAtomically(path, report.toJson());
}

void
writeRunReport(const OutputConfig& output,
               RunReport& report,
               OutputTransaction& transaction)
{
  report.outputs.emplace_back("report", transaction.finalPath(output.report));
  const std::string json = report.toJson();
  transaction.write(output.report, [&json](const std::string& path) {
    writeTextFileAtomically(path, json);
  });
}

} // namespace planar_grid
