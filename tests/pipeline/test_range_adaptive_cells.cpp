// SPDX-License-Identifier: BSD-3-Clause
// Range-adaptive cells: depth_error_filter's far levels (eq. 4) and
// range_adaptive_cells on a synthetic camera-frame scene with exact labels beyond the
// 0.3 m bound (14.86 m with Karlsruhe's rig): a flat road 1.6 m below the camera, a
// guardrail standing on it, a wall and a few isolated stray points.
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <set>
#include <string>
#include <tuple>
#include <vector>

#include "../test_constants.h"

namespace {

enum FarLabel : int { NEAR_ROAD, FAR_ROAD, GUARDRAIL, FAR_WALL, STRAY };

using planar_grid_test::KARLSRUHE_BASELINE_M;
using planar_grid_test::KARLSRUHE_FOCAL_PX;
constexpr double CAMERA_HEIGHT_M = 1.6;

/** The depth whose eq. 4 error (0.5 px) is \a error_m. */
float
depthOfError(double error_m)
{
  return static_cast<float>(
    std::sqrt(error_m / 0.5 * KARLSRUHE_FOCAL_PX * KARLSRUHE_BASELINE_M));
}

struct FarScene {
  planar_grid::Frame frame;
  std::map<int, std::size_t> count;
};

/** Camera frame: x right, y down, z forward; the road is y = +1.6. Points every 0.05 m;
 * the intensity holds the label. */
FarScene
makeFarScene()
{
  FarScene s;
  auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
  const auto add = [&](float x, float y, float z, FarLabel l) {
    pcl::PointXYZI p;
    p.x = x;
    p.y = y;
    p.z = z;
    p.intensity = static_cast<float>(l);
    cloud->push_back(p);
    ++s.count[l];
  };
  const auto road_y = static_cast<float>(CAMERA_HEIGHT_M);
  for (float z = 5.0f; z < 35.0f; z += 0.05f)
    for (float x = -4.0f; x < 4.0f; x += 0.05f)
      add(x, road_y, z, z < 14.0f ? NEAR_ROAD : FAR_ROAD);
  // A guardrail 0.4-0.8 m above the road at x = -3.5 from 16 to 28 m ahead.
  for (float z = 16.0f; z < 28.0f; z += 0.05f)
    for (float h = 0.4f; h < 0.8f; h += 0.05f)
      add(-3.5f, road_y - h, z, GUARDRAIL);
  // A wall at 24 m ahead, 2-5 m above the road (its foot hidden).
  for (float x = 0.0f; x < 3.0f; x += 0.05f)
    for (float h = 2.0f; h < 5.0f; h += 0.05f)
      add(x, road_y - h, 24.0f, FAR_WALL);
  // Isolated strays above the road, each far from every other point.
  for (int k = 0; k < 5; ++k)
    add(2.0f, road_y - 1.5f, 17.0f + 2.0f * static_cast<float>(k), STRAY);
  s.frame.cloud = cloud;
  s.frame.name = "far scene";
  s.frame.calibration.focal_length_px = KARLSRUHE_FOCAL_PX;
  s.frame.calibration.baseline_m = KARLSRUHE_BASELINE_M;
  // The road as ground_removal reports it: camera frame, normal up (-y), the camera's
  // signed distance its height.
  s.frame.has_ground = true;
  s.frame.ground_coefficients =
    Eigen::Vector4f(0.0f, -1.0f, 0.0f, static_cast<float>(CAMERA_HEIGHT_M));
  return s;
}

void
runFilter(FarScene& s, int far_levels)
{
  planar_grid::PipelineState state;
  const auto* filter = planar_grid::findStage("depth_error_filter");
  ASSERT_NE(filter, nullptr);
  planar_grid::ParamValues fp = planar_grid::defaultParams(filter->params);
  fp.set("max_depth_error_m", 0.3);
  fp.set("far_levels", far_levels);
  filter->create(fp)->process(s.frame, state);
}

void
runCells(FarScene& s, int min_points_per_cell, bool fit_to_points = true)
{
  planar_grid::PipelineState state;
  const auto* cells = planar_grid::findStage("range_adaptive_cells");
  ASSERT_NE(cells, nullptr);
  planar_grid::ParamValues cp = planar_grid::defaultParams(cells->params);
  cp.set("min_cell_size_m", 0.1);
  cp.set("min_points_per_cell", min_points_per_cell);
  cp.set("fit_to_points", fit_to_points);
  cells->create(cp)->process(s.frame, state);
}

} // namespace

// Level l holds the depths whose error is within 0.3 m x 2^l: (14.86, 21.02] m level 1,
// (21.02, 29.72] m level 2; deeper points and the nearer ones are not kept aside.
TEST(RangeAdaptiveCells, FarLevelsFollowTheDepthError)
{
  FarScene s = makeFarScene();
  runFilter(s, 2);
  ASSERT_TRUE(s.frame.far_cloud);
  const auto& far = *s.frame.far_cloud;
  ASSERT_EQ(far.size(), s.frame.far_levels.size());
  const float bound = depthOfError(0.3), level1 = depthOfError(0.6),
              level2 = depthOfError(1.2);
  std::size_t expected = 0;
  for (const auto& p : s.frame.cloud->points)
    EXPECT_FALSE(std::isfinite(p.z) && p.z > bound)
      << "a far point stayed in the cloud";
  FarScene all = makeFarScene();
  for (const auto& p : all.frame.cloud->points)
    expected += p.z > bound && p.z <= level2;
  EXPECT_EQ(far.size(), expected);
  for (std::size_t i = 0; i < far.size(); ++i) {
    const float z = far[i].z;
    const int level = s.frame.far_levels[i];
    EXPECT_EQ(level, z <= level1 ? 1 : 2) << "depth " << z;
    EXPECT_GT(z, bound);
    EXPECT_LE(z, level2);
  }
  // Without far levels nothing is kept aside.
  FarScene none = makeFarScene();
  runFilter(none, 0);
  EXPECT_TRUE(!none.frame.far_cloud || none.frame.far_cloud->empty());
}

// The lattice cells (fit_to_points off) against a brute-force count: every cell holds
// at least min_points_per_cell kept far points and has the size of its level; the road
// beyond the bound makes no cell; every guardrail and wall point in a lattice cell of
// its level with enough points is inside a cell; the isolated strays make none.
TEST(RangeAdaptiveCells, FarStructuresBecomeCoarseCellsAndTheFarRoadGoes)
{
  FarScene s = makeFarScene();
  runFilter(s, 2);
  const std::size_t near_cells = s.frame.cuboids.size();
  const planar_grid::Frame::Cloud::ConstPtr far_before = s.frame.far_cloud;
  runCells(s, 10, false);
  ASSERT_GT(s.frame.cuboids.size(), near_cells);
  const auto& far = *far_before;
  // The frame keeps the far points it mapped: the structures and strays, not the road.
  ASSERT_TRUE(s.frame.far_cloud);
  ASSERT_EQ(s.frame.far_cloud->size(), s.frame.far_levels.size());
  std::map<int, std::size_t> before, after;
  for (const auto& p : far.points)
    ++before[static_cast<int>(p.intensity)];
  for (const auto& p : s.frame.far_cloud->points)
    ++after[static_cast<int>(p.intensity)];
  EXPECT_EQ(after.count(FAR_ROAD), 0u);
  EXPECT_EQ(after[GUARDRAIL], before[GUARDRAIL]);
  EXPECT_EQ(after[FAR_WALL], before[FAR_WALL]);
  EXPECT_EQ(after[STRAY], before[STRAY]);
  const float level1 = depthOfError(0.6);
  std::set<std::tuple<float, float, float>> centres;
  for (std::size_t k = near_cells; k < s.frame.cuboids.size(); ++k) {
    const auto& c = s.frame.cuboids[k];
    EXPECT_FALSE(c.is_planar);
    EXPECT_EQ(c.plane_id, -1);
    // level 1 within 21 m, level 2 beyond: 0.2 m or 0.4 m cubes (a cell may straddle
    // the level boundary by less than its size)
    const float expected_size = c.centre.z() < level1 - 0.4f   ? 0.2f
                                : c.centre.z() > level1 + 0.4f ? 0.4f
                                                               : c.width_m;
    EXPECT_FLOAT_EQ(c.width_m, expected_size);
    EXPECT_FLOAT_EQ(c.height_m, c.width_m);
    EXPECT_FLOAT_EQ(c.thickness_m, c.width_m);
    EXPECT_TRUE(centres.emplace(c.centre.x(), c.centre.y(), c.centre.z()).second)
      << "two cells at one place";
    std::size_t inside = 0;
    for (std::size_t i = 0; i < far.size(); ++i) {
      const auto label = static_cast<int>(far[i].intensity);
      inside += c.contains(far[i].getVector3fMap(), 1e-4f);
      EXPECT_FALSE(label == FAR_ROAD && c.contains(far[i].getVector3fMap(), -1e-4f))
        << "a road point inside a cell at " << c.centre.transpose();
      EXPECT_FALSE(label == STRAY && c.contains(far[i].getVector3fMap(), 0.0f))
        << "a stray point made a cell";
    }
    EXPECT_GE(inside, 10u) << "cell at " << c.centre.transpose();
  }
  // Every guardrail and wall point lies in a cell, except where its lattice cell of
  // the level holds fewer than 10 points (the ends of the rail): at most 5 % of them.
  std::size_t structure = 0, covered = 0;
  for (const auto& p : far.points) {
    const auto label = static_cast<int>(p.intensity);
    if (label != GUARDRAIL && label != FAR_WALL)
      continue;
    ++structure;
    for (std::size_t k = near_cells; k < s.frame.cuboids.size(); ++k)
      if (s.frame.cuboids[k].contains(p.getVector3fMap(), 1e-4f)) {
        ++covered;
        break;
      }
  }
  ASSERT_GT(structure, 0u);
  EXPECT_GE(static_cast<double>(covered), 0.95 * static_cast<double>(structure));
}

// fit_to_points against the lattice cells of the same frame: one box per lattice cell,
// inside it, holding every far point the lattice cell holds, each face within one
// 0.1 m step of a point (brute force over the points), sides multiples of 0.1 m; the
// wall seen face-on at 24 m is one 0.1 m step thick instead of its 0.4 m cell.
TEST(RangeAdaptiveCells, FittedCellsAreTheBoundsOfTheirPointsInsideTheLatticeCells)
{
  FarScene lattice = makeFarScene();
  runFilter(lattice, 2);
  const std::size_t near_cells = lattice.frame.cuboids.size();
  FarScene fitted = lattice;
  runCells(lattice, 10, false);
  runCells(fitted, 10, true);
  ASSERT_EQ(fitted.frame.cuboids.size(), lattice.frame.cuboids.size());
  ASSERT_GT(lattice.frame.cuboids.size(), near_cells);
  const auto& far = *fitted.frame.far_cloud;
  constexpr float r = 0.1f, eps = 1e-4f;
  std::size_t wall_cells = 0;
  for (std::size_t k = near_cells; k < fitted.frame.cuboids.size(); ++k) {
    const auto& box = lattice.frame.cuboids[k];
    const auto& fit = fitted.frame.cuboids[k];
    EXPECT_FALSE(fit.is_planar);
    EXPECT_EQ(fit.point_count, box.point_count);
    const Eigen::Vector3f size(fit.width_m, fit.height_m, fit.thickness_m);
    for (int d = 0; d < 3; ++d) {
      EXPECT_GE(size[d], r - eps);
      EXPECT_LE(size[d], box.width_m + eps);
      EXPECT_NEAR(size[d] / r, std::round(size[d] / r), 1e-3f);
    }
    // the fitted box's corners lie in the lattice cell
    for (int corner = 0; corner < 8; ++corner) {
      const Eigen::Vector3f offset((corner & 1 ? 0.5f : -0.5f) * fit.width_m,
                                   (corner & 2 ? 0.5f : -0.5f) * fit.height_m,
                                   (corner & 4 ? 0.5f : -0.5f) * fit.thickness_m);
      const Eigen::Vector3f p = fit.centre + fit.horizontal_axis * offset.x()
                                + fit.verticalAxis() * offset.y()
                                + fit.normal * offset.z();
      EXPECT_TRUE(box.contains(p, eps))
        << "corner " << corner << " of the box at " << fit.centre.transpose();
    }
    if (std::abs(fit.centre.z() - 24.0f) < 0.2f && fit.centre.y() < -0.5f) {
      ++wall_cells;
      EXPECT_NEAR(std::abs(fit.normal.z()), 1.0f, 1e-5f);
      EXPECT_FLOAT_EQ(box.thickness_m, 0.4f);
      EXPECT_NEAR(fit.thickness_m, r, eps);
    }
    // every point of the lattice cell is in the fitted box, and each face has a point
    // within one step inside it
    const Eigen::Vector3f axes[3] = {fit.horizontal_axis, fit.verticalAxis(),
                                     fit.normal};
    Eigen::Vector3f lo = Eigen::Vector3f::Constant(1e9f), hi = -lo;
    std::size_t inside = 0;
    // the lattice cells of the two levels overlap where the levels meet: a point
    // belongs to the cell of its own level
    const int level = box.width_m > 0.3f ? 2 : 1;
    for (std::size_t i = 0; i < far.size(); ++i) {
      const auto& q = far[i];
      if (fitted.frame.far_levels[i] != level
          || !box.contains(q.getVector3fMap(), -eps))
        continue;
      ++inside;
      EXPECT_TRUE(fit.contains(q.getVector3fMap(), eps))
        << "a point of its lattice cell outside the box at " << fit.centre.transpose();
      for (int d = 0; d < 3; ++d) {
        const float t = axes[d].dot(q.getVector3fMap() - fit.centre);
        lo[d] = std::min(lo[d], t);
        hi[d] = std::max(hi[d], t);
      }
    }
    if (inside == 0)
      continue;
    for (int d = 0; d < 3; ++d) {
      EXPECT_LE(-0.5f * size[d], lo[d] + eps);
      EXPECT_GT(-0.5f * size[d] + r, lo[d] - eps) << "axis " << d;
      EXPECT_GE(0.5f * size[d], hi[d] - eps);
      EXPECT_LT(0.5f * size[d] - r, hi[d] + eps) << "axis " << d;
    }
  }
  EXPECT_GT(wall_cells, 0u);
}

// Without a ground plane there is no terrain rule: the far road makes cells too; with
// no far points the stage adds nothing.
TEST(RangeAdaptiveCells, WithoutGroundTheRoadStaysAndWithoutFarPointsNothingIsAdded)
{
  FarScene s = makeFarScene();
  runFilter(s, 2);
  s.frame.has_ground = false;
  runCells(s, 10);
  std::size_t on_road = 0;
  for (const auto& c : s.frame.cuboids)
    on_road +=
      std::abs(c.centre.y() - static_cast<float>(CAMERA_HEIGHT_M)) < c.height_m;
  EXPECT_GT(on_road, 0u);

  FarScene none = makeFarScene();
  runFilter(none, 0);
  const std::size_t before = none.frame.cuboids.size();
  runCells(none, 10);
  EXPECT_EQ(none.frame.cuboids.size(), before);
}

// With max_plane_depth_error_m at the far levels' bound the far points also stay in
// the cloud for the planes: the guardrail and the wall make planes of their own (eq.
// 11's band projected on each plane's normal, so that the road's takes neither), their
// far points leave the far cloud, and range_adaptive_cells maps no cell over them; the
// far road stays in the far cloud for range_adaptive_cells' terrain rule.
TEST(RangeAdaptiveCells, FarPointsOnAPlaneMakeNoFarCell)
{
  FarScene s = makeFarScene();
  planar_grid::PipelineState state;
  const auto* filter = planar_grid::findStage("depth_error_filter");
  ASSERT_NE(filter, nullptr);
  planar_grid::ParamValues fp = planar_grid::defaultParams(filter->params);
  fp.set("max_depth_error_m", 0.3);
  fp.set("max_plane_depth_error_m", 1.2);
  fp.set("far_levels", 2);
  filter->create(fp)->process(s.frame, state);
  ASSERT_TRUE(s.frame.far_cloud);
  const planar_grid::Frame::Cloud::ConstPtr far_before = s.frame.far_cloud;
  std::map<int, std::size_t> before;
  for (const auto& p : far_before->points)
    ++before[static_cast<int>(p.intensity)];
  ASSERT_GT(before[GUARDRAIL], 0u);
  ASSERT_GT(before[FAR_WALL], 0u);

  // Key features, the planes' hypotheses: every tenth point of the road, the guardrail
  // and the wall (the far points make no hypotheses of the cloud's).
  const FarScene all = makeFarScene();
  for (std::size_t i = 0; i < all.frame.cloud->size(); i += 10) {
    const auto& p = (*all.frame.cloud)[i];
    if (static_cast<int>(p.intensity) == STRAY)
      continue;
    s.frame.features.points.push_back(pcl::PointXYZ(p.x, p.y, p.z));
    s.frame.features.keypoints_left.emplace_back(0.0f, 0.0f, 1.0f);
  }
  const auto* segmentation = planar_grid::findStage("multi_plane_segmentation");
  ASSERT_NE(segmentation, nullptr);
  planar_grid::ParamValues sp = planar_grid::defaultParams(segmentation->params);
  sp.set("sample", std::string("features"));
  sp.set("depth_noise_disparity_px", 0.5);
  sp.set("depth_noise_along_sight", true);
  sp.set("min_inliers", 300);
  sp.set("max_planes", 4);
  sp.set("min_remaining_fraction", 0.0);
  sp.set("cluster_cell_m", 0.1); // as config/eval/kitti_range_adaptive.yaml
  segmentation->create(sp)->process(s.frame, state);

  // The guardrail (x = -3.5) and the wall (z = 24) are planes of their own.
  const auto planeOf = [&](FarLabel label) {
    std::size_t best = 0, count = 0;
    for (std::size_t k = 0; k < s.frame.planes.size(); ++k) {
      std::size_t n = 0;
      for (const auto i : s.frame.planes[k].inliers.indices)
        n += static_cast<int>((*s.frame.cloud)[static_cast<std::size_t>(i)].intensity)
             == label;
      if (n > count) {
        best = k;
        count = n;
      }
    }
    return std::make_pair(best, count);
  };
  const auto rail = planeOf(GUARDRAIL);
  const auto wall = planeOf(FAR_WALL);
  ASSERT_GT(rail.second, 0u);
  ASSERT_GT(wall.second, 0u);
  EXPECT_GT(std::abs(s.frame.planes[rail.first].model_coefficients.values[0]), 0.99f);
  EXPECT_GT(std::abs(s.frame.planes[wall.first].model_coefficients.values[2]), 0.99f);

  std::map<int, std::size_t> after;
  ASSERT_TRUE(s.frame.far_cloud);
  ASSERT_EQ(s.frame.far_cloud->size(), s.frame.far_levels.size());
  for (const auto& p : s.frame.far_cloud->points)
    ++after[static_cast<int>(p.intensity)];
  EXPECT_EQ(after[GUARDRAIL], 0u);
  EXPECT_EQ(after[FAR_WALL], 0u);
  EXPECT_EQ(after[FAR_ROAD], before[FAR_ROAD]);
  EXPECT_EQ(after[STRAY], before[STRAY]);
  // The input far cloud is not changed in place (frame copies share it).
  EXPECT_EQ(far_before->size(),
            before[FAR_ROAD] + before[GUARDRAIL] + before[FAR_WALL] + before[STRAY]);

  const std::size_t cells_before = s.frame.cuboids.size();
  runCells(s, 10);
  for (std::size_t k = cells_before; k < s.frame.cuboids.size(); ++k)
    for (const auto& p : far_before->points)
      EXPECT_FALSE(static_cast<int>(p.intensity) == GUARDRAIL
                   && s.frame.cuboids[k].contains(p.getVector3fMap(), -1e-4f))
        << "a far cell on the guardrail at " << s.frame.cuboids[k].centre.transpose();
}
