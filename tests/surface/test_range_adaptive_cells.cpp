// SPDX-License-Identifier: BSD-3-Clause
// RangeAdaptiveCells: far points as non-planar cells whose size doubles with their
// level, and the far terrain left out, against hand-computed lattices.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/range_adaptive_cells.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstdint>
#include <vector>

namespace {

using planar_grid::PlanarCuboid;
using planar_grid::PlanarCuboids;
using planar_grid::RangeAdaptiveCells;

/** \a per_side^3 points on a regular grid inside the box [lo, hi). */
RangeAdaptiveCells::Points
boxPoints(const Eigen::Vector3f& lo, const Eigen::Vector3f& hi, int per_side)
{
  RangeAdaptiveCells::Points points;
  for (int i = 0; i < per_side; ++i)
    for (int j = 0; j < per_side; ++j)
      for (int k = 0; k < per_side; ++k) {
        const Eigen::Vector3f t((i + 0.5f) / per_side, (j + 0.5f) / per_side,
                                (k + 0.5f) / per_side);
        points.emplace_back(lo + (hi - lo).cwiseProduct(t));
      }
  return points;
}

/** The cell's axis-aligned bounds (every cell here has axes along the world's). */
void
bounds(const PlanarCuboid& c, Eigen::Vector3f& lo, Eigen::Vector3f& hi)
{
  Eigen::Vector3f half = Eigen::Vector3f::Zero();
  for (const auto& corner : c.corners())
    half = half.cwiseMax((corner - c.centre).cwiseAbs());
  lo = c.centre - half;
  hi = c.centre + half;
}

TEST(RangeAdaptiveCells, ACellPerOccupiedLatticeCellOfItsLevel)
{
  RangeAdaptiveCells::Params params;
  params.min_cell_size_m = 0.5;
  params.min_points_per_cell = 5;
  params.fit_to_points = false;
  RangeAdaptiveCells cells(params);
  cells.setSensorOrigin(Eigen::Vector3f(0.25f, 0.25f, 0.25f));
  // Level 0 points inside the lattice cell [0.25, 0.75)^3 + (20, 0, 0); level 2 points
  // inside the 2 m cell [20.25, 22.25) x [0.25, 2.25) x [0.25, 2.25); and 4 points of
  // level 1, too few for a cell.
  RangeAdaptiveCells::Points points =
    boxPoints({20.3f, 0.3f, 0.3f}, {20.7f, 0.7f, 0.7f}, 2); // 8 points, level 0
  const auto far = boxPoints({20.5f, 0.5f, 0.5f}, {22.0f, 2.0f, 2.0f}, 3); // 27
  points.insert(points.end(), far.begin(), far.end());
  std::vector<std::uint8_t> levels(8, 0);
  levels.resize(35, 2);
  for (int i = 0; i < 4; ++i) {
    points.emplace_back(30.1f + 0.01f * i, 0.3f, 0.3f);
    levels.push_back(1);
  }
  std::vector<std::uint8_t> terrain;
  PlanarCuboids out;
  ASSERT_EQ(cells.compute(points, levels, terrain, out), 2u);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_EQ(std::count(terrain.begin(), terrain.end(), 1), 0);
  // Sorted by level first.
  Eigen::Vector3f lo, hi;
  bounds(out[0], lo, hi);
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3f(20.25f, 0.25f, 0.25f), 1e-5f));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3f(20.75f, 0.75f, 0.75f), 1e-5f));
  EXPECT_EQ(out[0].point_count, 8u);
  bounds(out[1], lo, hi);
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3f(20.25f, 0.25f, 0.25f), 1e-5f));
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3f(22.25f, 2.25f, 2.25f), 1e-5f));
  EXPECT_EQ(out[1].point_count, 27u);
  for (const auto& c : out) {
    EXPECT_FALSE(c.is_planar);
    EXPECT_EQ(c.plane_id, -1);
    EXPECT_TRUE(c.verticalAxis().isApprox(Eigen::Vector3f::UnitZ(), 1e-6f));
  }
}

TEST(RangeAdaptiveCells, FitToPointsShrinksACoarseCellToItsPoints)
{
  RangeAdaptiveCells::Params params;
  params.min_cell_size_m = 0.5;
  params.min_points_per_cell = 5;
  RangeAdaptiveCells cells(params);
  // A thin wall in a 2 m cell of level 2: x from 0.6 to 0.9 (sub-cell [0.5, 1.0)),
  // y and z over the whole cell.
  const auto points = boxPoints({0.6f, 0.1f, 0.1f}, {0.9f, 1.9f, 1.9f}, 4);
  std::vector<std::uint8_t> terrain;
  PlanarCuboids out;
  ASSERT_EQ(
    cells.compute(points, std::vector<std::uint8_t>(points.size(), 2), terrain, out),
    1u);
  Eigen::Vector3f lo, hi;
  bounds(out[0], lo, hi);
  EXPECT_TRUE(lo.isApprox(Eigen::Vector3f(0.5f, 0.0f, 0.0f), 1e-5f)) << lo.transpose();
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3f(1.0f, 2.0f, 2.0f), 1e-5f)) << hi.transpose();
  // Level 0 cells are never shrunk: they are the minimum cell already.
  params.fit_to_points = false;
  cells.setParams(params);
  out.clear();
  cells.compute(points, std::vector<std::uint8_t>(points.size(), 2), terrain, out);
  bounds(out[0], lo, hi);
  EXPECT_TRUE(hi.isApprox(Eigen::Vector3f(2.0f, 2.0f, 2.0f), 1e-5f)) << hi.transpose();
}

TEST(RangeAdaptiveCells, TheFarTerrainMakesNoCell)
{
  RangeAdaptiveCells::Params params;
  params.min_cell_size_m = 0.5;
  params.min_points_per_cell = 5;
  params.terrain_height_m = 0.3;
  params.terrain_cell_m = 2.0;
  params.terrain_max_rise_m = 1.0;
  RangeAdaptiveCells cells(params);
  // The ground z = -1.5 under a sensor at the origin: height = z + 1.5.
  cells.setGroundPlane(Eigen::Vector4f(0.0f, 0.0f, 1.0f, 1.5f));
  // A road patch at heights 0-0.2 (terrain), a post on it up to 2 m (kept above the
  // band), and a crown whose column's lowest point is 3 m up (its foot unseen: kept
  // above terrain_max_rise + terrain_height, 1.3 m, so all of it).
  RangeAdaptiveCells::Points points =
    boxPoints({20.1f, 0.1f, -1.5f}, {21.9f, 1.9f, -1.3f}, 4); // 64 road points
  const auto post = boxPoints({20.9f, 0.9f, -1.0f}, {21.1f, 1.1f, 0.5f}, 3); // 27
  const auto crown = boxPoints({30.1f, 0.1f, 1.5f}, {31.9f, 1.9f, 2.5f}, 3); // 27
  points.insert(points.end(), post.begin(), post.end());
  points.insert(points.end(), crown.begin(), crown.end());
  // Level 3: cells of 4 m, so that each object is one or two cells.
  const std::vector<std::uint8_t> levels(points.size(), 3);
  std::vector<std::uint8_t> terrain;
  PlanarCuboids out;
  cells.compute(points, levels, terrain, out);
  ASSERT_EQ(terrain.size(), points.size());
  for (std::size_t i = 0; i < points.size(); ++i)
    EXPECT_EQ(terrain[i], i < 64 ? 1 : 0) << i << " at height " << points[i].z() + 1.5f;
  // The post below z = 0 (18 points), above it (9) and the crown (27): every point
  // but the road's in a cell.
  ASSERT_EQ(out.size(), 3u);
  std::vector<std::size_t> counts;
  for (const auto& c : out)
    counts.push_back(c.point_count);
  std::sort(counts.begin(), counts.end());
  EXPECT_EQ(counts, (std::vector<std::size_t>{9, 18, 27}));
  // Without the ground plane nothing is terrain.
  cells.clearGroundPlane();
  out.clear();
  cells.compute(points, levels, terrain, out);
  EXPECT_EQ(std::count(terrain.begin(), terrain.end(), 1), 0);
  counts.clear();
  for (const auto& c : out)
    counts.push_back(c.point_count);
  std::sort(counts.begin(), counts.end());
  EXPECT_EQ(counts, (std::vector<std::size_t>{9, 27, 64 + 18}));
}

TEST(RangeAdaptiveCells, BadInputThrows)
{
  RangeAdaptiveCells cells;
  std::vector<std::uint8_t> terrain;
  PlanarCuboids out;
  const RangeAdaptiveCells::Points points(3, Eigen::Vector3f(10.0f, 0.0f, 0.0f));
  EXPECT_THROW(cells.compute(points, {0, 0}, terrain, out), planar_grid::Exception);
  EXPECT_THROW(cells.compute(points, {0, 0, 16}, terrain, out), planar_grid::Exception);
  EXPECT_TRUE(out.empty());
  RangeAdaptiveCells::Params params;
  params.min_cell_size_m = 0.0;
  EXPECT_THROW(cells.setParams(params), planar_grid::Exception);
  EXPECT_EQ(cells.getParams().min_cell_size_m, 0.1); // unchanged
  EXPECT_THROW(cells.setUpAxis(Eigen::Vector3f::Zero()), planar_grid::Exception);
}

} // namespace
