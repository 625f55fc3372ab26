// SPDX-License-Identifier: BSD-3-Clause
// The octree bit stream of ExplicitSpaceGrid (the map file's space layer, paper Sec.
// IV): serialize() and deserialize(), with the checks that reject a corrupt stream
// before anything is allocated.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <array>
#include <cstdint>
#include <limits>
#include <memory>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "explicit_space_grid_impl.h"

namespace planar_grid {

using namespace explicit_space;

namespace {

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
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto blocks = impl_->storage.sortedBlocks(prior);
  Eigen::Vector3i root = Eigen::Vector3i::Zero();
  int depth = 0;
  LabelWriter out;
  if (blocks.empty())
    out.putLeaf(prior);
  else {
    Eigen::Vector3i lo, hi;
    keyBounds(blocks, lo, hi);
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
  BlockStorage& storage = impl->storage;
  for (const auto& leaf : parser.leaves) {
    if (leaf.level >= BLOCK_SHIFT) {
      const std::int64_t nb = std::int64_t{1} << (leaf.level - BLOCK_SHIFT);
      for (std::int64_t k = 0; k < nb; ++k)
        for (std::int64_t j = 0; j < nb; ++j)
          for (std::int64_t i = 0; i < nb; ++i) {
            const BlockKey bk{static_cast<int>((leaf.x >> BLOCK_SHIFT) + i),
                              static_cast<int>((leaf.y >> BLOCK_SHIFT) + j),
                              static_cast<int>((leaf.z >> BLOCK_SHIFT) + k)};
            storage.edits[storage.open(bk, prior)].uniform = leaf.state;
          }
      continue;
    }
    const BlockKey bk{static_cast<int>(leaf.x >> BLOCK_SHIFT),
                      static_cast<int>(leaf.y >> BLOCK_SHIFT),
                      static_cast<int>(leaf.z >> BLOCK_SHIFT)};
    const std::uint32_t e = storage.open(bk, prior);
    const int edge = 1 << leaf.level;
    const int lx = static_cast<int>(leaf.x & 7), ly = static_cast<int>(leaf.y & 7),
              lz = static_cast<int>(leaf.z & 7);
    for (int k = lz; k < lz + edge; ++k)
      for (int j = ly; j < ly + edge; ++j)
        for (int i = lx; i < lx + edge; ++i)
          storage.setEdit(e, i + 8 * j + 64 * k, leaf.state);
  }
  storage.commit(prior);
  storage.releaseEdits();
  impl_ = std::move(impl);
  params_.prior = prior_state;
}

} // namespace planar_grid
