// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::integrate(MapFrame): one frame into the map in one call.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_frame.h>
#include <planar_grid/map/planar_grid_map.h>

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <string>
#include <utility>
#include <vector>

#include "wall_cuboid.h"

namespace {

using planar_grid::DepthImage;
using planar_grid::MapFrame;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarGridMap;
using planar_grid::PlaneModels;
using planar_grid::SpaceState;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** A street-side scene seen by a camera driving along +x: a wall at y = 4 (normal -y,
 * toward the road), a non-planar box in front of it, and feature points on the wall.
 * Each frame is held here so that a MapFrame can point at it. */
class MapFrameTest : public ::testing::Test {
protected:
  /** The inputs of one frame. */
  struct SceneFrame {
    PlanarCuboids cuboids;
    PlaneModels planes;
    Cloud features;
    std::vector<float> probabilities;
    Eigen::Isometry3d world_T_sensor{Eigen::Isometry3d::Identity()};
    DepthImage depth;
    Cloud rays;
  };

  static PlanarGridMap::Params params()
  {
    PlanarGridMap::Params p;
    p.resolution_m = 0.1;
    p.space.prior = SpaceState::UNKNOWN;
    p.space.max_range_m = 10.0;
    p.surface.skip_isolated_non_planar = false;
    return p;
  }

  /** Frame \a k: the camera at x = 2 k, 1.5 m high, looking along +y (camera z =
   * world y, camera x = world x, camera y = world -z); the wall's points 4 m ahead,
   * every 2 cm over x in [2 k - 2, 2 k + 2] and z in [0, 3], and a box's points
   * 2.5 m ahead. */
  static SceneFrame sceneFrame(int k)
  {
    SceneFrame f;
    const double x = 2.0 * k;
    Eigen::Matrix3d world_R_camera;
    world_R_camera.col(0) = Eigen::Vector3d::UnitX();
    world_R_camera.col(1) = -Eigen::Vector3d::UnitZ();
    world_R_camera.col(2) = Eigen::Vector3d::UnitY();
    f.world_T_sensor.linear() = world_R_camera;
    f.world_T_sensor.translation() = Eigen::Vector3d(x, 0.0, 1.5);

    const auto fx = static_cast<float>(x);
    f.planes.emplace_back(0.0f, -1.0f, 0.0f, 4.0f); // -y + 4 = 0: y = 4
    f.cuboids.push_back(planar_grid_test::wallCuboid(
      Eigen::Vector3f(fx, 4.0f, 1.5f), -Eigen::Vector3f::UnitY(),
      Eigen::Vector3f::UnitX(), 4.0f, 3.0f, 0));
    f.cuboids.back().point_count = 400;
    PlanarCuboid box;
    box.normal = -Eigen::Vector3f::UnitZ();
    box.horizontal_axis = Eigen::Vector3f::UnitX();
    box.width_m = box.height_m = box.thickness_m = 0.4f;
    box.centre = Eigen::Vector3f(1.0f, 2.5f, 0.2f);
    box.plane_id = -1;
    box.is_planar = false;
    box.point_count = 20;
    f.cuboids.push_back(box);

    for (int i = 0; i < 5; ++i) {
      f.features.push_back(
        pcl::PointXYZ(fx - 1.0f + 0.5f * static_cast<float>(i), 4.0f, 1.0f));
      f.probabilities.push_back(0.6f + 0.05f * static_cast<float>(i));
    }

    for (int i = 0; i <= 200; ++i)
      for (int j = 0; j <= 150; ++j)
        f.rays.push_back(pcl::PointXYZ(fx - 2.0f + 0.02f * static_cast<float>(i), 4.0f,
                                       0.02f * static_cast<float>(j)));
    for (int i = 0; i <= 20; ++i)
      for (int j = 0; j <= 20; ++j)
        f.rays.push_back(pcl::PointXYZ(0.8f + 0.02f * static_cast<float>(i), 2.3f,
                                       0.02f * static_cast<float>(j)));
    Cloud camera_cloud;
    const Eigen::Isometry3f camera_T_world = f.world_T_sensor.inverse().cast<float>();
    for (const auto& p : f.rays.points) {
      pcl::PointXYZ q;
      q.getVector3fMap() = camera_T_world * p.getVector3fMap();
      camera_cloud.push_back(q);
    }
    f.depth =
      DepthImage::fromPointCloud(camera_cloud, 80, 60, 40.0f, 40.0f, 40.0f, 30.0f);
    return f;
  }

  /** The MapFrame of \a f: its depth image (\a rays false) or its rays. */
  static MapFrame mapFrame(const SceneFrame& f, bool rays, double order, double window)
  {
    MapFrame m;
    m.cuboids = &f.cuboids;
    m.planes = &f.planes;
    m.features = &f.features;
    m.probabilities = &f.probabilities;
    m.world_T_sensor = f.world_T_sensor;
    if (rays)
      m.rays = &f.rays;
    else
      m.depth = &f.depth;
    m.observation_order = order;
    m.window_half_size_m = window;
    return m;
  }

  /** The calls integrate() stands for, one by one. */
  static void integrateStepByStep(PlanarGridMap& map,
                                  const SceneFrame& f,
                                  bool rays,
                                  double order,
                                  double window)
  {
    map.integrateSurface(f.cuboids, f.planes, f.features, f.probabilities);
    const Eigen::Vector3f origin = f.world_T_sensor.translation().cast<float>();
    if (rays)
      map.integratePointCloud(f.rays, origin);
    else
      map.integrateDepthImage(f.depth, f.world_T_sensor);
    map.noteObservationOrder(order);
    if (window > 0.0) {
      const auto half = static_cast<float>(window);
      const float inf = std::numeric_limits<float>::infinity();
      map.removeOutside(Eigen::AlignedBox3f(
        Eigen::Vector3f(origin.x() - half, origin.y() - half, -inf),
        Eigen::Vector3f(origin.x() + half, origin.y() + half, inf)));
    }
  }

  static std::string bytes(const PlanarGridMap& map)
  {
    std::string b;
    map.serialize(b);
    return b;
  }

  /** Both maps hold the same cuboids, voxels and bytes. */
  static void expectSameMap(const PlanarGridMap& a, const PlanarGridMap& b)
  {
    const PlanarCuboids ca = a.getSurfaceLayer().getCuboids();
    const PlanarCuboids cb = b.getSurfaceLayer().getCuboids();
    ASSERT_EQ(ca.size(), cb.size());
    for (std::size_t i = 0; i < ca.size(); ++i) {
      EXPECT_EQ(ca[i].centre, cb[i].centre) << "cuboid " << i;
      EXPECT_EQ(ca[i].normal, cb[i].normal) << "cuboid " << i;
      EXPECT_EQ(ca[i].width_m, cb[i].width_m) << "cuboid " << i;
      EXPECT_EQ(ca[i].height_m, cb[i].height_m) << "cuboid " << i;
      EXPECT_EQ(ca[i].probability, cb[i].probability) << "cuboid " << i;
    }
    for (const SpaceState s :
         {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN})
      EXPECT_EQ(a.getSpaceLayer().getVoxelCount(s), b.getSpaceLayer().getVoxelCount(s));
    EXPECT_TRUE(a == b);
    EXPECT_EQ(bytes(a), bytes(b));
  }

  /** Four frames through integrate() and through the steps it replaces, the window
   * off for the first two and 5 m after (the camera has moved on): the same map after
   * each frame, the window cut the map, and the scene reached both layers (the
   * comparison is not of two empty maps). \a first_order: the first frame's order. */
  void expectIntegrateEqualsTheSteps(bool rays, double first_order)
  {
    PlanarGridMap one_call(params());
    PlanarGridMap steps(params());
    bool window_removed = false;
    for (int k = 0; k < 4; ++k) {
      const SceneFrame f = sceneFrame(k);
      const double window = k < 2 ? 0.0 : 5.0;
      const planar_grid::MapWindowRemoval removed =
        one_call.integrate(mapFrame(f, rays, first_order + k, window));
      if (window == 0.0) {
        EXPECT_EQ(removed.space_voxels, 0u);
      }
      window_removed = window_removed || removed.space_voxels > 0;
      integrateStepByStep(steps, f, rays, first_order + k, window);
      expectSameMap(one_call, steps);
    }
    EXPECT_TRUE(window_removed);
    EXPECT_GT(one_call.getSurfaceLayer().getCuboidCount(), 0u);
    EXPECT_GT(one_call.getSpaceLayer().getVoxelCount(SpaceState::FREE), 0u);
    EXPECT_GT(one_call.getSpaceLayer().getVoxelCount(SpaceState::OCCUPIED), 0u);
    EXPECT_EQ(one_call.getObservationSpan().first, first_order);
    EXPECT_EQ(one_call.getObservationSpan().last, first_order + 3.0);
  }
};

TEST_F(MapFrameTest, IntegrateEqualsTheStepsItReplacesForDepthImages)
{
  expectIntegrateEqualsTheSteps(false, 0.0);
}

TEST_F(MapFrameTest, IntegrateEqualsTheStepsItReplacesForRays)
{
  expectIntegrateEqualsTheSteps(true, 10.0);
}

TEST_F(MapFrameTest, AbsentInputsAreEmpty)
{
  // Null cuboids, planes, features and probabilities integrate as empty inputs.
  const SceneFrame f = sceneFrame(0);
  PlanarGridMap one_call(params());
  MapFrame m;
  m.world_T_sensor = f.world_T_sensor;
  m.depth = &f.depth;
  one_call.integrate(m);
  PlanarGridMap steps(params());
  integrateStepByStep(steps,
                      SceneFrame{PlanarCuboids(), PlaneModels(), Cloud(),
                                 std::vector<float>(), f.world_T_sensor, f.depth,
                                 Cloud()},
                      false, 0.0, 0.0);
  expectSameMap(one_call, steps);
  EXPECT_EQ(one_call.getSurfaceLayer().getCuboidCount(), 0u);
}

TEST_F(MapFrameTest, InvalidFramesThrowAndLeaveTheMapUnchanged)
{
  PlanarGridMap map(params());
  const SceneFrame first = sceneFrame(0);
  map.integrate(mapFrame(first, false, 0.0, 0.0));
  const std::string before = bytes(map);
  ASSERT_GT(map.getSurfaceLayer().getCuboidCount(), 0u);

  const SceneFrame f = sceneFrame(1);
  const std::vector<float> short_probabilities(f.probabilities.size() - 1, 0.7f);
  DepthImage short_depth = f.depth;
  short_depth.depth_m.pop_back();
  DepthImage empty_depth;
  DepthImage zero_focal_length = f.depth;
  zero_focal_length.fy = 0.0f;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const double inf = std::numeric_limits<double>::infinity();
  const std::vector<std::pair<std::string, std::function<void(MapFrame&)>>> cases = {
    {"no space measurement",
     [](MapFrame& m) {
       m.depth = nullptr;
     }},
    {"both measurements",
     [&](MapFrame& m) {
       m.rays = &f.rays;
     }},
    {"fewer depths than pixels",
     [&](MapFrame& m) {
       m.depth = &short_depth;
     }},
    {"an empty depth image",
     [&](MapFrame& m) {
       m.depth = &empty_depth;
     }},
    {"a zero focal length",
     [&](MapFrame& m) {
       m.depth = &zero_focal_length;
     }},
    {"fewer probabilities than features",
     [&](MapFrame& m) {
       m.probabilities = &short_probabilities;
     }},
    {"features without probabilities",
     [](MapFrame& m) {
       m.probabilities = nullptr;
     }},
    {"probabilities without features",
     [](MapFrame& m) {
       m.features = nullptr;
     }},
    {"NaN in the pose",
     [&](MapFrame& m) {
       m.world_T_sensor.translation().x() = nan;
     }},
    {"infinite rotation",
     [&](MapFrame& m) {
       m.world_T_sensor.linear()(1, 1) = inf;
     }},
    {"NaN order",
     [&](MapFrame& m) {
       m.observation_order = nan;
     }},
    {"infinite order",
     [&](MapFrame& m) {
       m.observation_order = inf;
     }},
    {"negative window",
     [](MapFrame& m) {
       m.window_half_size_m = -1.0;
     }},
    {"NaN window",
     [&](MapFrame& m) {
       m.window_half_size_m = nan;
     }},
    {"infinite window",
     [&](MapFrame& m) {
       m.window_half_size_m = inf;
     }},
  };
  for (const auto& [name, spoil] : cases) {
    MapFrame m = mapFrame(f, false, 1.0, 2.0);
    spoil(m);
    EXPECT_THROW(map.integrate(m), planar_grid::Exception) << name;
    EXPECT_EQ(bytes(map), before) << name;
    EXPECT_EQ(map.getObservationSpan().last, 0.0) << name;
  }
  // The valid frame still integrates afterwards.
  map.integrate(mapFrame(f, false, 1.0, 2.0));
  EXPECT_NE(bytes(map), before);
  EXPECT_EQ(map.getObservationSpan().last, 1.0);
}

TEST_F(MapFrameTest, TheErrorNamesTheProblem)
{
  PlanarGridMap map(params());
  const SceneFrame f = sceneFrame(0);
  MapFrame m = mapFrame(f, false, 0.0, 0.0);
  m.depth = nullptr;
  try {
    map.integrate(m);
    FAIL() << "no exception";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("no space measurement"), std::string::npos)
      << e.what();
  }
  m = mapFrame(f, false, 0.0, 0.0);
  const std::vector<float> three(3, 0.5f);
  m.probabilities = &three;
  try {
    map.integrate(m);
    FAIL() << "no exception";
  } catch (const planar_grid::Exception& e) {
    EXPECT_NE(std::string(e.what()).find("5 feature points but 3 probabilities"),
              std::string::npos)
      << e.what();
  }
}

} // namespace
