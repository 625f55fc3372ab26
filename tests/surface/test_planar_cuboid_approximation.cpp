// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_plane.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <vector>

namespace {

/** The paper's splitting, which these tests were written for: a non-planar box stops at
 * D_T. The class's default (0.25) is the pipeline's. */
planar_grid::PlanarCuboidApproximationParams
paperParams()
{
  planar_grid::PlanarCuboidApproximationParams params;
  params.non_planar_density_threshold = 0.0;
  return params;
}

using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboidApproximation;
using planar_grid::PlanarCuboids;
using planar_grid::PlanarSegment;
using planar_grid::PlanarSegments;

constexpr double DEG = M_PI / 180.0;

template <typename PointT>
PointT
makePoint(const Eigen::Vector3f& p)
{
  PointT q;
  q.x = p.x();
  q.y = p.y();
  q.z = p.z();
  return q;
}

/** A planar patch in the frame (corner, h, v): the truth of the tests. */
struct Patch {
  Eigen::Vector3f corner;
  Eigen::Vector3f h; // unit, horizontal (perpendicular to up)
  Eigen::Vector3f v; // unit, in-plane, perpendicular to h
  Eigen::Vector3f normal() const { return h.cross(v).normalized(); }
  Eigen::Vector3f at(float s, float t) const { return corner + h * s + v * t; }
  /** (s, t) of a point, its coordinates along h and v. */
  Eigen::Vector2f local(const Eigen::Vector3f& p) const
  {
    return {h.dot(p - corner), v.dot(p - corner)};
  }
};

/** Wall of width x height m with up = z, rotated by yaw about z and leaning back by
 * tilt from vertical, its corner at (-1, 5, 0.5) (in front of the sensor at 0). */
Patch
wall(double yaw_rad, double tilt_rad)
{
  const Eigen::Vector3f up = Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f h(static_cast<float>(std::cos(yaw_rad)),
                          static_cast<float>(std::sin(yaw_rad)), 0.0f);
  const Eigen::Vector3f away = up.cross(h); // horizontal, away from the sensor
  const Eigen::Vector3f v = static_cast<float>(std::cos(tilt_rad)) * up
                            + static_cast<float>(std::sin(tilt_rad)) * away;
  return Patch{Eigen::Vector3f(-1.0f, 5.0f, 0.5f), h, v.normalized()};
}

/** Uniform random points with density `per_m2` on the patch where keep(s, t), (s, t) in
 * [0, w] x [0, h], plus Gaussian noise sigma_m along the normal. Returns the indices.
 */
template <typename PointT, typename Keep>
std::vector<int>
addRandomPatch(pcl::PointCloud<PointT>& cloud,
               const Patch& patch,
               float w,
               float h,
               double per_m2,
               double sigma_m,
               std::mt19937& rng,
               Keep keep)
{
  std::uniform_real_distribution<float> us(0.0f, w), ut(0.0f, h);
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma_m));
  const auto count = static_cast<int>(per_m2 * w * h);
  std::vector<int> indices;
  for (int k = 0; k < count; ++k) {
    const float s = us(rng), t = ut(rng);
    if (!keep(s, t))
      continue;
    indices.push_back(static_cast<int>(cloud.size()));
    cloud.push_back(makePoint<PointT>(patch.at(s, t) + patch.normal() * noise(rng)));
  }
  return indices;
}

/** Grid-sampled wall (spacing_m) with isotropic Gaussian noise sigma_m (3D). */
template <typename PointT>
std::vector<int>
addGridWall(pcl::PointCloud<PointT>& cloud,
            const Patch& patch,
            float w,
            float h,
            float spacing_m,
            double sigma_m,
            std::mt19937& rng)
{
  std::normal_distribution<float> noise(0.0f, static_cast<float>(sigma_m));
  std::vector<int> indices;
  const int ns = static_cast<int>(std::lround(w / spacing_m));
  const int nt = static_cast<int>(std::lround(h / spacing_m));
  for (int i = 0; i <= ns; ++i)
    for (int j = 0; j <= nt; ++j) {
      const Eigen::Vector3f n(noise(rng), noise(rng), noise(rng));
      indices.push_back(static_cast<int>(cloud.size()));
      cloud.push_back(makePoint<PointT>(patch.at(i * spacing_m, j * spacing_m) + n));
    }
  return indices;
}

PlanarSegment
segmentOf(const Patch& patch, const std::vector<int>& inliers)
{
  PlanarSegment segment;
  const Eigen::Vector3f n = patch.normal();
  segment.model_coefficients.values = {n.x(), n.y(), n.z(), -n.dot(patch.corner)};
  segment.inliers.indices.assign(inliers.begin(), inliers.end());
  return segment;
}

template <typename PointT>
std::size_t
countUncovered(const pcl::PointCloud<PointT>& cloud,
               const PlanarCuboids& cuboids,
               float tolerance_m)
{
  std::size_t uncovered = 0;
  for (const auto& p : cloud) {
    if (!std::isfinite(p.x))
      continue;
    const Eigen::Vector3f q = p.getVector3fMap();
    bool inside = false;
    for (const auto& c : cuboids)
      if (c.contains(q, tolerance_m)) {
        inside = true;
        break;
      }
    uncovered += inside ? 0 : 1;
  }
  return uncovered;
}

/** Face extent of a planar cuboid in the patch's (s, t) frame: (s0, t0, s1, t1). */
Eigen::Vector4f
faceInPatch(const PlanarCuboid& c, const Patch& patch)
{
  Eigen::Vector4f box(
    std::numeric_limits<float>::max(), std::numeric_limits<float>::max(),
    -std::numeric_limits<float>::max(), -std::numeric_limits<float>::max());
  for (const auto& corner : c.face()) {
    const Eigen::Vector2f st = patch.local(corner);
    box.head<2>() = box.head<2>().cwiseMin(st);
    box.tail<2>() = box.tail<2>().cwiseMax(st);
  }
  return box;
}

float
overlap1D(float a0, float a1, float b0, float b1)
{
  return std::max(0.0f, std::min(a1, b1) - std::max(a0, b0));
}

// --- PlanarCuboid ----------------------------------------------------------------

TEST(PlanarCuboid, CornersVolumeAndContains)
{
  PlanarCuboid c;
  c.centre = Eigen::Vector3f(1, 2, 3);
  c.normal = Eigen::Vector3f::UnitY();
  c.horizontal_axis = Eigen::Vector3f::UnitX();
  c.width_m = 2.0f;
  c.height_m = 1.0f;
  c.thickness_m = 0.5f;
  // vertical = y x x = -z
  EXPECT_NEAR((c.verticalAxis() - Eigen::Vector3f(0, 0, -1)).norm(), 0.0f, 1e-6f);
  EXPECT_FLOAT_EQ(c.volume(), 1.0f);
  EXPECT_FLOAT_EQ(c.faceArea(), 2.0f);
  EXPECT_NEAR((c.faceCentre() - Eigen::Vector3f(1, 2.25f, 3)).norm(), 0.0f, 1e-6f);
  const auto corners = c.corners();
  for (const auto& k : corners) {
    EXPECT_NEAR(std::abs(k.x() - 1.0f), 1.0f, 1e-6f);
    EXPECT_NEAR(std::abs(k.y() - 2.0f), 0.25f, 1e-6f);
    EXPECT_NEAR(std::abs(k.z() - 3.0f), 0.5f, 1e-6f);
    EXPECT_TRUE(c.contains(k, 1e-5f));
  }
  // the first four corners are the face (front, +normal side)
  for (int k = 0; k < 4; ++k)
    EXPECT_NEAR(corners[k].y(), 2.25f, 1e-6f);
  EXPECT_TRUE(c.contains(c.centre));
  EXPECT_FALSE(c.contains(Eigen::Vector3f(1, 2.3f, 3)));
  EXPECT_TRUE(c.contains(Eigen::Vector3f(1, 2.3f, 3), 0.06f));
  EXPECT_FALSE(c.contains(Eigen::Vector3f(2.1f, 2, 3)));
  EXPECT_FALSE(c.contains(Eigen::Vector3f(NAN, 2, 3)));
}

// --- PlanarCuboidApproximation ----------------------------------------------------

template <typename PointT>
class PlanarCuboidApproximationTyped : public testing::Test {};
using PointTypes = testing::Types<pcl::PointXYZ, pcl::PointXYZI, pcl::PointXYZRGB>;
TYPED_TEST_SUITE(PlanarCuboidApproximationTyped, PointTypes);

// A 4 m x 2.5 m wall leaning back 30 deg (yaw 25 deg), sampled on a 0.02 m grid with
// 0.005 m isotropic noise, its true plane given. All 41 x 26 raster cells of 0.1 m are
// occupied (25 points per cell), so the quadtree covers exactly the bounding
// rectangle and the merge gives ONE cuboid; the same wall axis-aligned and upright
// gives the same count (the paper's point against axis-aligned cuboids).
TYPED_TEST(PlanarCuboidApproximationTyped, TiltedWallIsOneCuboid)
{
  for (const bool tilted : {true, false}) {
    const Patch patch = tilted ? wall(25 * DEG, 30 * DEG) : wall(0.0, 0.0);
    typename pcl::PointCloud<TypeParam>::Ptr cloud(new pcl::PointCloud<TypeParam>);
    std::mt19937 rng(1);
    const auto inliers = addGridWall(*cloud, patch, 4.0f, 2.5f, 0.02f, 0.005, rng);
    PlanarCuboidApproximation<TypeParam> approx(paperParams());
    approx.setInputCloud(cloud);
    approx.setPlanes(PlanarSegments{segmentOf(patch, inliers)});
    PlanarCuboids cuboids;
    approx.approximate(cuboids);
    ASSERT_EQ(cuboids.size(), 1u) << (tilted ? "tilted" : "axis-aligned");
    const PlanarCuboid& c = cuboids[0];
    EXPECT_TRUE(c.is_planar);
    EXPECT_EQ(c.plane_id, 0);
    EXPECT_EQ(c.point_count, cloud->size());
    // Coverage: tolerance 1e-4 m is float rounding of the plane coordinates.
    EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
    // Face outside the true rectangle: the noise (sigma 5 mm, max ~4 sigma over
    // 25k points) widens each edge by <= 0.02 m: <= 13 m x 0.02 m = 0.26 m^2, i.e.
    // 2.6 % of 10 m^2; bound 5 %.
    const Eigen::Vector4f box = faceInPatch(c, patch);
    const float inside =
      overlap1D(box[0], box[2], 0.0f, 4.0f) * overlap1D(box[1], box[3], 0.0f, 2.5f);
    EXPECT_LT(c.faceArea() - inside, 0.05f * 10.0f);
    EXPECT_GT(inside, 0.99f * 10.0f);
    // Orientation: normal toward the sensor at 0, axes orthonormal, horizontal axis
    // perpendicular to up.
    EXPECT_GT(c.normal.dot(-c.centre), 0.0f);
    EXPECT_NEAR(std::abs(c.normal.dot(patch.normal())), 1.0f, 1e-5f);
    EXPECT_NEAR(c.horizontal_axis.z(), 0.0f, 1e-5f);
    EXPECT_NEAR(c.horizontal_axis.dot(c.normal), 0.0f, 1e-5f);
    EXPECT_GT(c.verticalAxis().z(), 0.0f); // vertical axis points up the plane
    // Extruded to the back: the face is the front-most inlier (<= 5 sigma = 0.025 m
    // in front of the true plane), the box reaches >= thickness (0.1 m) behind it.
    const float face_offset = (c.faceCentre() - patch.corner).dot(c.normal);
    EXPECT_GT(face_offset, 0.0f);
    EXPECT_LT(face_offset, 0.025f);
    EXPECT_GE(c.thickness_m, 0.1f - 1e-6f);
    EXPECT_LT((c.centre - patch.corner).dot(c.normal), 0.0f);
  }
}

// A 4 x 2.5 m wall with a 0.9 x 0.9 m window hole at s in [1.55, 2.45], t in
// [0.85, 1.75]; 2500 random points / m^2 (25 per 0.1 m cell, so no wall cell is empty).
// The hole's edges lie mid-cell of the 0.1 m raster (origin at the min point, ~0), so
// the border cells are occupied and the 8 x 8 cells inside are empty; no quadtree
// unit that touches them reaches D_T = 0.9 (the densest, 7 of 8 rows occupied, has
// D = 0.875). Horizontal-first merge: below, left, right, above the hole = 4 cuboids.
// No cuboid may cover the hole's central 0.5 x 0.5 m, on or 0.05 m off the plane.
TEST(PlanarCuboidApproximation, WindowHoleIsNotCovered)
{
  const Patch patch = wall(10 * DEG, 0.0);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(2);
  const auto inliers =
    addRandomPatch(*cloud, patch, 4.0f, 2.5f, 2500.0, 0.003, rng, [](float s, float t) {
      return !(s > 1.55f && s < 2.45f && t > 0.85f && t < 1.75f);
    });
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setPlanes(PlanarSegments{segmentOf(patch, inliers)});
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  std::printf("window: %zu cuboids\n", cuboids.size());
  for (const auto& c : cuboids) {
    const Eigen::Vector4f b = faceInPatch(c, patch);
    std::printf("  face s [%.3f, %.3f] t [%.3f, %.3f] m\n", b[0], b[2], b[1], b[3]);
  }
  // Horizontal-first decomposition: below the hole, left of it, right of it, above.
  EXPECT_EQ(cuboids.size(), 4u);
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
  std::size_t probes = 0, inside = 0;
  for (float s = 1.75f; s <= 2.25f; s += 0.05f)
    for (float t = 1.05f; t <= 1.55f; t += 0.05f)
      for (float w : {-0.05f, 0.0f, 0.05f}) {
        const Eigen::Vector3f p = patch.at(s, t) + patch.normal() * w;
        ++probes;
        for (const auto& c : cuboids)
          inside += c.contains(p) ? 1 : 0;
      }
  EXPECT_GT(probes, 300u);
  EXPECT_EQ(inside, 0u);
}

// An L: a 4 x 1 m bar at the bottom and a 1 x 2 m upright on its left. Horizontal
// merge first (Fig. 6(b)) gives the full-width bottom bar plus the upright (2
// cuboids); vertical-first would give a 1 x 3 m column plus a 3 x 1 m bar.
TEST(PlanarCuboidApproximation, LShapeMergesHorizontallyFirst)
{
  const Patch patch = wall(0.0, 0.0);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(3);
  const auto inliers =
    addRandomPatch(*cloud, patch, 4.0f, 3.0f, 2500.0, 0.002, rng,
                   [](float s, float t) { return t < 1.0f || s < 1.0f; });
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setPlanes(PlanarSegments{segmentOf(patch, inliers)});
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  ASSERT_EQ(cuboids.size(), 2u);
  // Tight faces: 2500 points / m^2 leave gaps of ~0.01 m at the edges; tolerance
  // 0.03 m.
  std::vector<Eigen::Vector4f> boxes;
  for (const auto& c : cuboids)
    boxes.push_back(faceInPatch(c, patch));
  std::sort(boxes.begin(), boxes.end(),
            [](const auto& a, const auto& b) { return a[1] < b[1]; });
  const Eigen::Vector4f bar(0, 0, 4, 1), upright(0, 1, 1, 3);
  EXPECT_LT((boxes[0] - bar).cwiseAbs().maxCoeff(), 0.03f) << boxes[0].transpose();
  EXPECT_LT((boxes[1] - upright).cwiseAbs().maxCoeff(), 0.03f) << boxes[1].transpose();
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
}

// Oracle: a wall plus a Gaussian blob (non-planar) plus outliers; with
// min_points_per_cell = 1 every finite point lies in some cuboid (brute force over
// all cuboids with PlanarCuboid::contains, tolerance 1e-4 m = float rounding), and
// the planar faces of one plane never overlap (exact merge on the raster).
TEST(PlanarCuboidApproximation, MixedSceneEveryPointCovered)
{
  const Patch patch = wall(20 * DEG, 15 * DEG);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(4);
  const auto inliers = addRandomPatch(*cloud, patch, 3.0f, 2.0f, 1500.0, 0.01, rng,
                                      [](float, float) { return true; });
  std::normal_distribution<float> blob(0.0f, 0.3f);
  for (int k = 0; k < 2000; ++k)
    cloud->push_back(
      makePoint<pcl::PointXYZ>(Eigen::Vector3f(0.5f, 3.0f, 1.0f)
                               + Eigen::Vector3f(blob(rng), blob(rng), blob(rng))));
  std::uniform_real_distribution<float> anywhere(-3.0f, 6.0f);
  for (int k = 0; k < 50; ++k)
    cloud->push_back(makePoint<pcl::PointXYZ>(
      Eigen::Vector3f(anywhere(rng), anywhere(rng), anywhere(rng))));
  cloud->push_back(makePoint<pcl::PointXYZ>(Eigen::Vector3f(NAN, 0, 0)));

  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setPlanes(PlanarSegments{segmentOf(patch, inliers)});
  approx.setMinPointsPerCell(1);
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  std::size_t planar = 0, points = 0;
  for (const auto& c : cuboids) {
    planar += c.is_planar ? 1 : 0;
    points += c.point_count;
    EXPECT_EQ(c.plane_id, c.is_planar ? 0 : -1);
  }
  std::printf("mixed: %zu cuboids, %zu planar\n", cuboids.size(), planar);
  EXPECT_GE(planar, 1u);
  EXPECT_GT(cuboids.size(), planar);
  EXPECT_EQ(points, cloud->size() - 1); // every finite point counted exactly once
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
  for (std::size_t i = 0; i < cuboids.size(); ++i)
    for (std::size_t j = i + 1; j < cuboids.size(); ++j) {
      if (!cuboids[i].is_planar || !cuboids[j].is_planar)
        continue;
      const Eigen::Vector4f a = faceInPatch(cuboids[i], patch);
      const Eigen::Vector4f b = faceInPatch(cuboids[j], patch);
      EXPECT_LT(overlap1D(a[0], a[2], b[0], b[2]) * overlap1D(a[1], a[3], b[1], b[3]),
                1e-6f);
    }

  // With the default min_points_per_cell = 3 only parts with 1-2 points are dropped:
  // the 50 random outliers and the sparse tails of the blob, cut along the depth at
  // gaps > 0.1 m (measured: 201 of 11051 points, 1.8 %); bound 3 %.
  approx.setMinPointsPerCell(3);
  approx.approximate(cuboids);
  EXPECT_LT(countUncovered(*cloud, cuboids, 1e-4f), 3 * cloud->size() / 100);
}

// Non-planar points are split (Fig. 7) but never merged: the 4 x 2.5 m wall given
// WITHOUT its plane. Its 41 x 26 cells (root unit 64 cells) split into units of at
// most 16 cells = 1.6 m (a 32-cell unit holds at most 32 x 26 / 1024 = 0.81 < D_T
// occupied), so >= ceil(4.1 / 1.6) x ceil(2.6 / 1.6) = 6 cuboids, each <= 1.6 m wide
// and high, where the planar path gives 1.
TEST(PlanarCuboidApproximation, NonPlanarCellsAreNeverMerged)
{
  const Patch patch = wall(0.0, 0.0);
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(5);
  addGridWall(*cloud, patch, 4.0f, 2.5f, 0.02f, 0.005, rng);
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  // 1: the corner cells of the raster can hold only 1-2 points (the raster origin is
  // the min point); with the default 3 they would be dropped, uncovered.
  approx.setMinPointsPerCell(1);
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  std::printf("non-planar wall: %zu cuboids\n", cuboids.size());
  EXPECT_GE(cuboids.size(), 6u);
  for (const auto& c : cuboids) {
    EXPECT_FALSE(c.is_planar);
    EXPECT_EQ(c.plane_id, -1);
    EXPECT_LE(c.width_m, 1.6f + 1e-4f);
    EXPECT_LE(c.height_m, 1.6f + 1e-4f);
    EXPECT_GE(c.thickness_m, 0.1f - 1e-6f);
    EXPECT_NEAR(c.verticalAxis().z(), 1.0f, 1e-6f); // up-aligned frame
  }
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);

  // Split limit: with D_T = 1 and W_T = H_T = 0.2 m no unit is larger than needed:
  // units stop at 2 cells (0.2 m) unless fully occupied.
  approx.setDensityThreshold(1.0);
  approx.setMinWidth(0.2);
  approx.setMinHeight(0.2);
  approx.approximate(cuboids);
  for (const auto& c : cuboids) {
    EXPECT_LE(c.width_m, 1.6f + 1e-4f);
    EXPECT_LE(c.height_m, 1.6f + 1e-4f);
  }
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);

  // Two blobs 2 m apart in depth, in the same image column: never one box.
  cloud->clear();
  std::normal_distribution<float> blob(0.0f, 0.05f);
  for (float depth : {3.0f, 5.0f})
    for (int k = 0; k < 500; ++k)
      cloud->push_back(makePoint<pcl::PointXYZ>(
        Eigen::Vector3f(blob(rng), depth + blob(rng), 1.0f + blob(rng))));
  approx.setDensityThreshold(0.9);
  approx.approximate(cuboids);
  for (const auto& c : cuboids)
    EXPECT_LT(c.thickness_m, 1.0f);
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
}

TEST(PlanarCuboidApproximation, NonPlanarBoxesStayWithinOneCellOfTheirPoints)
{
  // Stereo-like noise: a 3 m x 2 m patch whose points are spread over 1.2 m of depth
  // (the depth error of a far surface), sparse, plus a dense 0.4 m cube. The quadtree
  // leaf and the depth cut alone would give boxes spanning the whole depth spread.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> across(0.0f, 3.0f), high(0.0f, 2.0f),
    depth(6.0f, 7.2f), cube(0.0f, 0.4f);
  for (int k = 0; k < 1500; ++k)
    cloud->push_back(
      makePoint<pcl::PointXYZ>(Eigen::Vector3f(across(rng), depth(rng), high(rng))));
  for (int k = 0; k < 2000; ++k)
    cloud->push_back(makePoint<pcl::PointXYZ>(
      Eigen::Vector3f(4.0f + cube(rng), 3.0f + cube(rng), cube(rng))));
  const float cell = 0.1f;
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setMinCellSize(cell);
  approx.setMinPointsPerCell(1);
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  ASSERT_FALSE(cuboids.empty());
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
  // Oracle: for every box, the extent of the points inside it along each of its axes;
  // the box reaches at most one cell beyond it on every side.
  double box_volume = 0.0;
  for (const auto& c : cuboids) {
    const Eigen::Vector3f axes[3] = {c.horizontal_axis, c.verticalAxis(), c.normal};
    const float half[3] = {0.5f * c.width_m, 0.5f * c.height_m, 0.5f * c.thickness_m};
    float lo[3] = {1e9f, 1e9f, 1e9f}, hi[3] = {-1e9f, -1e9f, -1e9f};
    std::size_t inside = 0;
    for (const auto& p : cloud->points) {
      if (!c.contains(p.getVector3fMap(), 1e-4f))
        continue;
      ++inside;
      for (int a = 0; a < 3; ++a) {
        const float x = axes[a].dot(p.getVector3fMap() - c.centre);
        lo[a] = std::min(lo[a], x);
        hi[a] = std::max(hi[a], x);
      }
    }
    ASSERT_GT(inside, 0u);
    for (int a = 0; a < 3; ++a) {
      EXPECT_LE(-half[a], lo[a] + 1e-4f); // the box holds its points
      EXPECT_GE(lo[a] - (-half[a]), -1e-4f);
      EXPECT_LE(lo[a] - (-half[a]), cell + 1e-4f) << "axis " << a;
      EXPECT_LE(half[a] - hi[a], cell + 1e-4f) << "axis " << a;
    }
    box_volume += static_cast<double>(c.width_m) * c.height_m * c.thickness_m;
  }
  // The boxes' volume stays near the occupied volume: every box is at least D_T
  // occupied on its lattice, grown by at most half a cell per side for its extent
  // (brute-force count of the occupied 0.1 m voxels).
  std::vector<std::int64_t> keys;
  for (const auto& p : cloud->points)
    keys.push_back((static_cast<std::int64_t>(std::floor(p.x / cell)) + 1000) * 1000000
                   + (static_cast<std::int64_t>(std::floor(p.y / cell)) + 500) * 1000
                   + static_cast<std::int64_t>(std::floor(p.z / cell)) + 500);
  std::sort(keys.begin(), keys.end());
  const auto voxels =
    static_cast<double>(std::unique(keys.begin(), keys.end()) - keys.begin());
  const double voxel_volume = voxels * cell * cell * cell;
  std::printf(
    "non-planar noise: %zu boxes, volume %.3f m^3, occupied voxels %.3f m^3\n",
    cuboids.size(), box_volume, voxel_volume);
  EXPECT_LT(box_volume, 3.0 * voxel_volume);
  // The sparse patch's old single boxes spanned 1.2 m of depth; now none does.
  for (const auto& c : cuboids)
    EXPECT_LT(c.thickness_m, 0.8f);
}

// Degenerate inputs give empty (or partial) output and no crash.
TEST(PlanarCuboidApproximation, DegenerateInputs)
{
  using Cloud = pcl::PointCloud<pcl::PointXYZ>;
  PlanarCuboids cuboids(3);
  {
    PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams()); // no input
    approx.approximate(cuboids);
    EXPECT_TRUE(cuboids.empty());
  }
  Cloud::Ptr cloud(new Cloud);
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud); // empty
  approx.approximate(cuboids);
  EXPECT_TRUE(cuboids.empty());

  cloud->push_back(makePoint<pcl::PointXYZ>(Eigen::Vector3f(NAN, NAN, NAN)));
  approx.setInputCloud(cloud); // only NaN
  approx.approximate(cuboids);
  EXPECT_TRUE(cuboids.empty());

  cloud->clear();
  cloud->push_back(makePoint<pcl::PointXYZ>(Eigen::Vector3f(1, 2, 3)));
  approx.setInputCloud(cloud); // a single point: below min_points_per_cell = 3
  approx.approximate(cuboids);
  EXPECT_TRUE(cuboids.empty());
  approx.setMinPointsPerCell(1); // ... or one min_cell_size x thickness cuboid
  approx.approximate(cuboids);
  ASSERT_EQ(cuboids.size(), 1u);
  EXPECT_NEAR(cuboids[0].volume(), 0.1f * 0.1f * 0.1f, 1e-6f);
  EXPECT_TRUE(cuboids[0].contains(Eigen::Vector3f(1, 2, 3)));

  // Bad planes are skipped; their points become non-planar.
  PlanarSegment empty_inliers;
  empty_inliers.model_coefficients.values = {0, 1, 0, -2};
  PlanarSegment short_coefficients;
  short_coefficients.model_coefficients.values = {0, 1, 0};
  short_coefficients.inliers.indices = {0};
  PlanarSegment nan_coefficients;
  nan_coefficients.model_coefficients.values = {NAN, 1, 0, -2};
  nan_coefficients.inliers.indices = {0};
  PlanarSegment zero_normal;
  zero_normal.model_coefficients.values = {0, 0, 0, -2};
  zero_normal.inliers.indices = {0};
  PlanarSegment bad_indices;
  bad_indices.model_coefficients.values = {0, 1, 0, -2};
  bad_indices.inliers.indices = {-1, 7, 1000};
  approx.setPlanes(
    {empty_inliers, short_coefficients, nan_coefficients, zero_normal, bad_indices});
  approx.approximate(cuboids);
  ASSERT_EQ(cuboids.size(), 1u);
  EXPECT_FALSE(cuboids[0].is_planar);

  // Invalid parameters: empty output.
  const auto expectEmpty = [&](const char* what, auto set) {
    PlanarCuboidApproximation<pcl::PointXYZ> bad(paperParams());
    bad.setInputCloud(cloud);
    set(bad);
    PlanarCuboids out(1);
    bad.approximate(out);
    EXPECT_TRUE(out.empty()) << what;
  };
  using A = PlanarCuboidApproximation<pcl::PointXYZ>;
  expectEmpty("cell 0", [](A& a) { a.setMinCellSize(0.0); });
  expectEmpty("cell NaN", [](A& a) { a.setMinCellSize(NAN); });
  expectEmpty("D_T 0", [](A& a) { a.setDensityThreshold(0.0); });
  expectEmpty("D_T 1.5", [](A& a) { a.setDensityThreshold(1.5); });
  expectEmpty("W_T < 0", [](A& a) { a.setMinWidth(-1.0); });
  expectEmpty("H_T < 0", [](A& a) { a.setMinHeight(-1.0); });
  expectEmpty("thickness 0", [](A& a) { a.setThickness(0.0); });
  expectEmpty("min points 0", [](A& a) { a.setMinPointsPerCell(0); });
  expectEmpty("up 0", [](A& a) { a.setUpAxis(Eigen::Vector3f::Zero()); });
  expectEmpty("origin NaN",
              [](A& a) { a.setSensorOrigin(Eigen::Vector3f(NAN, 0, 0)); });

  // Indices restrict the input.
  cloud->push_back(makePoint<pcl::PointXYZ>(Eigen::Vector3f(5, 5, 5)));
  pcl::IndicesPtr indices(new pcl::Indices{1});
  approx.setPlanes({});
  approx.setIndices(indices);
  approx.approximate(cuboids);
  ASSERT_EQ(cuboids.size(), 1u);
  EXPECT_TRUE(cuboids[0].contains(Eigen::Vector3f(5, 5, 5)));
}

// The horizontal reference and the frame convention (documented in the header).
TEST(PlanarCuboidApproximation, HorizontalReferenceConvention)
{
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  EXPECT_NEAR((approx.getHorizontalReference() - Eigen::Vector3f::UnitX()).norm(), 0.0f,
              1e-6f);
  approx.setUpAxis(Eigen::Vector3f(0, -1, 0));
  EXPECT_NEAR((approx.getHorizontalReference() - Eigen::Vector3f::UnitX()).norm(), 0.0f,
              1e-6f);
  approx.setUpAxis(Eigen::Vector3f(1, 0, 0));
  EXPECT_NEAR((approx.getHorizontalReference() - Eigen::Vector3f::UnitY()).norm(), 0.0f,
              1e-6f);
}

// Real data: office1.pcd (Kinect, camera frame, up = -y), 0.05 m voxel-downsampled,
// planes by SACMultiPlaneSegmentation, approximated at 0.1 m. Measured counts are in
// docs/SURFACE.md; the bound (half the occupied 0.1 m voxels) leaves a wide margin.
TEST(PlanarCuboidApproximation, OfficeCloudFarFewerCuboidsThanVoxels)
{
  using Cloud = pcl::PointCloud<pcl::PointXYZRGB>;
  Cloud::Ptr raw(new Cloud);
  const std::string path =
    std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/office1.pcd";
  if (pcl::io::loadPCDFile(path, *raw) != 0)
    GTEST_SKIP() << "missing " << path;
  Cloud::Ptr cloud(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZRGB> down;
  down.setInputCloud(raw);
  down.setLeafSize(0.05f, 0.05f, 0.05f);
  down.filter(*cloud);
  Cloud voxels;
  down.setInputCloud(cloud);
  down.setLeafSize(0.1f, 0.1f, 0.1f);
  down.filter(voxels);

  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZRGB> seg;
  // Eq. 11 by distance alone, the sample threshold d_T (the class's defaults are
  // the pipeline's normal test and 0.1 m sample threshold).
  seg.setMaxNormalAngle(0.0);
  seg.setMinNormalAgreement(0.0);
  seg.setMinTerrainSensorHeight(0.0);
  seg.setSampleDistanceThreshold(0.05);
  seg.setInputCloud(cloud);
  seg.setUpAxis(Eigen::Vector3f(0, -1, 0));
  seg.setMinInliers(200);
  PlanarSegments planes;
  seg.segment(planes);
  ASSERT_GE(planes.size(), 2u);

  PlanarCuboidApproximation<pcl::PointXYZRGB> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setUpAxis(Eigen::Vector3f(0, -1, 0));
  approx.setPlanes(planes);
  approx.setMinPointsPerCell(1);
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  std::size_t planar = 0;
  for (const auto& c : cuboids)
    planar += c.is_planar ? 1 : 0;
  std::printf("office1: %zu points, %zu planes, %zu occupied 0.1 m voxels, %zu cuboids "
              "(%zu planar)\n",
              cloud->size(), planes.size(), voxels.size(), cuboids.size(), planar);
  EXPECT_LT(cuboids.size(), voxels.size() / 2);
  EXPECT_EQ(countUncovered(*cloud, cuboids, 1e-4f), 0u);
}

/** A wall (3 x 2 m, 0.03 m grid, 0.004 m noise) beside a floor patch (2 x 2 m, 2500
 * points / m^2, 0.003 m noise) and a small blob off both, in a z-up world with the
 * sensor at the origin. */
pcl::PointCloud<pcl::PointXYZ>::Ptr
wallFloorAndBlob(std::vector<int>* wall_inliers = nullptr)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::mt19937 rng(7);
  const auto inliers =
    addGridWall(*cloud, wall(20 * DEG, 0.0), 3.0f, 2.0f, 0.03f, 0.004, rng);
  if (wall_inliers)
    *wall_inliers = inliers;
  const Patch floor{Eigen::Vector3f(-2.0f, 1.0f, -1.2f), Eigen::Vector3f::UnitX(),
                    Eigen::Vector3f::UnitY()};
  addRandomPatch(*cloud, floor, 2.0f, 2.0f, 2500.0, 0.003, rng,
                 [](float, float) { return true; });
  std::normal_distribution<float> blob(0.0f, 0.15f);
  for (int k = 0; k < 300; ++k)
    cloud->push_back(makePoint<pcl::PointXYZ>(
      Eigen::Vector3f(2.5f + blob(rng), 2.0f + blob(rng), 0.0f + blob(rng))));
  return cloud;
}

// PCL's own plane output: its plane RANSAC run once per plane (each run on the points
// the earlier planes left) gives parallel ModelCoefficients and PointIndices
// with unit normals of either sign. Passed in as they are, they give exactly the
// cuboids of the project's PlanarSegments holding the same planes with the normals
// turned toward the sensor, as SACMultiPlaneSegmentation gives them.
TEST(PlanarCuboidApproximation, PlanesFromPCLRansacGiveTheSameCuboids)
{
  // PCL's plane RANSAC as pcl::SACSegmentation runs it (the best model, its
  // least-squares refinement, the points within the threshold of the refined plane),
  // written out as PCL's ModelCoefficients and PointIndices. The models are made here,
  // not inside libpcl_segmentation, so that the sanitizer build allocates and frees
  // them on one side.
  const auto cloud = wallFloorAndBlob();
  std::vector<pcl::ModelCoefficients> model_coefficients;
  std::vector<pcl::PointIndices> inliers;
  pcl::Indices remaining(cloud->size());
  for (std::size_t i = 0; i < cloud->size(); ++i)
    remaining[i] = static_cast<int>(i);
  for (int plane = 0; plane < 2; ++plane) {
    pcl::SampleConsensusModelPlane<pcl::PointXYZ>::Ptr model(
      new pcl::SampleConsensusModelPlane<pcl::PointXYZ>(cloud, remaining));
    pcl::RandomSampleConsensus<pcl::PointXYZ> ransac(model, 0.02);
    ransac.setMaxIterations(500);
    ASSERT_TRUE(ransac.computeModel());
    pcl::Indices best;
    ransac.getInliers(best);
    Eigen::VectorXf coefficients, refined;
    ransac.getModelCoefficients(coefficients);
    model->optimizeModelCoefficients(best, coefficients, refined);
    pcl::PointIndices plane_inliers;
    model->selectWithinDistance(refined, 0.02, plane_inliers.indices);
    ASSERT_GT(plane_inliers.indices.size(), 5000u) << "plane " << plane;
    pcl::ModelCoefficients plane_coefficients;
    plane_coefficients.values.assign(refined.data(), refined.data() + refined.size());
    std::vector<std::uint8_t> taken(cloud->size(), 0);
    for (const auto index : plane_inliers.indices)
      taken[static_cast<std::size_t>(index)] = 1;
    remaining.erase(std::remove_if(remaining.begin(), remaining.end(),
                                   [&taken](int index) {
                                     return taken[static_cast<std::size_t>(index)] != 0;
                                   }),
                    remaining.end());
    model_coefficients.push_back(plane_coefficients);
    inliers.push_back(plane_inliers);
  }

  PlanarSegments segments;
  for (std::size_t i = 0; i < inliers.size(); ++i) {
    PlanarSegment segment;
    segment.model_coefficients = model_coefficients[i];
    auto& c = segment.model_coefficients.values;
    ASSERT_EQ(c.size(), 4u);
    if (c[3] < 0.0f) // toward the sensor at the origin: a o + d >= 0
      for (auto& value : c)
        value = -value;
    segment.inliers = inliers[i];
    segments.push_back(segment);
  }

  PlanarCuboids from_pcl, from_segments;
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setPlanes(model_coefficients, inliers);
  ASSERT_EQ(approx.getPlanes().size(), 2u);
  approx.approximate(from_pcl);
  approx.setPlanes(segments);
  approx.approximate(from_segments);

  const auto expectSame = [](const PlanarCuboids& cuboids,
                             const PlanarCuboids& expected, const char* what) {
    ASSERT_EQ(cuboids.size(), expected.size()) << what;
    for (std::size_t i = 0; i < cuboids.size(); ++i) {
      const PlanarCuboid& a = cuboids[i];
      const PlanarCuboid& b = expected[i];
      EXPECT_EQ(a.centre, b.centre) << what << " " << i;
      EXPECT_EQ(a.normal, b.normal) << what << " " << i;
      EXPECT_EQ(a.horizontal_axis, b.horizontal_axis) << what << " " << i;
      EXPECT_EQ(a.width_m, b.width_m) << what << " " << i;
      EXPECT_EQ(a.height_m, b.height_m) << what << " " << i;
      EXPECT_EQ(a.thickness_m, b.thickness_m) << what << " " << i;
      EXPECT_EQ(a.plane_id, b.plane_id) << what << " " << i;
      EXPECT_EQ(a.point_count, b.point_count) << what << " " << i;
      EXPECT_EQ(a.is_planar, b.is_planar) << what << " " << i;
    }
  };
  expectSame(from_pcl, from_segments, "PCL RANSAC output");
  std::size_t planar[2] = {0, 0};
  for (const PlanarCuboid& c : from_segments)
    if (c.is_planar) {
      ASSERT_TRUE(c.plane_id == 0 || c.plane_id == 1) << c.plane_id;
      ++planar[c.plane_id];
      EXPECT_GT(c.normal.dot(-c.centre), 0.0f); // faces the sensor
    }
  EXPECT_GE(planar[0], 1u);
  EXPECT_GE(planar[1], 1u);

  // The normal's sign and length do not matter: the first plane turned round, the
  // second at twice the length (exact in floating point) give the same cuboids.
  std::vector<pcl::ModelCoefficients> rescaled = model_coefficients;
  for (auto& value : rescaled[0].values)
    value = -value;
  for (auto& value : rescaled[1].values)
    value *= 2.0f;
  PlanarCuboids from_rescaled;
  approx.setPlanes(rescaled, inliers);
  approx.approximate(from_rescaled);
  expectSame(from_rescaled, from_segments, "rescaled");

  // Lists of different lengths are refused and leave the planes as they were.
  inliers.pop_back();
  EXPECT_THROW(approx.setPlanes(model_coefficients, inliers), planar_grid::Exception);
  EXPECT_EQ(approx.getPlanes().size(), 2u);
  EXPECT_EQ(approx.getPlanes()[1].inliers.indices, segments[1].inliers.indices);
  EXPECT_EQ(approx.getPlanes()[1].model_coefficients.values, rescaled[1].values);
}

// The mesh of reconstruct(): 8 vertices and 12 triangles per cuboid, the vertices the
// boxes' corners (oracle: centre +- the half extents along the three axes, computed
// here), every triangle of one box facing out of it, and each box closed (every edge
// shared by two of its triangles, in opposite directions).
TEST(PlanarCuboidApproximation, ReconstructGivesEachCuboidAsAClosedBoxMesh)
{
  std::vector<int> wall_inliers;
  const auto cloud = wallFloorAndBlob(&wall_inliers);
  cloud->header.frame_id = "world";
  cloud->header.stamp = 1234567;
  const Patch patch = wall(20 * DEG, 0.0);
  PlanarCuboidApproximation<pcl::PointXYZ> approx(paperParams());
  approx.setInputCloud(cloud);
  approx.setPlanes(PlanarSegments{segmentOf(patch, wall_inliers)});
  PlanarCuboids cuboids;
  approx.approximate(cuboids);
  pcl::PolygonMesh mesh;
  approx.reconstruct(mesh);
  ASSERT_GT(cuboids.size(), 3u);

  EXPECT_EQ(mesh.header.frame_id, "world");
  EXPECT_EQ(mesh.header.stamp, 1234567u);
  pcl::PointCloud<pcl::PointXYZ> vertices;
  pcl::fromPCLPointCloud2(mesh.cloud, vertices);
  ASSERT_EQ(vertices.size(), 8 * cuboids.size());
  ASSERT_EQ(mesh.polygons.size(), 12 * cuboids.size());
  for (std::size_t i = 0; i < cuboids.size(); ++i) {
    const PlanarCuboid& c = cuboids[i];
    const Eigen::Vector3f v = c.normal.cross(c.horizontal_axis);
    // The oracle corners; each matches one vertex of the box and each vertex one.
    std::vector<Eigen::Vector3f> oracle;
    for (const float sn : {-0.5f, 0.5f})
      for (const float sh : {-0.5f, 0.5f})
        for (const float sv : {-0.5f, 0.5f})
          oracle.push_back(c.centre + c.normal * (sn * c.thickness_m)
                           + c.horizontal_axis * (sh * c.width_m)
                           + v * (sv * c.height_m));
    std::vector<bool> matched(8, false);
    for (std::size_t k = 0; k < 8; ++k) {
      const Eigen::Vector3f p = vertices[8 * i + k].getVector3fMap();
      std::size_t hits = 0;
      for (std::size_t o = 0; o < 8; ++o)
        if ((p - oracle[o]).norm() < 1e-4f) {
          ++hits;
          matched[o] = true;
        }
      EXPECT_EQ(hits, 1u) << "cuboid " << i << " vertex " << k;
    }
    EXPECT_EQ(std::count(matched.begin(), matched.end(), true), 8) << "cuboid " << i;

    std::map<std::pair<pcl::index_t, pcl::index_t>, int> edges;
    for (std::size_t t = 12 * i; t < 12 * i + 12; ++t) {
      const auto& index = mesh.polygons[t].vertices;
      ASSERT_EQ(index.size(), 3u);
      for (const auto k : index) {
        ASSERT_GE(k, 0);
        ASSERT_GE(static_cast<std::size_t>(k), 8 * i);
        ASSERT_LT(static_cast<std::size_t>(k), 8 * i + 8);
      }
      const Eigen::Vector3f a = vertices[index[0]].getVector3fMap();
      const Eigen::Vector3f b = vertices[index[1]].getVector3fMap();
      const Eigen::Vector3f d = vertices[index[2]].getVector3fMap();
      const Eigen::Vector3f outward = (a + b + d) / 3.0f - c.centre;
      EXPECT_GT((b - a).cross(d - a).dot(outward), 0.0f) << "cuboid " << i << " " << t;
      for (int e = 0; e < 3; ++e)
        ++edges[{index[e], index[(e + 1) % 3]}];
    }
    EXPECT_EQ(edges.size(), 36u) << "cuboid " << i;
    for (const auto& [edge, count] : edges) {
      EXPECT_EQ(count, 1) << "cuboid " << i;
      EXPECT_EQ(edges.count({edge.second, edge.first}), 1u) << "cuboid " << i;
    }
  }

  // No input: an empty mesh.
  PlanarCuboidApproximation<pcl::PointXYZ> empty(paperParams());
  empty.reconstruct(mesh);
  EXPECT_EQ(mesh.cloud.width * mesh.cloud.height, 0u);
  EXPECT_TRUE(mesh.polygons.empty());
}

} // namespace
