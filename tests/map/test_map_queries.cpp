// SPDX-License-Identifier: BSD-3-Clause
// The planner's queries of PlanarGridMap (getDistance, isCollisionFree,
// exportOccupancyGrid2D): exact truth on hand-built maps, a brute-force oracle over
// every occupied cuboid and voxel on random maps and a real Karlsruhe frame, and the
// 2D map read back the way ROS map_server reads it.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/map_region_index.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <fstream>
#include <limits>
#include <map>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "../benchmarks/karlsruhe_frame.h"
#include "../test_constants.h"
#include "map_queries_oracle.h"

namespace planar_grid {
namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using planar_grid_test::PI;

PlanarGridMap::Params
mapParams(SpaceState prior)
{
  PlanarGridMap::Params p;
  p.resolution_m = 0.1;
  p.space.prior = prior;
  p.space.max_range_m = 25.0;
  p.clear_non_planar = false;
  return p;
}

/** A non-planar cuboid (stored as given; probability 0.5 without features, which is
 * occupied at the default occupancy_thres 0.5) along the columns of \a rotation:
 * width along the first, height along the second, thickness along the third. */
PlanarCuboid
box(const Eigen::Vector3f& centre,
    const Eigen::Vector3f& size,
    const Eigen::Matrix3f& rotation)
{
  PlanarCuboid c;
  c.centre = centre;
  c.horizontal_axis = rotation.col(0);
  c.normal = rotation.col(2);
  // verticalAxis() = normal x horizontal_axis = z x x = y for a rotation
  c.width_m = size.x();
  c.height_m = size.y();
  c.thickness_m = size.z();
  c.plane_id = -1;
  c.is_planar = false;
  return c;
}

// ---- the oracle: every obstacle box, double precision ----------------------------

using test::OracleBox;

std::vector<OracleBox>
oracleBoxes(const PlanarGridMap& map, bool unknown_is_occupied)
{
  std::vector<OracleBox> out;
  const float thres =
    static_cast<float>(map.getSurfaceLayer().getParams().occupancy_thres);
  for (const PlanarCuboid& c : map.getSurfaceLayer().getCuboids()) {
    if (c.probability < thres)
      continue;
    OracleBox b;
    b.axes.col(0) = c.horizontal_axis.cast<double>();
    b.axes.col(1) = c.verticalAxis().cast<double>();
    b.axes.col(2) = c.normal.cast<double>();
    b.centre = c.centre.cast<double>();
    b.half = 0.5 * Eigen::Vector3d(c.width_m, c.height_m, c.thickness_m);
    out.push_back(b);
  }
  const double r = map.getResolution();
  const auto addVoxel = [&](const Eigen::Vector3i& k) {
    OracleBox b;
    b.axes.setIdentity();
    b.centre = (k.cast<double>() + Eigen::Vector3d::Constant(0.5)) * r;
    b.half.setConstant(0.5 * r);
    out.push_back(b);
  };
  const ExplicitSpaceGrid& space = map.getSpaceLayer();
  if (unknown_is_occupied && space.getParams().prior == SpaceState::UNKNOWN) {
    Eigen::Vector3i lo, hi;
    if (space.getBounds(lo, hi))
      for (int z = lo.z(); z <= hi.z(); ++z)
        for (int y = lo.y(); y <= hi.y(); ++y)
          for (int x = lo.x(); x <= hi.x(); ++x)
            if (space.getState(Eigen::Vector3i(x, y, z)) != SpaceState::FREE)
              addVoxel(Eigen::Vector3i(x, y, z));
  } else {
    space.forEachVoxel([&](const Eigen::Vector3i& k, SpaceState s) {
      if (s == SpaceState::OCCUPIED
          || (unknown_is_occupied && s == SpaceState::UNKNOWN))
        addVoxel(k);
    });
  }
  return out;
}

/** Checks getDistance() against the oracle at \a points: distances within 1 mm,
 * gradients within 1 degree where every obstacle within 1 mm of the nearest gives the
 * same direction. \a outside_lo / hi: the unknown outside (with the unknown prior). */
void
expectOracleDistances(const PlanarGridMap& map,
                      const Eigen::Matrix3Xf& points,
                      double cap,
                      bool unknown_is_occupied,
                      std::size_t& gradients_compared)
{
  const auto boxes = oracleBoxes(map, unknown_is_occupied);
  Eigen::VectorXf dist(points.cols());
  Eigen::Matrix3Xf grad(3, points.cols());
  map.getDistance(points, cap, dist, grad, unknown_is_occupied);
  const bool outside =
    unknown_is_occupied && map.getSpaceLayer().getParams().prior == SpaceState::UNKNOWN;
  Eigen::Vector3i klo, khi;
  const bool has_bounds = map.getSpaceLayer().getBounds(klo, khi);
  const double r = map.getResolution();
  for (Eigen::Index i = 0; i < points.cols(); ++i) {
    const Eigen::Vector3d p = points.col(i).cast<double>();
    std::vector<std::pair<double, Eigen::Vector3d>> near;
    double best = test::oracleNearest(boxes, p, cap, 1e-3, near);
    if (outside && has_bounds) {
      const Eigen::Vector3d lo = klo.cast<double>() * r;
      const Eigen::Vector3d hi = (khi.cast<double>() + Eigen::Vector3d::Ones()) * r;
      const Eigen::Vector3d below = p - lo, above = hi - p;
      const double d = std::max(0.0, std::min(below.minCoeff(), above.minCoeff()));
      int a = 0, c = 0;
      below.minCoeff(&a);
      above.minCoeff(&c);
      Eigen::Vector3d g = Eigen::Vector3d::Zero();
      if (below[a] <= above[c])
        g[a] = 1.0;
      else
        g[c] = -1.0;
      near.emplace_back(d, g);
      best = std::min(best, d);
    }
    ASSERT_NEAR(dist[i], best, 1e-3) << "point " << p.transpose();
    if (best >= cap - 1e-3 || best < 1e-3)
      continue;
    bool unique = true;
    Eigen::Vector3d g0 = Eigen::Vector3d::Zero();
    for (const auto& [d, g] : near) {
      if (d > best + 1e-3)
        continue;
      if (g0.isZero())
        g0 = g;
      else if (g.dot(g0) < std::cos(PI / 180.0))
        unique = false;
    }
    if (!unique)
      continue;
    ++gradients_compared;
    const double cosine = grad.col(i).cast<double>().dot(g0);
    EXPECT_GT(cosine, std::cos(PI / 180.0)) << "point " << p.transpose();
  }
}

/** Checks isCollisionFree() against the oracle; answers whose margin to touching is
 * under 1e-4 m (float rounding) are counted apart and must be few. */
void
expectOracleCollisions(const PlanarGridMap& map,
                       const CollisionBodies& bodies,
                       bool unknown_is_occupied)
{
  const auto boxes = oracleBoxes(map, unknown_is_occupied);
  const auto free = map.isCollisionFree(bodies, unknown_is_occupied);
  ASSERT_EQ(free.size(), bodies.size());
  const bool outside =
    unknown_is_occupied && map.getSpaceLayer().getParams().prior == SpaceState::UNKNOWN;
  Eigen::Vector3i klo, khi;
  const bool has_bounds = map.getSpaceLayer().getBounds(klo, khi);
  std::size_t collisions = 0, borderline = 0;
  for (std::size_t i = 0; i < bodies.size(); ++i) {
    const CollisionBody& body = bodies[i];
    const Eigen::Matrix3d ra = body.rotation.cast<double>();
    const Eigen::Vector3d ca = body.centre.cast<double>();
    const Eigen::Vector3d ha = body.half_extents.cast<double>();
    // > 0 free
    double margin =
      body.shape == CollisionBody::Shape::BOX
        ? test::oracleBoxMargin(boxes, ra, ca, ha, 1e-3)
        : test::oracleSphereMargin(boxes, ca, static_cast<double>(body.radius_m), 1e-3);
    if (outside && has_bounds) {
      const double r = map.getResolution();
      const Eigen::Vector3d lo = klo.cast<double>() * r;
      const Eigen::Vector3d hi = (khi.cast<double>() + Eigen::Vector3d::Ones()) * r;
      const Eigen::Vector3d h = body.shape == CollisionBody::Shape::BOX
                                  ? Eigen::Vector3d(ra.cwiseAbs() * ha)
                                  : Eigen::Vector3d::Constant(body.radius_m);
      margin =
        std::min(margin, std::min((ca - h - lo).minCoeff(), (hi - ca - h).minCoeff()));
    }
    const bool oracle_free = margin > 0.0;
    collisions += oracle_free ? 0 : 1;
    if (std::abs(margin) < 1e-4) {
      ++borderline;
      continue;
    }
    EXPECT_EQ(free[i] != 0, oracle_free) << "body " << i << " margin " << margin;
  }
  EXPECT_LE(borderline, bodies.size() / 100 + 1);
  // Both answers occur, so the comparison says something.
  EXPECT_GT(collisions, 0u);
  EXPECT_LT(collisions, bodies.size());
}

Eigen::Matrix3f
randomRotation(std::mt19937& rng)
{
  std::normal_distribution<float> n(0.0f, 1.0f);
  Eigen::Quaternionf q(n(rng), n(rng), n(rng), n(rng));
  q.normalize();
  return q.toRotationMatrix();
}

// ---- exact truth -------------------------------------------------------------------

TEST(MapQueries, DistanceToOneBoxIsExact)
{
  for (const bool rotated : {false, true}) {
    PlanarGridMap::Params params = mapParams(SpaceState::UNKNOWN);
    params.merge_non_planar = false; // the box as given, off the voxel lattice
    PlanarGridMap map(params);
    const Eigen::Matrix3f rot =
      rotated ? Eigen::AngleAxisf(0.7f, Eigen::Vector3f(1, 2, 3).normalized())
                  .toRotationMatrix()
              : Eigen::Matrix3f::Identity();
    const Eigen::Vector3f c(1.0f, 2.0f, 3.0f);
    const Eigen::Vector3f size(2.0f, 1.0f, 0.5f); // along rot's columns
    map.integrateSurface({box(c, size, rot)}, {}, Cloud(), {});
    ASSERT_EQ(map.getSurfaceLayer().getCuboids().size(), 1u);
    // local offsets from the centre and the known answers
    struct Case {
      Eigen::Vector3f local;
      float distance;
      Eigen::Vector3f gradient; // local frame
    };
    const std::vector<Case> cases = {
      {{1.0f + 0.7f, 0.0f, 0.0f}, 0.7f, {1, 0, 0}},
      {{0.0f, -0.5f - 0.25f, 0.1f}, 0.25f, {0, -1, 0}},
      {{0.2f, 0.1f, 0.25f + 0.4f}, 0.4f, {0, 0, 1}},
      {{1.0f + 0.3f, 0.5f + 0.4f, 0.25f + 1.2f},
       1.3f,
       Eigen::Vector3f(0.3f, 0.4f, 1.2f) / 1.3f},
      {{-1.0f - 0.6f, -0.5f - 0.8f, 0.0f}, 1.0f, Eigen::Vector3f(-0.6f, -0.8f, 0.0f)},
      // inside: distance 0, the normal of the nearest face (the +n face, 0.05 away)
      {{0.1f, 0.0f, 0.2f}, 0.0f, {0, 0, 1}},
      // on the boundary
      {{1.0f, 0.0f, 0.0f}, 0.0f, {1, 0, 0}},
      // beyond the cap (1.5 m): the cap and a zero gradient
      {{1.0f + 3.0f, 0.0f, 0.0f}, 1.5f, {0, 0, 0}},
    };
    Eigen::Matrix3Xf points(3, static_cast<Eigen::Index>(cases.size()));
    for (std::size_t i = 0; i < cases.size(); ++i)
      points.col(static_cast<Eigen::Index>(i)) = c + rot * cases[i].local;
    Eigen::VectorXf d(points.cols());
    Eigen::Matrix3Xf g(3, points.cols());
    map.getDistance(points, 1.5, d, g);
    for (std::size_t i = 0; i < cases.size(); ++i) {
      const auto k = static_cast<Eigen::Index>(i);
      EXPECT_NEAR(d[k], cases[i].distance, 1e-5f)
        << "case " << i << " rotated " << rotated;
      EXPECT_TRUE((g.col(k) - rot * cases[i].gradient).norm() < 1e-4f)
        << "case " << i << " rotated " << rotated << ": " << g.col(k).transpose();
    }
    // unknown_is_occupied with nothing observed (unknown prior): everything is unknown
    map.getDistance(points, 1.5, d, g, true);
    EXPECT_TRUE((d.array() == 0.0f).all());
  }
}

TEST(MapQueries, DistanceToVoxelsAndNonFinitePoints)
{
  PlanarGridMap map(mapParams(SpaceState::FREE));
  map.getSpaceLayer().setState(Eigen::Vector3i(10, 0, 0), SpaceState::OCCUPIED);
  map.getSpaceLayer().setState(Eigen::Vector3i(11, 0, 0), SpaceState::OCCUPIED);
  map.getSpaceLayer().setState(Eigen::Vector3i(-5, 0, 0), SpaceState::UNKNOWN);
  Eigen::Matrix3Xf points(3, 4);
  points.col(0) = Eigen::Vector3f(1.05f, 0.05f, 0.5f);  // 0.4 above the run
  points.col(1) = Eigen::Vector3f(1.6f, 0.05f, 0.05f);  // 0.4 past its end
  points.col(2) = Eigen::Vector3f(-0.7f, 0.05f, 0.05f); // 0.2 from the unknown voxel
  points.col(3) = Eigen::Vector3f(std::nanf(""), 0.0f, 0.0f);
  Eigen::VectorXf d(4);
  Eigen::Matrix3Xf g(3, 4);
  map.getDistance(points, 5.0, d, g);
  EXPECT_NEAR(d[0], 0.4f, 1e-5f);
  EXPECT_TRUE(g.col(0).isApprox(Eigen::Vector3f::UnitZ(), 1e-5f));
  EXPECT_NEAR(d[1], 0.4f, 1e-5f);
  EXPECT_TRUE(g.col(1).isApprox(Eigen::Vector3f::UnitX(), 1e-5f));
  EXPECT_NEAR(d[2], 1.7f, 1e-5f); // to the occupied run, unknown is not an obstacle
  EXPECT_TRUE(std::isnan(d[3]));
  map.getDistance(points, 5.0, d, g, true);
  EXPECT_NEAR(d[2], 0.2f, 1e-5f);
  EXPECT_TRUE(g.col(2).isApprox(-Eigen::Vector3f::UnitX(), 1e-5f));
  // a change of the map drops the index
  map.getSpaceLayer().setState(Eigen::Vector3i(10, 0, 4), SpaceState::OCCUPIED);
  map.getDistance(points, 5.0, d, g);
  EXPECT_NEAR(d[0], 0.0f, 1e-6f);

  Eigen::VectorXf short_d(3);
  EXPECT_THROW(map.getDistance(points, 5.0, short_d, g), Exception);
  EXPECT_THROW(map.getDistance(points, 0.0, d, g), Exception);
  EXPECT_THROW(map.getDistance(points, std::nan(""), d, g), Exception);
}

TEST(MapQueries, SpheresAndBoxesTouchingOrNot)
{
  PlanarGridMap map(mapParams(SpaceState::UNKNOWN));
  const Eigen::Matrix3f rot =
    Eigen::AngleAxisf(0.4f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  // a 2 x 1 x 0.5 box about the origin, turned 0.4 rad about z
  map.integrateSurface({box(Eigen::Vector3f::Zero(), Eigen::Vector3f(2, 1, 0.5f), rot)},
                       {}, Cloud(), {});
  const Eigen::Vector3f x = rot.col(0), y = rot.col(1), z = rot.col(2);
  CollisionBodies bodies;
  // spheres 0.5 m from the +x face: radius 0.5 -+ 1 mm
  bodies.push_back(CollisionBody::sphere(x * 1.5f, 0.499f));
  bodies.push_back(CollisionBody::sphere(x * 1.5f, 0.501f));
  // a sphere off an edge: distance sqrt(0.3^2 + 0.4^2) = 0.5
  bodies.push_back(CollisionBody::sphere(x * 1.3f + y * 0.9f, 0.499f));
  bodies.push_back(CollisionBody::sphere(x * 1.3f + y * 0.9f, 0.501f));
  // a cube of half edge 0.2 turned 45 degrees about z in the box frame, its corner
  // toward the +x face: the corner reaches 0.2 sqrt(2) from its centre
  const Eigen::Matrix3f turned =
    rot
    * Eigen::AngleAxisf(static_cast<float>(PI / 4), Eigen::Vector3f::UnitZ())
        .toRotationMatrix();
  const float reach = 0.2f * std::sqrt(2.0f);
  bodies.push_back(CollisionBody::box(x * (1.0f + reach + 0.001f),
                                      Eigen::Vector3f::Constant(0.2f), turned));
  bodies.push_back(CollisionBody::box(x * (1.0f + reach - 0.001f),
                                      Eigen::Vector3f::Constant(0.2f), turned));
  // edge against edge: a cube turned 45 degrees about x (its edge along x at the
  // bottom) above the box's top edge turned 45 degrees about y: only a cross product
  // of the two edges separates them
  const Eigen::Matrix3f edge_a =
    rot
    * Eigen::AngleAxisf(static_cast<float>(PI / 4), Eigen::Vector3f::UnitX())
        .toRotationMatrix();
  // its lowest edge is 0.2 sqrt(2) below its centre; the box's top face is at z 0.25
  bodies.push_back(CollisionBody::box(z * (0.25f + reach + 0.001f),
                                      Eigen::Vector3f::Constant(0.2f), edge_a));
  bodies.push_back(CollisionBody::box(z * (0.25f + reach - 0.001f),
                                      Eigen::Vector3f::Constant(0.2f), edge_a));
  // invalid bodies are never free
  bodies.push_back(CollisionBody::sphere(Eigen::Vector3f(100, 0, 0), -1.0f));
  bodies.push_back(CollisionBody::sphere(Eigen::Vector3f(std::nanf(""), 0, 0), 1.0f));
  const auto free = map.isCollisionFree(bodies);
  const std::vector<std::uint8_t> expected = {1, 0, 1, 0, 1, 0, 1, 0, 0, 0};
  EXPECT_EQ(free, expected);
  // with the unknown prior and nothing observed, unknown space is everywhere
  const auto strict = map.isCollisionFree(bodies, true);
  EXPECT_EQ(std::count(strict.begin(), strict.end(), 1), 0);
}

TEST(MapQueries, EdgeAgainstEdgeNeedsTheCrossAxis)
{
  // Two unit cubes whose edges cross at right angles: a box on its edge (turned 45
  // degrees about x) above one turned 45 degrees about y; their face axes all
  // overlap while their lowest / highest edges are 2 mm apart.
  PlanarGridMap map(mapParams(SpaceState::UNKNOWN));
  const Eigen::Matrix3f below =
    Eigen::AngleAxisf(static_cast<float>(PI / 4), Eigen::Vector3f::UnitY())
      .toRotationMatrix();
  map.integrateSurface({box(Eigen::Vector3f::Zero(), Eigen::Vector3f::Ones(), below)},
                       {}, Cloud(), {});
  const Eigen::Matrix3f above =
    Eigen::AngleAxisf(static_cast<float>(PI / 4), Eigen::Vector3f::UnitX())
      .toRotationMatrix();
  const float reach = std::sqrt(0.5f); // half diagonal of a unit square
  CollisionBodies bodies = {
    CollisionBody::box(Eigen::Vector3f(0, 0, 2 * reach + 0.002f),
                       Eigen::Vector3f::Constant(0.5f), above),
    CollisionBody::box(Eigen::Vector3f(0, 0, 2 * reach - 0.002f),
                       Eigen::Vector3f::Constant(0.5f), above)};
  const auto free = map.isCollisionFree(bodies);
  EXPECT_EQ(free[0], 1);
  EXPECT_EQ(free[1], 0);
}

// ---- oracle on random maps ---------------------------------------------------------

/** A random map: cuboids of random size and rotation (some free: features of
 * probability 0.1 inside), occupied voxels in runs and blobs, free voxels around. */
PlanarGridMap
randomMap(std::mt19937& rng, SpaceState prior)
{
  PlanarGridMap map(mapParams(prior));
  std::uniform_real_distribution<float> u(0.0f, 1.0f);
  PlanarCuboids cuboids;
  Cloud features;
  std::vector<float> probabilities;
  for (int i = 0; i < 25; ++i) {
    const Eigen::Vector3f c(6.0f * u(rng), 6.0f * u(rng), 3.0f * u(rng));
    const Eigen::Vector3f size(0.1f + 1.5f * u(rng), 0.1f + 1.5f * u(rng),
                               0.05f + 0.3f * u(rng));
    cuboids.push_back(box(c, size, randomRotation(rng)));
    if (i % 4 == 0) {
      features.push_back(pcl::PointXYZ(c.x(), c.y(), c.z()));
      probabilities.push_back(0.1f);
    }
  }
  map.integrateSurface(cuboids, {}, features, probabilities);
  auto& space = map.getSpaceLayer();
  // a region seen free (3 x 3 x 1.5 m), so that bodies there are free also with unknown
  // space counted as occupied
  for (int z = 5; z < 20; ++z)
    for (int y = 5; y < 35; ++y)
      for (int x = 5; x < 35; ++x)
        space.setState(Eigen::Vector3i(x, y, z), SpaceState::FREE);
  std::uniform_int_distribution<int> kx(0, 60), kz(0, 30);
  for (int i = 0; i < 400; ++i)
    space.setState(Eigen::Vector3i(kx(rng), kx(rng), kz(rng)), SpaceState::FREE);
  for (int i = 0; i < 60; ++i) {
    const Eigen::Vector3i k(kx(rng), kx(rng), kz(rng));
    const int len = 1 + static_cast<int>(8 * u(rng));
    for (int j = 0; j < len; ++j)
      space.setState(k + Eigen::Vector3i(j, (j * 3) % 2, 0),
                     i % 5 == 0 ? SpaceState::UNKNOWN : SpaceState::OCCUPIED);
  }
  // a solid observed block (a whole 8^3 block) and a free one next to it
  for (int z = 0; z < 8; ++z)
    for (int y = 0; y < 8; ++y)
      for (int x = 0; x < 16; ++x)
        space.setState(Eigen::Vector3i(16 + x, 24 + y, 8 + z),
                       x < 8 ? SpaceState::OCCUPIED : SpaceState::FREE);
  return map;
}

TEST(MapQueries, RandomMapsMatchTheOracle)
{
  std::mt19937 rng(7);
  std::size_t gradients = 0;
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    for (int trial = 0; trial < 2; ++trial) {
      const PlanarGridMap map = randomMap(rng, prior);
      // points and bodies over the map, half of them in the region seen free
      std::uniform_real_distribution<float> u(-1.0f, 8.0f), f(0.5f, 3.5f);
      Eigen::Matrix3Xf points(3, 300);
      for (Eigen::Index i = 0; i < points.cols(); ++i)
        points.col(i) = i % 2 == 0 ? Eigen::Vector3f(u(rng), u(rng), 0.5f * u(rng))
                                   : Eigen::Vector3f(f(rng), f(rng), 0.5f * f(rng));
      for (const bool unknown : {false, true}) {
        expectOracleDistances(map, points, 2.0, unknown, gradients);
        CollisionBodies bodies;
        std::uniform_real_distribution<float> s(0.05f, 0.6f);
        for (int i = 0; i < 300; ++i) {
          const Eigen::Vector3f c = i % 2 == 0
                                      ? Eigen::Vector3f(u(rng), u(rng), 0.5f * u(rng))
                                      : Eigen::Vector3f(f(rng), f(rng), 0.5f * f(rng));
          if (i % 3 == 0)
            bodies.push_back(CollisionBody::sphere(c, s(rng)));
          else
            bodies.push_back(CollisionBody::box(
              c, Eigen::Vector3f(s(rng), s(rng), s(rng)), randomRotation(rng)));
        }
        expectOracleCollisions(map, bodies, unknown);
      }
    }
  }
  EXPECT_GT(gradients, 500u);
}

TEST(MapQueries, ConcurrentReadersAgree)
{
  std::mt19937 rng(3);
  const PlanarGridMap map = randomMap(rng, SpaceState::UNKNOWN);
  std::uniform_real_distribution<float> u(-1.0f, 8.0f);
  Eigen::Matrix3Xf points(3, 2000);
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    points.col(i) = Eigen::Vector3f(u(rng), u(rng), 0.5f * u(rng));
  // the first queries race to build the index
  std::vector<Eigen::VectorXf> results(4, Eigen::VectorXf(points.cols()));
  std::vector<std::thread> threads;
  for (std::size_t t = 0; t < results.size(); ++t)
    threads.emplace_back([&, t] {
      Eigen::Matrix3Xf g(3, points.cols());
      map.getDistance(points, 3.0, results[t], g, t % 2 == 1);
    });
  for (auto& t : threads)
    t.join();
  EXPECT_TRUE(results[0] == results[2]);
  EXPECT_TRUE(results[1] == results[3]);
}

// ---- a real map --------------------------------------------------------------------

/** Karlsruhe frame 10 mapped in a world frame (up = z, camera 1.57 m high, pitched
 * 0.09 rad down, as config/karlsruhe.yaml): the SGBM depth into the space layer and
 * the cuboids of the segmented cloud into the surface layer. */
bool
karlsruheMap(PlanarGridMap& map)
{
  const auto pair = bench::loadKarlsruhePair(10);
  if (!pair.ok)
    return false;
  cv::Mat disparity;
  DisparityEstimator().compute(pair.left, pair.right, disparity);
  Eigen::Matrix3f axes;
  axes << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  Eigen::Affine3f world_T_camera = Eigen::Affine3f::Identity();
  world_T_camera.linear() =
    Eigen::AngleAxisf(-0.09f, Eigen::Vector3f::UnitX()).toRotationMatrix() * axes;
  world_T_camera.translation() = Eigen::Vector3f(0, 0, 1.57f);
  const DepthImage depth =
    DepthImage::fromDisparity(disparity.ptr<float>(0), disparity.cols, disparity.rows,
                              disparity.step, pair.model.calibration);
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = world_T_camera.linear().cast<double>();
  pose.translation() = world_T_camera.translation().cast<double>();
  map.integrateDepthImage(depth, pose);

  pcl::PointCloud<pcl::PointXYZI> dense;
  disparityToPointCloud(disparity, pair.left, pair.model.calibration, 20.0, dense);
  pcl::PointCloud<pcl::PointXYZI>::Ptr finite(new pcl::PointCloud<pcl::PointXYZI>);
  for (const auto& p : dense)
    if (std::isfinite(p.x))
      finite->push_back(p);
  pcl::PointCloud<pcl::PointXYZI>::Ptr moved(new pcl::PointCloud<pcl::PointXYZI>);
  pcl::transformPointCloud(*finite, *moved, world_T_camera);
  pcl::PointCloud<pcl::PointXYZI>::Ptr world(new pcl::PointCloud<pcl::PointXYZI>);
  pcl::VoxelGrid<pcl::PointXYZI> grid;
  grid.setInputCloud(moved);
  grid.setLeafSize(0.1f, 0.1f, 0.1f);
  grid.filter(*world);
  SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
  // Eq. 11 by distance alone, the sample threshold d_T (the class's defaults are
  // the pipeline's normal test and 0.1 m sample threshold).
  seg.setMaxNormalAngle(0.0);
  seg.setMinNormalAgreement(0.0);
  seg.setMinTerrainSensorHeight(0.0);
  seg.setSampleDistanceThreshold(0.05);
  seg.setInputCloud(world);
  seg.setUpAxis(Eigen::Vector3f::UnitZ());
  seg.setDistanceThreshold(0.05);
  seg.setMaxPlanes(8);
  seg.setMinInliers(300);
  seg.setSeed(1);
  PlanarSegments segments;
  seg.segment(segments);
  PlanarCuboidApproximation<pcl::PointXYZI> approx;
  // A non-planar box stops at D_T (the class's 0.25 is the pipeline's).
  approx.setNonPlanarDensityThreshold(0.0);
  approx.setInputCloud(world);
  approx.setPlanes(segments);
  approx.setUpAxis(Eigen::Vector3f::UnitZ());
  approx.setSensorOrigin(world_T_camera.translation());
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  PlaneModels planes;
  for (const auto& s : segments) {
    const auto& v = s.model_coefficients.values;
    planes.emplace_back(v[0], v[1], v[2], v[3]);
  }
  map.integrateSurface(cuboids, planes, Cloud(), {});
  return true;
}

class MapQueriesKarlsruhe : public ::testing::Test {
protected:
  static void SetUpTestSuite()
  {
    map_ = new PlanarGridMap(mapParams(SpaceState::UNKNOWN));
    if (!karlsruheMap(*map_)) {
      delete map_;
      map_ = nullptr;
    }
  }
  static void TearDownTestSuite()
  {
    delete map_;
    map_ = nullptr;
  }
  static PlanarGridMap* map_;
};
PlanarGridMap* MapQueriesKarlsruhe::map_ = nullptr;

TEST_F(MapQueriesKarlsruhe, DistancesAndCollisionsMatchTheOracle)
{
  if (map_ == nullptr)
    GTEST_SKIP() << "Karlsruhe frame 10 missing under " << PLANAR_GRID_DATA_DIR;
  const PlanarGridMap& map = *map_;
  ASSERT_GT(map.getSurfaceLayer().getCuboidCount(), 20u);
  ASSERT_GT(map.getSpaceLayer().getVoxelCount(SpaceState::OCCUPIED), 1000u);
  std::mt19937 rng(11);
  // the street ahead of the camera: x across, y forward, z up
  std::uniform_real_distribution<float> ux(-8.0f, 8.0f), uy(0.0f, 20.0f),
    uz(-0.5f, 3.0f);
  Eigen::Matrix3Xf points(3, 300);
  for (Eigen::Index i = 0; i < points.cols(); ++i)
    points.col(i) = Eigen::Vector3f(ux(rng), uy(rng), uz(rng));
  std::size_t gradients = 0;
  expectOracleDistances(map, points, 3.0, false, gradients);
  EXPECT_GT(gradients, 100u);
  CollisionBodies robots;
  std::uniform_real_distribution<float> yaw(-3.1f, 3.1f);
  for (int i = 0; i < 200; ++i) {
    const Eigen::Matrix3f r =
      Eigen::AngleAxisf(yaw(rng), Eigen::Vector3f::UnitZ()).toRotationMatrix();
    robots.push_back(CollisionBody::box(Eigen::Vector3f(ux(rng), uy(rng), 0.93f),
                                        Eigen::Vector3f(0.5f, 0.3f, 0.75f), r));
  }
  expectOracleCollisions(map, robots, false);
}

// ---- the 2D map --------------------------------------------------------------------

/** A map_server map read back the way map_server reads it (image_loader: the YAML's
 * keys, the image's pixels, p = (255 - value) / 255 with negate 0, row 0 of the image
 * at the top); values -1 / 0 / 100 by the trinary thresholds. */
struct LoadedMap {
  double resolution{0.0};
  double origin_x{0.0}, origin_y{0.0};
  double occupied_thresh{0.0}, free_thresh{0.0};
  int negate{-1};
  std::string image, mode;
  int width{0}, height{0};
  std::vector<int> data; // row 0 = the lowest y, as nav_msgs/OccupancyGrid
};

bool
loadMapServerMap(const std::string& yaml_path, LoadedMap& m)
{
  std::ifstream in(yaml_path);
  if (!in)
    return false;
  std::string line;
  while (std::getline(in, line)) {
    const auto colon = line.find(':');
    if (colon == std::string::npos)
      continue;
    const std::string key = line.substr(0, colon);
    std::string value = line.substr(colon + 1);
    value.erase(0, value.find_first_not_of(' '));
    if (key == "image")
      m.image = value;
    else if (key == "mode")
      m.mode = value;
    else if (key == "resolution")
      m.resolution = std::stod(value);
    else if (key == "negate")
      m.negate = std::stoi(value);
    else if (key == "occupied_thresh")
      m.occupied_thresh = std::stod(value);
    else if (key == "free_thresh")
      m.free_thresh = std::stod(value);
    else if (key == "origin")
      std::sscanf(value.c_str(), "[%lf, %lf", &m.origin_x, &m.origin_y);
  }
  const std::string folder = yaml_path.substr(0, yaml_path.find_last_of('/') + 1);
  std::ifstream pgm(m.image.front() == '/' ? m.image : folder + m.image,
                    std::ios::binary);
  if (!pgm)
    return false;
  std::string magic;
  pgm >> magic;
  if (magic != "P5")
    return false;
  int maxval = 0;
  const auto next = [&]() {
    pgm >> std::ws;
    while (pgm.peek() == '#') {
      std::string comment;
      std::getline(pgm, comment);
      pgm >> std::ws;
    }
    int v = 0;
    pgm >> v;
    return v;
  };
  m.width = next();
  m.height = next();
  maxval = next();
  pgm.get();
  if (maxval != 255)
    return false;
  std::vector<unsigned char> pixels(static_cast<std::size_t>(m.width) * m.height);
  pgm.read(reinterpret_cast<char*>(pixels.data()),
           static_cast<std::streamsize>(pixels.size()));
  if (!pgm)
    return false;
  m.data.assign(pixels.size(), -1);
  for (int row = 0; row < m.height; ++row)
    for (int col = 0; col < m.width; ++col) {
      const unsigned char v =
        pixels[static_cast<std::size_t>(m.height - 1 - row) * m.width + col];
      const double p = (255.0 - v) / 255.0;
      int out = -1;
      if (p > m.occupied_thresh)
        out = 100;
      else if (p < m.free_thresh)
        out = 0;
      m.data[static_cast<std::size_t>(row) * m.width + col] = out;
    }
  return true;
}

std::string
tempFolder()
{
  const std::string dir =
    ::testing::TempDir() + "/map_queries_" + std::to_string(::getpid());
  std::system(("mkdir -p " + dir).c_str());
  return dir;
}

TEST(MapQueries, OccupancyGrid2DReadsBackAsMapServerWould)
{
  PlanarGridMap map(mapParams(SpaceState::UNKNOWN));
  auto& space = map.getSpaceLayer();
  // a 2 x 2 m floor seen free between z 0 and 1 m
  for (int x = 0; x < 20; ++x)
    for (int y = 0; y < 20; ++y)
      for (int z = 0; z < 10; ++z)
        space.setState(Eigen::Vector3i(x, y, z), SpaceState::FREE);
  // an occupied voxel column at cell (5, 7), 0.5 m up
  space.setState(Eigen::Vector3i(5, 7, 5), SpaceState::OCCUPIED);
  // an occupied voxel too low for the band (z 0 .. 0.1) at (8, 8)
  space.setState(Eigen::Vector3i(8, 8, 0), SpaceState::OCCUPIED);
  // a wall cuboid at x 1.5 .. 1.6, y 0.2 .. 0.8, z 0 .. 1.5 (normal along +x)
  PlanarCuboid wall =
    box(Eigen::Vector3f(1.55f, 0.5f, 0.75f), Eigen::Vector3f(0.6f, 1.5f, 0.1f),
        (Eigen::Matrix3f() << 0, 0, 1, 1, 0, 0, 0, 1, 0).finished());
  map.integrateSurface({wall}, {}, Cloud(), {});

  const std::string dir = tempFolder();
  OccupancyGrid2DParams params;
  params.z_ref_m = 0.0;
  params.z_min_m = 0.2;
  params.z_max_m = 2.0;
  const OccupancyGrid2D grid = map.exportOccupancyGrid2D(dir + "/floor.yaml", params);
  LoadedMap loaded;
  ASSERT_TRUE(loadMapServerMap(dir + "/floor.yaml", loaded));
  EXPECT_EQ(loaded.image, "floor.pgm");
  EXPECT_EQ(loaded.mode, "trinary");
  EXPECT_EQ(loaded.negate, 0);
  EXPECT_DOUBLE_EQ(loaded.resolution, 0.1);
  EXPECT_DOUBLE_EQ(loaded.occupied_thresh, 0.65);
  EXPECT_DOUBLE_EQ(loaded.free_thresh, 0.196);
  EXPECT_EQ(loaded.width, grid.width);
  EXPECT_EQ(loaded.height, grid.height);
  const auto cellAt = [&](double x, double y) {
    const int col =
      static_cast<int>(std::floor((x - loaded.origin_x) / loaded.resolution));
    const int row =
      static_cast<int>(std::floor((y - loaded.origin_y) / loaded.resolution));
    EXPECT_TRUE(col >= 0 && col < loaded.width && row >= 0 && row < loaded.height)
      << x << ", " << y;
    return loaded.data[static_cast<std::size_t>(row) * loaded.width + col];
  };
  EXPECT_EQ(cellAt(0.55, 0.75), 100); // the voxel in the band
  EXPECT_EQ(cellAt(0.85, 0.85), 0);   // the low voxel is under the band: free above
  EXPECT_EQ(cellAt(1.05, 1.05), 0);   // free floor
  EXPECT_EQ(cellAt(1.55, 0.5), 100);  // the wall
  EXPECT_EQ(cellAt(1.55, 0.15), 0);   // beside the wall
  EXPECT_EQ(cellAt(2.25, 0.5),
            -1); // beyond the free area (in the stored blocks): unknown
  std::size_t occupied = 0;
  for (const int v : loaded.data)
    occupied += v == 100 ? 1 : 0;
  EXPECT_EQ(occupied, 1u + 6u); // the voxel and the wall's 6 cells
  EXPECT_EQ(grid.count(OccupancyGrid2D::OCCUPIED), occupied);
  EXPECT_EQ(grid.count(OccupancyGrid2D::FREE), 400u - 1u - 6u);

  // a band that starts higher leaves the voxel at 0.5 m out
  params.z_min_m = 0.65;
  EXPECT_EQ(map.computeOccupancyGrid2D(params).count(OccupancyGrid2D::OCCUPIED), 6u);

  // errors: bad names, folders and parameters
  params.z_min_m = 0.2;
  EXPECT_THROW(map.exportOccupancyGrid2D(dir + "/floor.pgm", params), IOError);
  EXPECT_THROW(map.exportOccupancyGrid2D(dir + "/missing/floor.yaml", params), IOError);
  OccupancyGrid2DParams bad = params;
  bad.z_max_m = bad.z_min_m;
  EXPECT_THROW(map.exportOccupancyGrid2D(dir + "/bad.yaml", bad), Exception);
  bad = params;
  bad.free_thresh = 0.9;
  EXPECT_THROW(map.computeOccupancyGrid2D(bad), Exception);
  bad = params;
  bad.resolution_m = -1.0;
  EXPECT_THROW(map.computeOccupancyGrid2D(bad), Exception);
  std::ifstream missing(dir + "/bad.yaml");
  EXPECT_FALSE(missing.good());
  PlanarGridMap empty(mapParams(SpaceState::UNKNOWN));
  EXPECT_THROW(empty.computeOccupancyGrid2D(params), Exception);
}

TEST(MapQueries, SteepTerrainIsAnObstacleAndFlatTerrainIsFloor)
{
  PlanarGridMap map(mapParams(SpaceState::UNKNOWN));
  // two planar cuboids on their own planes: a flat floor patch and a 40 degree ramp,
  // both reaching below the band (z_ref 0, band 0.2 .. 2.0)
  const auto planar = [](const Eigen::Vector3f& c, const Eigen::Vector3f& size,
                         const Eigen::Matrix3f& rot, int id) {
    PlanarCuboid p = box(c, size, rot);
    p.is_planar = true;
    p.plane_id = id;
    return p;
  };
  const Eigen::Matrix3f ramp_rot =
    Eigen::AngleAxisf(static_cast<float>(-40.0 * PI / 180.0), Eigen::Vector3f::UnitY())
      .toRotationMatrix();
  PlanarCuboids cuboids = {planar(Eigen::Vector3f(0.5f, 0.5f, -0.05f),
                                  Eigen::Vector3f(1.0f, 1.0f, 0.1f),
                                  Eigen::Matrix3f::Identity(), 0),
                           planar(Eigen::Vector3f(2.5f, 0.5f, 0.0f),
                                  Eigen::Vector3f(0.8f, 1.0f, 0.1f), ramp_rot, 1)};
  PlaneModels planes;
  for (const auto& c : cuboids)
    planes.emplace_back(c.normal.x(), c.normal.y(), c.normal.z(),
                        -c.normal.dot(c.faceCentre()));
  map.integrateSurface(cuboids, planes, Cloud(), {});
  const auto stored = map.getSurfaceLayer().getCuboids();
  ASSERT_GE(stored.size(), 2u);
  OccupancyGrid2DParams params;
  const OccupancyGrid2D grid = map.computeOccupancyGrid2D(params);
  const auto at = [&](double x, double y) {
    return grid.at(
      static_cast<int>(std::floor((x - grid.origin.x()) / grid.resolution_m)),
      static_cast<int>(std::floor((y - grid.origin.y()) / grid.resolution_m)));
  };
  EXPECT_EQ(at(0.55, 0.55), OccupancyGrid2D::FREE);     // flat floor: walkable
  EXPECT_EQ(at(2.55, 0.55), OccupancyGrid2D::OCCUPIED); // the ramp: too steep
  params.max_slope_rad = 50.0 * PI / 180.0;
  EXPECT_EQ(
    map.computeOccupancyGrid2D(params).at(
      static_cast<int>(std::floor((2.55 - grid.origin.x()) / grid.resolution_m)),
      static_cast<int>(std::floor((0.55 - grid.origin.y()) / grid.resolution_m))),
    OccupancyGrid2D::FREE);
}

} // namespace
} // namespace planar_grid

namespace planar_grid {
namespace {

TEST(MapQueries, BandAboveTheTerrainTheViewsSaw)
{
  // A road seen from above at z 0.3 .. 0.4 (occupied voxels, free above up to 1.3 m)
  // over 4 x 4 m, and a box (a parked car) 1 m high standing on it.
  PlanarGridMap map(mapParams(SpaceState::UNKNOWN));
  auto& space = map.getSpaceLayer();
  for (int x = 0; x < 40; ++x)
    for (int y = 0; y < 40; ++y) {
      space.setState(Eigen::Vector3i(x, y, 3), SpaceState::OCCUPIED);
      const bool car = x >= 10 && x < 20 && y >= 10 && y < 15;
      for (int z = 4; z < 13; ++z)
        space.setState(Eigen::Vector3i(x, y, z),
                       car && z < 14 ? SpaceState::OCCUPIED : SpaceState::FREE);
    }
  OccupancyGrid2DParams params; // band 0.2 .. 2.0 above z 0: the road is in it
  const OccupancyGrid2D fixed = map.computeOccupancyGrid2D(params);
  EXPECT_EQ(fixed.count(OccupancyGrid2D::OCCUPIED), 1600u);
  params.above_terrain = true; // 0.2 .. 2.0 above the road (0.4)
  const OccupancyGrid2D terrain = map.computeOccupancyGrid2D(params);
  EXPECT_EQ(terrain.count(OccupancyGrid2D::OCCUPIED), 50u); // the car
  EXPECT_EQ(terrain.count(OccupancyGrid2D::FREE), 1600u - 50u);
  const auto at = [&](double x, double y) {
    return terrain.at(
      static_cast<int>(std::floor((x - terrain.origin.x()) / terrain.resolution_m)),
      static_cast<int>(std::floor((y - terrain.origin.y()) / terrain.resolution_m)));
  };
  EXPECT_EQ(at(1.55, 1.25), OccupancyGrid2D::OCCUPIED);
  EXPECT_EQ(at(0.55, 0.55), OccupancyGrid2D::FREE);
}

} // namespace
} // namespace planar_grid

namespace planar_grid {
namespace {

TEST(MapQueries, RegionIndexAnswersAsTheWholeMapInsideItsRegion)
{
  std::mt19937 rng(5);
  for (const bool unknown : {false, true}) {
    const PlanarGridMap map = randomMap(rng, SpaceState::UNKNOWN);
    const Eigen::Vector3f lo(1.0f, 1.5f, 0.2f), hi(3.5f, 4.0f, 1.2f);
    const MapRegionIndex region(map, lo, hi, 1.0, unknown);
    EXPECT_GT(region.getObstacleCount(), 0u);
    std::uniform_real_distribution<float> u(0.0f, 1.0f);
    Eigen::Matrix3Xf points(3, 500);
    for (Eigen::Index i = 0; i < points.cols(); ++i)
      points.col(i) =
        lo + Eigen::Vector3f(u(rng), u(rng), u(rng)).cwiseProduct(hi - lo);
    points.col(0) = Eigen::Vector3f(5.0f, 5.0f, 0.5f); // outside
    Eigen::VectorXf d(points.cols()), whole(points.cols());
    Eigen::Matrix3Xf g(3, points.cols()), whole_g(3, points.cols());
    region.getDistance(points, d, g);
    map.getDistance(points, 1.0, whole, whole_g, unknown);
    EXPECT_TRUE(std::isnan(d[0]));
    for (Eigen::Index i = 1; i < points.cols(); ++i) {
      ASSERT_NEAR(d[i], whole[i], 1e-6f) << i;
      if (whole[i] > 1e-4f && whole[i] < 1.0f) {
        EXPECT_GT(g.col(i).dot(whole_g.col(i)), 0.9998f) << i;
      }
    }
    CollisionBodies bodies;
    for (int i = 0; i < 200; ++i)
      bodies.push_back(CollisionBody::box(
        lo + Eigen::Vector3f(u(rng), u(rng), u(rng)).cwiseProduct(hi - lo),
        Eigen::Vector3f::Constant(0.3f * u(rng)), randomRotation(rng)));
    EXPECT_EQ(region.isCollisionFree(bodies), map.isCollisionFree(bodies, unknown));
    // a body reaching beyond the region grown by the cap is not known free
    const CollisionBodies far = {CollisionBody::sphere(hi, 1.5f)};
    EXPECT_EQ(region.isCollisionFree(far)[0], 0);
  }
  PlanarGridMap empty(mapParams(SpaceState::FREE));
  EXPECT_THROW(
    MapRegionIndex(empty, Eigen::Vector3f::Ones(), Eigen::Vector3f::Zero(), 1.0),
    Exception);
  EXPECT_THROW(
    MapRegionIndex(empty, Eigen::Vector3f::Zero(), Eigen::Vector3f::Ones(), 0.0),
    Exception);
}

} // namespace
} // namespace planar_grid

namespace planar_grid {
namespace {

TEST(MapQueries, ForEachVoxelInVisitsExactlyTheVoxelsOfOneState)
{
  std::mt19937 rng(9);
  for (const SpaceState prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    const PlanarGridMap map = randomMap(rng, prior);
    const ExplicitSpaceGrid& space = map.getSpaceLayer();
    for (const SpaceState state :
         {SpaceState::FREE, SpaceState::OCCUPIED, SpaceState::UNKNOWN}) {
      std::vector<Eigen::Vector3i> all, in;
      space.forEachVoxel([&](const Eigen::Vector3i& k, SpaceState s) {
        if (s == state)
          all.push_back(k);
      });
      space.forEachVoxelIn(state, [&](const Eigen::Vector3i& k) { in.push_back(k); });
      EXPECT_EQ(in, all) << toString(state) << " prior " << toString(prior);
      EXPECT_EQ(in.size(), space.getVoxelCount(state));
    }
  }
}

} // namespace
} // namespace planar_grid
