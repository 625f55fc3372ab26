// SPDX-License-Identifier: BSD-3-Clause
// The plane precision of PG's planar cells against a known truth: a cell on a flat
// wall is precise, a tilted one or one in empty space is not, mixtures weigh by face
// area, and the k-d tree path agrees with a brute-force oracle.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstddef>
#include <random>

#include "mapping_error_oracle.h"

namespace {

using planar_grid::GroundTruthSurface;
using planar_grid::MappingErrorRegion;
using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::PlanePrecision;
using Cloud = pcl::PointCloud<pcl::PointXYZ>;

constexpr double MAP_RESOLUTION_M = 0.1;
/** \brief Sums of a few face areas (products of floats) agree to this, m^2 or ratio. */
constexpr double AREA_TOLERANCE = 1e-6;

/** \brief The wall x = 1 m over y, z in [0, 2] m, sampled every 0.02 m (101 x 101
 * points): about 300 points within the 0.2 m neighbourhood radius of a sample on it. */
Cloud::Ptr
wallAtOneMetre()
{
  Cloud::Ptr cloud(new Cloud);
  for (int k = 0; k <= 100; ++k)
    for (int j = 0; j <= 100; ++j)
      cloud->push_back(pcl::PointXYZ(1.0f, 0.02f * static_cast<float>(j),
                                     0.02f * static_cast<float>(k)));
  return cloud;
}

/** \brief A planar cuboid whose face (at centre + normal thickness / 2) is centred at
 * \a face_centre, 0.1 m thick, occupied. */
PlanarCuboid
planarCell(const Eigen::Vector3f& face_centre,
           const Eigen::Vector3f& normal,
           const Eigen::Vector3f& horizontal_axis,
           float width_m,
           float height_m)
{
  PlanarCuboid c;
  c.normal = normal.normalized();
  c.horizontal_axis = horizontal_axis.normalized();
  c.thickness_m = 0.1f;
  c.centre = face_centre - c.normal * (0.5f * c.thickness_m);
  c.width_m = width_m;
  c.height_m = height_m;
  c.probability = 0.9f;
  c.is_planar = true;
  c.plane_id = 0;
  return c;
}

/** \brief A 1.0 m x 0.8 m cell lying on the wall at (1, 1, 1), facing -x (toward a
 * sensor at the origin): 10 x 8 face samples of 0.01 m^2 at 0.1 m. */
PlanarCuboid
cellOnWall()
{
  return planarCell(Eigen::Vector3f(1.0f, 1.0f, 1.0f), -Eigen::Vector3f::UnitX(),
                    Eigen::Vector3f::UnitY(), 1.0f, 0.8f);
}

TEST(PlanePrecision, CellOnAFlatWallIsPrecise)
{
  const GroundTruthSurface truth(wallAtOneMetre());
  PlanarCuboids cells{cellOnWall()};
  PlanePrecision p =
    planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_EQ(p.precise_samples, 80u);
  EXPECT_NEAR(p.face_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_NEAR(p.precise_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_DOUBLE_EQ(p.ratio(), 1.0);
  // The normal's sign does not matter (a cell facing +x is on the same surface).
  cells[0].normal = Eigen::Vector3f::UnitX();
  cells[0].centre = Eigen::Vector3f(1.0f, 1.0f, 1.0f) - 0.05f * cells[0].normal;
  p = planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_DOUBLE_EQ(p.ratio(), 1.0);
  // 15 degrees off the wall's normal is within the 20 degree bound.
  const float a15 = 15.0f * static_cast<float>(M_PI) / 180.0f;
  cells[0] =
    planarCell(Eigen::Vector3f(1.0f, 1.0f, 1.0f),
               Eigen::Vector3f(-std::cos(a15), std::sin(a15), 0.0f),
               Eigen::Vector3f(std::sin(a15), std::cos(a15), 0.0f), 0.4f, 0.8f);
  p = planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 32u);
  EXPECT_DOUBLE_EQ(p.ratio(), 1.0);
}

TEST(PlanePrecision, TiltedCellOrCellInEmptySpaceIsNotPrecise)
{
  const GroundTruthSurface truth(wallAtOneMetre());
  // Turned 45 degrees about the vertical through the wall: every face sample sees the
  // wall's normal at 45 degrees.
  const float a45 = 0.25f * static_cast<float>(M_PI);
  PlanarCuboids tilted{planarCell(Eigen::Vector3f(1.0f, 1.0f, 1.0f),
                                  Eigen::Vector3f(-std::cos(a45), std::sin(a45), 0.0f),
                                  Eigen::Vector3f(std::sin(a45), std::cos(a45), 0.0f),
                                  1.0f, 0.8f)};
  PlanePrecision p =
    planar_grid::evaluatePlanePrecision(tilted, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_EQ(p.precise_samples, 0u);
  EXPECT_NEAR(p.face_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_DOUBLE_EQ(p.ratio(), 0.0);
  // By cause: every sample lies within 0.36 m of the wall, inside its 0.4 m
  // neighbourhood, and sees the wall's normal 45 degrees off.
  EXPECT_NEAR(p.misoriented_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_DOUBLE_EQ(p.no_truth_area_m2, 0.0);
  EXPECT_DOUBLE_EQ(p.not_surface_area_m2, 0.0);
  // 1 m in front of the wall, parallel to it: no truth point within 0.2 m.
  PlanarCuboids empty_space{planarCell(Eigen::Vector3f(0.0f, 1.0f, 1.0f),
                                       -Eigen::Vector3f::UnitX(),
                                       Eigen::Vector3f::UnitY(), 1.0f, 0.8f)};
  p = planar_grid::evaluatePlanePrecision(empty_space, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_EQ(p.precise_samples, 0u);
  EXPECT_DOUBLE_EQ(p.ratio(), 0.0);
  EXPECT_NEAR(p.no_truth_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_DOUBLE_EQ(p.misoriented_area_m2, 0.0);
}

TEST(PlanePrecision, MixturesWeighByFaceArea)
{
  const GroundTruthSurface truth(wallAtOneMetre());
  // Half and half: the cell on the wall and one of the same size in empty space.
  PlanarCuboids cells{cellOnWall(), planarCell(Eigen::Vector3f(0.0f, 1.0f, 1.0f),
                                               -Eigen::Vector3f::UnitX(),
                                               Eigen::Vector3f::UnitY(), 1.0f, 0.8f)};
  PlanePrecision p =
    planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 160u);
  EXPECT_EQ(p.precise_samples, 80u);
  EXPECT_NEAR(p.ratio(), 0.5, AREA_TOLERANCE);
  // The empty-space cell shrunk to 0.45 m x 0.45 m: 5 x 5 samples of 0.0081 m^2
  // (0.2025 m^2), so the share by area, 0.8 / 1.0025, differs from the share by count,
  // 80 / 105.
  cells[1].width_m = 0.45f;
  cells[1].height_m = 0.45f;
  p = planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 80u + 25u);
  EXPECT_NEAR(p.face_area_m2, 0.8 + 0.2025, AREA_TOLERANCE);
  EXPECT_NEAR(p.ratio(), 0.8 / 1.0025, AREA_TOLERANCE);
  EXPECT_GT(std::abs(p.ratio() - 80.0 / 105.0), 0.02); // not the count share
  // Non-planar cells and planar ones below the occupancy threshold are not counted.
  PlanarCuboid box = cells[1];
  box.is_planar = false;
  box.plane_id = -1;
  PlanarCuboid free_cell = cells[1];
  free_cell.probability = 0.3f;
  PlanarCuboids ignored{cellOnWall(), box, free_cell};
  p = planar_grid::evaluatePlanePrecision(ignored, 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_DOUBLE_EQ(p.ratio(), 1.0);
}

TEST(PlanePrecision, RegionCountsItsFaceSamplesOnly)
{
  const GroundTruthSurface truth(wallAtOneMetre());
  // The wall cell and the empty-space one; a region y <= 1.0 keeps the 5 left columns
  // of each (y = 0.55 ... 0.95), x >= 0.5 the wall cell alone.
  PlanarCuboids cells{cellOnWall(), planarCell(Eigen::Vector3f(0.0f, 1.0f, 1.0f),
                                               -Eigen::Vector3f::UnitX(),
                                               Eigen::Vector3f::UnitY(), 1.0f, 0.8f)};
  MappingErrorRegion left;
  left.max_m.y() = 1.0f;
  PlanePrecision p =
    planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth, left);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_EQ(p.precise_samples, 40u);
  EXPECT_NEAR(p.face_area_m2, 0.8, AREA_TOLERANCE);
  MappingErrorRegion near_wall;
  near_wall.min_m.x() = 0.5f;
  p =
    planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth, near_wall);
  EXPECT_EQ(p.samples, 80u);
  EXPECT_DOUBLE_EQ(p.ratio(), 1.0);
}

TEST(PlanePrecision, NeedsASurfaceOfEnoughPoints)
{
  // A line of points (no surface: two eigenvalues vanish) and four points of a plane
  // (fewer than five) give no normal; the cell lying on them is not precise.
  Cloud::Ptr line(new Cloud);
  for (int j = 0; j <= 100; ++j)
    line->push_back(pcl::PointXYZ(1.0f, 0.02f * static_cast<float>(j), 1.0f));
  PlanarCuboids cells{cellOnWall()};
  const PlanePrecision on_line = planar_grid::evaluatePlanePrecision(
    cells, 0.5, MAP_RESOLUTION_M, GroundTruthSurface(line));
  EXPECT_DOUBLE_EQ(on_line.ratio(), 0.0);
  // Every sample lies within 0.4 m of the line and sees points that are no surface,
  // in every neighbourhood up to PLANE_PRECISION_MAX_RADIUS_M.
  EXPECT_NEAR(on_line.not_surface_area_m2, 0.8, AREA_TOLERANCE);
  EXPECT_DOUBLE_EQ(on_line.no_truth_area_m2, 0.0);
  EXPECT_DOUBLE_EQ(on_line.misoriented_area_m2, 0.0);
  Cloud::Ptr four(new Cloud);
  for (const float y : {0.95f, 1.05f})
    for (const float z : {0.95f, 1.05f})
      four->push_back(pcl::PointXYZ(1.0f, y, z));
  EXPECT_EQ(planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M,
                                                GroundTruthSurface(four))
              .precise_samples,
            0u);
  // Five: the samples within 0.2 m of all five (a disc about (1, 1, 1)) are precise.
  four->push_back(pcl::PointXYZ(1.0f, 1.0f, 1.0f));
  EXPECT_GT(planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M,
                                                GroundTruthSurface(four))
              .precise_samples,
            0u);
}

TEST(PlanePrecision, DegenerateInputAndBadArguments)
{
  const GroundTruthSurface truth(wallAtOneMetre());
  const PlanePrecision none =
    planar_grid::evaluatePlanePrecision(PlanarCuboids(), 0.5, MAP_RESOLUTION_M, truth);
  EXPECT_EQ(none.samples, 0u);
  EXPECT_DOUBLE_EQ(none.face_area_m2, 0.0);
  EXPECT_TRUE(std::isnan(none.ratio()));
  // A cell with a NaN centre is skipped (a warning), the others still count.
  PlanarCuboids cells{cellOnWall(), cellOnWall()};
  cells[1].centre.x() = std::nanf("");
  EXPECT_EQ(
    planar_grid::evaluatePlanePrecision(cells, 0.5, MAP_RESOLUTION_M, truth).samples,
    80u);
  EXPECT_THROW(planar_grid::evaluatePlanePrecision(cells, 0.5, 0.0, truth),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluatePlanePrecision(cells, 0.5, -0.1, truth),
               planar_grid::Exception);
  EXPECT_THROW(planar_grid::evaluatePlanePrecision(cells, 1.5, MAP_RESOLUTION_M, truth),
               planar_grid::Exception);
  EXPECT_THROW(
    planar_grid::evaluatePlanePrecision(cells, std::nan(""), MAP_RESOLUTION_M, truth),
    planar_grid::Exception);
}

/** \brief A wall x = 0 over y, z in [-2, 2] m sampled every 0.05 m, each point
 * scattered across the wall by a normal distribution of \a sigma_m (a multi-view
 * stereo reference is as thick as its depth noise). */
Cloud::Ptr
thickWall(float sigma_m)
{
  std::mt19937 rng(3);
  std::normal_distribution<float> across(0.0f, sigma_m);
  Cloud::Ptr wall(new Cloud);
  for (int j = -40; j <= 40; ++j)
    for (int i = -40; i <= 40; ++i)
      for (int layer = 0; layer < 2; ++layer)
        wall->push_back(pcl::PointXYZ(across(rng), 0.05f * static_cast<float>(i),
                                      0.05f * static_cast<float>(j)));
  return wall;
}

TEST(PlanePrecision, ThickReferenceOfAWallIsStillAWall)
{
  // Scattered 0.2 m across, the wall's points within 0.4 m of a face sample are no
  // surface (smallest to middle eigenvalue about 0.6); within 0.8 m they are (0.3).
  const GroundTruthSurface truth(thickWall(0.2f));
  PlanarCuboids on_wall{planarCell(Eigen::Vector3f::Zero(), -Eigen::Vector3f::UnitX(),
                                   Eigen::Vector3f::UnitY(), 1.0f, 1.0f)};
  PlanePrecision p = planar_grid::evaluatePlanePrecision(on_wall, 0.5, 0.1, truth);
  EXPECT_GT(p.ratio(), 0.95);
  EXPECT_LT(p.not_surface_area_m2, 0.05);
  // Turned 45 degrees, the same cell meets the wall's normal: misoriented, not
  // "not a surface".
  const float a45 = 0.25f * static_cast<float>(M_PI);
  PlanarCuboids turned{planarCell(
    Eigen::Vector3f::Zero(), Eigen::Vector3f(-std::cos(a45), std::sin(a45), 0.0f),
    Eigen::Vector3f(std::sin(a45), std::cos(a45), 0.0f), 0.6f, 1.0f)};
  p = planar_grid::evaluatePlanePrecision(turned, 0.5, 0.1, truth);
  EXPECT_DOUBLE_EQ(p.ratio(), 0.0);
  EXPECT_GT(p.misoriented_area_m2, 0.9 * p.face_area_m2);
  // A cube of uniformly scattered points (a canopy, clutter) is no surface at any
  // radius: the cell in it is not precise, whatever its normal.
  std::mt19937 rng(5);
  std::uniform_real_distribution<float> inside(-2.0f, 2.0f);
  Cloud::Ptr canopy(new Cloud);
  for (int k = 0; k < 40000; ++k)
    canopy->push_back(pcl::PointXYZ(inside(rng), inside(rng), inside(rng)));
  p =
    planar_grid::evaluatePlanePrecision(on_wall, 0.5, 0.1, GroundTruthSurface(canopy));
  EXPECT_DOUBLE_EQ(p.ratio(), 0.0);
  EXPECT_NEAR(p.not_surface_area_m2, p.face_area_m2, AREA_TOLERANCE);
}

TEST(PlanePrecision, MatchesTheBruteForceOracle)
{
  // A room corner: the floor z = 0 and the wall x = 0 over [0, 2] m, every 0.04 m,
  // with 5 mm of noise, then with 0.15 m (a thick reference: the wider
  // neighbourhoods decide); random planar cells near it, facing the floor's or the
  // wall's normal turned by up to 40 degrees, at two cell sizes (neighbourhood radii
  // from 0.4 m and 0.5 m).
  for (const float sigma_m : {0.005f, 0.15f}) {
    std::mt19937 rng(7);
    std::normal_distribution<float> noise(0.0f, sigma_m);
    Cloud::Ptr corner(new Cloud);
    for (int j = 0; j <= 50; ++j)
      for (int i = 0; i <= 50; ++i) {
        const float s = 0.04f * static_cast<float>(i),
                    t = 0.04f * static_cast<float>(j);
        corner->push_back(pcl::PointXYZ(s, t, noise(rng)));
        corner->push_back(pcl::PointXYZ(noise(rng), s, t));
      }
    const GroundTruthSurface truth(corner);
    std::uniform_real_distribution<float> position(0.0f, 2.0f);
    std::uniform_real_distribution<float> extent(0.1f, 0.7f);
    std::uniform_real_distribution<float> turn(-0.7f, 0.7f); // about 40 degrees
    std::uniform_int_distribution<int> which(0, 1);
    PlanarCuboids cells;
    for (int k = 0; k < 40; ++k) {
      const bool wall = which(rng) == 1;
      const Eigen::Vector3f base =
        wall ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitZ();
      const Eigen::Vector3f axis =
        wall ? Eigen::Vector3f::UnitZ() : Eigen::Vector3f::UnitX();
      const Eigen::Vector3f normal =
        Eigen::AngleAxisf(turn(rng), Eigen::Vector3f::UnitY()) * base;
      const Eigen::Vector3f horizontal = normal.cross(axis).normalized();
      Eigen::Vector3f face(position(rng), position(rng), position(rng));
      face[wall ? 0 : 2] = 0.3f * position(rng) - 0.1f; // within about 0.5 m of it
      cells.push_back(planarCell(face, normal, horizontal, extent(rng), extent(rng)));
    }
    for (const double r : {0.1, 0.25}) {
      const PlanePrecision p =
        planar_grid::evaluatePlanePrecision(cells, 0.5, r, truth);
      const PlanePrecision oracle =
        planar_grid::test::oraclePlanePrecision(*corner, cells, r);
      EXPECT_EQ(p.samples, oracle.samples) << r;
      EXPECT_EQ(p.precise_samples, oracle.precise_samples) << r;
      EXPECT_NEAR(p.face_area_m2, oracle.face_area_m2, AREA_TOLERANCE) << r;
      EXPECT_NEAR(p.precise_area_m2, oracle.precise_area_m2, AREA_TOLERANCE) << r;
      EXPECT_NEAR(p.no_truth_area_m2, oracle.no_truth_area_m2, AREA_TOLERANCE) << r;
      EXPECT_NEAR(p.not_surface_area_m2, oracle.not_surface_area_m2, AREA_TOLERANCE)
        << r;
      EXPECT_NEAR(p.misoriented_area_m2, oracle.misoriented_area_m2, AREA_TOLERANCE)
        << r;
      EXPECT_NEAR(p.precise_area_m2 + p.no_truth_area_m2 + p.not_surface_area_m2
                    + p.misoriented_area_m2,
                  p.face_area_m2, AREA_TOLERANCE)
        << r;
      // Both outcomes occur, so the comparison tests the angle and the spread.
      EXPECT_GT(p.precise_samples, p.samples / 10) << r << " " << sigma_m;
      EXPECT_LT(p.precise_samples, p.samples - p.samples / 10) << r << " " << sigma_m;
    }
  }
}

TEST(GroundTruthSurface, RadiusSearchMatchesBruteForce)
{
  std::mt19937 rng(3);
  std::uniform_real_distribution<float> coord(-1.0f, 1.0f);
  Cloud::Ptr points(new Cloud);
  for (int i = 0; i < 400; ++i)
    points->push_back(pcl::PointXYZ(coord(rng), coord(rng), coord(rng)));
  const GroundTruthSurface truth(points);
  pcl::Indices found;
  for (int q = 0; q < 50; ++q) {
    const Eigen::Vector3f centre(coord(rng), coord(rng), coord(rng));
    std::size_t expected = 0;
    for (const auto& p : points->points)
      expected += (p.getVector3fMap() - centre).squaredNorm() <= 0.3f * 0.3f;
    EXPECT_EQ(truth.radiusSearch(centre, 0.3, found), expected) << q;
    EXPECT_EQ(found.size(), expected) << q;
  }
  EXPECT_EQ(truth.radiusSearch(Eigen::Vector3f::Constant(NAN), 0.3, found), 0u);
  EXPECT_TRUE(found.empty());
  EXPECT_EQ(truth.radiusSearch(Eigen::Vector3f::Zero(), 0.0, found), 0u);
}

} // namespace
