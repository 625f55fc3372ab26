// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <random>

namespace planar_grid_test {

/** \brief Samples a room in its own z-up frame, metres: floor z = 0 over
 * [-3, 3] x [-2, 2], four walls 2.5 m high, a table (top 1.2 x 0.8 at z = 0.75,
 * centred at (1.5, 0.8)) and a pillar (0.4 x 0.4, centred at (-1.8, -1.2)), on a grid
 * of \a step_m with Gaussian noise of \a noise_m (fixed seed). The table and the pillar
 * break the room's symmetry, so a registration has one answer. */
inline pcl::PointCloud<pcl::PointXYZ>
syntheticRoom(float step_m = 0.04f, float noise_m = 0.003f, unsigned seed = 7)
{
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, noise_m);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  const auto add = [&](float x, float y, float z) {
    cloud.push_back(pcl::PointXYZ(x + noise(rng), y + noise(rng), z + noise(rng)));
  };
  for (float x = -3.0f; x <= 3.0f; x += step_m)
    for (float y = -2.0f; y <= 2.0f; y += step_m)
      add(x, y, 0.0f);
  for (float z = step_m; z <= 2.5f; z += step_m) {
    for (float x = -3.0f; x <= 3.0f; x += step_m) {
      add(x, -2.0f, z);
      add(x, 2.0f, z);
    }
    for (float y = -2.0f; y <= 2.0f; y += step_m) {
      add(-3.0f, y, z);
      add(3.0f, y, z);
    }
  }
  for (float x = 0.9f; x <= 2.1f; x += step_m)
    for (float y = 0.4f; y <= 1.2f; y += step_m)
      add(x, y, 0.75f);
  for (float z = step_m; z <= 2.5f; z += step_m)
    for (float t = -0.2f; t <= 0.2f; t += step_m) {
      add(-1.8f + t, -1.4f, z);
      add(-1.8f + t, -1.0f, z);
      add(-2.0f, -1.2f + t, z);
      add(-1.6f, -1.2f + t, z);
    }
  return cloud;
}

} // namespace planar_grid_test
