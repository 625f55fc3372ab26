// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <gtest/gtest.h>

#include <boost/crc.hpp>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <random>
#include <string>
#include <vector>

namespace {

using planar_grid::ExplicitSpaceGrid;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarGridMap;
using planar_grid::PlaneModels;
using planar_grid::SpaceState;

class PlanarGridMapTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    folder_ = std::filesystem::temp_directory_path()
              / ("planar_grid_map_test_" + std::to_string(::getpid()) + "_"
                 + ::testing::UnitTest::GetInstance()->current_test_info()->name());
    std::filesystem::create_directories(folder_);
  }
  void TearDown() override { std::filesystem::remove_all(folder_); }

  std::string path(const std::string& name) const { return (folder_ / name).string(); }

  static std::vector<char> readAll(const std::string& file)
  {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }

  static void writeAll(const std::string& file, const std::vector<char>& bytes)
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
  }

  /** A small map: a 2 m x 1 m wall at x = 2 (normal -x, toward the origin) seen by a
   * few features, plus voxels of each state. */
  static void fill(PlanarGridMap& map)
  {
    PlaneModels planes{Eigen::Vector4f(-1.0f, 0.0f, 0.0f, 2.0f)};
    PlanarCuboids cuboids;
    PlanarCuboid wall;
    wall.normal = -Eigen::Vector3f::UnitX();
    wall.horizontal_axis = Eigen::Vector3f::UnitY();
    wall.width_m = 2.0f;
    wall.height_m = 1.0f;
    wall.thickness_m = 0.1f;
    wall.centre = Eigen::Vector3f(2.05f, 0.0f, 0.5f); // face at x = 2
    wall.plane_id = 0;
    wall.is_planar = true;
    wall.point_count = 200;
    cuboids.push_back(wall);
    pcl::PointCloud<pcl::PointXYZ> features;
    std::vector<float> probabilities;
    for (int k = 0; k < 5; ++k) {
      features.push_back(
        pcl::PointXYZ(2.0f, -0.8f + 0.4f * static_cast<float>(k), 0.5f));
      probabilities.push_back(0.9f);
    }
    map.integrateSurface(cuboids, planes, features, probabilities);
    auto& space = map.getSpaceLayer();
    for (int i = 0; i < 10; ++i)
      space.setState(ExplicitSpaceGrid::VoxelKey(i, 0, 3), SpaceState::FREE);
    space.setState(ExplicitSpaceGrid::VoxelKey(5, 5, 5), SpaceState::OCCUPIED);
    space.setState(ExplicitSpaceGrid::VoxelKey(-7, 3, 2), SpaceState::UNKNOWN);
    space.setState(ExplicitSpaceGrid::VoxelKey(40, -3, 1), SpaceState::OCCUPIED);
  }

  static PlanarGridMap::Params params()
  {
    PlanarGridMap::Params p;
    p.space.resolution_m = 0.1;
    p.surface.resolution_m = 0.1;
    p.space.prior = SpaceState::UNKNOWN;
    return p;
  }

  std::filesystem::path folder_;
};

TEST_F(PlanarGridMapTest, RoundTripIsEqualAndOneFlippedVoxelIsNot)
{
  PlanarGridMap map(params());
  fill(map);
  ASSERT_GT(map.getSurfaceLayer().getCuboids().size(), 0u);
  const std::string file = path("map.pgmap");
  map.save(file);
  const PlanarGridMap loaded = PlanarGridMap::load(file);
  EXPECT_TRUE(loaded == map);
  EXPECT_EQ(loaded.getSpaceLayer().getVoxelCount(SpaceState::OCCUPIED), 2u);
  EXPECT_EQ(loaded.getSpaceLayer().getVoxelCount(SpaceState::FREE), 10u);
  EXPECT_EQ(loaded.getSurfaceLayer().getCuboids().size(),
            map.getSurfaceLayer().getCuboids().size());
  EXPECT_DOUBLE_EQ(loaded.getResolution(), 0.1);

  map.getSpaceLayer().setState(ExplicitSpaceGrid::VoxelKey(5, 5, 5), SpaceState::FREE);
  EXPECT_FALSE(loaded == map);
  // Saved again, the file differs and loads to the changed map.
  map.save(file);
  EXPECT_TRUE(PlanarGridMap::load(file) == map);
}

TEST_F(PlanarGridMapTest, EmptyMapRoundTrips)
{
  PlanarGridMap map(params());
  const std::string file = path("empty.pgmap");
  map.save(file);
  EXPECT_TRUE(PlanarGridMap::load(file) == map);
}

TEST_F(PlanarGridMapTest, EveryTruncationIsRejected)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  const std::vector<char> bytes = readAll(file);
  ASSERT_GT(bytes.size(), 100u);
  const std::string cut = path("cut.pgmap");
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    writeAll(cut, std::vector<char>(bytes.begin(),
                                    bytes.begin() + static_cast<std::ptrdiff_t>(n)));
    EXPECT_THROW(PlanarGridMap::load(cut), planar_grid::IOError) << n << " bytes";
  }
  // Trailing data is rejected too.
  std::vector<char> longer = bytes;
  longer.push_back('x');
  writeAll(cut, longer);
  EXPECT_THROW(PlanarGridMap::load(cut), planar_grid::IOError);
}

TEST_F(PlanarGridMapTest, CorruptDataFailsTheChecksumAndNamesTheFile)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  std::vector<char> bytes = readAll(file);
  const std::string text(bytes.begin(), bytes.end());
  const std::size_t data = text.find("\ndata\n") + 6;
  ASSERT_LT(data, bytes.size());
  // Flip one bit in each data byte in turn: always the checksum.
  for (std::size_t i = data; i < bytes.size(); ++i) {
    std::vector<char> corrupt = bytes;
    corrupt[i] = static_cast<char>(corrupt[i] ^ 0x10);
    writeAll(file, corrupt);
    try {
      PlanarGridMap::load(file);
      ADD_FAILURE() << "byte " << i << " flipped was accepted";
    } catch (const planar_grid::IOError& e) {
      EXPECT_NE(std::string(e.what()).find(file), std::string::npos);
      EXPECT_NE(std::string(e.what()).find("checksum"), std::string::npos) << e.what();
    }
  }
}

TEST_F(PlanarGridMapTest, EveryFlippedByteIsRefused)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  const std::vector<char> bytes = readAll(file);
  // Every byte, header included, changed in two ways (its lowest bit, all its bits):
  // each change is an IOError naming the file, never a map with other parameters
  // (e.g. resolution_m 0.1 read as 0.3) and never a crash.
  for (std::size_t i = 0; i < bytes.size(); ++i)
    for (const char mask : {'\x01', '\xff'}) {
      std::vector<char> corrupt = bytes;
      corrupt[i] = static_cast<char>(corrupt[i] ^ mask);
      writeAll(file, corrupt);
      try {
        PlanarGridMap::load(file);
        ADD_FAILURE() << "byte " << i << " ('" << bytes[i] << "') changed was accepted";
      } catch (const planar_grid::IOError& e) {
        EXPECT_NE(std::string(e.what()).find(file), std::string::npos) << e.what();
      }
    }
}

TEST_F(PlanarGridMapTest, VersionOneFilesAreStillRead)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  const std::vector<char> bytes = readAll(file);
  std::string text(bytes.begin(), bytes.end());
  // A version 1 file: the same header with its CRC over the data only.
  const std::size_t data = text.find("\ndata\n") + 6;
  const std::size_t crc = text.find("checksum_crc32 0x") + 17;
  boost::crc_32_type data_crc;
  data_crc.process_bytes(text.data() + data, text.size() - data);
  char hex[16];
  std::snprintf(hex, sizeof(hex), "%08x", data_crc.checksum());
  text.replace(crc, 8, hex);
  text.replace(text.find("version 2"), 9, "version 1");
  writeAll(file, std::vector<char>(text.begin(), text.end()));
  EXPECT_TRUE(PlanarGridMap::load(file) == map);
  // A version 2 file relabelled version 1 keeps its header-covering CRC: refused.
  std::string relabelled(bytes.begin(), bytes.end());
  relabelled.replace(relabelled.find("version 2"), 9, "version 1");
  writeAll(file, std::vector<char>(relabelled.begin(), relabelled.end()));
  EXPECT_THROW(PlanarGridMap::load(file), planar_grid::IOError);
}

TEST_F(PlanarGridMapTest, BadHeadersAreRejected)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  const std::vector<char> bytes = readAll(file);
  const std::string text(bytes.begin(), bytes.end());
  const auto replaced = [&](const std::string& from, const std::string& to) {
    std::string t = text;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    t.replace(at, from.size(), to);
    const std::string bad = path("bad.pgmap");
    writeAll(bad, std::vector<char>(t.begin(), t.end()));
    return bad;
  };
  const auto expectError = [](const std::string& bad, const std::string& what) {
    try {
      PlanarGridMap::load(bad);
      ADD_FAILURE() << "accepted: " << what;
    } catch (const planar_grid::IOError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  };
  expectError(replaced("# Planar grid map file", "# Something else"), "first line");
  expectError(replaced("version 2", "version 3"), "version 3");
  expectError(replaced("resolution_m 0.1", "resolution_m 0"), "resolution_m");
  expectError(replaced("resolution_m 0.1", "resolution_m -0.1"), "resolution_m");
  expectError(replaced("resolution_m 0.1", "resolution_m abc"), "resolution_m");
  expectError(replaced("prior unknown", "prior maybe"), "prior");
  expectError(replaced("id PlanarGridMap\n", ""), "'id'");
  expectError(replaced("planes 1", "planes 2"), "checksum");
  expectError(replaced("space_bytes ", "space_bytes 9"), "truncated");
  expectError(replaced("version 2\n", "version 2\nversion 2\n"), "twice");
  expectError(replaced("checksum_crc32", "# a comment\nchecksum_crc32"), "checksum");
  expectError(replaced("\ndata\n", "\n"), "data");
  EXPECT_THROW(PlanarGridMap::load(path("missing.pgmap")), planar_grid::IOError);
}

TEST_F(PlanarGridMapTest, SaveIsAtomic)
{
  PlanarGridMap map(params());
  fill(map);
  const std::string file = path("map.pgmap");
  map.save(file);
  const std::vector<char> before = readAll(file);
  // A folder in the way of the temporary file's rename: the save fails, the old map
  // stays as it was and no temporary file is left.
  EXPECT_THROW(map.save(path("no_such_folder/map.pgmap")), planar_grid::IOError);
  EXPECT_EQ(readAll(file), before);
  std::size_t files = 0;
  for (const auto& entry : std::filesystem::directory_iterator(folder_))
    files += entry.is_regular_file();
  EXPECT_EQ(files, 1u);
}

TEST_F(PlanarGridMapTest, QueriesCombineTheLayers)
{
  PlanarGridMap map(params());
  fill(map);
  // Inside the wall cuboid (probability 0.9 from the features): occupied.
  const Eigen::Vector3f in_wall(2.02f, 0.0f, 0.5f);
  ASSERT_NE(map.getSurfaceLayer().findCuboid(in_wall), nullptr);
  EXPECT_EQ(map.getState(in_wall), SpaceState::OCCUPIED);
  EXPECT_NEAR(map.getOccupancy(in_wall), 0.9f, 1e-3f);
  // The free voxel row at z in [0.3, 0.4), x in [0, 1).
  EXPECT_EQ(map.getState(Eigen::Vector3f(0.55f, 0.05f, 0.35f)), SpaceState::FREE);
  EXPECT_NEAR(map.getOccupancy(Eigen::Vector3f(0.55f, 0.05f, 0.35f)), 0.1192f, 1e-4f);
  EXPECT_EQ(map.getState(Eigen::Vector3f(0.55f, 0.55f, 0.55f)), SpaceState::OCCUPIED);
  // Nowhere: the prior.
  EXPECT_EQ(map.getState(Eigen::Vector3f(-30.0f, 0.0f, 0.0f)), SpaceState::UNKNOWN);
  EXPECT_NEAR(map.getOccupancy(Eigen::Vector3f(-30.0f, 0.0f, 0.0f)), 0.5f, 1e-6f);

  // A ray along +x at z = 0.55, y = 0.55 hits the occupied voxel (5,5,5) at x in
  // [0.5, 0.6) before the wall at x = 2.
  Eigen::Vector3f hit;
  ASSERT_TRUE(map.castRay(Eigen::Vector3f(0.0f, 0.55f, 0.55f), Eigen::Vector3f::UnitX(),
                          10.0, hit));
  EXPECT_NEAR(hit.x(), 0.55f, 0.06f);
  // At y = 0.25 it misses that voxel and stops at the wall's face (x = 2).
  ASSERT_TRUE(map.castRay(Eigen::Vector3f(0.0f, 0.25f, 0.55f), Eigen::Vector3f::UnitX(),
                          10.0, hit));
  EXPECT_NEAR(hit.x(), 2.0f, 0.06f);
  // Too short to reach it, or pointing away: no hit.
  EXPECT_FALSE(map.castRay(Eigen::Vector3f(0.0f, 0.25f, 0.55f),
                           Eigen::Vector3f::UnitX(), 1.5, hit));
  EXPECT_FALSE(map.castRay(Eigen::Vector3f(0.0f, 0.25f, 0.55f),
                           -Eigen::Vector3f::UnitX(), 10.0, hit));
  EXPECT_FALSE(map.castRay(Eigen::Vector3f(0.0f, 0.25f, 0.55f), Eigen::Vector3f::Zero(),
                           10.0, hit));
}

TEST_F(PlanarGridMapTest, MemoryIsTheSumOfTheLayers)
{
  PlanarGridMap map(params());
  const auto empty = map.getMemory();
  fill(map);
  const auto filled = map.getMemory();
  EXPECT_EQ(filled.total_bytes, filled.surface_bytes + filled.space_bytes);
  EXPECT_EQ(filled.space_bytes, map.getSpaceLayer().getMemoryBytes());
  EXPECT_EQ(filled.surface_bytes, map.getSurfaceLayer().getMemoryBytes());
  EXPECT_GT(filled.space_bytes, empty.space_bytes);
  EXPECT_GT(filled.surface_bytes, empty.surface_bytes);
}

TEST_F(PlanarGridMapTest, DifferentResolutionsAreRejected)
{
  PlanarGridMap::Params p = params();
  p.surface.resolution_m = 0.2;
  EXPECT_THROW(PlanarGridMap map(p), planar_grid::Exception);
}

} // namespace
