// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>

#include <pcl/console/print.h>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <map>
#include <new>
#include <random>
#include <set>
#include <tuple>
#include <vector>

namespace {

/** \brief Bytes and allocations live through the global operator new of this test
 * executable (replaced below), to check the grid's memory accounting. */
struct HeapUse {
  std::size_t bytes{0};
  std::size_t blocks{0};
};

std::atomic<std::size_t>&
liveBytes()
{
  static std::atomic<std::size_t> n{0};
  return n;
}

std::atomic<std::size_t>&
liveBlocks()
{
  static std::atomic<std::size_t> n{0};
  return n;
}

HeapUse
heapUse()
{
  return {liveBytes().load(), liveBlocks().load()};
}

/** \brief Header before each allocation: its requested size (16 bytes keep the
 * default new alignment). */
constexpr std::size_t HOOK_HEADER = 16;

void*
hookedAllocate(std::size_t n)
{
  auto* p = static_cast<unsigned char*>(std::malloc(n + HOOK_HEADER));
  if (p == nullptr)
    throw std::bad_alloc();
  std::memcpy(p, &n, sizeof(n));
  liveBytes() += n;
  ++liveBlocks();
  return p + HOOK_HEADER;
}

void
hookedFree(void* q) noexcept
{
  if (q == nullptr)
    return;
  auto* p = static_cast<unsigned char*>(q) - HOOK_HEADER;
  std::size_t n = 0;
  std::memcpy(&n, p, sizeof(n));
  liveBytes() -= n;
  --liveBlocks();
  std::free(p);
}

} // namespace

void*
operator new(std::size_t n)
{
  return hookedAllocate(n);
}
void*
operator new[](std::size_t n)
{
  return hookedAllocate(n);
}
void*
operator new(std::size_t n, const std::nothrow_t&) noexcept
{
  try {
    return hookedAllocate(n);
  } catch (...) {
    return nullptr;
  }
}
void*
operator new[](std::size_t n, const std::nothrow_t&) noexcept
{
  try {
    return hookedAllocate(n);
  } catch (...) {
    return nullptr;
  }
}
void
operator delete(void* p) noexcept
{
  hookedFree(p);
}
void
operator delete[](void* p) noexcept
{
  hookedFree(p);
}
void
operator delete(void* p, std::size_t) noexcept
{
  hookedFree(p);
}
void
operator delete[](void* p, std::size_t) noexcept
{
  hookedFree(p);
}
void
operator delete(void* p, const std::nothrow_t&) noexcept
{
  hookedFree(p);
}
void
operator delete[](void* p, const std::nothrow_t&) noexcept
{
  hookedFree(p);
}

namespace planar_grid {
/** \brief Test access to the thread count of integrateDepthImage() (a friend). */
struct ExplicitSpaceGridThreads {
  static void set(ExplicitSpaceGrid& grid, int n) { grid.num_threads_ = n; }
};
} // namespace planar_grid

namespace {

using planar_grid::DepthImage;
using planar_grid::ExplicitSpaceGrid;
using planar_grid::SpaceState;
using Key = ExplicitSpaceGrid::VoxelKey;

/** \brief std::map key for voxel keys. */
std::tuple<int, int, int>
tup(const Key& k)
{
  return {k.x(), k.y(), k.z()};
}

ExplicitSpaceGrid::Params
params(SpaceState prior, double resolution_m = 0.1, double max_range_m = 25.0)
{
  ExplicitSpaceGrid::Params p;
  p.resolution_m = resolution_m;
  p.max_range_m = max_range_m;
  p.prior = prior;
  return p;
}

/** \brief Random voxels in [-range, range)^3 with random states; the oracle map holds
 * the last state set per voxel. */
void
fillRandom(ExplicitSpaceGrid& grid,
           std::map<std::tuple<int, int, int>, SpaceState>& oracle,
           int n,
           int range,
           unsigned seed)
{
  std::mt19937 rng(seed);
  std::uniform_int_distribution<int> coord(-range, range - 1);
  std::uniform_int_distribution<int> state(0, 2);
  for (int i = 0; i < n; ++i) {
    const Key k(coord(rng), coord(rng), coord(rng));
    const auto s = static_cast<SpaceState>(state(rng));
    grid.setState(k, s);
    oracle[tup(k)] = s;
  }
}

/** \brief Analytic depth image of a box room seen from its inside (camera frame: x
 * right, y down, z forward): walls x = +-4, floor y = 2, ceiling y = -2, front wall z =
 * 8 (open behind the camera), and an occluder box x, y in [-0.6, 0.6], z in [3, 4]. */
DepthImage
renderBoxRoom()
{
  DepthImage image;
  image.width = 160;
  image.height = 120;
  image.fx = image.fy = 100.0f;
  image.cx = 79.5f;
  image.cy = 59.5f;
  image.depth_m.resize(160 * 120);
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u) {
      const double xn = (u - image.cx) / image.fx, yn = (v - image.cy) / image.fy;
      double z = 8.0; // front wall
      if (xn != 0.0)
        z = std::min(z, 4.0 / std::abs(xn));
      if (yn != 0.0)
        z = std::min(z, 2.0 / std::abs(yn));
      // occluder front face at z = 3 (its sides are hidden behind it from the centre)
      if (std::abs(xn * 3.0) <= 0.6 && std::abs(yn * 3.0) <= 0.6)
        z = std::min(z, 3.0);
      image.depth_m[static_cast<std::size_t>(v * image.width + u)] =
        static_cast<float>(z);
    }
  return image;
}

/** \brief renderBoxRoom() with holes and outliers from the generator seeded with \a
 * seed: each pixel is NaN with probability 0.2, otherwise scaled by a factor in [0.5,
 * 1.5) with probability 0.1. */
DepthImage
renderBoxRoomWithHoles(unsigned seed)
{
  DepthImage holes = renderBoxRoom();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (auto& d : holes.depth_m)
    if (unit(rng) < 0.2f)
      d = std::numeric_limits<float>::quiet_NaN();
    else if (unit(rng) < 0.1f)
      d *= 0.5f + unit(rng);
  return holes;
}

/** \brief The pose used for the room: a general rotation and translation. */
Eigen::Isometry3d
roomPose()
{
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.3, Eigen::Vector3d(0.2, 1.0, 0.1).normalized())
                 .toRotationMatrix();
  T.translation() = Eigen::Vector3d(1.3, -0.4, 2.1);
  return T;
}

/** \brief Depth of the room along the ray through camera point \a pc. */
double
roomDepthAlong(const DepthImage& image, const Eigen::Vector3d& pc)
{
  const int u =
    static_cast<int>(std::floor(image.fx * pc.x() / pc.z() + image.cx + 0.5));
  const int v =
    static_cast<int>(std::floor(image.fy * pc.y() / pc.z() + image.cy + 0.5));
  if (u < 0 || v < 0 || u >= image.width || v >= image.height)
    return -1.0;
  return image.at(u, v);
}

} // namespace

TEST(ExplicitSpaceGrid, StateNames)
{
  for (const auto s : {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
    EXPECT_EQ(planar_grid::spaceStateFromString(planar_grid::toString(s)), s);
  EXPECT_THROW(planar_grid::spaceStateFromString("maybe"), planar_grid::Exception);
}

TEST(ExplicitSpaceGrid, ParametersOutOfRangeThrow)
{
  auto p = params(SpaceState::UNKNOWN);
  p.resolution_m = 0.0;
  EXPECT_THROW(ExplicitSpaceGrid{p}, planar_grid::Exception);
  p = params(SpaceState::UNKNOWN);
  p.resolution_m = std::numeric_limits<double>::quiet_NaN();
  EXPECT_THROW(ExplicitSpaceGrid{p}, planar_grid::Exception);
  p = params(SpaceState::UNKNOWN);
  p.max_range_m = -1.0;
  EXPECT_THROW(ExplicitSpaceGrid{p}, planar_grid::Exception);
  p = params(SpaceState::UNKNOWN);
  p.surface_margin_m = -0.1;
  EXPECT_THROW(ExplicitSpaceGrid{p}, planar_grid::Exception);
  p = params(SpaceState::OCCUPIED); // an occupied prior is not a valid choice
  EXPECT_THROW(ExplicitSpaceGrid{p}, planar_grid::Exception);
  EXPECT_NO_THROW(ExplicitSpaceGrid{params(SpaceState::FREE)});
  EXPECT_THROW(DepthImage::fromPointCloud({}, 0, 10, 1.0f, 1.0f, 0.0f, 0.0f),
               planar_grid::Exception);
  EXPECT_THROW(DepthImage::fromPointCloud({}, 10, 10, 0.0f, 1.0f, 0.0f, 0.0f),
               planar_grid::Exception);
}

TEST(ExplicitSpaceGrid, GetStateMatchesMapOracle)
{
  for (const auto prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid grid(params(prior));
    std::map<std::tuple<int, int, int>, SpaceState> oracle;
    fillRandom(grid, oracle, 3000, 20, 7u);
    // every voxel of the cube (and a margin) against the map
    for (int z = -22; z < 22; ++z)
      for (int y = -22; y < 22; ++y)
        for (int x = -22; x < 22; ++x) {
          const auto it = oracle.find({x, y, z});
          const SpaceState expected = it == oracle.end() ? prior : it->second;
          ASSERT_EQ(grid.getState(Key(x, y, z)), expected) << x << " " << y << " " << z;
        }
    // points: the voxel containing a random point, via toKey
    std::mt19937 rng(11u);
    std::uniform_real_distribution<float> coord(-2.2f, 2.2f);
    for (int i = 0; i < 5000; ++i) {
      const Eigen::Vector3f p(coord(rng), coord(rng), coord(rng));
      const Key k = grid.toKey(p);
      EXPECT_TRUE((grid.toCentre(k) - p).cwiseAbs().maxCoeff() <= 0.05f + 1e-5f);
      const auto it = oracle.find(tup(k));
      EXPECT_EQ(grid.getState(p), it == oracle.end() ? prior : it->second);
    }
    EXPECT_EQ(grid.getState(Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f)), prior);
    // counts and forEachVoxel against the map: every voxel set is observed, except
    // UNKNOWN with the unknown prior (the state of space never observed)
    const auto observed = [prior](SpaceState s) {
      return !(s == SpaceState::UNKNOWN && prior == SpaceState::UNKNOWN);
    };
    std::map<SpaceState, std::size_t> counts;
    std::size_t visited = 0;
    for (const auto& kv : oracle)
      if (observed(kv.second))
        ++counts[kv.second];
    grid.forEachVoxel([&](const Key& k, SpaceState s) {
      ++visited;
      const auto it = oracle.find(tup(k));
      ASSERT_NE(it, oracle.end());
      EXPECT_EQ(it->second, s);
    });
    EXPECT_EQ(visited, counts[SpaceState::FREE] + counts[SpaceState::OCCUPIED]
                         + counts[SpaceState::UNKNOWN]);
    for (const auto s : {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
      EXPECT_EQ(grid.getVoxelCount(s), observed(s) ? counts[s] : 0u);
  }
}

TEST(ExplicitSpaceGrid, CastRayMatchesBruteForce)
{
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.25));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 400, 12, 3u);
  const float res = 0.25f;
  std::mt19937 rng(5u);
  std::uniform_real_distribution<float> coord(-3.0f, 3.0f);
  std::normal_distribution<float> dir(0.0f, 1.0f);
  int hits = 0;
  for (int trial = 0; trial < 500; ++trial) {
    const Eigen::Vector3f o(coord(rng), coord(rng), coord(rng));
    const Eigen::Vector3f d =
      Eigen::Vector3f(dir(rng), dir(rng), dir(rng)).normalized();
    // One ray in five without a range limit: the walk is clipped to the stored
    // super-blocks, and must still find what the oracle finds.
    const double max_range =
      trial % 5 == 0 ? std::numeric_limits<double>::infinity() : 4.0;
    // brute force: the occupied voxel whose box the ray enters first (slab test)
    double best_t = std::numeric_limits<double>::infinity();
    Eigen::Vector3f best_centre = Eigen::Vector3f::Zero();
    for (const auto& [k, s] : oracle) {
      if (s != SpaceState::OCCUPIED)
        continue;
      const Key key(std::get<0>(k), std::get<1>(k), std::get<2>(k));
      double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
      for (int a = 0; a < 3; ++a) {
        const double lo = key[a] * static_cast<double>(res), hi = lo + res;
        if (d[a] == 0.0f) {
          if (o[a] < lo || o[a] >= hi)
            t1 = -1.0;
          continue;
        }
        double ta = (lo - o[a]) / d[a], tb = (hi - o[a]) / d[a];
        if (ta > tb)
          std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
      }
      if (t0 < t1 && t0 <= max_range && t0 < best_t) {
        best_t = t0;
        best_centre = grid.toCentre(key);
      }
    }
    Eigen::Vector3f hit;
    const bool found = grid.castRay(o, d * 3.0f, max_range, hit);
    ASSERT_EQ(found, std::isfinite(best_t)) << "trial " << trial;
    if (found) {
      ++hits;
      EXPECT_TRUE((hit - best_centre).norm() < 1e-4f) << "trial " << trial;
    }
  }
  EXPECT_GT(hits, 50); // the random set is dense enough for many hits
  Eigen::Vector3f hit;
  EXPECT_THROW(grid.castRay(Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero(), 5.0, hit),
               planar_grid::Exception);
}

TEST(ExplicitSpaceGrid, CountsAndMemoryConsistent)
{
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN));
  EXPECT_EQ(grid.getBlockCount(), 0u);
  Key lo, hi;
  EXPECT_FALSE(grid.getBounds(lo, hi));
  const std::size_t empty_bytes = grid.getMemoryBytes();
  // one whole block free: stored as one uniform block (no payload)
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        grid.setState(Key(x, y, z), SpaceState::FREE);
  EXPECT_EQ(grid.getBlockCount(), 1u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::FREE), 512u);
  const std::size_t uniform_bytes = grid.getMemoryBytes();
  EXPECT_GT(uniform_bytes, empty_bytes);
  // one voxel occupied: the block needs its compact form; it holds two states, so a
  // node is one bit: 3 bytes for its 4^3 cubes (mask, header, cube bits), 2 for the
  // one mixed cube's 2^3 cells and 1 for the one mixed cell's 8 voxels, plus its
  // 2-byte offset, in one allocation (16 bytes counted for the allocator's header and
  // rounding)
  grid.setState(Key(3, 3, 3), SpaceState::OCCUPIED);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::FREE), 511u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 1u);
  EXPECT_EQ(grid.getMemoryBytes(), uniform_bytes + 6u + 2u + 16u);
  // a checkerboard of two states: every 2^3 cell mixed, the largest two-state form
  // (3 + 8 x 2 + 64 x 1 bytes)
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        grid.setState(Key(x, y, z),
                      (x + y + z) % 2 ? SpaceState::OCCUPIED : SpaceState::FREE);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 256u);
  EXPECT_EQ(grid.getMemoryBytes(), uniform_bytes + 83u + 2u + 16u);
  // three states in every 2^3 cell: 2-bit codes, the largest compact form (4 + 8 x 3 +
  // 64 x 2 bytes)
  const SpaceState three[3] = {SpaceState::FREE, SpaceState::OCCUPIED,
                               SpaceState::UNKNOWN};
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        grid.setState(Key(x, y, z), three[(x + y + z) % 3]);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 171u);
  EXPECT_EQ(grid.getMemoryBytes(), uniform_bytes + 156u + 2u + 16u);
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        ASSERT_EQ(grid.getState(Key(x, y, z)), three[(x + y + z) % 3]);
  // a road: free space above, the occupied surface at z = 4, unknown below. Its 2-bit
  // form takes 4 + 4 x 3 + 16 x 2 = 48 bytes (the 4 upper cubes mixed, 4 mixed cells
  // in each); written in two layers it takes 30: unknown against the rest, every cube
  // uniform (3 bytes), then the rest (unknown voxels taking free) as occupied in free,
  // 3 + 4 x 2 + 16 x 1 = 27 bytes
  const auto road = [](int z) {
    return z > 4    ? SpaceState::FREE
           : z == 4 ? SpaceState::OCCUPIED
                    : SpaceState::UNKNOWN;
  };
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        grid.setState(Key(x, y, z), road(z));
  EXPECT_EQ(grid.getVoxelCount(SpaceState::FREE), 192u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 64u);
  EXPECT_EQ(grid.getMemoryBytes(), uniform_bytes + 30u + 2u + 16u);
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        ASSERT_EQ(grid.getState(Key(x, y, z)), road(z));
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 8; ++x)
        grid.setState(Key(x, y, z), x == 3 && y == 3 && z == 3 ? SpaceState::OCCUPIED
                                                               : SpaceState::FREE);
  // a second block far away, negative keys
  grid.setState(Key(-100, -1, -9), SpaceState::UNKNOWN); // the prior: nothing stored
  EXPECT_EQ(grid.getBlockCount(), 1u);
  grid.setState(Key(-100, -1, -9), SpaceState::OCCUPIED);
  EXPECT_EQ(grid.getBlockCount(), 2u);
  ASSERT_TRUE(grid.getBounds(lo, hi));
  EXPECT_EQ(lo, Key(-104, -8, -16)); // block-aligned: -100 lies in block [-104, -97]
  EXPECT_EQ(hi, Key(7, 7, 7));
  // back to the prior: the blocks are dropped
  grid.setState(Key(-100, -1, -9), SpaceState::UNKNOWN);
  grid.setState(Key(3, 3, 3), SpaceState::FREE);
  EXPECT_EQ(grid.getBlockCount(), 1u);
  EXPECT_EQ(grid.getMemoryBytes(), uniform_bytes);
  grid.clear();
  EXPECT_EQ(grid.getBlockCount(), 0u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::FREE), 0u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::UNKNOWN), 0u); // the prior is never counted
  EXPECT_EQ(grid.getMemoryBytes(), empty_bytes);
}

TEST(ExplicitSpaceGrid, CompactStorageMatchesMapOracle)
{
  // Boxes of every size and alignment (whole blocks, 4^3 cubes, 2^3 cells, single
  // voxels, and boxes back to the prior) over three super-blocks of 64^3 voxels along
  // x, with negative keys; the oracle holds the last state set per voxel. Queries in
  // between read writes still waiting in the edit buffer.
  for (const auto prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid grid(params(prior));
    std::map<std::tuple<int, int, int>, SpaceState> oracle;
    std::mt19937 rng(prior == SpaceState::FREE ? 21u : 23u);
    std::uniform_int_distribution<int> cx(-80, 79), cyz(-20, 19), edge(1, 12);
    std::uniform_int_distribution<int> state(0, 2), align(0, 3);
    const auto stateAt = [&](int x, int y, int z) {
      const auto it = oracle.find({x, y, z});
      return it == oracle.end() ? prior : it->second;
    };
    for (int box = 0; box < 160; ++box) {
      const int a = align(rng);
      // a = 0: any box; 1: 8-aligned blocks; 2: 4-aligned cubes; 3: 2-aligned cells
      const int step = a == 0 ? 1 : 16 >> a;
      const int e = a == 0 ? edge(rng) : step * (1 + edge(rng) % 2);
      const int x0 = cx(rng) / step * step, y0 = cyz(rng) / step * step,
                z0 = cyz(rng) / step * step;
      const auto s = box % 10 == 9 ? prior : static_cast<SpaceState>(state(rng));
      for (int z = z0; z < z0 + e; ++z)
        for (int y = y0; y < y0 + e; ++y)
          for (int x = x0; x < x0 + e; ++x) {
            grid.setState(Key(x, y, z), s);
            oracle[{x, y, z}] = s;
          }
      // reads with pending edits
      for (int k = 0; k < 20; ++k) {
        const int x = cx(rng), y = cyz(rng), z = cyz(rng);
        ASSERT_EQ(grid.getState(Key(x, y, z)), stateAt(x, y, z));
      }
      if (box % 40 == 39) {
        EXPECT_GT(grid.getBlockCount(), 0u); // commits the pending edits
      }
    }
    for (int z = -24; z < 36; ++z)
      for (int y = -24; y < 36; ++y)
        for (int x = -84; x < 96; ++x)
          ASSERT_EQ(grid.getState(Key(x, y, z)), stateAt(x, y, z))
            << x << " " << y << " " << z;
    // blocks: those holding a voxel whose stored code is not the prior's (observed
    // free space with the free prior, UNKNOWN with the unknown prior is the prior)
    std::set<std::tuple<int, int, int>> blocks;
    std::map<SpaceState, std::size_t> counts;
    for (const auto& [k, s] : oracle) {
      if (prior == SpaceState::UNKNOWN && s == SpaceState::UNKNOWN)
        continue;
      blocks.insert({std::get<0>(k) >> 3, std::get<1>(k) >> 3, std::get<2>(k) >> 3});
      ++counts[s];
    }
    EXPECT_EQ(grid.getBlockCount(), blocks.size());
    for (const auto s : {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
      EXPECT_EQ(grid.getVoxelCount(s),
                prior == SpaceState::UNKNOWN && s == SpaceState::UNKNOWN ? 0u
                                                                         : counts[s]);
    // forEachVoxel: every observed voxel once, blocks in key order
    std::size_t visited = 0;
    std::tuple<int, int, int> last_block{std::numeric_limits<int>::min(), 0, 0};
    grid.forEachVoxel([&](const Key& k, SpaceState s) {
      ++visited;
      EXPECT_EQ(stateAt(k.x(), k.y(), k.z()), s);
      const std::tuple<int, int, int> b{k.z() >> 3, k.y() >> 3, k.x() >> 3};
      EXPECT_TRUE(!(b < last_block));
      last_block = b;
    });
    EXPECT_EQ(visited,
              counts[SpaceState::FREE] + counts[SpaceState::OCCUPIED]
                + (prior == SpaceState::FREE ? counts[SpaceState::UNKNOWN] : 0));
    // forEachVoxelRun: the same voxels with the same states, each once, in vertical
    // runs inside one block; two runs that touch in a column differ in state
    std::map<std::tuple<int, int, int>, SpaceState> from_runs;
    std::map<std::tuple<int, int, int>, SpaceState> run_tops;
    std::size_t runs = 0;
    grid.forEachVoxelRun([&](const Key& k, int length, SpaceState s) {
      ++runs;
      ASSERT_GE(length, 1);
      ASSERT_LE((k.z() & 7) + length, 8) << "a run crosses a block boundary";
      const auto below = run_tops.find({k.x(), k.y(), k.z() - 1});
      if (below != run_tops.end() && (k.z() & 7) != 0) {
        EXPECT_NE(below->second, s) << "two runs of one state touch";
      }
      for (int dz = 0; dz < length; ++dz) {
        EXPECT_TRUE(from_runs.insert({{k.x(), k.y(), k.z() + dz}, s}).second);
      }
      run_tops[{k.x(), k.y(), k.z() + length - 1}] = s;
    });
    std::map<std::tuple<int, int, int>, SpaceState> from_voxels;
    grid.forEachVoxel([&](const Key& k, SpaceState s) {
      from_voxels[{k.x(), k.y(), k.z()}] = s;
    });
    EXPECT_EQ(from_runs, from_voxels);
    EXPECT_LT(runs, from_voxels.size());
    // round trip through the bit stream
    std::vector<std::uint8_t> bytes, again;
    grid.serialize(bytes);
    ExplicitSpaceGrid read(params(prior));
    read.deserialize(bytes.data(), bytes.size());
    EXPECT_TRUE(read == grid);
    read.serialize(again);
    EXPECT_EQ(again, bytes);
    // with the unknown prior, every stored voxel back to the prior: nothing stored, no
    // memory beyond the empty grid's (with the free prior, setState() stores observed
    // free space: never-observed space is not written back)
    if (prior == SpaceState::FREE)
      continue;
    const ExplicitSpaceGrid empty(params(prior));
    for (const auto& kv : oracle)
      grid.setState(
        Key(std::get<0>(kv.first), std::get<1>(kv.first), std::get<2>(kv.first)),
        prior);
    EXPECT_EQ(grid.getBlockCount(), 0u);
    EXPECT_TRUE(grid == empty);
    EXPECT_EQ(grid.getMemoryBytes(), empty.getMemoryBytes());
  }
}

TEST(ExplicitSpaceGrid, MemoryBytesMatchTheAllocations)
{
  // Every byte a grid's storage holds is counted: the bytes requested from operator new
  // while a grid is decoded (its old, empty storage freed, the new one allocated; the
  // decoder's scratch freed before it returns) and 16 bytes of allocator overhead per
  // allocation still held give exactly the growth of getMemoryBytes().
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 20000, 100, 31u);
  for (int z = 0; z < 64; ++z)
    for (int y = 0; y < 64; ++y)
      for (int x = 0; x < 64; ++x)
        grid.setState(Key(x + 200, y, z),
                      (x * y + z) % 7 == 0 ? SpaceState::OCCUPIED : SpaceState::FREE);
  std::vector<std::uint8_t> bytes;
  grid.serialize(bytes);
  ExplicitSpaceGrid read(params(SpaceState::UNKNOWN));
  const std::size_t empty_bytes = read.getMemoryBytes();
  const HeapUse before = heapUse();
  read.deserialize(bytes.data(), bytes.size());
  const HeapUse after = heapUse();
  ASSERT_GT(after.blocks, before.blocks);
  const std::size_t requested = after.bytes - before.bytes;
  const std::size_t allocations = after.blocks - before.blocks;
  EXPECT_EQ(read.getMemoryBytes() - empty_bytes, requested + 16 * allocations);
  EXPECT_GT(read.getBlockCount(), 5000u);
  EXPECT_TRUE(read == grid);
}

TEST(ExplicitSpaceGrid, SerializeRoundTrip)
{
  for (const auto prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid grid(params(prior));
    std::map<std::tuple<int, int, int>, SpaceState> oracle;
    fillRandom(grid, oracle, 2000, 30, 13u);
    // plus uniform blocks and a large uniform region (inner leaves above block level)
    for (int z = 64; z < 96; ++z)
      for (int y = -32; y < 0; ++y)
        for (int x = 0; x < 32; ++x)
          grid.setState(Key(x, y, z), SpaceState::OCCUPIED);
    std::vector<std::uint8_t> bytes;
    grid.serialize(bytes);
    ExplicitSpaceGrid read(
      params(prior == SpaceState::FREE ? SpaceState::UNKNOWN : SpaceState::FREE));
    read.deserialize(bytes.data(), bytes.size());
    EXPECT_EQ(read.getParams().prior, prior); // the prior comes from the stream
    EXPECT_TRUE(read == grid);
    std::vector<std::uint8_t> again;
    read.serialize(again);
    EXPECT_EQ(again, bytes);
    // flip one voxel: unequal
    const Key k(1, 2, 3);
    read.setState(k, grid.getState(k) == SpaceState::OCCUPIED ? SpaceState::FREE
                                                              : SpaceState::OCCUPIED);
    EXPECT_TRUE(read != grid);
  }
  // an empty grid is one prior leaf
  ExplicitSpaceGrid empty(params(SpaceState::FREE));
  std::vector<std::uint8_t> bytes;
  empty.serialize(bytes);
  EXPECT_EQ(bytes.size(), 23u); // 22-byte header + 1 label byte
  ExplicitSpaceGrid read(params(SpaceState::FREE));
  read.setState(Key(0, 0, 0), SpaceState::OCCUPIED);
  read.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(read == empty);
  // different resolution: unequal
  ExplicitSpaceGrid coarse(params(SpaceState::FREE, 0.2));
  EXPECT_TRUE(coarse != empty);
}

TEST(ExplicitSpaceGrid, TruncatedStreamRejected)
{
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 60, 10, 21u);
  std::vector<std::uint8_t> bytes;
  grid.serialize(bytes);
  ASSERT_GT(bytes.size(), 30u);
  ExplicitSpaceGrid read(params(SpaceState::UNKNOWN));
  read.setState(Key(0, 0, 0), SpaceState::OCCUPIED);
  for (std::size_t n = 0; n < bytes.size(); ++n)
    EXPECT_THROW(read.deserialize(bytes.data(), n), planar_grid::IOError) << n;
  // the grid is unchanged after each rejection
  EXPECT_EQ(read.getState(Key(0, 0, 0)), SpaceState::OCCUPIED);
  EXPECT_EQ(read.getBlockCount(), 1u);
  // trailing byte
  auto longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(read.deserialize(longer.data(), longer.size()), planar_grid::IOError);
}

TEST(ExplicitSpaceGrid, CorruptStreamRejected)
{
  const auto header = [](int depth, int prior, std::uint64_t count) {
    std::vector<std::uint8_t> b(22, 0);
    b[12] = static_cast<std::uint8_t>(depth);
    b[13] = static_cast<std::uint8_t>(prior);
    for (int i = 0; i < 8; ++i)
      b[static_cast<std::size_t>(14 + i)] = static_cast<std::uint8_t>(count >> (8 * i));
    return b;
  };
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN));
  // depth 22 > 21
  auto b = header(22, 2, 1);
  b.push_back(2);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // prior label 01 (occupied) or 11 is not a prior
  b = header(0, 1, 1);
  b.push_back(1);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // label 11 at voxel level
  b = header(0, 2, 1);
  b.push_back(3);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // inner root with too few labels for its children
  b = header(1, 2, 4);
  b.push_back(0x03);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // label count far beyond the data (must not allocate)
  b = header(3, 2, std::numeric_limits<std::uint64_t>::max());
  b.push_back(0);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // a 2^21-voxel occupied leaf: too many blocks, rejected before allocating
  b = header(21, 2, 1);
  b.push_back(1);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // root key not block-aligned
  b = header(3, 2, 1);
  b[0] = 3;
  b.push_back(1);
  EXPECT_THROW(grid.deserialize(b.data(), b.size()), planar_grid::IOError);
  // valid: depth 3, one occupied leaf = one uniform block
  b = header(3, 2, 1);
  b.push_back(1);
  ASSERT_NO_THROW(grid.deserialize(b.data(), b.size()));
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 512u);
  EXPECT_EQ(grid.getBlockCount(), 1u);
}

TEST(ExplicitSpaceGrid, RandomByteFlipsNeverCrash)
{
  ExplicitSpaceGrid grid(params(SpaceState::FREE));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 200, 16, 31u);
  std::vector<std::uint8_t> bytes;
  grid.serialize(bytes);
  std::mt19937 rng(99u);
  std::uniform_int_distribution<std::size_t> pos(0, bytes.size() - 1);
  std::uniform_int_distribution<int> bit(0, 7);
  int rejected = 0, accepted = 0;
  for (int trial = 0; trial < 2000; ++trial) {
    auto corrupt = bytes;
    const int flips = 1 + trial % 3;
    for (int f = 0; f < flips; ++f)
      corrupt[pos(rng)] ^= static_cast<std::uint8_t>(1u << bit(rng));
    ExplicitSpaceGrid read(params(SpaceState::FREE));
    try {
      read.deserialize(corrupt.data(), corrupt.size());
      ++accepted;
      // a valid grid: it re-encodes and decodes to itself
      std::vector<std::uint8_t> again;
      read.serialize(again);
      ExplicitSpaceGrid twice(params(SpaceState::FREE));
      twice.deserialize(again.data(), again.size());
      EXPECT_TRUE(twice == read);
    } catch (const planar_grid::IOError&) {
      ++rejected;
    }
  }
  EXPECT_GT(rejected, 0);
  EXPECT_EQ(rejected + accepted, 2000);
}

TEST(ExplicitSpaceGrid, DepthImageZBufferKeepsNearest)
{
  pcl::PointCloud<pcl::PointXYZ> cloud;
  cloud.push_back({0.0f, 0.0f, 5.0f});
  cloud.push_back({0.0f, 0.0f, 2.0f}); // same pixel, nearer: wins
  cloud.push_back({0.0f, 0.0f, 3.0f});
  cloud.push_back({0.5f, 0.0f, 1.0f});  // pixel (u = 10 * 0.5 + 4.5 -> 10 >= 10): out
  cloud.push_back({0.1f, 0.1f, -1.0f}); // behind the camera: skipped
  cloud.push_back({std::nanf(""), 0.0f, 1.0f});
  cloud.push_back(
    {0.2f, -0.1f, 2.0f}); // u = 10 * 0.1 + 4.5 = 5.5 -> 6, v = 4.5 - 0.5 = 4
  const DepthImage image =
    DepthImage::fromPointCloud(cloud, 10, 10, 10.0f, 10.0f, 4.5f, 4.5f);
  EXPECT_EQ(image.width, 10);
  EXPECT_EQ(image.depth_m.size(), 100u);
  EXPECT_FLOAT_EQ(image.at(5, 5), 2.0f); // u = 4.5 -> floor(4.5 + 0.5) = 5
  EXPECT_FLOAT_EQ(image.at(6, 4), 2.0f);
  int valid = 0;
  for (const float d : image.depth_m)
    valid += std::isfinite(d) ? 1 : 0;
  EXPECT_EQ(valid, 2);
}

TEST(ExplicitSpaceGrid, EmptyAndInvalidImagesChangeNothing)
{
  ExplicitSpaceGrid grid(params(SpaceState::FREE));
  grid.setState(Key(0, 0, 20), SpaceState::OCCUPIED);
  grid.integrateDepthImage(DepthImage{}, Eigen::Isometry3d::Identity());
  DepthImage nan_image = renderBoxRoom();
  std::fill(nan_image.depth_m.begin(), nan_image.depth_m.end(), std::nanf(""));
  grid.integrateDepthImage(nan_image, Eigen::Isometry3d::Identity());
  std::fill(nan_image.depth_m.begin(), nan_image.depth_m.end(), -1.0f);
  grid.integrateDepthImage(nan_image, Eigen::Isometry3d::Identity());
  DepthImage wrong_size = renderBoxRoom();
  wrong_size.depth_m.pop_back();
  grid.integrateDepthImage(wrong_size, Eigen::Isometry3d::Identity());
  EXPECT_EQ(grid.getBlockCount(), 1u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::OCCUPIED), 1u);
  EXPECT_EQ(grid.getVoxelCount(SpaceState::UNKNOWN), 0u);
}

/** \brief A box room with an occluder seen from one general pose, for both priors. */
TEST(ExplicitSpaceGrid, BoxRoomFreeOccupiedUnknown)
{
  const DepthImage image = renderBoxRoom();
  const Eigen::Isometry3d T = roomPose();
  for (const auto prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid grid(params(prior, 0.1, 20.0));
    grid.integrateDepthImage(image, T);
    const auto state = [&](const Eigen::Vector3d& pc) {
      return grid.getState((T * pc).cast<float>().eval());
    };
    // Named points (camera frame).
    EXPECT_EQ(state({0.0, 0.0, 2.0}), SpaceState::FREE);    // in front of the occluder
    EXPECT_EQ(state({2.5, 0.3, 6.0}), SpaceState::FREE);    // beside its shadow
    EXPECT_EQ(state({0.0, 0.0, 6.0}), SpaceState::UNKNOWN); // in its shadow
    EXPECT_EQ(state({2.5, 0.3, 9.0}), SpaceState::UNKNOWN); // behind the front wall
    EXPECT_EQ(state({0.0, 0.0, -2.0}), prior);              // behind the camera
    EXPECT_EQ(state({30.0, 0.0, 5.0}), prior);              // far outside the frustum
    // Random points: in front of the surface by > 0.3 m -> free; in the occluder's
    // shadow and > 0.3 m behind it -> unknown; outside the frustum -> the prior.
    std::mt19937 rng(17u);
    std::uniform_real_distribution<double> ux(-6.0, 6.0), uy(-3.0, 3.0), uz(-3.0, 12.0);
    int n_free = 0, ok_free = 0, n_shadow = 0, ok_shadow = 0, n_out = 0, ok_out = 0;
    for (int i = 0; i < 40000; ++i) {
      const Eigen::Vector3d pc(ux(rng), uy(rng), uz(rng));
      const SpaceState s = state(pc);
      // outside: behind the camera, or projecting 2 px outside the image
      const bool behind = pc.z() < -0.2;
      const double u = image.fx * pc.x() / pc.z() + image.cx,
                   v = image.fy * pc.y() / pc.z() + image.cy;
      const double pad = image.fx * 0.09 / std::max(pc.z(), 0.1) + 2.0;
      if (behind
          || (pc.z() > 0.2
              && (u < -pad || v < -pad || u > image.width + pad
                  || v > image.height + pad))) {
        ++n_out;
        ok_out += s == prior ? 1 : 0;
        continue;
      }
      if (pc.z() < 0.5)
        continue;
      // min and max room depth over a window twice a voxel's footprint: the truth
      // for a voxel, not only for its centre ray
      if (roomDepthAlong(image, pc) < 0.0)
        continue;
      const int cu = static_cast<int>(std::floor(u + 0.5)),
                cv = static_cast<int>(std::floor(v + 0.5));
      const int k = static_cast<int>(std::ceil(2.0 * image.fx * 0.0866 / pc.z())) + 1;
      double dmin = 1e9, dmax = 0.0;
      for (int wv = std::max(cv - k, 0); wv <= std::min(cv + k, image.height - 1); ++wv)
        for (int wu = std::max(cu - k, 0); wu <= std::min(cu + k, image.width - 1);
             ++wu) {
          dmin = std::min(dmin, static_cast<double>(image.at(wu, wv)));
          dmax = std::max(dmax, static_cast<double>(image.at(wu, wv)));
        }
      if (pc.z() < dmin - 0.2) {
        ++n_free;
        ok_free += s == SpaceState::FREE ? 1 : 0;
      } else if (dmax < 3.01 && pc.z() > 3.3 && pc.z() < 7.5) {
        ++n_shadow;
        ok_shadow += s == SpaceState::UNKNOWN ? 1 : 0;
      }
    }
    EXPECT_GT(n_free, 2000);
    EXPECT_GT(n_shadow, 20);
    EXPECT_GT(n_out, 5000);
    // 98 %: the integration's footprint is a superset (mip cells) of the window
    EXPECT_GE(ok_free, n_free * 98 / 100) << "prior " << planar_grid::toString(prior);
    EXPECT_EQ(ok_shadow, n_shadow) << "prior " << planar_grid::toString(prior);
    EXPECT_EQ(ok_out, n_out);
    // Occupied: every wall sample's voxel (all pixels are measured, pixel spacing below
    // the voxel edge), and the count matches the distinct voxels of the pixels.
    std::set<std::tuple<int, int, int>> surface;
    for (int v = 0; v < image.height; ++v)
      for (int u = 0; u < image.width; ++u) {
        const double d = image.at(u, v);
        const Eigen::Vector3d pc((u - image.cx) / image.fx * d,
                                 (v - image.cy) / image.fy * d, d);
        surface.insert(tup(grid.toKey((T * pc).cast<float>().eval())));
      }
    std::size_t occupied_hits = 0;
    for (const auto& k : surface)
      occupied_hits +=
        grid.getState(Key(std::get<0>(k), std::get<1>(k), std::get<2>(k)))
            == SpaceState::OCCUPIED
          ? 1
          : 0;
    EXPECT_GE(occupied_hits, surface.size() * 99 / 100);
    const double ratio =
      static_cast<double>(grid.getVoxelCount(SpaceState::OCCUPIED)) / surface.size();
    EXPECT_GT(ratio, 0.98);
    EXPECT_LT(ratio, 1.02);
    if (prior == SpaceState::FREE)
      EXPECT_GT(grid.getVoxelCount(SpaceState::UNKNOWN), 1000u);
    else
      EXPECT_GT(grid.getVoxelCount(SpaceState::FREE), 50000u);
  }
}

/** \brief The occupied voxels of a view are exactly the voxels of its pixels within
 * range: floor((world_T_camera * (xn d, yn d, d)) / resolution) per pixel in float,
 * xn = (u - cx) / fx, yn = (v - cy) / fy (the brute-force oracle), on random depths
 * with holes and depths beyond the range, near the origin and 6e7 m from it (keys
 * near 2^29, where the integration clamps before converting). */
TEST(ExplicitSpaceGrid, OccupiedVoxelsAreThoseOfThePixels)
{
  std::mt19937 rng(29u);
  std::uniform_real_distribution<float> depth(0.3f, 9.0f), unit(0.0f, 1.0f);
  DepthImage image;
  image.width = 97;
  image.height = 61;
  image.fx = 70.0f;
  image.fy = 72.0f;
  image.cx = 48.3f;
  image.cy = 29.8f;
  image.depth_m.resize(static_cast<std::size_t>(image.width * image.height));
  for (auto& d : image.depth_m) {
    const float r = unit(rng);
    d = r < 0.1f    ? std::numeric_limits<float>::quiet_NaN()
        : r < 0.15f ? 0.0f
        : r < 0.2f  ? std::numeric_limits<float>::infinity()
                    : depth(rng); // some beyond the 8 m range
  }
  for (const double offset_m : {0.0, 6.0e7}) {
    Eigen::Isometry3d T = roomPose();
    T.translation() += Eigen::Vector3d(offset_m, -0.5 * offset_m, 0.25 * offset_m);
    const double resolution_m = 0.1;
    ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, resolution_m, 8.0));
    grid.integrateDepthImage(image, T);
    const Eigen::Isometry3f T_f = T.cast<float>();
    const float inv_res = 1.0f / static_cast<float>(resolution_m);
    std::set<std::tuple<int, int, int>> expected;
    for (int v = 0; v < image.height; ++v)
      for (int u = 0; u < image.width; ++u) {
        const float d = image.at(u, v);
        if (!(d > 0.0f && d <= 8.0f))
          continue;
        const float xn = (static_cast<float>(u) - image.cx) / image.fx;
        const float yn = (static_cast<float>(v) - image.cy) / image.fy;
        const Eigen::Vector3f pw = (T_f * Eigen::Vector3f(xn * d, yn * d, d)) * inv_res;
        expected.insert({static_cast<int>(std::floor(pw.x())),
                         static_cast<int>(std::floor(pw.y())),
                         static_cast<int>(std::floor(pw.z()))});
      }
    std::set<std::tuple<int, int, int>> occupied;
    grid.forEachVoxel([&](const Key& k, SpaceState s) {
      if (s == SpaceState::OCCUPIED)
        occupied.insert(tup(k));
    });
    // far from the origin, floats are 4 m apart: few distinct voxels
    EXPECT_GT(expected.size(), offset_m == 0.0 ? 1000u : 10u);
    EXPECT_EQ(occupied, expected) << "offset " << offset_m << " m";
  }
}

/** \brief Newest free / occupied observation wins; occlusion never erases them. */
TEST(ExplicitSpaceGrid, OcclusionKeepsKnownStates)
{
  const DepthImage image = renderBoxRoom();
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.1, 20.0));
  // a voxel in the occluder's shadow, known free and one known occupied beforehand
  const Key shadow_free = grid.toKey(Eigen::Vector3f(0.05f, 0.05f, 6.0f));
  const Key shadow_occ = grid.toKey(Eigen::Vector3f(-0.2f, 0.1f, 5.0f));
  const Key seen = grid.toKey(Eigen::Vector3f(0.0f, 0.0f, 2.0f));
  grid.setState(shadow_free, SpaceState::FREE);
  grid.setState(shadow_occ, SpaceState::OCCUPIED);
  grid.setState(seen, SpaceState::OCCUPIED);
  grid.integrateDepthImage(image, Eigen::Isometry3d::Identity());
  EXPECT_EQ(grid.getState(shadow_free), SpaceState::FREE);
  EXPECT_EQ(grid.getState(shadow_occ), SpaceState::OCCUPIED);
  EXPECT_EQ(grid.getState(seen), SpaceState::FREE); // newest observation
  // prior free: occluded space never observed becomes unknown; observed free and
  // occupied stay
  ExplicitSpaceGrid free_prior(params(SpaceState::FREE, 0.1, 20.0));
  const Key shadow_never = grid.toKey(Eigen::Vector3f(0.05f, -0.15f, 6.0f));
  free_prior.setState(shadow_occ, SpaceState::OCCUPIED);
  free_prior.setState(shadow_free, SpaceState::FREE);
  EXPECT_EQ(free_prior.getVoxelCount(SpaceState::FREE), 1u); // observed, not the prior
  free_prior.integrateDepthImage(image, Eigen::Isometry3d::Identity());
  EXPECT_EQ(free_prior.getState(shadow_occ), SpaceState::OCCUPIED);
  EXPECT_EQ(free_prior.getState(shadow_free), SpaceState::FREE);
  EXPECT_EQ(free_prior.getState(shadow_never), SpaceState::UNKNOWN);
  // the free space the view saw is stored as observed: the same voxels as with the
  // unknown prior
  ExplicitSpaceGrid unknown_prior(params(SpaceState::UNKNOWN, 0.1, 20.0));
  unknown_prior.integrateDepthImage(image, Eigen::Isometry3d::Identity());
  ExplicitSpaceGrid free_only(params(SpaceState::FREE, 0.1, 20.0));
  free_only.integrateDepthImage(image, Eigen::Isometry3d::Identity());
  EXPECT_GT(unknown_prior.getVoxelCount(SpaceState::FREE), 10000u);
  EXPECT_EQ(free_only.getVoxelCount(SpaceState::FREE),
            unknown_prior.getVoxelCount(SpaceState::FREE));
  EXPECT_EQ(free_only.getVoxelCount(SpaceState::OCCUPIED),
            unknown_prior.getVoxelCount(SpaceState::OCCUPIED));
  std::size_t differ = 0;
  unknown_prior.forEachVoxel(
    [&](const Key& k, SpaceState s) { differ += free_only.getState(k) != s ? 1 : 0; });
  EXPECT_EQ(differ, 0u);
}

/** \brief The same bytes read as a version 2 and a version 3 stream: in version 2 a
 * leaf with the free prior's label was never observed; in version 3 it is observed
 * free space, and never observed has its own escaped label. */
TEST(ExplicitSpaceGrid, VersionTwoStreamsReadFreeAsNeverObserved)
{
  // root (0, 0, 0), depth 3 (one block), prior free (0), one label: 00
  std::vector<std::uint8_t> b(22, 0);
  b[12] = 3;
  b[14] = 1;
  b.push_back(0x00);
  ExplicitSpaceGrid v2(params(SpaceState::UNKNOWN));
  v2.deserialize(b.data(), b.size(), 2);
  EXPECT_EQ(v2.getParams().prior, SpaceState::FREE);
  EXPECT_EQ(v2.getBlockCount(), 0u);
  EXPECT_EQ(v2.getVoxelCount(SpaceState::FREE), 0u);
  EXPECT_EQ(v2.getState(Key(1, 2, 3)), SpaceState::FREE);
  ExplicitSpaceGrid v3(params(SpaceState::UNKNOWN));
  v3.deserialize(b.data(), b.size(), 3);
  EXPECT_EQ(v3.getBlockCount(), 1u);
  EXPECT_EQ(v3.getVoxelCount(SpaceState::FREE), 512u);
  // version 3, never observed: 11 then 00 (labels 3, 0: byte 0x03), two labels
  b[14] = 2;
  b.back() = 0x03;
  v3.deserialize(b.data(), b.size(), 3);
  EXPECT_EQ(v3.getBlockCount(), 0u);
  EXPECT_EQ(v3.getState(Key(1, 2, 3)), SpaceState::FREE);
  // ... which the unknown prior has no use for (never observed is 10 there)
  b[13] = 2;
  EXPECT_THROW(v3.deserialize(b.data(), b.size(), 3), planar_grid::IOError);
  // an escape followed by 01 or 10
  b[13] = 0;
  b.back() = 0x07;
  EXPECT_THROW(v3.deserialize(b.data(), b.size(), 3), planar_grid::IOError);
  // unknown versions
  EXPECT_THROW(v3.deserialize(b.data(), b.size(), 0), planar_grid::IOError);
  EXPECT_THROW(v3.deserialize(b.data(), b.size(), 4), planar_grid::IOError);
  // the empty free-prior grid writes exactly that never-observed root
  ExplicitSpaceGrid empty(params(SpaceState::FREE));
  std::vector<std::uint8_t> bytes;
  empty.serialize(bytes);
  b[12] = 0; // depth 0: the root is one voxel
  b.back() = 0x03;
  EXPECT_EQ(bytes, b);
}

/** \brief The result does not depend on the number of threads: byte-identical
 * streams, equal grids and equal memory for 1, 2, 3 and 7 threads, both priors, two
 * overlapping views (the second over known states), a room with holes punched into the
 * depth image. */
TEST(ExplicitSpaceGrid, ThreadCountDoesNotChangeTheResult)
{
  const DepthImage holes = renderBoxRoomWithHoles(7);
  Eigen::Isometry3d second = Eigen::Isometry3d::Identity();
  second.linear() =
    Eigen::AngleAxisd(-0.5, Eigen::Vector3d(0.3, -1.0, 0.4).normalized())
      .toRotationMatrix();
  second.translation() = Eigen::Vector3d(-0.7, 0.3, 0.9);
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    std::vector<std::uint8_t> reference;
    std::size_t reference_memory = 0;
    ExplicitSpaceGrid single(params(prior, 0.1, 12.0));
    for (const int threads : {1, 2, 3, 7}) {
      ExplicitSpaceGrid grid(params(prior, 0.1, 12.0));
      planar_grid::ExplicitSpaceGridThreads::set(grid, threads);
      grid.integrateDepthImage(holes, roomPose());
      grid.integrateDepthImage(renderBoxRoom(), second);
      std::vector<std::uint8_t> bytes;
      grid.serialize(bytes);
      if (threads == 1) {
        reference = bytes;
        reference_memory = grid.getMemoryBytes();
        single.deserialize(bytes.data(), bytes.size());
        // something besides the prior was written
        EXPECT_GT(grid.getVoxelCount(prior == SpaceState::FREE ? SpaceState::UNKNOWN
                                                               : SpaceState::FREE),
                  1000u);
        continue;
      }
      EXPECT_EQ(bytes, reference)
        << threads << " threads, prior " << planar_grid::toString(prior);
      EXPECT_TRUE(grid == single) << threads << " threads";
      EXPECT_EQ(grid.getMemoryBytes(), reference_memory) << threads << " threads";
    }
  }
}

TEST(ExplicitSpaceGrid, SkippingStoredFreeSpaceChangesNothing)
{
  // integrateDepthImage() does not observe the 4^3 cubes already free in the storage,
  // unless setState() edits are pending; a pending edit far from the views makes the
  // second grid observe every cube. Both must end with the same bytes.
  const DepthImage holes = renderBoxRoomWithHoles(11);
  // the room 1.5 times as large: space behind the walls of the other views is seen
  DepthImage larger = renderBoxRoom();
  for (auto& d : larger.depth_m)
    d *= 1.5f;
  const Key far(5000, 5000, 5000);
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid skipping(params(prior, 0.1, 12.0)),
      observing(params(prior, 0.1, 12.0));
    for (int k = 0; k < 6; ++k) {
      // the same room from nearby poses: later views see space earlier ones freed
      Eigen::Isometry3d pose = roomPose();
      pose.translation() += Eigen::Vector3d(0.13 * k, -0.05 * k, 0.31 * k);
      const DepthImage& image = k % 3 == 0   ? holes
                                : k % 3 == 1 ? renderBoxRoom()
                                             : larger;
      // a change each view (setState() of the voxel's own state writes nothing)
      const SpaceState far_state = k % 2 == 0 ? SpaceState::OCCUPIED : SpaceState::FREE;
      skipping.setState(far, far_state);
      EXPECT_GT(skipping.getMemoryBytes(), 0u); // commits the edit: nothing pending
      skipping.integrateDepthImage(image, pose);
      observing.setState(far, far_state); // left pending
      observing.integrateDepthImage(image, pose);
    }
    std::vector<std::uint8_t> a, b;
    skipping.serialize(a);
    observing.serialize(b);
    EXPECT_EQ(a, b) << "prior " << planar_grid::toString(prior);
    EXPECT_TRUE(skipping == observing);
    EXPECT_EQ(skipping.getMemoryBytes(), observing.getMemoryBytes());
    EXPECT_GT(skipping.getVoxelCount(SpaceState::FREE), 10000u);
  }
}

TEST(ExplicitSpaceGrid, ExportOctoMapReadsBack)
{
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.2));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 500, 10, 41u);
  const auto dir = std::filesystem::temp_directory_path()
                   / ("planar_grid_space_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "space.bt").string();
  grid.exportOctoMap(path);
  octomap::OcTree tree(0.2);
  ASSERT_TRUE(tree.readBinary(path));
  EXPECT_DOUBLE_EQ(tree.getResolution(), 0.2);
  std::size_t occupied = 0;
  grid.forEachVoxel([&](const Key& k, SpaceState s) {
    const Eigen::Vector3f c = grid.toCentre(k);
    const octomap::OcTreeNode* node = tree.search(c.x(), c.y(), c.z());
    if (s == SpaceState::UNKNOWN) {
      EXPECT_EQ(node, nullptr);
      return;
    }
    ASSERT_NE(node, nullptr);
    EXPECT_EQ(tree.isNodeOccupied(node), s == SpaceState::OCCUPIED);
    occupied += s == SpaceState::OCCUPIED ? 1 : 0;
  });
  // the tree holds no other occupied voxels
  tree.expand();
  std::size_t tree_occupied = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it)
    tree_occupied += tree.isNodeOccupied(*it) ? 1 : 0;
  EXPECT_EQ(tree_occupied, occupied);
  EXPECT_GT(occupied, 100u);
  std::filesystem::remove_all(dir);
  EXPECT_THROW(grid.exportOctoMap("/nonexistent_folder_planar_grid/x.bt"),
               planar_grid::IOError);
}

/** \brief With the free prior the export holds what the view saw: observed free voxels
 * free, occupied ones occupied, occluded and never-observed space absent. Against the
 * grid voxel by voxel (read back with liboctomap). */
TEST(ExplicitSpaceGrid, ExportOctoMapFreePriorKeepsOnlyObservedSpace)
{
  const DepthImage image = renderBoxRoom();
  ExplicitSpaceGrid grid(params(SpaceState::FREE, 0.2, 12.0));
  grid.integrateDepthImage(image, roomPose());
  ASSERT_GT(grid.getVoxelCount(SpaceState::FREE), 1000u);
  ASSERT_GT(grid.getVoxelCount(SpaceState::UNKNOWN), 100u);
  const auto dir = std::filesystem::temp_directory_path()
                   / ("planar_grid_free_prior_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "space.bt").string();
  grid.exportOctoMap(path);
  octomap::OcTree tree(0.2);
  ASSERT_TRUE(tree.readBinary(path));
  std::filesystem::remove_all(dir);
  std::size_t unknown = 0;
  grid.forEachVoxel([&](const Key& k, SpaceState s) {
    const Eigen::Vector3f c = grid.toCentre(k);
    const octomap::OcTreeNode* node = tree.search(c.x(), c.y(), c.z());
    if (s == SpaceState::UNKNOWN) {
      ++unknown;
      ASSERT_EQ(node, nullptr);
      return;
    }
    ASSERT_NE(node, nullptr) << k.transpose();
    ASSERT_EQ(tree.isNodeOccupied(node), s == SpaceState::OCCUPIED) << k.transpose();
  });
  EXPECT_EQ(unknown, grid.getVoxelCount(SpaceState::UNKNOWN));
  // behind the camera: never observed, free by the prior, absent from the tree
  const Eigen::Vector3f behind =
    (roomPose() * Eigen::Vector3d(0.0, 0.0, -2.0)).cast<float>();
  EXPECT_EQ(grid.getState(behind), SpaceState::FREE);
  EXPECT_EQ(tree.search(behind.x(), behind.y(), behind.z()), nullptr);
  tree.expand();
  std::size_t free_voxels = 0, occupied_voxels = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it)
    (tree.isNodeOccupied(*it) ? occupied_voxels : free_voxels) += 1;
  EXPECT_EQ(free_voxels, grid.getVoxelCount(SpaceState::FREE));
  EXPECT_EQ(occupied_voxels, grid.getVoxelCount(SpaceState::OCCUPIED));
}

/** \brief Real data: Karlsruhe frame 10 (SGBM disparity, depth = f B / d) at 0.1 m. */
TEST(ExplicitSpaceGrid, KarlsruheFrame10)
{
  const std::string dir =
    std::string(PLANAR_GRID_DATA_DIR) + "/karlsruhe_2010_03_09_drive_0023";
  const cv::Mat left = cv::imread(dir + "/left/I1_000010.png", cv::IMREAD_GRAYSCALE);
  const cv::Mat right = cv::imread(dir + "/right/I2_000010.png", cv::IMREAD_GRAYSCALE);
  if (left.empty() || right.empty())
    GTEST_SKIP() << "Karlsruhe data not found in " << dir;
  const auto model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::KARLSRUHE, dir + "/calib.txt");
  const auto& calib = model.calibration;
  cv::Mat disparity;
  planar_grid::DisparityEstimator().compute(left, right, disparity);
  const DepthImage image = DepthImage::fromDisparity(
    disparity.ptr<float>(0), disparity.cols, disparity.rows, disparity.step, calib);
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.1, 25.0));
  if (std::getenv("PLANAR_GRID_DEBUG"))
    pcl::console::setVerbosityLevel(pcl::console::L_DEBUG);
  const auto t0 = std::chrono::steady_clock::now();
  grid.integrateDepthImage(image, Eigen::Isometry3d::Identity());
  const double ms =
    std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t0)
      .count();
  std::printf(
    "[ info ] frame 10: %.1f ms, %zu free, %zu occupied, %zu blocks, %zu bytes\n", ms,
    grid.getVoxelCount(SpaceState::FREE), grid.getVoxelCount(SpaceState::OCCUPIED),
    grid.getBlockCount(), grid.getMemoryBytes());

  // Occupied: the distinct voxels of the valid pixels within 25 m.
  std::set<std::tuple<int, int, int>> surface;
  int free_checked = 0, free_ok = 0;
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u) {
      const float d = image.at(u, v);
      if (!(d > 0.0f) || d > 25.0f)
        continue;
      const Eigen::Vector3f pc((u - image.cx) / image.fx * d,
                               (v - image.cy) / image.fy * d, d);
      surface.insert(tup(grid.toKey(pc)));
      // lower middle of the image: the road ahead; half way to it is free
      if (v > image.height * 3 / 4 && u > image.width / 3 && u < image.width * 2 / 3
          && d > 5.0f && d < 20.0f && (u + v) % 7 == 0) {
        ++free_checked;
        free_ok +=
          grid.getState(Eigen::Vector3f(pc * 0.5f)) == SpaceState::FREE ? 1 : 0;
      }
    }
  const double ratio =
    static_cast<double>(grid.getVoxelCount(SpaceState::OCCUPIED)) / surface.size();
  EXPECT_GT(ratio, 0.95);
  EXPECT_LT(ratio, 1.05);
  EXPECT_GT(surface.size(), 20000u);
  EXPECT_GT(free_checked, 100);
  EXPECT_GE(free_ok, free_checked * 95 / 100);
  EXPECT_GT(grid.getVoxelCount(SpaceState::FREE), 500000u);
  // Everything outside the frustum (slack: one voxel's footprint) is at the prior:
  // every stored voxel's centre projects into the image within 25 m.
  std::size_t outside = 0;
  grid.forEachVoxel([&](const Key& k, SpaceState) {
    const Eigen::Vector3f c = grid.toCentre(k);
    const float slack_m = 0.0867f; // half the voxel diagonal
    if (c.z() < -slack_m || c.z() > 25.0f + slack_m) {
      ++outside;
      return;
    }
    const float z = std::max(c.z(), 0.05f);
    const float pad = image.fx * slack_m / z + 1.0f;
    const float u = image.fx * c.x() / z + image.cx,
                v = image.fy * c.y() / z + image.cy;
    if (u < -pad || v < -pad || u > image.width + pad || v > image.height + pad)
      ++outside;
  });
  EXPECT_EQ(outside, 0u);
  EXPECT_EQ(grid.getState(Eigen::Vector3f(0.0f, 0.0f, -3.0f)), SpaceState::UNKNOWN);
  EXPECT_EQ(grid.getState(Eigen::Vector3f(0.0f, -20.0f, 5.0f)), SpaceState::UNKNOWN);
}

TEST(DepthImage, FromDisparityIsFocalTimesBaselineOverDisparity)
{
  // f B = 100 px * 0.5 m = 50 px m: d = 10 px -> 5 m, 5 px -> 10 m, 20 px -> 2.5 m;
  // 0, negative and NaN disparities are no measurement. Rows padded to 4 floats.
  planar_grid::StereoCalibration calib;
  calib.focal_length_px = 100.0;
  calib.baseline_m = 0.5;
  calib.cx_px = 1.0;
  calib.cy_px = 0.5;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float disparity[8] = {0.0f, 10.0f, nan, 99.0f, 5.0f, -1.0f, 20.0f, 99.0f};
  const DepthImage image =
    DepthImage::fromDisparity(disparity, 3, 2, 4 * sizeof(float), calib);
  ASSERT_EQ(image.width, 3);
  ASSERT_EQ(image.height, 2);
  EXPECT_FLOAT_EQ(image.fx, 100.0f);
  EXPECT_FLOAT_EQ(image.cx, 1.0f);
  EXPECT_TRUE(std::isnan(image.at(0, 0)));
  EXPECT_FLOAT_EQ(image.at(1, 0), 5.0f);
  EXPECT_TRUE(std::isnan(image.at(2, 0)));
  EXPECT_FLOAT_EQ(image.at(0, 1), 10.0f);
  EXPECT_TRUE(std::isnan(image.at(1, 1)));
  EXPECT_FLOAT_EQ(image.at(2, 1), 2.5f);
  EXPECT_EQ(image.countValid(), 3u);
  EXPECT_THROW(DepthImage::fromDisparity(disparity, 3, 2, 8, calib),
               planar_grid::Exception); // stride shorter than a row
  EXPECT_THROW(DepthImage::fromDisparity(disparity, 0, 2, 16, calib),
               planar_grid::Exception);
  calib.baseline_m = 0.0;
  EXPECT_THROW(DepthImage::fromDisparity(disparity, 3, 2, 16, calib),
               planar_grid::Exception);
}

// assignFromDisparity() fills an image in place: the same depths as fromDisparity(),
// in the buffer of the previous image when the size is unchanged; an invalid input
// throws and leaves the image as it was.
TEST(DepthImage, AssignFromDisparityReusesTheImage)
{
  planar_grid::StereoCalibration calib;
  calib.focal_length_px = 100.0;
  calib.baseline_m = 0.5;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float first[6] = {10.0f, 5.0f, nan, 20.0f, 0.0f, 25.0f};
  const float second[6] = {nan, 50.0f, 2.0f, -3.0f, 10.0f, 5.0f};
  DepthImage image;
  image.assignFromDisparity(first, 3, 2, 3 * sizeof(float), calib);
  const float* buffer = image.depth_m.data();
  image.assignFromDisparity(second, 3, 2, 3 * sizeof(float), calib);
  EXPECT_EQ(image.depth_m.data(), buffer);
  const DepthImage expected =
    DepthImage::fromDisparity(second, 3, 2, 3 * sizeof(float), calib);
  ASSERT_EQ(image.depth_m.size(), expected.depth_m.size());
  for (std::size_t i = 0; i < expected.depth_m.size(); ++i)
    if (std::isnan(expected.depth_m[i]))
      EXPECT_TRUE(std::isnan(image.depth_m[i])) << i;
    else
      EXPECT_EQ(image.depth_m[i], expected.depth_m[i]) << i;
  EXPECT_THROW(image.assignFromDisparity(first, 3, 2, 8, calib),
               planar_grid::Exception);
  EXPECT_EQ(image.width, 3);
  EXPECT_EQ(image.depth_m.data(), buffer);
  EXPECT_FLOAT_EQ(image.at(1, 0), 1.0f); // f B / 50 px = 50 px m / 50 px
}

TEST(ExplicitSpaceGrid, ManyMixedBlocksRoundTrip)
{
  // 9,216 blocks, each a checkerboard of occupied and prior voxels: 512 leaves per
  // block, 4.7 million leaves in all, more than the 2^22 blocks the reader allows; the
  // limit counts blocks, not leaves, so this (real maps have such blocks) must load.
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.1, 25.0));
  for (int bx = 0; bx < 24; ++bx)
    for (int by = 0; by < 24; ++by)
      for (int bz = 0; bz < 16; ++bz)
        for (int i = 0; i < 512; i += 2) {
          const int x = i & 7, y = (i >> 3) & 7, z = i >> 6;
          grid.setState(Key(8 * bx + x + ((y + z) & 1), 8 * by + y, 8 * bz + z),
                        SpaceState::OCCUPIED);
        }
  ASSERT_EQ(grid.getBlockCount(), 24u * 24u * 16u);
  std::vector<std::uint8_t> bytes;
  grid.serialize(bytes);
  ExplicitSpaceGrid decoded(params(SpaceState::UNKNOWN, 0.1, 25.0));
  decoded.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(decoded == grid);
}

TEST(ExplicitSpaceGrid, ScanRaysMatchABruteForceSegmentOracle)
{
  // A 360 degree scan of a 6 x 4 x 3 m box room from an off-centre sensor, with a
  // 2.5 m range so that some rays end in range and others are cut: every voxel a
  // segment truly crosses (a slab test of the segment against each voxel of its
  // bounding box) before the surface margin in front of its point is FREE, every
  // point's voxel in range is OCCUPIED, and nothing else changes.
  const double res = 0.1, max_range = 2.5;
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, res, max_range));
  const Eigen::Vector3d origin(0.2317, 0.1713, 1.3129);
  const Eigen::Vector3d lo(-3.0, -2.0, 0.0), hi(3.0, 2.0, 3.0);
  pcl::PointCloud<pcl::PointXYZ> scan;
  std::mt19937 rng(5u);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  while (scan.size() < 400) {
    Eigen::Vector3d d(unit(rng), unit(rng), unit(rng));
    if (d.norm() > 1.0 || d.norm() < 0.1)
      continue;
    d.normalize();
    double t_exit = std::numeric_limits<double>::infinity(); // leaving the room
    for (int a = 0; a < 3; ++a)
      if (d[a] != 0.0)
        t_exit = std::min(t_exit, ((d[a] > 0.0 ? hi[a] : lo[a]) - origin[a]) / d[a]);
    const Eigen::Vector3d p = origin + 0.999999 * t_exit * d;
    scan.push_back(pcl::PointXYZ(static_cast<float>(p.x()), static_cast<float>(p.y()),
                                 static_cast<float>(p.z())));
  }
  scan.push_back(pcl::PointXYZ(std::nanf(""), 0.0f, 0.0f)); // skipped
  grid.integratePointCloud(scan, origin.cast<float>());

  std::set<std::tuple<int, int, int>> free_keys, occupied_keys;
  // The sensor origin as the grid receives it (single precision).
  const Eigen::Vector3d o = origin.cast<float>().cast<double>() / res;
  for (const auto& pt : scan) {
    if (!std::isfinite(pt.x))
      continue;
    const Eigen::Vector3d e = pt.getVector3fMap().cast<double>() / res;
    const double length = (e - o).norm();
    const bool hits = length <= max_range / res;
    // A hit clears up to the surface margin (half a voxel diagonal) before its point.
    const double t_end = std::min(length - std::sqrt(3.0) / 2.0, max_range / res);
    const Eigen::Vector3d d = (e - o) / length;
    const std::tuple<int, int, int> end{static_cast<int>(std::floor(e.x())),
                                        static_cast<int>(std::floor(e.y())),
                                        static_cast<int>(std::floor(e.z()))};
    if (hits)
      occupied_keys.insert(end);
    const Eigen::Vector3d a = o, b = o + t_end * d;
    const Eigen::Vector3i kmin = a.cwiseMin(b).array().floor().cast<int>();
    const Eigen::Vector3i kmax = a.cwiseMax(b).array().floor().cast<int>();
    for (int z = kmin.z(); z <= kmax.z(); ++z)
      for (int y = kmin.y(); y <= kmax.y(); ++y)
        for (int x = kmin.x(); x <= kmax.x(); ++x) {
          // Slab test: the segment's parameters inside voxel (x, y, z).
          double t0 = 0.0, t1 = t_end;
          const Eigen::Vector3d vlo(x, y, z);
          for (int k = 0; k < 3; ++k) {
            if (d[k] == 0.0)
              continue;
            double ta = (vlo[k] - o[k]) / d[k], tb = (vlo[k] + 1.0 - o[k]) / d[k];
            if (ta > tb)
              std::swap(ta, tb);
            t0 = std::max(t0, ta);
            t1 = std::min(t1, tb);
          }
          if (t1 - t0 > 1e-9 && !(hits && std::make_tuple(x, y, z) == end))
            free_keys.insert({x, y, z});
        }
  }
  ASSERT_GT(occupied_keys.size(), 50u);
  ASSERT_GT(free_keys.size(), 1000u);
  std::size_t checked_free = 0, checked_occupied = 0;
  for (int z = -2; z <= 32; ++z)
    for (int y = -22; y <= 22; ++y)
      for (int x = -32; x <= 32; ++x) {
        const auto k = std::make_tuple(x, y, z);
        SpaceState expected = SpaceState::UNKNOWN;
        if (occupied_keys.count(k)) {
          expected = SpaceState::OCCUPIED;
          ++checked_occupied;
        } else if (free_keys.count(k)) {
          expected = SpaceState::FREE;
          ++checked_free;
        }
        ASSERT_EQ(grid.getState(Key(x, y, z)), expected) << x << " " << y << " " << z;
      }
  EXPECT_EQ(checked_occupied, occupied_keys.size());
  EXPECT_EQ(checked_free + checked_occupied,
            grid.getVoxelCount(SpaceState::FREE)
              + grid.getVoxelCount(SpaceState::OCCUPIED));
  // A second scan from elsewhere: its rays cross voxels the first scan saw occupied,
  // which stay occupied (one hit outweighs one miss), while the free space it crosses
  // grows.
  const std::size_t free_before = grid.getVoxelCount(SpaceState::FREE);
  grid.integratePointCloud(scan, Eigen::Vector3f(-1.9f, 1.3f, 0.6f));
  for (const auto& k : occupied_keys)
    ASSERT_EQ(grid.getState(Key(std::get<0>(k), std::get<1>(k), std::get<2>(k))),
              SpaceState::OCCUPIED);
  EXPECT_GT(grid.getVoxelCount(SpaceState::FREE), free_before);
  EXPECT_THROW(
    grid.integratePointCloud(scan, Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f)),
    planar_grid::Exception);
}

TEST(ExplicitSpaceGrid, ExportOctoMapWholeBlocks)
{
  // Uniform blocks go to the tree as whole nodes (eight free blocks side by side, one
  // occupied block), mixed blocks voxel by voxel: read back with liboctomap, every
  // voxel has the grid's state, and the free and occupied volumes match the grid's
  // counts.
  ExplicitSpaceGrid grid(params(SpaceState::UNKNOWN, 0.2));
  std::map<std::tuple<int, int, int>, SpaceState> oracle;
  fillRandom(grid, oracle, 500, 10, 43u);
  const auto fill = [&grid](const Key& lo, const Key& hi, SpaceState s) {
    for (int z = lo.z(); z <= hi.z(); ++z)
      for (int y = lo.y(); y <= hi.y(); ++y)
        for (int x = lo.x(); x <= hi.x(); ++x)
          grid.setState(Key(x, y, z), s);
  };
  fill(Key(32, 32, 32), Key(47, 47, 47), SpaceState::FREE);     // 2 x 2 x 2 blocks
  fill(Key(64, 32, 32), Key(71, 39, 39), SpaceState::OCCUPIED); // one block
  fill(Key(-48, 32, 32), Key(-41, 39, 39), SpaceState::FREE);   // negative keys
  const auto dir = std::filesystem::temp_directory_path()
                   / ("planar_grid_blocks_" + std::to_string(::getpid()));
  std::filesystem::create_directories(dir);
  const std::string path = (dir / "space.bt").string();
  grid.exportOctoMap(path);
  octomap::OcTree tree(0.2);
  ASSERT_TRUE(tree.readBinary(path));
  std::filesystem::remove_all(dir);
  grid.forEachVoxel([&](const Key& k, SpaceState s) {
    const Eigen::Vector3f c = grid.toCentre(k);
    const octomap::OcTreeNode* node = tree.search(c.x(), c.y(), c.z());
    if (s == SpaceState::UNKNOWN) {
      ASSERT_EQ(node, nullptr);
      return;
    }
    ASSERT_NE(node, nullptr) << k.transpose();
    ASSERT_EQ(tree.isNodeOccupied(node), s == SpaceState::OCCUPIED) << k.transpose();
  });
  tree.expand();
  std::size_t free_voxels = 0, occupied_voxels = 0;
  for (auto it = tree.begin_leafs(); it != tree.end_leafs(); ++it)
    (tree.isNodeOccupied(*it) ? occupied_voxels : free_voxels) += 1;
  EXPECT_EQ(free_voxels, grid.getVoxelCount(SpaceState::FREE));
  EXPECT_EQ(occupied_voxels, grid.getVoxelCount(SpaceState::OCCUPIED));
  EXPECT_GE(free_voxels, 16u * 16u * 16u + 512u);
}
