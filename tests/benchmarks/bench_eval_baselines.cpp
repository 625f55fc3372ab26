// SPDX-License-Identifier: BSD-3-Clause
// The baselines of Sec. IV-B on Karlsruhe frame 10: SG
// (StandardVoxelGrid::insertPointCloud) and OG (octomap::OcTree::insertPointCloud,
// discretize = false) on the same voxelised cloud in the same run, and the RA merge of
// the SG grid. Args: resolution in cm, and the input: 0 = the ground-free voxelised
// cloud of karlsruhe_scene.h (what PG maps), 1 = the voxelised cloud with the ground
// (pcl::VoxelGrid at 0.1 m of the finite SGBM points to 30 m). Sensor origin 0 (camera
// frame), no max range (the cloud is cut at 30 m).
#include <planar_grid/eval/rectangular_cuboid_approximation.h>
#include <planar_grid/eval/standard_voxel_grid.h>

#include <pcl/common/io.h>
#include <pcl/filters/voxel_grid.h>

#include <benchmark/benchmark.h>
#include <octomap/OcTree.h>

#include <chrono>
#include <cstddef>

#include "karlsruhe_scene.h"

namespace {

using planar_grid::AxisAlignedBoxes;
using planar_grid::RectangularCuboidApproximation;
using planar_grid::StandardVoxelGrid;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** \brief Input 0 (ground-free) or 1 (with ground) of frame 10, computed once; empty
 * when the data are missing. */
const Cloud&
frame10(int input)
{
  static Cloud clouds[2];
  static bool done = false;
  if (!done) {
    done = true;
    const auto& scene = planar_grid::bench::karlsruhe(10);
    if (scene.ok) {
      pcl::copyPointCloud(*scene.cloud, clouds[0]);
      pcl::PointCloud<pcl::PointXYZI> voxelised;
      pcl::VoxelGrid<pcl::PointXYZI> voxel_grid;
      voxel_grid.setInputCloud(scene.dense);
      voxel_grid.setLeafSize(0.1f, 0.1f, 0.1f);
      voxel_grid.filter(voxelised);
      pcl::copyPointCloud(voxelised, clouds[1]);
    }
  }
  return clouds[input];
}

StandardVoxelGrid::Params
params(const benchmark::State& state)
{
  StandardVoxelGrid::Params p;
  p.resolution_m = static_cast<double>(state.range(0)) / 100.0;
  return p;
}

octomap::Pointcloud
toOctoMap(const Cloud& cloud)
{
  octomap::Pointcloud scan;
  scan.reserve(cloud.size());
  for (const auto& p : cloud.points)
    scan.push_back(p.x, p.y, p.z);
  return scan;
}

/** \brief Occupied voxels of a tree (pruned leaves expanded). */
std::size_t
occupiedVoxels(const octomap::OcTree& tree)
{
  std::size_t n = 0;
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it)
    if (tree.isNodeOccupied(*it)) {
      const std::size_t e = std::size_t{1} << (tree.getTreeDepth() - it.getDepth());
      n += e * e * e;
    }
  return n;
}

void
BM_StandardVoxelGridInsert(benchmark::State& state)
{
  const Cloud& cloud = frame10(static_cast<int>(state.range(1)));
  if (cloud.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  std::size_t bytes = 0, voxels = 0, occupied = 0;
  for (auto _ : state) {
    StandardVoxelGrid grid(params(state));
    grid.insertPointCloud(cloud, Eigen::Vector3f::Zero());
    bytes = grid.getMemoryBytes();
    voxels = grid.getVoxelCount();
    benchmark::DoNotOptimize(voxels);
    state.PauseTiming();
    occupied = grid.getOccupiedCount();
    state.ResumeTiming();
  }
  state.counters["points"] = static_cast<double>(cloud.size());
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["voxels"] = static_cast<double>(voxels);
  state.counters["occupied"] = static_cast<double>(occupied);
}

void
BM_OctoMapInsertPointCloud(benchmark::State& state)
{
  const Cloud& cloud = frame10(static_cast<int>(state.range(1)));
  if (cloud.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  const octomap::Pointcloud scan = toOctoMap(cloud);
  std::size_t bytes = 0, leaves = 0, occupied = 0;
  for (auto _ : state) {
    octomap::OcTree tree(params(state).resolution_m);
    tree.insertPointCloud(scan, octomap::point3d(0, 0, 0), -1.0, false, false);
    bytes = tree.memoryUsage();
    leaves = tree.getNumLeafNodes();
    benchmark::DoNotOptimize(leaves);
    state.PauseTiming();
    occupied = occupiedVoxels(tree);
    state.ResumeTiming();
  }
  state.counters["points"] = static_cast<double>(cloud.size());
  state.counters["memory_bytes"] = static_cast<double>(bytes);
  state.counters["leaves"] = static_cast<double>(leaves);
  state.counters["occupied"] = static_cast<double>(occupied);
}

/** \brief SG and OctoMap timed back to back inside each iteration (the same load on
 * the shared machine for both); counters: mean ms of each and their ratio. */
void
BM_SGvsOctoMapSameIteration(benchmark::State& state)
{
  const Cloud& cloud = frame10(static_cast<int>(state.range(1)));
  if (cloud.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  const octomap::Pointcloud scan = toOctoMap(cloud);
  using Clock = std::chrono::steady_clock;
  double sg_s = 0.0, og_s = 0.0;
  for (auto _ : state) {
    const auto t0 = Clock::now();
    StandardVoxelGrid grid(params(state));
    grid.insertPointCloud(cloud, Eigen::Vector3f::Zero());
    benchmark::DoNotOptimize(grid.getVoxelCount());
    const auto t1 = Clock::now();
    octomap::OcTree tree(params(state).resolution_m);
    tree.insertPointCloud(scan, octomap::point3d(0, 0, 0), -1.0, false, false);
    benchmark::DoNotOptimize(tree.size());
    const auto t2 = Clock::now();
    sg_s += std::chrono::duration<double>(t1 - t0).count();
    og_s += std::chrono::duration<double>(t2 - t1).count();
  }
  const auto n = static_cast<double>(state.iterations());
  state.counters["sg_ms"] = 1e3 * sg_s / n;
  state.counters["octomap_ms"] = 1e3 * og_s / n;
  state.counters["octomap_over_sg"] = og_s / sg_s;
}

void
BM_RectangularCuboidApproximation(benchmark::State& state)
{
  const Cloud& cloud = frame10(static_cast<int>(state.range(1)));
  if (cloud.empty()) {
    state.SkipWithError("Karlsruhe frame 10 not found");
    return;
  }
  StandardVoxelGrid grid(params(state));
  grid.insertPointCloud(cloud, Eigen::Vector3f::Zero());
  AxisAlignedBoxes boxes;
  for (auto _ : state) {
    RectangularCuboidApproximation().compute(grid, boxes);
    benchmark::DoNotOptimize(boxes.data());
  }
  std::size_t occupied_boxes = 0;
  for (const auto& b : boxes)
    occupied_boxes += b.occupied ? 1 : 0;
  const auto voxels = static_cast<double>(grid.getVoxelCount());
  const auto occupied = static_cast<double>(grid.getOccupiedCount());
  state.counters["boxes"] = static_cast<double>(boxes.size());
  state.counters["occupied_boxes"] = static_cast<double>(occupied_boxes);
  state.counters["memory_bytes"] =
    static_cast<double>(RectangularCuboidApproximation::getMemoryBytes(boxes));
  // combination efficiency against SG (Fig. 12): 1 - boxes / voxels
  state.counters["eta_all"] = 1.0 - static_cast<double>(boxes.size()) / voxels;
  state.counters["eta_occupied"] = 1.0 - static_cast<double>(occupied_boxes) / occupied;
}

/** \brief Args: resolution (cm), input (0 = ground-free, 1 = with ground). OctoMap
 * takes seconds per insertion at 0.1 m: 3 iterations each. */
void
evalArgs(benchmark::internal::Benchmark* b)
{
  b->ArgNames({"res_cm", "ground"})
    ->Args({10, 0})
    ->Args({10, 1})
    ->Args({20, 1})
    ->Args({50, 1})
    ->Unit(benchmark::kMillisecond)
    ->Iterations(3);
}
BENCHMARK(BM_StandardVoxelGridInsert)->Apply(evalArgs);
BENCHMARK(BM_OctoMapInsertPointCloud)->Apply(evalArgs);
BENCHMARK(BM_SGvsOctoMapSameIteration)->Apply(evalArgs);
BENCHMARK(BM_RectangularCuboidApproximation)->Apply(evalArgs);

} // namespace

BENCHMARK_MAIN();
