// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/PolygonMesh.h>
#include <pcl/common/transforms.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/ply_io.h>
#include <pcl/io/vtk_lib_io.h>

#include <Eigen/Eigenvalues>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <tuple>
#include <vector>

#include "../benchmarks/karlsruhe_frame.h"
#include "wall_cuboid.h"

namespace {

using planar_grid::IOError;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlaneModels;
using planar_grid::SurfaceLayer;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

/** A plane with the layer's 2D frame convention (u = z x n normalised, or x projected
 * for a horizontal plane; v = n x u; origin -d n), computed independently here. */
struct PlaneFrame {
  Eigen::Vector3f n, u, v, origin;
  float d;
  PlaneFrame(const Eigen::Vector3f& normal, float offset) :
      n(normal.normalized()), d(offset)
  {
    u = Eigen::Vector3f::UnitZ().cross(n);
    if (u.norm() < 1e-3f)
      u = Eigen::Vector3f::UnitX() - n * n.x();
    u.normalize();
    v = n.cross(u);
    origin = -d * n;
  }
  Eigen::Vector3f at(float s, float t) const { return origin + u * s + v * t; }
  Eigen::Vector4f model() const { return {n.x(), n.y(), n.z(), d}; }
};

/** A planar cuboid of plane_id whose face is the rectangle [u0, u1] x [v0, v1] of
 * \a frame, extruded by thickness behind it. */
PlanarCuboid
faceCuboid(const PlaneFrame& frame,
           int plane_id,
           float u0,
           float u1,
           float v0,
           float v1,
           float thickness = 0.1f)
{
  PlanarCuboid c;
  c.normal = frame.n;
  c.horizontal_axis = frame.u;
  c.width_m = u1 - u0;
  c.height_m = v1 - v0;
  c.thickness_m = thickness;
  c.centre =
    frame.at(0.5f * (u0 + u1), 0.5f * (v0 + v1)) - frame.n * (0.5f * thickness);
  c.plane_id = plane_id;
  c.is_planar = true;
  return c;
}

/** Wall at y = 5 facing a sensor at the origin: n = (0, -1, 0), d = 5. */
PlaneFrame
wallFrame()
{
  return PlaneFrame(Eigen::Vector3f(0.0f, -1.0f, 0.0f), 5.0f);
}

/** A rectangle of a cuboid in the (u, v) coordinates of \a frame. */
struct Rect {
  float u0, u1, v0, v1;
};
Rect
rectIn(const PlaneFrame& frame, const PlanarCuboid& c)
{
  const Eigen::Vector3f fc = c.faceCentre() - frame.origin;
  const float uc = fc.dot(frame.u), vc = fc.dot(frame.v);
  return {uc - 0.5f * c.width_m, uc + 0.5f * c.width_m, vc - 0.5f * c.height_m,
          vc + 0.5f * c.height_m};
}

SurfaceLayer::Params
defaultParams()
{
  return SurfaceLayer::Params{};
}

bool
sameCuboids(const PlanarCuboids& a, const PlanarCuboids& b)
{
  if (a.size() != b.size())
    return false;
  for (std::size_t k = 0; k < a.size(); ++k) {
    const PlanarCuboid& x = a[k];
    const PlanarCuboid& y = b[k];
    if (!x.centre.isApprox(y.centre, 1e-6f) || !x.normal.isApprox(y.normal, 1e-6f)
        || !x.horizontal_axis.isApprox(y.horizontal_axis, 1e-6f)
        || x.width_m != y.width_m || x.height_m != y.height_m
        || x.thickness_m != y.thickness_m || x.plane_id != y.plane_id
        || x.is_planar != y.is_planar
        || std::abs(x.probability - y.probability) > 1e-6f)
      return false;
  }
  return true;
}

// Frame A: L shape [0, 2] x [0, 1] + [0, 1] x [1, 2] on the wall. Frame B: [1.5, 3] x
// [0, 1.5] on the wall tilted by 0.02 rad about u and moved 0.03 m (within the 0.1 rad
// / 0.15 m tolerances). Union: 3 + 2.25 - 0.5 (overlap [1.5, 2] x [0, 1]) = 4.75 m^2,
// i.e. 475 cells of 0.1 m; rows v in [0, 1) run u in [0, 3], rows [1, 1.5) run
// [0, 1] and [1.5, 3] (a gap of 5 cells, wider than the 2 closed), rows [1.5, 2) run
// [0, 1]: 3 rectangles after the merge. The map plane is the least-squares plane of
// both frames' faces: between A's and B's normals, and the raster (in A's frame) is
// placed on it.
TEST(SurfaceLayer, OverlappingFramesOfOneWallMergeIntoOnePlane)
{
  const PlaneFrame a = wallFrame();
  const Eigen::Vector3f n_b = Eigen::AngleAxisf(0.02f, a.u) * a.n;
  const PlaneFrame b_plane(n_b, -n_b.dot(a.origin + a.n * 0.03f));
  SurfaceLayer layer(defaultParams());
  const Cloud no_features;
  layer.integrate({faceCuboid(a, 0, 0, 2, 0, 1), faceCuboid(a, 0, 0, 1, 1, 2)},
                  PlaneModels{a.model()}, no_features, {});
  // frame B's rectangle: the same (u, v) of the map frame, lifted onto plane B
  PlanarCuboid cb = faceCuboid(b_plane, 0, 0, 1.5f, 0, 1.5f);
  const Eigen::Vector3f target = a.at(2.25f, 0.75f);
  const float s = -(n_b.dot(target) + b_plane.d) / n_b.dot(a.n);
  cb.centre = target + a.n * s - n_b * 0.05f;
  layer.integrate({cb}, PlaneModels{b_plane.model()}, no_features, {});

  ASSERT_EQ(layer.getPlanes().size(), 1u);
  const Eigen::Vector4f plane = layer.getPlanes()[0];
  const Eigen::Vector3f n = plane.head<3>();
  // Oracle: the least-squares plane of the three faces, sampled on a 1 cm grid (the
  // samples weigh each face by its area), by an independent eigen-decomposition.
  {
    std::vector<Eigen::Vector3d> samples;
    const auto sample = [&samples](const PlanarCuboid& c) {
      const int nu = static_cast<int>(std::lround(c.width_m / 0.01f));
      const int nv = static_cast<int>(std::lround(c.height_m / 0.01f));
      for (int iu = 0; iu < nu; ++iu)
        for (int iv = 0; iv < nv; ++iv)
          samples.push_back(
            (c.faceCentre()
             + c.horizontal_axis * ((iu + 0.5f) * 0.01f - 0.5f * c.width_m)
             + c.verticalAxis() * ((iv + 0.5f) * 0.01f - 0.5f * c.height_m))
              .cast<double>());
    };
    sample(faceCuboid(a, 0, 0, 2, 0, 1));
    sample(faceCuboid(a, 0, 0, 1, 1, 2));
    sample(cb);
    Eigen::Vector3d mean = Eigen::Vector3d::Zero();
    for (const auto& q : samples)
      mean += q;
    mean /= static_cast<double>(samples.size());
    Eigen::Matrix3d covariance = Eigen::Matrix3d::Zero();
    for (const auto& q : samples)
      covariance += (q - mean) * (q - mean).transpose();
    const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
    Eigen::Vector3d expected = solver.eigenvectors().col(0);
    if (expected.dot(a.n.cast<double>()) < 0.0)
      expected = -expected;
    EXPECT_LT(std::acos(std::min(1.0, expected.dot(n.cast<double>()))), 1e-4);
    EXPECT_NEAR(plane[3], -expected.dot(mean), 1e-4);
  }
  const PlanarCuboids& cuboids = layer.getCuboids();
  ASSERT_EQ(cuboids.size(), 3u);
  EXPECT_EQ(layer.getCellCount(), 475u);
  // the rectangles in the faces' own frame on the refined plane
  PlaneFrame refined(n, plane[3]);
  refined.u = cuboids[0].horizontal_axis;
  refined.v = cuboids[0].verticalAxis();
  double area = 0.0;
  std::vector<Rect> rects;
  for (const auto& c : cuboids) {
    EXPECT_EQ(c.plane_id, 0);
    EXPECT_TRUE(c.is_planar);
    EXPECT_NEAR(c.thickness_m, 0.1f, 1e-6f);
    EXPECT_GT(c.normal.dot(n), 1.0f - 1e-6f);
    EXPECT_GT(c.horizontal_axis.dot(refined.u), 1.0f - 1e-6f);
    area += c.faceArea();
    rects.push_back(rectIn(refined, c));
  }
  // the raster's area, scaled by the projections of A's u and v onto the refined
  // plane
  const double scale = (a.u - n * n.dot(a.u)).norm() * (a.v - n * n.dot(a.v)).norm();
  EXPECT_NEAR(area, 4.75 * scale, 1e-4);
  for (std::size_t i = 0; i < rects.size(); ++i)
    for (std::size_t j = i + 1; j < rects.size(); ++j) {
      const float du =
        std::min(rects[i].u1, rects[j].u1) - std::max(rects[i].u0, rects[j].u0);
      const float dv =
        std::min(rects[i].v1, rects[j].v1) - std::max(rects[i].v0, rects[j].v0);
      EXPECT_FALSE(du > 1e-4f && dv > 1e-4f) << "cuboids " << i << " and " << j;
    }
  // every cell centre of the union, placed like the raster (projected along the
  // refined normal onto the refined plane) and 0.05 m behind the face, is in exactly
  // one cuboid, others in none
  for (int i = -2; i < 32; ++i)
    for (int j = -2; j < 22; ++j) {
      const float u = (i + 0.5f) * 0.1f, v = (j + 0.5f) * 0.1f;
      const bool in_a =
        (u < 2 && v < 1 && u > 0 && v > 0) || (u < 1 && v < 2 && u > 0 && v > 0);
      const bool in_b = u > 1.5f && u < 3 && v > 0 && v < 1.5f;
      const Eigen::Vector3f on_frame = a.at(u, v);
      const Eigen::Vector3f p = on_frame - n * (n.dot(on_frame) + plane[3]) - n * 0.05f;
      int hits = 0;
      for (const auto& c : cuboids)
        hits += c.contains(p) ? 1 : 0;
      EXPECT_EQ(hits, (in_a || in_b) ? 1 : 0) << "u " << u << " v " << v;
    }
}

TEST(SurfaceLayer, DifferentPlanesStaySeparate)
{
  const PlaneFrame a = wallFrame();
  // 0.3 rad away (tolerance 0.1 rad), and a parallel wall 0.7 m behind (0.15 m, and
  // beyond the absorb_distance_m of 0.5 m within which a stacked plane merges).
  const PlaneFrame turned(Eigen::AngleAxisf(0.3f, Eigen::Vector3f::UnitZ()) * a.n,
                          5.0f);
  const PlaneFrame behind(a.n, 5.7f);
  SurfaceLayer layer(defaultParams());
  const Cloud none;
  layer.integrate({faceCuboid(a, 0, 0, 1, 0, 1), faceCuboid(turned, 1, 0, 1, 0, 1),
                   faceCuboid(behind, 2, 0, 1, 0, 1)},
                  PlaneModels{a.model(), turned.model(), behind.model()}, none, {});
  EXPECT_EQ(layer.getPlanes().size(), 3u);
  EXPECT_EQ(layer.getCuboids().size(), 3u);
  // a plane within tolerance in a second frame joins the first
  const PlaneFrame close(a.n, 5.1f);
  layer.integrate({faceCuboid(close, 0, 1, 2, 0, 1)}, PlaneModels{close.model()}, none,
                  {});
  EXPECT_EQ(layer.getPlanes().size(), 3u);
  // the plane model given with the opposite sign is oriented by its cuboids' normal
  layer.integrate({faceCuboid(a, 0, 2, 3, 0, 1)}, PlaneModels{-a.model()}, none, {});
  EXPECT_EQ(layer.getPlanes().size(), 3u);
  EXPECT_EQ(layer.getCuboids().size(), 3u); // [0, 3] x [0, 1] on the first wall
}

// Terrain tiles (terrain_plane_tile_m 4 m): a road seen as two level planes 0.05 m
// apart in height (within plane_merge_distance_m), side by side in the tiles x in
// [0, 4) and [4, 8), stays two map planes, each at its own height; without tiles the
// second joins the first (one plane between the two heights). Walls are not level:
// two views of one wall in the two tiles join either way.
TEST(SurfaceLayer, TerrainTilesBoundLevelPlanes)
{
  const PlaneFrame near_road(Eigen::Vector3f::UnitZ(), 1.5f); // z = -1.5
  const PlaneFrame far_road(Eigen::Vector3f::UnitZ(), 1.45f); // z = -1.45
  const PlaneFrame wall = wallFrame();
  const Cloud none;
  for (const double tile_m : {0.0, 4.0}) {
    SCOPED_TRACE(tile_m);
    SurfaceLayer::Params params = defaultParams();
    params.terrain_plane_tile_m = tile_m;
    SurfaceLayer layer(params);
    // u runs along x on both (the horizontal planes' u is x projected), v along y
    layer.integrate({faceCuboid(near_road, 0, 0.5f, 4.0f, 0.5f, 3.5f),
                     faceCuboid(wall, 1, 0.5f, 3.5f, 0.0f, 2.0f)},
                    PlaneModels{near_road.model(), wall.model()}, none, {});
    ASSERT_EQ(layer.getPlanes().size(), 2u);
    layer.integrate({faceCuboid(far_road, 0, 4.0f, 7.5f, 0.5f, 3.5f),
                     faceCuboid(wall, 1, 4.5f, 7.5f, 0.0f, 2.0f)},
                    PlaneModels{far_road.model(), wall.model()}, none, {});
    const PlaneModels& planes = layer.getPlanes();
    // the level planes' heights at the middles of the two tiles, x = 2 and x = 6
    std::vector<Eigen::Vector2f> road_heights;
    std::size_t walls = 0;
    for (const Eigen::Vector4f& p : planes) {
      const auto height = [&p](float x) {
        return -(p[3] + p.x() * x + p.y() * 2.0f) / p.z();
      };
      if (std::abs(p.z()) > 0.99f)
        road_heights.emplace_back(height(2.0f), height(6.0f));
      else
        ++walls;
    }
    EXPECT_EQ(walls, 1u);
    if (tile_m > 0.0) {
      // each at its own height over its tile
      ASSERT_EQ(road_heights.size(), 2u);
      const bool near_first = road_heights[0].x() < road_heights[1].x();
      EXPECT_NEAR(road_heights[near_first ? 0 : 1].x(), -1.5f, 1e-4f);
      EXPECT_NEAR(road_heights[near_first ? 1 : 0].y(), -1.45f, 1e-4f);
    } else {
      // one plane fitted across both, off each by more than a millimetre
      ASSERT_EQ(road_heights.size(), 1u);
      EXPECT_GT(road_heights[0].x(), -1.5f + 1e-3f);
      EXPECT_LT(road_heights[0].y(), -1.45f - 1e-3f);
    }
    // the parameter travels with the section
    std::vector<std::uint8_t> bytes;
    layer.serialize(bytes);
    SurfaceLayer copy(defaultParams());
    copy.deserialize(bytes.data(), bytes.size());
    EXPECT_EQ(copy.getParams().terrain_plane_tile_m, tile_m);
    EXPECT_TRUE(copy == layer);
  }
}

// With terrain tiles the level planes take terrain_cover_density: a floor and a wall
// observed over the same 2 m x 1 m of 0.1 m cells, one cell in nine missing (an
// isolated hole every third row and column), covered by the density rule at 0.7.
// With terrain_cover_density 1 the floor's rectangles hold no hole while the wall's
// span some; without tiles the floor is covered like the wall.
TEST(SurfaceLayer, TerrainCoverDensityCoversTheLevelPlanes)
{
  const PlaneFrame floor(Eigen::Vector3f::UnitZ(), 1.5f); // z = -1.5, u = x, v = y
  const PlaneFrame wall = wallFrame();
  const Cloud none;
  const auto hole = [](int i, int j) {
    return i % 3 == 1 && j % 3 == 1;
  };
  // how many holes of the plane on \a frame lie inside a cuboid
  const auto coveredHoles = [&](const PlanarCuboids& out, const PlaneFrame& frame) {
    int covered = 0;
    for (int i = 5; i < 25; ++i)
      for (int j = 5; j < 15; ++j) {
        if (!hole(i, j))
          continue;
        const Eigen::Vector3f p =
          frame.at(0.1f * i + 0.05f, 0.1f * j + 0.05f) - frame.n * 0.05f;
        for (const auto& c : out)
          if (c.contains(p)) {
            ++covered;
            break;
          }
      }
    return covered;
  };
  for (const double tile_m : {0.0, 4.0}) {
    SCOPED_TRACE(tile_m);
    SurfaceLayer::Params params = defaultParams();
    params.close_gaps_cells = 0;
    params.merge_rule = planar_grid::SurfaceMergeRule::DENSITY;
    params.cover_density = 0.7;
    params.terrain_plane_tile_m = tile_m;
    params.terrain_cover_density = 1.0;
    SurfaceLayer layer(params);
    PlanarCuboids cells;
    for (int i = 5; i < 25; ++i)
      for (int j = 5; j < 15; ++j)
        if (!hole(i, j))
          for (int id = 0; id < 2; ++id)
            cells.push_back(faceCuboid(id == 0 ? floor : wall, id, 0.1f * i,
                                       0.1f * i + 0.1f, 0.1f * j, 0.1f * j + 0.1f));
    layer.integrate(cells, PlaneModels{floor.model(), wall.model()}, none, {});
    ASSERT_EQ(layer.getPlanes().size(), 2u);
    PlanarCuboids on_floor, on_wall;
    for (const auto& c : layer.getCuboids())
      (std::abs(c.normal.z()) > 0.99f ? on_floor : on_wall).push_back(c);
    const int holes = 7 * 3; // i in 7, 10, ..., 25 and j in 7, 10, 13
    EXPECT_GT(coveredHoles(on_wall, wall), holes / 2);
    if (tile_m > 0.0)
      EXPECT_EQ(coveredHoles(on_floor, floor), 0);
    else
      EXPECT_EQ(coveredHoles(on_floor, floor), coveredHoles(on_wall, wall));
    // every observed floor cell is covered either way
    for (int i = 5; i < 25; ++i)
      for (int j = 5; j < 15; ++j)
        if (!hole(i, j)) {
          const Eigen::Vector3f p =
            floor.at(0.1f * i + 0.05f, 0.1f * j + 0.05f) - floor.n * 0.05f;
          EXPECT_TRUE(
            std::any_of(on_floor.begin(), on_floor.end(),
                        [&p](const PlanarCuboid& c) { return c.contains(p); }))
            << i << " " << j;
        }
    // the parameter travels with the section
    std::vector<std::uint8_t> bytes;
    layer.serialize(bytes);
    SurfaceLayer copy(defaultParams());
    copy.deserialize(bytes.data(), bytes.size());
    EXPECT_EQ(copy.getParams().terrain_cover_density, 1.0);
    EXPECT_TRUE(copy == layer);
  }
}

// The distance of a frame's plane to a map plane is measured where the faces are: a
// wall 500 m along from the world origin's foot point, seen again on a plane turned
// by 0.01 rad about the face centre, differs in d by ~5 m, yet its faces lie on the
// first ones: one map plane. A parallel wall 0.32 m in front is not associated: with
// the map plane's evidence (weight 8 m^2) its face (4 m^2) fits a plane 0.32 x 8 / 12
// = 0.21 m from it (> 0.15 m). (Lying over the first, it would merge as a stacked
// plane within absorb_distance_m: StackedParallelPlanesMerge. Here that distance is
// 0.2 m, so that only the association decides.)
TEST(SurfaceLayer, PlaneDistanceIsMeasuredWhereTheFacesAre)
{
  const PlaneFrame wall = wallFrame();
  const Eigen::Vector3f centre = wall.at(501.0f, 1.0f);
  const Eigen::Vector3f n_b = Eigen::AngleAxisf(0.01f, wall.v) * wall.n;
  const PlaneFrame turned(n_b, -n_b.dot(centre));
  ASSERT_GT(std::abs(turned.d - wall.d), 4.0f); // the d offsets differ by metres
  SurfaceLayer::Params params = defaultParams();
  params.absorb_distance_m = 0.2;
  SurfaceLayer layer(params);
  layer.integrate({faceCuboid(wall, 0, 500, 502, 0, 2)}, PlaneModels{wall.model()},
                  Cloud(), {});
  PlanarCuboid cb = faceCuboid(turned, 0, 0, 2, 0, 2);
  cb.centre = centre - n_b * 0.05f;
  layer.integrate({cb}, PlaneModels{turned.model()}, Cloud(), {});
  EXPECT_EQ(layer.getPlanes().size(), 1u);
  EXPECT_EQ(layer.getCellCount(), 400u); // the same 2 m x 2 m
  const PlaneFrame front(wall.n, wall.d - 0.32f);
  layer.integrate({faceCuboid(front, 0, 500, 502, 0, 2)}, PlaneModels{front.model()},
                  Cloud(), {});
  EXPECT_EQ(layer.getPlanes().size(), 2u);
}

// One surface mapped twice a little apart merges: a wall [0, 4] x [0, 2] (0.1 m
// cells) and, in a second frame, a plane turned 0.08 rad about the wall's v axis
// (within plane_merge_angle_rad, 0.1) whose face [1, 3] x [0, 2] lies 0.3 m in front
// of it at its middle. The association does not join them (the joint plane is more
// than plane_merge_distance_m, 0.15 m, from the faces), but every cell of the second
// lies over an observed cell of the first within absorb_distance_m (0.5 m): one map
// plane, the wall's 800 cells. It stays two planes when the second lies beside the
// wall (no cell over it), 0.7 m in front, turned 0.3 rad, or, parallel 0.45 m in
// front, over less than a quarter of its cells ([3.6, 5.6]: 0.4 of 2 m; [3.2, 5.2],
// 0.8 of 2 m, merges), when its evidence is less than a quarter of the wall's, or when
// both are level (a floor and a step 0.3 m up: the step is real).
TEST(SurfaceLayer, StackedParallelPlanesMerge)
{
  const PlaneFrame wall = wallFrame();
  const auto second = [&wall](float angle_rad, float gap_m, float u0, float u1) {
    const Eigen::Vector3f n = Eigen::AngleAxisf(angle_rad, wall.v) * wall.n;
    const Eigen::Vector3f middle = wall.at(0.5f * (u0 + u1), 1.0f) + wall.n * gap_m;
    const PlaneFrame turned(n, -n.dot(middle));
    PlanarCuboid c = faceCuboid(wall, 0, u0, u1, 0, 2);
    c.normal = n;
    c.horizontal_axis = (wall.u - n * n.dot(wall.u)).normalized();
    c.centre = middle - n * 0.05f;
    return std::make_pair(c, turned.model());
  };
  const auto planesAfter = [&](const std::pair<PlanarCuboid, Eigen::Vector4f>& b,
                               const PlaneFrame& a_frame, bool level) {
    SurfaceLayer layer(defaultParams());
    layer.integrate({faceCuboid(a_frame, 0, 0, 4, 0, 2)}, PlaneModels{a_frame.model()},
                    Cloud(), {});
    if (level) {
      const PlaneFrame step(a_frame.n, a_frame.d - 0.3f);
      layer.integrate({faceCuboid(step, 0, 1, 3, 0, 2)}, PlaneModels{step.model()},
                      Cloud(), {});
    } else
      layer.integrate({b.first}, PlaneModels{b.second}, Cloud(), {});
    return std::make_pair(layer.getPlanes().size(), layer.getCellCount());
  };
  const auto stacked = planesAfter(second(0.08f, 0.3f, 1, 3), wall, false);
  EXPECT_EQ(stacked.first, 1u);
  EXPECT_EQ(stacked.second, 800u);
  EXPECT_EQ(planesAfter(second(0.08f, 0.3f, 5, 7), wall, false).first, 2u);
  EXPECT_EQ(planesAfter(second(0.08f, 0.7f, 1, 3), wall, false).first, 2u);
  EXPECT_EQ(planesAfter(second(0.3f, 0.3f, 1, 3), wall, false).first, 2u);
  EXPECT_EQ(planesAfter(second(0.0f, 0.45f, 3.6f, 5.6f), wall, false).first, 2u);
  EXPECT_EQ(planesAfter(second(0.0f, 0.45f, 3.2f, 5.2f), wall, false).first, 1u);
  // 1.6 m^2 of evidence against the wall's 8: an object in front of it, or a fragment
  // left to absorbOverlappingPlaneCells()
  EXPECT_EQ(planesAfter(second(0.08f, 0.3f, 1.6f, 2.4f), wall, false).first, 2u);
  const PlaneFrame floor(Eigen::Vector3f::UnitZ(), 1.5f);
  EXPECT_EQ(planesAfter({}, floor, true).first, 2u);
}

// Planes that converge merge. Offsets o along the wall's normal (toward the sensor),
// weights = face areas: frame 1 sees [0, 2] x [0, 4] at o = +0.14 m (weight 8), frame
// 2 sees [0, 2] x [1, 2], inside it, at o = -0.14 (weight 2): the plane fitted to
// both is at o = 0.084, 0.224 m from frame 2's faces (> 0.15 m), so frame 2 starts a
// second map plane (the rasters overlap, the planes differ). Frame 3 sees [0, 5] x
// [0, 2] at o = -0.07 (weight 10): it fits either map plane and joins the nearer,
// the second (their joint plane near o = -0.08, 0.01 m from frame 3's faces, against
// ~0.09 m with the first). Now one plane (near o = 0.007, the mean) explains the
// first's evidence (~0.13 m) and the second's (~0.09 m), and the rasters overlap:
// they merge into one plane. Its raster is the union [0, 5] x [0, 2] + [0, 2] x
// [2, 4] = 1400 cells (all frames share the wall's in-plane axes: no resampling),
// covered by 2 rectangles. (absorb_distance_m is 0.2 m here, below the 0.28 m
// between frames 1 and 2, so that frame 2's plane does not merge at once as a plane
// stacked over the first: StackedParallelPlanesMerge.)
TEST(SurfaceLayer, MapPlanesThatConvergeMerge)
{
  const PlaneFrame wall = wallFrame();
  const auto at = [&wall](float o) {
    return PlaneFrame(wall.n, wall.d - o);
  };
  SurfaceLayer::Params params = defaultParams();
  params.absorb_distance_m = 0.2;
  SurfaceLayer layer(params);
  layer.integrate({faceCuboid(at(0.14f), 0, 0, 2, 0, 4)},
                  PlaneModels{at(0.14f).model()}, Cloud(), {});
  layer.integrate({faceCuboid(at(-0.14f), 0, 0, 2, 1, 2)},
                  PlaneModels{at(-0.14f).model()}, Cloud(), {});
  ASSERT_EQ(layer.getPlanes().size(), 2u);
  layer.integrate({faceCuboid(at(-0.07f), 0, 0, 5, 0, 2)},
                  PlaneModels{at(-0.07f).model()}, Cloud(), {});
  ASSERT_EQ(layer.getPlanes().size(), 1u);
  EXPECT_EQ(layer.getCellCount(), 1400u);
  EXPECT_EQ(layer.getCuboids().size(), 2u);
  // the least-squares plane of all faces: through their area-weighted centroid, at
  // o = 0.007 (tilted a little: the faces at o = +0.14 are all at u < 2)
  const Eigen::Vector4f plane = layer.getPlanes()[0];
  const Eigen::Vector3f n = plane.head<3>();
  double area = 0.0;
  for (const auto& c : layer.getCuboids())
    area += c.faceArea();
  const double scale =
    (wall.u - n * n.dot(wall.u)).norm() * (wall.v - n * n.dot(wall.v)).norm();
  EXPECT_NEAR(area, 14.0 * scale, 1e-3);
  const Eigen::Vector3f centroid =
    (8.0f * at(0.14f).at(1, 2) + 2.0f * at(-0.14f).at(1, 1.5f)
     + 10.0f * at(-0.07f).at(2.5f, 1))
    / 20.0f;
  EXPECT_GT(plane.head<3>().dot(wall.n), std::cos(0.1f));
  EXPECT_NEAR(plane.head<3>().dot(centroid) + plane[3], 0.0f, 1e-4f);
  EXPECT_NEAR(wall.n.dot(centroid) + wall.d, 0.007f, 1e-4f);
}

/** One frame of planar cuboids: its cuboids and plane models. */
struct Frame {
  PlanarCuboids cuboids;
  PlaneModels planes;
};

/** 2 x \a pairs frames of the facade [0, 10] x [0, 4] m of wallFrame(). Pair k sees
 * the window [s, s + 6] x [0, 4], s = 4 k / (pairs - 1), as 1 m blocks, some
 * shrunk by 0.1 m toward the next block (a 1-cell gap) and one inner block missing;
 * its two frames put the same faces on the plane turned by +angle and -angle about an
 * in-plane axis through the window centre, shifted by +offset and -offset: the noise
 * has zero mean exactly. Pair 0: angle = max_angle_rad about the vertical axis,
 * offset = max_offset_m; the others: angle in [max/2, max], any axis, offset in
 * [-max, max]. */
std::vector<Frame>
noisyFacadeFrames(int pairs, unsigned seed, float max_angle_rad, float max_offset_m)
{
  const PlaneFrame truth = wallFrame();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  std::vector<Frame> frames;
  for (int k = 0; k < pairs; ++k) {
    float angle = max_angle_rad, direction = 0.5f * static_cast<float>(M_PI);
    float offset = max_offset_m;
    if (k > 0) {
      angle = max_angle_rad * (0.5f + 0.5f * uni(rng));
      direction = 2.0f * static_cast<float>(M_PI) * uni(rng);
      offset = max_offset_m * (2.0f * uni(rng) - 1.0f);
    }
    const Eigen::Vector3f axis =
      std::cos(direction) * truth.u + std::sin(direction) * truth.v;
    const float s = pairs > 1 ? 4.0f * static_cast<float>(k) / (pairs - 1) : 0.0f;
    std::vector<Rect> faces;
    const int missing = 5 + static_cast<int>(uni(rng) * 14.0f); // bu 1-4, bv 1-2
    for (int bu = 0; bu < 6; ++bu)
      for (int bv = 0; bv < 4; ++bv) {
        const bool inner = bu >= 1 && bu <= 4 && bv >= 1 && bv <= 2;
        const bool shrink_u = uni(rng) < 0.3f, shrink_v = uni(rng) < 0.3f;
        if (inner && (bu - 1) * 2 + (bv - 1) + 5 == missing)
          continue;
        Rect f{s + static_cast<float>(bu), s + static_cast<float>(bu) + 1.0f,
               static_cast<float>(bv), static_cast<float>(bv) + 1.0f};
        if (bu < 5 && shrink_u)
          f.u1 -= 0.1f;
        if (bv < 3 && shrink_v)
          f.v1 -= 0.1f;
        faces.push_back(f);
      }
    for (const float sign : {1.0f, -1.0f}) {
      const Eigen::Vector3f n = Eigen::AngleAxisf(sign * angle, axis) * truth.n;
      const Eigen::Vector3f through =
        truth.at(s + 3.0f, 2.0f) + truth.n * (sign * offset);
      const PlaneFrame noisy(n, -n.dot(through));
      Frame frame;
      frame.planes = {noisy.model()};
      for (const Rect& f : faces) {
        const Eigen::Vector3f target =
          truth.at(0.5f * (f.u0 + f.u1), 0.5f * (f.v0 + f.v1));
        PlanarCuboid c;
        c.normal = n;
        c.horizontal_axis = noisy.u;
        c.width_m = f.u1 - f.u0;
        c.height_m = f.v1 - f.v0;
        c.thickness_m = 0.1f;
        c.centre = target - n * (n.dot(target) + noisy.d) - n * 0.05f;
        c.plane_id = 0;
        c.is_planar = true;
        frame.cuboids.push_back(c);
      }
      frames.push_back(frame);
    }
  }
  return frames;
}

/** Angle between the unit normals of two planes, radians. */
double
normalAngle(const Eigen::Vector3f& a, const Eigen::Vector3f& b)
{
  return std::acos(
    std::min(1.0, static_cast<double>(a.normalized().dot(b.normalized()))));
}

// A 10 m x 4 m facade seen in 20 frames whose plane estimates are off by up to 2 deg
// and 5 cm (zero mean), each frame covering 6 m of it with 1-cell gaps and a missing
// 1 m block: after every frame the layer has ONE map plane; at the end the plane is
// the truth (the faces of each pair are mirror images about it, so the least-squares
// plane is exact up to rounding: bound 0.5 deg and 1 cm, while the first frame's
// estimate is 2 deg and 5 cm off), the raster covers the facade (the union of the
// windows is [0, 10] x [0, 4]; the gaps left by all frames are closed), and it is
// covered by at most 4 rectangles (1 for a perfectly straight border; a border cell
// whose centre lies within a millimetre of a slanted face edge may add a notch).
TEST(SurfaceLayer, NoisyFacadeFramesBecomeOnePlaneFittedToTheTruth)
{
  const PlaneFrame truth = wallFrame();
  const std::vector<Frame> frames =
    noisyFacadeFrames(10, 17, static_cast<float>(2.0 * M_PI / 180.0), 0.05f);
  SurfaceLayer layer(defaultParams());
  for (std::size_t k = 0; k < frames.size(); ++k) {
    layer.integrate(frames[k].cuboids, frames[k].planes, Cloud(), {});
    ASSERT_EQ(layer.getPlanes().size(), 1u) << "after frame " << k;
  }
  const Eigen::Vector4f first = frames[0].planes[0];
  const Eigen::Vector4f plane = layer.getPlanes()[0];
  const Eigen::Vector3f centre = truth.at(5.0f, 2.0f);
  const double first_angle = normalAngle(first.head<3>(), truth.n);
  const double angle = normalAngle(plane.head<3>(), truth.n);
  const double offset = std::abs(plane.head<3>().dot(centre) + plane[3]);
  std::printf("noisy facade: first frame's plane %.3f deg, %.4f m off; the map's "
              "plane %.5f deg, %.5f m off; %zu cells, %zu cuboids\n",
              first_angle * 180.0 / M_PI,
              std::abs(first.head<3>().dot(centre) + first[3]), angle * 180.0 / M_PI,
              offset, layer.getCellCount(), layer.getCuboids().size());
  // the round trip restores the refined planes and moments bit for bit (faces on
  // tilted planes: the moments' products are not symmetric by themselves)
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  SurfaceLayer copy(defaultParams());
  copy.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(copy == layer);
  copy.integrate(frames[3].cuboids, frames[3].planes, Cloud(), {});
  SurfaceLayer again(defaultParams());
  for (std::size_t k = 0; k < frames.size(); ++k)
    again.integrate(frames[k].cuboids, frames[k].planes, Cloud(), {});
  again.integrate(frames[3].cuboids, frames[3].planes, Cloud(), {});
  EXPECT_TRUE(copy == again);
  EXPECT_GT(first_angle, 1.9 * M_PI / 180.0); // what keeping the first frame would give
  EXPECT_LT(angle, 0.5 * M_PI / 180.0);
  EXPECT_LT(offset, 0.01);
  const PlanarCuboids& cuboids = layer.getCuboids();
  EXPECT_LE(cuboids.size(), 4u);
  double area = 0.0;
  for (const auto& c : cuboids)
    area += c.faceArea();
  EXPECT_NEAR(area, 40.0, 0.1 * (10.0 + 4.0)); // within a cell row around the border
  // every point of the facade 0.15 m inside its border is in a cuboid
  for (int i = 0; i <= 97; ++i)
    for (int j = 0; j <= 37; ++j) {
      const Eigen::Vector3f p = truth.at(0.15f + 0.1f * i, 0.15f + 0.1f * j);
      const Eigen::Vector3f on =
        p - plane.head<3>() * (plane.head<3>().dot(p) + plane[3]);
      EXPECT_NE(layer.findCuboid(on - plane.head<3>() * 0.05f), nullptr)
        << i << " " << j;
    }
}

/** Adds the 1-cell face of cell (i, j) of \a wall (resolution 0.1 m) to \a cuboids. */
void
addCell(const PlaneFrame& wall, int i, int j, PlanarCuboids& cuboids)
{
  cuboids.push_back(
    faceCuboid(wall, 0, 0.1f * i, 0.1f * (i + 1), 0.1f * j, 0.1f * (j + 1)));
}

/** Number of cuboids of \a layer containing the centre of cell (i, j) of \a wall,
 * 0.05 m behind the face. */
int
hitsAt(const SurfaceLayer& layer, const PlaneFrame& wall, int i, int j)
{
  const Eigen::Vector3f p =
    wall.at(0.1f * i + 0.05f, 0.1f * j + 0.05f) - wall.n * 0.05f;
  int hits = 0;
  for (const auto& c : layer.getCuboids())
    hits += c.contains(p) ? 1 : 0;
  return hits;
}

// A 20 x 10 cell raster (2 m x 1 m of 1-cell faces) with three 1-cell holes and one
// 2 x 2 hole: with close_gaps_cells = 2 it closes into ONE rectangle of 2 m x 1 m
// (the observed cells stay 200 - 3 - 4 = 193); with 0 no cuboid covers a hole. A
// raster with a 5-cell-wide gap across it (columns 8-12) stays two rectangles with
// close_gaps_cells = 2 and closes with 5.
TEST(SurfaceLayer, GapClosingFillsGapsUpToCloseGapsCells)
{
  const PlaneFrame wall = wallFrame();
  const std::vector<std::pair<int, int>> holes = {{3, 3}, {10, 5}, {15, 2}, {6, 6},
                                                  {7, 6}, {6, 7},  {7, 7}};
  PlanarCuboids holey;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 10; ++j)
      if (std::find(holes.begin(), holes.end(), std::make_pair(i, j)) == holes.end())
        addCell(wall, i, j, holey);
  for (const int close : {2, 0}) {
    SurfaceLayer::Params params;
    params.close_gaps_cells = close;
    SurfaceLayer layer(params);
    layer.integrate(holey, PlaneModels{wall.model()}, Cloud(), {});
    EXPECT_EQ(layer.getCellCount(), 193u);
    if (close == 2) {
      ASSERT_EQ(layer.getCuboids().size(), 1u);
      EXPECT_NEAR(layer.getCuboids()[0].width_m, 2.0f, 1e-5f);
      EXPECT_NEAR(layer.getCuboids()[0].height_m, 1.0f, 1e-5f);
    } else {
      EXPECT_GT(layer.getCuboids().size(), 1u);
    }
    for (const auto& hole : holes)
      EXPECT_EQ(hitsAt(layer, wall, hole.first, hole.second), close == 2 ? 1 : 0);
  }
  PlanarCuboids split;
  for (int i = 0; i < 20; ++i)
    for (int j = 0; j < 10; ++j)
      if (i < 8 || i > 12)
        addCell(wall, i, j, split);
  for (const int close : {2, 5}) {
    SurfaceLayer::Params params;
    params.close_gaps_cells = close;
    SurfaceLayer layer(params);
    layer.integrate(split, PlaneModels{wall.model()}, Cloud(), {});
    EXPECT_EQ(layer.getCuboids().size(), close == 2 ? 2u : 1u);
    for (int i = 8; i <= 12; ++i)
      EXPECT_EQ(hitsAt(layer, wall, i, 4), close == 2 ? 0 : 1) << i;
  }
  // a notch open on one side (the missing corner [0, 3) x [0, 3)) is not a gap
  PlanarCuboids notched;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      if (i >= 3 || j >= 3)
        addCell(wall, i, j, notched);
  SurfaceLayer layer(defaultParams());
  layer.integrate(notched, PlaneModels{wall.model()}, Cloud(), {});
  EXPECT_EQ(layer.getCuboids().size(), 2u);
  EXPECT_EQ(hitsAt(layer, wall, 1, 1), 0);
}

// Oracle for the occupancy propagation (and its row-sweep neighbour search): random
// 30 x 20 rasters, some cells with one feature of random probability; expected: each
// featured cell its feature's probability, the others the mean of their valued
// 8-neighbours layer by layer outward (brute force over a dense grid), 0.5 when
// unreached. Every cuboid's probability is the mean of its cells' values.
TEST(SurfaceLayer, OccupancyPropagationMatchesBruteForce)
{
  const PlaneFrame wall = wallFrame();
  std::mt19937 rng(31);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const int w = 30, h = 20;
  for (int trial = 0; trial < 20; ++trial) {
    std::vector<int> observed(w * h, 0);
    std::vector<double> value(w * h, std::nan(""));
    PlanarCuboids cuboids;
    Cloud features;
    std::vector<float> probabilities;
    const float density = 0.5f + 0.5f * uni(rng), featured = 0.05f + 0.3f * uni(rng);
    for (int y = 0; y < h; ++y)
      for (int x = 0; x < w; ++x) {
        if (!(uni(rng) < density))
          continue;
        observed[y * w + x] = 1;
        addCell(wall, x, y, cuboids);
        if (uni(rng) < featured) {
          const float p = uni(rng);
          value[y * w + x] = p;
          pcl::PointXYZ q;
          q.getVector3fMap() = wall.at(0.1f * x + 0.05f, 0.1f * y + 0.05f);
          features.push_back(q);
          probabilities.push_back(p);
        }
      }
    for (bool changed = true; changed;) {
      changed = false;
      std::vector<double> next = value;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
          if (observed[y * w + x] == 0 || !std::isnan(value[y * w + x]))
            continue;
          double sum = 0.0;
          int valued = 0;
          for (int dy = -1; dy <= 1; ++dy)
            for (int dx = -1; dx <= 1; ++dx) {
              const int nx = x + dx, ny = y + dy;
              if ((dx != 0 || dy != 0) && nx >= 0 && ny >= 0 && nx < w && ny < h
                  && observed[ny * w + nx] != 0 && !std::isnan(value[ny * w + nx])) {
                sum += value[ny * w + nx];
                ++valued;
              }
            }
          if (valued > 0) {
            next[y * w + x] = sum / valued;
            changed = true;
          }
        }
      value = next;
    }
    SurfaceLayer::Params params;
    params.close_gaps_cells = 0;
    params.merge_rule = planar_grid::SurfaceMergeRule::PAPER;
    SurfaceLayer layer(params);
    layer.integrate(cuboids, PlaneModels{wall.model()}, features, probabilities);
    for (const auto& c : layer.getCuboids()) {
      const Rect r = rectIn(wall, c);
      double sum = 0.0;
      int cells = 0;
      for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
          if (observed[y * w + x] != 0 && 0.1f * x + 0.05f > r.u0
              && 0.1f * x + 0.05f < r.u1 && 0.1f * y + 0.05f > r.v0
              && 0.1f * y + 0.05f < r.v1) {
            sum += std::isnan(value[y * w + x]) ? 0.5 : value[y * w + x];
            ++cells;
          }
      ASSERT_GT(cells, 0);
      EXPECT_NEAR(c.probability, sum / cells, 1e-5) << "trial " << trial;
    }
  }
}

/** A random 24 x 16 raster on \a wall (density 0.5-0.95; one class, or two from
 * features of probability 0.2 / 0.8 at the cell centres): one cuboid per observed cell.
 * Returns the class of every cell (i, j), -1 unobserved. */
std::vector<std::vector<int>>
randomRaster(const PlaneFrame& wall,
             bool two_classes,
             std::mt19937& rng,
             PlanarCuboids& cuboids,
             Cloud& features,
             std::vector<float>& probabilities)
{
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const float density = 0.5f + 0.45f * uni(rng);
  std::vector<std::vector<int>> cls(24, std::vector<int>(16, -1));
  for (int i = 0; i < 24; ++i)
    for (int j = 0; j < 16; ++j) {
      if (!(uni(rng) < density))
        continue;
      addCell(wall, i, j, cuboids);
      cls[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] = 1;
      if (two_classes) {
        const bool occupied = uni(rng) < 0.6f;
        cls[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)] =
          occupied ? 1 : 0;
        pcl::PointXYZ q;
        q.getVector3fMap() = wall.at(0.1f * i + 0.05f, 0.1f * j + 0.05f);
        features.push_back(q);
        probabilities.push_back(occupied ? 0.8f : 0.2f);
      }
    }
  return cls;
}

// Oracle: random rasters (24 x 16 cells, densities 0.5-0.95, one or two occupancy
// classes from features of probability 0.2 / 0.8 at the cell centres), no closing.
// Both rules cover exactly the observed cells (every observed cell centre in exactly
// one cuboid, every other in none), each cuboid holds cells of one class, and
// min_rectangles never needs more rectangles than the paper's rule.
TEST(SurfaceLayer, MinRectanglesCoverIsExactAndNoWorseThanThePapers)
{
  const PlaneFrame wall = wallFrame();
  std::mt19937 rng(99);
  std::size_t cells_total = 0, rects_paper = 0, rects_max = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const bool two_classes = trial % 2 == 1;
    PlanarCuboids cuboids;
    Cloud features;
    std::vector<float> probabilities;
    const std::vector<std::vector<int>> cls =
      randomRaster(wall, two_classes, rng, cuboids, features, probabilities);
    std::size_t counts[2] = {0, 0};
    for (const auto rule : {planar_grid::SurfaceMergeRule::PAPER,
                            planar_grid::SurfaceMergeRule::MIN_RECTANGLES}) {
      SurfaceLayer::Params params;
      params.close_gaps_cells = 0;
      params.merge_rule = rule;
      SurfaceLayer layer(params);
      layer.integrate(cuboids, PlaneModels{wall.model()}, features, probabilities);
      const PlanarCuboids& out = layer.getCuboids();
      counts[rule == planar_grid::SurfaceMergeRule::PAPER ? 0 : 1] = out.size();
      for (int i = -1; i <= 24; ++i)
        for (int j = -1; j <= 16; ++j) {
          const int c =
            (i >= 0 && i < 24 && j >= 0 && j < 16)
              ? cls[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]
              : -1;
          const Eigen::Vector3f p =
            wall.at(0.1f * i + 0.05f, 0.1f * j + 0.05f) - wall.n * 0.05f;
          int hits = 0;
          for (const auto& cuboid : out)
            if (cuboid.contains(p)) {
              ++hits;
              if (two_classes) {
                EXPECT_EQ(cuboid.probability >= 0.5f ? 1 : 0, c) << trial;
              }
            }
          ASSERT_EQ(hits, c >= 0 ? 1 : 0)
            << "trial " << trial << " cell " << i << " " << j;
        }
      if (rule == planar_grid::SurfaceMergeRule::PAPER)
        cells_total += layer.getCellCount();
    }
    EXPECT_LE(counts[1], counts[0]) << "trial " << trial;
    rects_paper += counts[0];
    rects_max += counts[1];
  }
  std::printf("random rasters: %zu cells; paper %zu rectangles (%.2f cells each), "
              "min_rectangles %zu (%.2f cells each)\n",
              cells_total, rects_paper,
              static_cast<double>(cells_total) / static_cast<double>(rects_paper),
              rects_max,
              static_cast<double>(cells_total) / static_cast<double>(rects_max));
  EXPECT_LT(rects_max, rects_paper);
}

// Oracle: random rasters (24 x 16 cells, densities 0.5-0.95, one or two occupancy
// classes from features of probability 0.2 / 0.8 at the cell centres), no closing,
// the density rule at D = 0.9 and at 1. Every observed cell centre lies in exactly
// one cuboid, every unobserved one in at most one; at least D of the cell centres
// inside each cuboid are observed cells of one class, whose class the cuboid takes
// when it is above 0.9 (at D = 1: the cover is exact, one class per cuboid). With
// D = 0.9 it needs fewer rectangles than min_rectangles.
TEST(SurfaceLayer, DensityCoverHoldsTheRasterAtItsDensity)
{
  const PlaneFrame wall = wallFrame();
  std::mt19937 rng(42);
  std::size_t rects_exact = 0, rects_dense = 0, rects_fewest = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const bool two_classes = trial % 2 == 1;
    PlanarCuboids cuboids;
    Cloud features;
    std::vector<float> probabilities;
    const std::vector<std::vector<int>> cls =
      randomRaster(wall, two_classes, rng, cuboids, features, probabilities);
    for (const double cover_density : {1.0, 0.9}) {
      SurfaceLayer::Params params;
      params.close_gaps_cells = 0;
      params.merge_rule = planar_grid::SurfaceMergeRule::DENSITY;
      params.cover_density = cover_density;
      SurfaceLayer layer(params);
      layer.integrate(cuboids, PlaneModels{wall.model()}, features, probabilities);
      const PlanarCuboids& out = layer.getCuboids();
      (cover_density == 1.0 ? rects_exact : rects_dense) += out.size();
      std::vector<int> cells_in(out.size(), 0);
      std::vector<std::array<int, 2>> of_class(out.size(), {0, 0});
      for (int i = -1; i <= 24; ++i)
        for (int j = -1; j <= 16; ++j) {
          const int c =
            (i >= 0 && i < 24 && j >= 0 && j < 16)
              ? cls[static_cast<std::size_t>(i)][static_cast<std::size_t>(j)]
              : -1;
          const Eigen::Vector3f p =
            wall.at(0.1f * i + 0.05f, 0.1f * j + 0.05f) - wall.n * 0.05f;
          int hits = 0;
          for (std::size_t k = 0; k < out.size(); ++k)
            if (out[k].contains(p)) {
              ++hits;
              ++cells_in[k];
              if (c >= 0)
                ++of_class[k][c];
            }
          if (c >= 0 || cover_density == 1.0) {
            ASSERT_EQ(hits, c >= 0 ? 1 : 0)
              << "trial " << trial << " cell " << i << " " << j;
          } else {
            ASSERT_LE(hits, 1) << "trial " << trial << " cell " << i << " " << j;
          }
        }
      for (std::size_t k = 0; k < out.size(); ++k) {
        const int major = of_class[k][1] >= of_class[k][0] ? 1 : 0;
        EXPECT_GE(static_cast<double>(of_class[k][major]),
                  cover_density * static_cast<double>(cells_in[k]) - 1e-9)
          << "trial " << trial << " rectangle " << k;
        // the rectangle's probability is its cells' mean of 0.8 and 0.2
        if (two_classes && of_class[k][1 - major] * 10 < cells_in[k]) {
          EXPECT_EQ(out[k].probability >= 0.5f ? 1 : 0, major) << trial;
        }
      }
    }
    SurfaceLayer::Params params;
    params.close_gaps_cells = 0;
    params.merge_rule = planar_grid::SurfaceMergeRule::MIN_RECTANGLES;
    SurfaceLayer layer(params);
    layer.integrate(cuboids, PlaneModels{wall.model()}, features, probabilities);
    rects_fewest += layer.getCuboids().size();
  }
  std::printf("random rasters: density 1: %zu rectangles, density 0.9: %zu, "
              "min_rectangles: %zu\n",
              rects_exact, rects_dense, rects_fewest);
  EXPECT_LT(rects_dense, rects_fewest);
}

/** \a count frames of the facade [0, 10] x [0, 4] m of wallFrame(), each made of 40
 * random faces of 0.3-1.5 m a side (clipped to the facade) on the plane turned by up
 * to \a max_angle_rad about an in-plane axis through the facade centre and shifted by
 * up to \a max_offset_m: a blotchy union with ragged edges and scattered holes, as
 * the frames of a real street leave. */
std::vector<Frame>
blotchyFacadeFrames(int count, unsigned seed, float max_angle_rad, float max_offset_m)
{
  const PlaneFrame truth = wallFrame();
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  std::vector<Frame> frames;
  for (int k = 0; k < count; ++k) {
    const float direction = 2.0f * static_cast<float>(M_PI) * uni(rng);
    const Eigen::Vector3f axis =
      std::cos(direction) * truth.u + std::sin(direction) * truth.v;
    const Eigen::Vector3f n =
      Eigen::AngleAxisf(max_angle_rad * (2.0f * uni(rng) - 1.0f), axis) * truth.n;
    const Eigen::Vector3f through =
      truth.at(5.0f, 2.0f) + truth.n * (max_offset_m * (2.0f * uni(rng) - 1.0f));
    const PlaneFrame noisy(n, -n.dot(through));
    Frame frame;
    frame.planes = {noisy.model()};
    for (int f = 0; f < 40; ++f) {
      const float u0 = 10.0f * uni(rng) - 0.5f, v0 = 4.0f * uni(rng) - 0.5f;
      const float u1 = std::min(10.0f, u0 + 0.3f + 1.2f * uni(rng));
      const float v1 = std::min(4.0f, v0 + 0.3f + 1.2f * uni(rng));
      const float cu0 = std::max(0.0f, u0), cv0 = std::max(0.0f, v0);
      if (u1 - cu0 < 0.05f || v1 - cv0 < 0.05f)
        continue;
      const Eigen::Vector3f target = truth.at(0.5f * (cu0 + u1), 0.5f * (cv0 + v1));
      PlanarCuboid c;
      c.normal = n;
      c.horizontal_axis = noisy.u;
      c.width_m = u1 - cu0;
      c.height_m = v1 - cv0;
      c.thickness_m = 0.1f;
      c.centre = target - n * (n.dot(target) + noisy.d) - n * 0.05f;
      c.plane_id = 0;
      c.is_planar = true;
      frame.cuboids.push_back(c);
    }
    frames.push_back(frame);
  }
  return frames;
}

// Cells per rectangle on a noisy raster: the facade seen in 3 blotchy frames (plane
// noise up to 2 deg and 5 cm), with each rule, without and with the closing (printed
// for the record). Bounds: min_rectangles never needs more rectangles than the
// paper's rule, and with close_gaps_cells = 2 at most 3/4 of the paper's rule's
// without closing (measured: 35 and 55).
TEST(SurfaceLayer, MergeRulesOnANoisyFacade)
{
  const std::vector<Frame> frames =
    blotchyFacadeFrames(3, 5, static_cast<float>(2.0 * M_PI / 180.0), 0.05f);
  double per_rect[2][2] = {{0.0, 0.0}, {0.0, 0.0}};
  std::size_t rects[2][2] = {{0, 0}, {0, 0}};
  for (const int rule : {0, 1})
    for (const int close : {0, 2}) {
      SurfaceLayer::Params params;
      params.merge_rule = rule == 0 ? planar_grid::SurfaceMergeRule::PAPER
                                    : planar_grid::SurfaceMergeRule::MIN_RECTANGLES;
      params.close_gaps_cells = close;
      SurfaceLayer layer(params);
      for (const Frame& f : frames)
        layer.integrate(f.cuboids, f.planes, Cloud(), {});
      ASSERT_EQ(layer.getPlanes().size(), 1u);
      rects[rule][close / 2] = layer.getCuboids().size();
      per_rect[rule][close / 2] = static_cast<double>(layer.getCellCount())
                                  / static_cast<double>(rects[rule][close / 2]);
      std::printf("noisy facade, %s, close_gaps_cells %d: %zu observed cells, %zu "
                  "rectangles, %.1f observed cells per rectangle\n",
                  planar_grid::toString(params.merge_rule).c_str(), close,
                  layer.getCellCount(), rects[rule][close / 2],
                  per_rect[rule][close / 2]);
    }
  EXPECT_LE(rects[1][0], rects[0][0]);
  EXPECT_LE(rects[1][1], rects[0][1]);
  // measured 35 against 55: bound 3/4
  EXPECT_LE(4 * rects[1][1], 3 * rects[0][0]);
  // The paper's D_T on the merge: rectangles at least 90 % observed.
  SurfaceLayer::Params params;
  params.merge_rule = planar_grid::SurfaceMergeRule::DENSITY;
  params.close_gaps_cells = 2;
  SurfaceLayer layer(params);
  for (const Frame& f : frames)
    layer.integrate(f.cuboids, f.planes, Cloud(), {});
  ASSERT_EQ(layer.getPlanes().size(), 1u);
  std::printf("noisy facade, density 0.9, close_gaps_cells 2: %zu rectangles, %.1f "
              "observed cells per rectangle\n",
              layer.getCuboids().size(),
              static_cast<double>(layer.getCellCount())
                / static_cast<double>(layer.getCuboids().size()));
  EXPECT_LT(layer.getCuboids().size(), rects[1][1]);
}

/** A frame: two planes, non-planar boxes and features, seeded. */
void
makeFrame(unsigned seed,
          PlanarCuboids& cuboids,
          PlaneModels& planes,
          Cloud& features,
          std::vector<float>& probabilities)
{
  std::mt19937 rng(seed);
  std::uniform_real_distribution<float> uni(0.0f, 1.0f);
  const PlaneFrame wall = wallFrame();
  const PlaneFrame floor_plane(Eigen::Vector3f::UnitZ(), 0.2f); // z = -0.2
  planes = {wall.model(), floor_plane.model()};
  cuboids.clear();
  for (int k = 0; k < 6; ++k) {
    const float u0 = 4.0f * uni(rng) - 2.0f, v0 = 2.0f * uni(rng);
    cuboids.push_back(
      faceCuboid(wall, 0, u0, u0 + 0.2f + uni(rng), v0, v0 + 0.2f + uni(rng)));
    const float x0 = 4.0f * uni(rng) - 2.0f, y0 = 3.0f * uni(rng);
    cuboids.push_back(
      faceCuboid(floor_plane, 1, x0, x0 + 0.3f + uni(rng), y0, y0 + 0.3f + uni(rng)));
  }
  for (int k = 0; k < 8; ++k) {
    PlanarCuboid c;
    c.centre =
      Eigen::Vector3f(4.0f * uni(rng) - 2.0f, 1.0f + 2.0f * uni(rng), 0.2f + uni(rng));
    c.normal = -Eigen::Vector3f::UnitY();
    c.horizontal_axis = Eigen::Vector3f::UnitX();
    c.width_m = 0.1f + 0.3f * uni(rng);
    c.height_m = 0.1f + 0.3f * uni(rng);
    c.thickness_m = 0.1f + 0.3f * uni(rng);
    cuboids.push_back(c);
  }
  features.clear();
  probabilities.clear();
  for (int k = 0; k < 300; ++k) {
    const PlanarCuboid& c = cuboids[static_cast<std::size_t>(k) % cuboids.size()];
    const Eigen::Vector3f p = c.centre
                              + c.horizontal_axis * (c.width_m * (uni(rng) - 0.5f))
                              + c.verticalAxis() * (c.height_m * (uni(rng) - 0.5f))
                              + c.normal * (c.thickness_m * 0.5f);
    pcl::PointXYZ q;
    q.getVector3fMap() = p;
    features.push_back(q);
    probabilities.push_back(uni(rng));
  }
}

TEST(SurfaceLayer, SameFrameTwiceEqualsOnce)
{
  PlanarCuboids cuboids;
  PlaneModels planes;
  Cloud features;
  std::vector<float> probabilities;
  makeFrame(7, cuboids, planes, features, probabilities);
  SurfaceLayer once(defaultParams()), twice(defaultParams());
  once.integrate(cuboids, planes, features, probabilities);
  twice.integrate(cuboids, planes, features, probabilities);
  (void)twice.getCuboids(); // the list is not held: no effect on the memory
  const std::size_t cells = twice.getCellCount();
  const std::size_t bytes = twice.getMemoryBytes();
  twice.integrate(cuboids, planes, features, probabilities);
  EXPECT_TRUE(sameCuboids(once.getCuboids(), twice.getCuboids()));
  EXPECT_EQ(once.getPlanes().size(), twice.getPlanes().size());
  std::printf("memory once %zu bytes, twice %zu bytes (%zu before)\n",
              once.getMemoryBytes(), twice.getMemoryBytes(), bytes);
  EXPECT_EQ(twice.getCellCount(), cells);
  EXPECT_EQ(twice.getCellCount(), once.getCellCount());
  EXPECT_LE(twice.getMemoryBytes(), bytes + bytes / 10);
  EXPECT_GT(once.getMemoryBytes(), sizeof(SurfaceLayer));
}

// The tiled raster against a brute-force set of cells: random rectangles of whole
// cells (negative indices, across 8 x 8 tile borders) on the plane z = 0, whose frame
// is u = x, v = y, origin 0; features at cell centres, in observed and unobserved
// cells. The serialized cells (sorted by row, then column, with their probability
// sums and feature counts) equal the oracle's, sum for sum.
TEST(SurfaceLayer, RasterCellsAndEvidenceMatchBruteForce)
{
  constexpr float R = 0.1f;
  SurfaceLayer layer(defaultParams());
  const PlaneFrame ground(Eigen::Vector3f::UnitZ(), 0.0f);
  std::map<std::pair<int, int>, std::pair<float, std::uint32_t>> oracle; // (j, i)
  std::mt19937 rng(5);
  std::uniform_int_distribution<int> corner(-40, 40), extent(1, 12), rects(1, 3);
  std::uniform_real_distribution<float> probability(0.0f, 1.0f);
  for (int frame = 0; frame < 25; ++frame) {
    PlanarCuboids cuboids;
    const int count = rects(rng);
    for (int k = 0; k < count; ++k) {
      const int i0 = corner(rng), j0 = corner(rng);
      const int i1 = i0 + extent(rng), j1 = j0 + extent(rng);
      cuboids.push_back(faceCuboid(ground, 0, i0 * R, i1 * R, j0 * R, j1 * R));
      for (int j = j0; j < j1; ++j)
        for (int i = i0; i < i1; ++i)
          oracle.emplace(std::make_pair(j, i), std::make_pair(0.0f, 0u));
    }
    Cloud features;
    std::vector<float> probabilities;
    for (int f = 0; f < 300; ++f) {
      const int i = corner(rng) / 2, j = corner(rng) / 2;
      const float p = probability(rng);
      features.push_back(pcl::PointXYZ((i + 0.5f) * R, (j + 0.5f) * R, 0.0f));
      probabilities.push_back(p);
      const auto it = oracle.find(std::make_pair(j, i));
      if (it != oracle.end()) { // the layer's float sum, one feature at a time
        ++it->second.second;
        it->second.first =
          static_cast<float>(std::min(static_cast<double>(it->second.first) + p,
                                      static_cast<double>(it->second.second)));
      }
    }
    layer.integrate(cuboids, PlaneModels{ground.model()}, features, probabilities);
  }
  ASSERT_EQ(layer.getPlanes().size(), 1u);
  ASSERT_EQ(layer.getCellCount(), oracle.size());
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  // header: magic, version, 6 f64 params, u32, u8, f64, f64, f64, f64, u8, u32; u64
  // planes; the plane's 8 f32 planes and 13 f64 moments; u64 cells
  std::size_t at = 4 + 4 + 6 * 8 + 4 + 1 + 8 + 8 + 8 + 8 + 1 + 4 + 8 + 8 * 4 + 13 * 8;
  std::uint64_t cells = 0;
  std::memcpy(&cells, bytes.data() + at, 8);
  at += 8;
  ASSERT_EQ(cells, oracle.size());
  std::size_t with_features = 0;
  for (const auto& [cell, evidence] : oracle) {
    std::int32_t i = 0, j = 0;
    float sum = 0.0f;
    std::uint16_t features = 0;
    std::memcpy(&i, bytes.data() + at, 4);
    std::memcpy(&j, bytes.data() + at + 4, 4);
    std::memcpy(&sum, bytes.data() + at + 8, 4);
    std::memcpy(&features, bytes.data() + at + 12, 2);
    at += 14;
    ASSERT_EQ(j, cell.first);
    ASSERT_EQ(i, cell.second);
    EXPECT_EQ(features, evidence.second) << i << " " << j;
    EXPECT_EQ(sum, evidence.first) << i << " " << j;
    with_features += features > 0 ? 1 : 0;
  }
  EXPECT_GT(with_features, 50u);
  EXPECT_LT(with_features, oracle.size());
  // decoded: the same cells, and the same bytes again
  SurfaceLayer read(defaultParams());
  read.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(read == layer);
  std::vector<std::uint8_t> again;
  read.serialize(again);
  EXPECT_EQ(again, bytes);
}

// Memory: a featureless 80 x 80-cell wall costs its tiles (24 bytes per 64 cells),
// not bytes per cell; the cuboid list is not held, the query index is held from the
// first query until the next integrate().
TEST(SurfaceLayer, MemoryHoldsTilesAndTheQueryIndexOnlyWhileValid)
{
  SurfaceLayer layer(defaultParams());
  const PlaneFrame wall = wallFrame();
  // 8.0 x 8.0 m starting on a tile border: 80 x 80 cells, 100 tiles
  const PlanarCuboids cuboids{faceCuboid(wall, 0, 0.0f, 8.0f, 0.0f, 8.0f)};
  layer.integrate(cuboids, PlaneModels{wall.model()}, Cloud(), {});
  ASSERT_EQ(layer.getCellCount(), 6400u);
  EXPECT_EQ(layer.getCuboidCount(), 1u); // builds (and caches) the plane's cover
  const std::size_t bytes = layer.getMemoryBytes();
  std::printf("featureless 6400-cell wall: %zu bytes\n", bytes);
  EXPECT_LT(bytes, 6400u / 2 + 2048u); // 14 bytes per cell were 89,600
  const PlanarCuboids all = layer.getCuboids();
  ASSERT_EQ(all.size(), 1u);
  EXPECT_EQ(layer.getMemoryBytes(), bytes);
  ASSERT_NE(layer.findCuboid(all[0].centre), nullptr);
  EXPECT_GE(layer.getMemoryBytes(), bytes + sizeof(PlanarCuboid));
  layer.integrate(cuboids, PlaneModels{wall.model()}, Cloud(), {});
  EXPECT_EQ(layer.getMemoryBytes(), bytes);
}

// Non-planar boxes of several orientations keep their own axes through replacement
// (the last cell moving into a removed one's place), serialization and decoding.
TEST(SurfaceLayer, NonPlanarCellsKeepTheirOrientations)
{
  SurfaceLayer layer(defaultParams());
  const auto box = [](const Eigen::Vector3f& centre, const Eigen::Vector3f& normal,
                      const Eigen::Vector3f& axis) {
    PlanarCuboid c;
    c.centre = centre;
    c.normal = normal.normalized();
    c.horizontal_axis = axis.normalized();
    c.width_m = c.height_m = c.thickness_m = 0.2f;
    c.plane_id = -1;
    return c;
  };
  const Eigen::Vector3f x = Eigen::Vector3f::UnitX(), y = Eigen::Vector3f::UnitY(),
                        z = Eigen::Vector3f::UnitZ();
  const Eigen::Vector3f diagonal(1.0f, 1.0f, 0.0f), across(1.0f, -1.0f, 0.0f);
  PlanarCuboids first;
  for (int k = 0; k < 6; ++k) {
    const Eigen::Vector3f centre(static_cast<float>(k), 0.0f, 1.0f);
    first.push_back(k % 3 == 0   ? box(centre, -y, x)
                    : k % 3 == 1 ? box(centre, z, x)
                                 : box(centre, across, diagonal));
  }
  layer.integrate(first, PlaneModels{}, Cloud(), {});
  // the second frame replaces the boxes at x = 0 and x = 3 (both -y / x) by a box of
  // a new orientation at x = 0
  const PlanarCuboids second{box(Eigen::Vector3f(0.0f, 0.0f, 1.0f), -x, y),
                             box(Eigen::Vector3f(3.0f, 0.0f, 1.0f), -x, y)};
  layer.integrate(second, PlaneModels{}, Cloud(), {});
  // highest removed first, the last cell taking its place: 3 <- 5, then 0 <- 4; then
  // the new cells
  const PlanarCuboids expected{first[4], first[1],  first[2],
                               first[5], second[0], second[1]};
  const PlanarCuboids got = layer.getCuboids();
  ASSERT_EQ(got.size(), expected.size());
  for (std::size_t k = 0; k < got.size(); ++k) {
    EXPECT_EQ(got[k].centre, expected[k].centre) << k;
    EXPECT_EQ(got[k].normal, expected[k].normal) << k;
    EXPECT_EQ(got[k].horizontal_axis, expected[k].horizontal_axis) << k;
    EXPECT_FALSE(got[k].is_planar);
  }
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  SurfaceLayer read(defaultParams());
  read.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(read == layer);
  EXPECT_TRUE(sameCuboids(read.getCuboids(), got));
}

// Two maps with a non-planar cell at the same place and of the same size (one key) but
// another orientation, as two segments of one drive see a bush from two sides: the
// merge keeps one of them, the same one in either direction, so the layer still holds
// one cell per key and its file reads back (the reader refuses two cells of one key).
TEST(SurfaceLayer, MergedNonPlanarCellsOfOneKeyKeepOne)
{
  const auto box = [](const Eigen::Vector3f& normal, const Eigen::Vector3f& axis) {
    PlanarCuboid c;
    c.centre = Eigen::Vector3f(1.05f, 0.05f, 1.05f);
    c.normal = normal.normalized();
    c.horizontal_axis = axis.normalized();
    c.width_m = c.height_m = c.thickness_m = 0.2f;
    c.plane_id = -1;
    return c;
  };
  const Eigen::Vector3f x = Eigen::Vector3f::UnitX(), y = Eigen::Vector3f::UnitY(),
                        z = Eigen::Vector3f::UnitZ();
  // map a also has a cell elsewhere, of a third orientation
  PlanarCuboid elsewhere = box(z, x);
  elsewhere.centre = Eigen::Vector3f(3.0f, 0.0f, 1.0f);
  const PlanarCuboids cells_a{box(-y, x), elsewhere}, cells_b{box(-x, y)};
  SurfaceLayer ab(defaultParams()), ba(defaultParams());
  {
    SurfaceLayer a(defaultParams()), b(defaultParams());
    a.integrate(cells_a, PlaneModels{}, Cloud(), {});
    b.integrate(cells_b, PlaneModels{}, Cloud(), {});
    ab.integrate(cells_a, PlaneModels{}, Cloud(), {});
    ab.merge(b, Eigen::Isometry3d::Identity());
    ba.integrate(cells_b, PlaneModels{}, Cloud(), {});
    ba.merge(a, Eigen::Isometry3d::Identity());
  }
  // by x: the cell at x = 1.05, then the one at x = 3
  const auto sorted = [](PlanarCuboids cuboids) {
    std::sort(cuboids.begin(), cuboids.end(),
              [](const PlanarCuboid& p, const PlanarCuboid& q) {
                return p.centre.x() < q.centre.x();
              });
    return cuboids;
  };
  const PlanarCuboids got = sorted(ab.getCuboids());
  ASSERT_EQ(got.size(), 2u);
  EXPECT_TRUE(sameCuboids(got, sorted(ba.getCuboids())));
  // equal evidence (no features): the smaller geometry stays, normal -x before -y
  EXPECT_EQ(got[0].normal, -x);
  EXPECT_EQ(got[1].normal, z);
  for (const SurfaceLayer* merged : {&ab, &ba}) {
    std::vector<std::uint8_t> bytes;
    merged->serialize(bytes);
    SurfaceLayer read(defaultParams());
    ASSERT_NO_THROW(read.deserialize(bytes.data(), bytes.size()));
    EXPECT_TRUE(sameCuboids(sorted(read.getCuboids()), got));
  }
}

// Row of 3 cells [0, 0.3] x [0, 0.1] on the wall, occupancy_thres 0.6. Features: cell 0
// gets 0.9 and 0.7 (mean 0.8), cell 2 gets 0.2; cell 1 has none and takes the mean of
// its valued neighbours (0.8 + 0.2) / 2 = 0.5. Classes: occupied (0.8), free (0.5,
// 0.2): cuboids [0, 0.1] with 0.8 and [0.1, 0.3] with (0.5 + 0.2) / 2 = 0.35.
TEST(SurfaceLayer, OccupancyIsMeanOfFeaturesElseOfNeighbours)
{
  SurfaceLayer::Params params;
  params.occupancy_thres = 0.6;
  SurfaceLayer layer(params);
  const PlaneFrame wall = wallFrame();
  Cloud features;
  std::vector<float> probabilities;
  const auto add = [&](const Eigen::Vector3f& p, float probability) {
    pcl::PointXYZ q;
    q.getVector3fMap() = p;
    features.push_back(q);
    probabilities.push_back(probability);
  };
  add(wall.at(0.03f, 0.05f) + wall.n * 0.02f, 0.9f);
  add(wall.at(0.07f, 0.02f) - wall.n * 0.05f, 0.7f);
  add(wall.at(0.25f, 0.05f), 0.2f);
  add(wall.at(0.15f, 0.05f) + wall.n * 0.3f, 1.0f); // beyond feature_distance_m
  add(wall.at(0.55f, 0.05f), 1.0f);                 // outside the observed cells
  layer.integrate({faceCuboid(wall, 0, 0.0f, 0.3f, 0.0f, 0.1f)},
                  PlaneModels{wall.model()}, features, probabilities);
  const PlanarCuboids& cuboids = layer.getCuboids();
  ASSERT_EQ(cuboids.size(), 2u);
  EXPECT_NEAR(cuboids[0].width_m, 0.1f, 1e-5f);
  EXPECT_NEAR(cuboids[0].probability, 0.8f, 1e-6f);
  EXPECT_EQ(cuboids[0].point_count, 2u);
  EXPECT_NEAR(cuboids[1].width_m, 0.2f, 1e-5f);
  EXPECT_NEAR(cuboids[1].probability, 0.35f, 1e-6f);
  EXPECT_EQ(cuboids[1].point_count, 1u);

  // non-planar: mean of the features inside the box, 0.5 without any
  SurfaceLayer boxes(params);
  PlanarCuboid box;
  box.centre = Eigen::Vector3f(0, 2, 1);
  box.width_m = box.height_m = box.thickness_m = 0.2f;
  box.normal = -Eigen::Vector3f::UnitY();
  PlanarCuboid empty_box = box;
  empty_box.centre.x() = 3.0f;
  features.clear();
  probabilities.clear();
  add(Eigen::Vector3f(0.05f, 2.0f, 1.05f), 0.3f);
  add(Eigen::Vector3f(-0.05f, 2.05f, 0.95f), 0.5f);
  boxes.integrate({box, empty_box}, PlaneModels{}, features, probabilities);
  ASSERT_EQ(boxes.getCuboids().size(), 2u);
  EXPECT_NEAR(boxes.getCuboids()[0].probability, 0.4f, 1e-6f);
  EXPECT_NEAR(boxes.getCuboids()[1].probability, 0.5f, 1e-6f);
  EXPECT_FALSE(boxes.getCuboids()[0].is_planar);
  EXPECT_EQ(boxes.getCuboids()[0].plane_id, -1);
  // the same box again replaces the cell: no pile-up
  boxes.integrate({box}, PlaneModels{}, features, probabilities);
  EXPECT_EQ(boxes.getCuboids().size(), 2u);
}

TEST(SurfaceLayer, FeaturelessPlaneKeepsHalfAndDifferentClassesAreNotMerged)
{
  const PlaneFrame wall = wallFrame();
  SurfaceLayer layer(defaultParams());
  Cloud features;
  std::vector<float> probabilities;
  // 4 x 2 cells: columns 0-1 occupied (0.9), columns 2-3 free (0.1); the featureless
  // cells of each column pair take their neighbours' means: 0.9 / 0.1 in the same
  // columns except the border pair (cells at i = 1 / 2 see both sides).
  for (int i = 0; i < 4; ++i) {
    pcl::PointXYZ q;
    q.getVector3fMap() = wall.at(0.05f + 0.1f * i, 0.05f);
    features.push_back(q);
    probabilities.push_back(i < 2 ? 0.9f : 0.1f);
  }
  layer.integrate({faceCuboid(wall, 0, 0, 0.4f, 0, 0.2f)}, PlaneModels{wall.model()},
                  features, probabilities);
  // row 0: 0.9 0.9 | 0.1 0.1 (features). Row 1 featureless: (0, 1) neighbours 0.9, 0.9
  // -> 0.9; (1, 1): 0.9, 0.9, 0.1 -> 0.633; (2, 1): 0.9, 0.1, 0.1 -> 0.367; (3, 1):
  // 0.1. Occupied: i < 2 in both rows -> one 0.2 x 0.2 rectangle; free the other.
  const PlanarCuboids& cuboids = layer.getCuboids();
  ASSERT_EQ(cuboids.size(), 2u);
  EXPECT_NEAR(cuboids[0].faceArea(), 0.04f, 1e-5f);
  EXPECT_NEAR(cuboids[0].probability, (0.9f + 0.9f + 0.9f + (1.9f / 3.0f)) / 4.0f,
              1e-5f);
  EXPECT_NEAR(cuboids[1].probability, (0.1f + 0.1f + 0.1f + (1.1f / 3.0f)) / 4.0f,
              1e-5f);

  SurfaceLayer bare(defaultParams());
  bare.integrate({faceCuboid(wall, 0, 0, 0.4f, 0, 0.2f)}, PlaneModels{wall.model()},
                 Cloud(), {});
  ASSERT_EQ(bare.getCuboids().size(), 1u);
  EXPECT_FLOAT_EQ(bare.getCuboids()[0].probability, 0.5f);
}

/** Independent slab test in double: entry distance or -1. */
double
slabEntry(const PlanarCuboid& c, const Eigen::Vector3f& o, const Eigen::Vector3f& d)
{
  const Eigen::Vector3d axes[3] = {c.horizontal_axis.cast<double>(),
                                   c.verticalAxis().cast<double>(),
                                   c.normal.cast<double>()};
  const double half[3] = {0.5 * c.width_m, 0.5 * c.height_m, 0.5 * c.thickness_m};
  const Eigen::Vector3d rel = (o - c.centre).cast<double>();
  const Eigen::Vector3d dir = d.cast<double>().normalized();
  double t0 = 0.0, t1 = std::numeric_limits<double>::infinity();
  for (int k = 0; k < 3; ++k) {
    const double p = rel.dot(axes[k]), q = dir.dot(axes[k]);
    if (std::abs(q) < 1e-12) {
      if (std::abs(p) > half[k])
        return -1.0;
      continue;
    }
    double a = (-half[k] - p) / q, b = (half[k] - p) / q;
    if (a > b)
      std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  return t0 <= t1 ? t0 : -1.0;
}

TEST(SurfaceLayer, FindCuboidAndCastRayMatchBruteForce)
{
  SurfaceLayer layer(defaultParams());
  for (unsigned seed = 1; seed <= 3; ++seed) {
    PlanarCuboids cuboids;
    PlaneModels planes;
    Cloud features;
    std::vector<float> probabilities;
    makeFrame(seed, cuboids, planes, features, probabilities);
    layer.integrate(cuboids, planes, features, probabilities);
  }
  const PlanarCuboids& all = layer.getCuboids();
  ASSERT_GT(all.size(), 20u);
  std::size_t occupied = 0;
  for (const auto& c : all)
    occupied += c.probability >= 0.5f ? 1 : 0;
  ASSERT_GT(occupied, 0u);
  ASSERT_LT(occupied, all.size());

  std::mt19937 rng(42);
  std::uniform_real_distribution<float> x(-2.5f, 2.5f), y(-0.5f, 5.5f), z(-0.5f, 2.5f);
  std::size_t found = 0;
  for (int k = 0; k < 5000; ++k) {
    const Eigen::Vector3f p(x(rng), y(rng), z(rng));
    const PlanarCuboid* expected = nullptr;
    for (const auto& c : all)
      if (c.contains(p)) {
        expected = &c;
        break;
      }
    const PlanarCuboid* got = layer.findCuboid(p);
    ASSERT_EQ(got != nullptr, expected != nullptr) << p.transpose();
    // the lowest index: the same cuboid (the layer's own copy)
    if (expected != nullptr) {
      EXPECT_TRUE(got->centre == expected->centre && got->normal == expected->normal
                  && got->width_m == expected->width_m
                  && got->height_m == expected->height_m
                  && got->plane_id == expected->plane_id
                  && got->probability == expected->probability)
        << p.transpose();
    }
    found += expected != nullptr ? 1 : 0;
  }
  EXPECT_GT(found, 50u);

  std::normal_distribution<float> gauss(0.0f, 1.0f);
  std::size_t hits = 0;
  for (int k = 0; k < 2000; ++k) {
    const Eigen::Vector3f o(x(rng), y(rng) - 3.0f, z(rng));
    const Eigen::Vector3f d(gauss(rng), gauss(rng), gauss(rng));
    const double max_range = 8.0;
    double best = std::numeric_limits<double>::infinity();
    for (const auto& c : all)
      if (c.probability >= 0.5f) {
        const double t = slabEntry(c, o, d);
        if (t >= 0.0 && t <= max_range)
          best = std::min(best, t);
      }
    float distance = -1.0f;
    std::size_t index = 0;
    const bool hit = layer.castRay(o, d * 3.0f, max_range, distance, index);
    // rays grazing within 1e-4 m of a box may differ between float and double
    if (std::isfinite(best) != hit) {
      EXPECT_TRUE(false) << "ray " << k << " expected " << best;
      continue;
    }
    if (!hit)
      continue;
    ++hits;
    EXPECT_NEAR(distance, best, 1e-3);
    ASSERT_LT(index, all.size());
    EXPECT_GE(all[index].probability, 0.5f);
    EXPECT_NEAR(slabEntry(all[index], o, d), best, 1e-3);
  }
  EXPECT_GT(hits, 50u);
  float distance = 0.0f;
  std::size_t index = 0;
  EXPECT_FALSE(layer.castRay(Eigen::Vector3f::Zero(), Eigen::Vector3f::Zero(), 10.0,
                             distance, index));
  EXPECT_EQ(layer.findCuboid(Eigen::Vector3f::Constant(NAN)), nullptr);
}

SurfaceLayer
smallLayer()
{
  SurfaceLayer layer(defaultParams());
  PlanarCuboids cuboids;
  PlaneModels planes;
  Cloud features;
  std::vector<float> probabilities;
  makeFrame(3, cuboids, planes, features, probabilities);
  cuboids.resize(4);
  cuboids.push_back(cuboids.back());
  cuboids.back().is_planar = false;
  cuboids.back().plane_id = -1;
  for (auto& c : cuboids) {
    c.width_m = std::min(c.width_m, 0.3f);
    c.height_m = std::min(c.height_m, 0.3f);
  }
  layer.integrate(cuboids, planes, features, probabilities);
  return layer;
}

TEST(SurfaceLayer, SerializeRoundTrip)
{
  PlanarCuboids cuboids;
  PlaneModels planes;
  Cloud features;
  std::vector<float> probabilities;
  makeFrame(11, cuboids, planes, features, probabilities);
  SurfaceLayer layer(defaultParams());
  layer.integrate(cuboids, planes, features, probabilities);
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  SurfaceLayer::Params other_params;
  other_params.resolution_m = 0.3;
  SurfaceLayer copy(other_params);
  EXPECT_TRUE(copy != layer);
  copy.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(copy == layer);
  EXPECT_EQ(copy.getParams().resolution_m, 0.1);
  EXPECT_TRUE(sameCuboids(copy.getCuboids(), layer.getCuboids()));
  std::vector<std::uint8_t> again;
  copy.serialize(again);
  EXPECT_EQ(again, bytes);
  // one changed value: one more feature on the wall
  Cloud one;
  pcl::PointXYZ q;
  q.getVector3fMap() = cuboids[0].faceCentre();
  one.push_back(q);
  copy.integrate({cuboids[0]}, PlaneModels{planes[0]}, one, {0.25f});
  EXPECT_TRUE(copy != layer);
  // the new parameters travel with the section; the same cuboids after a refit
  SurfaceLayer::Params paper_params;
  paper_params.close_gaps_cells = 5;
  paper_params.merge_rule = planar_grid::SurfaceMergeRule::PAPER;
  paper_params.absorb_distance_m = 0.0;          // what versions 2 and 3 are read with
  paper_params.skip_isolated_non_planar = false; // and versions 2 to 6
  paper_params.min_plane_cells = 0;              // and versions 2 to 7
  SurfaceLayer paper(paper_params);
  for (unsigned seed = 11; seed <= 13; ++seed) {
    makeFrame(seed, cuboids, planes, features, probabilities);
    paper.integrate(cuboids, planes, features, probabilities);
  }
  bytes.clear();
  paper.serialize(bytes);
  SurfaceLayer paper_copy(defaultParams());
  EXPECT_TRUE(paper_copy != paper);
  paper_copy.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(paper_copy == paper);
  EXPECT_EQ(paper_copy.getParams().close_gaps_cells, 5);
  EXPECT_EQ(paper_copy.getParams().merge_rule, planar_grid::SurfaceMergeRule::PAPER);
  EXPECT_TRUE(sameCuboids(paper_copy.getCuboids(), paper.getCuboids()));
  // a decoded layer continues exactly like the original
  makeFrame(14, cuboids, planes, features, probabilities);
  paper.integrate(cuboids, planes, features, probabilities);
  paper_copy.integrate(cuboids, planes, features, probabilities);
  EXPECT_TRUE(paper_copy == paper);
  EXPECT_TRUE(sameCuboids(paper_copy.getCuboids(), paper.getCuboids()));
  // the density rule and its share travel too, and give the same cuboids
  SurfaceLayer::Params density_params;
  density_params.merge_rule = planar_grid::SurfaceMergeRule::DENSITY;
  density_params.cover_density = 0.7;
  SurfaceLayer dense(density_params);
  for (unsigned seed = 11; seed <= 13; ++seed) {
    makeFrame(seed, cuboids, planes, features, probabilities);
    dense.integrate(cuboids, planes, features, probabilities);
  }
  bytes.clear();
  dense.serialize(bytes);
  SurfaceLayer dense_copy(defaultParams());
  dense_copy.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(dense_copy == dense);
  EXPECT_EQ(dense_copy.getParams().merge_rule, planar_grid::SurfaceMergeRule::DENSITY);
  EXPECT_EQ(dense_copy.getParams().cover_density, 0.7);
  EXPECT_TRUE(sameCuboids(dense_copy.getCuboids(), dense.getCuboids()));
  // version 1 sections (planes without their evidence) are refused, by name
  std::vector<std::uint8_t> old_version = bytes;
  old_version[4] = 1; // the u32 version after the u32 magic
  try {
    paper_copy.deserialize(old_version.data(), old_version.size());
    ADD_FAILURE() << "version 1 accepted";
  } catch (const IOError& e) {
    EXPECT_NE(std::string(e.what()).find("version 1"), std::string::npos) << e.what();
  }
  EXPECT_TRUE(paper_copy == paper); // unchanged
  // version 2 sections (no density rule: no cover_density, absorb_distance_m and
  // terrain_plane_tile_m after the merge_rule byte) still load, with the default
  // cover_density and absorb_distance_m 0; version 3 sections (no absorb_distance_m
  // and terrain_plane_tile_m after the cover_density) with absorb_distance_m 0;
  // version 4 sections (no terrain_plane_tile_m after the absorb_distance_m) with
  // terrain_plane_tile_m 0; version 5 sections (no terrain_cover_density after the
  // terrain_plane_tile_m) with terrain_cover_density = cover_density; version 6
  // sections (no skip_isolated_non_planar after the terrain_cover_density) with it
  // false; version 7 sections (no min_plane_cells after the flag) with 0
  std::vector<std::uint8_t> paper_bytes;
  paper.serialize(paper_bytes);
  const std::size_t density_at = 4 + 4 + 6 * 8 + 4 + 1;
  // a section of an older version: the bytes up to density_at + kept, the version
  // field set, the later parameters left out
  const auto older = [&](std::uint8_t version, std::size_t kept) {
    std::vector<std::uint8_t> bytes_of(paper_bytes.begin(),
                                       paper_bytes.begin() + density_at + kept);
    bytes_of.insert(bytes_of.end(), paper_bytes.begin() + density_at + 37,
                    paper_bytes.end());
    bytes_of[4] = version;
    SurfaceLayer decoded(defaultParams());
    decoded.deserialize(bytes_of.data(), bytes_of.size());
    EXPECT_TRUE(decoded == paper) << "version " << static_cast<int>(version);
    return decoded.getParams();
  };
  older(2, 0);
  EXPECT_EQ(older(3, 8).absorb_distance_m, 0.0);
  EXPECT_EQ(older(4, 16).terrain_plane_tile_m, 0.0);
  EXPECT_EQ(older(5, 24).terrain_cover_density, paper.getParams().cover_density);
  EXPECT_FALSE(older(6, 32).skip_isolated_non_planar);
  EXPECT_EQ(older(7, 33).min_plane_cells, 0);
  // a flag byte other than 0 or 1 is refused
  std::vector<std::uint8_t> bad_flag = paper_bytes;
  bad_flag[density_at + 32] = 2;
  SurfaceLayer bad_target(defaultParams());
  EXPECT_THROW(bad_target.deserialize(bad_flag.data(), bad_flag.size()), IOError);
  // so is a min_plane_cells beyond its range
  std::vector<std::uint8_t> bad_count = paper_bytes;
  const std::uint32_t too_many = 1000001;
  std::memcpy(bad_count.data() + density_at + 33, &too_many, sizeof(too_many));
  EXPECT_THROW(bad_target.deserialize(bad_count.data(), bad_count.size()), IOError);
  // empty layer
  SurfaceLayer empty(defaultParams()), empty_copy(defaultParams());
  bytes.clear();
  empty.serialize(bytes);
  empty_copy.deserialize(bytes.data(), bytes.size());
  EXPECT_TRUE(empty == empty_copy);
}

TEST(SurfaceLayer, TruncatedOrCorruptDataThrowsIOErrorOrLoads)
{
  const SurfaceLayer layer = smallLayer();
  std::vector<std::uint8_t> bytes;
  layer.serialize(bytes);
  ASSERT_LT(bytes.size(), 4000u);
  SurfaceLayer target(defaultParams());
  for (std::size_t n = 0; n < bytes.size(); ++n) {
    EXPECT_THROW(target.deserialize(bytes.data(), n), IOError) << n;
    EXPECT_EQ(target.getCellCount(), 0u); // unchanged on error
  }
  std::vector<std::uint8_t> longer = bytes;
  longer.push_back(0);
  EXPECT_THROW(target.deserialize(longer.data(), longer.size()), IOError);
  EXPECT_THROW(target.deserialize(nullptr, 10), IOError);
  std::mt19937 rng(5);
  std::size_t loaded = 0;
  for (int trial = 0; trial < 3000; ++trial) {
    std::vector<std::uint8_t> bad = bytes;
    const int flips = 1 + trial % 3;
    for (int f = 0; f < flips; ++f)
      bad[rng() % bad.size()] ^= static_cast<std::uint8_t>(1u << (rng() % 8));
    SurfaceLayer victim(defaultParams());
    try {
      victim.deserialize(bad.data(), bad.size());
    } catch (const IOError&) {
      EXPECT_EQ(victim.getCellCount(), 0u);
      continue;
    }
    ++loaded; // a valid layer: every query works
    const PlanarCuboids& cuboids = victim.getCuboids();
    for (const auto& c : cuboids)
      (void)victim.findCuboid(c.centre);
    float distance = 0.0f;
    std::size_t index = 0;
    (void)victim.castRay(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitY(), 20.0,
                         distance, index);
    std::vector<std::uint8_t> out;
    victim.serialize(out);
    EXPECT_GT(victim.getMemoryBytes(), 0u);
  }
  EXPECT_GT(loaded, 0u);
}

TEST(SurfaceLayer, ExportMeshPlyAndVtk)
{
  const SurfaceLayer layer = smallLayer();
  const std::size_t n = layer.getCuboids().size();
  ASSERT_GT(n, 0u);
  const std::string dir = ::testing::TempDir();
  for (const std::string ext : {".ply", ".vtk"}) {
    const std::string path = dir + "/surface_layer_test" + ext;
    layer.exportMesh(path);
    pcl::PolygonMesh mesh;
    if (ext == ".ply")
      ASSERT_EQ(pcl::io::loadPLYFile(path, mesh), 0);
    else
      ASSERT_GT(pcl::io::loadPolygonFileVTK(path, mesh), 0);
    EXPECT_EQ(mesh.polygons.size(), 12 * n) << ext;
    EXPECT_EQ(static_cast<std::size_t>(mesh.cloud.width) * mesh.cloud.height, 8 * n)
      << ext;
    std::remove(path.c_str());
  }
  EXPECT_THROW(layer.exportMesh(dir + "/surface_layer_test.obj"), IOError);
  EXPECT_THROW(layer.exportMesh(dir + "/no_such_folder/x.ply"), IOError);
}

TEST(SurfaceLayer, InvalidParametersThrow)
{
  const auto check = [](void (*change)(SurfaceLayer::Params&)) {
    SurfaceLayer::Params p;
    change(p);
    EXPECT_THROW(SurfaceLayer layer(p), planar_grid::Exception);
  };
  check([](SurfaceLayer::Params& p) { p.resolution_m = 0.0; });
  check([](SurfaceLayer::Params& p) { p.resolution_m = NAN; });
  check([](SurfaceLayer::Params& p) { p.resolution_m = 1e-6; });
  check([](SurfaceLayer::Params& p) { p.thickness_m = -0.1; });
  check([](SurfaceLayer::Params& p) { p.plane_merge_angle_rad = 0.0; });
  check([](SurfaceLayer::Params& p) { p.plane_merge_angle_rad = 2.0; });
  check([](SurfaceLayer::Params& p) { p.plane_merge_distance_m = 0.0; });
  check([](SurfaceLayer::Params& p) { p.occupancy_thres = 1.0; });
  check([](SurfaceLayer::Params& p) { p.occupancy_thres = 0.0; });
  check([](SurfaceLayer::Params& p) { p.feature_distance_m = -1.0; });
  check([](SurfaceLayer::Params& p) { p.close_gaps_cells = -1; });
  check([](SurfaceLayer::Params& p) { p.close_gaps_cells = 33; });
  check([](SurfaceLayer::Params& p) { p.cover_density = 0.4; });
  check([](SurfaceLayer::Params& p) { p.cover_density = 1.01; });
  check([](SurfaceLayer::Params& p) { p.cover_density = NAN; });
  check([](SurfaceLayer::Params& p) {
    p.merge_rule = static_cast<planar_grid::SurfaceMergeRule>(3);
  });
  EXPECT_EQ(planar_grid::surfaceMergeRuleFromString("paper"),
            planar_grid::SurfaceMergeRule::PAPER);
  EXPECT_EQ(planar_grid::surfaceMergeRuleFromString(
              planar_grid::toString(planar_grid::SurfaceMergeRule::MIN_RECTANGLES)),
            planar_grid::SurfaceMergeRule::MIN_RECTANGLES);
  EXPECT_EQ(planar_grid::surfaceMergeRuleFromString(
              planar_grid::toString(planar_grid::SurfaceMergeRule::DENSITY)),
            planar_grid::SurfaceMergeRule::DENSITY);
  EXPECT_THROW(planar_grid::surfaceMergeRuleFromString("greedy"),
               planar_grid::Exception);
  EXPECT_NO_THROW(SurfaceLayer layer(defaultParams()));
}

TEST(SurfaceLayer, DegenerateInputs)
{
  SurfaceLayer layer(defaultParams());
  layer.integrate({}, {}, Cloud(), {});
  EXPECT_TRUE(layer.getCuboids().empty());
  EXPECT_EQ(layer.getCellCount(), 0u);
  EXPECT_EQ(layer.findCuboid(Eigen::Vector3f::Zero()), nullptr);
  float distance = 0.0f;
  std::size_t index = 0;
  EXPECT_FALSE(layer.castRay(Eigen::Vector3f::Zero(), Eigen::Vector3f::UnitX(), 10.0,
                             distance, index));
  const PlaneFrame wall = wallFrame();
  PlanarCuboid out_of_range = faceCuboid(wall, 5, 0, 1, 0, 1); // plane 5 of 1
  PlanarCuboid nan_box = faceCuboid(wall, 0, 0, 1, 0, 1);
  nan_box.centre.x() = NAN;
  Cloud features;
  features.push_back(pcl::PointXYZ(0.5f, 5.0f, 0.5f));
  // probabilities of the wrong size: features ignored
  layer.integrate({out_of_range, nan_box}, PlaneModels{wall.model()}, features, {});
  ASSERT_EQ(layer.getCuboids().size(), 1u);
  EXPECT_FALSE(layer.getCuboids()[0].is_planar);
  EXPECT_FLOAT_EQ(layer.getCuboids()[0].probability, 0.5f);
  layer.clear();
  EXPECT_TRUE(layer.getCuboids().empty());
  EXPECT_TRUE(layer.getPlanes().empty());
}

/** Non-planar boxes (up-aligned, axis-parallel) of edge \a edge tiling the cube
 * [x0, x0 + 2] x [0, 2] x [0, 2]. */
PlanarCuboids
tiledBoxes(float x0, float edge)
{
  PlanarCuboids boxes;
  const int n = static_cast<int>(std::lround(2.0f / edge));
  for (int a = 0; a < n; ++a)
    for (int b = 0; b < n; ++b)
      for (int c = 0; c < n; ++c) {
        PlanarCuboid box;
        box.normal = Eigen::Vector3f::UnitY();
        box.horizontal_axis = Eigen::Vector3f::UnitX();
        box.width_m = box.height_m = box.thickness_m = edge;
        box.centre =
          Eigen::Vector3f(x0 + (a + 0.5f) * edge, (b + 0.5f) * edge, (c + 0.5f) * edge);
        boxes.push_back(box);
      }
  return boxes;
}

// The same 2 m cube split into 8 boxes of 1 m by one frame and 64 boxes of 0.5 m
// (shifted by 0.03 m) by another: after both frames, in either order, the layer holds
// exactly the later frame's cells (bound: no more than one frame's worth), and a box
// outside the cube seen only by the first frame is kept.
TEST(SurfaceLayer, NonPlanarCellsOfANewFrameReplaceOverlappedOnes)
{
  const PlanarCuboids coarse = tiledBoxes(0.0f, 1.0f);
  const PlanarCuboids fine = tiledBoxes(0.03f, 0.5f);
  PlanarCuboids elsewhere = tiledBoxes(10.0f, 2.0f); // one box, x in [10, 12]
  for (const bool coarse_first : {true, false}) {
    SurfaceLayer layer(defaultParams());
    PlanarCuboids first = coarse_first ? coarse : fine;
    const PlanarCuboids& second = coarse_first ? fine : coarse;
    first.push_back(elsewhere[0]);
    layer.integrate(first, {}, Cloud(), {});
    EXPECT_EQ(layer.getCellCount(), first.size());
    layer.integrate(second, {}, Cloud(), {});
    EXPECT_EQ(layer.getCellCount(), second.size() + 1) << coarse_first;
    const PlanarCuboids& out = layer.getCuboids();
    float volume = 0.0f;
    for (const PlanarCuboid& c : out)
      volume += c.volume();
    EXPECT_NEAR(volume, 8.0f + 8.0f, 1e-3f); // the cube once + the box elsewhere
    EXPECT_NE(layer.findCuboid(Eigen::Vector3f(11.0f, 1.0f, 1.0f)), nullptr);
    // the same second frame again changes nothing; the round trip keeps the cells
    layer.integrate(second, {}, Cloud(), {});
    EXPECT_EQ(layer.getCellCount(), second.size() + 1);
    std::vector<std::uint8_t> bytes;
    layer.serialize(bytes);
    SurfaceLayer copy(defaultParams());
    copy.deserialize(bytes.data(), bytes.size());
    EXPECT_TRUE(copy == layer);
    copy.integrate(first, {}, Cloud(), {});
    EXPECT_EQ(copy.getCellCount(), first.size());
  }
}

// A plane of fewer than min_plane_cells observed cells that a frame did not see
// becomes one non-planar box per cell, with the cell's feature evidence: a floor patch
// of three 0.1 m cells beside a 1 m x 1 m wall, the second frame seeing the wall only.
// The patch stays a plane when the second frame sees it too, when it holds
// min_plane_cells cells, or with min_plane_cells 0.
TEST(SurfaceLayer, SmallPlanesAFrameDidNotSeeBecomeNonPlanarBoxes)
{
  const PlaneFrame wall = wallFrame();
  const PlaneFrame floor(Eigen::Vector3f::UnitZ(), 1.5f); // z = -1.5, u = x, v = y
  PlanarCuboids wall_cells;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      wall_cells.push_back(
        faceCuboid(wall, 0, 0.1f * i, 0.1f * i + 0.1f, 0.1f * j, 0.1f * j + 0.1f));
  struct Case {
    const char* name;
    int min_plane_cells;
    int patch_cells;
    bool seen_again;
    bool demoted;
  };
  for (const Case& t :
       {Case{"unseen", 4, 3, false, true}, Case{"seen again", 4, 3, true, false},
        Case{"at the minimum", 4, 4, false, false},
        Case{"no minimum", 0, 1, false, false}}) {
    SCOPED_TRACE(t.name);
    SurfaceLayer::Params params = defaultParams();
    params.resolution_m = 0.1;
    params.thickness_m = 0.1;
    params.skip_isolated_non_planar = false;
    params.min_plane_cells = t.min_plane_cells;
    SurfaceLayer layer(params);
    PlanarCuboids first = wall_cells;
    PlanarCuboids patch;
    for (int i = 0; i < t.patch_cells; ++i)
      patch.push_back(
        faceCuboid(floor, 1, 2.0f + 0.1f * i, 2.1f + 0.1f * i, 0.0f, 0.1f));
    first.insert(first.end(), patch.begin(), patch.end());
    // one feature on the patch's first cell, occupied with probability 0.8
    Cloud feature;
    const Eigen::Vector3f on_first = floor.at(2.05f, 0.05f);
    feature.push_back(pcl::PointXYZ(on_first.x(), on_first.y(), on_first.z()));
    const PlaneModels models{wall.model(), floor.model()};
    layer.integrate(first, models, feature, {0.8f});
    ASSERT_EQ(layer.getPlaneCount(), 2u);
    PlanarCuboids second = wall_cells;
    if (t.seen_again)
      second.insert(second.end(), patch.begin(), patch.end());
    layer.integrate(second, models, Cloud(), {});
    const PlanarCuboids out = layer.getCuboids();
    std::vector<PlanarCuboid> boxes;
    for (const PlanarCuboid& c : out)
      if (!c.is_planar)
        boxes.push_back(c);
    if (!t.demoted) {
      EXPECT_EQ(layer.getPlaneCount(), 2u);
      EXPECT_TRUE(boxes.empty());
      continue;
    }
    ASSERT_EQ(layer.getPlaneCount(), 1u);
    EXPECT_NEAR(std::abs(layer.getPlanes()[0].y()), 1.0f, 1e-4f);
    // the wall's cells are untouched: its cuboids still cover exactly 1 m^2
    float wall_area = 0.0f;
    for (const PlanarCuboid& c : out)
      if (c.is_planar)
        wall_area += c.width_m * c.height_m;
    EXPECT_NEAR(wall_area, 1.0f, 1e-4f);
    ASSERT_EQ(boxes.size(), patch.size());
    for (const PlanarCuboid& cell : patch) {
      const auto match = std::find_if(boxes.begin(), boxes.end(), [&](const auto& b) {
        return b.centre.isApprox(cell.centre, 1e-4f);
      });
      ASSERT_NE(match, boxes.end()) << cell.centre.transpose();
      EXPECT_EQ(match->plane_id, -1);
      EXPECT_NEAR(match->width_m, 0.1f, 1e-5f);
      EXPECT_NEAR(match->height_m, 0.1f, 1e-5f);
      EXPECT_NEAR(match->thickness_m, 0.1f, 1e-5f);
      EXPECT_NEAR(std::abs(match->normal.z()), 1.0f, 1e-5f);
      const bool has_feature = cell.contains(on_first - floor.n * 0.05f);
      EXPECT_EQ(match->point_count, has_feature ? 1u : 0u);
      EXPECT_NEAR(match->probability, has_feature ? 0.8f : 0.5f, 1e-5f);
    }
    // the parameter travels with the section, and the decoded layer is the same
    std::vector<std::uint8_t> bytes;
    layer.serialize(bytes);
    SurfaceLayer copy(defaultParams());
    copy.deserialize(bytes.data(), bytes.size());
    EXPECT_EQ(copy.getParams().min_plane_cells, t.min_plane_cells);
    EXPECT_TRUE(copy == layer);
  }
}

/** Segmentation + cuboids of a cloud in a world frame (up = z), sensor at \a origin. */
void
approximate(const pcl::PointCloud<pcl::PointXYZI>::Ptr& cloud,
            const Eigen::Vector3f& origin,
            PlanarCuboids& cuboids,
            PlaneModels& planes)
{
  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
  // Eq. 11 by distance alone, the sample threshold d_T (the class's defaults are
  // the pipeline's normal test and 0.1 m sample threshold).
  seg.setMaxNormalAngle(0.0);
  seg.setMinNormalAgreement(0.0);
  seg.setMinTerrainSensorHeight(0.0);
  seg.setSampleDistanceThreshold(0.05);
  seg.setInputCloud(cloud);
  seg.setUpAxis(Eigen::Vector3f::UnitZ());
  seg.setDistanceThreshold(0.05);
  seg.setMaxPlanes(8);
  seg.setMinInliers(300);
  seg.setSeed(1);
  planar_grid::PlanarSegments segments;
  seg.segment(segments);
  planar_grid::PlanarCuboidApproximation<pcl::PointXYZI> approx;
  // A non-planar box stops at D_T (the class's 0.25 is the pipeline's).
  approx.setNonPlanarDensityThreshold(0.0);
  approx.setInputCloud(cloud);
  approx.setPlanes(segments);
  approx.setUpAxis(Eigen::Vector3f::UnitZ());
  approx.setSensorOrigin(origin);
  approx.approximate(cuboids);
  planes.clear();
  for (const auto& s : segments) {
    const auto& v = s.model_coefficients.values;
    planes.emplace_back(v[0], v[1], v[2], v[3]);
  }
}

// Real data: Karlsruhe frame 10 (SGBM cloud to 20 m, 0.1 m voxels) in a world frame
// (up = z, camera 1.57 m high, pitched 0.09 rad down, as config/karlsruhe.yaml), seen
// twice, plus the same frame processed after a known rigid motion of the world (0.4 m,
// 0.05 rad yaw) and mapped back: the planes match, the rasters merge.
TEST(SurfaceLayer, KarlsruheFramesMergeIntoFewerCuboids)
{
  const auto pair = planar_grid::bench::loadKarlsruhePair(10);
  if (!pair.ok)
    GTEST_SKIP() << "Karlsruhe frame 10 missing under " << PLANAR_GRID_DATA_DIR;
  pcl::PointCloud<pcl::PointXYZI> dense;
  planar_grid::bench::denseCloud(pair, 20.0, dense);
  // camera (x right, y down, z forward) -> world (x right, y forward, z up)
  Eigen::Matrix3f axes;
  axes << 1, 0, 0, 0, 0, 1, 0, -1, 0;
  Eigen::Affine3f world_T_camera = Eigen::Affine3f::Identity();
  world_T_camera.linear() =
    Eigen::AngleAxisf(-0.09f, Eigen::Vector3f::UnitX()).toRotationMatrix() * axes;
  world_T_camera.translation() = Eigen::Vector3f(0, 0, 1.57f);
  pcl::PointCloud<pcl::PointXYZI>::Ptr world(new pcl::PointCloud<pcl::PointXYZI>);
  {
    pcl::PointCloud<pcl::PointXYZI>::Ptr finite(new pcl::PointCloud<pcl::PointXYZI>);
    for (const auto& p : dense)
      if (std::isfinite(p.x))
        finite->push_back(p);
    pcl::PointCloud<pcl::PointXYZI>::Ptr moved(new pcl::PointCloud<pcl::PointXYZI>);
    pcl::transformPointCloud(*finite, *moved, world_T_camera);
    pcl::VoxelGrid<pcl::PointXYZI> grid;
    grid.setInputCloud(moved);
    grid.setLeafSize(0.1f, 0.1f, 0.1f);
    grid.filter(*world);
  }
  const Eigen::Vector3f sensor = world_T_camera.translation();
  PlanarCuboids cuboids_a, cuboids_b;
  PlaneModels planes_a, planes_b;
  approximate(world, sensor, cuboids_a, planes_a);
  ASSERT_GE(planes_a.size(), 2u);

  Eigen::Affine3f motion = Eigen::Affine3f::Identity();
  motion.linear() =
    Eigen::AngleAxisf(0.05f, Eigen::Vector3f::UnitZ()).toRotationMatrix();
  motion.translation() = Eigen::Vector3f(0.4f, 0.23f, 0.0f);
  pcl::PointCloud<pcl::PointXYZI>::Ptr moved(new pcl::PointCloud<pcl::PointXYZI>);
  pcl::transformPointCloud(*world, *moved, motion);
  approximate(moved, motion * sensor, cuboids_b, planes_b);
  const Eigen::Affine3f back = motion.inverse();
  for (auto& c : cuboids_b) {
    c.centre = back * c.centre;
    c.normal = back.linear() * c.normal;
    c.horizontal_axis = back.linear() * c.horizontal_axis;
  }
  for (auto& p : planes_b) {
    const Eigen::Vector3f n = back.linear() * p.head<3>();
    // n' . x' + d = 0 with x' = motion x: n . x + (n' . t + d) = 0
    p = Eigen::Vector4f(n.x(), n.y(), n.z(),
                        p[3] + p.head<3>().dot(motion.translation()));
  }
  std::size_t planar_a = 0, planar_b = 0;
  for (const auto& c : cuboids_a)
    planar_a += c.is_planar ? 1 : 0;
  for (const auto& c : cuboids_b)
    planar_b += c.is_planar ? 1 : 0;

  SurfaceLayer layer(defaultParams());
  const auto t0 = std::chrono::steady_clock::now();
  layer.integrate(cuboids_a, planes_a, Cloud(), {});
  const auto t1 = std::chrono::steady_clock::now();
  const std::size_t once = layer.getCuboids().size();
  const auto t2 = std::chrono::steady_clock::now();
  layer.integrate(cuboids_a, planes_a, Cloud(), {});
  EXPECT_EQ(layer.getCuboids().size(), once);
  layer.integrate(cuboids_b, planes_b, Cloud(), {});
  const PlanarCuboids& merged = layer.getCuboids();
  std::printf("Karlsruhe frame 10: A %zu cuboids (%zu planar, %zu planes), B %zu (%zu "
              "planar, %zu planes); layer after A %zu, after A+A+B %zu cuboids, %zu "
              "planes, %zu cells, %zu bytes; integrate A %.2f ms, rebuild %.2f ms\n",
              cuboids_a.size(), planar_a, planes_a.size(), cuboids_b.size(), planar_b,
              planes_b.size(), once, merged.size(), layer.getPlanes().size(),
              layer.getCellCount(), layer.getMemoryBytes(),
              std::chrono::duration<double, std::milli>(t1 - t0).count(),
              std::chrono::duration<double, std::milli>(t2 - t1).count());
  EXPECT_LT(merged.size(), cuboids_a.size() + cuboids_b.size());
  EXPECT_LT(layer.getPlanes().size(), planes_a.size() + planes_b.size());
  // coverage: the centre of every planar face of both frames lies in a planar cuboid
  // of the layer, in-plane within 0.05 m (half a cell: faces are marked by cell
  // centres); along the normal within 0.2 m, since the layer's plane is the
  // least-squares plane of all the faces it received, while a face sits at its
  // frame's front-most inlier (measured: up to 0.12 m in front on the road at 20 m).
  std::size_t covered = 0, total = 0;
  for (const PlanarCuboids* frame : {&cuboids_a, &cuboids_b})
    for (const auto& c : *frame) {
      if (!c.is_planar)
        continue;
      ++total;
      const Eigen::Vector3f p = c.faceCentre();
      bool hit = false;
      for (const auto& m : merged) {
        const Eigen::Vector3f q = p - m.centre;
        if (m.is_planar
            && std::abs(q.dot(m.horizontal_axis)) <= 0.5f * m.width_m + 0.05f
            && std::abs(q.dot(m.verticalAxis())) <= 0.5f * m.height_m + 0.05f
            && std::abs(q.dot(m.normal)) <= 0.5f * m.thickness_m + 0.2f) {
          hit = true;
          break;
        }
      }
      covered += hit ? 1 : 0;
    }
  std::printf("planar faces covered: %zu / %zu\n", covered, total);
  EXPECT_GE(covered, total * 95 / 100);
}

/** A non-planar lattice box of nx x ny x nz voxels of 0.1 m whose lowest voxel has
 * the centre \a first (world axes). */
PlanarCuboid
latticeBox(const Eigen::Vector3f& first, int nx = 1, int ny = 1, int nz = 1)
{
  PlanarCuboid c;
  c.normal = Eigen::Vector3f::UnitZ();
  c.horizontal_axis = Eigen::Vector3f::UnitX();
  c.width_m = 0.1f * static_cast<float>(nx);
  c.height_m = 0.1f * static_cast<float>(ny);
  c.thickness_m = 0.1f * static_cast<float>(nz);
  c.centre =
    first
    + 0.05f
        * Eigen::Vector3f(static_cast<float>(nx - 1), static_cast<float>(ny - 1),
                          static_cast<float>(nz - 1));
  c.plane_id = -1;
  c.is_planar = false;
  c.point_count = 5;
  return c;
}

/** Centres of the non-planar cuboids of \a cuboids, rounded to millimetres. */
std::vector<std::array<int, 3>>
nonPlanarCentres(const PlanarCuboids& cuboids)
{
  std::vector<std::array<int, 3>> centres;
  for (const auto& c : cuboids)
    if (!c.is_planar)
      centres.push_back({static_cast<int>(std::lround(c.centre.x() * 1000.0f)),
                         static_cast<int>(std::lround(c.centre.y() * 1000.0f)),
                         static_cast<int>(std::lround(c.centre.z() * 1000.0f))});
  std::sort(centres.begin(), centres.end());
  return centres;
}

TEST(SurfaceLayer, IsolatedOneVoxelNonPlanarCellsAreLeftOut)
{
  // a 2 m wall facing -y with its face at y = 1 (the box reaches to y = 1.1)
  const PlanarCuboid wall =
    planar_grid_test::wallCuboid({20.0f, 1.0f, 1.0f}, -Eigen::Vector3f::UnitY(),
                                 Eigen::Vector3f::UnitX(), 2.0f, 2.0f, 0);
  const PlaneModels planes{Eigen::Vector4f(0.0f, -1.0f, 0.0f, 1.0f)};
  const PlanarCuboids frame{
    wall,
    latticeBox({2.05f, 0.05f, 1.05f}), // alone
    latticeBox({5.05f, 0.05f, 1.05f}),
    latticeBox({5.15f, 0.05f, 1.05f}), // face pair
    latticeBox({8.05f, 0.05f, 1.05f}),
    latticeBox({8.15f, 0.15f, 1.15f}), // corner pair
    latticeBox({11.05f, 0.05f, 1.05f}),
    latticeBox({11.25f, 0.05f, 1.05f}),    // one apart
    latticeBox({14.05f, 0.05f, 1.05f}, 2), // two voxels
    latticeBox({20.05f, 0.95f, 1.05f}),    // on the wall
  };
  const auto mm = [](float x, float y, float z) {
    return std::array<int, 3>{static_cast<int>(std::lround(x * 1000.0f)),
                              static_cast<int>(std::lround(y * 1000.0f)),
                              static_cast<int>(std::lround(z * 1000.0f))};
  };
  std::vector<std::array<int, 3>> kept{
    mm(5.05f, 0.05f, 1.05f), mm(5.15f, 0.05f, 1.05f), mm(8.05f, 0.05f, 1.05f),
    mm(8.15f, 0.15f, 1.15f), mm(14.1f, 0.05f, 1.05f), mm(20.05f, 0.95f, 1.05f)};
  std::sort(kept.begin(), kept.end());

  SurfaceLayer::Params params = defaultParams();
  ASSERT_TRUE(params.skip_isolated_non_planar);
  SurfaceLayer layer(params);
  layer.integrate(frame, planes, Cloud(), {});
  const PlanarCuboids cuboids = layer.getCuboids();
  EXPECT_EQ(nonPlanarCentres(cuboids), kept);
  EXPECT_EQ(layer.getCuboidCount(), cuboids.size());
  // the left-out cells stay stored
  params.skip_isolated_non_planar = false;
  SurfaceLayer every(params);
  every.integrate(frame, planes, Cloud(), {});
  EXPECT_EQ(every.getCellCount(), layer.getCellCount());
  EXPECT_EQ(nonPlanarCentres(every.getCuboids()).size(), 9u);
  EXPECT_EQ(every.getCuboidCount(), cuboids.size() + 3);
  // nothing reaches a left-out cell
  EXPECT_EQ(layer.findCuboid({2.05f, 0.05f, 1.05f}), nullptr);
  EXPECT_NE(every.findCuboid({2.05f, 0.05f, 1.05f}), nullptr);

  // a neighbour seen later brings the lone cell back
  layer.integrate({latticeBox({2.05f, 0.05f, 1.15f})}, PlaneModels{}, Cloud(), {});
  kept.push_back(mm(2.05f, 0.05f, 1.05f));
  kept.push_back(mm(2.05f, 0.05f, 1.15f));
  std::sort(kept.begin(), kept.end());
  EXPECT_EQ(nonPlanarCentres(layer.getCuboids()), kept);

  // the setting travels with the layer; sections before it reported every cell
  std::vector<std::uint8_t> bytes;
  every.serialize(bytes);
  SurfaceLayer copy(defaultParams());
  copy.deserialize(bytes.data(), bytes.size());
  EXPECT_FALSE(copy.getParams().skip_isolated_non_planar);
  EXPECT_EQ(copy.getCuboidCount(), every.getCuboidCount());
  EXPECT_TRUE(copy == every);
}

// The merge of the non-planar cells against a brute-force oracle of its rule: every
// round, every pair of cells overlapping within half a cell on all three axes, smallest
// bounding box first, each cell at most once per round; a pair becomes its bounding
// box when the cells fill min_fill of it and accept() agrees; rounds until none
// merges. Random lattice boxes, so that many merge over several rounds.
TEST(SurfaceLayer, NonPlanarMergeMatchesAllPairsOracle)
{
  SurfaceLayer::Params params = defaultParams();
  params.resolution_m = 0.1;
  params.skip_isolated_non_planar = false;
  for (const unsigned seed : {3u, 11u, 29u}) {
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> position(0, 30), edge(1, 4);
    PlanarCuboids cuboids;
    for (int k = 0; k < 500; ++k) {
      PlanarCuboid c;
      c.normal = Eigen::Vector3f::UnitZ();
      c.horizontal_axis = Eigen::Vector3f::UnitX();
      const Eigen::Vector3f size(0.1f * static_cast<float>(edge(rng)),
                                 0.1f * static_cast<float>(edge(rng)),
                                 0.1f * static_cast<float>(edge(rng)));
      const Eigen::Vector3f corner(0.1f * static_cast<float>(position(rng)),
                                   0.1f * static_cast<float>(position(rng)),
                                   0.1f * static_cast<float>(position(rng)));
      c.centre = corner + 0.5f * size;
      c.width_m = size.x();
      c.height_m = size.y();
      c.thickness_m = size.z();
      c.is_planar = false;
      c.plane_id = -1;
      cuboids.push_back(c);
    }
    SurfaceLayer layer(params);
    layer.integrate(cuboids, PlaneModels{}, Cloud(), {});
    const PlanarCuboids start = layer.getCuboids();
    // The oracle, on the same cells in the same order (local axes = world axes).
    struct Cell {
      Eigen::Vector3f centre, size;
      float filled;
      bool alive;
      Eigen::Vector3f lo() const { return centre - 0.5f * size; }
      Eigen::Vector3f hi() const { return centre + 0.5f * size; }
    };
    std::vector<Cell> cells;
    for (const auto& c : start) {
      const Eigen::Vector3f size(c.width_m, c.height_m, c.thickness_m);
      cells.push_back({c.centre, size, size.prod(), true});
    }
    const float slack = 0.05f;
    const double min_fill = 0.6;
    const auto accept = [](const PlanarCuboid& box) {
      return box.width_m * box.height_m * box.thickness_m <= 0.25f;
    };
    int rounds = 0;
    for (bool merged = true; merged;) {
      merged = false;
      std::vector<std::tuple<float, std::size_t, std::size_t>> pairs;
      for (std::size_t a = 0; a < cells.size(); ++a)
        for (std::size_t b = a + 1; b < cells.size(); ++b) {
          if (!cells[a].alive || !cells[b].alive)
            continue;
          const Eigen::Vector3f lo_a = cells[a].lo(), hi_a = cells[a].hi();
          const Eigen::Vector3f lo_b = cells[b].lo(), hi_b = cells[b].hi();
          bool overlap = true;
          for (int d = 0; d < 3; ++d)
            overlap =
              overlap && lo_b[d] <= hi_a[d] + slack && lo_a[d] <= hi_b[d] + slack;
          if (overlap)
            pairs.emplace_back((hi_a.cwiseMax(hi_b) - lo_a.cwiseMin(lo_b)).prod(), a,
                               b);
        }
      std::sort(pairs.begin(), pairs.end());
      std::vector<char> used(cells.size(), 0);
      for (const auto& [volume, a, b] : pairs) {
        static_cast<void>(volume);
        if (used[a] || used[b])
          continue;
        const Eigen::Vector3f lo = cells[a].lo().cwiseMin(cells[b].lo());
        const Eigen::Vector3f hi = cells[a].hi().cwiseMax(cells[b].hi());
        const Eigen::Vector3f overlap = (cells[a].hi().cwiseMin(cells[b].hi())
                                         - cells[a].lo().cwiseMax(cells[b].lo()))
                                          .cwiseMax(0.0f);
        const float fill = cells[a].filled + cells[b].filled - overlap.prod();
        PlanarCuboid box;
        box.centre = 0.5f * (lo + hi);
        box.width_m = (hi - lo).x();
        box.height_m = (hi - lo).y();
        box.thickness_m = (hi - lo).z();
        if (static_cast<double>(fill) < min_fill * static_cast<double>((hi - lo).prod())
            || !accept(box))
          continue;
        cells[a].centre = box.centre;
        cells[a].size = hi - lo;
        cells[a].filled = fill;
        cells[b].alive = false;
        used[a] = used[b] = 1;
        merged = true;
      }
      ++rounds;
    }
    const auto all = [](const PlanarCuboid&) {
      return true;
    };
    layer.mergeNonPlanarCells(all, accept, min_fill);
    const PlanarCuboids got = layer.getCuboids();
    std::vector<Cell> expected;
    for (const auto& c : cells)
      if (c.alive)
        expected.push_back(c);
    EXPECT_GE(rounds, 3) << "seed " << seed;
    EXPECT_LT(5 * expected.size(), 4 * start.size()) << "seed " << seed;
    ASSERT_EQ(got.size(), expected.size()) << "seed " << seed;
    for (std::size_t k = 0; k < got.size(); ++k) {
      EXPECT_TRUE(got[k].centre.isApprox(expected[k].centre, 1e-6f))
        << "seed " << seed << " cell " << k;
      EXPECT_NEAR(got[k].width_m, expected[k].size.x(), 1e-6f);
      EXPECT_NEAR(got[k].height_m, expected[k].size.y(), 1e-6f);
      EXPECT_NEAR(got[k].thickness_m, expected[k].size.z(), 1e-6f);
    }
  }
}

} // namespace
