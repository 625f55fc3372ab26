// SPDX-License-Identifier: BSD-3-Clause
// The building of the obstacle index of the planner's queries (map_queries.cpp): the
// map's occupied cuboids as oriented boxes, its obstacle voxels merged into
// axis-aligned boxes per block, and the bounding-volume hierarchy over them.
#include "map_queries_index.h"

#include <planar_grid/map/planar_grid_map.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <unordered_map>
#include <utility>
#include <vector>

namespace planar_grid {
namespace map_queries {

namespace {

constexpr int BLOCK = 8;
using Mask = std::array<std::uint64_t, 8>; // bit (x + 8 y) of word z

std::int64_t
packBlock(int bx, int by, int bz)
{
  return (static_cast<std::int64_t>(bx + (1 << 20)) << 42)
         | (static_cast<std::int64_t>(by + (1 << 20)) << 21)
         | static_cast<std::int64_t>(bz + (1 << 20));
}

void
unpackBlock(std::int64_t key, int& bx, int& by, int& bz)
{
  bx = static_cast<int>((key >> 42) & 0x1FFFFF) - (1 << 20);
  by = static_cast<int>((key >> 21) & 0x1FFFFF) - (1 << 20);
  bz = static_cast<int>(key & 0x1FFFFF) - (1 << 20);
}

/** \brief Floor division by the block edge (keys may be negative). */
int
blockOf(int k)
{
  return k >= 0 ? k / BLOCK : -((-k + BLOCK - 1) / BLOCK);
}

/** \brief Appends the box of voxels [b[0], b[1]) x [b[2], b[3]) x [b[4], b[5])
 * (voxel keys) of edge \a r. */
void
addVoxelBox(ObstacleIndex& index, double r, const std::array<int, 6>& b)
{
  const Eigen::Vector3d lo(b[0] * r, b[2] * r, b[4] * r);
  const Eigen::Vector3d hi(b[1] * r, b[3] * r, b[5] * r);
  ObstacleBox box;
  box.centre = (0.5 * (lo + hi)).cast<float>();
  box.half = (0.5 * (hi - lo)).cast<float>();
  index.boxes.push_back(box);
}

/** \brief Covers the obstacle voxels \a m of block (bx, by, bz) with boxes: runs along
 * x, runs of equal runs in consecutive rows merged into rectangles, equal rectangles
 * in consecutive layers into boxes. The union is the voxels' exactly. */
void
addBlockBoxes(ObstacleIndex& index, double r, const Mask& m, int bx, int by, int bz)
{
  // Boxes in block-local voxel keys, still growing along z: x0, x1, y0, y1, z0, z1.
  std::vector<std::array<int, 6>> open, next, layer;
  for (int z = 0; z <= BLOCK; ++z) {
    // This layer's rectangles (none past the last layer).
    layer.clear();
    if (z < BLOCK) {
      std::vector<std::array<int, 6>> rows; // rectangles growing along y
      for (int y = 0; y <= BLOCK; ++y) {
        std::vector<std::array<int, 6>> grown;
        if (y < BLOCK) {
          const auto row = static_cast<unsigned>(
            (m[static_cast<std::size_t>(z)] >> (BLOCK * y)) & 0xFFu);
          int x = 0;
          while (x < BLOCK) {
            if (!(row & (1u << x))) {
              ++x;
              continue;
            }
            int e = x;
            while (e < BLOCK && (row & (1u << e)))
              ++e;
            auto it = std::find_if(rows.begin(), rows.end(), [&](const auto& q) {
              return q[0] == x && q[1] == e && q[3] == y;
            });
            if (it != rows.end()) {
              (*it)[3] = y + 1;
              grown.push_back(*it);
              rows.erase(it);
            } else {
              grown.push_back({x, e, y, y + 1, z, z + 1});
            }
            x = e;
          }
        }
        layer.insert(layer.end(), rows.begin(), rows.end()); // closed rectangles
        rows.swap(grown);
      }
    }
    next.clear();
    for (const auto& q : layer) {
      auto it = std::find_if(open.begin(), open.end(), [&](const auto& o) {
        return o[0] == q[0] && o[1] == q[1] && o[2] == q[2] && o[3] == q[3];
      });
      if (it != open.end()) {
        (*it)[5] = z + 1;
        next.push_back(*it);
        open.erase(it);
      } else {
        next.push_back(q);
      }
    }
    for (const auto& o : open) // not continued in this layer: done
      addVoxelBox(index, r,
                  {bx * BLOCK + o[0], bx * BLOCK + o[1], by * BLOCK + o[2],
                   by * BLOCK + o[3], bz * BLOCK + o[4], bz * BLOCK + o[5]});
    open.swap(next);
  }
}

std::uint32_t
buildNodes(ObstacleIndex& index,
           std::vector<std::uint32_t>& order,
           const std::vector<Eigen::Vector3f,
                             Eigen::aligned_allocator<Eigen::Vector3f>>& centres,
           std::uint32_t begin,
           std::uint32_t end)
{
  const auto id = static_cast<std::uint32_t>(index.nodes.size());
  index.nodes.emplace_back();
  Eigen::Vector3f lo = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  Eigen::Vector3f hi = -lo;
  Eigen::Vector3f clo = lo, chi = hi;
  for (std::uint32_t i = begin; i < end; ++i) {
    const ObstacleBox& b = index.boxes[order[i]];
    const Eigen::Vector3f h = b.aabbHalf();
    lo = lo.cwiseMin(b.centre - h);
    hi = hi.cwiseMax(b.centre + h);
    clo = clo.cwiseMin(centres[order[i]]);
    chi = chi.cwiseMax(centres[order[i]]);
  }
  index.nodes[id].lo = lo;
  index.nodes[id].hi = hi;
  if (end - begin <= 4) {
    index.nodes[id].first = begin;
    index.nodes[id].count = end - begin;
    return id;
  }
  int axis = 0;
  (chi - clo).maxCoeff(&axis);
  const std::uint32_t mid = begin + (end - begin) / 2;
  std::nth_element(order.begin() + begin, order.begin() + mid, order.begin() + end,
                   [&](std::uint32_t a, std::uint32_t b) {
                     return centres[a][axis] < centres[b][axis];
                   });
  buildNodes(index, order, centres, begin, mid);
  const std::uint32_t right = buildNodes(index, order, centres, mid, end);
  index.nodes[id].first = right;
  index.nodes[id].count = 0;
  return id;
}

/** \brief Orders the boxes as the leaves list them and builds the hierarchy. */
void
buildHierarchy(ObstacleIndex& index)
{
  index.nodes.clear();
  if (index.boxes.empty())
    return;
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> centres;
  centres.reserve(index.boxes.size());
  for (const auto& b : index.boxes)
    centres.push_back(b.centre);
  std::vector<std::uint32_t> order(index.boxes.size());
  for (std::uint32_t i = 0; i < order.size(); ++i)
    order[i] = i;
  index.nodes.reserve(2 * index.boxes.size() / 3 + 1);
  buildNodes(index, order, centres, 0, static_cast<std::uint32_t>(order.size()));
  std::vector<ObstacleBox, Eigen::aligned_allocator<ObstacleBox>> sorted;
  sorted.reserve(order.size());
  for (const std::uint32_t i : order)
    sorted.push_back(index.boxes[i]);
  index.boxes.swap(sorted);
}

/** \brief The map's occupied cuboids as obstacle boxes; with \a keep, only those
 * whose bounding box meets it. */
void
addCuboidObstacles(const PlanarGridMap& map,
                   const Eigen::AlignedBox3f* keep,
                   ObstacleIndex& index)
{
  const auto thres =
    static_cast<float>(map.getSurfaceLayer().getParams().occupancy_thres);
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids()) {
    if (!(c.probability >= thres))
      continue;
    ObstacleBox b;
    b.axes.col(0) = c.horizontal_axis;
    b.axes.col(1) = c.verticalAxis();
    b.axes.col(2) = c.normal;
    b.centre = c.centre;
    b.half = 0.5f * Eigen::Vector3f(c.width_m, c.height_m, c.thickness_m);
    b.aligned = false;
    if (keep != nullptr) {
      const Eigen::Vector3f h = b.aabbHalf();
      if (((b.centre + h).array() < keep->min().array()).any()
          || ((b.centre - h).array() > keep->max().array()).any())
        continue;
    }
    index.boxes.push_back(b);
  }
}

/** \brief The voxels' obstacle masks per block (and, to complement the unknown
 * space, the observed voxels' masks), within the blocks [keep_lo, keep_hi]. */
struct VoxelMasks {
  std::unordered_map<std::int64_t, Mask> obstacle, known;
};

/** \brief Marks the voxels that are obstacles, and the observed ones when
 * \a complement (the unknown space is then what was not observed). Only the states
 * that matter are visited: whole blocks of free space are skipped unless the free
 * voxels are needed. */
VoxelMasks
voxelMasks(const ExplicitSpaceGrid& space,
           bool unknown_is_occupied,
           bool complement,
           const Eigen::Vector3i& keep_lo,
           const Eigen::Vector3i& keep_hi)
{
  VoxelMasks masks;
  // The voxels come block by block: the masks of the current block are looked up once.
  std::int64_t last_key = std::numeric_limits<std::int64_t>::min();
  Mask* last_known = nullptr;
  Mask* last_obstacle = nullptr;
  const auto mark = [&](const ExplicitSpaceGrid::VoxelKey& k, bool is_obstacle) {
    const int bx = blockOf(k.x()), by = blockOf(k.y()), bz = blockOf(k.z());
    if (bx < keep_lo.x() || by < keep_lo.y() || bz < keep_lo.z() || bx > keep_hi.x()
        || by > keep_hi.y() || bz > keep_hi.z())
      return;
    const int lx = k.x() - bx * BLOCK, ly = k.y() - by * BLOCK, lz = k.z() - bz * BLOCK;
    const std::uint64_t bit = std::uint64_t{1} << (lx + BLOCK * ly);
    const std::int64_t key = packBlock(bx, by, bz);
    if (key != last_key) {
      last_key = key;
      last_obstacle = &masks.obstacle[key];
      last_known = complement ? &masks.known[key] : nullptr;
    }
    if (complement)
      (*last_known)[static_cast<std::size_t>(lz)] |= bit;
    if (is_obstacle)
      (*last_obstacle)[static_cast<std::size_t>(lz)] |= bit;
  };
  space.forEachVoxelIn(SpaceState::OCCUPIED,
                       [&](const ExplicitSpaceGrid::VoxelKey& k) { mark(k, true); });
  if (complement)
    space.forEachVoxelIn(SpaceState::FREE,
                         [&](const ExplicitSpaceGrid::VoxelKey& k) { mark(k, false); });
  else if (unknown_is_occupied)
    space.forEachVoxelIn(SpaceState::UNKNOWN,
                         [&](const ExplicitSpaceGrid::VoxelKey& k) { mark(k, true); });
  return masks;
}

/** \brief With the unknown prior, every block inside the stored bounds: the voxels
 * never observed are obstacles (never-observed blocks whole ones), and so is the whole
 * outside. False when nothing was observed (everything is an obstacle). */
bool
complementUnknown(const ExplicitSpaceGrid& space,
                  double r,
                  const Eigen::Vector3i& keep_lo,
                  const Eigen::Vector3i& keep_hi,
                  VoxelMasks& masks,
                  ObstacleIndex& index)
{
  ExplicitSpaceGrid::VoxelKey lo, hi;
  index.outside_is_obstacle = true;
  if (!space.getBounds(lo, hi)) {
    index.everything_is_obstacle = true;
    return false;
  }
  index.known_lo = (lo.cast<double>() * r).cast<float>();
  index.known_hi = ((hi.cast<double>() + Eigen::Vector3d::Ones()) * r).cast<float>();
  for (int bz = std::max(blockOf(lo.z()), keep_lo.z());
       bz <= std::min(blockOf(hi.z()), keep_hi.z()); ++bz)
    for (int by = std::max(blockOf(lo.y()), keep_lo.y());
         by <= std::min(blockOf(hi.y()), keep_hi.y()); ++by)
      for (int bx = std::max(blockOf(lo.x()), keep_lo.x());
           bx <= std::min(blockOf(hi.x()), keep_hi.x()); ++bx) {
        const std::int64_t key = packBlock(bx, by, bz);
        auto& m = masks.obstacle[key];
        const auto it = masks.known.find(key);
        for (std::size_t z = 0; z < 8; ++z)
          m[z] |= it == masks.known.end() ? ~std::uint64_t{0} : ~it->second[z];
      }
  return true;
}

/** \brief The obstacle voxels as boxes: whole blocks along x become one box; other
 * blocks give one box per run of obstacle voxels along x in each row. */
void
addVoxelObstacles(std::unordered_map<std::int64_t, Mask>& obstacle,
                  double r,
                  ObstacleIndex& index)
{
  std::vector<std::int64_t> blocks;
  index.boxes.reserve(index.boxes.size() + 8 * obstacle.size());
  blocks.reserve(obstacle.size());
  for (const auto& kv : obstacle)
    blocks.push_back(kv.first);
  // Sorted by (z, y, x) so that runs of whole blocks along x merge.
  std::sort(blocks.begin(), blocks.end(), [](std::int64_t a, std::int64_t b) {
    int ax, ay, az, bx, by, bz;
    unpackBlock(a, ax, ay, az);
    unpackBlock(b, bx, by, bz);
    return std::make_tuple(az, ay, ax) < std::make_tuple(bz, by, bx);
  });
  const auto isFull = [](const Mask& m) {
    return std::all_of(m.begin(), m.end(),
                       [](std::uint64_t w) { return w == ~std::uint64_t{0}; });
  };
  std::size_t i = 0;
  while (i < blocks.size()) {
    int bx, by, bz;
    unpackBlock(blocks[i], bx, by, bz);
    const Mask& m = obstacle[blocks[i]];
    if (!isFull(m)) {
      addBlockBoxes(index, r, m, bx, by, bz);
      ++i;
      continue;
    }
    std::size_t j = i + 1;
    int last = bx;
    while (j < blocks.size()) {
      int nx, ny, nz;
      unpackBlock(blocks[j], nx, ny, nz);
      if (ny != by || nz != bz || nx != last + 1 || !isFull(obstacle[blocks[j]]))
        break;
      last = nx;
      ++j;
    }
    ObstacleBox b;
    const Eigen::Vector3d lo(bx * BLOCK * r, by * BLOCK * r, bz * BLOCK * r);
    const Eigen::Vector3d hi((last + 1) * BLOCK * r, (by + 1) * BLOCK * r,
                             (bz + 1) * BLOCK * r);
    b.centre = (0.5 * (lo + hi)).cast<float>();
    b.half = (0.5 * (hi - lo)).cast<float>();
    index.boxes.push_back(b);
    i = j;
  }
}

} // namespace

/** \brief Gathers the obstacles of \a map for one mode. */
std::unique_ptr<ObstacleIndex>
buildIndex(const PlanarGridMap& map,
           bool unknown_is_occupied,
           const Eigen::AlignedBox3f* keep)
{
  auto index = std::make_unique<ObstacleIndex>();
  // With keep, the obstacles whose bounding box misses it are left out, voxels by
  // whole blocks (block keys [keep_lo, keep_hi]).
  Eigen::Vector3i keep_lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  Eigen::Vector3i keep_hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  const double r = map.getResolution();
  if (keep != nullptr)
    for (int k = 0; k < 3; ++k) {
      keep_lo[k] = blockOf(static_cast<int>(std::floor(keep->min()[k] / r)));
      keep_hi[k] = blockOf(static_cast<int>(std::floor(keep->max()[k] / r)));
    }
  addCuboidObstacles(map, keep, *index);
  const ExplicitSpaceGrid& space = map.getSpaceLayer();
  const bool unknown_prior = space.getParams().prior == SpaceState::UNKNOWN;
  // With the unknown prior, unknown space is everything not observed: the complement
  // of the observed free and occupied voxels (inside the stored bounds; beyond them
  // the whole outside). With the free prior it is the occluded voxels stored.
  const bool complement = unknown_is_occupied && unknown_prior;
  VoxelMasks masks =
    voxelMasks(space, unknown_is_occupied, complement, keep_lo, keep_hi);
  if (complement && !complementUnknown(space, r, keep_lo, keep_hi, masks, *index))
    return index;
  addVoxelObstacles(masks.obstacle, r, *index);
  buildHierarchy(*index);
  return index;
}

} // namespace map_queries
} // namespace planar_grid
