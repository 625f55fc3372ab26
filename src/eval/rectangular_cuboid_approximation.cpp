// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/eval/rectangular_cuboid_approximation.h>

#include <cstdint>
#include <limits>

namespace planar_grid {

namespace {

/** \brief The observed voxels with their class, in a flat open-addressing table
 * (linear probing, load <= 0.5): packed index (0 = empty slot) and a state, 1 free,
 * 2 occupied, 0 once covered by a box. */
class VoxelTable {
public:
  static constexpr std::size_t NONE = std::numeric_limits<std::size_t>::max();

  explicit VoxelTable(std::size_t count)
  {
    std::size_t n = 16;
    shift_ = 60;
    while (n < 2 * count) {
      n *= 2;
      --shift_;
    }
    keys_.assign(n, 0);
    states_.assign(n, 0);
    mask_ = n - 1;
  }

  /** \brief Packs an index (0 when outside StandardVoxelGrid's range: never stored). */
  static std::uint64_t pack(int x, int y, int z)
  {
    constexpr int M = StandardVoxelGrid::MAX_INDEX;
    if (x < -M || x > M || y < -M || y > M || z < -M || z > M)
      return 0;
    constexpr std::int64_t OFFSET = std::int64_t{1} << 20;
    return static_cast<std::uint64_t>(x + OFFSET)
           | (static_cast<std::uint64_t>(y + OFFSET) << 21)
           | (static_cast<std::uint64_t>(z + OFFSET) << 42);
  }

  void insert(std::uint64_t key, std::uint8_t state)
  {
    std::size_t i = slot(key);
    while (keys_[i] != 0 && keys_[i] != key)
      i = (i + 1) & mask_;
    keys_[i] = key;
    states_[i] = state;
  }

  /** \brief Slot of \a key, or NONE. */
  std::size_t find(std::uint64_t key) const
  {
    if (key == 0)
      return NONE;
    for (std::size_t i = slot(key);; i = (i + 1) & mask_) {
      if (keys_[i] == key)
        return i;
      if (keys_[i] == 0)
        return NONE;
    }
  }

  /** \brief State of voxel (x, y, z): 0 when unobserved or covered. */
  std::uint8_t state(int x, int y, int z) const
  {
    const std::size_t i = find(pack(x, y, z));
    return i == NONE ? 0 : states_[i];
  }

  /** \brief Marks an observed voxel covered. */
  void cover(int x, int y, int z)
  {
    const std::size_t i = find(pack(x, y, z));
    if (i != NONE)
      states_[i] = 0;
  }

private:
  std::size_t slot(std::uint64_t key) const
  {
    return static_cast<std::size_t>((key * 0x9E3779B97F4A7C15ULL) >> shift_);
  }

  std::vector<std::uint64_t> keys_;
  std::vector<std::uint8_t> states_;
  std::size_t mask_{0};
  int shift_{60};
};

} // namespace

void
RectangularCuboidApproximation::compute(const StandardVoxelGrid& grid,
                                        AxisAlignedBoxes& boxes) const
{
  boxes.clear();
  std::vector<StandardVoxelGrid::Voxel> voxels;
  grid.getVoxels(voxels); // (z, y, x) order
  if (voxels.empty())
    return;
  const float occupied_log_odds = grid.getOccupancyThresLogOdds();
  const auto classOf = [occupied_log_odds](float log_odds) -> std::uint8_t {
    return log_odds >= occupied_log_odds ? 2 : 1;
  };
  VoxelTable table(voxels.size());
  for (const auto& v : voxels)
    table.insert(VoxelTable::pack(v.index.x(), v.index.y(), v.index.z()),
                 classOf(v.log_odds));

  for (const auto& v : voxels) {
    const int x = v.index.x(), y = v.index.y(), z = v.index.z();
    const std::uint8_t cls = table.state(x, y, z);
    if (cls == 0)
      continue; // covered by an earlier box
    int sx = 1, sy = 1, sz = 1;
    while (table.state(x + sx, y, z) == cls)
      ++sx;
    const auto rowMatches = [&](int row_y, int row_z) {
      for (int i = 0; i < sx; ++i)
        if (table.state(x + i, row_y, row_z) != cls)
          return false;
      return true;
    };
    while (rowMatches(y + sy, z))
      ++sy;
    const auto slabMatches = [&](int slab_z) {
      for (int j = 0; j < sy; ++j)
        if (!rowMatches(y + j, slab_z))
          return false;
      return true;
    };
    while (slabMatches(z + sz))
      ++sz;
    for (int k = 0; k < sz; ++k)
      for (int j = 0; j < sy; ++j)
        for (int i = 0; i < sx; ++i)
          table.cover(x + i, y + j, z + k);
    boxes.push_back({v.index, Eigen::Vector3i(sx, sy, sz), cls == 2});
  }
  // The memory figure is capacity x sizeof: drop the growth slack of push_back.
  boxes.shrink_to_fit();
}

std::size_t
RectangularCuboidApproximation::getMemoryBytes(const AxisAlignedBoxes& boxes)
{
  return boxes.capacity() * sizeof(AxisAlignedBox);
}

} // namespace planar_grid
