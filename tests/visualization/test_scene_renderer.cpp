// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/street_camera.h>

#include <pcl/conversions.h>

#include <gtest/gtest.h>
#include <unistd.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPNGReader.h>
#include <vtkSmartPointer.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <string>
#include <utility>
#include <vector>

namespace {

namespace fs = std::filesystem;

/** \brief An RGB image read back from a PNG; row 0 is the TOP row of the picture. */
struct Image {
  int width{0};
  int height{0};
  vtkSmartPointer<vtkImageData> data;

  std::array<int, 3> at(int x, int y_from_top) const
  {
    // VTK images start at the bottom-left corner.
    const auto* p = static_cast<const unsigned char*>(
      data->GetScalarPointer(x, height - 1 - y_from_top, 0));
    return {p[0], p[1], p[2]};
  }
};

Image
readPNG(const std::string& path)
{
  vtkNew<vtkPNGReader> reader;
  reader->SetFileName(path.c_str());
  reader->Update();
  Image image;
  image.data = reader->GetOutput();
  const int* dims = image.data->GetDimensions();
  image.width = dims[0];
  image.height = dims[1];
  return image;
}

bool
isRed(const std::array<int, 3>& c)
{
  return c[0] > 200 && c[1] < 60 && c[2] < 60;
}

bool
isBlack(const std::array<int, 3>& c)
{
  return c[0] < 10 && c[1] < 10 && c[2] < 10;
}

/** \brief A flat square patch in the z = 0 plane, \a side metres wide, centred on
 * (cx, cy), 101 x 101 points (spacing side / 100). */
pcl::PointCloud<pcl::PointXYZI>
squarePatch(double cx, double cy, double side)
{
  pcl::PointCloud<pcl::PointXYZI> cloud;
  for (int i = 0; i <= 100; ++i)
    for (int j = 0; j <= 100; ++j) {
      pcl::PointXYZI p;
      p.x = static_cast<float>(cx + side * (i / 100.0 - 0.5));
      p.y = static_cast<float>(cy + side * (j / 100.0 - 0.5));
      p.z = 0.0f;
      p.intensity = 0.0f;
      cloud.push_back(p);
    }
  return cloud;
}

/** \brief Looks down -z at the origin from 10 m; with a 30 degree vertical view angle
 * the image spans 2 * 10 * tan(15 deg) = 5.36 m vertically. */
planar_grid::CameraParameters
topCamera()
{
  planar_grid::CameraParameters camera;
  camera.position = Eigen::Vector3d(0.0, 0.0, 10.0);
  camera.focal_point = Eigen::Vector3d(0.0, 0.0, 0.0);
  camera.view_up = Eigen::Vector3d(0.0, 1.0, 0.0);
  camera.view_angle_deg = 30.0;
  return camera;
}

class SceneRendererTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    if (!planar_grid::hasDisplay())
      GTEST_SKIP() << "no X display; run under xvfb-run -a";
    const std::string name =
      std::string("planar_grid_test_viz_")
      + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"
      + std::to_string(::getpid());
    dir_ = fs::temp_directory_path() / name;
    fs::create_directories(dir_);
  }

  void TearDown() override
  {
    std::error_code ec;
    if (!dir_.empty())
      fs::remove_all(dir_, ec);
  }

  /** \brief A per-test folder, removed afterwards. */
  fs::path dir_;
};

TEST_F(SceneRendererTest, SnapshotHasRequestedSizeAndRedPatchAtCentre)
{
  planar_grid::SceneRenderer renderer;
  renderer.setBackground(Eigen::Vector3d(0.0, 0.0, 0.0));
  // 2 m square at the origin: about 2 / 5.36 = 37% of the image height, centred.
  renderer.addPointCloud(squarePatch(0.0, 0.0, 2.0), planar_grid::ColorMode::SOLID, 4.0,
                         Eigen::Vector3d(1.0, 0.0, 0.0));
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "centre.png").string();
  renderer.saveSnapshot(path, 320, 240);

  ASSERT_TRUE(fs::exists(path));
  const Image image = readPNG(path);
  ASSERT_EQ(image.width, 320);
  ASSERT_EQ(image.height, 240);

  int red = 0, background = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const auto c = image.at(x, y);
      red += isRed(c) ? 1 : 0;
      background += isBlack(c) ? 1 : 0;
    }
  // The patch covers about (0.37 * 240)^2 = 89^2 px, i.e. ~7900 px of 76800; allow for
  // the gaps between points.
  EXPECT_GT(red, 3000);
  EXPECT_LT(red, 20000);
  EXPECT_EQ(red + background, image.width * image.height) << "only red and background";

  EXPECT_TRUE(isRed(image.at(160, 120)));
  EXPECT_TRUE(isBlack(image.at(2, 2)));
  EXPECT_TRUE(isBlack(image.at(317, 2)));
  EXPECT_TRUE(isBlack(image.at(2, 237)));
  EXPECT_TRUE(isBlack(image.at(317, 237)));
  // Everything red lies within the projected square (half side 0.37 * 240 / 2 = 45 px
  // around the centre, plus the point size).
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      if (isRed(image.at(x, y))) {
        EXPECT_LT(std::abs(x - 160), 50) << "x=" << x << " y=" << y;
        EXPECT_LT(std::abs(y - 120), 50) << "x=" << x << " y=" << y;
      }
}

TEST_F(SceneRendererTest, PatchShiftedRightAppearsOnlyInRightHalf)
{
  planar_grid::SceneRenderer renderer;
  // 1 m square centred 1.5 m to the right of the focal point (+x is image right with
  // view_up +y when looking down -z): image x = 160 + 1.5 / 5.36 * 240 = 227 px.
  renderer.addPointCloud(squarePatch(1.5, 0.0, 1.0), planar_grid::ColorMode::SOLID, 4.0,
                         Eigen::Vector3d(1.0, 0.0, 0.0));
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "right.png").string();
  renderer.saveSnapshot(path, 320, 240);

  const Image image = readPNG(path);
  ASSERT_EQ(image.width, 320);
  ASSERT_EQ(image.height, 240);
  int red_left = 0, red_right = 0;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      if (isRed(image.at(x, y)))
        ++(x < image.width / 2 ? red_left : red_right);
  EXPECT_EQ(red_left, 0);
  EXPECT_GT(red_right, 1000);
  EXPECT_TRUE(isRed(image.at(227, 120)));
  EXPECT_TRUE(isBlack(image.at(160, 120)));
}

TEST_F(SceneRendererTest, CuboidsRenderWhereTheyAreAndNonPlanarIsGrey)
{
  // A planar cuboid (plane 0) 1 m x 1 m facing up at x = -1.5 m and a non-planar one
  // (plane_id -1) at x = +1.5 m, seen from the top camera: image x = 160 -+ 1.5 / 5.36
  // * 240 = 93 and 227 px. The planar one takes the label palette's colour for plane 0
  // (not background, not grey); the non-planar one the grey given.
  planar_grid::PlanarCuboids cuboids(2);
  for (int k = 0; k < 2; ++k) {
    auto& c = cuboids[static_cast<std::size_t>(k)];
    c.centre = Eigen::Vector3f(k == 0 ? -1.5f : 1.5f, 0.0f, -0.05f);
    c.normal = Eigen::Vector3f::UnitZ();
    c.horizontal_axis = Eigen::Vector3f::UnitX();
    c.width_m = c.height_m = 1.0f;
    c.thickness_m = 0.1f;
    c.plane_id = k == 0 ? 0 : -1;
    c.is_planar = k == 0;
  }
  planar_grid::SceneRenderer renderer;
  renderer.setBackground(Eigen::Vector3d(0.0, 0.0, 0.0));
  renderer.addCuboids(cuboids, false, 1.0, Eigen::Vector3d(0.5, 0.5, 0.5));
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "cuboids.png").string();
  renderer.saveSnapshot(path, 320, 240);
  const Image image = readPNG(path);
  const auto planar = image.at(93, 120);
  const auto non_planar = image.at(227, 120);
  EXPECT_FALSE(isBlack(planar));
  EXPECT_FALSE(planar[0] == planar[1] && planar[1] == planar[2]) << "a hue, not grey";
  // Grey (lighting may darken it, but the three channels stay equal).
  EXPECT_FALSE(isBlack(non_planar));
  EXPECT_NEAR(non_planar[0], non_planar[1], 2);
  EXPECT_NEAR(non_planar[1], non_planar[2], 2);
  EXPECT_TRUE(isBlack(image.at(160, 120))) << "nothing between the two";
  EXPECT_TRUE(isBlack(image.at(160, 10)));
  EXPECT_THROW(renderer.addCuboids(cuboids, false, 0.0), planar_grid::Exception);
}

TEST_F(SceneRendererTest, MapOccupiedVoxelsRenderWhereTheyAreAndAreFramedExactly)
{
  // A 2 m x 1 m slab of occupied voxels (20 x 10 at z = 0, x in [1, 3) m) and one voxel
  // at x = -3 m, no cuboids: 201 occupied voxels drawn as grey boxes. The top preset
  // frames their exact bounds: the grey spans the image from the single voxel to the
  // slab's far end (more than 90 % of the width). Bounds padded by the largest box
  // (2 m on each side) would leave the grey in less than 80 % of it.
  planar_grid::PlanarGridMap::Params params;
  params.resolution_m = 0.1;
  planar_grid::PlanarGridMap map(params);
  auto& space = map.getSpaceLayer();
  std::size_t set = 0;
  for (int x = 10; x < 30; ++x)
    for (int y = -5; y < 5; ++y, ++set)
      space.setState(planar_grid::ExplicitSpaceGrid::VoxelKey(x, y, 0),
                     planar_grid::SpaceState::OCCUPIED);
  space.setState(planar_grid::ExplicitSpaceGrid::VoxelKey(-30, 0, 0),
                 planar_grid::SpaceState::OCCUPIED);
  ++set;

  planar_grid::SceneRenderer renderer;
  renderer.setBackground(Eigen::Vector3d(0.0, 0.0, 0.0));
  const planar_grid::MapRenderSummary summary = renderer.addMap(map);
  EXPECT_EQ(summary.cuboids, 0u);
  EXPECT_EQ(summary.occupied_voxel_boxes, set);
  EXPECT_EQ(summary.unknown_boxes, 0u);
  renderer.setCamera(planar_grid::CameraPreset::TOP);
  const std::string path = (dir_ / "map.png").string();
  renderer.saveSnapshot(path, 320, 240);
  const Image image = readPNG(path);
  int first = image.width, last = -1;
  for (int x = 0; x < image.width; ++x)
    for (int y = 0; y < image.height; ++y)
      if (!isBlack(image.at(x, y))) {
        first = std::min(first, x);
        last = std::max(last, x);
      }
  ASSERT_GE(last, first) << "nothing drawn";
  EXPECT_GT(last - first + 1, 0.9 * image.width);
  // The slab's centre (x = 2 m) is grey; the gap between the voxel and the slab is not
  // drawn.
  const int slab_x =
    first + static_cast<int>(std::lround((2.0 + 3.0) / 6.0 * (last - first)));
  const auto slab = image.at(slab_x, image.height / 2);
  EXPECT_FALSE(isBlack(slab));
  EXPECT_NEAR(slab[0], slab[1], 2);
  EXPECT_NEAR(slab[1], slab[2], 2);
  const int gap_x = first + static_cast<int>(std::lround(3.0 / 6.0 * (last - first)));
  EXPECT_TRUE(isBlack(image.at(gap_x, image.height / 2)));
}

TEST_F(SceneRendererTest, PolygonMeshRendersItsVertexColoursWhereItIs)
{
  // A 2 m x 2 m square of two triangles at z = 0, red vertices, centred on x = -1 m:
  // from the top camera (5.36 m across 240 px) it covers image x = 160 - 2 / 5.36 *
  // 240 = 70 px to 160 px; the right half of the image stays black.
  pcl::PointCloud<pcl::PointXYZRGB> vertices;
  for (const auto& [x, y] : std::vector<std::pair<float, float>>{
         {-2.0f, -1.0f}, {0.0f, -1.0f}, {0.0f, 1.0f}, {-2.0f, 1.0f}}) {
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
  planar_grid::SceneRenderer renderer;
  EXPECT_EQ(renderer.addPolygonMesh(mesh), 2u);
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "mesh.png").string();
  renderer.saveSnapshot(path, 320, 240);
  const Image image = readPNG(path);
  const auto inside = image.at(115, 120);
  EXPECT_GT(inside[0], 80);
  EXPECT_LT(inside[1], 30);
  EXPECT_LT(inside[2], 30);
  EXPECT_TRUE(isBlack(image.at(250, 120)));
  EXPECT_TRUE(isBlack(image.at(40, 120)));
  // a vertex index past the end, a bad opacity
  mesh.polygons[1].vertices = {0, 2, 4};
  EXPECT_THROW(renderer.addPolygonMesh(mesh), planar_grid::Exception);
  EXPECT_THROW(renderer.addPolygonMesh(mesh, 0.0), planar_grid::Exception);
}

TEST_F(SceneRendererTest, SnapshotIntoMissingFolderThrowsAndLeavesNothing)
{
  planar_grid::SceneRenderer renderer;
  renderer.addPointCloud(squarePatch(0.0, 0.0, 1.0), planar_grid::ColorMode::SOLID);
  const fs::path missing = dir_ / "no_such_folder";
  EXPECT_THROW(renderer.saveSnapshot((missing / "x.png").string(), 64, 48),
               planar_grid::Exception);
  EXPECT_FALSE(fs::exists(missing));
  EXPECT_TRUE(fs::is_empty(dir_)) << "no temporary file left behind";
}

TEST_F(SceneRendererTest, HeightColoringSeparatesLowAndHighPoints)
{
  // Two patches seen from above: the left one at z = 0, the right one at z = 1 m.
  pcl::PointCloud<pcl::PointXYZI> cloud = squarePatch(-1.2, 0.0, 1.0);
  pcl::PointCloud<pcl::PointXYZI> high = squarePatch(1.2, 0.0, 1.0);
  for (auto& p : high.points)
    p.z = 1.0f;
  cloud += high;
  planar_grid::SceneRenderer renderer;
  renderer.addPointCloud(cloud, planar_grid::ColorMode::HEIGHT, 4.0);
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "height.png").string();
  renderer.saveSnapshot(path, 320, 240);

  const Image image = readPNG(path);
  // Centres at x = 160 -+ 1.2 / 5.36 * 240 = 106 / 214 px (the high one slightly
  // further out, being closer to the camera).
  const auto low_color = image.at(106, 120);
  const auto high_color = image.at(214, 120);
  ASSERT_FALSE(isBlack(low_color));
  ASSERT_FALSE(isBlack(high_color));
  // Turbo: low is blue-ish (blue > red), high is red-ish (red > blue).
  EXPECT_GT(low_color[2], low_color[0]);
  EXPECT_GT(high_color[0], high_color[2]);
  EXPECT_NE(low_color, high_color);
}

TEST_F(SceneRendererTest, PresetsFrameTheWholeScene)
{
  planar_grid::SceneRenderer renderer;
  // A 40 m x 10 m area far from the origin: the preset must find it.
  pcl::PointCloud<pcl::PointXYZI> cloud = squarePatch(100.0, 50.0, 10.0);
  for (auto& p : cloud.points)
    p.x = 100.0f + 4.0f * (p.x - 100.0f);
  renderer.addPointCloud(cloud, planar_grid::ColorMode::SOLID, 2.0,
                         Eigen::Vector3d(1.0, 0.0, 0.0));
  for (const auto preset :
       {planar_grid::CameraPreset::TOP, planar_grid::CameraPreset::OBLIQUE}) {
    renderer.setCamera(preset);
    const std::string path = (dir_ / "preset.png").string();
    renderer.saveSnapshot(path, 320, 240);
    const Image image = readPNG(path);
    int red = 0;
    bool red_on_border = false;
    for (int y = 0; y < image.height; ++y)
      for (int x = 0; x < image.width; ++x)
        if (isRed(image.at(x, y))) {
          ++red;
          red_on_border |=
            x == 0 || y == 0 || x == image.width - 1 || y == image.height - 1;
        }
    EXPECT_GT(red, 2000) << "preset " << static_cast<int>(preset);
    EXPECT_FALSE(red_on_border)
      << "preset " << static_cast<int>(preset) << " cuts the scene";
    EXPECT_TRUE(isRed(image.at(160, 120))) << "preset " << static_cast<int>(preset);
  }
}

TEST_F(SceneRendererTest, TrajectoryAndTextRender)
{
  planar_grid::SceneRenderer renderer;
  renderer.addTrajectory(
    {Eigen::Vector3d(-2.0, 0.0, 0.0), Eigen::Vector3d(2.0, 0.0, 0.0)},
    Eigen::Vector3d(0.0, 1.0, 0.0), 5.0);
  renderer.addText("trajectory");
  renderer.setCamera(topCamera());
  const std::string path = (dir_ / "trajectory.png").string();
  renderer.saveSnapshot(path, 320, 240);
  const Image image = readPNG(path);
  // The horizontal line through the centre is green.
  const auto c = image.at(160, 120);
  EXPECT_GT(c[1], 200);
  EXPECT_LT(c[0], 60);
  // Text in the top-left corner: some non-background pixels there.
  int text_pixels = 0;
  for (int y = 0; y < 40; ++y)
    for (int x = 0; x < 160; ++x)
      text_pixels += isBlack(image.at(x, y)) ? 0 : 1;
  EXPECT_GT(text_pixels, 20);
}

TEST_F(SceneRendererTest, DegenerateInputAddsNothingAndStillRenders)
{
  planar_grid::SceneRenderer renderer;
  pcl::PointCloud<pcl::PointXYZI> empty;
  renderer.addPointCloud(empty);
  pcl::PointCloud<pcl::PointXYZI> nans = squarePatch(0.0, 0.0, 1.0);
  for (auto& p : nans.points)
    p.x = std::numeric_limits<float>::quiet_NaN();
  renderer.addPointCloud(nans);
  renderer.addTrajectory({Eigen::Vector3d::Zero()});
  renderer.setCamera(planar_grid::CameraPreset::OBLIQUE);
  const std::string path = (dir_ / "empty.png").string();
  renderer.saveSnapshot(path, 64, 48);
  const Image image = readPNG(path);
  ASSERT_EQ(image.width, 64);
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x)
      ASSERT_TRUE(isBlack(image.at(x, y)));
}

TEST_F(SceneRendererTest, StreetCameraLooksAlongTheTravelFromBehindThePose)
{
  // A z-up street along +x; the camera follows the pose at (20, 0, 1.5) with pitch
  // 0.45 rad, view angle 30 deg, 40 m ahead: it sits 11.3 m behind and 9.8 m above
  // the pose, the pose at the bottom edge of the image, the point 40 m ahead at the
  // top edge. Markers: 0.6 m cubes of points at the pose's height, each its own
  // colour (points are unlit, so the colours come out exactly).
  const Eigen::Vector3d pose(20.0, 0.0, 1.5);
  const auto cube = [](const Eigen::Vector3d& centre) {
    pcl::PointCloud<pcl::PointXYZI> cloud;
    for (int i = -3; i <= 3; ++i)
      for (int j = -3; j <= 3; ++j)
        for (int k = -3; k <= 3; ++k) {
          pcl::PointXYZI p;
          p.getVector3fMap() = (centre + 0.1 * Eigen::Vector3d(i, j, k)).cast<float>();
          p.intensity = 0.0f;
          cloud.push_back(p);
        }
    return cloud;
  };
  planar_grid::SceneRenderer renderer;
  const auto add = [&](const Eigen::Vector3d& offset, const Eigen::Vector3d& rgb) {
    renderer.addPointCloud(cube(pose + offset), planar_grid::ColorMode::SOLID, 3.0,
                           rgb);
  };
  add(Eigen::Vector3d(2.0, 0.0, 0.0), Eigen::Vector3d(1.0, 0.0, 0.0));   // near: red
  add(Eigen::Vector3d(30.0, 0.0, 0.0), Eigen::Vector3d(0.0, 1.0, 0.0));  // far: green
  add(Eigen::Vector3d(15.0, 5.0, 0.0), Eigen::Vector3d(0.0, 0.0, 1.0));  // left: blue
  add(Eigen::Vector3d(15.0, -5.0, 0.0), Eigen::Vector3d(1.0, 0.0, 1.0)); // right
  add(Eigen::Vector3d(-5.0, 0.0, 0.0), Eigen::Vector3d(0.0, 1.0, 1.0));  // behind
  planar_grid::PoseVector track;
  for (int k = 0; k <= 60; ++k) {
    Eigen::Isometry3d p = Eigen::Isometry3d::Identity();
    p.translation() = Eigen::Vector3d(k, 0.0, 1.5);
    track.push_back(p);
  }
  planar_grid::StreetCameraParameters parameters;
  parameters.pose_fraction = 1.0 / 3.0; // pose round(60 / 3) = 20, at x = 20 m
  parameters.pitch_rad = 0.45;
  parameters.view_angle_deg = 30.0;
  parameters.look_ahead_m = 40.0;
  renderer.setCamera(planar_grid::streetCamera(track, parameters));
  const std::string path = (dir_ / "street.png").string();
  renderer.saveSnapshot(path, 400, 250);
  const Image image = readPNG(path);
  ASSERT_EQ(image.width, 400);
  ASSERT_EQ(image.height, 250);

  // Per colour: pixel count, mean row and column, and the column range.
  struct Blob {
    int count{0};
    double row{0.0}, column{0.0};
    int min_column{1000}, max_column{-1};
  };
  const std::array<std::array<int, 3>, 5> colours{
    {{255, 0, 0}, {0, 255, 0}, {0, 0, 255}, {255, 0, 255}, {0, 255, 255}}};
  std::array<Blob, 5> blobs;
  for (int y = 0; y < image.height; ++y)
    for (int x = 0; x < image.width; ++x) {
      const auto c = image.at(x, y);
      for (std::size_t b = 0; b < blobs.size(); ++b) {
        bool match = true;
        for (std::size_t k = 0; k < 3; ++k)
          match = match && std::abs(c[k] - colours[b][k]) < 40;
        if (!match)
          continue;
        Blob& blob = blobs[b];
        ++blob.count;
        blob.row += y;
        blob.column += x;
        blob.min_column = std::min(blob.min_column, x);
        blob.max_column = std::max(blob.max_column, x);
      }
    }
  for (auto& blob : blobs)
    if (blob.count > 0) {
      blob.row /= blob.count;
      blob.column /= blob.count;
    }
  const Blob &near = blobs[0], &far = blobs[1], &left = blobs[2], &right = blobs[3],
             &behind = blobs[4];
  // Near (2 m ahead): 36.3 deg below the horizontal, 10.5 deg below the optical axis:
  // row 125 + 125 tan(10.5 deg) / tan(15 deg) = 212, centre column 200.
  ASSERT_GT(near.count, 20);
  EXPECT_NEAR(near.row, 212.0, 12.0);
  EXPECT_NEAR(near.column, 200.0, 8.0);
  // Far (30 m ahead): 13.3 deg below the horizontal, 12.5 deg above the axis: row
  // 125 - 125 tan(12.5 deg) / tan(15 deg) = 22.
  ASSERT_GT(far.count, 5);
  EXPECT_NEAR(far.row, 22.0, 12.0);
  EXPECT_NEAR(far.column, 200.0, 8.0);
  // Left of the travel direction (+y with z up, driving +x) is left in the image: 5 m
  // aside at a depth of 28.0 m along the optical axis is 5 / 28.0 * 125 / tan(15 deg)
  // = 83 px from the centre column, at row 81 both.
  ASSERT_GT(left.count, 5);
  ASSERT_GT(right.count, 5);
  EXPECT_LT(left.max_column, 190);
  EXPECT_GT(right.min_column, 210);
  EXPECT_NEAR(left.column, 117.0, 8.0);
  EXPECT_NEAR(right.column, 283.0, 8.0);
  EXPECT_NEAR(left.row, 81.0, 8.0);
  EXPECT_NEAR(left.row, right.row, 3.0);
  // 5 m behind the pose is below the bottom edge: not in view.
  EXPECT_EQ(behind.count, 0);
}

} // namespace

TEST(SceneRenderer, InvalidParametersThrow)
{
  // No display needed: nothing is rendered.
  planar_grid::SceneRenderer renderer;
  planar_grid::CameraParameters camera;
  camera.focal_point = camera.position;
  EXPECT_THROW(renderer.setCamera(camera), planar_grid::Exception);
  camera = planar_grid::CameraParameters();
  camera.view_up = Eigen::Vector3d(0.0, 0.0, 1.0); // parallel to the view direction
  EXPECT_THROW(renderer.setCamera(camera), planar_grid::Exception);
  camera = planar_grid::CameraParameters();
  camera.view_angle_deg = 0.0;
  EXPECT_THROW(renderer.setCamera(camera), planar_grid::Exception);
  EXPECT_THROW(renderer.addPointCloud(squarePatch(0.0, 0.0, 1.0),
                                      planar_grid::ColorMode::SOLID, 0.0),
               planar_grid::Exception);
  EXPECT_THROW(renderer.saveSnapshot("x.png", 0, 10), planar_grid::Exception);
}

TEST(SceneRenderer, WithoutDisplayHasDisplayIsFalseAndSnapshotThrows)
{
  const char* saved = std::getenv("DISPLAY");
  const std::string saved_display = saved != nullptr ? saved : "";
  ::unsetenv("DISPLAY");
  EXPECT_FALSE(planar_grid::hasDisplay());
  planar_grid::SceneRenderer renderer;
  renderer.addPointCloud(squarePatch(0.0, 0.0, 1.0));
  const fs::path path =
    fs::temp_directory_path()
    / ("planar_grid_test_viz_nodisplay_" + std::to_string(::getpid()) + ".png");
  EXPECT_THROW(renderer.saveSnapshot(path.string(), 64, 48), planar_grid::Exception);
  EXPECT_FALSE(fs::exists(path));
  if (saved != nullptr)
    ::setenv("DISPLAY", saved_display.c_str(), 1);
}
