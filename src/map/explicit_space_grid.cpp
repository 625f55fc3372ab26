// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid: parameters, voxel keys, single-voxel reads and writes, the
// queries over the stored blocks, and the DepthImage helpers. Integration, ray
// casting, the bit stream and the OctoMap export are in explicit_space_grid_*.cpp.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/explicit_space_grid.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <string>

#include "explicit_space_grid_impl.h"

namespace planar_grid {

using namespace explicit_space;

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
  DepthImage image;
  image.assignFromDisparity(disparity, width, height, row_stride_bytes, calibration);
  return image;
}

void
DepthImage::assignFromDisparity(const float* disparity,
                                int image_width,
                                int image_height,
                                std::size_t row_stride_bytes,
                                const StereoCalibration& calibration)
{
  if (image_width <= 0 || image_height <= 0 || disparity == nullptr)
    throw Exception("DepthImage::fromDisparity: image size must be positive, got "
                    + std::to_string(image_width) + "x" + std::to_string(image_height));
  if (row_stride_bytes < static_cast<std::size_t>(image_width) * sizeof(float))
    throw Exception("DepthImage::fromDisparity: row stride "
                    + std::to_string(row_stride_bytes)
                    + " bytes is shorter than a row");
  if (!(calibration.focal_length_px > 0.0) || !(calibration.baseline_m > 0.0))
    throw Exception("DepthImage::fromDisparity: the calibration needs focal_length_px "
                    "> 0 and baseline_m > 0");
  width = image_width;
  height = image_height;
  fx = fy = static_cast<float>(calibration.focal_length_px);
  cx = static_cast<float>(calibration.cx_px);
  cy = static_cast<float>(calibration.cy_px);
  // Every element is written below: the buffer is neither reallocated nor cleared
  // when the size is unchanged.
  depth_m.resize(static_cast<std::size_t>(width) * static_cast<std::size_t>(height));
  const auto fb =
    static_cast<float>(calibration.focal_length_px * calibration.baseline_m);
  const auto* bytes = reinterpret_cast<const unsigned char*>(disparity);
  for (int v = 0; v < height; ++v) {
    const auto* row = reinterpret_cast<const float*>(
      bytes + static_cast<std::size_t>(v) * row_stride_bytes);
    float* out =
      depth_m.data() + static_cast<std::size_t>(v) * static_cast<std::size_t>(width);
    // Two branch-free loops the compiler vectorises: f B / d everywhere, then NaN
    // where the disparity is not finite and positive.
    for (int u = 0; u < width; ++u)
      out[u] = fb / row[u];
    for (int u = 0; u < width; ++u)
      out[u] = explicit_space::isFiniteAndPositive(row[u])
                 ? out[u]
                 : std::numeric_limits<float>::quiet_NaN();
  }
}

std::size_t
DepthImage::countValid() const
{
  std::size_t n = 0;
  for (const float d : depth_m)
    n += static_cast<std::size_t>(explicit_space::isFiniteAndPositive(d));
  return n;
}

bool
DepthImage::isConsistent() const
{
  return width > 0 && height > 0
         && depth_m.size()
              == static_cast<std::size_t>(width) * static_cast<std::size_t>(height)
         && fx > 0.0f && fy > 0.0f && std::isfinite(fx) && std::isfinite(fy)
         && std::isfinite(cx) && std::isfinite(cy);
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
  namespace ranges = explicit_space_grid_ranges;
  const auto check = [](const char* name, double value, const ParamRange& range) {
    if (!range.contains(value))
      throw Exception("ExplicitSpaceGrid: " + paramRangeMessage(name, range, "m")
                      + ", got " + formatParamNumber(value));
  };
  check("resolution_m", params.resolution_m, ranges::RESOLUTION);
  check("max_range_m", params.max_range_m, ranges::MAX_RANGE);
  check("surface_margin_m", params.surface_margin_m, ranges::SURFACE_MARGIN);
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
  return stateOf(
    impl_->storage.codeAt(key.x(), key.y(), key.z(), priorCode(params_.prior)),
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
  if (impl_->storage.codeAt(key.x(), key.y(), key.z(), prior) == s)
    return;
  // The write waits in the edit buffer: voxel-by-voxel writes cost no rebuild of
  // their super-block each; queries read the buffer or commit it first.
  const BlockKey bk{blockOf(key.x()), blockOf(key.y()), blockOf(key.z())};
  const std::uint32_t e = impl_->storage.open(bk, prior);
  impl_->storage.setEdit(
    e, localOf(key.x()) + 8 * localOf(key.y()) + 64 * localOf(key.z()), s);
  if (impl_->storage.edits.size() >= MAX_PENDING_BLOCKS)
    impl_->storage.commit(prior);
}

void
ExplicitSpaceGrid::clear()
{
  impl_->storage.discardEdits();
  std::vector<SuperBlock>().swap(impl_->storage.supers);
  impl_->storage.directory.release();
}
void
ExplicitSpaceGrid::visitVoxels(void (*visit)(void*, const VoxelKey&, SpaceState),
                               void* context) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto sorted = impl_->storage.sortedBlocks(prior);
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

void
ExplicitSpaceGrid::visitVoxelRuns(
  void (*visit)(void*, const VoxelKey&, int, SpaceState),
  void* context) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto sorted = impl_->storage.sortedBlocks(prior);
  DenseBlock block;
  for (const auto& stored : sorted) {
    const BlockKey& bk = stored.key;
    const int x0 = bk.x * BLOCK_EDGE, y0 = bk.y * BLOCK_EDGE, z0 = bk.z * BLOCK_EDGE;
    if (!stored.super->isMixed(stored.j)) {
      const SpaceState state = stateOf(stored.super->code(stored.j), params_.prior);
      for (int c = 0; c < BLOCK_EDGE * BLOCK_EDGE; ++c)
        visit(context, VoxelKey(x0 + (c & 7), y0 + (c >> 3), z0), BLOCK_EDGE, state);
      continue;
    }
    stored.super->load(stored.j, block);
    // Voxel i of a block is x + 8 y + 64 z: column c = x + 8 y holds c + 64 z.
    for (int c = 0; c < BLOCK_EDGE * BLOCK_EDGE; ++c) {
      int z = 0;
      while (z < BLOCK_EDGE) {
        const std::uint8_t s = block.get(c + (z << 6));
        int end = z + 1;
        while (end < BLOCK_EDGE && block.get(c + (end << 6)) == s)
          ++end;
        if (s != prior)
          visit(context, VoxelKey(x0 + (c & 7), y0 + (c >> 3), z0 + z), end - z,
                stateOf(s, params_.prior));
        z = end;
      }
    }
  }
}

void
ExplicitSpaceGrid::visitVoxelsIn(SpaceState state,
                                 void (*visit)(void*, const VoxelKey&),
                                 void* context) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  const auto code = static_cast<std::uint8_t>(state);
  if (code == prior)
    return;
  const auto sorted = impl_->storage.sortedBlocks(prior);
  DenseBlock block;
  for (const auto& stored : sorted) {
    if (!stored.super->isMixed(stored.j) && stored.super->code(stored.j) != code)
      continue;
    stored.super->load(stored.j, block);
    const BlockKey& bk = stored.key;
    for (int i = 0; i < BLOCK_VOXELS; ++i)
      if (block.get(i) == code)
        visit(context,
              VoxelKey(bk.x * BLOCK_EDGE + (i & 7), bk.y * BLOCK_EDGE + ((i >> 3) & 7),
                       bk.z * BLOCK_EDGE + (i >> 6)));
  }
}

std::size_t
ExplicitSpaceGrid::getVoxelCount(SpaceState state) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  if (static_cast<std::uint8_t>(state) == prior)
    return 0;
  std::array<std::size_t, 4> n{};
  for (const auto& sb : impl_->storage.supers)
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
  impl_->storage.settle(priorCode(params_.prior));
  std::size_t n = 0;
  for (const auto& sb : impl_->storage.supers)
    n += sb.stored;
  return n;
}

std::size_t
ExplicitSpaceGrid::getMemoryBytes() const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  // Every allocation of the storage: the super-block array's capacity, each
  // super-block's array, the directory's slots, plus MALLOC_OVERHEAD per heap
  // allocation (the allocator's chunk header and rounding). The scratch buffers of
  // integration (depth pyramid, observations, edit buffer) are working memory of one
  // view, not the map's.
  constexpr std::size_t MALLOC_OVERHEAD = 16;
  const BlockStorage& storage = impl_->storage;
  std::size_t bytes = sizeof(Impl);
  const auto heap = [](std::size_t n) {
    return n == 0 ? 0 : n + MALLOC_OVERHEAD;
  };
  bytes += heap(storage.supers.capacity() * sizeof(SuperBlock));
  for (const auto& sb : storage.supers)
    bytes += heap(sb.data.capacity());
  bytes += heap(storage.directory.capacityBytes());
  return bytes;
}

std::uint64_t
ExplicitSpaceGrid::workingBytesBound(std::uint64_t view_blocks,
                                     std::uint64_t image_pixels)
{
  static_assert(BLOCK_EDGE_VOXELS == BLOCK_EDGE, "one block edge");
  // Per block the view touches: its observation (BlockResult), and in the edit buffer
  // its key, its edit, its place in commit()'s order, a payload (a mixed block) and
  // the directory's slots (at most half full, doubled when full: <= 4 per entry).
  // Each of these vectors doubles its capacity as it grows: up to twice the count.
  constexpr std::uint64_t SLOT_BYTES = sizeof(BlockKey) + sizeof(std::uint32_t);
  constexpr std::uint64_t PER_BLOCK =
    2
      * (sizeof(BlockResult) + sizeof(BlockKey) + sizeof(EditBlock)
         + sizeof(std::uint32_t) + sizeof(Payload))
    + 4 * SLOT_BYTES;
  // The depth pyramid: min and max levels (4/3 of the image each), the span minima
  // (8 arrays per level) and the hole levels (below 4/3 of the image per level): at
  // most 16 floats per pixel.
  constexpr std::uint64_t PER_PIXEL = 16 * sizeof(float);
  return view_blocks * PER_BLOCK + image_pixels * PER_PIXEL;
}

std::uint64_t
ExplicitSpaceGrid::storageBytesBound(std::uint64_t blocks, std::uint64_t super_blocks)
{
  // As getMemoryBytes() counts: a mixed block's compact form (at most
  // MAX_COMPACT_BYTES) and its offset; a super-block in the array (doubling: up to
  // twice), its exact-size array's allocator overhead, and the directory's slots
  // (<= 4 per entry).
  constexpr std::uint64_t MALLOC_OVERHEAD = 16;
  constexpr std::uint64_t SLOT_BYTES = sizeof(BlockKey) + sizeof(std::uint32_t);
  constexpr std::uint64_t PER_BLOCK = MAX_COMPACT_BYTES + sizeof(std::uint16_t);
  constexpr std::uint64_t PER_SUPER_BLOCK =
    2 * sizeof(SuperBlock) + MALLOC_OVERHEAD + 4 * SLOT_BYTES;
  return sizeof(Impl) + blocks * PER_BLOCK + super_blocks * PER_SUPER_BLOCK
         + 2 * MALLOC_OVERHEAD;
}

bool
ExplicitSpaceGrid::getBounds(VoxelKey& min_key, VoxelKey& max_key) const
{
  // Pending setState() edits go to the storage first (content unchanged).
  impl_->storage.settle(priorCode(params_.prior));
  const auto prior = priorCode(params_.prior);
  Eigen::Vector3i lo = Eigen::Vector3i::Constant(std::numeric_limits<int>::max());
  Eigen::Vector3i hi = Eigen::Vector3i::Constant(std::numeric_limits<int>::min());
  bool any = false;
  for (const auto& sb : impl_->storage.supers)
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
  impl_->storage.settle(prior); // pending setState() edits (content unchanged)
  other.impl_->storage.settle(prior);
  const auto a = impl_->storage.sortedBlocks(prior),
             b = other.impl_->storage.sortedBlocks(prior);
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

} // namespace planar_grid
