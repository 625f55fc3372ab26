// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/terrain_removal.h>

#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace {

using planar_grid::PlanarSegment;
using planar_grid::PlanarSegments;
using Removal = planar_grid::TerrainRemoval<pcl::PointXYZ>;

/** A street with exact truth, z up, the sensor 1.6 m above the road: the road (z =
 * 0), a sidewalk beside it (z = 0.15, a curb's step), a ramp too steep to be terrain,
 * a wall, a box standing on the road, loose points just above the road and the
 * sidewalk, and one road inlier standing 0.25 m above the road (a post's foot in
 * eq. 11's band). Each point's kind says what the terrain removal must do with it. */
struct Street {
  enum Kind {
    ROAD,
    ROAD_STANDING,
    SIDEWALK,
    RAMP,
    WALL,
    BOX,
    LOW_ON_ROAD,
    LOW_ON_SIDEWALK,
    HIGH_ON_SIDEWALK
  };
  pcl::PointCloud<pcl::PointXYZ> cloud;
  std::vector<Kind> kinds;
  PlanarSegments planes;
  Eigen::Vector3f sensor{0.0f, 0.0f, 1.6f};

  std::vector<int> add(Kind kind,
                       float x0,
                       float x1,
                       float y0,
                       float y1,
                       float step,
                       float z0,
                       float dz_dx = 0.0f)
  {
    std::vector<int> indices;
    for (float x = x0; x <= x1 + 1e-4f; x += step)
      for (float y = y0; y <= y1 + 1e-4f; y += step) {
        indices.push_back(static_cast<int>(cloud.size()));
        cloud.push_back(pcl::PointXYZ(x, y, z0 + dz_dx * (x - x0)));
        kinds.push_back(kind);
      }
    return indices;
  }

  void addPlane(const Eigen::Vector4f& c, std::vector<int> inliers)
  {
    PlanarSegment s;
    s.model_coefficients.values = {c[0], c[1], c[2], c[3]};
    s.inliers.indices = std::move(inliers);
    planes.push_back(s);
  }

  explicit Street(float sidewalk_height = 0.15f)
  {
    std::vector<int> road = add(ROAD, 2.0f, 12.0f, -4.0f, 3.8f, 0.2f, 0.0f);
    // a road inlier standing above the road
    road.push_back(static_cast<int>(cloud.size()));
    cloud.push_back(pcl::PointXYZ(6.1f, 0.1f, 0.25f));
    kinds.push_back(ROAD_STANDING);
    const std::vector<int> sidewalk =
      add(SIDEWALK, 2.0f, 12.0f, 4.0f, 7.0f, 0.2f, sidewalk_height);
    // 45 degrees: beyond terrain_max_slope_rad (0.3), though it rises from the road
    const std::vector<int> ramp = add(RAMP, 2.0f, 4.0f, -8.0f, -6.0f, 0.2f, 0.0f, 1.0f);
    std::vector<int> wall;
    for (float y = -4.0f; y <= 4.0f; y += 0.2f)
      for (float z = 0.0f; z <= 3.0f; z += 0.2f) {
        wall.push_back(static_cast<int>(cloud.size()));
        cloud.push_back(pcl::PointXYZ(14.0f, y, z));
        kinds.push_back(WALL);
      }
    for (float z = 0.5f; z <= 1.5f; z += 0.25f)
      add(BOX, 8.0f, 8.6f, -1.0f, -0.4f, 0.2f, z);
    add(LOW_ON_ROAD, 3.5f, 4.5f, -2.5f, -1.5f, 0.25f, 0.1f);
    add(LOW_ON_SIDEWALK, 5.2f, 5.8f, 5.2f, 5.8f, 0.2f, sidewalk_height + 0.15f);
    add(HIGH_ON_SIDEWALK, 9.2f, 9.8f, 5.2f, 5.8f, 0.2f, sidewalk_height + 0.35f);
    // sorted by inlier count, as SACMultiPlaneSegmentation gives them
    const float s = std::sqrt(0.5f);
    addPlane(Eigen::Vector4f(0.0f, 0.0f, 1.0f, 0.0f), road);
    addPlane(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -sidewalk_height), sidewalk);
    addPlane(Eigen::Vector4f(-1.0f, 0.0f, 0.0f, 14.0f), wall);
    addPlane(Eigen::Vector4f(-s, 0.0f, s, 2.0f * s), ramp);
  }
};

Removal
streetRemoval(const Street& street, double tile_m = 0.0)
{
  Removal::Params p;
  p.eps_angle_rad = 0.2;
  p.min_sensor_height_m = 0.5;
  p.terrain_max_slope_rad = 0.3;
  p.terrain_max_step_m = 0.3;
  p.terrain_height_m = 0.2;
  p.terrain_cell_m = 1.0;
  p.terrain_plane_tile_m = tile_m;
  Removal removal(p);
  removal.setUpAxis(Eigen::Vector3f::UnitZ());
  removal.setSensorOrigin(street.sensor);
  return removal;
}

/** Each point of \a street flagged terrain exactly when its kind is: the road, the
 * sidewalk and the loose points just above them go; the box, the wall, the ramp, the
 * post's foot and the points higher above the sidewalk stay. */
void
expectTerrainOfTheStreet(const Street& street, const std::vector<std::uint8_t>& terrain)
{
  ASSERT_EQ(terrain.size(), street.cloud.size());
  for (std::size_t i = 0; i < terrain.size(); ++i) {
    const Street::Kind k = street.kinds[i];
    const bool expected = k == Street::ROAD || k == Street::SIDEWALK
                          || k == Street::LOW_ON_ROAD || k == Street::LOW_ON_SIDEWALK;
    EXPECT_EQ(terrain[i] != 0, expected) << "point " << i << " of kind " << k;
  }
}

TEST(TerrainRemoval, FindsTheGroundAndTheSidewalkAndKeepsWhatStandsOnThem)
{
  Street street;
  Removal removal = streetRemoval(street);
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  ASSERT_TRUE(removal.segment(street.cloud, planes, terrain));
  // the road, its normal up: the sensor's signed distance is its height
  const Eigen::Vector4f g = removal.getGroundCoefficients();
  EXPECT_NEAR(g[2], 1.0f, 1e-6f);
  EXPECT_NEAR(g.head<3>().dot(street.sensor) + g[3], 1.6f, 1e-6f);
  EXPECT_EQ(removal.getTerrainPlaneCount(), 2u);
  // the wall and the ramp stay, in their order
  ASSERT_EQ(planes.size(), 2u);
  EXPECT_FLOAT_EQ(planes[0].model_coefficients.values[0], -1.0f);
  EXPECT_LT(planes[1].model_coefficients.values[0], -0.5f);
  expectTerrainOfTheStreet(street, terrain);
}

TEST(TerrainRemoval, FindsATiltedGroundGivenWithItsNormalDown)
{
  // The whole street turned by 0.1 rad about y and 0.05 rad about x (a road on a
  // slope, within eps_angle_rad of the up axis, which stays +z), the road's
  // coefficients given with the normal pointing down: the ground comes back as the
  // turned road with its normal up, and every point's fate is the level street's.
  Street street;
  const Eigen::Matrix3f turn = (Eigen::AngleAxisf(0.1f, Eigen::Vector3f::UnitY())
                                * Eigen::AngleAxisf(0.05f, Eigen::Vector3f::UnitX()))
                                 .toRotationMatrix();
  for (auto& p : street.cloud)
    p.getVector3fMap() = turn * p.getVector3fMap();
  street.sensor = turn * street.sensor;
  for (auto& plane : street.planes) {
    auto& c = plane.model_coefficients.values;
    const Eigen::Vector3f n = turn * Eigen::Vector3f(c[0], c[1], c[2]);
    c = {n.x(), n.y(), n.z(), c[3]};
  }
  for (auto& c : street.planes[0].model_coefficients.values)
    c = -c;
  Removal removal = streetRemoval(street);
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  ASSERT_TRUE(removal.segment(street.cloud, planes, terrain));
  const Eigen::Vector4f g = removal.getGroundCoefficients();
  const Eigen::Vector3f normal = turn * Eigen::Vector3f::UnitZ();
  EXPECT_NEAR(g[0], normal.x(), 1e-6f);
  EXPECT_NEAR(g[1], normal.y(), 1e-6f);
  EXPECT_NEAR(g[2], normal.z(), 1e-6f);
  EXPECT_NEAR(g[3], 0.0f, 1e-6f);
  EXPECT_NEAR(g.head<3>().dot(street.sensor) + g[3], 1.6f, 1e-5f);
  EXPECT_EQ(removal.getTerrainPlaneCount(), 2u);
  ASSERT_EQ(planes.size(), 2u);
  expectTerrainOfTheStreet(street, terrain);
}

TEST(TerrainRemoval, APlaneAboveTheStepIsNoTerrain)
{
  // a raised platform 0.5 m above the road: a step higher than terrain_max_step_m
  Street street(0.5f);
  Removal removal = streetRemoval(street);
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  ASSERT_TRUE(removal.segment(street.cloud, planes, terrain));
  EXPECT_EQ(removal.getTerrainPlaneCount(), 1u);
  EXPECT_EQ(planes.size(), 3u);
  for (std::size_t i = 0; i < terrain.size(); ++i) {
    if (street.kinds[i] == Street::SIDEWALK) {
      ASSERT_EQ(terrain[i], 0) << "point " << i;
    }
  }
}

TEST(TerrainRemoval, NoGroundBelowASensorTooLowLeavesEverything)
{
  Street street;
  street.sensor = Eigen::Vector3f(0.0f, 0.0f, 0.3f); // below min_sensor_height_m
  Removal removal = streetRemoval(street);
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  EXPECT_FALSE(removal.segment(street.cloud, planes, terrain));
  EXPECT_EQ(planes.size(), street.planes.size());
  ASSERT_EQ(terrain.size(), street.cloud.size());
  for (const auto t : terrain)
    EXPECT_EQ(t, 0);
}

TEST(TerrainRemoval, TilesKeepTheTerrainAsOnePlanePerTile)
{
  Street street;
  const double tile_m = 4.0;
  Removal removal = streetRemoval(street, tile_m);
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  ASSERT_TRUE(removal.segment(street.cloud, planes, terrain));
  // each terrain plane replaced in its place by its tiles' planes: the road's, the
  // sidewalk's, then the wall and the ramp
  ASSERT_GT(planes.size(), 4u);
  EXPECT_FLOAT_EQ(planes[planes.size() - 2].model_coefficients.values[0], -1.0f);
  EXPECT_LT(planes.back().model_coefficients.values[0], -0.5f);
  std::set<int> tiled;
  for (std::size_t k = 0; k + 2 < planes.size(); ++k) {
    std::set<std::pair<long, long>> tiles;
    const auto& c = planes[k].model_coefficients.values;
    EXPECT_GT(c[2], 0.99f) << "plane " << k;
    for (const int i : planes[k].inliers.indices) {
      const auto& p = street.cloud[static_cast<std::size_t>(i)];
      tiles.insert({static_cast<long>(std::floor(p.x / tile_m)),
                    static_cast<long>(std::floor(p.y / tile_m))});
      // refitted to its own inliers: they lie on it
      EXPECT_NEAR(c[0] * p.x + c[1] * p.y + c[2] * p.z + c[3], 0.0f, 1e-4f);
      EXPECT_TRUE(tiled.insert(i).second) << "inlier " << i << " in two tiles";
    }
    EXPECT_EQ(tiles.size(), 1u) << "plane " << k << " spans tiles";
  }
  // Every lying road and sidewalk inlier is in a tile, unless its tile had fewer than
  // 3 (then it is terrain); the standing one is in none and stays; the loose low
  // points still go.
  for (std::size_t i = 0; i < street.cloud.size(); ++i) {
    const Street::Kind k = street.kinds[i];
    const bool in_tile = tiled.count(static_cast<int>(i)) > 0;
    if (k == Street::ROAD || k == Street::SIDEWALK) {
      EXPECT_TRUE(in_tile || terrain[i]) << "point " << i;
      EXPECT_NE(in_tile, terrain[i] != 0) << "point " << i;
    } else {
      EXPECT_FALSE(in_tile) << "point " << i;
      const bool low = k == Street::LOW_ON_ROAD || k == Street::LOW_ON_SIDEWALK;
      EXPECT_EQ(terrain[i] != 0, low) << "point " << i << " of kind " << k;
    }
  }
}

TEST(TerrainRemoval, RefusesParametersOutOfRange)
{
  Street street;
  PlanarSegments planes = street.planes;
  std::vector<std::uint8_t> terrain;
  Removal removal = streetRemoval(street);
  Removal::Params p = removal.getParams();
  p.terrain_cell_m = 0.0;
  removal.setParams(p);
  try {
    removal.segment(street.cloud, planes, terrain);
    FAIL() << "terrain_cell_m 0 accepted";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("terrain_cell_m"), std::string::npos)
      << e.what();
  }
  EXPECT_EQ(planes.size(), street.planes.size());
  p.terrain_cell_m = 1.0;
  p.eps_angle_rad = -0.1;
  removal.setParams(p);
  EXPECT_THROW(removal.segment(street.cloud, planes, terrain), planar_grid::Exception);
  p.eps_angle_rad = 0.2;
  removal.setParams(p);
  removal.setUpAxis(Eigen::Vector3f::Zero());
  EXPECT_THROW(removal.segment(street.cloud, planes, terrain), planar_grid::Exception);
}

} // namespace
