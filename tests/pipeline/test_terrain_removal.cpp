// SPDX-License-Identifier: BSD-3-Clause
// The terrain removal of the ground_removal stage (paper Sec. III-F, second assumption)
// on a synthetic street with exact labels: road, a 0.15 m curb up to a sidewalk, a
// rough lawn and a ramp are terrain; a car-sized box standing on the road and a wall
// standing on the sidewalk stay.
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace {

enum Label : int { ROAD, CURB, SIDEWALK, LAWN, RAMP, CAR, WALL };

struct Street {
  planar_grid::Frame frame;
  std::vector<int> label;
};

/** Appends a point whose intensity holds its label. */
void
addLabelled(planar_grid::Frame::Cloud& cloud, float x, float y, float z, Label l)
{
  pcl::PointXYZI p;
  p.x = x;
  p.y = y;
  p.z = z;
  p.intensity = static_cast<float>(l);
  cloud.push_back(p);
}

/** Makes \a cloud the frame's world-frame cloud, seen from 1.6 m above the origin. */
void
setWorldCloud(Street& s,
              const std::shared_ptr<planar_grid::Frame::Cloud>& cloud,
              const std::string& name)
{
  cloud->sensor_origin_ = Eigen::Vector4f(0.0f, 0.0f, 1.6f, 1.0f);
  s.frame.cloud = cloud;
  s.frame.cloud_in_world_frame = true;
  s.frame.has_pose = true;
  s.frame.world_T_camera = Eigen::Isometry3d::Identity();
  s.frame.world_T_camera.translation() = Eigen::Vector3d(0.0, 0.0, 1.6);
  s.frame.name = name;
}

/** A 30 m x 24 m street in the world frame (z up), sensor 1.6 m above the road at the
 * origin. Points every 0.1 m, Gaussian noise of sigma_m along z (along y for the
 * wall), the intensity field holds the label. */
Street
makeStreet(double sigma_m)
{
  Street s;
  auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma_m));
  std::uniform_real_distribution<float> rough(-0.04f, 0.04f);
  const auto add = [&](float x, float y, float z, Label l) {
    addLabelled(*cloud, x, y, z, l);
  };
  const float step = 0.1f;
  for (float x = -5.0f; x < 25.0f; x += step) {
    for (float y = -8.0f; y < 5.0f; y += step) {
      // The ramp: x in [10, 20], y in [-8, -5], rising 0.12 m per m from the road.
      if (x >= 10.0f && y < -5.0f)
        add(x, y, 0.12f * (x - 10.0f) + noise(rng), RAMP);
      else
        add(x, y, noise(rng), ROAD);
    }
    for (float z = 0.0f; z < 0.15f; z += 0.05f)
      add(x, 5.0f + noise(rng), z, CURB);
    for (float y = 5.0f; y < 8.0f; y += step)
      add(x, y, 0.15f + noise(rng), SIDEWALK);
    for (float y = 8.0f; y < 12.0f; y += step)
      add(x, y, 0.2f + rough(rng) + noise(rng), LAWN);
    // A wall on the far side of the lawn, 3 m high.
    for (float z = 0.2f; z < 3.2f; z += step)
      add(x, 12.0f + noise(rng), z, WALL);
  }
  // A car-sized box (4 m x 1.8 m x 1.5 m, 0.2 m above the road) at x in [2, 6],
  // y in [-3, -1.2]: its top and four sides.
  for (float x = 2.0f; x <= 6.0f; x += step)
    for (float y = -3.0f; y <= -1.2f; y += step)
      add(x, y, 1.7f + noise(rng), CAR);
  for (float z = 0.2f; z <= 1.7f; z += step) {
    for (float x = 2.0f; x <= 6.0f; x += step) {
      add(x, -3.0f, z, CAR);
      add(x, -1.2f, z, CAR);
    }
    for (float y = -3.0f; y <= -1.2f; y += step) {
      add(2.0f, y, z, CAR);
      add(6.0f, y, z, CAR);
    }
  }
  setWorldCloud(s, cloud, "street");
  return s;
}

/** Runs multi_plane_segmentation (hypotheses from the cloud) and ground_removal with
 * \a ground_params set on the defaults; returns the points left per label. */
std::map<int, std::size_t>
removeTerrain(Street& s,
              const std::vector<std::pair<std::string, double>>& ground_params,
              std::map<int, std::size_t>& before)
{
  for (const auto& p : s.frame.cloud->points)
    ++before[static_cast<int>(p.intensity)];
  const auto* segmentation_info = planar_grid::findStage("multi_plane_segmentation");
  const auto* ground_info = planar_grid::findStage("ground_removal");
  EXPECT_NE(segmentation_info, nullptr);
  EXPECT_NE(ground_info, nullptr);
  planar_grid::ParamValues sp = planar_grid::defaultParams(segmentation_info->params);
  sp.set("sample", std::string("cloud"));
  sp.set("min_inliers", 300);
  sp.set("max_planes", 10);
  planar_grid::ParamValues gp = planar_grid::defaultParams(ground_info->params);
  for (const auto& kv : ground_params)
    gp.set(kv.first, kv.second);
  planar_grid::PipelineState state;
  segmentation_info->create(sp)->process(s.frame, state);
  ground_info->create(gp)->process(s.frame, state);
  std::map<int, std::size_t> after;
  for (const auto& p : s.frame.cloud->points)
    ++after[static_cast<int>(p.intensity)];
  return after;
}

/** Runs ground_removal alone on \a s with one given ground plane z = 0 whose inliers
 * are the points at most \a band_m above it, with one ground_removal parameter set. */
void
removeTerrainOfGroundPlane(Street& s,
                           float band_m,
                           const std::string& key,
                           double value)
{
  planar_grid::PlanarSegment ground;
  ground.model_coefficients.values = {0.0f, 0.0f, 1.0f, 0.0f};
  const auto& cloud = *s.frame.cloud;
  for (std::size_t i = 0; i < cloud.size(); ++i)
    if (cloud[i].z <= band_m + 1e-4f)
      ground.inliers.indices.push_back(static_cast<int>(i));
  s.frame.planes.push_back(ground);
  const auto* ground_info = planar_grid::findStage("ground_removal");
  ASSERT_NE(ground_info, nullptr);
  planar_grid::ParamValues gp = planar_grid::defaultParams(ground_info->params);
  gp.set(key, value);
  planar_grid::PipelineState state;
  ground_info->create(gp)->process(s.frame, state);
}

} // namespace

TEST(TerrainRemoval, RoadCurbSidewalkLawnAndRampGoTheCarAndTheWallStay)
{
  Street s = makeStreet(0.02);
  std::map<int, std::size_t> before;
  auto after = removeTerrain(s, {}, before);
  ASSERT_TRUE(s.frame.has_ground);
  for (const int terrain : {ROAD, CURB, SIDEWALK, LAWN, RAMP})
    EXPECT_LE(after[terrain], before[terrain] / 25) // <= 4 % left
      << "label " << terrain << ": " << after[terrain] << " of " << before[terrain];
  // Obstacles stay: the car (its lowest 0.2 m over the road is the only part that may
  // go) and the wall down to its foot on the lawn.
  EXPECT_GE(after[CAR], before[CAR] * 9 / 10);
  // (the lawn plane may take the wall's lowest row, where the two meet)
  EXPECT_GE(after[WALL], before[WALL] * 95 / 100);
  // The planes left index the compacted cloud and none of them is terrain.
  for (const auto& plane : s.frame.planes)
    for (const auto i : plane.inliers.indices) {
      ASSERT_GE(i, 0);
      ASSERT_LT(static_cast<std::size_t>(i), s.frame.cloud->size());
      const int l =
        static_cast<int>((*s.frame.cloud)[static_cast<std::size_t>(i)].intensity);
      EXPECT_TRUE(l == CAR || l == WALL) << "label " << l;
    }
}

TEST(TerrainRemoval, WithoutTerrainPlanesTheRampStays)
{
  // The paper's single ground plane (terrain planes and heights off): the ramp, a plane
  // of its own, stays; so the terrain planes are what removes it above. (The ground
  // plane itself, fitted by RANSAC for the most inliers, tilts by about 0.8 deg to take
  // in most of the sidewalk and the lawn.)
  Street s = makeStreet(0.02);
  std::map<int, std::size_t> before;
  auto after = removeTerrain(
    s, {{"terrain_max_slope_rad", 0.0}, {"terrain_height_m", 0.0}}, before);
  ASSERT_TRUE(s.frame.has_ground);
  EXPECT_LE(after[ROAD], before[ROAD] / 50);
  EXPECT_GE(after[RAMP], before[RAMP] * 9 / 10);
  EXPECT_GE(after[CAR], before[CAR] * 9 / 10);
}

/** A wall larger than the floor in view (an indoor scan): the wall is the first plane
 * and the floor, the ground, a later one. The planes before the ground keep their
 * coefficients and inliers. */
TEST(TerrainRemoval, PlanesListedBeforeTheGroundKeepTheirCoefficientsAndInliers)
{
  Street s;
  auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
  const auto add = [&](float x, float y, float z, Label l) {
    addLabelled(*cloud, x, y, z, l);
  };
  for (float x = -3.0f; x < 3.0f; x += 0.1f)
    for (float y = -1.0f; y < 2.9f; y += 0.1f)
      add(x, y, 0.0f, ROAD); // 60 x 39 points
  for (float x = -10.0f; x < 10.0f; x += 0.1f)
    for (float z = 0.1f; z < 5.0f; z += 0.1f)
      add(x, 3.0f, z, WALL); // 200 x 49 points
  setWorldCloud(s, cloud, "room");
  std::map<int, std::size_t> before;
  auto after = removeTerrain(s, {}, before);
  ASSERT_TRUE(s.frame.has_ground);
  EXPECT_EQ(after[ROAD], 0u);
  EXPECT_EQ(after[WALL], before[WALL]);
  ASSERT_EQ(s.frame.planes.size(), 1u);
  const auto& wall = s.frame.planes[0];
  ASSERT_EQ(wall.model_coefficients.values.size(), 4u);
  EXPECT_NEAR(std::abs(wall.model_coefficients.values[1]), 1.0f, 1e-3f);
  EXPECT_NEAR(std::abs(wall.model_coefficients.values[3]), 3.0f, 1e-2f);
  EXPECT_EQ(wall.inliers.indices.size(), before[WALL]);
  for (const auto i : wall.inliers.indices)
    EXPECT_EQ(static_cast<int>((*s.frame.cloud)[static_cast<std::size_t>(i)].intensity),
              WALL);
}

/** The ground's inlier band is wider than terrain_height where eq. 11 widens it with
 * the depth error (0.3 m at 15 m): a guardrail's rail from 0.1 to 0.8 m above the road
 * has its lowest rows in the road plane's inliers. The rows up to terrain_height (0.2
 * m) go with the road; the rows above stay. With terrain_height 0 (the paper's rule)
 * every inlier of the ground goes. */
TEST(TerrainRemoval, AGroundInlierStandingAboveTheTerrainHeightStays)
{
  const auto run = [](double terrain_height_m) {
    Street s;
    auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
    for (float x = -7.0f; x < 5.0f; x += 0.1f) // the verge under the rail too
      for (float y = 10.0f; y < 16.0f; y += 0.1f)
        addLabelled(*cloud, x, y, 0.0f, ROAD);
    for (float y = 10.0f; y < 16.0f; y += 0.1f)
      for (int row = 1; row <= 8; ++row)
        addLabelled(*cloud, -5.5f, y, 0.1f * static_cast<float>(row), CAR);
    setWorldCloud(s, cloud, "guardrail");
    // The road plane z = 0 with a 0.3 m band: the road and the rail's rows at 0.1-0.3
    // m.
    removeTerrainOfGroundPlane(s, 0.3f, "terrain_height_m", terrain_height_m);
    std::map<int, std::size_t> low_rail, after;
    for (const auto& p : s.frame.cloud->points) {
      ++after[static_cast<int>(p.intensity)];
      if (static_cast<int>(p.intensity) == CAR && p.z < 0.25f)
        ++low_rail[0];
    }
    return std::make_pair(after, low_rail[0]);
  };
  const auto [kept, low] = run(0.2);
  EXPECT_EQ(kept.count(ROAD), 0u);
  EXPECT_EQ(kept.at(CAR), 60u * 6u) << "the rows at 0.3-0.8 m"; // 60 positions x 6 rows
  EXPECT_EQ(low, 0u) << "the rows at 0.1 and 0.2 m are terrain";
  const auto [paper, paper_low] = run(0.0);
  EXPECT_EQ(paper.count(ROAD), 0u);
  EXPECT_EQ(paper.at(CAR), 60u * 5u) << "the rows at 0.4-0.8 m: the band goes whole";
  EXPECT_EQ(paper_low, 0u);
}

/** The ground as planar cells (terrain_plane_tile_m 4 m): a road 16 m x 8 m crowned
 * 0.128 m over its length (z = 0.128 - 0.002 (x - 8)^2), given as one ground plane z =
 * 0 with a 0.3 m band, stays in the cloud and becomes one plane per 4 m tile, each
 * fitted to its own points (within 0.01 m of them, where the one plane is up to 0.128
 * m off), facing the sensor above; every point is an inlier of exactly one tile's
 * plane, inside that tile. With the default 0 (the paper's rule) the road goes. */
TEST(TerrainRemoval, TerrainTilesKeepACrownedRoadAsLocalPlanes)
{
  const auto run = [](double tile_m, Street& s) {
    auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
    for (float x = 0.05f; x < 16.0f; x += 0.1f)
      for (float y = 0.05f; y < 8.0f; y += 0.1f)
        addLabelled(*cloud, x, y, 0.128f - 0.002f * (x - 8.0f) * (x - 8.0f), ROAD);
    setWorldCloud(s, cloud, "crowned road");
    removeTerrainOfGroundPlane(s, 0.3f, "terrain_plane_tile_m", tile_m);
  };
  Street paper;
  run(0.0, paper);
  EXPECT_EQ(paper.frame.cloud->size(), 0u);
  EXPECT_TRUE(paper.frame.planes.empty());

  Street s;
  run(4.0, s);
  const auto& cloud = *s.frame.cloud;
  ASSERT_EQ(cloud.size(), 160u * 80u);
  // 4 tiles along x, 2 across y
  ASSERT_EQ(s.frame.planes.size(), 8u);
  std::vector<int> seen(cloud.size(), 0);
  const Eigen::Vector3f origin = cloud.sensor_origin_.head<3>();
  for (const auto& plane : s.frame.planes) {
    ASSERT_EQ(plane.model_coefficients.values.size(), 4u);
    const Eigen::Vector4f c(plane.model_coefficients.values.data());
    EXPECT_NEAR(c.head<3>().norm(), 1.0f, 1e-5f);
    EXPECT_GT(c.head<3>().dot(origin) + c[3], 0.0f); // facing the sensor
    ASSERT_FALSE(plane.inliers.indices.empty());
    const auto& first = cloud[static_cast<std::size_t>(plane.inliers.indices[0])];
    const float tile_x = std::floor(first.x / 4.0f);
    const float tile_y = std::floor(first.y / 4.0f);
    float worst = 0.0f;
    for (const int i : plane.inliers.indices) {
      const auto& p = cloud[static_cast<std::size_t>(i)];
      ++seen[static_cast<std::size_t>(i)];
      EXPECT_EQ(std::floor(p.x / 4.0f), tile_x);
      EXPECT_EQ(std::floor(p.y / 4.0f), tile_y);
      worst = std::max(worst, std::abs(c.head<3>().dot(p.getVector3fMap()) + c[3]));
    }
    EXPECT_LT(worst, 0.01f) << "tile " << tile_x << ", " << tile_y;
  }
  for (std::size_t i = 0; i < seen.size(); ++i)
    ASSERT_EQ(seen[i], 1) << "point " << i;
}
