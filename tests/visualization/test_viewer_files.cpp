// SPDX-License-Identifier: BSD-3-Clause
// The viewer's PLY and OctoMap readers: files written by PCL and liboctomap read back
// with what was written; damaged files refused with the file and the cause.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/mesh_file.h>
#include <planar_grid/visualization/octomap_file.h>

#include <pcl/conversions.h>
#include <pcl/io/ply_io.h>

#include <gtest/gtest.h>
#include <octomap/OcTree.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <iterator>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;

class ViewerFilesTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    dir_ =
      fs::temp_directory_path()
      / ("planar_grid_viewer_files_"
         + std::string(::testing::UnitTest::GetInstance()->current_test_info()->name())
         + "_" + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }
  void TearDown() override
  {
    std::error_code ec;
    fs::remove_all(dir_, ec);
  }
  std::string path(const std::string& name) const { return (dir_ / name).string(); }

  static std::string readAll(const std::string& file)
  {
    std::ifstream in(file, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
  }
  static void writeAll(const std::string& file, const std::string& bytes)
  {
    std::ofstream out(file, std::ios::binary | std::ios::trunc);
    out << bytes;
  }
  /** \brief Expects \a f to throw an IOError whose message holds \a what. */
  template <typename F> static void expectError(F&& f, const std::string& what)
  {
    try {
      f();
      ADD_FAILURE() << "no error, expected: " << what;
    } catch (const planar_grid::IOError& e) {
      EXPECT_NE(std::string(e.what()).find(what), std::string::npos) << e.what();
    }
  }

  /** \brief Three voxels at 0.1 m: occupancy 0.9 and 0.7 (occupied) and 0.2 (free),
   * plus an occupied 2 x 2 x 2 cube (one pruned leaf of 0.2 m). */
  static octomap::OcTree threeVoxelsAndACube()
  {
    octomap::OcTree tree(0.1);
    const auto lo = [](double p) {
      return static_cast<float>(std::log(p / (1 - p)));
    };
    tree.setNodeValue(octomap::point3d(0.05f, 0.05f, 0.05f), lo(0.9));
    tree.setNodeValue(octomap::point3d(0.35f, 0.05f, 0.05f), lo(0.7));
    tree.setNodeValue(octomap::point3d(0.05f, 0.35f, 0.05f), lo(0.2));
    for (int k = 0; k < 8; ++k)
      tree.setNodeValue(octomap::point3d(1.05f + 0.1f * (k & 1),
                                         1.05f + 0.1f * ((k >> 1) & 1),
                                         1.05f + 0.1f * (k >> 2)),
                        lo(0.8));
    tree.updateInnerOccupancy();
    tree.prune();
    return tree;
  }

  fs::path dir_;
};

TEST_F(ViewerFilesTest, BinaryAndFullOctreesReadBackTheirLeaves)
{
  octomap::OcTree tree = threeVoxelsAndACube();
  ASSERT_TRUE(tree.write(path("tree.ot")));
  ASSERT_TRUE(tree.writeBinary(path("tree.bt")));
  for (const std::string name : {"tree.ot", "tree.bt"}) {
    ASSERT_NO_THROW(planar_grid::checkOctoMapFile(path(name)));
    const planar_grid::OctoMapLeaves leaves =
      planar_grid::loadOctoMapLeaves(path(name));
    EXPECT_DOUBLE_EQ(leaves.resolution_m, 0.1);
    // 2 voxels + the cube's 8 occupied; 1 free
    EXPECT_EQ(leaves.occupied_voxels, 10u) << name;
    EXPECT_EQ(leaves.free_voxels, 1u) << name;
    ASSERT_EQ(leaves.occupied.size(), 3u) << name; // the cube is one box
    std::size_t cubes = 0;
    for (const auto& box : leaves.occupied) {
      EXPECT_EQ(box.width_m, box.height_m);
      EXPECT_EQ(box.width_m, box.thickness_m);
      if (std::abs(box.width_m - 0.2f) < 1e-6f) {
        ++cubes;
        EXPECT_NEAR(box.centre.x(), 1.1f, 1e-5f);
        if (name == "tree.ot") {
          EXPECT_NEAR(box.probability, 0.8f, 1e-5f);
        }
      } else {
        EXPECT_NEAR(box.width_m, 0.1f, 1e-6f);
      }
      // the binary format keeps the state only: occupied leaves at clamping_thres_max
      if (name == "tree.bt") {
        EXPECT_NEAR(box.probability, 0.971f, 1e-3f);
      }
    }
    EXPECT_EQ(cubes, 1u);
  }
  // max_boxes limits the boxes, not the counts
  const auto few = planar_grid::loadOctoMapLeaves(path("tree.ot"), 1);
  EXPECT_EQ(few.occupied.size(), 1u);
  EXPECT_EQ(few.occupied_voxels, 10u);
}

TEST_F(ViewerFilesTest, DamagedOctreesAreRefusedWithTheCause)
{
  octomap::OcTree tree = threeVoxelsAndACube();
  ASSERT_TRUE(tree.write(path("tree.ot")));
  ASSERT_TRUE(tree.writeBinary(path("tree.bt")));
  for (const std::string name : {"tree.ot", "tree.bt"}) {
    const std::string bytes = readAll(path(name));
    const std::size_t data = bytes.find("\ndata\n") + 6;
    ASSERT_LT(data, bytes.size());
    // every cut inside the node stream is refused (and never crashes liboctomap)
    for (std::size_t n = data; n < bytes.size(); ++n) {
      writeAll(path("cut_" + name), bytes.substr(0, n));
      expectError([&] { planar_grid::loadOctoMapLeaves(path("cut_" + name)); },
                  "truncated");
    }
    writeAll(path("long_" + name), bytes + "x");
    expectError([&] { planar_grid::checkOctoMapFile(path("long_" + name)); },
                "1 bytes of trailing data");
    std::string other = bytes;
    other.replace(other.find("id OcTree"), 9, "id CountingOcTree");
    writeAll(path("other_" + name), other);
    expectError([&] { planar_grid::checkOctoMapFile(path("other_" + name)); },
                "is not an occupancy octree");
  }
  writeAll(path("empty.bt"), "");
  expectError([&] { planar_grid::checkOctoMapFile(path("empty.bt")); },
              "the file is empty");
  writeAll(path("cloud.bt"), "VERSION .7\nFIELDS x y z\n");
  expectError([&] { planar_grid::checkOctoMapFile(path("cloud.bt")); },
              "not an OctoMap file");
  expectError([&] { planar_grid::checkOctoMapFile(path("missing.bt")); },
              "no such file");
  // a non-finite log-odds in a full-format node
  std::string bytes = readAll(path("tree.ot"));
  const std::size_t data = bytes.find("\ndata\n") + 6;
  const float nan = std::nanf("");
  bytes.replace(data, sizeof(float), reinterpret_cast<const char*>(&nan),
                sizeof(float));
  writeAll(path("nan.ot"), bytes);
  expectError([&] { planar_grid::checkOctoMapFile(path("nan.ot")); }, "non-finite");
}

TEST_F(ViewerFilesTest, PlyMeshesReadBackAndDamagedOnesAreRefused)
{
  // A square of two triangles with red vertices, written by PCL in both encodings.
  pcl::PointCloud<pcl::PointXYZRGB> vertices;
  for (const auto& [x, y] : std::vector<std::pair<float, float>>{
         {-0.5f, -0.5f}, {0.5f, -0.5f}, {0.5f, 0.5f}, {-0.5f, 0.5f}}) {
    pcl::PointXYZRGB p;
    p.x = x;
    p.y = y;
    p.z = 0.0f;
    p.r = 255;
    p.g = p.b = 0;
    vertices.push_back(p);
  }
  pcl::PolygonMesh mesh;
  pcl::toPCLPointCloud2(vertices, mesh.cloud);
  mesh.polygons.resize(2);
  mesh.polygons[0].vertices = {0, 1, 2};
  mesh.polygons[1].vertices = {0, 2, 3};
  ASSERT_EQ(pcl::io::savePLYFileBinary(path("square.ply"), mesh), 0);
  ASSERT_EQ(pcl::io::savePLYFile(path("square_ascii.ply"), mesh), 0);
  for (const std::string name : {"square.ply", "square_ascii.ply"}) {
    const pcl::PolygonMesh read = planar_grid::loadPLYMesh(path(name));
    EXPECT_EQ(read.cloud.width * read.cloud.height, 4u) << name;
    ASSERT_EQ(read.polygons.size(), 2u) << name;
    EXPECT_EQ(read.polygons[1].vertices, (std::vector<pcl::index_t>{0, 2, 3}));
  }
  const std::string binary = readAll(path("square.ply"));
  const std::size_t data = binary.find("end_header\n") + 11;
  // the vertices cut short: refused from the header's counts
  for (std::size_t n = data; n < data + 4 * 15; n += 7) {
    writeAll(path("cut.ply"), binary.substr(0, n));
    expectError([&] { planar_grid::loadPLYMesh(path("cut.ply")); }, "truncated");
  }
  std::string huge = binary;
  huge.replace(huge.find("element vertex 4"), 16, "element vertex 4000000000");
  writeAll(path("huge.ply"), huge);
  expectError([&] { planar_grid::checkPLYFile(path("huge.ply")); },
              "declares 4000000000 vertex elements");
  writeAll(path("empty.ply"), "");
  expectError([&] { planar_grid::checkPLYFile(path("empty.ply")); }, "is empty");
  writeAll(path("nohead.ply"), "ply\nformat ascii 1.0\nelement vertex 1\n");
  expectError([&] { planar_grid::checkPLYFile(path("nohead.ply")); }, "end_header");
  writeAll(
    path("noxyz.ply"),
    "ply\nformat ascii 1.0\nelement vertex 1\nproperty float u\nend_header\n1\n");
  expectError([&] { planar_grid::checkPLYFile(path("noxyz.ply")); }, "x, y and z");
  writeAll(path("badtype.ply"), "ply\nformat ascii 1.0\nelement vertex 1\nproperty "
                                "quad x\nend_header\n1\n");
  expectError([&] { planar_grid::checkPLYFile(path("badtype.ply")); },
              "badtype.ply:4: not a PLY file: unknown property type 'quad'");
  writeAll(path("index.ply"),
           "ply\nformat ascii 1.0\nelement vertex 3\nproperty float "
           "x\nproperty float y\nproperty float z\nelement face "
           "1\nproperty list uchar int vertex_indices\nend_header\n0 "
           "0 0\n1 0 0\n0 1 0\n3 0 1 3\n");
  expectError([&] { planar_grid::loadPLYMesh(path("index.ply")); },
              "face 0 refers to vertex 3 of 3");
}

} // namespace
