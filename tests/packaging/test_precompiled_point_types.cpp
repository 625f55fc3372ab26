// SPDX-License-Identifier: BSD-3-Clause
// The precompiled point types: every type of PLANAR_GRID_POINT_TYPES is used here with
// the four template classes through their .h only (no impl/*.hpp, no
// PCL_NO_PRECOMPILE), so this executable links only when the libraries hold each
// instantiation, and each one behaves on synthetic data with known answers.
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/point_types.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/point_types.h>

#include <gtest/gtest.h>

#include <boost/preprocessor/seq/enum.hpp>
#include <boost/preprocessor/seq/for_each.hpp>
#include <boost/preprocessor/stringize.hpp>
#include <cmath>
#include <cstdint>
#include <random>
#include <string>
#include <vector>

#ifdef PCL_NO_PRECOMPILE
#error \
  "this test checks the precompiled instantiations; PCL_NO_PRECOMPILE must be unset"
#endif

namespace {

template <typename PointT>
PointT
makePoint(float x, float y, float z)
{
  PointT p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

/** The plane 0.6 y + 0.8 z - 2 = 0 (camera frame: x right, y down, z forward), x and y
 * in [-1, 1] m every 0.05 m (41 x 41 = 1681 points; in plane coordinates a 2 m x 2.5 m
 * rectangle, 5 m^2), with Gaussian noise of 2 mm along the normal (seed 7). */
template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr
tiltedPlane()
{
  typename pcl::PointCloud<PointT>::Ptr cloud(new pcl::PointCloud<PointT>);
  std::mt19937 rng(7);
  std::normal_distribution<float> noise(0.0f, 0.002f);
  for (int i = 0; i <= 40; ++i) {
    for (int j = 0; j <= 40; ++j) {
      const float x = -1.0f + 0.05f * static_cast<float>(i);
      const float y = -1.0f + 0.05f * static_cast<float>(j);
      const float z = (2.0f - 0.6f * y) / 0.8f;
      const float n = noise(rng);
      cloud->push_back(makePoint<PointT>(x, y + 0.6f * n, z + 0.8f * n));
    }
  }
  return cloud;
}

template <typename PointT> class PrecompiledPointType : public ::testing::Test {};

using PrecompiledPointTypes =
  ::testing::Types<BOOST_PP_SEQ_ENUM(PLANAR_GRID_POINT_TYPES)>;
TYPED_TEST_SUITE(PrecompiledPointType, PrecompiledPointTypes);

} // namespace

#define PLANAR_GRID_TEST_NAME(r, data, POINT_TYPE) BOOST_PP_STRINGIZE(POINT_TYPE) ","

// The generated header holds the list CMake checked (comma-separated here), in its
// order.
TEST(PrecompiledPointTypes, HeaderMatchesCMakeList)
{
  const std::string from_header =
    BOOST_PP_SEQ_FOR_EACH(PLANAR_GRID_TEST_NAME, _, PLANAR_GRID_POINT_TYPES);
  EXPECT_EQ(from_header, std::string(PLANAR_GRID_TEST_POINT_TYPES) + ",");
}

TYPED_TEST(PrecompiledPointType, SegmentationAndCuboidsFitKnownPlane)
{
  using PointT = TypeParam;
  const auto cloud = tiltedPlane<PointT>();
  const Eigen::Vector3f up(0.0f, -1.0f, 0.0f);
  planar_grid::SACMultiPlaneSegmentation<PointT> seg;
  seg.setInputCloud(cloud);
  seg.setDistanceThreshold(0.01);
  seg.setUpAxis(up);
  seg.setSeed(1);
  planar_grid::PlanarSegments planes;
  seg.segment(planes);
  ASSERT_EQ(planes.size(), 1u);
  // Normal toward the sensor: [a, b, c, d] = [0, -0.6, -0.8, 2]; every point within
  // the 10 mm threshold (5 sigma of the noise).
  const auto& c = planes[0].model_coefficients.values;
  ASSERT_EQ(c.size(), 4u);
  EXPECT_NEAR(c[0], 0.0f, 0.01f);
  EXPECT_NEAR(c[1], -0.6f, 0.01f);
  EXPECT_NEAR(c[2], -0.8f, 0.01f);
  EXPECT_NEAR(c[3], 2.0f, 0.01f);
  EXPECT_EQ(planes[0].inliers.indices.size(), cloud->size());

  planar_grid::PlanarCuboidApproximation<PointT> approximation;
  approximation.setInputCloud(cloud);
  approximation.setPlanes(planes);
  approximation.setUpAxis(up);
  approximation.setMinCellSize(0.1);
  approximation.setMinPointsPerCell(1);
  planar_grid::PlanarCuboids cuboids;
  approximation.approximate(cuboids);
  ASSERT_FALSE(cuboids.empty());
  double face_area_m2 = 0.0;
  for (const auto& cuboid : cuboids) {
    EXPECT_TRUE(cuboid.is_planar);
    face_area_m2 += cuboid.faceArea();
  }
  // The merged faces tile the 2 m x 2.5 m rectangle, tightened to the points' extent.
  EXPECT_NEAR(face_area_m2, 5.0, 0.3);
}

TYPED_TEST(PrecompiledPointType, OccupancyFilterDropsOutliers)
{
  // The wall z = 2.5 m, x and y in [-0.4, 0.4] m every 0.04 m (441 features), and 4
  // outliers 0.5 m in front of it; f = 500 px, B = 0.1 m, neighbourhood cells of 4 m
  // (tests/packaging/test_custom_point_type.cpp derives the probabilities): the wall is
  // kept, the outliers are not.
  using PointT = TypeParam;
  typename pcl::PointCloud<PointT>::Ptr features(new pcl::PointCloud<PointT>);
  for (int i = 0; i <= 20; ++i)
    for (int j = 0; j <= 20; ++j)
      features->push_back(makePoint<PointT>(-0.4f + 0.04f * static_cast<float>(i),
                                            -0.4f + 0.04f * static_cast<float>(j),
                                            2.5f));
  const std::size_t wall_size = features->size();
  for (const float x : {-0.2f, 0.2f})
    for (const float y : {-0.2f, 0.2f})
      features->push_back(makePoint<PointT>(x, y, 2.0f));
  std::vector<std::int64_t> track_ids(features->size());
  for (std::size_t i = 0; i < track_ids.size(); ++i)
    track_ids[i] = static_cast<std::int64_t>(i);

  planar_grid::KLDivergenceOccupancyFilter<PointT> occupancy;
  auto params = occupancy.getParams();
  params.neighbourhood_size_m = 4.0;
  occupancy.setParams(params);
  occupancy.setStereoParameters(500.0, 0.1);
  occupancy.setInputCloud(features);
  occupancy.setTrackIds(track_ids);
  pcl::Indices occupied;
  occupancy.filter(occupied);
  ASSERT_EQ(occupied.size(), wall_size);
  for (std::size_t k = 0; k < occupied.size(); ++k)
    EXPECT_EQ(occupied[k], static_cast<int>(k));
}

TYPED_TEST(PrecompiledPointType, OutlierRemovalDropsFarPoint)
{
  // A 10 x 10 grid on z = 1 m every 0.01 m and one point 1 m behind it: with 8
  // neighbours and a 1-sigma threshold only the far point's mean distance is above the
  // threshold.
  using PointT = TypeParam;
  typename pcl::PointCloud<PointT>::Ptr cloud(new pcl::PointCloud<PointT>);
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      cloud->push_back(makePoint<PointT>(0.01f * static_cast<float>(i),
                                         0.01f * static_cast<float>(j), 1.0f));
  cloud->push_back(makePoint<PointT>(0.05f, 0.05f, 2.0f));

  planar_grid::FastStatisticalOutlierRemoval<PointT> sor;
  sor.setInputCloud(cloud);
  sor.setMeanK(8);
  sor.setStddevMulThresh(1.0);
  pcl::Indices kept;
  sor.filter(kept);
  ASSERT_EQ(kept.size(), 100u);
  for (std::size_t k = 0; k < kept.size(); ++k)
    EXPECT_EQ(kept[k], static_cast<int>(k));
}
