// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/plane_registry.h>

#include <pcl/filters/uniform_sampling.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <tuple>
#include <vector>

namespace {

using planar_grid::PlaneRegistry;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** Coefficients [a, b, c, d] as a pcl::ModelCoefficients. */
pcl::ModelCoefficients
coefficients(float a, float b, float c, float d)
{
  pcl::ModelCoefficients m;
  m.values = {a, b, c, d};
  return m;
}

/** Appends \a n points of \a cloud (at (x0 + 0.01 k, y, z)) to \a inliers. */
void
addPoints(Cloud& cloud, pcl::PointIndices& inliers, int n, float x0, float y, float z)
{
  for (int k = 0; k < n; ++k) {
    inliers.indices.push_back(static_cast<int>(cloud.size()));
    cloud.push_back(pcl::PointXYZ(x0 + 0.01f * static_cast<float>(k), y, z));
  }
}

/** The points of a labelled cloud as sorted (x, y, z, label) tuples. */
std::vector<std::tuple<float, float, float, std::uint32_t>>
sortedPoints(const PlaneRegistry::PointCloud& cloud)
{
  std::vector<std::tuple<float, float, float, std::uint32_t>> out;
  for (const auto& p : cloud.points)
    out.emplace_back(p.x, p.y, p.z, p.label);
  std::sort(out.begin(), out.end());
  return out;
}

/** A registry that keeps every point (no downsampling), 0.1 rad and 0.2 m. */
PlaneRegistry::Params
keepEveryPoint()
{
  PlaneRegistry::Params params;
  params.eps_angle_rad = 0.1;
  params.distance_threshold_m = 0.2;
  params.leaf_size_m = 0.0;
  return params;
}

} // namespace

// Two frames of a wall and a floor: the first frame registers them as planes 0 and 1;
// in the second frame the wall, turned by 0.05 rad, 0.1 m further and fitted with its
// normal the other way, and the floor, 0.05 m higher, join them, each model becoming
// the inlier-weighted mean of the two views (computed here in double) and each count
// the sum; a third plane, a side wall, starts plane 2. The inlier cloud holds every
// inlier with its run-wide id.
TEST(PlaneRegistry, KnownPlanesGetRunWideIdsAndInlierWeightedModels)
{
  PlaneRegistry registry(keepEveryPoint());
  Cloud frame1;
  std::vector<pcl::ModelCoefficients> models1 = {coefficients(0.0f, 1.0f, 0.0f, -4.0f),
                                                 coefficients(0.0f, 0.0f, 1.0f, 0.0f)};
  std::vector<pcl::PointIndices> inliers1(2);
  addPoints(frame1, inliers1[0], 30, 0.0f, 4.0f, 1.0f); // wall y = 4
  addPoints(frame1, inliers1[1], 10, 0.0f, 2.0f, 0.0f); // floor z = 0
  std::vector<int> ids;
  registry.addPlanes(frame1, models1, inliers1, ids);
  EXPECT_EQ(ids, (std::vector<int>{0, 1}));

  // The wall as the second frame sees it: n = (-sin 0.05, -cos 0.05, 0), d = 4.1 (the
  // plane y cos 0.05 + x sin 0.05 = 4.1 with its normal turned towards the origin).
  const double a = 0.05;
  Cloud frame2;
  std::vector<pcl::ModelCoefficients> models2 = {
    coefficients(static_cast<float>(-std::sin(a)), static_cast<float>(-std::cos(a)),
                 0.0f, 4.1f),
    coefficients(0.0f, 0.0f, 1.0f, -0.05f), coefficients(1.0f, 0.0f, 0.0f, -6.0f)};
  std::vector<pcl::PointIndices> inliers2(3);
  addPoints(frame2, inliers2[0], 10, 1.0f, 4.1f, 1.0f);
  addPoints(frame2, inliers2[1], 30, 1.0f, 2.0f, 0.05f);
  addPoints(frame2, inliers2[2], 5, 6.0f, 1.0f, 1.0f);
  registry.addPlanes(frame2, models2, inliers2, ids);
  EXPECT_EQ(ids, (std::vector<int>{0, 1, 2}));
  ASSERT_EQ(registry.size(), 3u);

  // The wall: (30 (0, 1, 0, -4) + 10 (sin a, cos a, 0, -4.1)) / 40, the second view
  // flipped to the first one's side, then the normal made unit.
  Eigen::Vector4d wall = (30.0 * Eigen::Vector4d(0.0, 1.0, 0.0, -4.0)
                          + 10.0 * Eigen::Vector4d(std::sin(a), std::cos(a), 0.0, -4.1))
                         / 40.0;
  wall /= wall.head<3>().norm();
  // The floor: (10 (0, 0, 1, 0) + 30 (0, 0, 1, -0.05)) / 40 = (0, 0, 1, -0.0375).
  const Eigen::Vector4d floor(0.0, 0.0, 1.0, -0.0375);
  // The models are single precision: a few units in the last place of 4 m.
  const auto& models = registry.getModelCoefficients();
  for (int c = 0; c < 4; ++c) {
    EXPECT_NEAR(models[0][c], wall[c], 4e-6) << c;
    EXPECT_NEAR(models[1][c], floor[c], 4e-6) << c;
  }
  EXPECT_EQ(models[2], Eigen::Vector4f(1.0f, 0.0f, 0.0f, -6.0f));
  EXPECT_EQ(registry.getInlierCounts(), (std::vector<std::size_t>{40, 40, 5}));

  // 30 + 10 + 10 + 30 + 5 inliers, each with its plane's id
  std::vector<std::tuple<float, float, float, std::uint32_t>> expected;
  const auto add = [&expected](const Cloud& cloud, const pcl::PointIndices& in,
                               std::uint32_t id) {
    for (const int i : in.indices) {
      const auto& p = cloud[static_cast<std::size_t>(i)];
      expected.emplace_back(p.x, p.y, p.z, id);
    }
  };
  add(frame1, inliers1[0], 0);
  add(frame1, inliers1[1], 1);
  add(frame2, inliers2[0], 0);
  add(frame2, inliers2[1], 1);
  add(frame2, inliers2[2], 2);
  std::sort(expected.begin(), expected.end());
  EXPECT_EQ(registry.getInlierCloud().size(), 85u);
  EXPECT_EQ(sortedPoints(registry.getInlierCloud()), expected);
}

// A plane whose normal is within eps_angle_rad (0.1) of a registered plane's, either
// way round, joins it; one just beyond starts a new plane. The offsets are equal.
TEST(PlaneRegistry, AngleBoundaryBothSides)
{
  for (const double angle : {0.099, -0.099, 0.101, -0.101}) {
    for (const bool flipped : {false, true}) {
      SCOPED_TRACE(testing::Message() << angle << (flipped ? " flipped" : ""));
      PlaneRegistry registry(keepEveryPoint());
      ASSERT_EQ(registry.associate(Eigen::Vector4f(1.0f, 0.0f, 0.0f, -2.0f), 10), 0);
      Eigen::Vector4f observed(static_cast<float>(std::cos(angle)),
                               static_cast<float>(std::sin(angle)), 0.0f, -2.0f);
      if (flipped)
        observed = -observed;
      const int expected = std::abs(angle) < 0.1 ? 0 : 1;
      EXPECT_EQ(registry.associate(observed, 10), expected);
      EXPECT_EQ(registry.size(), static_cast<std::size_t>(expected + 1));
    }
  }
}

// A plane whose offset d is within distance_threshold_m (0.2 m) of a registered
// plane's joins it; one just beyond starts a new plane. The normals are equal.
TEST(PlaneRegistry, DistanceBoundaryBothSides)
{
  for (const float offset : {0.19f, -0.19f, 0.21f, -0.21f}) {
    SCOPED_TRACE(offset);
    PlaneRegistry registry(keepEveryPoint());
    ASSERT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.0f), 10), 0);
    const int expected = std::abs(offset) < 0.2f ? 0 : 1;
    EXPECT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.0f + offset), 10),
              expected);
    EXPECT_EQ(registry.size(), static_cast<std::size_t>(expected + 1));
  }
  // The nearest offset wins: d = -1.2 joins plane 1 (-1.3, 0.1 m away; plane 0 is
  // 0.2 m away), which becomes -1.25; d = -1.1 is within 0.2 m of both (0.1 m and
  // 0.15 m) and joins plane 0, which becomes -1.05.
  PlaneRegistry registry(keepEveryPoint());
  ASSERT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.0f), 10), 0);
  ASSERT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.3f), 10), 1);
  EXPECT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.2f), 10), 1);
  EXPECT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.1f), 10), 0);
  // Parameters other than the defaults: with 0.5 m, d = -1.7 joins plane 1 (-1.25,
  // 0.45 m away; plane 0 is 0.65 m away).
  PlaneRegistry::Params wide = keepEveryPoint();
  wide.distance_threshold_m = 0.5;
  registry.setParams(wide);
  EXPECT_EQ(registry.associate(Eigen::Vector4f(0.0f, 0.0f, 1.0f, -1.7f), 10), 1);
}

// The window keeps exactly the points within the half-size of the sensor in x and y,
// at every height, the box's faces included: a 13 x 13 lattice of 0.5 m at two heights
// around a sensor at (0.5, 0.5) with a 1 m half-size keeps x, y in
// {-0.5, 0, 0.5, 1, 1.5}, 5 x 5 x 2 = 50 points, in their order.
TEST(PlaneRegistry, CropToWindowKeepsExactlyThePointsInside)
{
  PlaneRegistry registry(keepEveryPoint());
  Cloud cloud;
  pcl::PointIndices inliers;
  std::vector<pcl::PointXYZ> expected;
  for (const float z : {0.0f, 7.0f})
    for (int i = -6; i <= 6; ++i)
      for (int j = -6; j <= 6; ++j) {
        const pcl::PointXYZ p(0.5f * static_cast<float>(i),
                              0.5f * static_cast<float>(j), z);
        inliers.indices.push_back(static_cast<int>(cloud.size()));
        cloud.push_back(p);
        if (i >= -1 && i <= 3 && j >= -1 && j <= 3)
          expected.push_back(p);
      }
  ASSERT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), inliers), 0);
  registry.cropToWindow(Eigen::Vector3d(0.5, 0.5, 100.0), 1.0);
  const auto& kept = registry.getInlierCloud();
  ASSERT_EQ(kept.size(), 50u);
  ASSERT_EQ(expected.size(), 50u);
  EXPECT_EQ(kept.width, 50u);
  EXPECT_EQ(kept.height, 1u);
  for (std::size_t k = 0; k < kept.size(); ++k) {
    EXPECT_EQ(kept[k].getVector3fMap(), expected[k].getVector3fMap()) << k;
    EXPECT_EQ(kept[k].label, 0u);
  }
  // the plane stays registered
  EXPECT_EQ(registry.size(), 1u);
  EXPECT_EQ(registry.getInlierCounts()[0], cloud.size());
}

// One point per voxel of 1 m, the one nearest the voxel's centre, whatever the order
// the points come in and the frame they come from: voxel (0, 0, 0) (centre
// (0.5, 0.5, 0.5)) first keeps (0.45, 0.55, 0.5), at 0.07 m from its centre, then
// (0.5, 0.5, 0.52) of a later frame, at 0.02 m; voxel (-1, 2, 0) (centre
// (-0.5, 2.5, 0.5)) keeps (-0.4, 2.6, 0.4); a non-finite point goes. Labels are those
// of the points kept, never mixed.
TEST(PlaneRegistry, DownsampleKeepsThePointNearestEachLeafCentre)
{
  PlaneRegistry::Params params = keepEveryPoint();
  params.leaf_size_m = 1.0;
  PlaneRegistry registry(params);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  Cloud frame1;
  frame1.push_back(pcl::PointXYZ(0.1f, 0.1f, 0.1f));   // voxel (0, 0, 0)
  frame1.push_back(pcl::PointXYZ(0.45f, 0.55f, 0.5f)); // voxel (0, 0, 0), nearest
  frame1.push_back(pcl::PointXYZ(0.9f, 0.9f, 0.9f));   // voxel (0, 0, 0)
  frame1.push_back(pcl::PointXYZ(-0.9f, 2.1f, 0.2f));  // voxel (-1, 2, 0)
  frame1.push_back(pcl::PointXYZ(-0.4f, 2.6f, 0.4f));  // voxel (-1, 2, 0), nearest
  frame1.push_back(pcl::PointXYZ(nan, nan, nan));      // goes
  pcl::PointIndices floor, wall;
  floor.indices = {0, 2, 3, 5};
  wall.indices = {1, 4};
  ASSERT_EQ(registry.addPlane(frame1, coefficients(0.0f, 0.0f, 1.0f, 0.0f), floor), 0);
  ASSERT_EQ(registry.addPlane(frame1, coefficients(1.0f, 0.0f, 0.0f, 0.0f), wall), 1);
  registry.downsample();
  using Point = std::tuple<float, float, float, std::uint32_t>;
  EXPECT_EQ(sortedPoints(registry.getInlierCloud()),
            (std::vector<Point>{{-0.4f, 2.6f, 0.4f, 1u}, {0.45f, 0.55f, 0.5f, 1u}}));
  EXPECT_TRUE(registry.getInlierCloud().is_dense);

  Cloud frame2;
  frame2.push_back(pcl::PointXYZ(0.5f, 0.5f, 0.52f));   // voxel (0, 0, 0), nearer
  frame2.push_back(pcl::PointXYZ(-0.95f, 2.05f, 0.9f)); // voxel (-1, 2, 0), farther
  frame2.push_back(pcl::PointXYZ(3.2f, -0.7f, 5.5f));   // voxel (3, -1, 5), new
  pcl::PointIndices all;
  all.indices = {0, 1, 2};
  ASSERT_EQ(registry.addPlane(frame2, coefficients(0.0f, 0.0f, 1.0f, 0.0f), all), 0);
  registry.downsample();
  EXPECT_EQ(sortedPoints(registry.getInlierCloud()),
            (std::vector<Point>{{-0.4f, 2.6f, 0.4f, 1u},
                                {0.5f, 0.5f, 0.52f, 0u},
                                {3.2f, -0.7f, 5.5f, 0u}}));
  // the planes' weights are the inliers given, not the points kept
  EXPECT_EQ(registry.getInlierCounts(), (std::vector<std::size_t>{7, 2}));
}

// Oracle: downsampling after every frame (each time visiting only the new points)
// gives pcl::UniformSampling's output over every inlier of every frame, for random
// planes of points on a 2 cm lattice with jitter (several candidates per 0.1 m voxel).
TEST(PlaneRegistry, IncrementalDownsampleMatchesUniformSampling)
{
  PlaneRegistry::Params params = keepEveryPoint();
  params.leaf_size_m = 0.1;
  PlaneRegistry registry(params);
  pcl::PointCloud<pcl::PointXYZL>::Ptr all(new pcl::PointCloud<pcl::PointXYZL>);
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> along(-2.0f, 2.0f), jitter(-0.003f, 0.003f);
  for (int f = 0; f < 6; ++f) {
    Cloud cloud;
    pcl::PointIndices inliers;
    for (int i = 0; i < 500; ++i) {
      const float u = std::round(along(rng) * 50.0f) / 50.0f + jitter(rng);
      const float w = std::round(along(rng) * 50.0f) / 50.0f + jitter(rng);
      inliers.indices.push_back(static_cast<int>(cloud.size()));
      cloud.push_back(pcl::PointXYZ(u, w, 1.0f));
    }
    const int id =
      registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, -1.0f), inliers);
    ASSERT_EQ(id, 0);
    for (const auto& p : cloud.points) {
      pcl::PointXYZL q;
      q.getVector3fMap() = p.getVector3fMap();
      q.label = 0;
      all->push_back(q);
    }
    registry.downsample();
    pcl::UniformSampling<pcl::PointXYZL> sampling;
    sampling.setRadiusSearch(0.1);
    sampling.setInputCloud(all);
    pcl::PointCloud<pcl::PointXYZL> expected;
    sampling.filter(expected);
    EXPECT_EQ(sortedPoints(registry.getInlierCloud()), sortedPoints(expected)) << f;
  }
}

// Degenerate input registers nothing: coefficients not four, a non-finite or zero
// normal, an inlier outside the cloud, vectors of different lengths; an empty cloud
// with no inliers is a plane of weight 0.
TEST(PlaneRegistry, DegenerateInputRegistersNothing)
{
  PlaneRegistry registry(keepEveryPoint());
  Cloud cloud;
  cloud.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));
  pcl::PointIndices one;
  one.indices = {0};
  pcl::ModelCoefficients three;
  three.values = {0.0f, 0.0f, 1.0f};
  EXPECT_EQ(registry.addPlane(cloud, three, one), -1);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  EXPECT_EQ(registry.addPlane(cloud, coefficients(nan, 0.0f, 1.0f, 0.0f), one), -1);
  EXPECT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 0.0f, 1.0f), one), -1);
  pcl::PointIndices outside;
  outside.indices = {0, 1};
  EXPECT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), outside),
            -1);
  outside.indices = {-1};
  EXPECT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), outside),
            -1);
  std::vector<int> ids{5};
  registry.addPlanes(cloud, {coefficients(0.0f, 0.0f, 1.0f, 0.0f)}, {}, ids);
  EXPECT_TRUE(ids.empty());
  EXPECT_TRUE(registry.empty());
  EXPECT_TRUE(registry.getInlierCloud().empty());
  EXPECT_TRUE(registry.getInlierCounts().empty());

  EXPECT_EQ(registry.addPlane(Cloud(), coefficients(0.0f, 0.0f, 1.0f, 0.0f),
                              pcl::PointIndices()),
            0);
  EXPECT_EQ(registry.getInlierCounts(), (std::vector<std::size_t>{0}));
  registry.downsample(); // a leaf size of 0 keeps everything, an empty cloud is fine
  registry.cropToWindow(Eigen::Vector3d::Zero(), 0.0);
  EXPECT_TRUE(registry.getInlierCloud().empty());
  registry.clear();
  EXPECT_TRUE(registry.empty());
}

// Parameters out of their ranges are rejected, and the registry keeps its own.
TEST(PlaneRegistry, InvalidParametersThrow)
{
  for (const auto& [angle, distance, leaf] :
       std::vector<std::tuple<double, double, double>>{{-0.1, 0.2, 0.1},
                                                       {1.6, 0.2, 0.1},
                                                       {0.1, -0.01, 0.1},
                                                       {0.1, 11.0, 0.1},
                                                       {0.1, 0.2, -1.0},
                                                       {0.1, 0.2, 20.0},
                                                       {std::nan(""), 0.2, 0.1}}) {
    PlaneRegistry::Params params;
    params.eps_angle_rad = angle;
    params.distance_threshold_m = distance;
    params.leaf_size_m = leaf;
    EXPECT_THROW(PlaneRegistry{params}, planar_grid::Exception);
    PlaneRegistry registry;
    EXPECT_THROW(registry.setParams(params), planar_grid::Exception);
    EXPECT_EQ(registry.getParams().eps_angle_rad,
              PlaneRegistry::Params().eps_angle_rad);
    EXPECT_EQ(registry.getParams().leaf_size_m, PlaneRegistry::Params().leaf_size_m);
  }
}

// setPlanes() restores what the accessors give (a checkpoint's round trip), and the
// restored registry goes on as the original: the next plane joins the same plane and
// the next downsampling keeps the same points. Inconsistent state is refused.
TEST(PlaneRegistry, SetPlanesRoundTrip)
{
  PlaneRegistry::Params params = keepEveryPoint();
  params.leaf_size_m = 0.5;
  PlaneRegistry original(params);
  Cloud cloud;
  pcl::PointIndices a, b;
  addPoints(cloud, a, 120, 0.0f, 3.0f, 1.0f);
  addPoints(cloud, b, 80, 0.0f, 1.0f, 0.0f);
  original.addPlane(cloud, coefficients(0.0f, 1.0f, 0.0f, -3.0f), a);
  original.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), b);
  original.downsample();
  original.addPlane(cloud, coefficients(0.0f, 1.0f, 0.0f, -3.05f), a);

  PlaneRegistry restored(params);
  restored.setPlanes(original.getModelCoefficients(), original.getInlierCounts(),
                     original.getInlierCloud());
  EXPECT_EQ(restored.getModelCoefficients(), original.getModelCoefficients());
  EXPECT_EQ(restored.getInlierCounts(), original.getInlierCounts());
  EXPECT_EQ(sortedPoints(restored.getInlierCloud()),
            sortedPoints(original.getInlierCloud()));
  const Eigen::Vector4f next(0.0f, 0.0f, 1.0f, 0.1f);
  EXPECT_EQ(restored.associate(next, 10), original.associate(next, 10));
  EXPECT_EQ(restored.getModelCoefficients(), original.getModelCoefficients());
  original.downsample();
  restored.downsample();
  EXPECT_EQ(sortedPoints(restored.getInlierCloud()),
            sortedPoints(original.getInlierCloud()));

  PlaneRegistry::PointCloud labelled;
  pcl::PointXYZL p;
  p.label = 2;
  labelled.push_back(p);
  EXPECT_THROW(restored.setPlanes(original.getModelCoefficients(),
                                  original.getInlierCounts(), labelled),
               planar_grid::Exception);
  EXPECT_THROW(restored.setPlanes(original.getModelCoefficients(), {1},
                                  PlaneRegistry::PointCloud()),
               planar_grid::Exception);
  EXPECT_EQ(restored.size(), 2u); // unchanged
}

// A new leaf size applies to every point at the next downsampling: (0.9, 0.9, 0.9),
// kept alone in voxel (0, 0, 0) of a 1 m leaf, lies in voxel (1, 1, 1) of a 0.5 m leaf,
// so a later (0.1, 0.1, 0.1), in voxel (0, 0, 0), does not replace it; both stay. The
// planes stay registered.
TEST(PlaneRegistry, NewLeafSizeAppliesToEveryPoint)
{
  PlaneRegistry::Params params = keepEveryPoint();
  params.leaf_size_m = 1.0;
  PlaneRegistry registry(params);
  Cloud cloud;
  cloud.push_back(pcl::PointXYZ(0.9f, 0.9f, 0.9f));
  pcl::PointIndices first;
  first.indices = {0};
  ASSERT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), first), 0);
  registry.downsample();
  ASSERT_EQ(registry.getInlierCloud().size(), 1u);

  params.leaf_size_m = 0.5;
  registry.setParams(params);
  EXPECT_EQ(registry.getParams().leaf_size_m, 0.5);
  EXPECT_EQ(registry.size(), 1u);
  cloud.push_back(pcl::PointXYZ(0.1f, 0.1f, 0.1f));
  pcl::PointIndices second;
  second.indices = {1};
  ASSERT_EQ(registry.addPlane(cloud, coefficients(0.0f, 0.0f, 1.0f, 0.0f), second), 0);
  registry.downsample();
  using Point = std::tuple<float, float, float, std::uint32_t>;
  EXPECT_EQ(sortedPoints(registry.getInlierCloud()),
            (std::vector<Point>{{0.1f, 0.1f, 0.1f, 0u}, {0.9f, 0.9f, 0.9f, 0u}}));
}
