// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: PipelineRunner::resumeFrom() on a checkpoint whose body is the
// fuzzer's input and whose CRC-32 the harness appends, so that the mutations reach the
// sections behind the checksum (the fingerprint, the report, the clouds, the planes,
// the embedded map, the stages' states). The pipeline is a PCD input of three tiny
// frames through voxel_grid, transform_to_world, multi_plane_segmentation,
// planar_cuboid_approximation, map_integration, accumulate (the seed is a checkpoint
// that pipeline wrote). The contract (pipeline_runner.h): the run resumes, or a
// planar_grid::Exception (IOError) naming the file; anything else is a finding.

#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/console/print.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <filesystem>
#include <fstream>
#include <memory>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

/** The pipeline the checkpoints belong to, with its three frames in a temporary
 * folder (removed at exit). */
struct Job {
  fs::path dir;
  planar_grid::PipelineConfig config;

  Job()
  {
    // One name for every process: a checkpoint records the paths of the files it
    // read, so the seeds only resume past those records where the paths are the same.
    // (One fuzzing process per target at a time.)
    dir = fs::temp_directory_path() / "planar_grid_fuzz_checkpoint";
    fs::create_directories(dir);
    std::ofstream poses(dir / "poses.txt");
    for (int f = 0; f < 3; ++f) {
      // A floor and a wall, 1 cm apart on a 20 x 20 grid.
      pcl::PointCloud<pcl::PointXYZ> cloud;
      for (int i = 0; i < 20; ++i)
        for (int j = 0; j < 20; ++j) {
          cloud.push_back(pcl::PointXYZ(0.05f * i, 0.05f * j, 0.0f));
          cloud.push_back(pcl::PointXYZ(0.05f * i, 1.0f, 0.05f * j));
        }
      pcl::io::savePCDFileBinary((dir / ("f" + std::to_string(f) + ".pcd")).string(),
                                 cloud);
      poses << "1 0 0 " << 0.1 * f << " 0 1 0 0 0 0 1 0\n";
    }
    poses.close();
    config = planar_grid::parsePipelineConfig(
      "input:\n  type: pcd_files\n  files: " + (dir / "f*.pcd").string()
        + "\n  poses: {format: kitti, file: " + (dir / "poses.txt").string()
        + "}\npipeline:\n  - type: voxel_grid\n    params: {leaf_size_m: 0.05}\n"
          "  - type: transform_to_world\n  - type: multi_plane_segmentation\n"
          "    params: {min_inliers: 50}\n  - type: planar_cuboid_approximation\n"
          "  - type: map_integration\n  - type: accumulate\n",
      "fuzz.yaml", "/");
  }
  ~Job()
  {
    std::error_code ec;
    fs::remove_all(dir, ec);
  }
};

} // namespace

// PCL's reader reports every malformed header line on the console: silenced, so that
// the fuzzer's time goes to the inputs.
extern "C" int
LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/)
{
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  static const Job job;
  const std::string path = (job.dir / "checkpoint.pgck").string();
  // PLANAR_GRID_FUZZ_WRITE_SEED=<file>: write the body of a real checkpoint (frames 0
  // and 1 of the job) there, for the seed corpus, and stop.
  if (const char* seed = std::getenv("PLANAR_GRID_FUZZ_WRITE_SEED")) {
    planar_grid::PipelineRunner runner(job.config);
    runner.setFrameRange(0, 2);
    runner.setCheckpoint(path, 2);
    runner.run();
    std::ifstream in(path, std::ios::binary);
    std::string bytes((std::istreambuf_iterator<char>(in)),
                      std::istreambuf_iterator<char>());
    std::ofstream(seed, std::ios::binary)
      .write(bytes.data(), static_cast<std::streamsize>(bytes.size() - 4));
    std::exit(0);
  }
  std::vector<std::uint8_t> bytes(data, data + size);
  const std::uint32_t crc = planar_grid::crc32(bytes.data(), bytes.size());
  for (int b = 0; b < 4; ++b)
    bytes.push_back(static_cast<std::uint8_t>(crc >> (8 * b)));
  std::ofstream(path, std::ios::binary | std::ios::trunc)
    .write(reinterpret_cast<const char*>(bytes.data()),
           static_cast<std::streamsize>(bytes.size()));
  try {
    planar_grid::PipelineRunner runner(job.config);
    runner.setFrameRange(0, 3);
    runner.resumeFrom(path);
    (void)runner.run();
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
