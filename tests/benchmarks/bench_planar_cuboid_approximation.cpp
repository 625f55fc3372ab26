// SPDX-License-Identifier: BSD-3-Clause
// PlanarCuboidApproximation (paper Sec. III-F, Figs. 6-8) on Karlsruhe frames (SGBM
// cloud, max range 30 m, 0.1 m VoxelGrid, SACMultiPlaneSegmentation, ground planes
// removed) and on office1.pcd (0.05 m VoxelGrid). Arg 0: the min cell size in cm
// (10-50). Counters: cuboids, voxels = occupied cells of pcl::VoxelGrid at the same
// size on the same (ground-free) points, eta = 1 - cuboids / voxels (combination
// efficiency), planar = planar cuboids, points.
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/common/io.h>
#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <benchmark/benchmark.h>
#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <map>
#include <string>

#include "karlsruhe_scene.h"

namespace {

using planar_grid::bench::Cloud;
using planar_grid::bench::karlsruhe;
using planar_grid::bench::Scene;

const Scene&
office()
{
  static const Scene scene = [] {
    Scene out;
    pcl::PointCloud<pcl::PointXYZRGB> raw;
    if (pcl::io::loadPCDFile(
          std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/office1.pcd", raw)
        != 0)
      return out;
    Cloud xyz;
    pcl::copyPointCloud(raw, xyz);
    planar_grid::bench::voxeliseAndSegment(xyz, 0.05f, out);
    return out;
  }();
  return scene;
}

void
run(benchmark::State& state, const Scene& scene)
{
  if (!scene.ok) {
    state.SkipWithError("data not found");
    return;
  }
  const double cell_m = 0.01 * static_cast<double>(state.range(0));
  Cloud voxels;
  pcl::VoxelGrid<pcl::PointXYZI> voxel_grid;
  voxel_grid.setInputCloud(scene.cloud);
  const auto leaf = static_cast<float>(cell_m);
  voxel_grid.setLeafSize(leaf, leaf, leaf);
  voxel_grid.filter(voxels);

  planar_grid::PlanarCuboidApproximation<pcl::PointXYZI> approx;
  // A non-planar box stops at D_T (the class's 0.25 is the pipeline's).
  approx.setNonPlanarDensityThreshold(0.0);
  approx.setInputCloud(scene.cloud);
  approx.setPlanes(scene.planes);
  approx.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
  approx.setMinCellSize(cell_m);
  approx.setMinWidth(cell_m);
  approx.setMinHeight(cell_m);
  approx.setThickness(cell_m);
  planar_grid::PlanarCuboids cuboids;
  for (auto _ : state) {
    approx.approximate(cuboids);
    benchmark::DoNotOptimize(cuboids.data());
  }
  std::size_t planar = 0;
  for (const auto& c : cuboids)
    planar += c.is_planar ? 1 : 0;
  state.counters["points"] = static_cast<double>(scene.cloud->size());
  state.counters["planes"] = static_cast<double>(scene.planes.size());
  state.counters["cuboids"] = static_cast<double>(cuboids.size());
  state.counters["planar"] = static_cast<double>(planar);
  state.counters["voxels"] = static_cast<double>(voxels.size());
  state.counters["eta"] =
    1.0 - static_cast<double>(cuboids.size()) / static_cast<double>(voxels.size());
}

void
BM_PlanarCuboidApproximationKarlsruhe10(benchmark::State& state)
{
  run(state, karlsruhe(10));
}

void
BM_PlanarCuboidApproximationKarlsruhe60(benchmark::State& state)
{
  run(state, karlsruhe(60));
}

void
BM_PlanarCuboidApproximationOffice1(benchmark::State& state)
{
  run(state, office());
}

} // namespace

BENCHMARK(BM_PlanarCuboidApproximationKarlsruhe10)
  ->DenseRange(10, 50, 10)
  ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PlanarCuboidApproximationKarlsruhe60)
  ->DenseRange(10, 50, 10)
  ->Unit(benchmark::kMillisecond);
BENCHMARK(BM_PlanarCuboidApproximationOffice1)
  ->DenseRange(10, 50, 10)
  ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
