// SPDX-License-Identifier: BSD-3-Clause
// Maps a stereo sequence frame by frame with planar_grid::Mapper, as a live camera
// would feed it; the configuration's own input reader stands in for the camera.
//   map_live config/karlsruhe.yaml 10 live.pgmap
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <algorithm>
#include <cstdlib>
#include <iostream>
#include <string>

int
main(int argc, char** argv)
{
  if (argc != 4) {
    std::cerr << "usage: " << argv[0] << " config.yaml frame_count map.pgmap\n";
    return EXIT_FAILURE;
  }
  try {
    const auto config = planar_grid::loadPipelineConfig(argv[1]);
    const auto camera = planar_grid::createFrameSource(config.input);
    planar_grid::Mapper mapper(planar_grid::toMapperConfig(config));
    const std::size_t n = std::min<std::size_t>(std::stoul(argv[2]), camera->size());
    for (std::size_t i = 0; i < n; ++i) {
      planar_grid::Frame frame;
      camera->load(i, frame); // images (CV_8UC1), calibration, INS pose
      const planar_grid::FrameStats stats = mapper.integrateStereo(
        frame.left, frame.right, frame.calibration, frame.world_T_camera);
      std::cout << "frame " << i << ": " << stats.total_ms << " ms, " << stats.cuboids
                << " cells, map " << stats.map_cells << " cells\n";
    }
    mapper.save(argv[3]);
  } catch (const std::exception& e) {
    std::cerr << "map_live: " << e.what() << "\n";
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
