// SPDX-License-Identifier: BSD-3-Clause
// A user-defined point type (not in PLANAR_GRID_POINT_TYPES) through PCL_NO_PRECOMPILE:
// the template classes are instantiated here from their impl/*.hpp, as PCL's are for
// custom point types, and behave as with the precompiled types on synthetic planes with
// known coefficients and fixed seeds; the two fast filters give PCL's own filters'
// output for the same type.
#define PCL_NO_PRECOMPILE
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/fast_voxel_grid.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/point_types.h>
#include <pcl/register_point_struct.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

namespace planar_grid_test {
/** A user's point type: XYZ plus a per-point confidence our classes know nothing of. */
struct EIGEN_ALIGN16 PointXYZConfidence {
  PCL_ADD_POINT4D;
  float confidence;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};
} // namespace planar_grid_test

// clang-format off
POINT_CLOUD_REGISTER_POINT_STRUCT(planar_grid_test::PointXYZConfidence,
                                  (float, x, x)(float, y, y)(float, z, z)
                                  (float, confidence, confidence))
// clang-format on

namespace {

using PointT = planar_grid_test::PointXYZConfidence;
using Cloud = pcl::PointCloud<PointT>;

PointT
makePoint(float x, float y, float z, float confidence)
{
  PointT p;
  p.x = x;
  p.y = y;
  p.z = z;
  p.confidence = confidence;
  return p;
}

/** The plane 0.6 y + 0.8 z - 2 = 0 in the camera frame (x right, y down, z forward),
 * x in [-1, 1] m and y in [-1, 1] m (z from 1.75 to 3.25 m: in plane coordinates a
 * 2 m x 2.5 m rectangle, 5 m^2), sampled every 0.025 m (81 x 81 = 6561 points) with
 * Gaussian noise of 2 mm along the normal (seed 7). */
Cloud::Ptr
tiltedPlane()
{
  Cloud::Ptr cloud(new Cloud);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int i = 0; i <= 80; ++i) {
    for (int j = 0; j <= 80; ++j) {
      const float x = -1.0f + 0.025f * static_cast<float>(i);
      const float y = -1.0f + 0.025f * static_cast<float>(j);
      const float z = (2.0f - 0.6f * y) / 0.8f;
      const float n = noise(rng);
      cloud->push_back(makePoint(x, y + 0.6f * n, z + 0.8f * n, 1.0f));
    }
  }
  return cloud;
}

} // namespace

TEST(CustomPointType, SegmentationFindsKnownPlane)
{
  const auto cloud = tiltedPlane();
  planar_grid::SACMultiPlaneSegmentation<PointT> seg;
  seg.setInputCloud(cloud);
  seg.setDistanceThreshold(0.01);
  seg.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
  std::vector<pcl::ModelCoefficients> model_coefficients;
  std::vector<pcl::PointIndices> inliers;
  seg.segment(model_coefficients, inliers);

  ASSERT_EQ(model_coefficients.size(), 1u);
  ASSERT_EQ(inliers.size(), 1u);
  // The normal points toward the sensor origin (0, 0, 0): [a, b, c, d] = [0, -0.6,
  // -0.8, 2]; a 2 mm noise gives errors far below 0.01.
  const auto& c = model_coefficients[0].values;
  ASSERT_EQ(c.size(), 4u);
  EXPECT_NEAR(c[0], 0.0f, 0.01f);
  EXPECT_NEAR(c[1], -0.6f, 0.01f);
  EXPECT_NEAR(c[2], -0.8f, 0.01f);
  EXPECT_NEAR(c[3], 2.0f, 0.01f);
  // Noise of 2 mm against a 10 mm threshold (5 sigma): every point is an inlier.
  EXPECT_EQ(inliers[0].indices.size(), cloud->size());
}

TEST(CustomPointType, CuboidsCoverKnownPlane)
{
  const auto cloud = tiltedPlane();
  const Eigen::Vector3f up(0.0f, -1.0f, 0.0f);
  planar_grid::SACMultiPlaneSegmentation<PointT> seg;
  seg.setInputCloud(cloud);
  seg.setDistanceThreshold(0.01);
  seg.setUpAxis(up);
  planar_grid::PlanarSegments planes;
  seg.segment(planes);
  ASSERT_EQ(planes.size(), 1u);

  planar_grid::PlanarCuboidApproximation<PointT> approximation;
  approximation.setInputCloud(cloud);
  approximation.setPlanes(planes);
  approximation.setUpAxis(up);
  approximation.setMinCellSize(0.1);
  approximation.setMinPointsPerCell(1);
  planar_grid::PlanarCuboids cuboids;
  approximation.approximate(cuboids);
  ASSERT_FALSE(cuboids.empty());

  const Eigen::Vector3f normal(0.0f, -0.6f, -0.8f);
  double face_area_m2 = 0.0;
  for (const auto& cuboid : cuboids) {
    ASSERT_TRUE(cuboid.is_planar);
    EXPECT_EQ(cuboid.plane_id, 0);
    EXPECT_GT(std::abs(cuboid.normal.dot(normal)), 0.999f);
    // The face lies on the plane (within the noise and the 10 mm threshold).
    EXPECT_NEAR(cuboid.faceCentre().dot(normal) + 2.0f, 0.0f, 0.02f);
    face_area_m2 += cuboid.faceArea();
  }
  // The merged faces tile the 2 m x 2.5 m rectangle, tightened to the points' extent.
  EXPECT_NEAR(face_area_m2, 5.0, 0.25);
  // With min_points_per_cell = 1 every finite point lies in some cuboid.
  for (const auto& p : cloud->points) {
    bool inside = false;
    for (const auto& cuboid : cuboids)
      inside = inside || cuboid.contains(p.getVector3fMap(), 1e-4f);
    ASSERT_TRUE(inside) << p.x << ' ' << p.y << ' ' << p.z;
  }
}

TEST(CustomPointType, OccupancyFilterKeepsPlaneAndDropsOutliers)
{
  // Features on the fronto-parallel wall z = 2.5 m ([0, 0, 1, -2.5]), x and y in
  // [-0.4, 0.4] m every 0.04 m (21 x 21 = 441), plus 4 outliers 0.5 m in front of it
  // at (+-0.2, +-0.2, 2.0). Neighbourhood cells of 4 m put each outlier in a cell of
  // wall features however the cells are anchored. Eq. 4 with f = 500 px, B = 0.1 m,
  // dd = 0.5 px: dr = (r_bar / z) z^2 dd / (B f) = 0.063 m on the wall, 0.05 m at an
  // outlier. The wall's ranges (2.5 to 2.563 m) differ from their cell mean by < 0.05 m
  // (p > 0.7, kept); an outlier's range is ~0.5 m (10 dr) short of its cell's mean
  // (p ~ 0, clamped to 0.1192, dropped). A second identical frame keeps the wall above
  // and the outliers below occupancy_thres = 0.5 (eq. 10: E = |D| + A when both
  // probabilities are <= 0.5).
  Cloud::Ptr features(new Cloud);
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j)
      features->push_back(makePoint(-0.4f + 0.04f * static_cast<float>(i),
                                    -0.4f + 0.04f * static_cast<float>(j), 2.5f,
                                    static_cast<float>(features->size())));
  const std::size_t wall_size = features->size();
  for (const float x : {-0.2f, 0.2f})
    for (const float y : {-0.2f, 0.2f})
      features->push_back(makePoint(x, y, 2.0f, static_cast<float>(features->size())));
  std::vector<std::int64_t> track_ids(features->size());
  for (std::size_t i = 0; i < track_ids.size(); ++i)
    track_ids[i] = static_cast<std::int64_t>(i);

  planar_grid::KLDivergenceOccupancyFilter<PointT> occupancy;
  auto params = occupancy.getParams();
  params.neighbourhood_size_m = 4.0;
  occupancy.setParams(params);
  occupancy.setStereoParameters(500.0, 0.1);
  for (int frame = 0; frame < 2; ++frame) {
    occupancy.setInputCloud(features);
    occupancy.setTrackIds(track_ids);
    pcl::Indices occupied;
    occupancy.filter(occupied);
    ASSERT_EQ(occupied.size(), wall_size) << "frame " << frame;
    for (std::size_t k = 0; k < occupied.size(); ++k)
      EXPECT_EQ(occupied[k], static_cast<int>(k));
    EXPECT_EQ(occupancy.getTrackCount(), features->size());
    const auto& probabilities = occupancy.getProbabilities();
    ASSERT_EQ(probabilities.size(), features->size());
    for (std::size_t k = 0; k < features->size(); ++k) {
      if (k < wall_size)
        EXPECT_GE(probabilities[k], 0.5f)
          << "frame " << frame << ", wall feature " << k;
      else
        EXPECT_LT(probabilities[k], 0.5f) << "frame " << frame << ", outlier " << k;
    }
  }

  // filter(cloud) of the same input only re-selects; the user's field is carried over.
  Cloud occupied_cloud;
  occupancy.filter(occupied_cloud);
  ASSERT_EQ(occupied_cloud.size(), wall_size);
  for (std::size_t k = 0; k < wall_size; ++k)
    EXPECT_EQ(occupied_cloud[k].confidence, static_cast<float>(k));
}

TEST(CustomPointType, FastVoxelGridEqualsPCLVoxelGrid)
{
  // The tilted plane (6561 points, 0.025 m spacing) in 0.1 m voxels, with the user's
  // field varying so that its centroid is checked too: pcl::VoxelGrid<PointT> is the
  // oracle, point for point and bit for bit.
  Cloud::Ptr cloud = tiltedPlane();
  for (std::size_t i = 0; i < cloud->size(); ++i)
    (*cloud)[i].confidence = static_cast<float>(i % 17) / 16.0f;
  for (const unsigned int min_points : {0u, 5u}) {
    SCOPED_TRACE("min points per voxel " + std::to_string(min_points));
    pcl::VoxelGrid<PointT> reference;
    reference.setInputCloud(cloud);
    reference.setLeafSize(0.1f, 0.1f, 0.1f);
    reference.setMinimumPointsNumberPerVoxel(min_points);
    Cloud expected;
    reference.filter(expected);

    planar_grid::FastVoxelGrid<PointT> grid;
    grid.setInputCloud(cloud);
    grid.setLeafSize(0.1f, 0.1f, 0.1f);
    grid.setMinimumPointsNumberPerVoxel(min_points);
    Cloud result;
    grid.filter(result);

    ASSERT_GT(expected.size(), 100u);
    ASSERT_EQ(result.size(), expected.size());
    for (std::size_t i = 0; i < result.size(); ++i) {
      EXPECT_EQ(result[i].x, expected[i].x) << i;
      EXPECT_EQ(result[i].y, expected[i].y) << i;
      EXPECT_EQ(result[i].z, expected[i].z) << i;
      EXPECT_EQ(result[i].confidence, expected[i].confidence) << i;
    }
  }
}

TEST(CustomPointType, FastOutlierRemovalEqualsPCLStatisticalOutlierRemoval)
{
  // The tilted plane with 20 points scattered 0.3-0.7 m in front of it (seed 11):
  // pcl::StatisticalOutlierRemoval<PointT> is the oracle, index for index, for the kept
  // points and for the removed ones.
  Cloud::Ptr cloud = tiltedPlane();
  std::mt19937 rng(11);
  std::uniform_real_distribution<float> across(-0.9f, 0.9f), offset(0.3f, 0.7f);
  for (int i = 0; i < 20; ++i) {
    const float x = across(rng), y = across(rng);
    cloud->push_back(makePoint(x, y, (2.0f - 0.6f * y) / 0.8f - offset(rng), 0.0f));
  }
  pcl::StatisticalOutlierRemoval<PointT> reference(true);
  reference.setInputCloud(cloud);
  reference.setMeanK(20);
  reference.setStddevMulThresh(2.0);
  pcl::Indices expected;
  reference.filter(expected);

  planar_grid::FastStatisticalOutlierRemoval<PointT> removal(true);
  removal.setInputCloud(cloud);
  removal.setMeanK(20);
  removal.setStddevMulThresh(2.0);
  pcl::Indices kept;
  removal.filter(kept);

  EXPECT_EQ(kept, expected);
  EXPECT_EQ(*removal.getRemovedIndices(), *reference.getRemovedIndices());
  // The scattered points are among the removed ones.
  ASSERT_GE(removal.getRemovedIndices()->size(), 15u);
  for (const auto index : *removal.getRemovedIndices())
    EXPECT_GE(static_cast<std::size_t>(index), cloud->size() - 20) << index;
}
