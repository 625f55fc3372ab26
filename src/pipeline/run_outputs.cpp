// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/run_outputs.h>

#include <pcl/io/pcd_io.h>

#include <filesystem>

namespace planar_grid {

std::string
outputPath(const OutputConfig& output, const std::string& name)
{
  return (std::filesystem::path(output.folder) / name).string();
}

namespace {
void
createFolder(const std::string& folder)
{
  std::error_code ec;
  std::filesystem::create_directories(folder, ec);
  if (ec || !std::filesystem::is_directory(folder))
    throw IOError(folder + ": cannot create the output folder: " + ec.message());
}
} // namespace

void
writeRunOutputs(const OutputConfig& output,
                const PipelineRunner& runner,
                RunReport& report)
{
  createFolder(output.folder);
  if (!output.cloud.empty()) {
    const std::string path = outputPath(output, output.cloud);
    const auto& cloud = runner.state().world_cloud;
    if (cloud && !cloud->empty()) {
      writeFileAtomically(path, [&cloud](const std::string& tmp) {
        pcl::PCDWriter writer;
        return writer.writeBinaryCompressed(tmp, *cloud) == 0;
      });
      report.outputs.emplace_back("cloud", path);
    }
  }
  if (!output.planes.empty()) {
    const auto& planes = runner.state().plane_cloud;
    if (planes && !planes->empty()) {
      const std::string path = outputPath(output, output.planes);
      writeFileAtomically(path, [&planes](const std::string& tmp) {
        pcl::PCDWriter writer;
        return writer.writeBinaryCompressed(tmp, *planes) == 0;
      });
      report.outputs.emplace_back("planes", path);
    }
  }
  if (const auto& map = runner.state().map) {
    if (!output.map.empty()) {
      const std::string path = outputPath(output, output.map);
      map->save(path);
      report.outputs.emplace_back("map", path);
    }
    if (!output.map_octomap.empty()) {
      const std::string path = outputPath(output, output.map_octomap);
      map->exportOctoMap(path);
      report.outputs.emplace_back("map_octomap", path);
    }
    if (!output.map_mesh.empty()) {
      const std::string path = outputPath(output, output.map_mesh);
      map->exportMesh(path);
      report.outputs.emplace_back("map_mesh", path);
    }
  }
  if (!output.trajectory.empty() && !runner.trajectory().empty()) {
    const std::string path = outputPath(output, output.trajectory);
    saveKittiPoses(path, runner.trajectory());
    report.outputs.emplace_back("trajectory", path);
  }
}

void
writeRunReport(const OutputConfig& output, RunReport& report)
{
  createFolder(output.folder);
  const std::string path = outputPath(output, output.report);
  report.outputs.emplace_back("report", path);
  writeTextFileAtomically(path, report.toJson());
}

} // namespace planar_grid
