// SPDX-License-Identifier: BSD-3-Clause
// The storage of ExplicitSpaceGrid: the compact form of a mixed block (encoding,
// decoding, counting) and the edit buffer's commit into the super-blocks.
#include "explicit_space_grid_storage.h"

#include <algorithm>
#include <array>
#include <cassert>
#include <cstdint>
#include <vector>

namespace planar_grid {
namespace explicit_space {

namespace {

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

/** \brief The word of the payload holding layer z (0-3) of the 4^3 cube c: voxel
 * x + 8 y + 64 z is in word 2 z + y / 4 (32 voxels, 4 rows of 8, per word). */
constexpr std::size_t
cubeWord(int c, int z)
{
  return static_cast<std::size_t>(2 * (4 * (c >> 2) + z) + ((c >> 1) & 1));
}

/** \brief The bits of cube c's 4 x 4 voxels in each of its words (4 voxels of each of
 * the word's 4 rows, 2 bits each). */
constexpr std::uint64_t
cubeMask(int c)
{
  return 0x00FF00FF00FF00FFULL << (8 * (c & 1));
}

/** \brief The 16 bits of 8 2-bit codes, code \a one where bit k of \a bits is set and
 * \a zero elsewhere: the bits spread to the low bit of each 2-bit lane, times the
 * codes' difference. */
inline std::uint32_t
expandBits(unsigned bits, std::uint32_t zero, std::uint32_t one)
{
  std::uint32_t b = bits & 0xFFu;
  b = (b | (b << 4)) & 0x0F0Fu;
  b = (b | (b << 2)) & 0x3333u;
  b = (b | (b << 1)) & 0x5555u;
  return cellPattern(zero) ^ (b * (zero ^ one));
}

/** \brief Per 2-bit field of \a w, both bits set where the field holds \a code. */
inline std::uint64_t
fieldsEqual(std::uint64_t w, std::uint8_t code)
{
  constexpr std::uint64_t LOW = 0x5555555555555555ULL;
  const std::uint64_t x = w ^ pattern(code);
  const std::uint64_t eq = ~(x | (x >> 1)) & LOW;
  return eq | (eq << 1);
}

/** \brief The low bits of the 32 2-bit lanes of \a lanes (each lane 0 or 1), packed. */
inline std::uint64_t
packLanes(std::uint64_t lanes)
{
  std::uint64_t x = lanes & 0x5555555555555555ULL;
  x = (x | (x >> 1)) & 0x3333333333333333ULL;
  x = (x | (x >> 2)) & 0x0F0F0F0F0F0F0F0FULL;
  x = (x | (x >> 4)) & 0x00FF00FF00FF00FFULL;
  x = (x | (x >> 8)) & 0x0000FFFF0000FFFFULL;
  return (x | (x >> 16)) & 0x00000000FFFFFFFFULL;
}

/** \brief Bit k set where code k of the 8 2-bit codes \a v is \a code. */
inline unsigned
gatherBits(std::uint32_t v, std::uint32_t code)
{
  return static_cast<unsigned>(
    packLanes(fieldsEqual(v, static_cast<std::uint8_t>(code))) & 0xFFu);
}

/** \brief Walks the compact block at \a data in cube and cell order: \a uniform(c, d,
 * code, voxels) for a uniform cube (d = -1, 64 voxels) or a uniform cell of a mixed
 * cube (8 voxels), \a mixed(c, d, v) for a mixed cell with its 8 codes \a v. */
template <typename Uniform, typename Mixed>
void
walkCompact(const std::uint8_t* data, Uniform&& uniform, Mixed&& mixed)
{
  const unsigned mixed_cubes = data[0];
  const CompactLayout layout(data[1]);
  // The two codes a mixed cell's bits choose between (a block of two codes).
  const std::uint32_t code0 = layout.code(0u, 0), code1 = layout.code(1u, 0);
  const unsigned cube_codes = layout.word(data + 2);
  const std::uint8_t* head = data + layout.cubes_end;
  const std::uint8_t* tail =
    data + layout.cubeRecord(static_cast<unsigned>(__builtin_popcount(mixed_cubes)));
  for (int c = 0; c < 8; ++c) {
    if (!((mixed_cubes >> c) & 1u)) {
      uniform(c, -1, layout.code(cube_codes, static_cast<unsigned>(c)), 64);
      continue;
    }
    const unsigned mixed_cells = head[0];
    const unsigned cell_codes = layout.word(head + 1);
    head += layout.cube_bytes;
    for (int d = 0; d < 8; ++d) {
      if ((mixed_cells >> d) & 1u) {
        mixed(c, d,
              layout.two_codes ? expandBits(tail[0], code0, code1)
                               : static_cast<std::uint32_t>(load16(tail)));
        tail += layout.cell_bytes;
      } else {
        uniform(c, d, layout.code(cell_codes, static_cast<unsigned>(d)), 8);
      }
    }
  }
}

} // namespace

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

namespace {

/** \brief Writes one form of \a p (whose code counts are \a n, at least two codes
 * present): one bit per node for two codes, else 2-bit codes. Returns its bytes. */
std::size_t
encodeForm(const Payload& p, const std::array<std::size_t, 4>& n, std::uint8_t* out)
{
  // The codes present: two of them (the usual edge of observed space) are written one
  // bit per node.
  std::uint32_t code0 = 4, code1 = 4;
  int present = 0;
  for (std::uint32_t s = 0; s < 4; ++s)
    if (n[s] > 0) {
      ++present;
      (code0 == 4 ? code0 : code1) = s;
    }
  const bool two_codes = present == 2;
  // A cube is uniform when its bits in its 4 words all repeat its first voxel's code;
  // only the mixed cubes' cells are read.
  std::array<std::uint32_t, 64> cells; // cube c, cell d at 8 c + d
  std::uint32_t mixed_cubes = 0, cube_codes = 0;
  // The bits of a node of code s: 1 bit (s is code1) or the 2-bit code.
  const auto nodeBits = [&](std::uint32_t s, int k) -> std::uint32_t {
    return two_codes ? static_cast<std::uint32_t>(s == code1) << k : s << (2 * k);
  };
  for (int c = 0; c < 8; ++c) {
    const std::uint64_t mask = cubeMask(c);
    const std::uint32_t code =
      static_cast<std::uint32_t>((p[cubeWord(c, 0)] >> (8 * (c & 1))) & 3u);
    const std::uint64_t expected = pattern(static_cast<std::uint8_t>(code)) & mask;
    bool uniform = true;
    for (int z = 0; z < 4; ++z)
      uniform = uniform && (p[cubeWord(c, z)] & mask) == expected;
    if (uniform) {
      cube_codes |= nodeBits(code, c);
      continue;
    }
    mixed_cubes |= 1u << c;
    for (int d = 0; d < 8; ++d)
      cells[static_cast<std::size_t>(8 * c + d)] = cellValue(p, cellOrigin(c, d));
  }
  const CompactLayout layout(
    static_cast<std::uint8_t>(two_codes ? TWO_CODES | code0 | (code1 << 2) : 0));
  out[0] = static_cast<std::uint8_t>(mixed_cubes);
  out[1] = layout.header;
  out[2] = static_cast<std::uint8_t>(cube_codes);
  if (!two_codes)
    out[3] = static_cast<std::uint8_t>(cube_codes >> 8);
  std::size_t head = layout.cubes_end;
  std::size_t tail =
    layout.cubeRecord(static_cast<unsigned>(__builtin_popcount(mixed_cubes)));
  for (int c = 0; c < 8; ++c) {
    if (!((mixed_cubes >> c) & 1u))
      continue;
    std::uint32_t mixed_cells = 0, cell_codes = 0;
    for (int d = 0; d < 8; ++d) {
      const std::uint32_t v = cells[static_cast<std::size_t>(8 * c + d)];
      if (v == cellPattern(v & 3u)) {
        cell_codes |= nodeBits(v & 3u, d);
        continue;
      }
      mixed_cells |= 1u << d;
      if (two_codes) {
        out[tail++] = static_cast<std::uint8_t>(gatherBits(v, code1));
      } else {
        out[tail++] = static_cast<std::uint8_t>(v);
        out[tail++] = static_cast<std::uint8_t>(v >> 8);
      }
    }
    out[head++] = static_cast<std::uint8_t>(mixed_cells);
    out[head++] = static_cast<std::uint8_t>(cell_codes);
    if (!two_codes)
      out[head++] = static_cast<std::uint8_t>(cell_codes >> 8);
  }
  return tail;
}

/** \brief Decodes the one form at \a data into \a p. */
void
decodeForm(const std::uint8_t* data, Payload& p)
{
  p.fill(0);
  walkCompact(
    data,
    [&p](int c, int d, unsigned code, int) {
      if (code == 0) // p is zeroed
        return;
      if (d >= 0) {
        putCell(p, cellOrigin(c, d), cellPattern(code));
        return;
      }
      // a whole cube: 8 bits of each of its 4 rows in each of 4 words
      for (int z = 0; z < 4; ++z)
        p[cubeWord(c, z)] |= pattern(static_cast<std::uint8_t>(code)) & cubeMask(c);
    },
    [&p](int c, int d, std::uint32_t v) { putCell(p, cellOrigin(c, d), v); });
}

/** \brief A set of a block's voxels: bit x + 8 y of word z. */
using VoxelMask = std::array<std::uint64_t, 8>;

/** \brief The voxels of \a p of code \a code. */
VoxelMask
voxelsOf(const Payload& p, std::uint8_t code)
{
  VoxelMask m;
  for (std::size_t z = 0; z < 8; ++z)
    m[z] = packLanes(fieldsEqual(p[2 * z], code))
           | (packLanes(fieldsEqual(p[2 * z + 1], code)) << 32);
  return m;
}

/** \brief Bytes of the one form of a block whose voxels the \a count sets \a parts
 * split (its codes): a node (4^3 cube, 2^3 cell) is uniform when one part holds all
 * of it. Two parts: 3 + 2 per mixed cube + 1 per mixed cell; more: 4 + 3 per mixed
 * cube + 2 per mixed cell (encodeForm()). */
std::size_t
formBytes(const VoxelMask* parts, int count)
{
  // Per part: whole 2 x 2 x 2 cells at (even x, even y) of each cell layer, then whole
  // cubes at x, y in {0, 4} of each cube layer.
  std::array<std::uint64_t, 4> uniform_cells{};
  std::array<std::uint64_t, 2> uniform_cubes{};
  for (int k = 0; k < count; ++k) {
    const VoxelMask& m = parts[k];
    std::array<std::uint64_t, 4> cells;
    for (std::size_t zc = 0; zc < 4; ++zc) {
      std::uint64_t w = m[2 * zc] & m[2 * zc + 1];
      w &= w >> 1;
      cells[zc] = w & (w >> 8);
      uniform_cells[zc] |= cells[zc];
    }
    for (std::size_t zq = 0; zq < 2; ++zq) {
      std::uint64_t w = cells[2 * zq] & cells[2 * zq + 1];
      w &= w >> 2;
      uniform_cubes[zq] |= w & (w >> 16);
    }
  }
  constexpr std::uint64_t CELL_CORNERS = 0x0055005500550055ULL; // even x, even y
  constexpr std::uint64_t CUBE_CORNERS = 0x0000001100000011ULL; // x, y in {0, 4}
  std::size_t mixed_cells = 0, mixed_cubes = 0;
  for (const auto w : uniform_cells)
    mixed_cells += static_cast<std::size_t>(__builtin_popcountll(~w & CELL_CORNERS));
  for (const auto w : uniform_cubes)
    mixed_cubes += static_cast<std::size_t>(__builtin_popcountll(~w & CUBE_CORNERS));
  return count == 2 ? 3 + 2 * mixed_cubes + mixed_cells
                    : 4 + 3 * mixed_cubes + 2 * mixed_cells;
}

} // namespace

std::size_t
encodeCompact(const Payload& p, std::uint8_t* out)
{
  const std::array<std::size_t, 4> n = countCodes(p);
  if ((n[0] > 0) + (n[1] > 0) + (n[2] > 0) + (n[3] > 0) <= 2)
    return encodeForm(p, n, out);
  // Three or four codes: the 2-bit form, or two layers: c0 against the most frequent
  // other code, then the rest with the c0 voxels taking that code. The sizes come from
  // the codes' voxel sets; only the shortest form is written.
  std::array<VoxelMask, 4> voxels{}, all_parts;
  int all_count = 0;
  for (std::uint8_t s = 0; s < 4; ++s)
    if (n[s] > 0) {
      voxels[s] = voxelsOf(p, s);
      all_parts[static_cast<std::size_t>(all_count++)] = voxels[s];
    }
  std::size_t best = formBytes(all_parts.data(), all_count);
  int best_c0 = -1, best_other = -1;
  for (std::uint8_t c0 = 0; c0 < 4; ++c0) {
    if (n[c0] == 0)
      continue;
    std::uint8_t other = c0 == 0 ? 1 : 0;
    for (std::uint8_t s = 0; s < 4; ++s)
      if (s != c0 && n[s] > n[other])
        other = s;
    VoxelMask rest;
    for (std::size_t z = 0; z < 8; ++z)
      rest[z] = ~voxels[c0][z];
    const VoxelMask first[2] = {voxels[c0], rest};
    std::array<VoxelMask, 3> second;
    int second_count = 0;
    for (std::uint8_t s = 0; s < 4; ++s) {
      if (s == c0 || n[s] == 0)
        continue;
      VoxelMask& m = second[static_cast<std::size_t>(second_count++)];
      m = voxels[s];
      if (s == other)
        for (std::size_t z = 0; z < 8; ++z)
          m[z] |= voxels[c0][z];
    }
    const std::size_t bytes =
      formBytes(first, 2) + formBytes(second.data(), second_count);
    if (bytes < best) {
      best = bytes;
      best_c0 = c0;
      best_other = other;
    }
  }
  if (best_c0 < 0)
    return encodeForm(p, n, out);
  const auto c0 = static_cast<std::uint8_t>(best_c0);
  const auto other = static_cast<std::uint8_t>(best_other);
  Payload first, second;
  for (std::size_t w = 0; w < p.size(); ++w) {
    const std::uint64_t is_c0 = fieldsEqual(p[w], c0);
    first[w] = (pattern(c0) & is_c0) | (pattern(other) & ~is_c0);
    second[w] = (pattern(other) & is_c0) | (p[w] & ~is_c0);
  }
  std::array<std::size_t, 4> n_first{}, n_second = n;
  n_first[c0] = n[c0];
  n_first[other] = BLOCK_VOXELS - n[c0];
  n_second[other] += n[c0];
  n_second[c0] = 0;
  const std::size_t first_bytes = encodeForm(first, n_first, out);
  out[1] =
    static_cast<std::uint8_t>(out[1] | LAYERED | (c0 > other ? C0_IS_SECOND : 0));
  const std::size_t bytes =
    first_bytes + encodeForm(second, n_second, out + first_bytes);
  assert(bytes == best);
  return bytes;
}

void
decodeCompact(const std::uint8_t* data, Payload& p)
{
  decodeForm(data, p);
  if (!(data[1] & LAYERED))
    return;
  const std::uint8_t c0 = layeredCode(data);
  Payload second;
  decodeForm(data + formSize(data), second);
  for (std::size_t w = 0; w < p.size(); ++w) {
    const std::uint64_t is_c0 = fieldsEqual(p[w], c0);
    p[w] = (p[w] & is_c0) | (second[w] & ~is_c0);
  }
}

void
countCompact(const std::uint8_t* data, std::array<std::size_t, 4>& n)
{
  if (data[1] & LAYERED) {
    Payload p;
    decodeCompact(data, p);
    const std::array<std::size_t, 4> m = countCodes(p);
    for (std::size_t s = 0; s < 4; ++s)
      n[s] += m[s];
    return;
  }
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

std::uint32_t
BlockStorage::open(const BlockKey& bk, std::uint8_t prior)
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

void
BlockStorage::commit(std::uint8_t prior)
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

void
BlockStorage::releaseEdits()
{
  edit_index.release();
  std::vector<BlockKey>().swap(edit_keys);
  std::vector<EditBlock>().swap(edits);
  std::vector<Payload>().swap(pool);
  std::vector<std::uint32_t>().swap(order);
  std::vector<std::uint32_t>().swap(new_offsets);
  std::vector<std::uint8_t>().swap(new_data);
}

void
BlockStorage::rebuild(SuperBlock& sb,
                      std::size_t first,
                      std::size_t last,
                      std::uint8_t prior)
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
  // The offsets first, then the forms: after the start of the word's first compact
  // form, at most 63 forms come before a form of the same word, below 2^16 bytes.
  const std::size_t n_mixed = new_offsets.size();
  std::vector<std::uint8_t> data(2 * n_mixed + new_data.size());
  std::size_t before = 0;
  for (std::size_t w = 0; w < 8; ++w) {
    const auto in_word = static_cast<std::size_t>(__builtin_popcountll(mixed[w]));
    sb.base[w] = in_word > 0 ? new_offsets[before] : 0;
    for (std::size_t r = before; r < before + in_word; ++r) {
      const std::uint32_t offset = new_offsets[r] - sb.base[w];
      data[2 * r] = static_cast<std::uint8_t>(offset & 0xffu);
      data[2 * r + 1] = static_cast<std::uint8_t>(offset >> 8);
    }
    before += in_word;
  }
  std::copy(new_data.begin(), new_data.end(),
            data.begin() + 2 * static_cast<std::ptrdiff_t>(n_mixed));
  sb.mixed_count = static_cast<std::uint16_t>(n_mixed);
  // a mixed block's code field is 0, never a prior code (2 or 3): counted as stored
  constexpr std::uint64_t LOW = 0x5555555555555555ULL;
  int stored = 0;
  for (const auto w : codes) {
    const std::uint64_t x = w ^ pattern(prior);
    stored += __builtin_popcountll((x | (x >> 1)) & LOW);
  }
  sb.stored = static_cast<std::uint16_t>(stored);
  // an exact-size array: the memory held is the information's
  data.swap(sb.data);
}

std::vector<StoredBlock>
BlockStorage::sortedBlocks(std::uint8_t prior) const
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

} // namespace explicit_space
} // namespace planar_grid
