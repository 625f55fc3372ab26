// SPDX-License-Identifier: BSD-3-Clause
// The storage of ExplicitSpaceGrid: voxel and block keys, the 2-bit codes, the compact
// form of a mixed block, super-blocks and their directory, and the edit buffer that
// writes reach the super-blocks through. Private to src/map.
#pragma once

#include <planar_grid/map/explicit_space_grid.h>

#include <algorithm>
#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <vector>

namespace planar_grid {
namespace explicit_space {

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
/** \brief Largest |voxel key| handled, so that block arithmetic never overflows. */
constexpr double MAX_KEY = 1073741824.0; // 2^30
/** \brief Blocks edited before they are written to the super-blocks (the bound of the
 * edit buffer of setState() and merge()). */
constexpr std::size_t MAX_PENDING_BLOCKS = 4096;

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

/** \brief The inclusive bounds \a lo, \a hi of the keys of \a items, each holding a
 * BlockKey `key` (stored blocks, super-blocks; the bounds in the items' own units);
 * false, and the bounds unset, when there are none. */
template <typename Range>
bool
keyBounds(const Range& items, Eigen::Vector3i& lo, Eigen::Vector3i& hi)
{
  lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  bool any = false;
  for (const auto& item : items) {
    const Eigen::Vector3i k(item.key.x, item.key.y, item.key.z);
    lo = lo.cwiseMin(k);
    hi = hi.cwiseMax(k);
    any = true;
  }
  return any;
}

/** \brief 512 voxels x 2 bits; voxel i = x + 8 y + 64 z sits at bits 2 (i % 32) of
 * word i / 32. */
using Payload = std::array<std::uint64_t, 16>;

/** \brief Voxels of each code in a payload. */
std::array<std::size_t, 4> countCodes(const Payload& p);

/** \brief True when the 2-bit codes of \a p are all equal; \a code is set to the
 * first. */
bool isUniform(const Payload& p, std::uint8_t& code);

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

// Compact form of a mixed block, a fixed two-level octree below the block. Byte 0 is
// the mask of the mixed 4^3 cubes (bit c: the cube at (4 (c & 1), 4 ((c >> 1) & 1),
// 4 (c >> 2))); byte 1 says how a node's code is written:
//  - A block of two codes a < b (most mixed blocks: the edge of the observed space,
//    free against unknown) has byte 1 = TWO_CODES | a | b << 2, and one bit per code
//    (0 a, 1 b):
//      byte 2      the bit of each uniform cube (bit c; 0 for a mixed cube)
//      2 bytes per mixed cube, in cube order: mask of its mixed 2^3 cells (bit d: the
//                  cell at offset (2 (d & 1), 2 ((d >> 1) & 1), 2 (d >> 2)) in the
//                  cube), then the bits of its uniform cells (bit d)
//      1 byte per mixed cell, in cube then cell order: its 8 voxels' bits (voxel
//                  (x, y, z) of the cell at bit x + 2 y + 4 z)
//  - A block of three or four codes has byte 1 = 0 and 2-bit codes:
//      bytes 2-3   the code of each uniform cube (bits 2 c; 0 for a mixed cube)
//      3 bytes per mixed cube: its mask of mixed cells, then its uniform cells' codes
//      2 bytes per mixed cell: the codes of its 8 voxels (voxel (x, y, z) at bits
//                  2 (x + 2 y + 4 z))
//  - A block of three or four codes may instead be written in two layers, when that
//    is shorter (a road: free space above, the surface, unknown below): a form of two
//    codes, c0 against one other code, then right after it a form (of two codes, or
//    of 2-bit codes) of the voxels that are not c0, where the c0 voxels take that
//    other code. The first form's byte 1 has LAYERED set, and C0_IS_SECOND when c0 is
//    its second code b. A voxel is c0 when the first form says so, else what the
//    second says.
// The encoding of a payload is unique (the shortest of these forms, the 2-bit form
// on a tie, then the lowest c0), so equal blocks have equal bytes.

/** \brief Flag of byte 1 of a compact block of two codes. */
constexpr std::uint8_t TWO_CODES = 0x10;
/** \brief Flag of byte 1 of the first of the two forms of a layered block. */
constexpr std::uint8_t LAYERED = 0x40;
/** \brief Flag of byte 1 of a layered block: c0 is the first form's second code. */
constexpr std::uint8_t C0_IS_SECOND = 0x20;
/** \brief Largest compact block: 4 + 8 x 3 + 64 x 2 bytes (three or four codes, every
 * cell mixed). */
constexpr std::size_t MAX_COMPACT_BYTES = 156;

static_assert(64 * MAX_COMPACT_BYTES < 65536, "a word's offsets fit 16 bits");

/** \brief The little-endian 16-bit word at \a b (the compact form's code words). */
inline unsigned
load16(const std::uint8_t* b)
{
  return static_cast<unsigned>(b[0]) | (static_cast<unsigned>(b[1]) << 8);
}

/** \brief Encodes a payload whose codes are not all equal; returns the byte count
 * (<= MAX_COMPACT_BYTES) written to \a out. */
std::size_t encodeCompact(const Payload& p, std::uint8_t* out);

/** \brief Where the parts of a compact block lie and how its node codes are written,
 * from its byte 1: nodes of 1 bit (two codes) or 2 bits; the cubes' codes end at byte
 * 3 or 4; a mixed cube's record (its mask of mixed cells, then its uniform cells'
 * codes) takes 2 or 3 bytes; a mixed cell's 8 voxels 1 or 2 bytes. */
struct CompactLayout {
  explicit CompactLayout(std::uint8_t header_byte) :
      header(header_byte), two_codes((header_byte & TWO_CODES) != 0),
      cubes_end(two_codes ? 3u : 4u), cube_bytes(two_codes ? 2u : 3u),
      cell_bytes(two_codes ? 1u : 2u)
  {}

  /** \brief The word of 8 node codes at \a p: one byte of bits, or 16 bits of codes. */
  unsigned word(const std::uint8_t* p) const { return two_codes ? p[0] : load16(p); }
  /** \brief Code of node \a k of \a w (a word()): its bit picks one of the header's two
   * codes, or its own 2 bits. */
  std::uint8_t code(unsigned w, unsigned k) const
  {
    return static_cast<std::uint8_t>(two_codes ? (header >> (2 * ((w >> k) & 1u))) & 3u
                                               : (w >> (2 * k)) & 3u);
  }
  /** \brief Start of mixed cube \a r's record (r: its rank among the mixed cubes). */
  unsigned cubeRecord(unsigned r) const { return cubes_end + cube_bytes * r; }

  std::uint8_t header;
  bool two_codes;
  unsigned cubes_end;
  unsigned cube_bytes;
  unsigned cell_bytes;
};

/** \brief Bytes of the one form at \a data (the first of a layered block). */
inline std::size_t
formSize(const std::uint8_t* data)
{
  const CompactLayout layout(data[1]);
  const auto n_cubes = static_cast<unsigned>(__builtin_popcount(data[0]));
  std::size_t n = layout.cubeRecord(n_cubes);
  for (unsigned k = 0; k < n_cubes; ++k)
    n += layout.cell_bytes
         * static_cast<std::size_t>(__builtin_popcount(data[layout.cubeRecord(k)]));
  return n;
}

/** \brief Bytes of the compact block at \a data. */
inline std::size_t
compactSize(const std::uint8_t* data)
{
  const std::size_t n = formSize(data);
  return (data[1] & LAYERED) ? n + formSize(data + n) : n;
}

/** \brief The code c0 of the layered block at \a data. */
inline std::uint8_t
layeredCode(const std::uint8_t* data)
{
  const unsigned h = data[1];
  return static_cast<std::uint8_t>((h >> ((h & C0_IS_SECOND) ? 2 : 0)) & 3u);
}

/** \brief Code of local voxel (x, y, z) of the one form at \a data. */
inline std::uint8_t
formGet(const std::uint8_t* data, int x, int y, int z)
{
  const CompactLayout layout(data[1]);
  const unsigned c =
    static_cast<unsigned>((x >> 2) | ((y >> 2) << 1) | ((z >> 2) << 2));
  const unsigned mixed_cubes = data[0];
  if (!((mixed_cubes >> c) & 1u))
    return layout.code(layout.word(data + 2), c);
  const auto r =
    static_cast<unsigned>(__builtin_popcount(mixed_cubes & ((1u << c) - 1u)));
  const std::uint8_t* cube = data + layout.cubeRecord(r);
  const unsigned d = static_cast<unsigned>(((x >> 1) & 1) | (((y >> 1) & 1) << 1)
                                           | (((z >> 1) & 1) << 2));
  const unsigned mixed_cells = cube[0];
  if (!((mixed_cells >> d) & 1u))
    return layout.code(layout.word(cube + 1), d);
  auto before =
    static_cast<unsigned>(__builtin_popcount(mixed_cells & ((1u << d) - 1u)));
  for (unsigned k = 0; k < r; ++k)
    before += static_cast<unsigned>(__builtin_popcount(data[layout.cubeRecord(k)]));
  const std::uint8_t* cell =
    data + layout.cubeRecord(static_cast<unsigned>(__builtin_popcount(mixed_cubes)))
    + layout.cell_bytes * before;
  return layout.code(layout.word(cell),
                     static_cast<unsigned>((x & 1) + 2 * (y & 1) + 4 * (z & 1)));
}

/** \brief Code of local voxel (x, y, z) of the compact block at \a data. */
inline std::uint8_t
compactGet(const std::uint8_t* data, int x, int y, int z)
{
  const std::uint8_t code = formGet(data, x, y, z);
  if (!(data[1] & LAYERED) || code == layeredCode(data))
    return code;
  return formGet(data + formSize(data), x, y, z);
}

/** \brief The uniform 4^3 cubes of code \a code of the one form at \a data: bit c for
 * the cube at (4 (c & 1), 4 ((c >> 1) & 1), 4 (c >> 2)). */
inline std::uint32_t
formUniformCubes(const std::uint8_t* data, std::uint32_t code)
{
  const CompactLayout layout(data[1]);
  const unsigned mixed_cubes = data[0], cube_codes = layout.word(data + 2);
  std::uint32_t cubes = 0;
  for (unsigned c = 0; c < 8; ++c)
    if (!((mixed_cubes >> c) & 1u) && layout.code(cube_codes, c) == code)
      cubes |= 1u << c;
  return cubes;
}

/** \brief The uniform 4^3 cubes of code \a code of the compact block at \a data: bit
 * c for the cube at (4 (c & 1), 4 ((c >> 1) & 1), 4 (c >> 2)). */
inline std::uint32_t
compactUniformCubes(const std::uint8_t* data, std::uint32_t code)
{
  if (!(data[1] & LAYERED))
    return formUniformCubes(data, code);
  const std::uint32_t c0 = layeredCode(data);
  if (code == c0)
    return formUniformCubes(data, c0);
  // the cubes without c0 in the first form, and of the code in the second
  const unsigned h = data[1];
  const std::uint32_t other = (h >> ((h & C0_IS_SECOND) ? 0 : 2)) & 3u;
  return formUniformCubes(data, other) & formUniformCubes(data + formSize(data), code);
}

/** \brief Decodes the compact block at \a data into \a p. */
void decodeCompact(const std::uint8_t* data, Payload& p);

/** \brief Adds the voxels of each code of the compact block at \a data to \a n. */
void countCompact(const std::uint8_t* data, std::array<std::size_t, 4>& n);

/** \brief floor(a / 8) for negative a too. */
inline int
blockOf(int a)
{
  return a >> BLOCK_SHIFT; // arithmetic shift: floor for negative keys (C++20, GCC)
}

/** \brief a mod 8: the coordinate inside its block. */
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

/** \brief log2 of the edge of a super-block, in blocks. */
constexpr int SUPER_SHIFT = 3;
/** \brief Blocks per super-block (8 x 8 x 8). */
constexpr int SUPER_BLOCKS = 512;

/** \brief 8 x 8 x 8 blocks (64^3 voxels): the 2-bit code of each uniform block, a bit
 * per mixed block, and the mixed blocks' compact forms in one array. A block at the
 * grid's prior code is not stored (it is never-observed space). */
struct SuperBlock {
  /** \brief Super-block coordinates: floor(block key / 8). */
  BlockKey key{0, 0, 0};
  /** \brief Blocks not at the prior (uniform ones of another code, and mixed ones). */
  std::uint16_t stored{0};
  /** \brief Mixed blocks (the set bits of \a mixed). */
  std::uint16_t mixed_count{0};
  /** \brief Code of block j = x + 8 y + 64 z at bits 2 (j % 32) of word j / 32; 0 for
   * a mixed block. */
  std::array<std::uint64_t, 16> codes{};
  /** \brief Bit j % 64 of word j / 64: block j is mixed. */
  std::array<std::uint64_t, 8> mixed{};
  /** \brief Start, after the offsets in \a data, of the compact forms of the mixed
   * blocks of word w of \a mixed (64 blocks, at most 64 x MAX_COMPACT_BYTES bytes
   * after it). */
  std::array<std::uint32_t, 8> base{};
  /** \brief One allocation: a 16-bit little-endian offset per mixed block in block
   * order (from the \a base of its word of \a mixed), then the compact forms. */
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
    auto r = static_cast<std::size_t>(__builtin_popcountll(mixed[w] & below));
    for (std::size_t k = 0; k < w; ++k)
      r += static_cast<std::size_t>(__builtin_popcountll(mixed[k]));
    const std::uint8_t* forms = data.data() + 2 * std::size_t{mixed_count};
    return forms + base[w] + load16(data.data() + 2 * r);
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

/** \brief The blocks of the grid: super-blocks found through a directory, and the edit
 * buffer every write goes through (blocks decoded on first use, written to their
 * super-blocks by commit()). The working memory of integration (depth pyramid,
 * per-block observations) is not here: it belongs to one view, not to the map. */
struct BlockStorage {
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

  /** \brief The 4^3 cubes of block \a bk whose voxels are all free in the storage,
   * pending edits not read: bit c for the cube at (4 (c & 1), 4 ((c >> 1) & 1),
   * 4 (c >> 2)), 0xFF for a block free as a whole. */
  std::uint32_t storedFreeCubes(const BlockKey& bk) const
  {
    const auto free_code = static_cast<std::uint32_t>(SpaceState::FREE);
    const SuperBlock* sb = findSuper(superOf(bk));
    if (sb == nullptr)
      return 0;
    const int j = indexInSuper(bk);
    if (!sb->isMixed(j))
      return sb->code(j) == free_code ? 0xFFu : 0u;
    return compactUniformCubes(sb->compact(j), free_code);
  }

  /** \brief The edit of block \a bk, loaded from the storage on first use (out of
   * line: the callers' per-voxel loops reach it only when they enter another block). */
  std::uint32_t open(const BlockKey& bk, std::uint8_t prior);

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
  void commit(std::uint8_t prior);

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
  void releaseEdits();

  /** \brief Rebuilds \a sb with the edits order[first, last) (sorted by block). */
  void rebuild(SuperBlock& sb, std::size_t first, std::size_t last, std::uint8_t prior);

  /** \brief The stored blocks, in key order (z, then y, then x), for the outputs that
   * must not depend on the storage order. */
  std::vector<StoredBlock> sortedBlocks(std::uint8_t prior) const;
};

/** \brief Voxel-by-voxel writes through the edit buffer, for writes that stay in one
 * block for a while (a row of pixels, a ray): remembers the last block. */
class BlockStorage::Cursor {
public:
  Cursor(BlockStorage& storage, std::uint8_t prior) : storage_(storage), prior_(prior)
  {}

  /** \brief The edit of the block of voxel (kx, ky, kz); \a i is set to the voxel's
   * index in it. */
  std::uint32_t at(int kx, int ky, int kz, int& i)
  {
    const BlockKey bk{blockOf(kx), blockOf(ky), blockOf(kz)};
    if (cached_ == KeyIndex::NONE || !(bk == cached_key_)) {
      cached_ = storage_.open(bk, prior_);
      cached_key_ = bk;
    }
    i = localOf(kx) + 8 * localOf(ky) + 64 * localOf(kz);
    return cached_;
  }

private:
  BlockStorage& storage_;
  std::uint8_t prior_;
  BlockKey cached_key_{0, 0, 0};
  std::uint32_t cached_{KeyIndex::NONE};
};

} // namespace explicit_space
} // namespace planar_grid
