// SPDX-License-Identifier: BSD-3-Clause
// The planner's queries of PlanarGridMap: distance with gradient, collision of bodies
// and the projection into a 2D occupancy grid. The obstacles (occupied cuboids as
// oriented boxes, obstacle voxels merged into axis-aligned boxes per block) are
// indexed by a bounding-volume hierarchy built on the first query.
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>

#include <sys/stat.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <mutex>
#include <sstream>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

namespace planar_grid {
namespace map_queries {

/** \brief One obstacle: a box of half extents \a half about \a centre along the
 * columns of \a axes (identity for voxel runs, flagged by \a aligned). */
struct ObstacleBox {
  Eigen::Matrix3f axes{Eigen::Matrix3f::Identity()};
  Eigen::Vector3f centre{Eigen::Vector3f::Zero()};
  Eigen::Vector3f half{Eigen::Vector3f::Zero()};
  bool aligned{true};

  /** \brief p in the box frame, relative to the centre. */
  Eigen::Vector3f local(const Eigen::Vector3f& p) const
  {
    const Eigen::Vector3f d = p - centre;
    return aligned ? d : Eigen::Vector3f(axes.transpose() * d);
  }
  /** \brief The world vector of a vector \a v given in the box frame. */
  Eigen::Vector3f world(const Eigen::Vector3f& v) const
  {
    return aligned ? v : Eigen::Vector3f(axes * v);
  }
  /** \brief Half extents of the axis-aligned bounding box. */
  Eigen::Vector3f aabbHalf() const
  {
    return aligned ? half : Eigen::Vector3f(axes.cwiseAbs() * half);
  }
};

/** \brief Node of the hierarchy: a leaf holds count > 0 boxes from first; an inner
 * node (count 0) has its left child next in the array and its right child at first.
 */
struct Node {
  Eigen::Vector3f lo;
  Eigen::Vector3f hi;
  std::uint32_t first{0};
  std::uint32_t count{0};
};

/** \brief The obstacles of one query mode and their hierarchy. */
struct ObstacleIndex {
  std::vector<ObstacleBox, Eigen::aligned_allocator<ObstacleBox>> boxes;
  std::vector<Node> nodes;
  /** \brief Space outside [known_lo, known_hi] is an obstacle (unknown). */
  bool outside_is_obstacle{false};
  /** \brief With outside_is_obstacle and nothing stored: everything is. */
  bool everything_is_obstacle{false};
  Eigen::Vector3f known_lo{Eigen::Vector3f::Zero()};
  Eigen::Vector3f known_hi{Eigen::Vector3f::Zero()};
};

/** \brief The lazily built indices, one per unknown_is_occupied. */
struct QueryCache {
  std::mutex mutex;
  std::array<std::atomic<bool>, 2> ready{{false, false}};
  std::array<std::unique_ptr<ObstacleIndex>, 2> index;
};

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

/** \brief Gathers the obstacles of \a map for one mode. */
std::unique_ptr<ObstacleIndex>
buildIndex(const PlanarGridMap& map,
           bool unknown_is_occupied,
           const Eigen::AlignedBox3f* keep = nullptr)
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

/** \brief Squared distance from \a p to the box [lo, hi]. */
float
aabbDistance2(const Eigen::Vector3f& p,
              const Eigen::Vector3f& lo,
              const Eigen::Vector3f& hi)
{
  const Eigen::Vector3f d = (lo - p).cwiseMax(Eigen::Vector3f::Zero()).cwiseMax(p - hi);
  return d.squaredNorm();
}

/** \brief Distance from \a p to box \a b; 0 inside with \a grad the outward normal of
 * the nearest face, else \a grad from the closest point toward \a p. */
float
boxDistance(const ObstacleBox& b, const Eigen::Vector3f& p, Eigen::Vector3f& grad)
{
  const Eigen::Vector3f q = b.local(p);
  const Eigen::Vector3f d = q.cwiseAbs() - b.half;
  if ((d.array() <= 0.0f).all()) {
    int axis = 0;
    d.maxCoeff(&axis);
    Eigen::Vector3f n = Eigen::Vector3f::Zero();
    n[axis] = q[axis] < 0.0f ? -1.0f : 1.0f;
    grad = b.world(n);
    return 0.0f;
  }
  Eigen::Vector3f e;
  for (int k = 0; k < 3; ++k)
    e[k] = d[k] > 0.0f ? std::copysign(d[k], q[k]) : 0.0f;
  const float dist = e.norm();
  grad = b.world(e / dist);
  return dist;
}

/** \brief Exact overlap (closed sets) of an oriented box A (centre, axes, half) and
 * obstacle box B: the 15 separating axes. */
bool
boxesOverlap(const Eigen::Vector3f& ca,
             const Eigen::Matrix3f& ra,
             const Eigen::Vector3f& ha,
             const ObstacleBox& b)
{
  // B's axes and centre in A's frame.
  const Eigen::Matrix3f rb = b.aligned ? Eigen::Matrix3f::Identity() : b.axes;
  const Eigen::Matrix3f R = ra.transpose() * rb;
  const Eigen::Vector3f t = ra.transpose() * (b.centre - ca);
  // A small term keeps near-parallel edge pairs (whose cross product vanishes) from
  // reporting a separation that rounding made up.
  const Eigen::Matrix3f absR = R.cwiseAbs().array() + 1e-6f;
  const Eigen::Vector3f& hb = b.half;
  for (int i = 0; i < 3; ++i)
    if (std::abs(t[i]) > ha[i] + absR.row(i).dot(hb))
      return false;
  for (int j = 0; j < 3; ++j)
    if (std::abs(t.dot(R.col(j))) > absR.col(j).dot(ha) + hb[j])
      return false;
  for (int i = 0; i < 3; ++i) {
    const int i1 = (i + 1) % 3, i2 = (i + 2) % 3;
    for (int j = 0; j < 3; ++j) {
      const int j1 = (j + 1) % 3, j2 = (j + 2) % 3;
      const float ra_ = ha[i1] * absR(i2, j) + ha[i2] * absR(i1, j);
      const float rb_ = hb[j1] * absR(i, j2) + hb[j2] * absR(i, j1);
      if (std::abs(t[i2] * R(i1, j) - t[i1] * R(i2, j)) > ra_ + rb_)
        return false;
    }
  }
  return true;
}

/** \brief Distance and gradient at one point (finite), capped at \a cap. */
float
queryPoint(const ObstacleIndex& index,
           const Eigen::Vector3f& p,
           float cap,
           Eigen::Vector3f& grad)
{
  grad.setZero();
  if (index.everything_is_obstacle) {
    grad = Eigen::Vector3f::UnitZ();
    return 0.0f;
  }
  float best = cap;
  if (index.outside_is_obstacle) {
    const Eigen::Vector3f below = p - index.known_lo, above = index.known_hi - p;
    if ((below.array() < 0.0f).any() || (above.array() < 0.0f).any()) {
      // Outside the stored bounds: inside the unknown; the way out is toward them.
      const Eigen::Vector3f in =
        p.cwiseMax(index.known_lo).cwiseMin(index.known_hi) - p;
      grad = in / in.norm();
      return 0.0f;
    }
    int a = 0, c = 0;
    const float from_lo = below.minCoeff(&a), from_hi = above.minCoeff(&c);
    if (std::min(from_lo, from_hi) < best) {
      grad.setZero();
      if (from_lo <= from_hi) {
        best = from_lo;
        grad[a] = 1.0f;
      } else {
        best = from_hi;
        grad[c] = -1.0f;
      }
    }
  }
  if (index.nodes.empty())
    return best;
  float best2 = best * best;
  std::array<std::uint32_t, 128> stack;
  std::size_t top = 0;
  if (aabbDistance2(p, index.nodes[0].lo, index.nodes[0].hi) >= best2)
    return best;
  stack[top++] = 0;
  Eigen::Vector3f g;
  while (top > 0) {
    const Node& node = index.nodes[stack[--top]];
    if (aabbDistance2(p, node.lo, node.hi) >= best2)
      continue;
    if (node.count > 0) {
      for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
        const float d = boxDistance(index.boxes[k], p, g);
        if (d == 0.0f) {
          grad = g;
          return 0.0f;
        }
        if (d < best) {
          best = d;
          best2 = d * d;
          grad = g;
        }
      }
      continue;
    }
    const std::uint32_t left =
      static_cast<std::uint32_t>(&node - index.nodes.data()) + 1;
    const std::uint32_t right = node.first;
    const float dl = aabbDistance2(p, index.nodes[left].lo, index.nodes[left].hi);
    const float dr = aabbDistance2(p, index.nodes[right].lo, index.nodes[right].hi);
    // The nearer child is popped first.
    if (dl <= dr) {
      if (dr < best2)
        stack[top++] = right;
      if (dl < best2)
        stack[top++] = left;
    } else {
      if (dl < best2)
        stack[top++] = left;
      if (dr < best2)
        stack[top++] = right;
    }
  }
  return best;
}

/** \brief True when the body meets an obstacle of the index. */
bool
bodyCollides(const ObstacleIndex& index, const CollisionBody& body)
{
  if (index.everything_is_obstacle)
    return true;
  const bool is_box = body.shape == CollisionBody::Shape::BOX;
  const Eigen::Vector3f h =
    is_box ? Eigen::Vector3f(body.rotation.cwiseAbs() * body.half_extents)
           : Eigen::Vector3f::Constant(body.radius_m);
  const Eigen::Vector3f lo = body.centre - h, hi = body.centre + h;
  if (index.outside_is_obstacle
      && ((lo.array() < index.known_lo.array()).any()
          || (hi.array() > index.known_hi.array()).any()))
    return true;
  if (index.nodes.empty())
    return false;
  const float r2 = body.radius_m * body.radius_m;
  std::array<std::uint32_t, 128> stack;
  std::size_t top = 0;
  stack[top++] = 0;
  Eigen::Vector3f g;
  while (top > 0) {
    const std::uint32_t id = stack[--top];
    const Node& node = index.nodes[id];
    if ((node.lo.array() > hi.array()).any() || (node.hi.array() < lo.array()).any())
      continue;
    if (!is_box && aabbDistance2(body.centre, node.lo, node.hi) > r2)
      continue;
    if (node.count == 0) {
      stack[top++] = node.first;
      stack[top++] = id + 1;
      continue;
    }
    for (std::uint32_t k = node.first; k < node.first + node.count; ++k) {
      const ObstacleBox& b = index.boxes[k];
      if (is_box) {
        if (boxesOverlap(body.centre, body.rotation, body.half_extents, b))
          return true;
      } else if (boxDistance(b, body.centre, g) <= body.radius_m)
        return true;
    }
  }
  return false;
}

} // namespace

/** \brief Distances of the points at the index (NaN for non-finite points and, with
 * \a region, points outside it). */
void
distancesOf(const ObstacleIndex& index,
            const Eigen::Ref<const Eigen::Matrix3Xf>& points,
            float cap,
            Eigen::Ref<Eigen::VectorXf> distances,
            Eigen::Ref<Eigen::Matrix3Xf> gradients,
            const Eigen::AlignedBox3f* region)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3f p = points.col(i);
    if (!p.allFinite() || (region != nullptr && !region->contains(p))) {
      distances[i] = nan;
      gradients.col(i).setConstant(nan);
      continue;
    }
    Eigen::Vector3f g;
    distances[i] = queryPoint(index, p, cap, g);
    gradients.col(i) = g;
  }
}

/** \brief Free (1) or not (0) per body; with \a region, bodies whose bounding box
 * leaves it are not free. */
std::vector<std::uint8_t>
collisionsOf(const ObstacleIndex& index,
             const CollisionBodies& bodies,
             const Eigen::AlignedBox3f* region)
{
  std::vector<std::uint8_t> free(bodies.size(), 0);
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const CollisionBody& b = bodies[i];
    const bool is_box = b.shape == CollisionBody::Shape::BOX;
    const bool valid = b.centre.allFinite()
                       && (is_box ? b.rotation.allFinite() && b.half_extents.allFinite()
                                      && (b.half_extents.array() >= 0.0f).all()
                                  : std::isfinite(b.radius_m) && b.radius_m >= 0.0f);
    if (!valid)
      continue;
    if (region != nullptr) {
      const Eigen::Vector3f h =
        is_box ? Eigen::Vector3f(b.rotation.cwiseAbs() * b.half_extents)
               : Eigen::Vector3f::Constant(b.radius_m);
      if (!region->contains(b.centre - h) || !region->contains(b.centre + h))
        continue;
    }
    free[i] = bodyCollides(index, b) ? 0 : 1;
  }
  return free;
}

void
checkSizes(const char* what,
           Eigen::Index points,
           Eigen::Index distances,
           Eigen::Index gradients)
{
  if (distances != points || gradients != points)
    throw Exception(std::string(what) + ": " + std::to_string(points)
                    + " points but room for " + std::to_string(distances)
                    + " distances and " + std::to_string(gradients) + " gradients");
}

const ObstacleIndex&
getIndex(const std::shared_ptr<QueryCache>& cache,
         const PlanarGridMap& map,
         bool unknown_is_occupied)
{
  if (!cache)
    throw Exception("PlanarGridMap: query on a moved-from map");
  const std::size_t mode = unknown_is_occupied ? 1 : 0;
  if (!cache->ready[mode].load(std::memory_order_acquire)) {
    std::lock_guard<std::mutex> lock(cache->mutex);
    if (!cache->index[mode]) {
      cache->index[mode] = buildIndex(map, unknown_is_occupied);
      cache->ready[mode].store(true, std::memory_order_release);
    }
  }
  return *cache->index[mode];
}

} // namespace map_queries

void
PlanarGridMap::invalidateQueryCache()
{
  query_cache_ = std::make_shared<map_queries::QueryCache>();
}

void
PlanarGridMap::getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                           double max_distance_m,
                           Eigen::Ref<Eigen::VectorXf> distances,
                           Eigen::Ref<Eigen::Matrix3Xf> gradients,
                           bool unknown_is_occupied) const
{
  if (!(max_distance_m > 0.0) || !std::isfinite(max_distance_m))
    throw Exception(
      "PlanarGridMap::getDistance: max_distance_m must be finite and > 0, "
      "got "
      + std::to_string(max_distance_m));
  map_queries::checkSizes("PlanarGridMap::getDistance", points.cols(), distances.size(),
                          gradients.cols());
  const auto& index = map_queries::getIndex(query_cache_, *this, unknown_is_occupied);
  map_queries::distancesOf(index, points, static_cast<float>(max_distance_m), distances,
                           gradients, nullptr);
}

std::vector<std::uint8_t>
PlanarGridMap::isCollisionFree(const CollisionBodies& bodies,
                               bool unknown_is_occupied) const
{
  const auto& index = map_queries::getIndex(query_cache_, *this, unknown_is_occupied);
  return map_queries::collisionsOf(index, bodies, nullptr);
}

MapRegionIndex::MapRegionIndex(const PlanarGridMap& map,
                               const Eigen::Vector3f& min_m,
                               const Eigen::Vector3f& max_m,
                               double max_distance_m,
                               bool unknown_is_occupied) :
    min_(min_m),
    max_(max_m), max_distance_m_(static_cast<float>(max_distance_m))
{
  if (!min_m.allFinite() || !max_m.allFinite()
      || !(max_m.array() > min_m.array()).all())
    throw Exception("MapRegionIndex: the region needs finite corners min_m < max_m");
  if (!(max_distance_m > 0.0) || !std::isfinite(max_distance_m))
    throw Exception("MapRegionIndex: max_distance_m must be finite and > 0, got "
                    + std::to_string(max_distance_m));
  const Eigen::AlignedBox3f keep(min_m - Eigen::Vector3f::Constant(max_distance_m_),
                                 max_m + Eigen::Vector3f::Constant(max_distance_m_));
  index_ = map_queries::buildIndex(map, unknown_is_occupied, &keep);
}

MapRegionIndex::~MapRegionIndex() = default;
MapRegionIndex::MapRegionIndex(MapRegionIndex&&) noexcept = default;
MapRegionIndex& MapRegionIndex::operator=(MapRegionIndex&&) noexcept = default;

void
MapRegionIndex::getDistance(const Eigen::Ref<const Eigen::Matrix3Xf>& points,
                            Eigen::Ref<Eigen::VectorXf> distances,
                            Eigen::Ref<Eigen::Matrix3Xf> gradients) const
{
  map_queries::checkSizes("MapRegionIndex::getDistance", points.cols(),
                          distances.size(), gradients.cols());
  const Eigen::AlignedBox3f region(min_, max_);
  map_queries::distancesOf(*index_, points, max_distance_m_, distances, gradients,
                           &region);
}

std::vector<std::uint8_t>
MapRegionIndex::isCollisionFree(const CollisionBodies& bodies) const
{
  const Eigen::AlignedBox3f grown(min_ - Eigen::Vector3f::Constant(max_distance_m_),
                                  max_ + Eigen::Vector3f::Constant(max_distance_m_));
  return map_queries::collisionsOf(*index_, bodies, &grown);
}

std::size_t
MapRegionIndex::getObstacleCount() const
{
  return index_->boxes.size();
}

} // namespace planar_grid
