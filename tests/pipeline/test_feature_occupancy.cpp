// SPDX-License-Identifier: BSD-3-Clause
// The feature occupancy (paper eqs. 4-10) on point-cloud input: the cloud_features
// stage and kl_occupancy_filter with the depth camera and range sensor models.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <map>
#include <ostream>
#include <random>
#include <string>
#include <unordered_map>
#include <vector>

#include "../test_constants.h"

namespace fs = std::filesystem;

namespace {

using planar_grid_test::CLOUDS;
const std::string OFFICE1 = CLOUDS + "/office1.pcd";

/** \brief A stage of the registry with its default parameters and \a overrides. */
std::unique_ptr<planar_grid::Stage>
makeStage(const std::string& type,
          const std::map<std::string, std::variant<double, int, bool, std::string>>&
            overrides = {})
{
  const planar_grid::StageInfo* info = planar_grid::findStage(type);
  EXPECT_NE(info, nullptr) << type;
  planar_grid::ParamValues params = planar_grid::defaultParams(info->params);
  for (const auto& kv : overrides)
    params.set(kv.first, kv.second);
  return info->create(params);
}

/** \brief The sum of a stage's counter over the run (0 when absent). */
double
counter(const planar_grid::RunReport& report,
        const std::string& stage,
        const std::string& name)
{
  for (const auto& s : report.stages)
    if (s.type == stage)
      for (const auto& c : s.counters)
        if (c.first == name)
          return c.second;
  return 0.0;
}

/** \brief Figures of a map's cuboids: how many, how many carry a probability other
 * than the 0.5 of a cell without features and the share of the cuboids' face area
 * they cover, their mean probability, and how many of the planar ones are occupied
 * (>= 0.5). */
struct CuboidOccupancy {
  std::size_t cuboids{0};
  std::size_t from_features{0};
  double area_share{0.0};
  double mean_probability{0.0};
  std::size_t planar{0};
  std::size_t planar_from_features{0};
  std::size_t planar_occupied{0};
};

CuboidOccupancy
cuboidOccupancy(const planar_grid::PlanarGridMap& map)
{
  CuboidOccupancy o;
  double sum = 0.0, area = 0.0, area_from_features = 0.0;
  for (const auto& c : map.getSurfaceLayer().getCuboids()) {
    ++o.cuboids;
    const double a = static_cast<double>(c.width_m) * static_cast<double>(c.height_m);
    area += a;
    if (std::abs(c.probability - 0.5f) > 1e-6f) {
      ++o.from_features;
      area_from_features += a;
      sum += c.probability;
    }
    if (c.plane_id >= 0) {
      ++o.planar;
      o.planar_from_features += std::abs(c.probability - 0.5f) > 1e-6f ? 1 : 0;
      o.planar_occupied +=
        std::abs(c.probability - 0.5f) > 1e-6f && c.probability >= 0.5f ? 1 : 0;
    }
  }
  o.mean_probability = o.from_features ? sum / static_cast<double>(o.from_features) : 0;
  o.area_share = area > 0.0 ? area_from_features / area : 0.0;
  return o;
}

std::ostream&
operator<<(std::ostream& out, const CuboidOccupancy& o)
{
  return out << o.from_features << " of " << o.cuboids << " cuboids ("
             << 100.0 * o.area_share << " % of their area) from features, mean "
             << o.mean_probability << "; " << o.planar_from_features << " of "
             << o.planar << " planar cuboids from features, " << o.planar_occupied
             << " occupied";
}

class FeatureOccupancyTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = fs::temp_directory_path()
           / ("planar_grid_features_" + std::string(info->name()) + "_"
              + std::to_string(::getpid()));
    fs::remove_all(dir_);
    fs::create_directories(dir_);
  }
  void TearDown() override { fs::remove_all(dir_); }

  fs::path dir_;
};

/** \brief A 360 degree, 16-beam LiDAR scan (elevations -15..15 deg, 0.5 deg azimuth
 * steps) of a closed box room [-3, 3] x [-2, 2] x [0, 2.5] m from a sensor at \a
 * origin (z up, axes of the room), with Gaussian range noise of \a sigma_m; the points
 * are in the sensor frame. */
planar_grid::Frame::Cloud::Ptr
roomScan(const Eigen::Vector3f& origin, float sigma_m, unsigned seed)
{
  std::mt19937 rng(seed);
  std::normal_distribution<float> noise(0.0f, sigma_m);
  const Eigen::Vector3f lo(-3.0f, -2.0f, 0.0f), hi(3.0f, 2.0f, 2.5f);
  planar_grid::Frame::Cloud::Ptr cloud(new planar_grid::Frame::Cloud);
  constexpr float DEG = 3.14159265f / 180.0f;
  for (int beam = 0; beam < 16; ++beam) {
    const float elevation = (-15.0f + 2.0f * static_cast<float>(beam)) * DEG;
    for (int step = 0; step < 720; ++step) {
      const float azimuth = 0.5f * static_cast<float>(step) * DEG;
      const Eigen::Vector3f d(std::cos(elevation) * std::cos(azimuth),
                              std::cos(elevation) * std::sin(azimuth),
                              std::sin(elevation));
      // The nearest exit through the six faces of the box.
      float t = std::numeric_limits<float>::infinity();
      for (int a = 0; a < 3; ++a) {
        if (std::abs(d[a]) < 1e-9f)
          continue;
        const float face = d[a] > 0.0f ? hi[a] : lo[a];
        t = std::min(t, (face - origin[a]) / d[a]);
      }
      const float r = t + noise(rng);
      pcl::PointXYZI p;
      p.getVector3fMap() = r * d;
      p.intensity = 0.0f;
      cloud->push_back(p);
    }
  }
  return cloud;
}

} // namespace

TEST(FeatureOccupancy, PointFeaturesOfAScanGetEquationFourWithTheRangeError)
{
  // Oracle: eq. 4 by brute force on the features of one synthetic scan (range model,
  // dr = range_error_m): r_bar is the mean range of the features in the same
  // neighbourhood cube (sensor frame), p = exp(-0.5 ((r - r_bar) / dr)^2), clamped.
  const double dr = 0.02, cell = 0.5;
  auto features = makeStage("cloud_features");
  auto kl = makeStage("kl_occupancy_filter",
                      {{"range_error_m", dr}, {"neighbourhood_size_m", cell}});
  planar_grid::PipelineState state;
  planar_grid::Frame frame;
  frame.name = "scan";
  const Eigen::Vector3f origin(0.4f, -0.3f, 1.2f);
  frame.cloud = roomScan(origin, 0.02f, 1);
  frame.has_pose = true;
  frame.world_T_camera.translation() = origin.cast<double>();
  features->process(frame, state);
  kl->process(frame, state);

  const auto& points = frame.features.points;
  ASSERT_GT(points.size(), 500u);
  ASSERT_EQ(frame.feature_probabilities.size(), points.size());
  std::unordered_map<std::string, std::pair<double, int>> cells;
  const auto key = [&](const pcl::PointXYZ& p) {
    return std::to_string(static_cast<long>(std::floor(p.x / cell))) + ","
           + std::to_string(static_cast<long>(std::floor(p.y / cell))) + ","
           + std::to_string(static_cast<long>(std::floor(p.z / cell)));
  };
  for (const auto& p : points) {
    auto& c = cells[key(p)];
    c.first += p.getVector3fMap().cast<double>().norm();
    ++c.second;
  }
  std::size_t behind = 0;
  for (std::size_t i = 0; i < points.size(); ++i) {
    const auto& c = cells[key(points[i])];
    const double r = points[i].getVector3fMap().cast<double>().norm();
    const double t = (r - c.first / c.second) / dr;
    const double p = std::min(std::max(std::exp(-0.5 * t * t), 0.1192), 0.971);
    ASSERT_NEAR(frame.feature_probabilities[i], p, 1e-4) << "feature " << i;
    // A 360 degree scan: the points behind and below the sensor count too.
    behind += points[i].z < 0.0f || points[i].x < 0.0f ? 1 : 0;
  }
  EXPECT_GT(behind, points.size() / 3);
}

TEST(FeatureOccupancy, DepthCameraModelScalesTheRangeErrorWithDepth)
{
  // Two features in one 0.5 m neighbourhood cube straight ahead of the camera, at
  // z = 2.0 and 2.02 m: r_bar = 2.01 m, and the depth camera's dr = (r_bar / z) k z^2
  // = r_bar k z, so p = exp(-0.5 ((r - r_bar) / (r_bar k z))^2) for each (no stereo
  // parameters are needed).
  planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ> filter;
  planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ>::Params params;
  params.range_error_model = planar_grid::RangeErrorModel::DEPTH_QUADRATIC;
  params.depth_error_coefficient_per_m = 0.005;
  params.clamping_thres_min = 0.001;
  filter.setParams(params);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->push_back(pcl::PointXYZ(0.1f, 0.1f, 2.0f));
  cloud->push_back(pcl::PointXYZ(0.1f, 0.1f, 2.02f));
  filter.setInputCloud(cloud);
  pcl::Indices kept;
  filter.filter(kept);
  const auto& p = filter.getProbabilities();
  ASSERT_EQ(p.size(), 2u);
  const double r0 = cloud->at(0).getVector3fMap().cast<double>().norm();
  const double r1 = cloud->at(1).getVector3fMap().cast<double>().norm();
  const double mean = 0.5 * (r0 + r1);
  EXPECT_NEAR(p[0], planar_grid::sampledGaussianOccupancy(r0, mean, mean * 0.005 * 2.0),
              1e-5);
  EXPECT_NEAR(
    p[1], planar_grid::sampledGaussianOccupancy(r1, mean, mean * 0.005 * 2.02), 1e-5);
  // 0.01 m off a mean with dr of about 0.02 m: exp(-0.5 (0.5)^2) = 0.88.
  EXPECT_NEAR(p[0], 0.88, 0.01);
  // The stereo model still needs its stereo parameters: empty output, no update.
  params.range_error_model = planar_grid::RangeErrorModel::STEREO;
  filter.setParams(params);
  filter.setInputCloud(cloud);
  filter.filter(kept);
  EXPECT_TRUE(kept.empty());
  EXPECT_EQ(filter.getProbabilities()[0], 0.0f);
}

TEST(FeatureOccupancy, RepeatedScansRaiseTheOccupancyOfTheRoomsSurfaces)
{
  // Three scans of the same room from sensor positions 0.3 m apart, with their true
  // poses: the points of one scan are associated by position with the tracks of the
  // scans before (KL rule, eqs. 5-10). Truth: every point lies on the room's walls,
  // floor or ceiling, so the tracks seen again should end more occupied than they
  // began, and most of them occupied.
  auto features = makeStage("cloud_features", {{"point_spacing_m", 0.1}});
  auto kl = makeStage("kl_occupancy_filter", {{"range_error_m", 0.03},
                                              {"neighbourhood_size_m", 0.2},
                                              {"association_radius_m", 0.1}});
  planar_grid::PipelineState state;
  std::unordered_map<std::int64_t, float> first;
  double first_sum = 0.0, last_sum = 0.0;
  std::size_t reobserved = 0, first_occupied = 0, occupied = 0;
  for (int k = 0; k < 3; ++k) {
    planar_grid::Frame frame;
    frame.name = "scan " + std::to_string(k);
    const Eigen::Vector3f origin(-0.3f + 0.3f * static_cast<float>(k), 0.2f, 1.0f);
    frame.cloud = roomScan(origin, 0.01f, 10 + static_cast<unsigned>(k));
    frame.has_pose = true;
    frame.world_T_camera.translation() = origin.cast<double>();
    features->process(frame, state);
    kl->process(frame, state);
    ASSERT_EQ(frame.feature_track_ids.size(), frame.features.size());
    for (std::size_t i = 0; i < frame.feature_track_ids.size(); ++i) {
      const std::int64_t id = frame.feature_track_ids[i];
      const float p = frame.feature_probabilities[i];
      ASSERT_GE(id, 0);
      if (k == 0) {
        first[id] = p;
      } else if (k == 2 && first.count(id)) {
        ++reobserved;
        first_sum += first[id];
        first_occupied += first[id] >= 0.5f ? 1 : 0;
        last_sum += p;
        occupied += p >= 0.5f ? 1 : 0;
      }
    }
  }
  ASSERT_GT(reobserved, 200u);
  const double n = static_cast<double>(reobserved);
  std::cout << reobserved << " tracks seen in scans 1 and 3: mean probability "
            << first_sum / n << " -> " << last_sum / n << ", occupied "
            << first_occupied << " -> " << occupied << "\n";
  EXPECT_GT(last_sum / n, first_sum / n + 0.02);
  EXPECT_GT(occupied, first_occupied);
  EXPECT_GT(static_cast<double>(occupied) / n, 0.75);
}

TEST_F(FeatureOccupancyTest, Office1FeaturesAreTheCloudsOwnPoints)
{
  if (!fs::exists(OFFICE1))
    GTEST_SKIP() << OFFICE1 << " not found";
  // Key points on office1's colour image, lifted through the organized cloud: each
  // feature is the cloud's point at its key point's pixel (the oracle), with an ORB
  // descriptor.
  planar_grid::InputConfig input;
  input.type = planar_grid::InputConfig::Type::PCD_FILES;
  input.pcd_files = {OFFICE1};
  const auto frames = planar_grid::createFrameSource(input);
  planar_grid::Frame frame;
  frames->load(0, frame);
  ASSERT_TRUE(frame.cloud->isOrganized());
  planar_grid::PipelineState state;
  makeStage("cloud_features")->process(frame, state);
  const auto& f = frame.features;
  ASSERT_GT(f.size(), 300u);
  ASSERT_EQ(f.points.size(), f.size());
  ASSERT_EQ(static_cast<std::size_t>(f.descriptors.rows), f.size());
  for (std::size_t i = 0; i < f.size(); ++i) {
    const auto& kp = f.keypoints_left[i];
    const auto& p = frame.cloud->at(static_cast<int>(std::lround(kp.pt.x)),
                                    static_cast<int>(std::lround(kp.pt.y)));
    ASSERT_EQ(f.points[i].x, p.x);
    ASSERT_EQ(f.points[i].y, p.y);
    ASSERT_EQ(f.points[i].z, p.z);
  }
  // With source: image, a cloud without an image is an error naming the frame.
  planar_grid::Frame bare;
  bare.name = "bare.pcd";
  bare.cloud.reset(new planar_grid::Frame::Cloud(*frame.cloud));
  for (auto& p : bare.cloud->points)
    p.intensity = 0.0f;
  try {
    makeStage("cloud_features", {{"source", std::string("image")}})
      ->process(bare, state);
    FAIL() << "no error";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("bare.pcd has no image"), std::string::npos)
      << e.what();
  }
}

TEST_F(FeatureOccupancyTest, Office1MapCellsCarryFeatureOccupancyThatRisesWhenSeenAgain)
{
  if (!fs::exists(OFFICE1))
    GTEST_SKIP() << OFFICE1 << " not found";
  // config/office1.yaml as shipped: one frame.
  auto config = planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                                + "/config/office1.yaml");
  config.output.folder = (dir_ / "one").string();
  planar_grid::PipelineRunner one(config);
  const auto report_one = one.run();
  ASSERT_TRUE(one.state().map);
  const double features = counter(report_one, "cloud_features", "features");
  EXPECT_GT(features, 300.0);
  EXPECT_EQ(counter(report_one, "cloud_features", "from_image"), 1.0);
  EXPECT_EQ(counter(report_one, "kl_occupancy_filter", "range_error_model"), 1.0)
    << "depth camera model";
  const CuboidOccupancy a = cuboidOccupancy(*one.state().map);
  std::cout << "office1, 1 frame: " << a << "\n";
  // A cell takes the mean of the features in it (a planar one, without any, its
  // neighbours'; Sec. III-F); a cell without a feature near it keeps 0.5.
  EXPECT_GE(a.area_share, 0.3);
  EXPECT_GE(static_cast<double>(a.from_features),
            0.15 * static_cast<double>(a.cuboids));

  // Three views with the first run's pose (a KITTI pose file). The same view three
  // times: every feature is matched again by descriptor, and the KL rule (eq. 10)
  // raises a consistent observation (p, q > 0.5) to the upper clamp.
  const fs::path poses = dir_ / "poses.txt";
  planar_grid::saveKittiPoses(poses.string(),
                              planar_grid::Trajectory(3, one.trajectory().at(0)));
  config.input.poses_format = planar_grid::PoseFormat::KITTI;
  config.input.poses_file = poses.string();
  config.input.pcd_files = {OFFICE1, OFFICE1, OFFICE1};
  config.output.folder = (dir_ / "same").string();
  planar_grid::PipelineRunner same(config);
  const auto report_same = same.run();
  ASSERT_TRUE(same.state().map);
  EXPECT_GE(counter(report_same, "kl_occupancy_filter", "reobserved"),
            0.95 * 2.0 * features);
  const CuboidOccupancy b = cuboidOccupancy(*same.state().map);
  std::cout << "office1, the same view 3 times: " << b << "\n";
  EXPECT_GE(b.area_share, a.area_share);
  EXPECT_GT(b.mean_probability, a.mean_probability + 0.01);

  // The view again with new depth noise of the Kinect's size (dz = 0.0016 z^2 along
  // the ray, seeded): the features are still found and matched again.
  pcl::PointCloud<pcl::PointXYZRGB> office;
  ASSERT_EQ(pcl::io::loadPCDFile(OFFICE1, office), 0);
  std::vector<std::string> files{OFFICE1};
  for (int k = 0; k < 2; ++k) {
    std::mt19937 rng(100 + static_cast<unsigned>(k));
    std::normal_distribution<float> unit(0.0f, 1.0f);
    pcl::PointCloud<pcl::PointXYZRGB> noisy = office;
    for (auto& p : noisy.points) {
      if (!std::isfinite(p.z) || p.z <= 0.0f)
        continue;
      const float dz = 0.0016f * p.z * p.z * unit(rng);
      p.getVector3fMap() *= (p.z + dz) / p.z;
    }
    files.push_back((dir_ / ("office1_" + std::to_string(k) + ".pcd")).string());
    ASSERT_EQ(pcl::io::savePCDFileBinary(files.back(), noisy), 0);
  }
  config.input.pcd_files = files;
  config.output.folder = (dir_ / "noisy").string();
  planar_grid::PipelineRunner noisy(config);
  const auto report_noisy = noisy.run();
  ASSERT_TRUE(noisy.state().map);
  EXPECT_GE(counter(report_noisy, "kl_occupancy_filter", "reobserved"), features);
  const CuboidOccupancy c = cuboidOccupancy(*noisy.state().map);
  std::cout << "office1 and 2 noisy copies: " << c << "\n";
  EXPECT_GE(c.area_share, 0.3);
  // Truth: the office's walls, door and desk are there, so the planar cells carry
  // the features' probability and most of them are occupied.
  ASSERT_GT(c.planar, 0u);
  EXPECT_GE(static_cast<double>(c.planar_from_features),
            0.5 * static_cast<double>(c.planar));
  EXPECT_GT(static_cast<double>(c.planar_occupied),
            0.6 * static_cast<double>(c.planar_from_features));
}

TEST_F(FeatureOccupancyTest, RoomScan1MapCellsCarryRangeSensorOccupancy)
{
  const std::string scan1 = CLOUDS + "/room_scan1.pcd";
  if (!fs::exists(scan1))
    GTEST_SKIP() << scan1 << " not found";
  // The stages of config/room_scans.yaml on the first LiDAR scan alone (levelled on
  // its floor): the scan's points are the features, eq. 4 takes the range error.
  auto config = planar_grid::loadPipelineConfig(std::string(PLANAR_GRID_SOURCE_DIR)
                                                + "/config/room_scans.yaml");
  config.input.pcd_files = {scan1};
  config.input.poses_format = planar_grid::PoseFormat::VIEWPOINT;
  config.output.folder = (dir_ / "out").string();
  planar_grid::PipelineRunner runner(config);
  const auto report = runner.run();
  ASSERT_TRUE(runner.state().map);
  EXPECT_GT(counter(report, "cloud_features", "features"), 5000.0);
  EXPECT_EQ(counter(report, "cloud_features", "from_image"), 0.0);
  EXPECT_EQ(counter(report, "kl_occupancy_filter", "range_error_model"), 2.0)
    << "range sensor model";
  const CuboidOccupancy a = cuboidOccupancy(*runner.state().map);
  std::cout << "room_scan1: " << a << "\n";
  ASSERT_GT(a.planar, 0u);
  EXPECT_GE(static_cast<double>(a.planar_from_features),
            0.9 * static_cast<double>(a.planar));
  EXPECT_GE(a.area_share, 0.8);
  // Truth: every point lies on a surface, but eq. 4 judges a point by its range
  // against its neighbours' mean, which on a surface seen at a slant differs by more
  // than the 3 cm range error: about half of the planar cells end occupied.
  EXPECT_GT(static_cast<double>(a.planar_occupied),
            0.5 * static_cast<double>(a.planar));
}

TEST(FeatureOccupancy, StagesThatNeedStereoOrFeaturesAreRefusedAtTheirLine)
{
  const std::string pcd = "input:\n  type: pcd_files\n  files: a.pcd\npipeline:\n";
  const auto errorOf = [](const std::string& yaml) {
    try {
      planar_grid::parsePipelineConfig(yaml, "t.yaml", "/");
    } catch (const planar_grid::ConfigError& e) {
      return std::make_pair(e.line(), std::string(e.what()));
    }
    return std::make_pair(-1, std::string());
  };
  // The feature occupancy without a stage giving the features (line 5).
  auto e = errorOf(pcd + "  - type: kl_occupancy_filter\n");
  EXPECT_EQ(e.first, 5);
  EXPECT_NE(e.second.find("needs key features, which no earlier stage produces: put "
                          "'feature_matching' or 'cloud_features' before it"),
            std::string::npos)
    << e.second;
  // Stereo matching on a point cloud.
  e = errorOf(pcd + "  - type: cloud_features\n  - type: feature_matching\n");
  EXPECT_EQ(e.first, 6);
  EXPECT_NE(e.second.find("needs stereo images"), std::string::npos) << e.second;
  // The visual odometry (stereo reprojection) stays refused with features of a cloud.
  e = errorOf(pcd + "  - type: cloud_features\n  - type: visual_odometry\n");
  EXPECT_EQ(e.first, 6) << e.second;
  // The right order loads.
  EXPECT_NO_THROW(planar_grid::parsePipelineConfig(
    pcd + "  - type: cloud_features\n  - type: kl_occupancy_filter\n", "t.yaml", "/"));
}
