// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <pcl/console/print.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <thread>
#include <unordered_map>
#include <utility>

#include "octomap_writer.h"

namespace planar_grid {

namespace {

/** \brief Edge of a block, voxels. */
constexpr int BLOCK_EDGE = 8;
/** \brief log2(BLOCK_EDGE). */
constexpr int BLOCK_SHIFT = 3;
/** \brief Voxels per block. */
constexpr int BLOCK_VOXELS = 512;
/** \brief 2-bit code of a voxel never observed where the prior is free: it reads as
 * free but is not free space that a view saw (codes 0-2 are the SpaceState values).
 * With the unknown prior, never observed and occluded are one state, code 2. */
constexpr std::uint8_t NEVER_OBSERVED = 3;
/** \brief The "uniform code" of a block whose voxels are not all in one state. */
constexpr std::uint8_t MIXED = 4;
/** \brief Label of an inner octree node in the bit stream (versions 1 and 2), the
 * escape label in version 3. */
constexpr std::uint8_t INNER_LABEL = 3;
/** \brief Version 3: the label after the escape label of an inner node. */
constexpr std::uint8_t ESCAPED_INNER = 3;
/** \brief Version 3: the label after the escape label of a never-observed leaf. */
constexpr std::uint8_t ESCAPED_NEVER_OBSERVED = 0;
/** \brief Bytes of the bit stream header: root key (3 x int32), depth (uint8), prior
 * (uint8), label count (uint64), little-endian. */
constexpr std::size_t HEADER_BYTES = 22;
/** \brief Deepest octree the bit stream may describe (root edge 2^21 voxels). */
constexpr int MAX_DEPTH = 21;
/** \brief Most blocks a decoded stream may create (2^22 blocks = 2^31 voxels); larger
 * non-prior leaves are rejected as corrupt before anything is allocated. */
constexpr std::uint64_t MAX_DECODED_BLOCKS = std::uint64_t{1} << 22;
/** \brief Largest |voxel key| handled, so that block arithmetic never overflows. */
constexpr double MAX_KEY = 1073741824.0; // 2^30
/** \brief Nearest camera depth considered, meters (avoids the projection pole). */
constexpr float NEAR_Z = 1e-3f;

/** \brief A 64-bit word holding 32 copies of the 2-bit code \a s. */
constexpr std::uint64_t
pattern(std::uint8_t s)
{
  return static_cast<std::uint64_t>(s) * 0x5555555555555555ULL;
}

/** \brief The code stored for a voxel never observed: NEVER_OBSERVED with the free
 * prior, so that observed free space stays apart from it; UNKNOWN with the unknown
 * prior, where an occluded voxel and one never observed are the same state. */
constexpr std::uint8_t
priorCode(SpaceState prior)
{
  return prior == SpaceState::FREE ? NEVER_OBSERVED
                                   : static_cast<std::uint8_t>(SpaceState::UNKNOWN);
}

/** \brief The state a stored code reads as. */
constexpr SpaceState
stateOf(std::uint8_t code, SpaceState prior)
{
  return code == NEVER_OBSERVED ? prior : static_cast<SpaceState>(code);
}

/** \brief Block coordinates: floor(voxel key / 8). */
struct BlockKey {
  int x, y, z;
  bool operator==(const BlockKey& o) const { return x == o.x && y == o.y && z == o.z; }
  bool operator<(const BlockKey& o) const
  {
    if (z != o.z)
      return z < o.z;
    if (y != o.y)
      return y < o.y;
    return x < o.x;
  }
};

struct BlockKeyHash {
  std::size_t operator()(const BlockKey& k) const noexcept
  {
    const auto h = static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.x))
                     * 0x9E3779B97F4A7C15ULL
                   ^ static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.y))
                       * 0xC2B2AE3D27D4EB4FULL
                   ^ static_cast<std::uint64_t>(static_cast<std::uint32_t>(k.z))
                       * 0x165667B19E3779F9ULL;
    return static_cast<std::size_t>(h ^ (h >> 29));
  }
};

/** \brief 512 voxels x 2 bits; voxel i = x + 8 y + 64 z sits at bits 2 (i % 32) of
 * word i / 32. */
using Payload = std::array<std::uint64_t, 16>;

/** \brief Voxels of each code in a payload. */
std::array<std::size_t, 4>
countCodes(const Payload& p)
{
  std::array<std::size_t, 4> n{};
  constexpr std::uint64_t LOW = 0x5555555555555555ULL;
  for (const auto w : p) {
    const std::uint64_t lo = w & LOW, hi = (w >> 1) & LOW;
    n[0] += static_cast<std::size_t>(__builtin_popcountll(~(lo | hi) & LOW));
    n[1] += static_cast<std::size_t>(__builtin_popcountll(lo & ~hi));
    n[2] += static_cast<std::size_t>(__builtin_popcountll(hi & ~lo));
    n[3] += static_cast<std::size_t>(__builtin_popcountll(lo & hi));
  }
  return n;
}

/** \brief True when the 2-bit codes of \a p are all equal; \a code is set to the
 * first. */
bool
isUniform(const Payload& p, std::uint8_t& code)
{
  const std::uint64_t w0 = p[0];
  code = static_cast<std::uint8_t>(w0 & 3u);
  if (w0 != pattern(code))
    return false;
  for (const auto w : p)
    if (w != w0)
      return false;
  return true;
}

/** \brief One block decoded: a uniform state, or MIXED with every voxel's code. */
struct DenseBlock {
  std::uint8_t uniform{MIXED};
  Payload bits{};

  std::uint8_t get(int i) const
  {
    if (uniform != MIXED)
      return uniform;
    return static_cast<std::uint8_t>(
      (bits[static_cast<std::size_t>(i >> 5)] >> ((i & 31) * 2)) & 3u);
  }
};

// Compact form of a mixed block, a fixed two-level octree below the block:
//   byte 0     mask of the mixed 4^3 cubes (bit c: the cube at (4 (c & 1),
//              4 ((c >> 1) & 1), 4 (c >> 2)))
//   bytes 1-2  the 2-bit code of each uniform cube (bits 2 c; 0 for a mixed cube)
//   3 bytes per mixed cube, in cube order: mask of its mixed 2^3 cells (bit d: the
//              cell at offset (2 (d & 1), 2 ((d >> 1) & 1), 2 (d >> 2)) in the cube),
//              then the 2-bit codes of its uniform cells (bits 2 d; 0 when mixed)
//   2 bytes per mixed cell, in cube then cell order: the codes of its 8 voxels
//              (voxel (x, y, z) of the cell at bits 2 (x + 2 y + 4 z))
// The encoding of a payload is unique, so equal blocks have equal bytes.

/** \brief Largest compact block: 3 + 8 x 3 + 64 x 2 bytes. */
constexpr std::size_t MAX_COMPACT_BYTES = 155;

/** \brief 16 bits holding 8 copies of the 2-bit code \a s. */
constexpr std::uint32_t
cellPattern(std::uint32_t s)
{
  return s * 0x5555u;
}

/** \brief Local voxel index of the corner of cell d of cube c. */
constexpr int
cellOrigin(int c, int d)
{
  return (4 * (c & 1) + 2 * (d & 1)) + 8 * (4 * ((c >> 1) & 1) + 2 * ((d >> 1) & 1))
         + 64 * (4 * (c >> 2) + 2 * (d >> 2));
}

/** \brief The 8 codes of the 2^3 cell whose corner voxel is \a i0 (x of i0 even): two
 * voxels of a row are 4 consecutive bits of one word. */
inline std::uint32_t
cellValue(const Payload& p, int i0)
{
  std::uint32_t v = 0;
  for (int k = 0; k < 4; ++k) { // k = dy + 2 dz
    const int i = i0 + 8 * (k & 1) + 64 * (k >> 1);
    v |= static_cast<std::uint32_t>(
           (p[static_cast<std::size_t>(i >> 5)] >> (2 * (i & 31))) & 15u)
         << (4 * k);
  }
  return v;
}

/** \brief Writes the 8 codes \a v of the cell with corner voxel \a i0 into a zeroed
 * region of \a p. */
inline void
putCell(Payload& p, int i0, std::uint32_t v)
{
  for (int k = 0; k < 4; ++k) {
    const int i = i0 + 8 * (k & 1) + 64 * (k >> 1);
    p[static_cast<std::size_t>(i >> 5)] |=
      static_cast<std::uint64_t>((v >> (4 * k)) & 15u) << (2 * (i & 31));
  }
}

/** \brief The little-endian 16-bit word at \a b (the compact form's code words). */
inline unsigned
load16(const std::uint8_t* b)
{
  return static_cast<unsigned>(b[0]) | (static_cast<unsigned>(b[1]) << 8);
}

/** \brief Walks the compact block at \a data in cube and cell order: \a uniform(c, d,
 * code, voxels) for a uniform cube (d = -1, 64 voxels) or a uniform cell of a mixed
 * cube (8 voxels), \a mixed(c, d, v) for a mixed cell with its 8 codes \a v. */
template <typename Uniform, typename Mixed>
void
walkCompact(const std::uint8_t* data, Uniform&& uniform, Mixed&& mixed)
{
  const unsigned mixed_cubes = data[0];
  const unsigned cube_codes = load16(data + 1);
  const std::uint8_t* head = data + 3;
  const std::uint8_t* tail = data + 3 + 3 * __builtin_popcount(mixed_cubes);
  for (int c = 0; c < 8; ++c) {
    if (!((mixed_cubes >> c) & 1u)) {
      uniform(c, -1, (cube_codes >> (2 * c)) & 3u, 64);
      continue;
    }
    const unsigned mixed_cells = head[0];
    const unsigned cell_codes = load16(head + 1);
    head += 3;
    for (int d = 0; d < 8; ++d) {
      if ((mixed_cells >> d) & 1u) {
        mixed(c, d, static_cast<std::uint32_t>(load16(tail)));
        tail += 2;
      } else {
        uniform(c, d, (cell_codes >> (2 * d)) & 3u, 8);
      }
    }
  }
}

/** \brief Encodes a payload whose codes are not all equal; returns the byte count
 * (<= MAX_COMPACT_BYTES) written to \a out. */
std::size_t
encodeCompact(const Payload& p, std::uint8_t* out)
{
  std::array<std::uint32_t, 64> cells; // cube c, cell d at 8 c + d
  for (int c = 0; c < 8; ++c)
    for (int d = 0; d < 8; ++d)
      cells[static_cast<std::size_t>(8 * c + d)] = cellValue(p, cellOrigin(c, d));
  std::uint32_t mixed_cubes = 0, cube_codes = 0;
  for (int c = 0; c < 8; ++c) {
    const std::uint32_t v0 = cells[static_cast<std::size_t>(8 * c)];
    bool uniform = v0 == cellPattern(v0 & 3u);
    for (int d = 1; d < 8 && uniform; ++d)
      uniform = cells[static_cast<std::size_t>(8 * c + d)] == v0;
    if (uniform)
      cube_codes |= (v0 & 3u) << (2 * c);
    else
      mixed_cubes |= 1u << c;
  }
  out[0] = static_cast<std::uint8_t>(mixed_cubes);
  out[1] = static_cast<std::uint8_t>(cube_codes);
  out[2] = static_cast<std::uint8_t>(cube_codes >> 8);
  std::size_t head = 3;
  std::size_t tail = 3 + 3 * static_cast<std::size_t>(__builtin_popcount(mixed_cubes));
  for (int c = 0; c < 8; ++c) {
    if (!((mixed_cubes >> c) & 1u))
      continue;
    std::uint32_t mixed_cells = 0, cell_codes = 0;
    for (int d = 0; d < 8; ++d) {
      const std::uint32_t v = cells[static_cast<std::size_t>(8 * c + d)];
      if (v == cellPattern(v & 3u))
        cell_codes |= (v & 3u) << (2 * d);
      else {
        mixed_cells |= 1u << d;
        out[tail++] = static_cast<std::uint8_t>(v);
        out[tail++] = static_cast<std::uint8_t>(v >> 8);
      }
    }
    out[head++] = static_cast<std::uint8_t>(mixed_cells);
    out[head++] = static_cast<std::uint8_t>(cell_codes);
    out[head++] = static_cast<std::uint8_t>(cell_codes >> 8);
  }
  return tail;
}

/** \brief Bytes of the compact block at \a data. */
inline std::size_t
compactSize(const std::uint8_t* data)
{
  const int n_cubes = __builtin_popcount(data[0]);
  std::size_t n = 3 + 3 * static_cast<std::size_t>(n_cubes);
  for (int k = 0; k < n_cubes; ++k)
    n += 2 * static_cast<std::size_t>(__builtin_popcount(data[3 + 3 * k]));
  return n;
}

/** \brief Code of local voxel (x, y, z) of the compact block at \a data. */
inline std::uint8_t
compactGet(const std::uint8_t* data, int x, int y, int z)
{
  const unsigned c =
    static_cast<unsigned>((x >> 2) | ((y >> 2) << 1) | ((z >> 2) << 2));
  const unsigned mixed_cubes = data[0];
  if (!((mixed_cubes >> c) & 1u))
    return static_cast<std::uint8_t>((load16(data + 1) >> (2 * c)) & 3u);
  const int r = __builtin_popcount(mixed_cubes & ((1u << c) - 1u));
  const std::uint8_t* cube = data + 3 + 3 * r;
  const unsigned d = static_cast<unsigned>(((x >> 1) & 1) | (((y >> 1) & 1) << 1)
                                           | (((z >> 1) & 1) << 2));
  const unsigned mixed_cells = cube[0];
  if (!((mixed_cells >> d) & 1u))
    return static_cast<std::uint8_t>((load16(cube + 1) >> (2 * d)) & 3u);
  int before = __builtin_popcount(mixed_cells & ((1u << d) - 1u));
  for (int k = 0; k < r; ++k)
    before += __builtin_popcount(data[3 + 3 * k]);
  const std::uint8_t* cell =
    data + 3 + 3 * __builtin_popcount(mixed_cubes) + 2 * before;
  const unsigned v = load16(cell);
  return static_cast<std::uint8_t>((v >> (2 * ((x & 1) + 2 * (y & 1) + 4 * (z & 1))))
                                   & 3u);
}

/** \brief Decodes the compact block at \a data into \a p. */
void
decodeCompact(const std::uint8_t* data, Payload& p)
{
  p.fill(0);
  walkCompact(
    data,
    [&p](int c, int d, unsigned code, int) {
      const std::uint32_t v = cellPattern(code);
      if (d >= 0) {
        putCell(p, cellOrigin(c, d), v);
        return;
      }
      for (int k = 0; k < 8; ++k)
        putCell(p, cellOrigin(c, k), v);
    },
    [&p](int c, int d, std::uint32_t v) { putCell(p, cellOrigin(c, d), v); });
}

/** \brief Adds the voxels of each code of the compact block at \a data to \a n. */
void
countCompact(const std::uint8_t* data, std::array<std::size_t, 4>& n)
{
  walkCompact(
    data,
    [&n](int, int, unsigned code, int voxels) {
      n[code] += static_cast<std::size_t>(voxels);
    },
    [&n](int, int, std::uint32_t v) {
      for (int k = 0; k < 8; ++k)
        ++n[(v >> (2 * k)) & 3u];
    });
}

/** \brief static_cast<int>(std::floor(x)) for |x| < 2^31, without the call to floorf
 * (x86-64 before SSE4.1 has no rounding instruction). */
inline int
floorToInt(float x)
{
  const int t = static_cast<int>(x); // truncation towards zero
  return t - (static_cast<float>(t) > x ? 1 : 0);
}

/** \brief floor(a / 8) for negative a too. */
inline int
blockOf(int a)
{
  return a >> BLOCK_SHIFT; // arithmetic shift: floor for negative keys (C++20, GCC)
}

inline int
localOf(int a)
{
  return a & (BLOCK_EDGE - 1);
}

/** \brief Open-addressing hash table (linear probing, at most half full) from block
 * grid coordinates to indices; one flat array, no node per entry. */
class KeyIndex {
public:
  static constexpr std::uint32_t NONE = std::numeric_limits<std::uint32_t>::max();

  /** \brief The index stored for \a key, NONE when absent. */
  std::uint32_t find(const BlockKey& key) const
  {
    if (slots_.empty())
      return NONE;
    const std::size_t mask = slots_.size() - 1;
    for (std::size_t s = BlockKeyHash()(key) & mask;; s = (s + 1) & mask) {
      const Slot& slot = slots_[s];
      if (slot.index == NONE)
        return NONE;
      if (slot.key == key)
        return slot.index;
    }
  }

  /** \brief Stores key -> index; \a key must be absent. */
  void insert(const BlockKey& key, std::uint32_t index)
  {
    if (2 * (size_ + 1) > slots_.size())
      grow();
    place(key, index);
    ++size_;
  }

  /** \brief Removes every entry (keeps the table's capacity). */
  void clear()
  {
    for (auto& slot : slots_)
      slot.index = NONE;
    size_ = 0;
  }

  /** \brief Removes every entry and frees the table. */
  void release()
  {
    std::vector<Slot>().swap(slots_);
    size_ = 0;
  }

  /** \brief Bytes of the table's allocation. */
  std::size_t capacityBytes() const { return slots_.capacity() * sizeof(Slot); }

private:
  struct Slot {
    BlockKey key{0, 0, 0};
    std::uint32_t index{NONE};
  };

  void place(const BlockKey& key, std::uint32_t index)
  {
    const std::size_t mask = slots_.size() - 1;
    std::size_t s = BlockKeyHash()(key) & mask;
    while (slots_[s].index != NONE)
      s = (s + 1) & mask;
    slots_[s] = {key, index};
  }

  void grow()
  {
    std::vector<Slot> old;
    old.swap(slots_);
    slots_.assign(std::max<std::size_t>(16, 2 * old.size()), Slot{});
    for (const auto& slot : old)
      if (slot.index != NONE)
        place(slot.key, slot.index);
  }

  std::vector<Slot> slots_;
  std::size_t size_{0};
};

/** \brief Blocks setState() edits before it writes them to the storage. */
constexpr std::size_t MAX_PENDING_BLOCKS = 4096;
/** \brief log2 of the edge of a super-block, in blocks. */
constexpr int SUPER_SHIFT = 3;
/** \brief Blocks per super-block (8 x 8 x 8). */
constexpr int SUPER_BLOCKS = 512;

/** \brief 8 x 8 x 8 blocks (64^3 voxels): the 2-bit code of each uniform block, a bit
 * per mixed block, and the mixed blocks' compact forms back to back. A block at the
 * grid's prior code is not stored (it is never-observed space). */
struct SuperBlock {
  /** \brief Super-block coordinates: floor(block key / 8). */
  BlockKey key{0, 0, 0};
  /** \brief Code of block j = x + 8 y + 64 z at bits 2 (j % 32) of word j / 32; 0 for
   * a mixed block. */
  std::array<std::uint64_t, 16> codes{};
  /** \brief Bit j % 64 of word j / 64: block j is mixed. */
  std::array<std::uint64_t, 8> mixed{};
  /** \brief Mixed blocks in the words of \a mixed before word w. */
  std::array<std::uint16_t, 8> rank{};
  /** \brief Blocks not at the prior (uniform ones of another code, and mixed ones). */
  std::uint16_t stored{0};
  /** \brief Start of each mixed block's compact form in \a data, in block order. */
  std::vector<std::uint32_t> offsets;
  /** \brief The compact forms. */
  std::vector<std::uint8_t> data;

  bool isMixed(int j) const
  {
    return (mixed[static_cast<std::size_t>(j >> 6)] >> (j & 63)) & 1u;
  }
  std::uint8_t code(int j) const
  {
    return static_cast<std::uint8_t>(
      (codes[static_cast<std::size_t>(j >> 5)] >> (2 * (j & 31))) & 3u);
  }
  /** \brief The compact form of mixed block \a j. */
  const std::uint8_t* compact(int j) const
  {
    const auto w = static_cast<std::size_t>(j >> 6);
    const std::uint64_t below = (std::uint64_t{1} << (j & 63)) - 1;
    const auto r =
      rank[w] + static_cast<std::size_t>(__builtin_popcountll(mixed[w] & below));
    return data.data() + offsets[r];
  }
  /** \brief Code of voxel (x, y, z) (local to block j). */
  std::uint8_t get(int j, int x, int y, int z) const
  {
    return isMixed(j) ? compactGet(compact(j), x, y, z) : code(j);
  }
  /** \brief Block \a j decoded. */
  void load(int j, DenseBlock& out) const
  {
    if (isMixed(j)) {
      out.uniform = MIXED;
      decodeCompact(compact(j), out.bits);
    } else
      out.uniform = code(j);
  }
};

/** \brief Block \a j's coordinates in super-block \a s. */
inline BlockKey
blockKeyOf(const BlockKey& s, int j)
{
  return {s.x * 8 + (j & 7), s.y * 8 + ((j >> 3) & 7), s.z * 8 + (j >> 6)};
}

/** \brief A stored block: its key, and where it lives. */
struct StoredBlock {
  BlockKey key;
  const SuperBlock* super;
  int j;
};

/** \brief A block being written: a uniform code, or MIXED with a payload in the
 * edit buffer's pool. */
struct EditBlock {
  std::uint8_t uniform{MIXED};
  std::uint32_t payload{0};
};

/** \brief The start of a 3D DDA walk (Amanatides and Woo) from \a o along the unit
 * direction \a d, both in voxel units: the first voxel, the step per axis, the ray
 * parameter of the first boundary crossed per axis and the parameter between two. */
struct DdaWalk {
  std::array<int, 3> key{}, step{};
  std::array<double, 3> t_max{}, t_delta{};

  DdaWalk(const Eigen::Vector3d& o, const Eigen::Vector3d& d)
  {
    for (std::size_t a = 0; a < 3; ++a) {
      const double oa = o[static_cast<Eigen::Index>(a)];
      const double da = d[static_cast<Eigen::Index>(a)];
      key[a] = static_cast<int>(std::floor(oa));
      if (da > 0.0) {
        step[a] = 1;
        t_delta[a] = 1.0 / da;
        t_max[a] = (std::floor(oa) + 1.0 - oa) / da;
      } else if (da < 0.0) {
        step[a] = -1;
        t_delta[a] = -1.0 / da;
        t_max[a] = (std::floor(oa) - oa) / da;
      } else {
        t_delta[a] = t_max[a] = std::numeric_limits<double>::infinity();
      }
    }
  }

  /** \brief The parameter where the ray enters the next voxel. */
  double next() const { return std::min({t_max[0], t_max[1], t_max[2]}); }

  /** \brief Moves to the next voxel; returns the parameter where the ray enters it. */
  double advance()
  {
    std::size_t a = 0;
    if (t_max[1] < t_max[a])
      a = 1;
    if (t_max[2] < t_max[a])
      a = 2;
    const double t = t_max[a];
    key[a] += step[a];
    t_max[a] += t_delta[a];
    return t;
  }
};

void
putU32(std::vector<std::uint8_t>& b, std::uint32_t v)
{
  for (int i = 0; i < 4; ++i)
    b.push_back(static_cast<std::uint8_t>(v >> (8 * i)));
}

std::uint64_t
getLE(const std::uint8_t* p, int n)
{
  std::uint64_t v = 0;
  for (int i = 0; i < n; ++i)
    v |= static_cast<std::uint64_t>(p[i]) << (8 * i);
  return v;
}

/** \brief Depth pyramids of a depth image, over the measured (valid) pixels only:
 * min_level (+inf where a cell has no measurement), max_level (0 there), and, per
 * level j, hole[j][k] (k >= 1; k = 0 is min_level[j] itself): the max over 2^k x 2^k
 * cells of min_level[j], finite only when every level-j cell of the region holds a
 * measurement. */
struct DepthPyramid {
  std::vector<std::vector<float>> min_level, max_level;
  std::vector<std::vector<std::vector<float>>> hole;
  std::vector<int> w, h;
  /** \brief spanMin()'s arrays per level (k = 0 unused: min_level itself). */
  std::vector<std::array<std::vector<float>, 9>> span;

  static void reduce(const std::vector<float>& src,
                     int sw,
                     int sh,
                     bool take_max,
                     std::vector<float>& dst)
  {
    const int nw = (sw + 1) / 2, nh = (sh + 1) / 2;
    dst.resize(static_cast<std::size_t>(nw) * static_cast<std::size_t>(nh));
    for (int v = 0; v < nh; ++v) {
      const auto r0 = static_cast<std::size_t>(2 * v) * static_cast<std::size_t>(sw);
      const auto r1 = static_cast<std::size_t>(std::min(2 * v + 1, sh - 1))
                      * static_cast<std::size_t>(sw);
      for (int u = 0; u < nw; ++u) {
        const auto c0 = static_cast<std::size_t>(2 * u);
        const auto c1 = static_cast<std::size_t>(std::min(2 * u + 1, sw - 1));
        const float a = src[r0 + c0], b = src[r0 + c1], c = src[r1 + c0],
                    d = src[r1 + c1];
        dst[static_cast<std::size_t>(v) * static_cast<std::size_t>(nw)
            + static_cast<std::size_t>(u)] =
          take_max ? std::max(std::max(a, b), std::max(c, d))
                   : std::min(std::min(a, b), std::min(c, d));
      }
    }
  }

  void build(const DepthImage& image, float& max_valid_depth)
  {
    // Buffers are kept between views (no reallocation, no fresh pages).
    const float inf = std::numeric_limits<float>::infinity();
    w.assign(1, image.width);
    h.assign(1, image.height);
    while (w.back() > 1 || h.back() > 1) {
      w.push_back((w.back() + 1) / 2);
      h.push_back((h.back() + 1) / 2);
    }
    const std::size_t n_levels = w.size();
    min_level.resize(n_levels);
    max_level.resize(n_levels);
    auto& m0 = min_level[0];
    auto& x0 = max_level[0];
    m0.resize(image.depth_m.size());
    x0.resize(image.depth_m.size());
    float max_depth = 0.0f;
    for (std::size_t i = 0; i < m0.size(); ++i) {
      const float d = image.depth_m[i];
      const bool valid = d > 0.0f && d < inf; // finite and positive (NaN fails)
      m0[i] = valid ? d : inf;
      x0[i] = valid ? d : 0.0f;
      max_depth = std::max(max_depth, x0[i]);
    }
    max_valid_depth = max_depth;
    for (std::size_t l = 1; l < n_levels; ++l) {
      reduce(min_level[l - 1], w[l - 1], h[l - 1], false, min_level[l]);
      reduce(max_level[l - 1], w[l - 1], h[l - 1], true, max_level[l]);
    }
    hole.resize(n_levels);
    for (std::size_t j = 0; j < n_levels; ++j) {
      auto& hj = hole[j];
      hj.resize(n_levels - j); // hj[0] stays empty: it would be min_level[j]
      for (std::size_t k = 1; k < hj.size(); ++k)
        reduce(k == 1 ? min_level[j] : hj[k - 1], w[j + k - 1], h[j + k - 1], true,
               hj[k]);
    }
  }

  int levels() const { return static_cast<int>(w.size()); }

  /** \brief min_level[l] over the cells (cu .. cu + su) x (cv .. cv + sv), at
   * cu + cv w[l], for k = 3 su + sv (su, sv in 0..2); valid where those cells lie in
   * the level. Needs buildSpans() from a level <= l. */
  const float* spanMin(int l, int k) const
  {
    const auto sl = static_cast<std::size_t>(l);
    return k == 0 ? min_level[sl].data() : span[sl][static_cast<std::size_t>(k)].data();
  }

  /** \brief The span minima of levels first .. levels() - 1. */
  void buildSpans(int first)
  {
    span.resize(w.size());
    for (std::size_t l = static_cast<std::size_t>(std::max(first, 0)); l < w.size();
         ++l) {
      const int lw = w[l], lh = h[l];
      const std::size_t n = min_level[l].size();
      auto& sp = span[l];
      // along u: k = 3 and 6 (su = 1, 2)
      const std::vector<float>& m = min_level[l];
      sp[3].resize(n);
      sp[6].resize(n);
      for (int cv = 0; cv < lh; ++cv) {
        const std::size_t row =
          static_cast<std::size_t>(cv) * static_cast<std::size_t>(lw);
        for (int cu = 0; cu < lw; ++cu) {
          const std::size_t i = row + static_cast<std::size_t>(cu);
          const float a = m[i];
          const float b = m[row + static_cast<std::size_t>(std::min(cu + 1, lw - 1))];
          const float c = m[row + static_cast<std::size_t>(std::min(cu + 2, lw - 1))];
          sp[3][i] = std::min(a, b);
          sp[6][i] = std::min(std::min(a, b), c);
        }
      }
      // along v, from each of su = 0, 1, 2: k = 3 su + 1 and 3 su + 2
      for (int su = 0; su < 3; ++su) {
        const std::vector<float>& src =
          su == 0 ? m : sp[static_cast<std::size_t>(3 * su)];
        auto& d1 = sp[static_cast<std::size_t>(3 * su + 1)];
        auto& d2 = sp[static_cast<std::size_t>(3 * su + 2)];
        d1.resize(n);
        d2.resize(n);
        for (int cv = 0; cv < lh; ++cv) {
          const std::size_t r0 =
            static_cast<std::size_t>(cv) * static_cast<std::size_t>(lw);
          const std::size_t r1 = static_cast<std::size_t>(std::min(cv + 1, lh - 1))
                                 * static_cast<std::size_t>(lw);
          const std::size_t r2 = static_cast<std::size_t>(std::min(cv + 2, lh - 1))
                                 * static_cast<std::size_t>(lw);
          for (int cu = 0; cu < lw; ++cu) {
            const auto c = static_cast<std::size_t>(cu);
            const float ab = std::min(src[r0 + c], src[r1 + c]);
            d1[r0 + c] = ab;
            d2[r0 + c] = std::min(ab, src[r2 + c]);
          }
        }
      }
    }
  }

  /** \brief Smallest level whose cells are at least \a size pixels wide. */
  int levelFor(int size) const
  {
    int l = 0;
    while ((1 << l) < size && l + 1 < levels())
      ++l;
    return l;
  }

  /** \brief Min and max of the valid depths over the level-l cells covering the
   * clamped rectangle [u0, u1] x [v0, v1]. */
  void query(int l, int u0, int v0, int u1, int v1, float& mn, float& mx) const
  {
    const auto& lmin = min_level[static_cast<std::size_t>(l)];
    const auto& lmax = max_level[static_cast<std::size_t>(l)];
    const auto lw = static_cast<std::size_t>(w[static_cast<std::size_t>(l)]);
    mn = std::numeric_limits<float>::infinity();
    mx = 0.0f;
    for (int cv = v0 >> l; cv <= (v1 >> l); ++cv) {
      const std::size_t row = static_cast<std::size_t>(cv) * lw;
      for (int cu = u0 >> l; cu <= (u1 >> l); ++cu) {
        mn = std::min(mn, lmin[row + static_cast<std::size_t>(cu)]);
        mx = std::max(mx, lmax[row + static_cast<std::size_t>(cu)]);
      }
    }
  }

  /** \brief Clamps a pixel rectangle into the image; false when it misses it. */
  bool clampRect(int& u0, int& v0, int& u1, int& v1) const
  {
    u0 = std::max(u0, 0);
    v0 = std::max(v0, 0);
    u1 = std::min(u1, w[0] - 1);
    v1 = std::min(v1, h[0] - 1);
    return u0 <= u1 && v0 <= v1;
  }

  /** \brief Min and max valid depth over (a superset of) a clamped rectangle. */
  void queryRect(int u0, int v0, int u1, int v1, float& mn, float& mx) const
  {
    // cells of a quarter of the size: at most 5 x 5 of them, a tight superset
    query(levelFor((std::max(u1 - u0 + 1, v1 - v0 + 1) + 3) / 4), u0, v0, u1, v1, mn,
          mx);
  }

  /** \brief True when every level-j cell meeting the clamped rectangle holds a
   * measurement. */
  bool noHoles(int j, int u0, int v0, int u1, int v1) const
  {
    j = std::min(j, levels() - 1);
    const int l = std::max(levelFor((std::max(u1 - u0 + 1, v1 - v0 + 1) + 3) / 4), j);
    const auto& hk =
      l == j ? min_level[static_cast<std::size_t>(j)]
             : hole[static_cast<std::size_t>(j)][static_cast<std::size_t>(l - j)];
    const auto lw = static_cast<std::size_t>(w[static_cast<std::size_t>(l)]);
    for (int cv = v0 >> l; cv <= (v1 >> l); ++cv)
      for (int cu = u0 >> l; cu <= (u1 >> l); ++cu)
        if (!std::isfinite(
              hk[static_cast<std::size_t>(cv) * lw + static_cast<std::size_t>(cu)]))
          return false;
    return true;
  }
};

/** \brief What one view says of one block: free or occluded as a whole, or per voxel
 * (bit x + 8 y of word z; a voxel in neither mask is not observed). */
struct BlockResult {
  enum Kind : std::uint8_t { ALL_FREE, ALL_OCCLUDED, MASKS };
  BlockKey key{0, 0, 0};
  Kind kind{MASKS};
  std::array<std::uint64_t, BLOCK_EDGE> free{}, occluded{};
};

/** \brief Counters of the free / occluded pass (debug output). */
struct Counters {
  std::size_t visited{0}, fast{0}, slow{0};
};

/** \brief Bit i of \a b moved to bit 2 i. */
inline std::uint64_t
spreadBits(std::uint32_t b)
{
  std::uint64_t x = b;
  x = (x | (x << 16)) & 0x0000FFFF0000FFFFULL;
  x = (x | (x << 8)) & 0x00FF00FF00FF00FFULL;
  x = (x | (x << 4)) & 0x0F0F0F0F0F0F0F0FULL;
  x = (x | (x << 2)) & 0x3333333333333333ULL;
  x = (x | (x << 1)) & 0x5555555555555555ULL;
  return x;
}

/** \brief Camera and thresholds of the per-voxel test (copied to locals). */
struct VoxelKernel {
  float fx, fy, cx, cy, u_end, v_end, max_range, margin;
  int W, H;
  bool mark_occluded;
  const float* depth0; // min_level[0]: the measured depth per pixel, +inf for none
};

/** \brief What the 8 corner centres of a 4^3 cube tell of observeCube()'s per-voxel
 * test for all 64 voxels. */
enum class CubeBound : std::uint8_t {
  UNDECIDED, // the 64 centres must be tested
  ALL_FREE,  // every voxel is free
  NONE_FREE  // no voxel is free (and without mark_occluded, none is observed)
};

/** \brief Bounds observeCube()'s per-voxel test over the 4^3 cube at local offset
 * (ox, oy, oz) of the block with min corner c0 from its 8 corner centres instead of all
 * 64 projections. The projection is monotone along any line, so the extremes of the
 * centres' pixel coordinates and depths are those of the corner centres; they are
 * widened by a pixel and 1 mm against rounding. ALL_FREE: every centre is in range and
 * inside the image, and the largest centre depth is in front of every level cell
 * meeting the union of the footprints (minus the margin), so every voxel passes its own
 * test. NONE_FREE: the smallest centre depth is not in front of any level cell that
 * holds a centre's pixel (minus the margin); each voxel's footprint contains its own
 * pixel's cell, so no voxel passes. */
CubeBound
boundCube(const VoxelKernel& kernel,
          const float* lmin,
          int level_width,
          int level,
          int r,
          const Eigen::Vector3f& c0,
          const Eigen::Vector3f& ex,
          const Eigen::Vector3f& ey,
          const Eigen::Vector3f& ez,
          int ox,
          int oy,
          int oz)
{
  constexpr float SLACK_PX = 1.0f, SLACK_M = 1e-3f, FAR_PX = 1e6f;
  float umin = std::numeric_limits<float>::infinity(), umax = -umin, vmin = umin,
        vmax = -umin, zmin = umin, zmax = -umin;
  for (int i = 0; i < 8; ++i) {
    const Eigen::Vector3f p =
      c0 + (static_cast<float>(ox + 3 * (i & 1)) + 0.5f) * ex
      + (static_cast<float>(oy + 3 * ((i >> 1) & 1)) + 0.5f) * ey
      + (static_cast<float>(oz + 3 * (i >> 2)) + 0.5f) * ez;
    if (!(p.z() > NEAR_Z + SLACK_M))
      return CubeBound::UNDECIDED;
    zmin = std::min(zmin, p.z());
    zmax = std::max(zmax, p.z());
    const float inv = 1.0f / p.z();
    const float u = kernel.fx * p.x() * inv + kernel.cx,
                v = kernel.fy * p.y() * inv + kernel.cy;
    umin = std::min(umin, u);
    umax = std::max(umax, u);
    vmin = std::min(vmin, v);
    vmax = std::max(vmax, v);
  }
  zmin -= SLACK_M;
  zmax += SLACK_M;
  umin = std::max(umin - SLACK_PX, -FAR_PX);
  umax = std::min(umax + SLACK_PX, FAR_PX);
  vmin = std::max(vmin - SLACK_PX, -FAR_PX);
  vmax = std::min(vmax + SLACK_PX, FAR_PX);
  const auto lw = static_cast<std::ptrdiff_t>(level_width);
  const float margin = kernel.margin;
  if (zmax <= kernel.max_range && umin >= -0.5f && umax < kernel.u_end && vmin >= -0.5f
      && vmax < kernel.v_end) {
    // every centre valid; the footprints' cells as observeCube() bounds them
    const int u0 = static_cast<int>(umin + 0.5f), u1 = static_cast<int>(umax + 0.5f);
    const int v0 = static_cast<int>(vmin + 0.5f), v1 = static_cast<int>(vmax + 0.5f);
    const int cu0 = std::max(u0 - r, 0) >> level,
              cu2 = std::min(u1 + r, kernel.W - 1) >> level;
    const int cv0 = std::max(v0 - r, 0) >> level,
              cv2 = std::min(v1 + r, kernel.H - 1) >> level;
    bool all_free = true;
    for (int cv = cv0; cv <= cv2 && all_free; ++cv) {
      const float* row = lmin + cv * lw;
      for (int cu = cu0; cu <= cu2; ++cu)
        if (!(zmax < row[cu] - margin)) {
          all_free = false;
          break;
        }
    }
    if (all_free)
      return CubeBound::ALL_FREE;
  }
  // the cells of the centres' own pixels (those of the valid ones lie in the image)
  const int pu0 = std::max(static_cast<int>(std::floor(umin + 0.5f)), 0),
            pu1 = std::min(static_cast<int>(std::floor(umax + 0.5f)), kernel.W - 1);
  const int pv0 = std::max(static_cast<int>(std::floor(vmin + 0.5f)), 0),
            pv1 = std::min(static_cast<int>(std::floor(vmax + 0.5f)), kernel.H - 1);
  if (pu0 > pu1 || pv0 > pv1)
    return CubeBound::NONE_FREE; // no centre inside the image
  for (int cv = pv0 >> level; cv <= (pv1 >> level); ++cv) {
    const float* row = lmin + cv * lw;
    for (int cu = pu0 >> level; cu <= (pu1 >> level); ++cu)
      if (!(zmin >= row[cu] - margin))
        return CubeBound::UNDECIDED;
  }
  return CubeBound::NONE_FREE;
}

/** \brief Per-voxel observations of the 4^3 cube at local offset (ox, oy, oz) of the
 * block whose min corner is c0 (camera frame, voxel axes ex, ey, ez): free when the
 * centre is in front of the smallest depth over the level cells meeting its footprint
 * (radius r pixels, at most 3 x 3 cells of \a level) minus the margin, occluded (only
 * with mark_occluded) when behind its pixel's depth plus the margin. Sets bits
 * x + 8 y of words z. */
void
observeCube(const VoxelKernel& kernel,
            const DepthPyramid& pyr,
            int level,
            int r,
            const Eigen::Vector3f& c0,
            const Eigen::Vector3f& ex,
            const Eigen::Vector3f& ey,
            const Eigen::Vector3f& ez,
            int ox,
            int oy,
            int oz,
            std::array<std::uint64_t, BLOCK_EDGE>& free_mask,
            std::array<std::uint64_t, BLOCK_EDGE>& occluded_mask)
{
  const auto l = static_cast<std::size_t>(level);
  const float* const lmin = pyr.min_level[l].data();
  const int level_width = pyr.w[l];
  const CubeBound bound =
    boundCube(kernel, lmin, level_width, level, r, c0, ex, ey, ez, ox, oy, oz);
  if (bound == CubeBound::ALL_FREE) {
    for (int z = 0; z < 4; ++z)
      for (int y = 0; y < 4; ++y)
        free_mask[static_cast<std::size_t>(oz + z)] |= std::uint64_t{15}
                                                       << (ox + 8 * (oy + y));
    return;
  }
  if (bound == CubeBound::NONE_FREE && !kernel.mark_occluded) {
    return;
  }
  const float fx = kernel.fx, fy = kernel.fy, cx = kernel.cx, cy = kernel.cy;
  const float u_end = kernel.u_end, v_end = kernel.v_end;
  const float max_range = kernel.max_range, margin = kernel.margin;
  const int W = kernel.W, H = kernel.H;
  const float exx = ex.x(), exy = ex.y(), exz = ex.z();
  // The 64 centres (index x + 4 y + 16 z, local to the cube), then their projections
  // in a branch-free loop the compiler vectorises.
  std::array<float, 64> xs, ys, zs;
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const Eigen::Vector3f p0 = c0 + (static_cast<float>(ox) + 0.5f) * ex
                                 + (static_cast<float>(oy + y) + 0.5f) * ey
                                 + (static_cast<float>(oz + z) + 0.5f) * ez;
      float px = p0.x(), py = p0.y(), pz = p0.z();
      for (int x = 0; x < 4; ++x, px += exx, py += exy, pz += exz) {
        const auto i = static_cast<std::size_t>(x + 4 * y + 16 * z);
        xs[i] = px;
        ys[i] = py;
        zs[i] = pz;
      }
    }
  std::array<int, 64> us, vs;
  std::array<std::uint8_t, 64> in; // in range and inside the image
  const auto u_max = static_cast<float>(W - 1), v_max = static_cast<float>(H - 1);
  for (std::size_t i = 0; i < 64; ++i) {
    const float zc = zs[i];
    const float inv = 1.0f / zc;
    const float u = fx * xs[i] * inv + cx, v = fy * ys[i] * inv + cy;
    const int ok = static_cast<int>(zc > NEAR_Z) & static_cast<int>(zc <= max_range)
                   & static_cast<int>(u >= -0.5f) & static_cast<int>(u < u_end)
                   & static_cast<int>(v >= -0.5f) & static_cast<int>(v < v_end);
    in[i] = static_cast<std::uint8_t>(ok);
    // clamped into the image (NaN to 0), which leaves the valid centres' pixels as they
    // are: int(u + 0.5) for u in [-0.5, W - 0.5)
    us[i] = static_cast<int>(std::min(u_max, std::max(0.0f, u)) + 0.5f);
    vs[i] = static_cast<int>(std::min(v_max, std::max(0.0f, v)) + 0.5f);
  }
  // The smallest valid depth over the level cells meeting each footprint: one lookup
  // in the pyramid's minimum over the 1 to 3 cells it spans per axis.
  std::array<const float*, 9> span_min;
  for (int k = 0; k < 9; ++k)
    span_min[static_cast<std::size_t>(k)] = pyr.spanMin(level, k);
  const auto lw = static_cast<std::ptrdiff_t>(level_width);
  std::uint64_t valid = 0, free_bits = 0, occ_bits = 0;
  for (std::size_t i = 0; i < 64; ++i) {
    const int ui = us[i], vi = vs[i];
    const int cu0 = std::max(ui - r, 0) >> level,
              cu2 = std::min(ui + r, W - 1) >> level;
    const int cv0 = std::max(vi - r, 0) >> level,
              cv2 = std::min(vi + r, H - 1) >> level;
    const float fmin =
      span_min[static_cast<std::size_t>(3 * (cu2 - cu0) + (cv2 - cv0))][cv0 * lw + cu0];
    // branch-free: the outcome is unpredictable in mixed regions
    const bool is_free = in[i] != 0 && zs[i] < fmin - margin;
    valid |= static_cast<std::uint64_t>(in[i]) << i;
    free_bits |= static_cast<std::uint64_t>(is_free) << i;
  }
  if (kernel.mark_occluded) {
    const float inf = std::numeric_limits<float>::infinity();
    for (std::uint64_t todo = valid & ~free_bits; todo != 0; todo &= todo - 1) {
      const int i = __builtin_ctzll(todo);
      const auto si = static_cast<std::size_t>(i);
      const float d = kernel.depth0[static_cast<std::ptrdiff_t>(vs[si]) * W
                                    + static_cast<std::ptrdiff_t>(us[si])];
      occ_bits |= static_cast<std::uint64_t>(d < inf && zs[si] > d + margin) << i;
    }
  }
  // cube bits x + 4 y + 16 z to block bits (ox + x) + 8 (oy + y) of word oz + z
  for (int z = 0; z < 4; ++z)
    for (int y = 0; y < 4; ++y) {
      const int shift = 4 * y + 16 * z, to = ox + 8 * (oy + y);
      free_mask[static_cast<std::size_t>(oz + z)] |= ((free_bits >> shift) & 15u) << to;
      occluded_mask[static_cast<std::size_t>(oz + z)] |= ((occ_bits >> shift) & 15u)
                                                         << to;
    }
}

} // namespace

struct ExplicitSpaceGrid::Impl {
  class Cursor;

  /** \brief The super-blocks holding at least one stored block (any order). */
  std::vector<SuperBlock> supers;
  /** \brief Super-block coordinates -> index in \a supers. */
  KeyIndex directory;

  /** \brief Blocks being written (keys, their content, and their index), with the
   * payloads of the mixed ones; emptied by commit(). */
  KeyIndex edit_index;
  std::vector<BlockKey> edit_keys;
  std::vector<EditBlock> edits;
  std::vector<Payload> pool;
  /** \brief commit()'s scratch: the edits' order, one super-block's new arrays. */
  std::vector<std::uint32_t> order, new_offsets;
  std::vector<std::uint8_t> new_data;

  DepthPyramid pyramid;
  /** \brief The occupied pass's (u - cx) / fx per image column. */
  std::vector<float> column_x;
  /** \brief Per-thread observations of the blocks of the last view. */
  std::vector<std::vector<BlockResult>> results;

  static BlockKey superOf(const BlockKey& b)
  {
    return {b.x >> SUPER_SHIFT, b.y >> SUPER_SHIFT, b.z >> SUPER_SHIFT};
  }
  static int indexInSuper(const BlockKey& b)
  {
    return (b.x & 7) + 8 * (b.y & 7) + 64 * (b.z & 7);
  }

  const SuperBlock* findSuper(const BlockKey& s) const
  {
    const std::uint32_t i = directory.find(s);
    return i == KeyIndex::NONE ? nullptr : &supers[i];
  }

  /** \brief Code of voxel (kx, ky, kz), pending edits included; \a prior where
   * nothing is stored. */
  std::uint8_t codeAt(int kx, int ky, int kz, std::uint8_t prior) const
  {
    const BlockKey bk{blockOf(kx), blockOf(ky), blockOf(kz)};
    if (!edits.empty()) {
      const std::uint32_t e = edit_index.find(bk);
      if (e != KeyIndex::NONE)
        return getEdit(e, localOf(kx) + 8 * localOf(ky) + 64 * localOf(kz));
    }
    const SuperBlock* sb = findSuper(superOf(bk));
    if (sb == nullptr)
      return prior;
    return sb->get(indexInSuper(bk), localOf(kx), localOf(ky), localOf(kz));
  }

  /** \brief The edit of block \a bk, loaded from the storage on first use. */
  std::uint32_t open(const BlockKey& bk, std::uint8_t prior)
  {
    std::uint32_t e = edit_index.find(bk);
    if (e != KeyIndex::NONE)
      return e;
    e = static_cast<std::uint32_t>(edits.size());
    EditBlock block;
    block.uniform = prior;
    if (const SuperBlock* sb = findSuper(superOf(bk))) {
      const int j = indexInSuper(bk);
      if (sb->isMixed(j)) {
        block.uniform = MIXED;
        block.payload = newPayload();
        decodeCompact(sb->compact(j), pool[block.payload]);
      } else
        block.uniform = sb->code(j);
    }
    edit_keys.push_back(bk);
    edits.push_back(block);
    edit_index.insert(bk, e);
    return e;
  }

  std::uint32_t newPayload()
  {
    pool.emplace_back();
    return static_cast<std::uint32_t>(pool.size() - 1);
  }

  /** \brief The payload of edit \a e, made MIXED (voxel by voxel) first. */
  Payload& mixedPayload(std::uint32_t e)
  {
    EditBlock& block = edits[e];
    if (block.uniform != MIXED) {
      const std::uint8_t s = block.uniform;
      block.payload = newPayload();
      block.uniform = MIXED;
      pool[block.payload].fill(pattern(s));
    }
    return pool[block.payload];
  }

  std::uint8_t getEdit(std::uint32_t e, int i) const
  {
    const EditBlock& block = edits[e];
    if (block.uniform != MIXED)
      return block.uniform;
    return static_cast<std::uint8_t>(
      (pool[block.payload][static_cast<std::size_t>(i >> 5)] >> ((i & 31) * 2)) & 3u);
  }

  void setEdit(std::uint32_t e, int i, std::uint8_t s)
  {
    if (edits[e].uniform == s)
      return;
    auto& w = mixedPayload(e)[static_cast<std::size_t>(i >> 5)];
    const int shift = (i & 31) * 2;
    w = (w & ~(std::uint64_t{3} << shift)) | (static_cast<std::uint64_t>(s) << shift);
  }

  /** \brief Writes the edited blocks into their super-blocks (a block whose voxels
   * agree becomes uniform, one at the prior is dropped, a super-block left without
   * blocks is removed), then empties the edit buffer. */
  void commit(std::uint8_t prior)
  {
    const std::size_t n = edits.size();
    order.resize(n);
    for (std::size_t k = 0; k < n; ++k)
      order[k] = static_cast<std::uint32_t>(k);
    std::sort(order.begin(), order.end(), [this](std::uint32_t a, std::uint32_t b) {
      const BlockKey sa = superOf(edit_keys[a]), sb = superOf(edit_keys[b]);
      if (!(sa == sb))
        return sa < sb;
      return indexInSuper(edit_keys[a]) < indexInSuper(edit_keys[b]);
    });
    // New super-blocks: the array grows to exactly its new size (no capacity left
    // over: the memory held is what the content needs).
    std::size_t missing = 0;
    for (std::size_t g = 0; g < n;) {
      const BlockKey s = superOf(edit_keys[order[g]]);
      bool any = false;
      for (; g < n && superOf(edit_keys[order[g]]) == s; ++g)
        any = any || edits[order[g]].uniform != prior;
      missing += any && directory.find(s) == KeyIndex::NONE ? 1 : 0;
    }
    if (missing > 0)
      supers.reserve(supers.size() + missing);
    bool emptied = false;
    for (std::size_t g = 0; g < n;) {
      const BlockKey s = superOf(edit_keys[order[g]]);
      std::size_t end = g;
      bool any = false; // an edited block not at the prior
      for (; end < n && superOf(edit_keys[order[end]]) == s; ++end)
        any = any || edits[order[end]].uniform != prior;
      std::uint32_t si = directory.find(s);
      if (si == KeyIndex::NONE) {
        if (!any) {
          g = end;
          continue;
        }
        si = static_cast<std::uint32_t>(supers.size());
        supers.emplace_back();
        supers.back().key = s;
        supers.back().codes.fill(pattern(prior));
        directory.insert(s, si);
      }
      rebuild(supers[si], g, end, prior);
      emptied = emptied || supers[si].stored == 0;
      g = end;
    }
    if (emptied) {
      supers.erase(std::remove_if(supers.begin(), supers.end(),
                                  [](const SuperBlock& sb) { return sb.stored == 0; }),
                   supers.end());
      supers.shrink_to_fit(); // rare: the memory follows the content
      if (supers.empty())
        directory.release();
      else
        directory.clear();
      for (std::size_t i = 0; i < supers.size(); ++i)
        directory.insert(supers[i].key, static_cast<std::uint32_t>(i));
    }
    discardEdits();
  }

  /** \brief Commits the edits setState() left pending, so that the storage alone
   * holds the content. */
  void settle(std::uint8_t prior)
  {
    if (!edits.empty())
      commit(prior);
  }

  /** \brief Drops the pending edits. */
  void discardEdits()
  {
    edit_index.clear();
    edit_keys.clear();
    edits.clear();
    pool.clear();
  }

  /** \brief Frees the edit buffer and commit()'s scratch. */
  void releaseEdits()
  {
    edit_index.release();
    std::vector<BlockKey>().swap(edit_keys);
    std::vector<EditBlock>().swap(edits);
    std::vector<Payload>().swap(pool);
    std::vector<std::uint32_t>().swap(order);
    std::vector<std::uint32_t>().swap(new_offsets);
    std::vector<std::uint8_t>().swap(new_data);
  }

  /** \brief Rebuilds \a sb with the edits order[first, last) (sorted by block). */
  void rebuild(SuperBlock& sb, std::size_t first, std::size_t last, std::uint8_t prior)
  {
    std::array<std::uint64_t, 16> codes = sb.codes;
    std::array<std::uint64_t, 8> mixed = sb.mixed;
    new_offsets.clear();
    new_data.clear();
    std::array<std::uint8_t, MAX_COMPACT_BYTES> buffer;
    std::size_t next = first;
    for (int j = 0; j < SUPER_BLOCKS; ++j) {
      const bool edited = next < last && indexInSuper(edit_keys[order[next]]) == j;
      if (!edited) {
        if (sb.isMixed(j)) {
          const std::uint8_t* src = sb.compact(j);
          new_offsets.push_back(static_cast<std::uint32_t>(new_data.size()));
          new_data.insert(new_data.end(), src, src + compactSize(src));
        }
        continue;
      }
      const EditBlock& block = edits[order[next++]];
      std::uint8_t code = block.uniform, first = 0;
      if (code == MIXED && isUniform(pool[block.payload], first))
        code = first;
      const auto cw = static_cast<std::size_t>(j >> 5);
      const int cs = 2 * (j & 31);
      const auto mw = static_cast<std::size_t>(j >> 6);
      const std::uint64_t mbit = std::uint64_t{1} << (j & 63);
      codes[cw] &= ~(std::uint64_t{3} << cs);
      if (code == MIXED) {
        mixed[mw] |= mbit;
        const std::size_t bytes = encodeCompact(pool[block.payload], buffer.data());
        new_offsets.push_back(static_cast<std::uint32_t>(new_data.size()));
        new_data.insert(new_data.end(), buffer.begin(), buffer.begin() + bytes);
      } else {
        mixed[mw] &= ~mbit;
        codes[cw] |= static_cast<std::uint64_t>(code) << cs;
      }
    }
    sb.codes = codes;
    sb.mixed = mixed;
    std::uint16_t before = 0;
    for (std::size_t w = 0; w < 8; ++w) {
      sb.rank[w] = before;
      before = static_cast<std::uint16_t>(before + __builtin_popcountll(mixed[w]));
    }
    // a mixed block's code field is 0, never a prior code (2 or 3): counted as stored
    constexpr std::uint64_t LOW = 0x5555555555555555ULL;
    int stored = 0;
    for (const auto w : codes) {
      const std::uint64_t x = w ^ pattern(prior);
      stored += __builtin_popcountll((x | (x >> 1)) & LOW);
    }
    sb.stored = static_cast<std::uint16_t>(stored);
    // exact-size arrays: the memory held is the information's
    std::vector<std::uint32_t>(new_offsets.begin(), new_offsets.end()).swap(sb.offsets);
    std::vector<std::uint8_t>(new_data.begin(), new_data.end()).swap(sb.data);
  }

  /** \brief The stored blocks, in key order (z, then y, then x), for the outputs that
   * must not depend on the storage order. */
  std::vector<StoredBlock> sortedBlocks(std::uint8_t prior) const
  {
    std::vector<StoredBlock> sorted;
    for (const auto& sb : supers)
      for (int j = 0; j < SUPER_BLOCKS; ++j)
        if (sb.isMixed(j) || sb.code(j) != prior)
          sorted.push_back({blockKeyOf(sb.key, j), &sb, j});
    std::sort(sorted.begin(), sorted.end(),
              [](const StoredBlock& a, const StoredBlock& b) { return a.key < b.key; });
    return sorted;
  }
};

/** \brief Voxel-by-voxel writes through the edit buffer, for writes that stay in one
 * block for a while (a row of pixels, a ray): remembers the last block. */
class ExplicitSpaceGrid::Impl::Cursor {
public:
  Cursor(Impl& impl, std::uint8_t prior) : impl_(impl), prior_(prior) {}

  /** \brief The edit of the block of voxel (kx, ky, kz); \a i is set to the voxel's
   * index in it. */
  std::uint32_t at(int kx, int ky, int kz, int& i)
  {
    const BlockKey bk{blockOf(kx), blockOf(ky), blockOf(kz)};
    if (cached_ == KeyIndex::NONE || !(bk == cached_key_)) {
      cached_ = impl_.open(bk, prior_);
      cached_key_ = bk;
    }
    i = localOf(kx) + 8 * localOf(ky) + 64 * localOf(kz);
    return cached_;
  }

private:
  Impl& impl_;
  std::uint8_t prior_;
  BlockKey cached_key_{0, 0, 0};
  std::uint32_t cached_{KeyIndex::NONE};
};

// ---------------------------------------------------------------------------------

std::string
toString(SpaceState state)
{
  switch (state) {
    case SpaceState::FREE:
      return "free";
    case SpaceState::OCCUPIED:
      return "occupied";
    case SpaceState::UNKNOWN:
      return "unknown";
  }
  return "invalid";
}

SpaceState
spaceStateFromString(const std::string& name)
{
  if (name == "free")
    return SpaceState::FREE;
  if (name == "occupied")
    return SpaceState::OCCUPIED;
  if (name == "unknown")
    return SpaceState::UNKNOWN;
  throw Exception("Unknown space state '" + name
                  + "' (expected free, occupied or unknown)");
}

DepthImage
DepthImage::fromDisparity(const float* disparity,
                          int width,
                          int height,
                          std::size_t row_stride_bytes,
                          const StereoCalibration& calibration)
{
  if (width <= 0 || height <= 0 || disparity == nullptr)
    throw Exception("DepthImage::fromDisparity: image size must be positive, got "
                    + std::to_string(width) + "x" + std::to_string(height));
  if (row_stride_bytes < static_cast<std::size_t>(width) * sizeof(float))
    throw Exception("DepthImage::fromDisparity: row stride "
                    + std::to_string(row_stride_bytes)
                    + " bytes is shorter than a row");
  if (!(calibration.focal_length_px > 0.0) || !(calibration.baseline_m > 0.0))
    throw Exception("DepthImage::fromDisparity: the calibration needs focal_length_px "
                    "> 0 and baseline_m > 0");
  DepthImage image;
  image.width = width;
  image.height = height;
  image.fx = image.fy = static_cast<float>(calibration.focal_length_px);
  image.cx = static_cast<float>(calibration.cx_px);
  image.cy = static_cast<float>(calibration.cy_px);
  image.depth_m.assign(static_cast<std::size_t>(width)
                         * static_cast<std::size_t>(height),
                       std::numeric_limits<float>::quiet_NaN());
  const auto fb =
    static_cast<float>(calibration.focal_length_px * calibration.baseline_m);
  const auto* bytes = reinterpret_cast<const unsigned char*>(disparity);
  for (int v = 0; v < height; ++v) {
    const auto* row = reinterpret_cast<const float*>(
      bytes + static_cast<std::size_t>(v) * row_stride_bytes);
    float* out = image.depth_m.data()
                 + static_cast<std::size_t>(v) * static_cast<std::size_t>(width);
    for (int u = 0; u < width; ++u)
      if (row[u] > 0.0f && std::isfinite(row[u]))
        out[u] = fb / row[u];
  }
  return image;
}

std::size_t
DepthImage::countValid() const
{
  std::size_t n = 0;
  for (const float d : depth_m)
    n += (d > 0.0f && std::isfinite(d));
  return n;
}

DepthImage
DepthImage::fromPointCloud(const pcl::PointCloud<pcl::PointXYZ>& cloud,
                           int width,
                           int height,
                           float fx,
                           float fy,
                           float cx,
                           float cy)
{
  if (width <= 0 || height <= 0)
    throw Exception("DepthImage::fromPointCloud: image size must be positive, got "
                    + std::to_string(width) + " x " + std::to_string(height));
  if (!(fx > 0.0f) || !(fy > 0.0f) || !std::isfinite(fx) || !std::isfinite(fy)
      || !std::isfinite(cx) || !std::isfinite(cy))
    throw Exception("DepthImage::fromPointCloud: focal lengths must be finite and "
                    "positive, principal point finite");
  DepthImage image;
  image.width = width;
  image.height = height;
  image.fx = fx;
  image.fy = fy;
  image.cx = cx;
  image.cy = cy;
  image.depth_m.assign(static_cast<std::size_t>(width)
                         * static_cast<std::size_t>(height),
                       std::numeric_limits<float>::quiet_NaN());
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z)
        || !(p.z > 0.0f))
      continue;
    const float u = std::floor(fx * p.x / p.z + cx + 0.5f);
    const float v = std::floor(fy * p.y / p.z + cy + 0.5f);
    if (!(u >= 0.0f && u < static_cast<float>(width) && v >= 0.0f
          && v < static_cast<float>(height)))
      continue;
    float& d =
      image.depth_m[static_cast<std::size_t>(v) * static_cast<std::size_t>(width)
                    + static_cast<std::size_t>(u)];
    if (!(d <= p.z)) // NaN (empty) or farther
      d = p.z;
  }
  return image;
}

// ---------------------------------------------------------------------------------

ExplicitSpaceGrid::ExplicitSpaceGrid(const Params& params) :
    impl_(std::make_unique<Impl>()), params_(params)
{
  if (!(params.resolution_m > 0.0) || !std::isfinite(params.resolution_m))
    throw Exception("ExplicitSpaceGrid: resolution_m must be finite and > 0, got "
                    + std::to_string(params.resolution_m));
  if (!(params.max_range_m > 0.0) || !std::isfinite(params.max_range_m))
    throw Exception("ExplicitSpaceGrid: max_range_m must be finite and > 0, got "
                    + std::to_string(params.max_range_m));
  if (!(params.surface_margin_m >= 0.0) || !std::isfinite(params.surface_margin_m))
    throw Exception("ExplicitSpaceGrid: surface_margin_m must be finite and >= 0, got "
                    + std::to_string(params.surface_margin_m));
  if (params.prior != SpaceState::FREE && params.prior != SpaceState::UNKNOWN)
    throw Exception("ExplicitSpaceGrid: prior must be free or unknown, got "
                    + toString(params.prior));
}

ExplicitSpaceGrid::~ExplicitSpaceGrid() = default;
ExplicitSpaceGrid::ExplicitSpaceGrid(ExplicitSpaceGrid&&) noexcept = default;
ExplicitSpaceGrid& ExplicitSpaceGrid::operator=(ExplicitSpaceGrid&&) noexcept = default;

ExplicitSpaceGrid::VoxelKey
ExplicitSpaceGrid::toKey(const Eigen::Vector3f& point) const
{
  VoxelKey key;
  for (int a = 0; a < 3; ++a) {
    const double k = std::floor(static_cast<double>(point[a]) / params_.resolution_m);
    key[a] = static_cast<int>(std::clamp(k, -MAX_KEY, MAX_KEY));
  }
  return key;
}

Eigen::Vector3f
ExplicitSpaceGrid::toCentre(const VoxelKey& key) const
{
  return ((key.cast<double>().array() + 0.5) * params_.resolution_m).cast<float>();
}

SpaceState
ExplicitSpaceGrid::getState(const Eigen::Vector3f& point) const
{
  if (!point.allFinite())
    return params_.prior;
  for (int a = 0; a < 3; ++a)
    if (std::abs(static_cast<double>(point[a]) / params_.resolution_m) >= MAX_KEY)
      return params_.prior;
  return getState(toKey(point));
}

SpaceState
ExplicitSpaceGrid::getState(const VoxelKey& key) const
{
  return stateOf(impl_->codeAt(key.x(), key.y(), key.z(), priorCode(params_.prior)),
                 params_.prior);
}

void
ExplicitSpaceGrid::setState(const VoxelKey& key, SpaceState state)
{
  if (state != SpaceState::FREE && state != SpaceState::OCCUPIED
      && state != SpaceState::UNKNOWN)
    throw Exception("ExplicitSpaceGrid::setState: invalid state");
  const auto prior = priorCode(params_.prior);
  const auto s = static_cast<std::uint8_t>(state);
  if (impl_->codeAt(key.x(), key.y(), key.z(), prior) == s)
    return;
  // The write waits in the edit buffer: voxel-by-voxel writes cost no rebuild of
  // their super-block each; queries read the buffer or commit it first.
  const BlockKey bk{blockOf(key.x()), blockOf(key.y()), blockOf(key.z())};
  const std::uint32_t e = impl_->open(bk, prior);
  impl_->setEdit(e, localOf(key.x()) + 8 * localOf(key.y()) + 64 * localOf(key.z()), s);
  if (impl_->edits.size() >= MAX_PENDING_BLOCKS)
    impl_->commit(prior);
}

void
ExplicitSpaceGrid::clear()
{
  impl_->discardEdits();
  std::vector<SuperBlock>().swap(impl_->supers);
  impl_->directory.release();
}

// ---------------------------------------------------------------------------------

void
ExplicitSpaceGrid::integrateDepthImage(const DepthImage& depth,
                                       const Eigen::Isometry3d& world_T_camera)
{
  if (depth.width <= 0 || depth.height <= 0 || depth.depth_m.empty()) {
    PCL_WARN("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Empty depth image, "
             "nothing integrated.\n");
    return;
  }
  if (depth.depth_m.size()
        != static_cast<std::size_t>(depth.width)
             * static_cast<std::size_t>(depth.height)
      || !(depth.fx > 0.0f) || !(depth.fy > 0.0f) || !std::isfinite(depth.fx)
      || !std::isfinite(depth.fy) || !std::isfinite(depth.cx)
      || !std::isfinite(depth.cy) || !world_T_camera.matrix().allFinite()) {
    PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Inconsistent "
              "depth image (%d x %d with %zu depths, fx %g, fy %g) or pose; nothing "
              "integrated.\n",
              depth.width, depth.height, depth.depth_m.size(),
              static_cast<double>(depth.fx), static_cast<double>(depth.fy));
    return;
  }

  Impl& impl = *impl_;
  DepthPyramid& pyr = impl.pyramid;
  float max_valid_depth = 0.0f;
  pyr.build(depth, max_valid_depth);

  const float res = static_cast<float>(params_.resolution_m);
  const float max_range = static_cast<float>(params_.max_range_m);
  const float margin =
    params_.surface_margin_m > 0.0
      ? static_cast<float>(params_.surface_margin_m)
      : static_cast<float>(params_.resolution_m * std::sqrt(3.0) / 2.0);
  const auto prior = priorCode(params_.prior);
  const bool mark_occluded = params_.prior != SpaceState::UNKNOWN;
  // With an unknown prior, occlusion changes nothing: only space up to the farthest
  // measurement can change.
  const float z_far =
    mark_occluded ? max_range : std::min(max_range, max_valid_depth + margin);
  const int W = depth.width, H = depth.height;
  const float fx = depth.fx, fy = depth.fy, cx = depth.cx, cy = depth.cy;

  const Eigen::Isometry3f w_T_c = world_T_camera.cast<float>();
  const Eigen::Matrix3f R_cw = w_T_c.linear().transpose();
  const Eigen::Vector3f t_cw = -(R_cw * w_T_c.translation());

  // Voxels of the measured surface: every valid pixel within max_range back-projected.
  // Done first into a list, applied after the free / occluded pass so that it wins.
  if (max_valid_depth > 0.0f && z_far > NEAR_Z) {
    // Frustum bounding box in the world frame.
    Eigen::Vector3f lo = w_T_c.translation(), hi = lo;
    for (const float u : {-0.5f, static_cast<float>(W) - 0.5f})
      for (const float v : {-0.5f, static_cast<float>(H) - 0.5f}) {
        const Eigen::Vector3f pc((u - cx) / fx * z_far, (v - cy) / fy * z_far, z_far);
        const Eigen::Vector3f pw = w_T_c * pc;
        lo = lo.cwiseMin(pw);
        hi = hi.cwiseMax(pw);
      }
    const double span =
      static_cast<double>((hi - lo).maxCoeff()) / params_.resolution_m;
    if (span > 1e6
        || std::abs(lo.cast<double>().maxCoeff()) / params_.resolution_m > 1e9
        || std::abs(lo.cast<double>().minCoeff()) / params_.resolution_m > 1e9
        || std::abs(hi.cast<double>().maxCoeff()) / params_.resolution_m > 1e9
        || std::abs(hi.cast<double>().minCoeff()) / params_.resolution_m > 1e9) {
      PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] Frustum of "
                "%g voxels across or far from the origin; nothing integrated.\n",
                span);
      return;
    }
    const VoxelKey klo = toKey(lo), khi = toKey(hi);
    const BlockKey blo{blockOf(klo.x()), blockOf(klo.y()), blockOf(klo.z())};
    const BlockKey bhi{blockOf(khi.x()), blockOf(khi.y()), blockOf(khi.z())};

    const float block_edge = res * BLOCK_EDGE;
    const Eigen::Vector3f ex = R_cw.col(0) * res, ey = R_cw.col(1) * res,
                          ez = R_cw.col(2) * res;
    const float half_diag_px = std::max(fx, fy) * res * 0.8660254f;
    const float u_end = static_cast<float>(W) - 0.5f,
                v_end = static_cast<float>(H) - 0.5f;
    const int max_r = std::max(W, H);

    enum class Cube { NONE, FREE, OCCLUDED, SPLIT };
    struct CubeInfo {
      int r{0};                       // footprint radius of its voxels, pixels
      int u0{0}, v0{0}, u1{0}, v1{0}; // pixel region (clamped)
    };
    // Classifies the cube of s^3 voxels whose min corner is c (camera frame).
    const auto classify = [&](const Eigen::Vector3f& c, float s, CubeInfo& info) {
      const Eigen::Vector3f sx = s * ex, sy = s * ey, sz = s * ez;
      std::array<Eigen::Vector3f, 8> corners;
      float zmin = std::numeric_limits<float>::infinity(), zmax = -zmin;
      for (int i = 0; i < 8; ++i) {
        auto& p = corners[static_cast<std::size_t>(i)];
        p = c;
        if (i & 1)
          p += sx;
        if (i & 2)
          p += sy;
        if (i & 4)
          p += sz;
        zmin = std::min(zmin, p.z());
        zmax = std::max(zmax, p.z());
      }
      if (zmax <= NEAR_Z || zmin > z_far)
        return Cube::NONE;
      if (zmin <= NEAR_Z) { // straddles the camera plane: voxel by voxel
        info = {max_r, 0, 0, W - 1, H - 1};
        return Cube::SPLIT;
      }
      float umin = std::numeric_limits<float>::infinity(), umax = -umin, vmin = umin,
            vmax = -umin;
      for (const auto& p : corners) {
        const float inv = 1.0f / p.z();
        const float u = fx * p.x() * inv + cx, v = fy * p.y() * inv + cy;
        umin = std::min(umin, u);
        umax = std::max(umax, u);
        vmin = std::min(vmin, v);
        vmax = std::max(vmax, v);
      }
      if (umax < -0.5f || vmax < -0.5f || umin >= u_end || vmin >= v_end)
        return Cube::NONE;
      const bool inside =
        umin >= -0.5f && vmin >= -0.5f && umax < u_end && vmax < v_end;
      info.r = std::min(static_cast<int>(std::ceil(half_diag_px / zmin)), max_r);
      info.u0 = static_cast<int>(std::floor(umin + 0.5f)) - info.r;
      info.v0 = static_cast<int>(std::floor(vmin + 0.5f)) - info.r;
      info.u1 = static_cast<int>(std::floor(umax + 0.5f)) + info.r;
      info.v1 = static_cast<int>(std::floor(vmax + 0.5f)) + info.r;
      pyr.clampRect(info.u0, info.v0, info.u1, info.v1);
      float mn, mx;
      pyr.queryRect(info.u0, info.v0, info.u1, info.v1, mn, mx);
      if (std::isinf(mn))
        return Cube::NONE; // no measurement under the cube: no information
      if (zmax < mn - margin) {
        if (!inside || zmax > max_range)
          return Cube::SPLIT;
        // every voxel's footprint must hold a measurement: it contains a whole cell
        // of level j
        const int r_far = static_cast<int>(half_diag_px / zmax);
        int j = 0;
        while ((2 << j) <= r_far + 1)
          ++j;
        return pyr.noHoles(j, info.u0, info.v0, info.u1, info.v1) ? Cube::FREE
                                                                  : Cube::SPLIT;
      }
      if (zmin > mx + margin) { // behind every measurement of the region
        if (!mark_occluded)
          return Cube::NONE;
        return inside && zmax <= max_range
                   && pyr.noHoles(0, info.u0, info.v0, info.u1, info.v1)
                 ? Cube::OCCLUDED
                 : Cube::SPLIT;
      }
      return Cube::SPLIT;
    };
    const VoxelKernel kernel{
      fx,        fy,     cx, cy, u_end,         v_end,
      max_range, margin, W,  H,  mark_occluded, pyr.min_level[0].data()};
    // Every footprint radius is at least that of a voxel at z_far.
    pyr.buildSpans(pyr.levelFor(
      std::min(static_cast<int>(std::ceil(half_diag_px / z_far)), max_r) + 1));
    // Voxel-by-voxel observations of the 4^3 cube at local offset o of a block whose
    // min corner is c0, as bits (x + 8 y) of words z of the free / occluded masks.
    const auto perVoxel = [&](const Eigen::Vector3f& c0, int ox, int oy, int oz,
                              const CubeInfo& info, BlockResult& res) {
      const int level = pyr.levelFor(info.r + 1); // at most 3 x 3 cells per footprint
      observeCube(kernel, pyr, level, info.r, c0, ex, ey, ez, ox, oy, oz, res.free,
                  res.occluded);
    };
    // Bits of the 4^3 cube at local offset o in the masks.
    const auto cubeBits = [](std::array<std::uint64_t, BLOCK_EDGE>& mask, int ox,
                             int oy, int oz) {
      const std::uint64_t rows = std::uint64_t{0xF0F0F0F} << (ox + 8 * oy);
      for (int z = oz; z < oz + 4; ++z)
        mask[static_cast<std::size_t>(z)] |= rows;
    };
    // The observations of block (bx, by, bz); false when the view says nothing of it.
    // Inward unit normals of the frustum's side planes (through the camera centre,
    // along the image border u = -0.5, u = W - 0.5, v = -0.5, v = H - 0.5).
    const std::array<Eigen::Vector3f, 4> side_normals{
      Eigen::Vector3f(fx, 0.0f, cx + 0.5f).normalized(),
      Eigen::Vector3f(-fx, 0.0f, u_end - cx).normalized(),
      Eigen::Vector3f(0.0f, fy, cy + 0.5f).normalized(),
      Eigen::Vector3f(0.0f, -fy, v_end - cy).normalized()};
    const Eigen::Vector3f block_half = (ex + ey + ez) * (0.5f * BLOCK_EDGE);
    // half block diagonal plus slack for rounding
    const float reject_radius = block_half.norm() * 1.01f + 1e-3f;
    const auto observeBlock = [&](int bx, int by, int bz, BlockResult& res,
                                  Counters& counters) {
      const Eigen::Vector3f c0 =
        R_cw
          * Eigen::Vector3f(static_cast<float>(bx) * block_edge,
                            static_cast<float>(by) * block_edge,
                            static_cast<float>(bz) * block_edge)
        + t_cw;
      // Blocks whose bounding sphere lies (with slack) beyond the depth range or
      // outside a side plane of the frustum project outside the image: classify()
      // would say NONE; skip its 8 projections.
      const Eigen::Vector3f centre = c0 + block_half;
      if (centre.z() + reject_radius <= NEAR_Z || centre.z() - reject_radius > z_far)
        return false;
      if (centre.z() - reject_radius > NEAR_Z)
        for (const auto& n : side_normals)
          if (n.dot(centre) < -reject_radius)
            return false;
      CubeInfo info;
      const Cube kind = classify(c0, static_cast<float>(BLOCK_EDGE), info);
      if (kind == Cube::NONE)
        return false;
      ++counters.visited;
      res.key = {bx, by, bz};
      if (kind == Cube::FREE) {
        ++counters.fast;
        res.kind = BlockResult::ALL_FREE;
        return true;
      }
      if (kind == Cube::OCCLUDED) {
        res.kind = BlockResult::ALL_OCCLUDED;
        return true;
      }
      res.kind = BlockResult::MASKS;
      res.free.fill(0);
      res.occluded.fill(0);
      bool any = false;
      for (int c = 0; c < 8; ++c) {
        const int ox = (c & 1) * 4, oy = ((c >> 1) & 1) * 4, oz = ((c >> 2) & 1) * 4;
        const Eigen::Vector3f cc = c0 + static_cast<float>(ox) * ex
                                   + static_cast<float>(oy) * ey
                                   + static_cast<float>(oz) * ez;
        CubeInfo sub;
        const Cube sk = classify(cc, 4.0f, sub);
        if (sk == Cube::NONE)
          continue;
        if (sk == Cube::FREE) {
          cubeBits(res.free, ox, oy, oz);
          any = true;
        } else if (sk == Cube::OCCLUDED) {
          cubeBits(res.occluded, ox, oy, oz);
          any = true;
        } else {
          ++counters.slow;
          perVoxel(c0, ox, oy, oz, sub, res);
        }
      }
      if (!any)
        for (int z = 0; z < BLOCK_EDGE; ++z)
          any = any || res.free[static_cast<std::size_t>(z)] != 0
                || res.occluded[static_cast<std::size_t>(z)] != 0;
      return any;
    };

    // Observe the blocks of the frustum's bounding box (slabs of z split between the
    // threads, each slab's blocks in x-fastest order: the concatenation is the
    // single-threaded order), then apply the observations one block at a time.
    const int n_slabs = bhi.z - blo.z + 1;
    const int n_threads = std::max(1, std::min(num_threads_, n_slabs));
    auto& per_thread = impl_->results;
    per_thread.resize(static_cast<std::size_t>(n_threads));
    std::vector<Counters> counters(static_cast<std::size_t>(n_threads));
    const auto work = [&](int t) {
      auto& out = per_thread[static_cast<std::size_t>(t)];
      out.clear();
      const int z0 =
        blo.z + static_cast<int>(static_cast<long long>(n_slabs) * t / n_threads);
      const int z1 =
        blo.z + static_cast<int>(static_cast<long long>(n_slabs) * (t + 1) / n_threads);
      BlockResult res;
      for (int bz = z0; bz < z1; ++bz)
        for (int by = blo.y; by <= bhi.y; ++by)
          for (int bx = blo.x; bx <= bhi.x; ++bx)
            if (observeBlock(bx, by, bz, res, counters[static_cast<std::size_t>(t)]))
              out.push_back(res);
    };
    if (n_threads == 1)
      work(0);
    else {
      std::vector<std::thread> threads;
      for (int t = 1; t < n_threads; ++t)
        threads.emplace_back(work, t);
      work(0);
      for (auto& th : threads)
        th.join();
    }

    // The observations go to the edit buffer, block by block; the occupied voxels
    // below are written over them, and both reach the storage at once.
    const auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
    const auto unknown_code = static_cast<std::uint8_t>(SpaceState::UNKNOWN);
    constexpr std::uint64_t LOW = 0x5555555555555555ULL;
    for (const auto& list : per_thread)
      for (const BlockResult& res : list) {
        const std::uint32_t e = impl.open(res.key, prior);
        if (res.kind == BlockResult::ALL_FREE) {
          // Whole block in front of the surface: free without per-voxel work (observed
          // free is never the code of the prior).
          impl.edits[e].uniform = free_code;
          continue;
        }
        Payload& words = impl.mixedPayload(e);
        for (int k = 0; k < 16; ++k) {
          // voxels 32 k .. 32 k + 31: half of mask word k / 2
          const int shift = (k & 1) * 32;
          const std::uint64_t fs =
            res.kind == BlockResult::ALL_OCCLUDED
              ? 0
              : spreadBits(static_cast<std::uint32_t>(
                res.free[static_cast<std::size_t>(k >> 1)] >> shift));
          const std::uint64_t os =
            res.kind == BlockResult::ALL_OCCLUDED
              ? LOW
              : spreadBits(static_cast<std::uint32_t>(
                res.occluded[static_cast<std::size_t>(k >> 1)] >> shift));
          std::uint64_t w = words[static_cast<std::size_t>(k)];
          const std::uint64_t x = w ^ pattern(prior);
          const std::uint64_t at_prior = ~(x | (x >> 1)) & LOW;
          // occluded turns only the never-observed voxels unknown
          const std::uint64_t occ = os & at_prior;
          w &= ~((fs | occ) * 3);  // free = 00
          w |= occ * unknown_code; // unknown = 10
          words[static_cast<std::size_t>(k)] = w;
        }
      }
    Counters total;
    for (const auto& c : counters) {
      total.visited += c.visited;
      total.fast += c.fast;
      total.slow += c.slow;
    }
    PCL_DEBUG("[planar_grid::ExplicitSpaceGrid::integrateDepthImage] %zu blocks "
              "seen, %zu free as a whole, %zu 4^3 cubes voxel by voxel.\n",
              total.visited, total.fast, total.slow);
  }

  // Occupied: the voxel of every measured pixel within max_range. Neighbouring pixels
  // mostly fall in one voxel, which is written once per run of them.
  Impl::Cursor cursor(impl, prior);
  const auto occupied_code = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  const float inv_res = 1.0f / res;
  std::vector<float>& column_x = impl.column_x; // (u - cx) / fx
  column_x.resize(static_cast<std::size_t>(W));
  for (int u = 0; u < W; ++u)
    column_x[static_cast<std::size_t>(u)] = (static_cast<float>(u) - cx) / fx;
  for (int v = 0; v < H; ++v) {
    const float yn = (static_cast<float>(v) - cy) / fy;
    const float* row =
      &pyr.min_level[0][static_cast<std::size_t>(v) * static_cast<std::size_t>(W)];
    // |key| < 2^30 below: no voxel has this key
    int last_x = std::numeric_limits<int>::min(), last_y = 0, last_z = 0;
    for (int u = 0; u < W; ++u) {
      const float d = row[u];
      if (!(d <= max_range)) // +inf marks no measurement
        continue;
      const Eigen::Vector3f pc(column_x[static_cast<std::size_t>(u)] * d, yn * d, d);
      const Eigen::Vector3f pw = (w_T_c * pc) * inv_res;
      if (!(pw.cwiseAbs().maxCoeff() < static_cast<float>(MAX_KEY)))
        continue;
      const int kx = floorToInt(pw.x()), ky = floorToInt(pw.y()),
                kz = floorToInt(pw.z());
      if (kx == last_x && ky == last_y && kz == last_z)
        continue;
      last_x = kx;
      last_y = ky;
      last_z = kz;
      int i = 0;
      const std::uint32_t e = cursor.at(kx, ky, kz, i);
      impl.setEdit(e, i, occupied_code);
    }
  }
  impl.commit(prior);
}

void
ExplicitSpaceGrid::integratePointCloud(const pcl::PointCloud<pcl::PointXYZ>& points,
                                       const Eigen::Vector3f& sensor_origin)
{
  if (!sensor_origin.allFinite())
    throw Exception("ExplicitSpaceGrid::integratePointCloud: non-finite sensor origin");
  const double res = params_.resolution_m;
  const double max_t = params_.max_range_m / res; // voxel units
  const double margin =
    (params_.surface_margin_m > 0.0 ? params_.surface_margin_m
                                    : params_.resolution_m * std::sqrt(3.0) / 2.0)
    / res;
  const Eigen::Vector3d o = sensor_origin.cast<double>() / res;
  if (o.cwiseAbs().maxCoeff() + max_t >= MAX_KEY) {
    PCL_ERROR("[planar_grid::ExplicitSpaceGrid::integratePointCloud] Sensor origin "
              "too far from the map's origin; nothing integrated.\n");
    return;
  }
  Impl& impl = *impl_;
  const auto prior = priorCode(params_.prior);
  const auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
  const auto occupied_code = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  Impl::Cursor cursor(impl, prior);
  const auto set = [&](int kx, int ky, int kz, std::uint8_t state) {
    int i = 0;
    const std::uint32_t e = cursor.at(kx, ky, kz, i);
    const std::uint8_t current = impl.getEdit(e, i);
    // A ray passing through an occupied voxel leaves it occupied: one hit outweighs one
    // miss, as in OctoMap's sensor model (log-odds +0.85 against -0.41), and rays from
    // another scan graze floors and walls near their points.
    if (current == state || (current == occupied_code && state == free_code))
      return;
    impl.setEdit(e, i, state);
  };

  // Free: every voxel a ray crosses before its point's voxel (3D DDA, Amanatides and
  // Woo), up to max_range_m.
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d e = p.getVector3fMap().cast<double>() / res;
    const Eigen::Vector3d v = e - o;
    const double length = v.norm();
    if (!(length > 0.0))
      continue;
    const Eigen::Vector3d d = v / length;
    // A hit clears space up to the surface margin before it, as integrateDepthImage
    // does in front of the measured depth: rays that graze a surface near their own
    // point do not erase it.
    const double t_end = std::min(length - margin, max_t);
    const bool hits = length <= max_t;
    std::array<int, 3> end_key{};
    if (hits)
      end_key = {static_cast<int>(std::floor(e.x())),
                 static_cast<int>(std::floor(e.y())),
                 static_cast<int>(std::floor(e.z()))};
    DdaWalk walk(o, d);
    double t = 0.0;
    while (t <= t_end) {
      if (hits && walk.key == end_key)
        break;
      set(walk.key[0], walk.key[1], walk.key[2], free_code);
      t = walk.advance();
    }
  }
  // Occupied: the voxel of every point within range.
  for (const auto& p : points) {
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d e = p.getVector3fMap().cast<double>() / res;
    if ((e - o).norm() > max_t)
      continue;
    set(static_cast<int>(std::floor(e.x())), static_cast<int>(std::floor(e.y())),
        static_cast<int>(std::floor(e.z())), occupied_code);
  }
  impl.commit(prior);
}

// ---------------------------------------------------------------------------------

bool
ExplicitSpaceGrid::castRay(const Eigen::Vector3f& origin,
                           const Eigen::Vector3f& direction,
                           double max_range_m,
                           Eigen::Vector3f& hit) const
{
  const double n = static_cast<double>(direction.norm());
  if (!origin.allFinite() || !direction.allFinite() || !(n > 0.0)
      || !(max_range_m >= 0.0) || !std::isfinite(max_range_m))
    return false;
  const double res = params_.resolution_m;
  const Eigen::Vector3d o = origin.cast<double>() / res;
  const Eigen::Vector3d d = direction.cast<double>() / n;
  const double max_t = max_range_m / res; // in voxel units
  if (o.cwiseAbs().maxCoeff() + max_t >= MAX_KEY)
    return false;
  impl_->settle(
    priorCode(params_.prior)); // pending setState() edits (content unchanged)
  DdaWalk walk(o, d);
  const auto occupied = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  const bool prior_occupied = params_.prior == SpaceState::OCCUPIED;
  BlockKey cached_key{0, 0, 0}; // super-block coordinates
  const SuperBlock* cached = nullptr;
  bool cached_valid = false;
  while (true) {
    const std::array<int, 3>& key = walk.key;
    const BlockKey bk{blockOf(key[0]), blockOf(key[1]), blockOf(key[2])};
    const BlockKey sk = Impl::superOf(bk);
    if (!cached_valid || !(sk == cached_key)) {
      cached = impl_->findSuper(sk);
      cached_key = sk;
      cached_valid = true;
    }
    const bool occ = cached ? cached->get(Impl::indexInSuper(bk), localOf(key[0]),
                                          localOf(key[1]), localOf(key[2]))
                                == occupied
                            : prior_occupied;
    if (occ) {
      hit = toCentre(VoxelKey(key[0], key[1], key[2]));
      return true;
    }
    if (walk.next() > max_t)
      return false;
    walk.advance();
  }
}

// ---------------------------------------------------------------------------------

void
ExplicitSpaceGrid::visitVoxels(void (*visit)(void*, const VoxelKey&, SpaceState),
                               void* context) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto sorted = impl_->sortedBlocks(prior);
  DenseBlock block;
  for (const auto& stored : sorted) {
    stored.super->load(stored.j, block);
    const BlockKey& bk = stored.key;
    for (int i = 0; i < BLOCK_VOXELS; ++i) {
      const std::uint8_t s = block.get(i);
      if (s == prior)
        continue;
      const VoxelKey key(bk.x * BLOCK_EDGE + (i & 7),
                         bk.y * BLOCK_EDGE + ((i >> 3) & 7),
                         bk.z * BLOCK_EDGE + (i >> 6));
      visit(context, key, stateOf(s, params_.prior));
    }
  }
}

std::size_t
ExplicitSpaceGrid::getVoxelCount(SpaceState state) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  if (static_cast<std::uint8_t>(state) == prior)
    return 0;
  std::array<std::size_t, 4> n{};
  for (const auto& sb : impl_->supers)
    for (int j = 0; j < SUPER_BLOCKS; ++j) {
      if (sb.isMixed(j))
        countCompact(sb.compact(j), n);
      else
        n[sb.code(j)] += BLOCK_VOXELS;
    }
  return n[static_cast<std::size_t>(state)];
}

std::size_t
ExplicitSpaceGrid::getBlockCount() const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  std::size_t n = 0;
  for (const auto& sb : impl_->supers)
    n += sb.stored;
  return n;
}

std::size_t
ExplicitSpaceGrid::getMemoryBytes() const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  // Every allocation of the storage: the super-block array's capacity, each
  // super-block's two arrays, the directory's slots, plus MALLOC_OVERHEAD per heap
  // allocation (the allocator's chunk header and rounding). The scratch buffers of
  // integration (depth pyramid, observations, edit buffer) are working memory of one
  // view, not the map's.
  constexpr std::size_t MALLOC_OVERHEAD = 16;
  const Impl& impl = *impl_;
  std::size_t bytes = sizeof(Impl);
  const auto heap = [](std::size_t n) {
    return n == 0 ? 0 : n + MALLOC_OVERHEAD;
  };
  bytes += heap(impl.supers.capacity() * sizeof(SuperBlock));
  for (const auto& sb : impl.supers)
    bytes +=
      heap(sb.offsets.capacity() * sizeof(std::uint32_t)) + heap(sb.data.capacity());
  bytes += heap(impl.directory.capacityBytes());
  return bytes;
}

bool
ExplicitSpaceGrid::getBounds(VoxelKey& min_key, VoxelKey& max_key) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  bool any = false;
  for (const auto& sb : impl_->supers)
    for (int j = 0; j < SUPER_BLOCKS; ++j)
      if (sb.isMixed(j) || sb.code(j) != prior) {
        const BlockKey k = blockKeyOf(sb.key, j);
        const Eigen::Vector3i b(k.x, k.y, k.z);
        lo = lo.cwiseMin(b);
        hi = hi.cwiseMax(b);
        any = true;
      }
  if (!any)
    return false;
  min_key = lo * BLOCK_EDGE;
  max_key = hi * BLOCK_EDGE + Eigen::Vector3i::Constant(BLOCK_EDGE - 1);
  return true;
}

bool
ExplicitSpaceGrid::operator==(const ExplicitSpaceGrid& other) const
{
  if (params_.resolution_m != other.params_.resolution_m
      || params_.prior != other.params_.prior)
    return false;
  const auto prior = priorCode(params_.prior);
  impl_->settle(prior); // pending setState() edits (content unchanged)
  other.impl_->settle(prior);
  const auto a = impl_->sortedBlocks(prior), b = other.impl_->sortedBlocks(prior);
  if (a.size() != b.size())
    return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const StoredBlock &x = a[k], &y = b[k];
    if (!(x.key == y.key) || x.super->isMixed(x.j) != y.super->isMixed(y.j))
      return false;
    if (!x.super->isMixed(x.j)) {
      if (x.super->code(x.j) != y.super->code(y.j))
        return false;
      continue;
    }
    // the compact form of a payload is unique
    const std::uint8_t *cx = x.super->compact(x.j), *cy = y.super->compact(y.j);
    const std::size_t n = compactSize(cx);
    if (n != compactSize(cy) || std::memcmp(cx, cy, n) != 0)
      return false;
  }
  return true;
}

// ---------------------------------------------------------------------------------
// Octree bit stream

namespace {

/** \brief Writes 2-bit labels, 4 per byte, first label in the low bits. */
struct LabelWriter {
  std::vector<std::uint8_t> bytes;
  std::uint64_t count{0};
  void put(std::uint8_t label)
  {
    const int slot = static_cast<int>(count & 3u);
    if (slot == 0)
      bytes.push_back(0);
    bytes.back() = static_cast<std::uint8_t>(bytes.back() | (label << (2 * slot)));
    ++count;
  }
  /** \brief A leaf of stored code \a code (version 3: a never-observed leaf is the
   * escape label followed by ESCAPED_NEVER_OBSERVED). */
  void putLeaf(std::uint8_t code)
  {
    if (code == NEVER_OBSERVED) {
      put(INNER_LABEL);
      put(ESCAPED_NEVER_OBSERVED);
    } else
      put(code);
  }
  /** \brief An inner node (version 3: the escape label, then ESCAPED_INNER). */
  void putInner()
  {
    put(INNER_LABEL);
    put(ESCAPED_INNER);
  }
};

/** \brief Packs relative block coordinates (each < 2^18) into one integer. */
inline std::uint64_t
packRel(std::uint64_t x, std::uint64_t y, std::uint64_t z)
{
  return x | (y << 21) | (z << 42);
}

/** \brief Emits the sub-octree of a mixed block region: cube of edge 2^level voxels at
 * local (x, y, z). */
void
emitInBlock(const DenseBlock& b, int level, int x, int y, int z, LabelWriter& out)
{
  const int e = 1 << level;
  const std::uint8_t s0 = b.get(x + 8 * y + 64 * z);
  bool uniform = true;
  for (int k = z; k < z + e && uniform; ++k)
    for (int j = y; j < y + e && uniform; ++j)
      for (int i = x; i < x + e; ++i)
        if (b.get(i + 8 * j + 64 * k) != s0) {
          uniform = false;
          break;
        }
  if (uniform) {
    out.putLeaf(s0);
    return;
  }
  out.putInner();
  const int h = e / 2;
  for (int c = 0; c < 8; ++c)
    emitInBlock(b, level - 1, x + (c & 1) * h, y + ((c >> 1) & 1) * h,
                z + ((c >> 2) & 1) * h, out);
}

} // namespace

void
ExplicitSpaceGrid::serialize(std::vector<std::uint8_t>& bytes) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto blocks = impl_->sortedBlocks(prior);
  Eigen::Vector3i root = Eigen::Vector3i::Zero();
  int depth = 0;
  LabelWriter out;
  if (blocks.empty())
    out.putLeaf(prior);
  else {
    Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
    Eigen::Vector3i hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
    for (const auto& stored : blocks) {
      const Eigen::Vector3i b(stored.key.x, stored.key.y, stored.key.z);
      lo = lo.cwiseMin(b);
      hi = hi.cwiseMax(b);
    }
    const std::int64_t extent = static_cast<std::int64_t>((hi - lo).maxCoeff()) + 1;
    int block_levels = 0; // root edge in blocks = 2^block_levels
    while ((std::int64_t{1} << block_levels) < extent)
      ++block_levels;
    depth = block_levels + BLOCK_SHIFT;
    if (depth > MAX_DEPTH)
      throw Exception("ExplicitSpaceGrid::serialize: the layer spans "
                      + std::to_string(extent) + " blocks, more than the 2^"
                      + std::to_string(MAX_DEPTH) + "-voxel octree the format allows");
    root = lo * BLOCK_EDGE;
    // Summaries per level (0 = blocks): uniform state or MIXED; absent = prior.
    std::vector<std::unordered_map<std::uint64_t, std::uint8_t>> summary(
      static_cast<std::size_t>(block_levels) + 1);
    std::unordered_map<std::uint64_t, const StoredBlock*> by_rel;
    by_rel.reserve(blocks.size());
    summary[0].reserve(blocks.size());
    for (const auto& stored : blocks) {
      const auto rel = packRel(static_cast<std::uint64_t>(stored.key.x - lo.x()),
                               static_cast<std::uint64_t>(stored.key.y - lo.y()),
                               static_cast<std::uint64_t>(stored.key.z - lo.z()));
      by_rel.emplace(rel, &stored);
      summary[0].emplace(
        rel, stored.super->isMixed(stored.j) ? MIXED : stored.super->code(stored.j));
    }
    constexpr std::uint64_t MASK = (std::uint64_t{1} << 21) - 1;
    for (int l = 1; l <= block_levels; ++l) {
      // count of children and their common uniform state (MIXED when they differ)
      std::unordered_map<std::uint64_t, std::pair<int, std::uint8_t>> acc;
      for (const auto& [rel, code] : summary[static_cast<std::size_t>(l - 1)]) {
        const auto parent = packRel((rel & MASK) >> 1, ((rel >> 21) & MASK) >> 1,
                                    ((rel >> 42) & MASK) >> 1);
        auto [it, fresh] = acc.emplace(parent, std::make_pair(0, code));
        ++it->second.first;
        if (!fresh && it->second.second != code)
          it->second.second = MIXED;
      }
      auto& level = summary[static_cast<std::size_t>(l)];
      level.reserve(acc.size());
      for (const auto& [rel, a] : acc)
        level.emplace(rel, a.first == 8 ? a.second : MIXED);
    }
    // Depth-first emission, children x fastest, then y, then z.
    struct Emitter {
      const std::vector<std::unordered_map<std::uint64_t, std::uint8_t>>& summary;
      const std::unordered_map<std::uint64_t, const StoredBlock*>& by_rel;
      std::uint8_t prior;
      LabelWriter& out;
      DenseBlock block;
      void emit(int l, std::uint64_t x, std::uint64_t y, std::uint64_t z)
      {
        const auto& level = summary[static_cast<std::size_t>(l)];
        const auto it = level.find(packRel(x, y, z));
        if (it == level.end()) {
          out.putLeaf(prior);
          return;
        }
        if (it->second != MIXED) {
          out.putLeaf(it->second);
          return;
        }
        if (l == 0) {
          const StoredBlock& stored = *by_rel.at(packRel(x, y, z));
          stored.super->load(stored.j, block);
          emitInBlock(block, BLOCK_SHIFT, 0, 0, 0, out);
          return;
        }
        out.putInner();
        for (std::uint64_t c = 0; c < 8; ++c)
          emit(l - 1, 2 * x + (c & 1), 2 * y + ((c >> 1) & 1), 2 * z + ((c >> 2) & 1));
      }
    } emitter{summary, by_rel, prior, out, {}};
    emitter.emit(block_levels, 0, 0, 0);
  }
  for (int a = 0; a < 3; ++a)
    putU32(bytes, static_cast<std::uint32_t>(root[a]));
  bytes.push_back(static_cast<std::uint8_t>(depth));
  bytes.push_back(static_cast<std::uint8_t>(params_.prior));
  for (int i = 0; i < 8; ++i)
    bytes.push_back(static_cast<std::uint8_t>(out.count >> (8 * i)));
  bytes.insert(bytes.end(), out.bytes.begin(), out.bytes.end());
}

namespace {

/** \brief A leaf of a decoded stream whose state differs from the prior. */
struct DecodedLeaf {
  int level;
  std::int64_t x, y, z; // min voxel key
  std::uint8_t state;
};

struct StreamParser {
  const std::uint8_t* labels;
  std::uint64_t count;
  std::uint64_t next{0};
  /** \brief The stream's prior label (0 free, 2 unknown). */
  std::uint8_t prior_label;
  /** \brief The code stored for a never-observed voxel (priorCode()). */
  std::uint8_t prior;
  /** \brief Version 3 escapes inner nodes and never-observed leaves; versions 1 and 2
   * have the inner label alone, and a leaf with the prior's label is never observed. */
  bool escaped;
  std::uint64_t blocks_needed{0};
  std::vector<DecodedLeaf> leaves;

  std::uint8_t read()
  {
    if (next >= count)
      throw IOError("space layer stream: truncated octree (more nodes than the "
                    + std::to_string(count) + " labels announced)");
    const std::uint8_t l =
      static_cast<std::uint8_t>((labels[next >> 2] >> (2 * (next & 3u))) & 3u);
    ++next;
    return l;
  }

  /** \brief Returned by readNode() for an inner node (not a 2-bit code). */
  static constexpr std::uint8_t INNER_NODE = 0xff;

  /** \brief The next node: INNER_NODE, or the stored code of a leaf. */
  std::uint8_t readNode()
  {
    const std::uint8_t label = read();
    if (!escaped) {
      if (label == INNER_LABEL)
        return INNER_NODE;
      return label == prior_label ? prior : label;
    }
    if (label != INNER_LABEL)
      return label;
    const std::uint8_t second = read();
    if (second == ESCAPED_INNER)
      return INNER_NODE;
    if (second == ESCAPED_NEVER_OBSERVED && prior == NEVER_OBSERVED)
      return NEVER_OBSERVED;
    throw IOError("space layer stream: label " + std::to_string(second)
                  + " after the escape label 11 (label " + std::to_string(next - 1)
                  + ") is neither 11 (inner node) nor, with the free prior, 00 (never "
                    "observed)");
  }

  void parse(int level, std::int64_t x, std::int64_t y, std::int64_t z)
  {
    const std::uint8_t label = readNode();
    if (label == INNER_NODE) {
      if (level == 0)
        throw IOError("space layer stream: inner node at voxel level (label "
                      + std::to_string(next - 1) + ")");
      // An inner node at block level is one mixed block, however many leaves it holds
      // (they are contiguous in depth-first order).
      if (level == BLOCK_SHIFT && ++blocks_needed > MAX_DECODED_BLOCKS)
        throw IOError("space layer stream: more than "
                      + std::to_string(MAX_DECODED_BLOCKS) + " blocks");
      const std::int64_t h = std::int64_t{1} << (level - 1);
      for (int c = 0; c < 8; ++c)
        parse(level - 1, x + (c & 1) * h, y + ((c >> 1) & 1) * h,
              z + ((c >> 2) & 1) * h);
      return;
    }
    if (label == prior)
      return;
    if (level >= BLOCK_SHIFT) {
      const std::uint64_t n = std::uint64_t{1} << (3 * (level - BLOCK_SHIFT));
      if (n > MAX_DECODED_BLOCKS || blocks_needed + n > MAX_DECODED_BLOCKS)
        throw IOError("space layer stream: non-prior leaves cover more than "
                      + std::to_string(MAX_DECODED_BLOCKS) + " blocks");
      blocks_needed += n;
    }
    // A leaf below block level lies in a mixed block counted at its inner node.
    leaves.push_back({level, x, y, z, label});
  }
};

} // namespace

void
ExplicitSpaceGrid::deserialize(const std::uint8_t* data,
                               std::size_t size,
                               unsigned format_version)
{
  if (format_version < OLDEST_STREAM_VERSION || format_version > STREAM_VERSION)
    throw IOError("space layer stream: version " + std::to_string(format_version)
                  + " is not supported (this reader knows versions "
                  + std::to_string(OLDEST_STREAM_VERSION) + " to "
                  + std::to_string(STREAM_VERSION) + ")");
  if (size < HEADER_BYTES || data == nullptr)
    throw IOError("space layer stream: " + std::to_string(size)
                  + " bytes, fewer than the " + std::to_string(HEADER_BYTES)
                  + "-byte header");
  std::array<std::int64_t, 3> root{};
  for (int a = 0; a < 3; ++a)
    root[static_cast<std::size_t>(a)] =
      static_cast<std::int32_t>(static_cast<std::uint32_t>(getLE(data + 4 * a, 4)));
  const int depth = data[12];
  const std::uint8_t prior_label = data[13];
  const std::uint64_t count = getLE(data + 14, 8);
  if (depth > MAX_DEPTH)
    throw IOError("space layer stream: octree depth " + std::to_string(depth)
                  + " exceeds " + std::to_string(MAX_DEPTH));
  if (prior_label != static_cast<std::uint8_t>(SpaceState::FREE)
      && prior_label != static_cast<std::uint8_t>(SpaceState::UNKNOWN))
    throw IOError("space layer stream: prior label " + std::to_string(prior_label)
                  + " is neither free (0) nor unknown (2)");
  const auto prior_state = static_cast<SpaceState>(prior_label);
  const std::uint8_t prior = priorCode(prior_state);
  for (int a = 0; a < 3; ++a) {
    const std::int64_t r = root[static_cast<std::size_t>(a)];
    if (r % BLOCK_EDGE != 0)
      throw IOError("space layer stream: root key " + std::to_string(r)
                    + " is not a multiple of the 8-voxel block");
    if (r + (std::int64_t{1} << depth) - 1 > std::numeric_limits<std::int32_t>::max())
      throw IOError("space layer stream: octree exceeds the 32-bit key range");
  }
  const std::size_t payload = size - HEADER_BYTES;
  if (count == 0 || count > static_cast<std::uint64_t>(payload) * 4)
    throw IOError("space layer stream: " + std::to_string(count) + " labels need "
                  + std::to_string((count + 3) / 4) + " bytes, "
                  + std::to_string(payload) + " present (truncated or corrupt)");
  if ((count + 3) / 4 != payload)
    throw IOError("space layer stream: " + std::to_string(payload - (count + 3) / 4)
                  + " trailing bytes after " + std::to_string(count) + " labels");
  const std::uint8_t* labels = data + HEADER_BYTES;
  if ((count & 3u) != 0 && (labels[payload - 1] >> (2 * (count & 3u))) != 0)
    throw IOError("space layer stream: non-zero padding bits after the last label");

  StreamParser parser{labels, count, 0, prior_label, prior, format_version >= 3, 0, {}};
  parser.parse(depth, root[0], root[1], root[2]);
  if (parser.next != count)
    throw IOError("space layer stream: the octree ends after "
                  + std::to_string(parser.next) + " of " + std::to_string(count)
                  + " labels (trailing labels)");

  // Validated: build the new content, then swap it in.
  auto impl = std::make_unique<Impl>();
  for (const auto& leaf : parser.leaves) {
    if (leaf.level >= BLOCK_SHIFT) {
      const std::int64_t nb = std::int64_t{1} << (leaf.level - BLOCK_SHIFT);
      for (std::int64_t k = 0; k < nb; ++k)
        for (std::int64_t j = 0; j < nb; ++j)
          for (std::int64_t i = 0; i < nb; ++i) {
            const BlockKey bk{static_cast<int>((leaf.x >> BLOCK_SHIFT) + i),
                              static_cast<int>((leaf.y >> BLOCK_SHIFT) + j),
                              static_cast<int>((leaf.z >> BLOCK_SHIFT) + k)};
            impl->edits[impl->open(bk, prior)].uniform = leaf.state;
          }
      continue;
    }
    const BlockKey bk{static_cast<int>(leaf.x >> BLOCK_SHIFT),
                      static_cast<int>(leaf.y >> BLOCK_SHIFT),
                      static_cast<int>(leaf.z >> BLOCK_SHIFT)};
    const std::uint32_t e = impl->open(bk, prior);
    const int edge = 1 << leaf.level;
    const int lx = static_cast<int>(leaf.x & 7), ly = static_cast<int>(leaf.y & 7),
              lz = static_cast<int>(leaf.z & 7);
    for (int k = lz; k < lz + edge; ++k)
      for (int j = ly; j < ly + edge; ++j)
        for (int i = lx; i < lx + edge; ++i)
          impl->setEdit(e, i + 8 * j + 64 * k, leaf.state);
  }
  impl->commit(prior);
  impl->releaseEdits();
  impl_ = std::move(impl);
  params_.prior = prior_state;
}

// ---------------------------------------------------------------------------------

std::size_t
ExplicitSpaceGrid::insertIntoOcTree(octomap::OcTree& tree) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->settle(priorCode(params_.prior));
  if (std::abs(tree.getResolution() - params_.resolution_m)
      > 1e-9 * params_.resolution_m)
    throw Exception("ExplicitSpaceGrid::insertIntoOcTree: the tree's resolution ("
                    + std::to_string(tree.getResolution())
                    + " m) differs from the grid's ("
                    + std::to_string(params_.resolution_m) + " m)");
  if (tree.size() != 0)
    throw Exception("ExplicitSpaceGrid::insertIntoOcTree: the tree must be empty");
  const float occupied_log_odds = tree.getClampingThresMaxLog();
  const float free_log_odds = tree.getClampingThresMinLog();
  const int offset = static_cast<int>(tree.coordToKey(0.0)); // the key of coordinate 0
  // A block (8^3 voxels, aligned to multiples of 8 like the key offset) is one
  // OctoMap node three levels above the voxels.
  const unsigned block_depth = tree.getTreeDepth() - BLOCK_SHIFT;
  const auto free_code = static_cast<std::uint8_t>(SpaceState::FREE);
  const auto occupied = static_cast<std::uint8_t>(SpaceState::OCCUPIED);
  // Only what a view observed goes in: occluded and never-observed space stay out of
  // the tree (unknown in OctoMap), whatever the prior.
  const auto exported = [free_code, occupied](std::uint8_t code) {
    return code == free_code || code == occupied;
  };
  const auto sorted = impl_->sortedBlocks(priorCode(params_.prior));
  std::size_t skipped = 0;
  DenseBlock dense;
  const DenseBlock* const block = &dense;
  for (const auto& stored : sorted) {
    const BlockKey& bk = stored.key;
    stored.super->load(stored.j, dense);
    const Eigen::Vector3i base = Eigen::Vector3i(bk.x, bk.y, bk.z) * BLOCK_EDGE
                                 + Eigen::Vector3i::Constant(offset);
    if ((base.array() < 0).any()
        || (base.array() > 2 * offset - 1 - (BLOCK_EDGE - 1)).any()) {
      for (int i = 0; i < BLOCK_VOXELS; ++i)
        skipped += exported(block->get(i)) ? 1 : 0;
      continue;
    }
    const auto keyOf = [&base](int i) {
      return octomap::OcTreeKey(
        static_cast<octomap::key_type>(base.x() + (i & 7)),
        static_cast<octomap::key_type>(base.y() + ((i >> 3) & 7)),
        static_cast<octomap::key_type>(base.z() + (i >> 6)));
    };
    if (block->uniform != MIXED && !exported(block->uniform))
      continue;
    if (block->uniform == MIXED) {
      const auto counts = countCodes(block->bits);
      if (counts[free_code] + counts[occupied] == 0)
        continue; // occluded and never-observed voxels only: nothing to create
    }
    if (tree.getRoot() == nullptr) {
      // OcTree creates its root only through its updates: the first block exported
      // voxel by voxel, then collapsed like OctoMap's pruning.
      for (int i = 0; i < BLOCK_VOXELS; ++i) {
        const std::uint8_t code = block->get(i);
        if (exported(code))
          tree.setNodeValue(keyOf(i),
                            code == occupied ? occupied_log_odds : free_log_odds, true);
      }
      if (octomap::OcTreeNode* node = tree.search(keyOf(0), block_depth))
        octomap_writer::pruneSubtree(tree, node);
      continue;
    }
    // The block's node at its depth, created down from the root (blocks are disjoint
    // and the tree was empty, so the path never runs through a leaf).
    const octomap::OcTreeKey key = keyOf(0);
    octomap::OcTreeNode* node = tree.getRoot();
    for (unsigned depth = 0; depth < block_depth; ++depth) {
      const unsigned child = octomap::computeChildIdx(
        key, static_cast<int>(tree.getTreeDepth() - 1 - depth));
      if (!tree.nodeChildExists(node, child))
        tree.createNodeChild(node, child);
      node = tree.getNodeChild(node, child);
    }
    if (block->uniform != MIXED) {
      // A uniform block is one leaf.
      node->setLogOdds(block->uniform == occupied ? occupied_log_odds : free_log_odds);
      continue;
    }
    // A mixed block: its sub-cubes (4^3, 2^3, voxels) built below the block's node,
    // a sub-cube whose voxels all have one exported state as one leaf (OctoMap's
    // pruning, done as the tree is built), one with nothing exported left out.
    struct SubCubes {
      octomap::OcTree& tree;
      const DenseBlock& block;
      float occupied_log_odds, free_log_odds;
      std::uint8_t occupied_code, free_code;

      void build(octomap::OcTreeNode* parent, int level, int x, int y, int z)
      {
        // parent: a cube of edge 2^level voxels at local (x, y, z); its children
        const int h = 1 << (level - 1);
        for (unsigned c = 0; c < 8; ++c) {
          const int cx = x + static_cast<int>(c & 1) * h;
          const int cy = y + static_cast<int>((c >> 1) & 1) * h;
          const int cz = z + static_cast<int>((c >> 2) & 1) * h;
          const std::uint8_t first = block.get(cx + 8 * cy + 64 * cz);
          bool uniform = true;
          bool any = false;
          for (int k = cz; k < cz + h; ++k)
            for (int j = cy; j < cy + h; ++j)
              for (int i = cx; i < cx + h; ++i) {
                const std::uint8_t code = block.get(i + 8 * j + 64 * k);
                uniform = uniform && code == first;
                any = any || code == occupied_code || code == free_code;
              }
          if (!any)
            continue;
          octomap::OcTreeNode* child = tree.createNodeChild(parent, c);
          if (uniform)
            child->setLogOdds(first == occupied_code ? occupied_log_odds
                                                     : free_log_odds);
          else
            build(child, level - 1, cx, cy, cz);
        }
      }
    } sub_cubes{tree, *block, occupied_log_odds, free_log_odds, occupied, free_code};
    sub_cubes.build(node, BLOCK_SHIFT, 0, 0, 0);
  }
  tree.updateInnerOccupancy();
  return skipped;
}

void
ExplicitSpaceGrid::exportOctoMap(const std::string& path) const
{
  octomap::OcTree tree(params_.resolution_m);
  const std::size_t skipped = insertIntoOcTree(tree);
  if (skipped > 0)
    PCL_WARN("[planar_grid::ExplicitSpaceGrid::exportOctoMap] %zu voxels outside "
             "OctoMap's 2^16-voxel key range left out.\n",
             skipped);
  octomap_writer::write(tree, path);
}

} // namespace planar_grid
