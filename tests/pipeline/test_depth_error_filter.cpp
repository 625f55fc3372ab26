// SPDX-License-Identifier: BSD-3-Clause
// depth_error_filter's two bounds with multi_plane_segmentation and the cuboid
// approximation, on a synthetic camera-frame scene with exact labels: a side wall
// running from 5 m to 18 m ahead, a facade and a tree crown between the two bounds and
// a wall beyond both. Points are displaced along their line of sight by the stereo
// depth error (eq. 4 at 0.5 px, 1 sigma), as stereo displaces them.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <memory>
#include <random>
#include <string>
#include <vector>

#include "../test_constants.h"

namespace {

enum BoundsLabel : int { SIDE_WALL, FACADE, TREE, BEYOND };

// Karlsruhe's rig: B f = 368.3 px m, so at 0.5 px the depth error is 0.3 m at 14.86 m
// and 0.45 m at 18.20 m (eq. 4: Delta z = z^2 Delta d / (B f)).
using planar_grid_test::KARLSRUHE_BASELINE_M;
using planar_grid_test::KARLSRUHE_FOCAL_PX;
// The cell bound: the depth whose error is 0.3 m.
const float CELL_BOUND_M =
  static_cast<float>(std::sqrt(0.3 / 0.5 * KARLSRUHE_FOCAL_PX * KARLSRUHE_BASELINE_M));

struct BoundsScene {
  planar_grid::Frame frame;
  std::map<int, std::size_t> count;
};

BoundsScene
makeBoundsScene()
{
  BoundsScene s;
  auto cloud = std::make_shared<planar_grid::Frame::Cloud>();
  std::mt19937 rng(11);
  std::normal_distribution<float> unit(0.0f, 1.0f);
  const auto add = [&](const Eigen::Vector3f& p, BoundsLabel l) {
    const float sigma = static_cast<float>(
      p.z() * p.z() / (KARLSRUHE_FOCAL_PX * KARLSRUHE_BASELINE_M) * 0.5);
    pcl::PointXYZI q;
    q.getVector3fMap() = p + sigma * unit(rng) * p.normalized();
    q.intensity = static_cast<float>(l);
    cloud->push_back(q);
    ++s.count[l];
  };
  // The side wall x = -5 (z in [5, 18], y in [-4, 1]), seen at a grazing angle.
  for (float z = 5.0f; z < 18.0f; z += 0.1f)
    for (float y = -4.0f; y < 1.0f; y += 0.1f)
      add({-5.0f, y, z}, SIDE_WALL);
  // A facade z = 17.5 (x in [0, 8], y in [-4, 1]), between the two bounds.
  for (float x = 0.0f; x < 8.0f; x += 0.1f)
    for (float y = -4.0f; y < 1.0f; y += 0.1f)
      add({x, y, 17.5f}, FACADE);
  // A tree crown between the bounds, clear of both planes' eq. 11 slabs: a ball of
  // 0.9 m radius at (-2.5, -2, 15.8).
  std::uniform_real_distribution<float> ball(-0.9f, 0.9f);
  for (int k = 0; k < 3000;) {
    const Eigen::Vector3f d(ball(rng), ball(rng), ball(rng));
    if (d.norm() > 0.9f)
      continue;
    add(Eigen::Vector3f(-2.5f, -2.0f, 15.8f) + d, TREE);
    ++k;
  }
  // A wall beyond both bounds, at z = 22 m.
  for (float x = -4.0f; x < 6.0f; x += 0.1f)
    for (float y = -4.0f; y < 1.0f; y += 0.1f)
      add({x, y, 22.0f}, BEYOND);
  s.frame.cloud = cloud;
  s.frame.name = "scene";
  s.frame.calibration.focal_length_px = KARLSRUHE_FOCAL_PX;
  s.frame.calibration.baseline_m = KARLSRUHE_BASELINE_M;
  // Key features: 40 exact points on each wall.
  std::uniform_real_distribution<float> u01(0.0f, 1.0f);
  const auto feature = [&](float x, float y, float z) {
    s.frame.features.points.push_back(pcl::PointXYZ(x, y, z));
    s.frame.features.keypoints_left.emplace_back(0.0f, 0.0f, 1.0f);
  };
  for (int k = 0; k < 40; ++k) {
    feature(-5.0f, -4.0f + 5.0f * u01(rng), 5.0f + 13.0f * u01(rng));
    feature(8.0f * u01(rng), -4.0f + 5.0f * u01(rng), 17.5f);
  }
  return s;
}

std::map<int, std::size_t>
countLabels(const planar_grid::Frame::Cloud& cloud)
{
  std::map<int, std::size_t> out;
  for (const auto& p : cloud.points)
    if (std::isfinite(p.x))
      ++out[static_cast<int>(p.intensity)];
  return out;
}

std::size_t
depthOf(const planar_grid::Frame::Cloud& cloud, int label, float min_depth_m)
{
  std::size_t n = 0;
  for (const auto& p : cloud.points)
    n +=
      std::isfinite(p.x) && static_cast<int>(p.intensity) == label && p.z > min_depth_m;
  return n;
}

/** depth_error_filter (0.3 m; \a plane_bound_m for the planes), the segmentation on
 * the features with config/karlsruhe.yaml's tests, and the approximation. */
void
run(BoundsScene& s, double plane_bound_m, bool count_inlier_only)
{
  planar_grid::PipelineState state;
  const auto* filter = planar_grid::findStage("depth_error_filter");
  const auto* segmentation = planar_grid::findStage("multi_plane_segmentation");
  const auto* cuboids = planar_grid::findStage("planar_cuboid_approximation");
  ASSERT_TRUE(filter && segmentation && cuboids);
  planar_grid::ParamValues fp = planar_grid::defaultParams(filter->params);
  fp.set("max_depth_error_m", 0.3);
  fp.set("max_plane_depth_error_m", plane_bound_m);
  planar_grid::ParamValues sp = planar_grid::defaultParams(segmentation->params);
  sp.set("sample", std::string("features"));
  sp.set("sample_distance_threshold_m", 0.15);
  sp.set("min_inliers", 300);
  sp.set("depth_noise_disparity_px", 0.5);
  sp.set("max_visibility_conflict_ratio", 0.25);
  sp.set("min_sensor_distance_m", 1.0);
  sp.set("min_cluster_size", 300);
  sp.set("cluster_cell_m", 0.1);
  sp.set("count_inlier_only_points", count_inlier_only);
  planar_grid::ParamValues cp = planar_grid::defaultParams(cuboids->params);
  cp.set("min_cell_size_m", 0.1);
  filter->create(fp)->process(s.frame, state);
  segmentation->create(sp)->process(s.frame, state);
  cuboids->create(cp)->process(s.frame, state);
}

} // namespace

TEST(DepthErrorFilter, PointsBetweenTheBoundsExtendThePlanesOfTheNearerPoints)
{
  BoundsScene s = makeBoundsScene();
  run(s, 0.45, false);
  EXPECT_FALSE(std::isfinite(s.frame.inlier_only_depth_m));
  const auto left = countLabels(*s.frame.cloud);
  // No plane of their own: the crown's points beyond the cell bound, the facade's and
  // the farthest points go (the crown's nearest points, displaced by their noise to
  // within the bound, may make boxes).
  EXPECT_EQ(depthOf(*s.frame.cloud, TREE, CELL_BOUND_M), 0u);
  EXPECT_EQ(left.count(FACADE), 0u) << "the facade has no points nearer than the bound";
  EXPECT_EQ(left.count(BEYOND), 0u);
  // The side wall's points beyond the cell bound join its plane: most of them (its
  // noise along the normal is far below the eq. 11 threshold at that range).
  std::size_t far_wall = 0;
  for (const auto& p : s.frame.cloud->points)
    far_wall += static_cast<int>(p.intensity) == SIDE_WALL && p.z > CELL_BOUND_M;
  EXPECT_GT(far_wall, 0.8 * (s.count[SIDE_WALL] * 3.2 / 13.0));
  // The cells centred beyond the cell bound lie on the wall x = -5 (within eq. 11's
  // threshold there: a planar cell spans its inliers along the normal), and nearly all
  // are planar: the approximation hands the inliers of a rectangle with fewer than
  // min_points_per_cell points to its non-planar boxes, the only way these points
  // reach a box.
  std::size_t far_cells = 0, far_planar = 0;
  for (const auto& c : s.frame.cuboids) {
    if (c.centre.z() <= CELL_BOUND_M)
      continue;
    EXPECT_NEAR(c.centre.x(), -5.0f, 0.45f);
    ++far_cells;
    far_planar += c.is_planar;
  }
  EXPECT_GT(far_cells, 0u);
  EXPECT_GE(far_planar, 0.9 * far_cells) << far_planar << " of " << far_cells;
}

TEST(DepthErrorFilter, CountedThePointsBetweenTheBoundsCarryAPlaneTheFeaturesMake)
{
  BoundsScene s = makeBoundsScene();
  run(s, 0.45, true);
  const auto left = countLabels(*s.frame.cloud);
  EXPECT_EQ(depthOf(*s.frame.cloud, TREE, CELL_BOUND_M), 0u) << "no features, no plane";
  EXPECT_EQ(left.count(BEYOND), 0u);
  // The facade is one plane on its 40 features: its noise (1 sigma) is eq. 11's
  // threshold at its range (0.42 m), so about 2 / 3 of its points are inliers.
  EXPECT_GE(left.at(FACADE), s.count[FACADE] / 2);
  std::size_t facade_cells = 0;
  for (const auto& c : s.frame.cuboids)
    if (c.centre.z() > 16.5f && c.centre.x() > -1.0f) {
      EXPECT_TRUE(c.is_planar);
      // Its face at the front-most inlier, its back at the rearmost one.
      EXPECT_NEAR(c.centre.z(), 17.5f, 0.5f);
      ++facade_cells;
    }
  EXPECT_GT(facade_cells, 0u);
}

TEST(DepthErrorFilter, WithOneBoundNothingBeyondItIsKept)
{
  BoundsScene s = makeBoundsScene();
  run(s, 0.0, true);
  EXPECT_EQ(depthOf(*s.frame.cloud, SIDE_WALL, CELL_BOUND_M), 0u);
  EXPECT_EQ(depthOf(*s.frame.cloud, TREE, CELL_BOUND_M), 0u);
  const auto left = countLabels(*s.frame.cloud);
  EXPECT_EQ(left.count(BEYOND), 0u);
  EXPECT_EQ(left.count(FACADE), 0u);
  EXPECT_GT(left.at(SIDE_WALL), 0u);
}

TEST(DepthErrorFilter, ThePlaneBoundNeedsTheSegmentation)
{
  BoundsScene s = makeBoundsScene();
  planar_grid::PipelineState state;
  const auto* filter = planar_grid::findStage("depth_error_filter");
  const auto* cuboids = planar_grid::findStage("planar_cuboid_approximation");
  ASSERT_TRUE(filter && cuboids);
  planar_grid::ParamValues fp = planar_grid::defaultParams(filter->params);
  fp.set("max_plane_depth_error_m", 0.45);
  filter->create(fp)->process(s.frame, state);
  EXPECT_NEAR(s.frame.inlier_only_depth_m, CELL_BOUND_M, 0.01f);
  EXPECT_THROW(cuboids->create(planar_grid::defaultParams(cuboids->params))
                 ->process(s.frame, state),
               planar_grid::Exception);
}
