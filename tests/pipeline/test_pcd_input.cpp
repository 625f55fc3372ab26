// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/floor_alignment.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/common/transforms.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/point_types_conversion.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_parallel_plane.h>
#include <pcl/sample_consensus/sac_model_plane.h>
#include <pcl/search/kdtree.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <cmath>
#include <filesystem>
#include <memory>
#include <mutex>
#include <random>
#include <string>
#include <vector>

#include "../odometry/reprojected_view.h"
#include "../test_constants.h"

namespace fs = std::filesystem;
using planar_grid::parsePipelineConfig;

namespace {

using planar_grid_test::CLOUDS;
using planar_grid_test::DATA;
using planar_grid_test::PI;

using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** \brief A room in its own z-up frame, metres: floor z = 0 over [-3, 3] x [-2, 2],
 * four walls 2.5 m high and a table top at z = 0.75, on a 4 cm grid with 3 mm noise. */
Cloud
room()
{
  std::mt19937 rng(11);
  std::normal_distribution<float> noise(0.0f, 0.003f);
  Cloud cloud;
  const auto add = [&](float x, float y, float z) {
    cloud.push_back(pcl::PointXYZ(x + noise(rng), y + noise(rng), z + noise(rng)));
  };
  for (float x = -3.0f; x <= 3.0f; x += 0.04f)
    for (float y = -2.0f; y <= 2.0f; y += 0.04f)
      add(x, y, 0.0f);
  for (float z = 0.04f; z <= 2.5f; z += 0.04f) {
    for (float x = -3.0f; x <= 3.0f; x += 0.04f) {
      add(x, -2.0f, z);
      add(x, 2.0f, z);
    }
    for (float y = -2.0f; y <= 2.0f; y += 0.04f) {
      add(-3.0f, y, z);
      add(3.0f, y, z);
    }
  }
  for (float x = 0.9f; x <= 2.1f; x += 0.04f)
    for (float y = 0.4f; y <= 1.2f; y += 0.04f)
      add(x, y, 0.75f);
  return cloud;
}

/** \brief The frame's cloud (as XYZ) moved to the world by its pose. */
Cloud
worldCloud(const planar_grid::Frame& frame)
{
  Cloud points, world;
  pcl::copyPointCloud(*frame.cloud, points);
  pcl::transformPointCloud(points, world, frame.world_T_camera.cast<float>().matrix());
  return world;
}

/** \brief Tilt from the horizontal, degrees, of the floor below \a sensor_origin in a
 * world cloud, found with the world's +z as the prior up. */
double
floorTiltDeg(const Cloud& world, const Eigen::Vector3d& sensor_origin)
{
  Eigen::Vector4f floor;
  std::size_t inliers = 0;
  if (!planar_grid::estimateFloorPlane(
        world, sensor_origin.cast<float>(), Eigen::Vector3f::UnitZ(),
        planar_grid::FloorEstimationParams(), floor, inliers))
    return 90.0;
  return planar_grid::planeTiltFromHorizontal(floor) * 180.0 / PI;
}

/** \brief A RANSAC plane (PCL's plane model and estimator, refitted to its inliers, as
 * pcl::SACSegmentation with optimized coefficients does), optionally parallel to
 * \a axis within \a eps_rad. The model is created here, not inside PCL's library:
 * SACSegmentation allocates it there and frees it in the caller, which
 * AddressSanitizer reports as a malloc / operator delete mismatch. */
bool
fitPlane(const Cloud::ConstPtr& cloud,
         double threshold_m,
         const Eigen::Vector3f* axis,
         double eps_rad,
         pcl::Indices& inliers,
         Eigen::Vector4f& plane)
{
  pcl::SampleConsensusModel<pcl::PointXYZ>::Ptr model;
  if (axis) {
    pcl::SampleConsensusModelParallelPlane<pcl::PointXYZ>::Ptr parallel(
      new pcl::SampleConsensusModelParallelPlane<pcl::PointXYZ>(cloud));
    parallel->setAxis(*axis);
    parallel->setEpsAngle(eps_rad);
    model = parallel;
  } else
    model.reset(new pcl::SampleConsensusModelPlane<pcl::PointXYZ>(cloud));
  pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model, threshold_m);
  ransac.setMaxIterations(50); // SACSegmentation's default
  if (!ransac.computeModel())
    return false;
  ransac.getInliers(inliers);
  Eigen::VectorXf coefficients, refined;
  ransac.getModelCoefficients(coefficients);
  model->optimizeModelCoefficients(inliers, coefficients, refined);
  model->selectWithinDistance(refined, threshold_m, inliers);
  if (refined.size() != 4)
    return false;
  plane = refined.head<4>();
  return true;
}

/** \brief RMS point-to-plane distance, metres, from \a source's points (voxels of
 * \a leaf_m) to \a target's surface (normals from 3 leaf sizes), over the points
 * within \a max_distance_m of \a target; \a overlap gets their fraction. */
double
pointToPlaneResidual(const Cloud& source,
                     const Cloud& target,
                     float leaf_m,
                     float max_distance_m,
                     double& overlap)
{
  Cloud::Ptr target_down(new Cloud), source_down(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(leaf_m, leaf_m, leaf_m);
  grid.setInputCloud(Cloud::Ptr(new Cloud(target)));
  grid.filter(*target_down);
  grid.setInputCloud(Cloud::Ptr(new Cloud(source)));
  grid.filter(*source_down);
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(target_down);
  estimation.setSearchMethod(
    pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  estimation.setRadiusSearch(3.0 * leaf_m);
  pcl::PointCloud<pcl::Normal> normals;
  estimation.compute(normals);
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(target_down);
  pcl::Indices index(1);
  std::vector<float> squared(1);
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& p : source_down->points) {
    if (tree.nearestKSearch(p, 1, index, squared) != 1
        || squared[0] > max_distance_m * max_distance_m)
      continue;
    const auto k = static_cast<std::size_t>(index[0]);
    const Eigen::Vector3f n = normals[k].getNormalVector3fMap();
    if (!std::isfinite(n.x()))
      continue;
    const double d = n.dot(p.getVector3fMap() - (*target_down)[k].getVector3fMap());
    sum += d * d;
    ++count;
  }
  overlap = source_down->empty()
              ? 0.0
              : static_cast<double>(count) / static_cast<double>(source_down->size());
  return count == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(count));
}

/** \brief A fresh temporary folder per test. */
class PCDInputTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_pcd_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  /** The frame source of a pcd_files input over \a files with \a poses. */
  std::unique_ptr<planar_grid::FrameSource> source(const std::string& files,
                                                   const std::string& poses = "") const
  {
    const auto config =
      parsePipelineConfig("input:\n  type: pcd_files\n  files: " + files + "\n" + poses
                            + "pipeline:\n  - type: voxel_grid\n",
                          "t.yaml", "/");
    return planar_grid::createFrameSource(config.input);
  }

  static bool haveData(const std::string& path) { return fs::exists(path); }

  /** \brief config/room_scans.yaml's run: each scan as the runner loaded it (before
   * its first stage) moved to the world by the pose of the runner's registration, and
   * the map. */
  struct RoomScansRun {
    planar_grid::PipelineConfig config;
    std::vector<Eigen::Isometry3d> world_T_camera;
    std::vector<Cloud> world;
    std::shared_ptr<const planar_grid::PlanarGridMap> map;
  };

  /** \brief config/room_scans.yaml, as shipped, run once for the suite (the
   * registration and the map of the two LiDAR scans cost seconds each under the
   * sanitizers); its outputs are not written. */
  static const RoomScansRun& roomScansRun()
  {
    if (room_scans_run_)
      return *room_scans_run_;
    auto run = std::make_unique<RoomScansRun>();
    run->config = planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                                  + "/config/room_scans.yaml");
    auto config = run->config;
    const fs::path folder =
      fs::temp_directory_path()
      / ("planar_grid_pcd_room_scans_" + std::to_string(::getpid()));
    config.output.folder = folder.string();
    planar_grid::PipelineRunner runner(config);
    run->world_T_camera.resize(runner.frameCount());
    run->world.resize(runner.frameCount());
    std::mutex loaded;
    runner.setStageCallback([&](std::size_t s, planar_grid::Frame& frame) {
      if (s != 0)
        return;
      EXPECT_TRUE(frame.has_pose);
      const std::lock_guard<std::mutex> lock(loaded);
      run->world_T_camera.at(frame.sequence_number) = frame.world_T_camera;
      run->world.at(frame.sequence_number) = worldCloud(frame);
    });
    runner.run();
    fs::remove_all(folder);
    run->map = runner.state().map;
    room_scans_run_ = std::move(run);
    return *room_scans_run_;
  }

  static void TearDownTestSuite() { room_scans_run_.reset(); }

  fs::path dir_;

private:
  static inline std::unique_ptr<RoomScansRun> room_scans_run_;
};

} // namespace

TEST_F(PCDInputTest, ViewpointOfAKnownCameraPoseGivesAHorizontalFloor)
{
  // A camera 1.4 m above the floor, pitched 25 deg down and yawed 30 deg, sees the
  // room in its optical frame; its VIEWPOINT is that pose in PCL's y-up world.
  Eigen::Isometry3d world_T_camera = Eigen::Isometry3d::Identity();
  world_T_camera.linear() =
    planar_grid::zUpWorldFrom(planar_grid::WorldConvention::OPTICAL).linear()
    * Eigen::AngleAxisd(-30.0 * PI / 180.0, Eigen::Vector3d::UnitY()).matrix()
    * Eigen::AngleAxisd(-25.0 * PI / 180.0, Eigen::Vector3d::UnitX()).matrix();
  world_T_camera.translation() = Eigen::Vector3d(-1.0, 0.5, 1.4);
  Cloud camera_cloud;
  pcl::transformPointCloud(room(), camera_cloud,
                           world_T_camera.inverse().cast<float>().matrix());
  const Eigen::Isometry3d y_up_T_camera =
    planar_grid::zUpWorldFrom(planar_grid::WorldConvention::Y_UP).inverse()
    * world_T_camera;
  camera_cloud.sensor_origin_ << y_up_T_camera.translation().cast<float>(), 0.0f;
  camera_cloud.sensor_orientation_ =
    Eigen::Quaternionf(y_up_T_camera.rotation().cast<float>());
  const std::string path = (dir_ / "camera.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileBinary(path, camera_cloud), 0);

  const auto frames = source(path);
  ASSERT_EQ(frames->size(), 1u);
  planar_grid::Frame frame;
  frames->load(0, frame);
  ASSERT_TRUE(frame.has_pose);
  // PCD stores the VIEWPOINT with 6 significant digits: the pose comes back to ~1e-5.
  EXPECT_LT(
    (frame.world_T_camera.matrix() - world_T_camera.matrix()).cwiseAbs().maxCoeff(),
    1e-5);
  // The floor is back at z = 0 and level (the 25 deg pitch and 30 deg yaw undone).
  const Cloud world = worldCloud(frame);
  EXPECT_LT(floorTiltDeg(world, world_T_camera.translation()), 0.05);
  std::size_t on_floor = 0;
  for (const auto& p : world.points)
    on_floor += std::abs(p.z) < 0.015f;
  EXPECT_GT(on_floor, 14000u); // the floor grid: 151 x 101 = 15251 samples
}

TEST_F(PCDInputTest, IdenticalViewpointsAreRefused)
{
  Cloud cloud = room();
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "a.pcd").string(), cloud), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "b.pcd").string(), cloud), 0);
  try {
    source((dir_ / "*.pcd").string());
    FAIL() << "two identical VIEWPOINTs were accepted";
  } catch (const planar_grid::IOError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("registration"), std::string::npos) << what;
    EXPECT_NE(what.find("a.pcd"), std::string::npos) << what;
  }
}

TEST_F(PCDInputTest, UnposedScansAreRegisteredAndLevelled)
{
  // Two z-up scans (unorganized, default VIEWPOINT) of the room: the first from
  // (0, 0, 1.0), the second from a sensor moved by a known motion. Registration must
  // recover the motion, and the floor level the pair with the floor at z = 0.
  const Cloud world_room = room();
  Eigen::Isometry3d world_T_first(Eigen::Translation3d(0.0, 0.0, 1.0));
  Eigen::Isometry3d first_T_second = Eigen::Isometry3d::Identity();
  first_T_second.linear() =
    Eigen::AngleAxisd(0.25, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  first_T_second.translation() = Eigen::Vector3d(0.4, -0.3, 0.0);
  Cloud first, second;
  pcl::transformPointCloud(world_room, first,
                           world_T_first.inverse().cast<float>().matrix());
  pcl::transformPointCloud(
    world_room, second,
    (world_T_first * first_T_second).inverse().cast<float>().matrix());
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "scan1.pcd").string(), first), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "scan2.pcd").string(), second), 0);

  const auto frames =
    source((dir_ / "scan*.pcd").string(), "  poses: {format: registration}\n");
  ASSERT_EQ(frames->poses().size(), 2u);
  const Eigen::Isometry3d& pose0 = frames->poses()[0];
  const Eigen::Isometry3d& pose1 = frames->poses()[1];
  // Relative motion within 0.2 deg and 1 cm (3 mm noise, 5 cm voxels).
  const Eigen::Isometry3d motion = pose0.inverse() * pose1;
  EXPECT_LT(Eigen::AngleAxisd(motion.rotation().transpose() * first_T_second.rotation())
              .angle(),
            0.2 * PI / 180.0);
  EXPECT_LT((motion.translation() - first_T_second.translation()).norm(), 0.01);
  // Levelled on the floor: the first sensor 1.0 m above it, upright.
  EXPECT_NEAR(pose0.translation().z(), 1.0, 0.01);
  EXPECT_GT(pose0.rotation()(2, 2), std::cos(0.1 * PI / 180.0));
}

TEST_F(PCDInputTest, UnposedRGBDCloudsAreRegisteredThroughTheirImages)
{
  // office1's colour image on a plane 2.5 m ahead (a poster), and the view of it from
  // a camera stepped 0.25 m along the plane and turned by 3 deg, each with its own
  // Kinect depth noise, written as organized x y z rgb PCD files. The plane alone
  // fixes three of the six degrees of freedom; the registration must find the step
  // through the images' key features.
  const std::string path = CLOUDS + "/office1.pcd";
  if (!haveData(path))
    GTEST_SKIP() << path << " not found";
  pcl::PointCloud<pcl::PointXYZRGB> poster;
  ASSERT_EQ(pcl::io::loadPCDFile(path, poster), 0);
  const planar_grid_test::Intrinsics k = planar_grid_test::fitIntrinsics(poster);
  const Eigen::Vector3d normal(0.0, std::sin(10.0 * PI / 180.0),
                               std::cos(10.0 * PI / 180.0));
  planar_grid_test::projectOntoPlane(poster, k, normal, 2.5);
  Eigen::Isometry3d first_T_second = Eigen::Isometry3d::Identity();
  first_T_second.linear() =
    Eigen::AngleAxisd(3.0 * PI / 180.0, normal).toRotationMatrix();
  first_T_second.translation() =
    0.25 * normal.cross(Eigen::Vector3d::UnitY()).normalized();
  pcl::PointCloud<pcl::PointXYZRGB> view =
    planar_grid_test::reproject(poster, k, first_T_second);
  planar_grid_test::addDepthNoise(poster, 0.0016f, 11);
  planar_grid_test::addDepthNoise(view, 0.0016f, 12);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "view1.pcd").string(), poster), 0);
  ASSERT_EQ(pcl::io::savePCDFileBinary((dir_ / "view2.pcd").string(), view), 0);

  const auto frames =
    source((dir_ / "view*.pcd").string(), "  poses: {format: registration}\n");
  ASSERT_EQ(frames->poses().size(), 2u);
  const Eigen::Isometry3d motion = frames->poses()[0].inverse() * frames->poses()[1];
  const double rotation_error_deg =
    Eigen::AngleAxisd(motion.rotation().transpose() * first_T_second.rotation()).angle()
    * 180.0 / PI;
  const double translation_error_m =
    (motion.translation() - first_T_second.translation()).norm();
  std::cout << "RGB-D poster pair: rotation error " << rotation_error_deg
            << " deg, translation error " << translation_error_m << " m\n";
  // Within 0.5 deg and 2 cm; the clouds alone leave the second view where it started
  // (3 deg and 0.25 m off, test_cloud_registration).
  EXPECT_LT(rotation_error_deg, 0.5);
  EXPECT_LT(translation_error_m, 0.02);
}

TEST_F(PCDInputTest, ColourBecomesIntensity)
{
  pcl::PointCloud<pcl::PointXYZRGB> colour;
  pcl::PointXYZRGB p;
  p.r = p.g = p.b = 255;
  p.x = 1.0f;
  p.y = 2.0f;
  p.z = 3.0f;
  colour.push_back(p);
  const std::string path = (dir_ / "colour.pcd").string();
  ASSERT_EQ(pcl::io::savePCDFileBinary(path, colour), 0);
  const auto frames = source(path, "  poses: {format: none}\n");
  planar_grid::Frame frame;
  frames->load(0, frame);
  ASSERT_EQ(frame.cloud->size(), 1u);
  EXPECT_EQ((*frame.cloud)[0].x, 1.0f);
  // White: the grey value of PCL's RGB -> intensity conversion is 255.
  EXPECT_NEAR((*frame.cloud)[0].intensity, 255.0f, 1e-3f);
}

// ------------------------------------------------------------------ real data

TEST_F(PCDInputTest, RealOffice1FloorIsHorizontal)
{
  const std::string path = CLOUDS + "/office1.pcd";
  if (!haveData(path))
    GTEST_SKIP() << path << " not found";
  // Its VIEWPOINT is PCL's grabber constant: the camera is levelled on its floor.
  const auto frames = source(path);
  planar_grid::Frame frame;
  frames->load(0, frame);
  ASSERT_TRUE(frame.has_pose);
  const Cloud world = worldCloud(frame);
  const double tilt = floorTiltDeg(world, frame.world_T_camera.translation());
  std::cout << "office1.pcd: floor tilt " << tilt << " deg, camera "
            << frame.world_T_camera.translation().z() << " m above it\n";
  EXPECT_LT(tilt, 2.0);
  // The camera is about 1.3 m above the floor (a Kinect on a desk or a tripod). (Its
  // back wall, 5 m away, makes no check of verticality: at that range the Kinect's
  // depth is quantized into layers ~7 cm apart, and RANSAC takes a layer, perpendicular
  // to the optical axis, for the wall.)
  EXPECT_GT(frame.world_T_camera.translation().z(), 1.0);
  EXPECT_LT(frame.world_T_camera.translation().z(), 1.7);
}

TEST_F(PCDInputTest, RealPairwiseCapturesMapToOneOffice)
{
  const std::string first_path = CLOUDS + "/pairwise/capture0001.pcd";
  if (!haveData(first_path))
    GTEST_SKIP() << first_path << " not found";
  const auto frames = source(CLOUDS + "/pairwise/capture000*.pcd",
                             "  poses: {format: registration, leaf_size_m: 0.03, "
                             "max_correspondence_distance_m: 0.3}\n");
  ASSERT_EQ(frames->size(), 5u);
  planar_grid::Frame first, last;
  frames->load(0, first);
  frames->load(4, last);
  const Cloud first_world = worldCloud(first);
  const Cloud last_world = worldCloud(last);
  Cloud both = first_world;
  both += last_world;
  const double tilt = floorTiltDeg(both, first.world_T_camera.translation());
  EXPECT_LT(tilt, 2.0);

  // The walls: the vertical planes of the first capture (normals level within 10 deg)
  // of at least 2000 points (1.8 m^2 at 3 cm voxels). Each is fitted again on the last
  // capture's points within 0.15 m of it; where the last capture sees it, the two fits
  // must coincide: offsets within 0.05 m at the first wall's centroid, normals within
  // 2 deg.
  Cloud::Ptr remaining(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(0.03f, 0.03f, 0.03f);
  grid.setInputCloud(Cloud::Ptr(new Cloud(first_world)));
  grid.filter(*remaining);
  int walls = 0;
  for (int attempt = 0; attempt < 8; ++attempt) {
    const Eigen::Vector3f up = Eigen::Vector3f::UnitZ();
    pcl::PointIndices::Ptr inliers(new pcl::PointIndices);
    Eigen::Vector4f plane;
    if (!fitPlane(remaining, 0.03, &up, 10.0 * PI / 180.0, inliers->indices, plane)
        || inliers->indices.size() < 2000)
      break;
    Eigen::Vector3f centroid = Eigen::Vector3f::Zero();
    for (const auto i : inliers->indices)
      centroid += (*remaining)[static_cast<std::size_t>(i)].getVector3fMap();
    centroid /= static_cast<float>(inliers->indices.size());
    Cloud::Ptr near(new Cloud);
    for (const auto& p : last_world.points)
      if (std::isfinite(p.x)
          && std::abs(plane.head<3>().dot(p.getVector3fMap()) + plane[3]) < 0.15f)
        near->push_back(p);
    Cloud rest;
    for (std::size_t i = 0, k = 0; i < remaining->size(); ++i) {
      if (k < inliers->indices.size()
          && static_cast<std::size_t>(inliers->indices[k]) == i) {
        ++k;
        continue;
      }
      rest.push_back((*remaining)[i]);
    }
    *remaining = rest;
    if (near->size() < 500)
      continue; // not seen in the last capture
    pcl::Indices refit_inliers;
    Eigen::Vector4f again;
    ASSERT_TRUE(fitPlane(near, 0.03, nullptr, 0.0, refit_inliers, again));
    if (again.head<3>().dot(plane.head<3>()) < 0.0f)
      again = -again;
    const double angle_deg =
      std::acos(std::min(1.0f, again.head<3>().dot(plane.head<3>()))) * 180.0 / PI;
    const double offset_m = std::abs(again.head<3>().dot(centroid) + again[3]);
    std::cout << "pairwise wall " << walls << ": " << inliers->indices.size()
              << " points; in the last capture " << offset_m << " m and " << angle_deg
              << " deg apart\n";
    EXPECT_LT(offset_m, 0.05);
    EXPECT_LT(angle_deg, 2.0);
    ++walls;
  }
  EXPECT_GE(walls, 1);
  // And all of the last capture lies on the first one's surfaces where they overlap:
  // RMS point-to-plane within 0.05 m over the points within 0.1 m (3 cm voxels).
  double overlap = 0.0;
  const double residual =
    pointToPlaneResidual(last_world, first_world, 0.03f, 0.1f, overlap);
  std::cout << "pairwise: floor tilt " << tilt << " deg; last onto first: residual "
            << residual << " m, overlap " << overlap << "\n";
  EXPECT_LT(residual, 0.05);
  EXPECT_GT(overlap, 0.3);
}

TEST_F(PCDInputTest, RealRoomScansAreRegistered)
{
  const std::string scan1 = CLOUDS + "/room_scan1.pcd";
  if (!haveData(scan1))
    GTEST_SKIP() << scan1 << " not found";
  // The two scans registered with 10 cm voxels and 1 m correspondences, as
  // config/room_scans.yaml registers them: the scans of its run.
  const RoomScansRun& run = roomScansRun();
  const auto& input = run.config.input;
  ASSERT_EQ(input.pcd_files.size(), 2u);
  EXPECT_EQ(fs::path(input.pcd_files[0]).filename(), "room_scan1.pcd");
  EXPECT_EQ(fs::path(input.pcd_files[1]).filename(), "room_scan2.pcd");
  ASSERT_EQ(input.registration_leaf_size_m, 0.1);
  ASSERT_EQ(input.registration_max_correspondence_distance_m, 1.0);
  ASSERT_EQ(run.world.size(), 2u);
  const Cloud& a = run.world[0];
  const Cloud& b = run.world[1];
  const Eigen::Vector3d a_origin = run.world_T_camera[0].translation();
  // The residual measured here, independently of the registration's own: the RMS
  // point-to-plane distance from scan 2's points (10 cm voxels) to scan 1's surface
  // (normals from 30 cm), over the points within 0.1 m of scan 1.
  double overlap = 0.0;
  const double residual = pointToPlaneResidual(b, a, 0.1f, 0.1f, overlap);
  EXPECT_GT(overlap, 0.3) << "too little overlap";
  std::cout << "room scans: residual " << residual << " m, overlap " << overlap
            << "; floor tilt " << floorTiltDeg(a, a_origin) << " deg\n";
  EXPECT_LE(residual, 0.05);
  EXPECT_LT(floorTiltDeg(a, a_origin), 2.0);
}

TEST_F(PCDInputTest, RealRoomScansMapWithTheirPointsInOccupiedVoxels)
{
  const std::string scan1 = CLOUDS + "/room_scan1.pcd";
  if (!haveData(scan1))
    GTEST_SKIP() << scan1 << " not found";
  // config/room_scans.yaml, as shipped: the two LiDAR scans registered and mapped, the
  // explicit space by a ray to every point. Then the scans' own points, moved by their
  // poses, lie in occupied voxels (the ground's too).
  const RoomScansRun& run = roomScansRun();
  ASSERT_TRUE(run.map);
  const auto& space = run.map->getSpaceLayer();
  ASSERT_EQ(run.world.size(), 2u);
  for (std::size_t i = 0; i < run.world.size(); ++i) {
    std::size_t points = 0, occupied = 0;
    for (const auto& p : run.world[i]) {
      if (!pcl::isFinite(p))
        continue;
      ++points;
      occupied += space.getState(Eigen::Vector3f(p.x, p.y, p.z))
                      == planar_grid::SpaceState::OCCUPIED
                    ? 1
                    : 0;
    }
    const double share = static_cast<double>(occupied) / static_cast<double>(points);
    std::cout << "room scan " << i + 1 << ": " << occupied << " of " << points
              << " points in occupied voxels (" << share << ")\n";
    EXPECT_GE(share, 0.8) << "scan " << i + 1;
  }
}

TEST_F(PCDInputTest, RealKittiGroundTruthGroundInEveryFrame)
{
  const std::string kitti = DATA + "/kitti_odometry_snippet_2/poses.txt";
  if (!haveData(kitti))
    GTEST_SKIP() << kitti << " not found";
  // config/kitti_groundtruth.yaml, as shipped: KITTI's ground-truth poses, read in the
  // z-up world, and ground_removal with the world's up axis.
  auto config = planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                                + "/config/kitti_groundtruth.yaml");
  config.output.folder = (dir_ / "out").string();
  planar_grid::PipelineRunner runner(config);
  const auto report = runner.run();
  ASSERT_EQ(report.frames, 51u);
  bool checked = false;
  for (const auto& stage : report.stages)
    if (stage.type == "ground_removal") {
      ASSERT_FALSE(stage.counters.empty());
      EXPECT_EQ(stage.counters[0].first, "ground_found");
      EXPECT_DOUBLE_EQ(stage.counters[0].second, 51.0);
      checked = true;
    }
  EXPECT_TRUE(checked);
  // The first camera is level at the origin looking along +x, as the z-up world says.
  EXPECT_LT(
    (runner.trajectory()[0].rotation().col(2) - Eigen::Vector3d::UnitX()).norm(), 1e-6);
}
