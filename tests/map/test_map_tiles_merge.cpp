// SPDX-License-Identifier: BSD-3-Clause
// mergeTileSets() / mergeTile() / writeTileIndex() on the synthetic street of
// street_scene.h: segment maps saved as tiles and merged tile by tile, against the
// oracle of the whole maps merged and then saved as tiles.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_tiles.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "street_scene.h"

namespace {

namespace fs = std::filesystem;
namespace street = planar_grid_test::street;
using planar_grid::Exception;
using planar_grid::IOError;
using planar_grid::MapTile;
using planar_grid::MapTileIndex;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarGridMap;
using planar_grid::SpaceState;

using street::EVERYWHERE;
/** 5 m tiles cut the street (x in [-2, 20], y in [-3, 3]) into 5 x 2 squares and
 * more: every wall crosses 4 borders, the ground 9. */
constexpr double TILE_M = 5.0;

/** Fresh folders under the test temporary folder, removed at the end. */
class MapTilesMergeTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    root_ = fs::temp_directory_path()
            / ("planar_grid_tile_merge_" + std::string(info->name()) + "_"
               + std::to_string(::getpid()));
    fs::remove_all(root_);
  }
  void TearDown() override { fs::remove_all(root_); }

  /** The folder \a name under the test's folder. */
  std::string folder(const std::string& name) const { return (root_ / name).string(); }

  /** \a map saved as TILE_M tiles in folder \a name; returns the folder. */
  std::string saved(const PlanarGridMap& map, const std::string& name) const
  {
    planar_grid::saveTiles(map, folder(name), TILE_M);
    return folder(name);
  }

  fs::path root_;
};

/** The drive's segments: frames [k F / n, (k + 1) F / n), each noting its frames as
 * its observation span, as the pipeline does. */
std::vector<PlanarGridMap>
segments(int n)
{
  std::vector<PlanarGridMap> out;
  for (int k = 0; k < n; ++k)
    out.push_back(
      street::mapFrames(k * street::FRAMES / n, (k + 1) * street::FRAMES / n));
  return out;
}

/** The segments merged whole, in order, into a map of \a params. */
PlanarGridMap
mergedWhole(const std::vector<PlanarGridMap>& maps, const PlanarGridMap::Params& params)
{
  PlanarGridMap merged(params);
  for (const PlanarGridMap& m : maps)
    merged.merge(m, Eigen::Isometry3d::Identity());
  return merged;
}

/** Probes every 0.1 m over the street and 1 m beyond it, off the voxel faces: every
 * voxel column of the 5 m tiles' borders is probed. */
std::vector<Eigen::Vector3f>
denseProbes()
{
  std::vector<Eigen::Vector3f> out;
  for (int i = 0; i < 240; ++i)
    for (int j = 0; j < 80; ++j)
      for (int k = 0; k < 48; ++k)
        out.emplace_back(-2.95f + 0.1f * static_cast<float>(i),
                         -3.95f + 0.1f * static_cast<float>(j),
                         -0.35f + 0.1f * static_cast<float>(k));
  return out;
}

/** Probes where the maps' getState() differ. */
std::vector<Eigen::Vector3f>
stateDifferences(const PlanarGridMap& a, const PlanarGridMap& b)
{
  std::vector<Eigen::Vector3f> out;
  for (const Eigen::Vector3f& p : denseProbes())
    if (a.getState(p) != b.getState(p))
      out.push_back(p);
  return out;
}

/** The planar (or non-planar) cuboids as vectors of their geometry and probability
 * (m, unit vectors, probability in [0, 1]), sorted. */
std::vector<Eigen::Matrix<float, 13, 1>>
sortedCuboids(const PlanarGridMap& map, bool planar)
{
  std::vector<Eigen::Matrix<float, 13, 1>> out;
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids()) {
    if (c.is_planar != planar)
      continue;
    Eigen::Matrix<float, 13, 1> v;
    v << c.centre, c.normal, c.horizontal_axis, c.width_m, c.height_m, c.thickness_m,
      c.probability;
    out.push_back(v);
  }
  std::sort(out.begin(), out.end(), [](const auto& a, const auto& b) {
    return std::lexicographical_compare(a.data(), a.data() + 13, b.data(),
                                        b.data() + 13);
  });
  return out;
}

/** Number of cuboids of \a a that match none of \a b (each of \a b matched once)
 * within 2e-4 in every coordinate: a plane loaded from tiles is refitted from the sum
 * of its pieces' copies of one fit, and its cuboids move by float rounding (1e-5 m). */
std::size_t
unmatched(const std::vector<Eigen::Matrix<float, 13, 1>>& a,
          std::vector<Eigen::Matrix<float, 13, 1>> b)
{
  std::size_t missing = 0;
  for (const auto& v : a) {
    const auto match = std::find_if(b.begin(), b.end(), [&v](const auto& w) {
      return (v - w).cwiseAbs().maxCoeff() < 2e-4f;
    });
    if (match == b.end())
      ++missing;
    else
      b.erase(match);
  }
  return missing;
}

/** True when the cuboid sets match one to one (unmatched()). */
bool
sameSet(const std::vector<Eigen::Matrix<float, 13, 1>>& a,
        const std::vector<Eigen::Matrix<float, 13, 1>>& b)
{
  return a.size() == b.size() && unmatched(a, b) == 0;
}

/** The file names of \a folder. */
std::vector<std::string>
fileNames(const std::string& folder)
{
  std::vector<std::string> out;
  for (const auto& entry : fs::directory_iterator(folder))
    out.push_back(entry.path().filename().string());
  std::sort(out.begin(), out.end());
  return out;
}

// ---- the tests ---------------------------------------------------------------------

TEST_F(MapTilesMergeTest, PerTileMergeEqualsTheWholeMapsMergedWithoutTidying)
{
  // The oracle: the three segments merged whole, in frame order, then saved as tiles
  // and loaded. The merges of the tiles skip the planes' tidying, as loadTiles()
  // does; so does the oracle here (the next test measures the tidying).
  const std::vector<PlanarGridMap> maps = segments(3);
  PlanarGridMap::Params untidy = street::params();
  untidy.planes_absorb_overlapping = false;
  untidy.planes_replace_non_planar = false;
  planar_grid::saveTiles(mergedWhole(maps, untidy), folder("whole"), TILE_M);
  const PlanarGridMap oracle = planar_grid::loadTiles(folder("whole"), EVERYWHERE);

  const std::vector<std::string> sets{saved(maps[0], "s0"), saved(maps[1], "s1"),
                                      saved(maps[2], "s2")};
  const MapTileIndex index = planar_grid::mergeTileSets(sets, folder("out"));
  const PlanarGridMap merged = planar_grid::loadTiles(folder("out"), EVERYWHERE);
  EXPECT_EQ(index.tiles.size(),
            planar_grid::readTileIndex(folder("whole")).tiles.size());
  EXPECT_EQ(index.generation, 1u);

  // The space layer, voxel for voxel: each tile's voxels follow the spans' order.
  EXPECT_TRUE(merged.getSpaceLayer() == oracle.getSpaceLayer());
  EXPECT_EQ(merged.getObservationSpan().first, 0.0);
  EXPECT_EQ(merged.getObservationSpan().last, street::FRAMES - 1.0);
  // The state everywhere, and the cuboids up to order.
  const auto differ = stateDifferences(merged, oracle);
  EXPECT_EQ(differ.size(), 0u)
    << (differ.empty() ? Eigen::Vector3f::Zero() : differ[0]).transpose();
  const auto planar = sortedCuboids(merged, true),
             oracle_planar = sortedCuboids(oracle, true);
  EXPECT_EQ(planar.size(), oracle_planar.size());
  EXPECT_EQ(unmatched(planar, oracle_planar), 0u);
  EXPECT_TRUE(sameSet(sortedCuboids(merged, false), sortedCuboids(oracle, false)));
  EXPECT_EQ(merged.getSurfaceLayer().getPlanes().size(),
            oracle.getSurfaceLayer().getPlanes().size());
  RecordProperty("planar_cuboids", std::to_string(planar.size()));

  // The order of the folders is the order of the merges: the last segment before the
  // middle one, the middle one's span overlaps the union of the others', so its merge
  // compares them as unordered (occupied wins) and the voxels are not the drive's.
  planar_grid::mergeTileSets({sets[0], sets[2], sets[1]}, folder("shuffled"));
  EXPECT_FALSE(planar_grid::loadTiles(folder("shuffled"), EVERYWHERE).getSpaceLayer()
               == oracle.getSpaceLayer());
}

TEST_F(MapTilesMergeTest, TheTidyingTheTileMergeSkipsIsAllThatDiffers)
{
  // The first half of the drive holds a non-planar cell centred on the ground at
  // x = 18.5 m,
  // beyond the ground it saw (up to 17.2 m), so its own tidying keeps it; the second
  // half sees the ground there as a plane. Merged whole with the default parameters,
  // the merge's tidying removes the cell (a non-planar cell on a plane); merged tile by
  // tile it stays, as the tile merge skips the tidying. That cell is all that differs,
  // and the tidying done once on the loaded map removes it.
  std::vector<PlanarGridMap> maps = segments(2);
  planar_grid::PlanarCuboid cell;
  cell.normal = Eigen::Vector3f::UnitZ();
  cell.horizontal_axis = Eigen::Vector3f::UnitX();
  cell.width_m = cell.height_m = cell.thickness_m = 0.2f;
  cell.centre = Eigen::Vector3f(18.5f, 1.0f, 0.0f);
  cell.plane_id = -1;
  cell.is_planar = false;
  pcl::PointCloud<pcl::PointXYZ> feature;
  feature.push_back(pcl::PointXYZ(18.5f, 1.0f, 0.0f));
  maps[0].integrateSurface({cell}, {}, feature, {0.9f});
  ASSERT_EQ(sortedCuboids(maps[0], false).size(), 9u); // the box's 8 cells and this one

  planar_grid::saveTiles(mergedWhole(maps, street::params()), folder("whole"), TILE_M);
  const PlanarGridMap oracle = planar_grid::loadTiles(folder("whole"), EVERYWHERE);
  ASSERT_EQ(sortedCuboids(oracle, false).size(), 8u);
  planar_grid::mergeTileSets({saved(maps[0], "s0"), saved(maps[1], "s1")},
                             folder("out"));
  PlanarGridMap merged = planar_grid::loadTiles(folder("out"), EVERYWHERE);
  EXPECT_TRUE(merged.getSpaceLayer() == oracle.getSpaceLayer());
  EXPECT_TRUE(sameSet(sortedCuboids(merged, true), sortedCuboids(oracle, true)));
  const auto non_planar = sortedCuboids(merged, false);
  EXPECT_EQ(non_planar.size(), 9u);
  EXPECT_EQ(unmatched(non_planar, sortedCuboids(oracle, false)), 1u);
  // The states differ only inside the cell (its upper half, above the ground's
  // cuboid, which is 0.1 m thick below z = 0).
  const Eigen::AlignedBox3f box(cell.centre - Eigen::Vector3f::Constant(0.1f),
                                cell.centre + Eigen::Vector3f::Constant(0.1f));
  const auto differ = stateDifferences(merged, oracle);
  EXPECT_FALSE(differ.empty());
  for (const Eigen::Vector3f& p : differ)
    EXPECT_TRUE(box.contains(p)) << p.transpose();

  EXPECT_EQ(merged.removeNonPlanarCellsOnPlanes(), 1u);
  EXPECT_TRUE(sameSet(sortedCuboids(merged, false), sortedCuboids(oracle, false)));
  EXPECT_TRUE(stateDifferences(merged, oracle).empty());
}

TEST_F(MapTilesMergeTest, AnEmptySetChangesNothing)
{
  const PlanarGridMap map = street::mapFrames(0, street::FRAMES / 2);
  const std::string set = saved(map, "map");
  const std::string empty = saved(PlanarGridMap(street::params()), "empty");
  ASSERT_TRUE(planar_grid::readTileIndex(empty).tiles.empty());
  const PlanarGridMap alone = planar_grid::loadTiles(set, EVERYWHERE);
  for (const auto& order :
       {std::vector<std::string>{set, empty}, std::vector<std::string>{empty, set}}) {
    const MapTileIndex index = planar_grid::mergeTileSets(order, folder("out"));
    EXPECT_EQ(index.tiles.size(), planar_grid::readTileIndex(set).tiles.size());
    const PlanarGridMap merged = planar_grid::loadTiles(folder("out"), EVERYWHERE);
    EXPECT_TRUE(merged.getSpaceLayer() == alone.getSpaceLayer());
    EXPECT_TRUE(sameSet(sortedCuboids(merged, true), sortedCuboids(alone, true)));
    EXPECT_TRUE(sameSet(sortedCuboids(merged, false), sortedCuboids(alone, false)));
    EXPECT_EQ(merged.getSurfaceLayer().getPlanes().size(),
              alone.getSurfaceLayer().getPlanes().size());
  }
  // Only empty sets: an empty set.
  const std::string empty2 = saved(PlanarGridMap(street::params()), "empty2");
  const MapTileIndex none = planar_grid::mergeTileSets({empty, empty2}, folder("none"));
  EXPECT_TRUE(none.tiles.empty());
  EXPECT_EQ(planar_grid::loadTiles(folder("none"), EVERYWHERE),
            PlanarGridMap(street::params()));
}

TEST_F(MapTilesMergeTest, SetsThatDoNotMatchAreRefusedNamingTheFolder)
{
  const PlanarGridMap map = street::mapFrames(0, 4);
  const std::string good = saved(map, "good");
  const auto errorOf = [&](const std::vector<std::string>& folders) -> std::string {
    try {
      planar_grid::mergeTileSets(folders, folder("out"));
    } catch (const Exception& e) {
      return e.what();
    }
    return "";
  };
  // another resolution_m
  PlanarGridMap::Params coarse = street::params();
  coarse.resolution_m = 0.2;
  PlanarGridMap other(coarse);
  other.getSpaceLayer().setState(planar_grid::ExplicitSpaceGrid::VoxelKey(3, 0, 5),
                                 SpaceState::OCCUPIED);
  const std::string coarse_set = saved(other, "coarse");
  std::string error = errorOf({good, coarse_set});
  EXPECT_NE(error.find(coarse_set), std::string::npos) << error;
  EXPECT_NE(error.find("resolution_m 0.2"), std::string::npos) << error;
  // another tile size
  planar_grid::saveTiles(map, folder("ten"), 10.0);
  error = errorOf({good, folder("ten")});
  EXPECT_NE(error.find(folder("ten")), std::string::npos) << error;
  EXPECT_NE(error.find("tile_size_m 10"), std::string::npos) << error;
  // another prior
  PlanarGridMap::Params free_prior = street::params();
  free_prior.space.prior = SpaceState::FREE;
  error = errorOf({good, saved(PlanarGridMap(free_prior), "free")});
  EXPECT_NE(error.find(folder("free")), std::string::npos) << error;
  EXPECT_NE(error.find("prior free"), std::string::npos) << error;
  // one set twice, however the path is spelled: it would count its observations twice
  for (const std::string& again : {good, good + "/.", good + "/../good"}) {
    error = errorOf({good, again});
    EXPECT_NE(error.find("is given twice"), std::string::npos)
      << again << ": " << error;
    EXPECT_NE(error.find(again), std::string::npos) << error;
  }
  EXPECT_THROW(planar_grid::mergeTile({good, good}, 0, 0, folder("out"), 1), Exception);
  // not a tile folder
  EXPECT_THROW(planar_grid::mergeTileSets({good, folder("missing")}, folder("out")),
               IOError);
  EXPECT_THROW(planar_grid::mergeTileSets({}, folder("out")), Exception);
  // a key no folder holds, generation 0
  EXPECT_THROW(planar_grid::mergeTile({good}, 1000, 1000, folder("out"), 1), Exception);
  EXPECT_THROW(planar_grid::mergeTile({good}, 0, 0, folder("out"), 0), Exception);
  // nothing was written
  EXPECT_FALSE(fs::exists(folder("out") + "/" + planar_grid::MAP_TILE_INDEX_NAME));
}

TEST_F(MapTilesMergeTest, AHalfWrittenOutputLeavesThePreviousSetReadable)
{
  // The output folder holds set 1 (the first segment). A merge of both segments writes
  // its base and some tiles but not its index: the folder reads as set 1, exactly.
  const std::vector<PlanarGridMap> maps = segments(2);
  const std::string out = saved(maps[0], "out");
  const PlanarGridMap before = planar_grid::loadTiles(out, EVERYWHERE);
  const std::vector<std::string> folders{saved(maps[0], "s0"), saved(maps[1], "s1")};
  const MapTileIndex started = planar_grid::prepareTileMerge(folders, out);
  EXPECT_EQ(started.generation, 2u);
  const MapTileIndex second = planar_grid::readTileIndex(folders[1]);
  const MapTile tile = planar_grid::mergeTile(folders, second.tiles[0].key_x,
                                              second.tiles[0].key_y, out, 2);
  EXPECT_TRUE(fs::exists(out + "/" + tile.file));
  const PlanarGridMap during = planar_grid::loadTiles(out, EVERYWHERE);
  EXPECT_TRUE(during.getSpaceLayer() == before.getSpaceLayer());
  EXPECT_TRUE(sameSet(sortedCuboids(during, true), sortedCuboids(before, true)));
  EXPECT_EQ(planar_grid::readTileIndex(out).generation, 1u);

  // An index naming a file that is not there is refused, and the folder still reads
  // as set 1.
  MapTileIndex broken = started;
  MapTile ghost = tile;
  ghost.file = "tile_g2_99_99.pgmap";
  ghost.key_x = 99;
  broken.tiles = {tile, ghost};
  EXPECT_THROW(planar_grid::writeTileIndex(out, broken), IOError);
  EXPECT_TRUE(planar_grid::loadTiles(out, EVERYWHERE).getSpaceLayer()
              == before.getSpaceLayer());

  // The whole merge, in place, then replaces set 1 and removes its files and the
  // files of the merge that did not finish.
  const MapTileIndex done = planar_grid::mergeTileSets(folders, out);
  EXPECT_EQ(done.generation, 2u);
  std::vector<std::string> expected{planar_grid::MAP_TILE_INDEX_NAME, done.base_file};
  for (const MapTile& t : done.tiles)
    expected.push_back(t.file);
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(fileNames(out), expected);
  planar_grid::mergeTileSets(folders, folder("fresh"));
  EXPECT_TRUE(planar_grid::loadTiles(out, EVERYWHERE).getSpaceLayer()
              == planar_grid::loadTiles(folder("fresh"), EVERYWHERE).getSpaceLayer());
}

TEST_F(MapTilesMergeTest, OneTileAtATimeGivesTheSameSet)
{
  // The steps a distributed job runs (one task per key, in any order, then the index)
  // give the files mergeTileSets() writes, byte for byte.
  const std::vector<PlanarGridMap> maps = segments(2);
  const std::vector<std::string> folders{saved(maps[0], "s0"), saved(maps[1], "s1")};
  const MapTileIndex whole = planar_grid::mergeTileSets(folders, folder("whole"));
  MapTileIndex index = planar_grid::prepareTileMerge(folders, folder("steps"));
  for (auto t = whole.tiles.rbegin(); t != whole.tiles.rend(); ++t) {
    std::vector<std::string> holding; // only the sets that hold the key
    for (const std::string& f : folders)
      for (const MapTile& mine : planar_grid::readTileIndex(f).tiles)
        if (mine.key_x == t->key_x && mine.key_y == t->key_y)
          holding.push_back(f);
    index.tiles.push_back(planar_grid::mergeTile(holding, t->key_x, t->key_y,
                                                 folder("steps"), index.generation));
  }
  const MapTileIndex written = planar_grid::writeTileIndex(folder("steps"), index);
  ASSERT_EQ(written.tiles.size(), whole.tiles.size());
  for (std::size_t k = 0; k < whole.tiles.size(); ++k) {
    EXPECT_EQ(written.tiles[k].file, whole.tiles[k].file);
    EXPECT_EQ(written.tiles[k].file_bytes, whole.tiles[k].file_bytes);
    EXPECT_TRUE(written.tiles[k].bounds.isApprox(whole.tiles[k].bounds));
  }
  const auto read = [](const std::string& path) {
    std::ifstream in(path, std::ios::binary);
    return std::string(std::istreambuf_iterator<char>(in), {});
  };
  EXPECT_EQ(read(folder("steps") + "/" + planar_grid::MAP_TILE_INDEX_NAME),
            read(folder("whole") + "/" + planar_grid::MAP_TILE_INDEX_NAME));
}

} // namespace
