// SPDX-License-Identifier: BSD-3-Clause
// Loads a map written by the pipeline (map.pgmap) with planar_grid::PlanarGridMap and
// asks it, at each query point, for the distance to the nearest obstacle and whether a
// sphere about the point touches none (world frame, meters).
//   query_map map.pgmap [--radius R] [--max-distance D] x y z [x y z ...]
//   query_map map.pgmap [--radius R] [--max-distance D] --line x0 y0 z0 x1 y1 z1 n
// --line spreads n points evenly from (x0 y0 z0) to (x1 y1 z1). R is the sphere's
// radius (default 0.5 m), D the distance cap (default 10 m).
#include <planar_grid/map/planar_grid_map.h>

#include <Eigen/Core>

#include <cstdint>
#include <cstdlib>
#include <iomanip>
#include <iostream>
#include <string>
#include <vector>

int
main(int argc, char** argv)
{
  if (argc < 3) {
    std::cerr
      << "usage: " << argv[0]
      << " map.pgmap [--radius R] [--max-distance D] x y z [x y z ...]\n"
      << "       " << argv[0]
      << " map.pgmap [--radius R] [--max-distance D] --line x0 y0 z0 x1 y1 z1 n\n";
    return EXIT_FAILURE;
  }
  try {
    float radius_m = 0.5f;        // the sphere of the collision check, meters
    double max_distance_m = 10.0; // distances beyond it are printed as the cap
    bool line = false;
    std::vector<float> numbers;
    for (int i = 2; i < argc; ++i) {
      const std::string arg = argv[i];
      if (arg == "--radius" && i + 1 < argc)
        radius_m = std::stof(argv[++i]);
      else if (arg == "--max-distance" && i + 1 < argc)
        max_distance_m = std::stod(argv[++i]);
      else if (arg == "--line")
        line = true;
      else
        numbers.push_back(std::stof(arg));
    }

    Eigen::Matrix3Xf points; // 3 x N, world frame, meters
    if (line) {
      if (numbers.size() != 7 || numbers[6] < 2) {
        std::cerr << "query_map: --line takes x0 y0 z0 x1 y1 z1 n (n >= 2)\n";
        return EXIT_FAILURE;
      }
      const Eigen::Vector3f from(numbers[0], numbers[1], numbers[2]);
      const Eigen::Vector3f to(numbers[3], numbers[4], numbers[5]);
      const int n = static_cast<int>(numbers[6]);
      points.resize(3, n);
      for (int i = 0; i < n; ++i)
        points.col(i) = from + (to - from) * (static_cast<float>(i) / (n - 1));
    } else {
      if (numbers.empty() || numbers.size() % 3 != 0) {
        std::cerr << "query_map: give the points as x y z triples\n";
        return EXIT_FAILURE;
      }
      points =
        Eigen::Map<const Eigen::Matrix3Xf>(numbers.data(), 3, numbers.size() / 3);
    }

    const auto map = planar_grid::PlanarGridMap::load(argv[1]);
    std::cout << argv[1] << ": " << map.getSurfaceLayer().getCuboidCount()
              << " cuboids, resolution " << map.getResolution() << " m\n";

    // Distances and gradients for the whole batch; unknown space is not an obstacle
    // (pass unknown_is_occupied = true to count it).
    Eigen::VectorXf distances(points.cols());
    Eigen::Matrix3Xf gradients(3, points.cols());
    map.getDistance(points, max_distance_m, distances, gradients);

    planar_grid::CollisionBodies spheres;
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      spheres.push_back(planar_grid::CollisionBody::sphere(points.col(i), radius_m));
    const std::vector<std::uint8_t> free = map.isCollisionFree(spheres);

    std::cout << "       x        y        z  distance_m  state     sphere_free (r = "
              << radius_m << " m)\n"
              << std::fixed;
    for (Eigen::Index i = 0; i < points.cols(); ++i) {
      const Eigen::Vector3f p = points.col(i);
      std::cout << std::setprecision(2) << std::setw(8) << p.x() << ' ' << std::setw(8)
                << p.y() << ' ' << std::setw(8) << p.z() << ' ' << std::setw(11)
                << distances(i) << "  " << std::left << std::setw(8)
                << planar_grid::toString(map.getState(p)) << "  "
                << (free[i] ? "yes" : "no") << std::right << '\n';
    }
  } catch (const std::exception& e) {
    std::cerr << "query_map: " << e.what() << "\n";
    return EXIT_FAILURE;
  }
  return EXIT_SUCCESS;
}
