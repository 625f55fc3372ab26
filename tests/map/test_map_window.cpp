// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::removeOutside() (the rolling window of a long run) against the truth
// of a small synthetic map: what lies inside the box is unchanged, what lies outside
// reads as never seen, the counts are those of a brute-force walk, the file round-trips
// and the memory falls.
#include <planar_grid/map/planar_grid_map.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "wall_cuboid.h"

namespace {

using planar_grid::ExplicitSpaceGrid;
using planar_grid::MapWindowRemoval;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarGridMap;
using planar_grid::PlaneModels;
using planar_grid::SpaceState;
using Key = ExplicitSpaceGrid::VoxelKey;

constexpr float R = 0.1f; // the map's cell, meters

/** A planar cuboid: face centre \a face, normal \a normal (toward the sensors),
 * horizontal axis \a u, extruded 0.1 m behind the face, of 100 points. */
PlanarCuboid
wall(const Eigen::Vector3f& face,
     const Eigen::Vector3f& normal,
     const Eigen::Vector3f& u,
     float width_m,
     float height_m,
     int plane_id)
{
  PlanarCuboid c =
    planar_grid_test::wallCuboid(face, normal, u, width_m, height_m, plane_id);
  c.point_count = 100;
  return c;
}

PlanarCuboid
cube(const Eigen::Vector3f& centre)
{
  PlanarCuboid c;
  c.normal = -Eigen::Vector3f::UnitZ();
  c.horizontal_axis = Eigen::Vector3f::UnitX();
  c.width_m = c.height_m = c.thickness_m = R;
  c.centre = centre;
  c.plane_id = -1;
  c.is_planar = false;
  c.point_count = 3;
  return c;
}

/** The voxels set in the space layer: x in [-30, 80), y in [-12, 32), z in [-4, 12)
 * (keys), uniformly free for x < -10 (whole blocks), a mix of free, occupied and
 * occluded elsewhere. */
constexpr int X0 = -30, X1 = 80, Y0 = -12, Y1 = 32, Z0 = -4, Z1 = 12;

/** The box kept: its bounds are not on voxel or block boundaries' centres, so that
 * blocks straddle it along x, y and z. */
const Eigen::AlignedBox3f KEEP(Eigen::Vector3f(-2.0f, -2.0f, -0.2f),
                               Eigen::Vector3f(5.0f, 3.0f, 3.0f));

/** Walls A (y = 1, x in [-1, 1]: inside the box), B (y = 2, x in [3, 7]: across its
 * x = 5 face) and C (x = 20: outside), a non-planar cell inside and one outside, and
 * the voxels above. */
void
fill(PlanarGridMap& map)
{
  const PlaneModels planes{Eigen::Vector4f(0.0f, -1.0f, 0.0f, 1.0f),
                           Eigen::Vector4f(0.0f, -1.0f, 0.0f, 2.0f),
                           Eigen::Vector4f(-1.0f, 0.0f, 0.0f, 20.0f)};
  const PlanarCuboids cuboids{
    wall(Eigen::Vector3f(0.0f, 1.0f, 0.5f), -Eigen::Vector3f::UnitY(),
         Eigen::Vector3f::UnitX(), 2.0f, 1.0f, 0),
    wall(Eigen::Vector3f(5.0f, 2.0f, 0.5f), -Eigen::Vector3f::UnitY(),
         Eigen::Vector3f::UnitX(), 4.0f, 1.0f, 1),
    wall(Eigen::Vector3f(20.0f, 0.0f, 0.5f), -Eigen::Vector3f::UnitX(),
         Eigen::Vector3f::UnitY(), 2.0f, 1.0f, 2),
    cube(Eigen::Vector3f(0.05f, -1.05f, 0.55f)),
    cube(Eigen::Vector3f(10.05f, -1.05f, 0.55f))};
  pcl::PointCloud<pcl::PointXYZ> features;
  std::vector<float> probabilities;
  for (int k = 0; k < 9; ++k) {
    const float t = -0.8f + 0.2f * static_cast<float>(k);
    features.push_back(pcl::PointXYZ(t, 1.0f, 0.5f));
    features.push_back(pcl::PointXYZ(5.0f + 2.0f * t, 2.0f, 0.5f));
    features.push_back(pcl::PointXYZ(20.0f, t, 0.5f));
    probabilities.insert(probabilities.end(), {0.9f, 0.8f, 0.7f});
  }
  map.integrateSurface(cuboids, planes, features, probabilities);
  ExplicitSpaceGrid& space = map.getSpaceLayer();
  for (int z = Z0; z < Z1; ++z)
    for (int y = Y0; y < Y1; ++y)
      for (int x = X0; x < X1; ++x) {
        const int v = ((x * 7 + y * 3 + z) % 5 + 5) % 5;
        if (x < -10 || v <= 1)
          space.setState(Key(x, y, z), SpaceState::FREE);
        else if (v == 2)
          space.setState(Key(x, y, z), SpaceState::OCCUPIED);
        else if (v == 3)
          space.setState(Key(x, y, z), SpaceState::UNKNOWN);
      }
}

PlanarGridMap::Params
windowMapParams(SpaceState prior)
{
  PlanarGridMap::Params p;
  p.resolution_m = R;
  p.space.prior = prior;
  // the window must keep every cell inside exactly, including a lone one-voxel
  // non-planar cell whose neighbours it removes
  p.surface.skip_isolated_non_planar = false;
  return p;
}

Eigen::Vector3f
centre(const Key& k)
{
  return (k.cast<float>() + Eigen::Vector3f::Constant(0.5f)) * R;
}

bool
inside(const Eigen::AlignedBox3f& box, const Eigen::Vector3f& p)
{
  return (p.array() >= box.min().array()).all()
         && (p.array() <= box.max().array()).all();
}

Eigen::AlignedBox3f
grown(const Eigen::AlignedBox3f& box, float margin)
{
  return Eigen::AlignedBox3f(box.min() - Eigen::Vector3f::Constant(margin),
                             box.max() + Eigen::Vector3f::Constant(margin));
}

/** An independent copy of \a map through its file content. */
PlanarGridMap
copyOf(const PlanarGridMap& map)
{
  std::string bytes;
  map.serialize(bytes);
  return PlanarGridMap::deserialize(bytes, "copy");
}

/** Every field of a cuboid, to compare cuboids exactly. */
std::vector<float>
fields(const PlanarCuboid& c)
{
  return {c.centre.x(),
          c.centre.y(),
          c.centre.z(),
          c.normal.x(),
          c.normal.y(),
          c.normal.z(),
          c.horizontal_axis.x(),
          c.horizontal_axis.y(),
          c.horizontal_axis.z(),
          c.width_m,
          c.height_m,
          c.thickness_m,
          c.probability,
          static_cast<float>(c.point_count),
          static_cast<float>(c.plane_id),
          c.is_planar ? 1.0f : 0.0f};
}

class MapWindowTest : public ::testing::TestWithParam<SpaceState> {};

TEST_P(MapWindowTest, RemoveOutsideKeepsTheBoxExactlyAndForgetsTheRest)
{
  const SpaceState prior = GetParam();
  PlanarGridMap map(windowMapParams(prior));
  fill(map);
  const PlanarGridMap before = copyOf(map);
  ASSERT_TRUE(before == map);

  // The truth, by brute force over the observed voxels and the cuboids.
  std::uint64_t voxels_outside = 0;
  std::set<std::tuple<int, int, int>> blocks, blocks_inside;
  map.getSpaceLayer().forEachVoxel([&](const Key& k, SpaceState) {
    const auto block = std::make_tuple(k.x() >> 3, k.y() >> 3, k.z() >> 3);
    blocks.insert(block);
    if (inside(KEEP, centre(k)))
      blocks_inside.insert(block);
    else
      ++voxels_outside;
  });
  const PlanarCuboids cuboids_before = map.getSurfaceLayer().getCuboids();
  const std::size_t cells_before = map.getSurfaceLayer().getCellCount();
  const auto memory_before = map.getMemory();
  ASSERT_EQ(map.getSurfaceLayer().getPlanes().size(), 3u);

  const MapWindowRemoval removed = map.removeOutside(KEEP);
  // The storage held falls in both layers (the covers rebuilt, as before; no query
  // index held either time).
  const PlanarCuboids cuboids_after = map.getSurfaceLayer().getCuboids();
  const auto memory_after = map.getMemory();
  EXPECT_LT(memory_after.space_bytes, memory_before.space_bytes);
  EXPECT_LT(memory_after.surface_bytes, memory_before.surface_bytes);
  EXPECT_LT(memory_after.total_bytes, memory_before.total_bytes);

  EXPECT_EQ(removed.space_voxels, voxels_outside);
  EXPECT_EQ(removed.space_blocks, blocks.size() - blocks_inside.size());
  EXPECT_EQ(map.getSpaceLayer().getBlockCount(), blocks_inside.size());
  // Wall B keeps its cells of x centre <= 5 (20 of 40 columns, 10 rows), wall C goes
  // whole (20 x 10), and so does its plane; one of the two non-planar cells goes.
  EXPECT_EQ(removed.plane_cells, 400u);
  EXPECT_EQ(removed.planes, 1u);
  EXPECT_EQ(removed.non_planar_cells, 1u);
  EXPECT_EQ(map.getSurfaceLayer().getCellCount(),
            cells_before - removed.plane_cells - removed.non_planar_cells);
  EXPECT_EQ(map.getSurfaceLayer().getPlanes().size(), 2u);

  // The space layer, voxel by voxel (a margin of 8 voxels around what was set): a
  // voxel whose centre lies in the box keeps its state, any other reads the prior.
  std::size_t kept = 0, forgotten = 0;
  for (int z = Z0 - 8; z < Z1 + 8; ++z)
    for (int y = Y0 - 8; y < Y1 + 8; ++y)
      for (int x = X0 - 8; x < X1 + 8; ++x) {
        const Key k(x, y, z);
        if (inside(KEEP, centre(k))) {
          ++kept;
          ASSERT_EQ(map.getSpaceLayer().getState(k), before.getSpaceLayer().getState(k))
            << x << " " << y << " " << z;
        } else {
          ++forgotten;
          ASSERT_EQ(map.getSpaceLayer().getState(k), prior)
            << x << " " << y << " " << z;
        }
      }
  ASSERT_GT(kept, 0u);
  ASSERT_GT(forgotten, 0u);

  // Both layers together, at every voxel centre: inside the box (a cell away from its
  // faces, where a rectangle across the boundary is covered again) the map answers as
  // before; a cell beyond it (the kept cells' faces and thickness reach half a cell
  // and a cell out) it answers the prior.
  const Eigen::AlignedBox3f deep = grown(KEEP, -1.5f * R);
  const Eigen::AlignedBox3f near = grown(KEEP, 1.5f * R);
  for (int z = Z0 - 8; z < Z1 + 8; ++z)
    for (int y = Y0 - 8; y < Y1 + 8; ++y)
      for (int x = X0 - 8; x < X1 + 8; ++x) {
        const Eigen::Vector3f p = centre(Key(x, y, z));
        if (inside(deep, p)) {
          ASSERT_EQ(map.getState(p), before.getState(p)) << p.transpose();
        } else if (!inside(near, p)) {
          ASSERT_EQ(map.getState(p), prior) << p.transpose();
        }
      }
  // On the walls' faces, cell by cell: wall A whole, wall B up to x = 5.
  for (int i = -10; i < 10; ++i) {
    const float x = (static_cast<float>(i) + 0.5f) * R;
    EXPECT_EQ(map.getState(Eigen::Vector3f(x, 1.02f, 0.55f)), SpaceState::OCCUPIED)
      << x;
  }
  for (int i = 30; i < 70; ++i) {
    const float x = (static_cast<float>(i) + 0.5f) * R;
    EXPECT_EQ(map.getState(Eigen::Vector3f(x, 2.02f, 0.55f)),
              x <= 5.0f ? SpaceState::OCCUPIED : prior)
      << x;
  }
  EXPECT_EQ(map.getState(Eigen::Vector3f(19.98f, 0.05f, 0.55f)), prior); // wall C

  // The cuboids that lay inside the box are there as they were; none lies outside.
  std::set<std::vector<float>> after;
  for (const auto& c : cuboids_after) {
    after.insert(fields(c));
    EXPECT_TRUE(inside(grown(KEEP, R), c.centre)) << c.centre.transpose();
  }
  std::size_t inside_before = 0;
  for (const auto& c : cuboids_before) {
    Eigen::Vector3f lo = c.centre, hi = c.centre;
    for (const float s : {-0.5f, 0.5f})
      for (const float t : {-0.5f, 0.5f})
        for (const float w : {-0.5f, 0.5f}) {
          const Eigen::Vector3f corner = c.centre + s * c.width_m * c.horizontal_axis
                                         + t * c.height_m * c.verticalAxis()
                                         + w * c.thickness_m * c.normal;
          lo = lo.cwiseMin(corner);
          hi = hi.cwiseMax(corner);
        }
    if (inside(KEEP, lo) && inside(KEEP, hi)) {
      ++inside_before;
      EXPECT_EQ(after.count(fields(c)), 1u) << c.centre.transpose();
    }
  }
  EXPECT_GE(inside_before, 2u); // wall A's rectangle and the non-planar cell

  // A second removal with the same box removes nothing.
  const MapWindowRemoval again = map.removeOutside(KEEP);
  EXPECT_EQ(again.space_blocks + again.space_voxels + again.plane_cells + again.planes
              + again.non_planar_cells,
            0u);
}

TEST_P(MapWindowTest, MapAfterRemovalRoundTripsThroughItsFile)
{
  PlanarGridMap map(windowMapParams(GetParam()));
  fill(map);
  map.removeOutside(KEEP);
  const std::string file =
    (std::filesystem::temp_directory_path()
     / ("planar_grid_window_" + std::to_string(::getpid()) + ".pgmap"))
      .string();
  map.save(file);
  const PlanarGridMap loaded = PlanarGridMap::load(file);
  std::filesystem::remove(file);
  EXPECT_TRUE(loaded == map);
  const PlanarCuboids a = map.getSurfaceLayer().getCuboids();
  const PlanarCuboids b = loaded.getSurfaceLayer().getCuboids();
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t k = 0; k < a.size(); ++k)
    EXPECT_EQ(fields(a[k]), fields(b[k])) << k;
  std::string first, second;
  map.serialize(first);
  loaded.serialize(second);
  EXPECT_EQ(first, second);
}

TEST_P(MapWindowTest, UnboundedBoxRemovesNothingAndEmptyBoxRemovesEverything)
{
  PlanarGridMap map(windowMapParams(GetParam()));
  fill(map);
  const PlanarGridMap before = copyOf(map);
  const float inf = std::numeric_limits<float>::infinity();
  const MapWindowRemoval none = map.removeOutside(Eigen::AlignedBox3f(
    Eigen::Vector3f::Constant(-inf), Eigen::Vector3f::Constant(inf)));
  EXPECT_EQ(none.space_blocks + none.space_voxels + none.plane_cells + none.planes
              + none.non_planar_cells,
            0u);
  EXPECT_TRUE(map == before);
  // z unlimited, x and y bounded: what the pipeline's window keeps.
  const MapWindowRemoval column = map.removeOutside(Eigen::AlignedBox3f(
    Eigen::Vector3f(-2.0f, -2.0f, -inf), Eigen::Vector3f(5.0f, 3.0f, inf)));
  EXPECT_GT(column.space_voxels, 0u);
  EXPECT_EQ(column.planes, 1u);

  const MapWindowRemoval all = map.removeOutside(Eigen::AlignedBox3f()); // empty box
  EXPECT_EQ(all.planes, 2u);
  EXPECT_EQ(all.non_planar_cells, 1u);
  EXPECT_EQ(map.getSpaceLayer().getBlockCount(), 0u);
  EXPECT_EQ(map.getSurfaceLayer().getCellCount(), 0u);
  EXPECT_TRUE(map.getSurfaceLayer().getCuboids().empty());
  EXPECT_TRUE(map == PlanarGridMap(windowMapParams(GetParam())));
  EXPECT_TRUE(copyOf(map) == map);
  EXPECT_LE(map.getMemory().space_bytes,
            PlanarGridMap(windowMapParams(GetParam())).getMemory().space_bytes);
}

std::string
priorName(const ::testing::TestParamInfo<SpaceState>& param)
{
  return param.param == SpaceState::FREE ? "Free" : "Unknown";
}

INSTANTIATE_TEST_SUITE_P(Priors,
                         MapWindowTest,
                         ::testing::Values(SpaceState::UNKNOWN, SpaceState::FREE),
                         priorName);

} // namespace
