// SPDX-License-Identifier: BSD-3-Clause
// The planner's queries of PlanarGridMap on the main job's map (config/karlsruhe.yaml,
// its map.pgmap and map.bt), with the voxel peers in the same run:
// - point state queries: PlanarGridMap::getState vs octomap::OcTree::search on the .bt;
// - distance: building what is needed plus 100,000 queries in a 30 x 30 x 6 m region
//   around a pose of the trajectory, PlanarGridMap::getDistance (obstacle hierarchy
//   over the whole map) vs DynamicEDTOctomap (OctoMap's EDT, over the region of the
//   .bt), with the two distance fields compared;
// - collision: 100,000 robot boxes (1.0 x 0.6 x 1.5 m) at random poses on the street.
// The map folder is PLANAR_GRID_MAP_DIR (default: output/karlsruhe of the source tree),
// holding map.pgmap, map.bt and trajectory.txt of a main job run.
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>

#include <benchmark/benchmark.h>
#include <dynamicEDT3D/dynamicEDTOctomap.h>
#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace {

using planar_grid::CollisionBodies;
using planar_grid::CollisionBody;
using planar_grid::PlanarGridMap;

constexpr std::size_t QUERIES = 100000;
constexpr double MAX_DISTANCE_M = 5.0;
constexpr float CAMERA_HEIGHT_M = 1.57f; // config/karlsruhe.yaml: ground at z 0 below

struct Scene {
  std::unique_ptr<PlanarGridMap> map;
  std::unique_ptr<octomap::OcTree> tree;
  std::vector<Eigen::Vector3f> poses; // camera positions of the trajectory
  Eigen::Vector3f centre;             // the pose the region is around
  Eigen::Vector3f region_lo, region_hi;
  Eigen::Matrix3Xf points; // QUERIES points in the region
  CollisionBodies robots;  // QUERIES robot boxes on the street
  bool ok{false};
};

std::string
mapDir()
{
  const char* dir = std::getenv("PLANAR_GRID_MAP_DIR");
  return dir != nullptr ? dir
                        : std::string(PLANAR_GRID_SOURCE_DIR) + "/output/karlsruhe";
}

const Scene&
scene()
{
  static const Scene s = [] {
    Scene out;
    const std::string dir = mapDir();
    std::ifstream traj(dir + "/trajectory.txt");
    std::string line;
    while (std::getline(traj, line)) {
      std::istringstream row(line);
      double m[12];
      for (double& v : m)
        row >> v;
      // trajectory.txt is in KITTI's convention (the optical frame: x right, y down,
      // z forward); the map's world is z up, x forward, y left.
      if (row)
        out.poses.emplace_back(static_cast<float>(m[11]), static_cast<float>(-m[3]),
                               static_cast<float>(-m[7]));
    }
    try {
      out.map =
        std::make_unique<PlanarGridMap>(PlanarGridMap::load(dir + "/map.pgmap"));
    } catch (const std::exception& e) {
      std::fprintf(stderr, "bench_map_queries: %s\n", e.what());
      return out;
    }
    out.tree = std::make_unique<octomap::OcTree>(out.map->getResolution());
    if (!out.tree->readBinary(dir + "/map.bt") || out.poses.empty()) {
      std::fprintf(stderr, "bench_map_queries: %s/map.bt or trajectory.txt missing\n",
                   dir.c_str());
      return out;
    }
    // The region: 30 x 30 m around the middle pose, from 2 m below the camera to 4 m
    // above it (the road to above the cars and the lower floors).
    out.centre = out.poses[out.poses.size() / 2];
    out.region_lo = out.centre - Eigen::Vector3f(15.0f, 15.0f, 2.0f);
    out.region_hi = out.centre + Eigen::Vector3f(15.0f, 15.0f, 4.0f);
    std::mt19937 rng(42);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    out.points.resize(3, static_cast<Eigen::Index>(QUERIES));
    for (Eigen::Index i = 0; i < out.points.cols(); ++i)
      for (int k = 0; k < 3; ++k)
        out.points(k, i) =
          out.region_lo[k] + u(rng) * (out.region_hi[k] - out.region_lo[k]);
    // Robot boxes on the street: near a pose of the trajectory (up to 4 m across and
    // along it), any yaw, the body 0.2 m above the road under the camera (a ground
    // clearance: the road's own voxels reach up to 0.1 m and more with stereo noise).
    std::uniform_int_distribution<std::size_t> pick(0, out.poses.size() - 1);
    std::uniform_real_distribution<float> offset(-4.0f, 4.0f), yaw(-3.14159f, 3.14159f);
    out.robots.reserve(QUERIES);
    for (std::size_t i = 0; i < QUERIES; ++i) {
      const Eigen::Vector3f p = out.poses[pick(rng)];
      const Eigen::Vector3f c(p.x() + offset(rng), p.y() + offset(rng),
                              p.z() - CAMERA_HEIGHT_M + 0.75f + 0.2f);
      out.robots.push_back(CollisionBody::box(
        c, Eigen::Vector3f(0.5f, 0.3f, 0.75f),
        Eigen::AngleAxisf(yaw(rng), Eigen::Vector3f::UnitZ()).toRotationMatrix()));
    }
    out.ok = true;
    return out;
  }();
  return s;
}

#define REQUIRE_SCENE(s)                                             \
  if (!(s).ok) {                                                     \
    state.SkipWithError(("no main job map in " + mapDir()).c_str()); \
    return;                                                          \
  }

void
BM_StateQueries_PlanarGrid(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  std::size_t occupied = 0;
  for (auto _ : state) {
    occupied = 0;
    for (Eigen::Index i = 0; i < s.points.cols(); ++i)
      occupied +=
        s.map->getState(s.points.col(i)) == planar_grid::SpaceState::OCCUPIED ? 1 : 0;
    benchmark::DoNotOptimize(occupied);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  state.counters["occupied"] = static_cast<double>(occupied);
}
BENCHMARK(BM_StateQueries_PlanarGrid)->Unit(benchmark::kMillisecond);

void
BM_StateQueries_OctoMapSearch(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  std::size_t occupied = 0;
  for (auto _ : state) {
    occupied = 0;
    for (Eigen::Index i = 0; i < s.points.cols(); ++i) {
      const octomap::OcTreeNode* node =
        s.tree->search(s.points(0, i), s.points(1, i), s.points(2, i));
      occupied += node != nullptr && s.tree->isNodeOccupied(node) ? 1 : 0;
    }
    benchmark::DoNotOptimize(occupied);
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  state.counters["occupied"] = static_cast<double>(occupied);
}
BENCHMARK(BM_StateQueries_OctoMapSearch)->Unit(benchmark::kMillisecond);

/** Builds the obstacle hierarchy (the map's query index is dropped first) and answers
 * the 100,000 distance queries. */
void
BM_Distance_PlanarGrid_BuildAndQuery(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  PlanarGridMap& map = *s.map;
  Eigen::VectorXf d(s.points.cols());
  Eigen::Matrix3Xf g(3, s.points.cols());
  for (auto _ : state) {
    map.invalidateQueryCache();
    map.getDistance(s.points, MAX_DISTANCE_M, d, g);
    benchmark::DoNotOptimize(d.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  state.counters["mean_distance_m"] = static_cast<double>(d.mean());
}
BENCHMARK(BM_Distance_PlanarGrid_BuildAndQuery)->Unit(benchmark::kMillisecond);

/** MapRegionIndex over the region (the obstacles within the cap of it, as a distance
 * transform over its bounding box), built and queried. */
void
BM_Distance_PlanarGridRegion_BuildAndQuery(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  Eigen::VectorXf d(s.points.cols());
  Eigen::Matrix3Xf g(3, s.points.cols());
  std::size_t obstacles = 0;
  for (auto _ : state) {
    const planar_grid::MapRegionIndex index(*s.map, s.region_lo, s.region_hi,
                                            MAX_DISTANCE_M);
    index.getDistance(s.points, d, g);
    obstacles = index.getObstacleCount();
    benchmark::DoNotOptimize(d.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  state.counters["obstacles"] = static_cast<double>(obstacles);
  // the same distances as the whole map's index
  Eigen::VectorXf whole(s.points.cols());
  s.map->getDistance(s.points, MAX_DISTANCE_M, whole, g);
  state.counters["max_diff_to_whole_map_m"] =
    static_cast<double>((whole - d).cwiseAbs().maxCoeff());
}
BENCHMARK(BM_Distance_PlanarGridRegion_BuildAndQuery)->Unit(benchmark::kMillisecond);

/** The queries alone, on the built hierarchy. */
void
BM_Distance_PlanarGrid_QueryOnly(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  Eigen::VectorXf d(s.points.cols());
  Eigen::Matrix3Xf g(3, s.points.cols());
  s.map->getDistance(s.points, MAX_DISTANCE_M, d, g);
  for (auto _ : state) {
    s.map->getDistance(s.points, MAX_DISTANCE_M, d, g);
    benchmark::DoNotOptimize(d.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
}
BENCHMARK(BM_Distance_PlanarGrid_QueryOnly)->Unit(benchmark::kMillisecond);

/** DynamicEDTOctomap over the region of the .bt (unknown as free, as the planar
 * query's default), built and queried at the same points. */
void
BM_Distance_DynamicEDT3D_BuildAndQuery(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  const octomap::point3d lo(s.region_lo.x(), s.region_lo.y(), s.region_lo.z());
  const octomap::point3d hi(s.region_hi.x(), s.region_hi.y(), s.region_hi.z());
  std::vector<float> edt(QUERIES);
  for (auto _ : state) {
    DynamicEDTOctomap field(static_cast<float>(MAX_DISTANCE_M), s.tree.get(), lo, hi,
                            false);
    field.update();
    for (Eigen::Index i = 0; i < s.points.cols(); ++i)
      edt[static_cast<std::size_t>(i)] = field.getDistance(
        octomap::point3d(s.points(0, i), s.points(1, i), s.points(2, i)));
    benchmark::DoNotOptimize(edt.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  // The two fields compared: DynamicEDT3D measures between voxel centres (a voxel's
  // distance to itself is 0), the planar map to the obstacles' surfaces, so the EDT
  // reads about half a voxel to one voxel more.
  Eigen::VectorXf d(s.points.cols());
  Eigen::Matrix3Xf g(3, s.points.cols());
  s.map->getDistance(s.points, MAX_DISTANCE_M, d, g);
  std::vector<double> diff;
  double sum = 0.0;
  std::size_t within_voxel = 0, compared = 0;
  for (std::size_t i = 0; i < QUERIES; ++i) {
    const float e = edt[i];
    if (!(e >= 0.0f) || e >= MAX_DISTANCE_M
        || d[static_cast<Eigen::Index>(i)] >= MAX_DISTANCE_M)
      continue;
    const double delta = e - d[static_cast<Eigen::Index>(i)];
    diff.push_back(std::abs(delta));
    sum += delta;
    ++compared;
    within_voxel += std::abs(delta) <= 0.1 * std::sqrt(3.0) ? 1 : 0;
  }
  std::sort(diff.begin(), diff.end());
  state.counters["compared"] = static_cast<double>(compared);
  if (compared > 0) {
    state.counters["mean_edt_minus_planar_m"] = sum / static_cast<double>(compared);
    state.counters["median_abs_diff_m"] = diff[diff.size() / 2];
    state.counters["p95_abs_diff_m"] = diff[diff.size() * 95 / 100];
    state.counters["share_within_voxel_diag"] =
      static_cast<double>(within_voxel) / static_cast<double>(compared);
  }
}
BENCHMARK(BM_Distance_DynamicEDT3D_BuildAndQuery)->Unit(benchmark::kMillisecond);

/** 100,000 robot boxes on the street, on the built hierarchy. */
void
BM_Collision_RobotBoxes(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  std::vector<std::uint8_t> free = s.map->isCollisionFree(s.robots);
  for (auto _ : state) {
    free = s.map->isCollisionFree(s.robots);
    benchmark::DoNotOptimize(free.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(QUERIES));
  state.counters["free_share"] =
    static_cast<double>(std::count(free.begin(), free.end(), 1)) / QUERIES;
}
BENCHMARK(BM_Collision_RobotBoxes)->Unit(benchmark::kMillisecond);

// ---- the brute-force oracle on the main job's map ----------------------------------

struct OracleBox {
  Eigen::Matrix3d axes;
  Eigen::Vector3d centre, half;
};

/** Every obstacle box (occupied cuboids, occupied voxels) whose bounding box meets
 * [lo, hi]. */
std::vector<OracleBox>
oracleBoxes(const PlanarGridMap& map,
            const Eigen::Vector3d& lo,
            const Eigen::Vector3d& hi)
{
  std::vector<OracleBox> out;
  const auto keep = [&](const OracleBox& b) {
    const Eigen::Vector3d reach = b.axes.cwiseAbs() * b.half;
    if (((b.centre - reach).array() <= hi.array()).all()
        && ((b.centre + reach).array() >= lo.array()).all())
      out.push_back(b);
  };
  const float thres =
    static_cast<float>(map.getSurfaceLayer().getParams().occupancy_thres);
  for (const auto& c : map.getSurfaceLayer().getCuboids())
    if (c.probability >= thres) {
      OracleBox b;
      b.axes.col(0) = c.horizontal_axis.cast<double>();
      b.axes.col(1) = c.verticalAxis().cast<double>();
      b.axes.col(2) = c.normal.cast<double>();
      b.centre = c.centre.cast<double>();
      b.half = 0.5 * Eigen::Vector3d(c.width_m, c.height_m, c.thickness_m);
      keep(b);
    }
  const double r = map.getResolution();
  map.getSpaceLayer().forEachVoxel(
    [&](const Eigen::Vector3i& k, planar_grid::SpaceState st) {
      if (st != planar_grid::SpaceState::OCCUPIED)
        return;
      OracleBox b;
      b.axes.setIdentity();
      b.centre = (k.cast<double>() + Eigen::Vector3d::Constant(0.5)) * r;
      b.half.setConstant(0.5 * r);
      keep(b);
    });
  return out;
}

/** Largest gap over the 15 separating axes by the corners' projections (> 0 apart). */
double
oracleGap(const CollisionBody& body, const OracleBox& b)
{
  const Eigen::Matrix3d ra = body.rotation.cast<double>();
  std::vector<Eigen::Vector3d> axes;
  for (int i = 0; i < 3; ++i) {
    axes.push_back(ra.col(i));
    axes.push_back(b.axes.col(i));
    for (int j = 0; j < 3; ++j) {
      const Eigen::Vector3d c = ra.col(i).cross(b.axes.col(j));
      if (c.norm() > 1e-9)
        axes.push_back(c.normalized());
    }
  }
  double gap = -1e30;
  for (const auto& axis : axes) {
    const double ca = axis.dot(body.centre.cast<double>()), cb = axis.dot(b.centre);
    const double ha =
      (ra.transpose() * axis).cwiseAbs().dot(body.half_extents.cast<double>());
    const double hb = (b.axes.transpose() * axis).cwiseAbs().dot(b.half);
    gap = std::max(gap, std::abs(ca - cb) - ha - hb);
  }
  return gap;
}

/** The queries against the brute force over every obstacle near the region: 2,000
 * points of the distance region and the 2,000 robot boxes nearest the middle pose. */
void
BM_OracleCheck(benchmark::State& state)
{
  const Scene& s = scene();
  REQUIRE_SCENE(s)
  const Eigen::Vector3d margin = Eigen::Vector3d::Constant(MAX_DISTANCE_M + 2.0);
  const auto boxes = oracleBoxes(*s.map, s.region_lo.cast<double>() - margin,
                                 s.region_hi.cast<double>() + margin);
  const Eigen::Index n = 2000;
  Eigen::VectorXf d(n);
  Eigen::Matrix3Xf g(3, n);
  const Eigen::Matrix3Xf points = s.points.leftCols(n);
  s.map->getDistance(points, MAX_DISTANCE_M, d, g);
  double worst = 0.0;
  for (Eigen::Index i = 0; i < n; ++i) {
    const Eigen::Vector3d p = points.col(i).cast<double>();
    double best = MAX_DISTANCE_M;
    for (const auto& b : boxes) {
      const Eigen::Vector3d q = b.axes.transpose() * (p - b.centre);
      best = std::min(best, (q - q.cwiseMax(-b.half).cwiseMin(b.half)).norm());
    }
    worst = std::max(worst, std::abs(best - d[i]));
  }
  CollisionBodies robots;
  for (const auto& r : s.robots)
    if ((r.centre - s.centre).head<2>().norm() < 10.0f && robots.size() < 2000)
      robots.push_back(r);
  const auto free = s.map->isCollisionFree(robots);
  std::size_t mismatches = 0, borderline = 0, collisions = 0;
  for (std::size_t i = 0; i < robots.size(); ++i) {
    double margin_m = 1e30;
    const Eigen::Vector3d reach = robots[i].rotation.cast<double>().cwiseAbs()
                                  * robots[i].half_extents.cast<double>();
    for (const auto& b : boxes) {
      const Eigen::Vector3d b_reach = b.axes.cwiseAbs() * b.half;
      if (((robots[i].centre.cast<double>() - b.centre).cwiseAbs() - reach - b_reach)
            .maxCoeff()
          > 1e-3)
        continue;
      margin_m = std::min(margin_m, oracleGap(robots[i], b));
    }
    collisions += margin_m > 0.0 ? 0 : 1;
    if (std::abs(margin_m) < 1e-4)
      ++borderline;
    else if ((margin_m > 0.0) != (free[i] != 0))
      ++mismatches;
  }
  for (auto _ : state)
    benchmark::DoNotOptimize(worst);
  state.counters["obstacles"] = static_cast<double>(boxes.size());
  state.counters["distance_max_error_m"] = worst;
  state.counters["robots"] = static_cast<double>(robots.size());
  state.counters["robot_collisions"] = static_cast<double>(collisions);
  state.counters["collision_mismatches"] = static_cast<double>(mismatches);
  state.counters["collision_borderline"] = static_cast<double>(borderline);
}
BENCHMARK(BM_OracleCheck)->Iterations(1)->Unit(benchmark::kMillisecond);

} // namespace

BENCHMARK_MAIN();
