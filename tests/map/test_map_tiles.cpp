// SPDX-License-Identifier: BSD-3-Clause
// saveTiles() / loadTiles() on the synthetic street of test_map_merge.cpp (surfaces
// known exactly) and on a small real map file: all tiles give back the map, a region
// holds the map inside it, a wall across tiles is one plane again, bad sets are
// refused.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <functional>
#include <sstream>
#include <string>
#include <vector>

#include "street_scene.h"

namespace {

namespace fs = std::filesystem;
namespace street = planar_grid_test::street;
using planar_grid::IOError;
using planar_grid::MapTileIndex;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarGridMap;
using planar_grid::SpaceState;

using street::EVERYWHERE;
using street::INF;

/** A fresh folder under the test temporary folder, removed at the end. */
class MapTilesTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    folder_ = fs::temp_directory_path()
              / ("planar_grid_tiles_" + std::string(info->name()) + "_"
                 + std::to_string(::getpid()));
    fs::remove_all(folder_);
  }
  void TearDown() override { fs::remove_all(folder_); }

  std::string folder() const { return folder_.string(); }
  std::string file(const std::string& name) const { return (folder_ / name).string(); }

  /** The index's text. */
  std::string indexText() const
  {
    std::ifstream in(file(planar_grid::MAP_TILE_INDEX_NAME));
    std::stringstream s;
    s << in.rdbuf();
    return s.str();
  }
  void writeIndex(const std::string& text) const
  {
    std::ofstream(file(planar_grid::MAP_TILE_INDEX_NAME)) << text;
  }

  /** The IOError message of loading every tile ("" when none is thrown). */
  std::string loadError() const
  {
    try {
      planar_grid::loadTiles(folder(), EVERYWHERE);
    } catch (const IOError& e) {
      return e.what();
    }
    return "";
  }

  fs::path folder_;
};

/** The street's map of every frame, built once (it takes a second). */
const PlanarGridMap&
streetMap()
{
  static const PlanarGridMap map = street::mapFrames(0, street::FRAMES);
  return map;
}

/** Probe points every 0.15 m over the street and 2 m beyond it, off the voxel faces. */
std::vector<Eigen::Vector3f>
probes()
{
  std::vector<Eigen::Vector3f> out;
  for (float x = -4.0f; x <= 23.0f; x += 0.15f)
    for (float y = -5.0f; y <= 5.0f; y += 0.15f)
      for (float z = -0.3f; z <= 4.3f; z += 0.15f)
        out.emplace_back(x + 0.0123f, y + 0.0231f, z + 0.0312f);
  return out;
}

/** The cuboids' kind, geometry and probability as vectors. */
std::vector<Eigen::Matrix<float, 14, 1>>
cuboidVectors(const PlanarGridMap& map)
{
  std::vector<Eigen::Matrix<float, 14, 1>> out;
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids()) {
    Eigen::Matrix<float, 14, 1> v;
    v << (c.is_planar ? 1.0f : 0.0f), c.centre, c.normal, c.horizontal_axis, c.width_m,
      c.height_m, c.thickness_m, c.probability;
    out.push_back(v);
  }
  return out;
}

/** True when the maps hold the same cuboids up to order: each cuboid of one matches
 * one of the other within 1e-4 (m, unit vectors, probability) and the counts agree.
 * (The plane of a map loaded from tiles is refitted from the sum of its pieces' copies
 * of one fit: equal up to float rounding.) */
bool
sameCuboids(const PlanarGridMap& a, const PlanarGridMap& b)
{
  const auto va = cuboidVectors(a);
  auto vb = cuboidVectors(b);
  if (va.size() != vb.size())
    return false;
  for (const auto& v : va) {
    const auto match = std::find_if(vb.begin(), vb.end(), [&v](const auto& w) {
      return (v - w).cwiseAbs().maxCoeff() < 1e-4f;
    });
    if (match == vb.end())
      return false;
    vb.erase(match);
  }
  return true;
}

/** Number of probes inside \a region where the maps' states differ; \a inside
 * receives the number of probes inside. */
std::size_t
differences(const PlanarGridMap& a,
            const PlanarGridMap& b,
            const std::function<bool(const Eigen::Vector3f&)>& in_region,
            std::size_t& inside)
{
  std::size_t differ = 0;
  inside = 0;
  for (const Eigen::Vector3f& p : probes())
    if (in_region(p)) {
      ++inside;
      differ += a.getState(p) != b.getState(p) ? 1 : 0;
    }
  return differ;
}

/** Planes of \a map whose normal is within 0.05 rad of \a normal (either sign) and
 * whose offset along it is within 0.05 m of \a offset_m. */
int
planesLike(const PlanarGridMap& map, const Eigen::Vector3f& normal, float offset_m)
{
  int n = 0;
  for (const Eigen::Vector4f& p : map.getSurfaceLayer().getPlanes()) {
    const float s = p.head<3>().dot(normal) < 0.0f ? -1.0f : 1.0f;
    if (std::abs(p.head<3>().dot(normal)) > std::cos(0.05f)
        && std::abs(-s * p[3] - offset_m) < 0.05f)
      ++n;
  }
  return n;
}

TEST_F(MapTilesTest, AllTilesGiveBackTheMap)
{
  const PlanarGridMap& map = streetMap();
  // The street spans x in [-2, 20] and y in [-3, 3]: 5 m tiles cut it into
  // 6 x 2 squares at least (y = 0 is a border), every wall across 5 of them.
  const MapTileIndex index = planar_grid::saveTiles(map, folder(), 5.0);
  EXPECT_GE(index.tiles.size(), 10u);
  EXPECT_TRUE(fs::exists(file(planar_grid::MAP_TILE_INDEX_NAME)));

  const PlanarGridMap loaded = planar_grid::loadTiles(folder(), EVERYWHERE);
  std::size_t inside = 0;
  EXPECT_EQ(differences(
              map, loaded, [](const Eigen::Vector3f&) { return true; }, inside),
            0u);
  EXPECT_GT(inside, 200'000u);
  for (const SpaceState s :
       {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
    EXPECT_EQ(loaded.getSpaceLayer().getVoxelCount(s),
              map.getSpaceLayer().getVoxelCount(s));
  EXPECT_EQ(loaded.getSpaceLayer(), map.getSpaceLayer());
  EXPECT_TRUE(sameCuboids(loaded, map));

  // The same planes: each plane of the map has one loaded plane with the same
  // coefficients (the pieces of a plane carry its whole fit), and no other.
  const auto& planes = map.getSurfaceLayer().getPlanes();
  const auto& loaded_planes = loaded.getSurfaceLayer().getPlanes();
  ASSERT_EQ(loaded_planes.size(), planes.size());
  for (const Eigen::Vector4f& p : planes) {
    int same = 0;
    for (const Eigen::Vector4f& q : loaded_planes)
      same += (p - q).cwiseAbs().maxCoeff() < 1e-5f ? 1 : 0;
    EXPECT_EQ(same, 1) << p.transpose();
  }
}

TEST_F(MapTilesTest, ARegionHoldsTheMapInsideAndNothingFarOutside)
{
  const PlanarGridMap& map = streetMap();
  planar_grid::saveTiles(map, folder(), 5.0);
  // x in [6, 9]: the tiles of x in [5, 10) m. The bounds of their neighbours end at
  // 5.6 and begin at 9.6 m (the voxel blocks across the borders, 0.8 m), so that
  // without a margin only they are loaded.
  const Eigen::AlignedBox3f region(Eigen::Vector3f(6.0f, -INF, -INF),
                                   Eigen::Vector3f(9.0f, INF, INF));
  const PlanarGridMap part = planar_grid::loadTiles(folder(), region);
  std::size_t inside = 0;
  EXPECT_EQ(
    differences(
      map, part, [&](const Eigen::Vector3f& p) { return region.contains(p); }, inside),
    0u);
  EXPECT_GT(inside, 20'000u);
  // nothing beyond the loaded tiles (x in [5, 10) and the half-cell cuboid overhang)
  std::size_t far = 0, far_known = 0;
  for (const Eigen::Vector3f& p : probes())
    if (p.x() < 4.8f || p.x() > 10.2f) {
      ++far;
      far_known += part.getState(p) != SpaceState::UNKNOWN ? 1 : 0;
    }
  EXPECT_GT(far, 100'000u);
  EXPECT_EQ(far_known, 0u);

  // The radius variant: a disc of 2 m around (8, 1) holds the box.
  const Eigen::Vector3f centre(8.0f, 1.0f, 0.0f);
  const PlanarGridMap disc = planar_grid::loadTiles(folder(), centre, 2.0, 2.0);
  EXPECT_EQ(
    differences(
      map, disc,
      [&](const Eigen::Vector3f& p) { return (p - centre).head<2>().norm() <= 2.0f; },
      inside),
    0u);
  EXPECT_GT(inside, 5'000u);
  EXPECT_EQ(disc.getState(Eigen::Vector3f(8.0f, 1.0f, 0.2f)), SpaceState::OCCUPIED);
  EXPECT_EQ(disc.getState(Eigen::Vector3f(16.0f, 0.0f, 1.5f)), SpaceState::UNKNOWN);
}

TEST_F(MapTilesTest, AWallAcrossTilesIsOnePlaneAgain)
{
  const PlanarGridMap& map = streetMap();
  // The truth: one plane per surface, the left wall y = 3 among them.
  ASSERT_EQ(planesLike(map, Eigen::Vector3f::UnitY(), 3.0f), 1);
  const MapTileIndex index = planar_grid::saveTiles(map, folder(), 5.0);
  // The wall is stored in pieces: the frames see it from x = 1 to 20 m, so each tile
  // of y in [0, 5) from x = 0 to 20 m holds a plane of it.
  int pieces = 0;
  for (const auto& t : index.tiles)
    pieces +=
      planesLike(PlanarGridMap::load(file(t.file)), Eigen::Vector3f::UnitY(), 3.0f);
  EXPECT_EQ(pieces, 4);
  // Loaded, the pieces are one plane: of the whole street, and of three tiles.
  const PlanarGridMap all = planar_grid::loadTiles(folder(), EVERYWHERE);
  EXPECT_EQ(planesLike(all, Eigen::Vector3f::UnitY(), 3.0f), 1);
  EXPECT_EQ(all.getSurfaceLayer().getPlanes().size(),
            map.getSurfaceLayer().getPlanes().size());
  const PlanarGridMap three = planar_grid::loadTiles(
    folder(), Eigen::AlignedBox3f(Eigen::Vector3f(6.0f, 2.0f, 0.0f),
                                  Eigen::Vector3f(14.0f, 4.0f, 4.0f)));
  EXPECT_EQ(planesLike(three, Eigen::Vector3f::UnitY(), 3.0f), 1);
  EXPECT_EQ(three.getState(Eigen::Vector3f(12.0f, 3.05f, 1.5f)), SpaceState::OCCUPIED);
}

TEST_F(MapTilesTest, ABadSetIsRefusedWithTheFileAndLine)
{
  const PlanarGridMap& map = streetMap();
  const MapTileIndex index = planar_grid::saveTiles(map, folder(), 5.0);
  const std::string good = indexText();
  const auto replaced = [&good](const std::string& from, const std::string& to) {
    std::string text = good;
    const std::size_t at = text.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return text.replace(at, from.size(), to);
  };
  const auto expectError = [&](const std::string& text, const std::string& what) {
    writeIndex(text);
    const std::string error = loadError();
    EXPECT_NE(error.find(what), std::string::npos)
      << "expected '" << what << "' in '" << error << "'";
  };
  const std::string at = std::string(planar_grid::MAP_TILE_INDEX_NAME) + ":";
  expectError(replaced("version 1", "version 2"), at + "2: unknown version 2");
  expectError(replaced("tile_size_m 5", "tile_size_m 5.05"), at + "5: tile_size_m");
  expectError(replaced("resolution_m 0.1", "resolution_m -1"), at + "4: resolution_m");
  expectError(replaced("prior unknown", "prior maybe"), at + "6: prior");
  expectError(replaced("\nend\n", "\n"), "truncated");
  expectError(good + "tile 0 0 x.pgmap 1 0 0 0 1 1 1\n", "after the 'end' line");
  const std::string first = "tile " + std::to_string(index.tiles[0].key_x) + " "
                            + std::to_string(index.tiles[0].key_y) + " ";
  expectError(
    replaced(first + index.tiles[0].file, first + "../" + index.tiles[0].file),
    at + "10: file name");
  expectError(
    replaced(first + index.tiles[0].file + " ", first + index.tiles[0].file + " 12x"),
    at + "10: tile file size");
  // the second tile listed under the first one's key
  const std::string second = "tile " + std::to_string(index.tiles[1].key_x) + " "
                             + std::to_string(index.tiles[1].key_y) + " ";
  expectError(replaced(second, first), at + "11: tile key");
  // a tile whose size differs from the index
  expectError(replaced(" " + std::to_string(index.tiles[0].file_bytes) + " ",
                       " " + std::to_string(index.tiles[0].file_bytes + 1) + " "),
              index.tiles[0].file + ": " + std::to_string(index.tiles[0].file_bytes)
                + " bytes, the index says");
  writeIndex(good);
  EXPECT_EQ(loadError(), "");

  // a tile of another resolution, its size written into the index
  PlanarGridMap::Params coarse = street::params();
  coarse.resolution_m = 0.2;
  PlanarGridMap other(coarse);
  other.getSpaceLayer().setState(planar_grid::ExplicitSpaceGrid::VoxelKey(35, 0, 5),
                                 SpaceState::OCCUPIED);
  other.save(file(index.tiles[0].file));
  expectError(
    replaced(" " + std::to_string(index.tiles[0].file_bytes) + " ",
             " " + std::to_string(fs::file_size(file(index.tiles[0].file))) + " "),
    index.tiles[0].file + ": resolution_m 0.2");

  // a missing tile (of a set written again), a missing index
  const MapTileIndex again = planar_grid::saveTiles(map, folder(), 5.0);
  fs::remove(file(again.tiles[1].file));
  EXPECT_NE(loadError().find(again.tiles[1].file + ": missing"), std::string::npos)
    << loadError();
  fs::remove(file(planar_grid::MAP_TILE_INDEX_NAME));
  EXPECT_NE(loadError().find("missing"), std::string::npos);
}

TEST_F(MapTilesTest, AHalfWrittenSetIsNeverRead)
{
  // Set 1: the first half of the drive. Set 2 (the whole drive) fails while its tiles
  // are written (a folder stands where one of its tile files would go): the folder
  // still reads as set 1, exactly.
  const PlanarGridMap first = street::mapFrames(0, street::FRAMES / 2);
  const MapTileIndex one = planar_grid::saveTiles(first, folder(), 5.0);
  fs::create_directories(file("tile_g2_1_0.pgmap"));
  EXPECT_THROW(planar_grid::saveTiles(streetMap(), folder(), 5.0), IOError);
  const PlanarGridMap read = planar_grid::loadTiles(folder(), EVERYWHERE);
  EXPECT_EQ(read.getSpaceLayer(), first.getSpaceLayer());
  EXPECT_TRUE(sameCuboids(read, first));

  // Written whole, set 2 replaces set 1, whose files go.
  fs::remove_all(file("tile_g2_1_0.pgmap"));
  const MapTileIndex two = planar_grid::saveTiles(streetMap(), folder(), 5.0);
  EXPECT_EQ(two.generation, one.generation + 1);
  for (const auto& t : one.tiles)
    EXPECT_FALSE(fs::exists(file(t.file))) << t.file;
  // A save that did not finish leaves files no index names; the next save removes
  // them, and leaves the files that are not a set's.
  std::ofstream(file("tile_g7_0_0.pgmap")) << "left by a crash";
  std::ofstream(file("notes.txt")) << "not a tile";
  const MapTileIndex three = planar_grid::saveTiles(streetMap(), folder(), 5.0);
  std::size_t files = 0;
  for (const auto& entry : fs::directory_iterator(folder_))
    files += entry.path().filename() != "notes.txt" ? 1 : 0;
  EXPECT_EQ(files, three.tiles.size() + 2); // the tiles, the base and the index
  EXPECT_TRUE(fs::exists(file("notes.txt")));
  EXPECT_EQ(planar_grid::loadTiles(folder(), EVERYWHERE).getSpaceLayer(),
            streetMap().getSpaceLayer());
}

TEST_F(MapTilesTest, AnEmptyMapGivesAnEmptySet)
{
  PlanarGridMap::Params params = street::params();
  params.resolution_m = 0.05;
  const PlanarGridMap empty(params);
  const MapTileIndex index = planar_grid::saveTiles(empty, folder(), 2.0);
  EXPECT_TRUE(index.tiles.empty());
  EXPECT_EQ(planar_grid::readTileIndex(folder()).tiles.size(), 0u);
  const PlanarGridMap loaded = planar_grid::loadTiles(folder(), EVERYWHERE);
  EXPECT_EQ(loaded, empty);
  EXPECT_EQ(loaded.getResolution(), 0.05);
}

TEST_F(MapTilesTest, InvalidTileSizesAreRefused)
{
  const PlanarGridMap& map = streetMap();
  for (const double size : {0.0, -5.0, 0.25, std::nan(""), 1e6})
    EXPECT_THROW(planar_grid::saveTiles(map, folder(), size), planar_grid::Exception)
      << size;
  EXPECT_THROW(planar_grid::loadTiles(folder(), EVERYWHERE, -1.0),
               planar_grid::Exception);
}

TEST_F(MapTilesTest, ARealMapFileRoundTrips)
{
  // The fuzz corpus' wall map (a real map file: 12 voxels, one plane) in 1 m tiles:
  // its plane in several pieces, loaded back as one.
  const std::string path =
    std::string(PLANAR_GRID_SOURCE_DIR) + "/tests/fuzz/corpus/fuzz_map_file/wall.pgmap";
  const PlanarGridMap map = PlanarGridMap::load(path);
  const MapTileIndex index = planar_grid::saveTiles(map, folder(), 1.0);
  std::size_t pieces = 0;
  for (const auto& t : index.tiles)
    pieces += PlanarGridMap::load(file(t.file)).getSurfaceLayer().getPlanes().size();
  EXPECT_GE(pieces, 2u);
  const PlanarGridMap loaded = planar_grid::loadTiles(folder(), EVERYWHERE);
  EXPECT_EQ(loaded.getSpaceLayer(), map.getSpaceLayer());
  EXPECT_TRUE(sameCuboids(loaded, map));
  EXPECT_EQ(loaded.getSurfaceLayer().getPlanes().size(), 1u);
}

} // namespace
