// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>

#include <pcl/filters/statistical_outlier_removal.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

#include "../test_constants.h"

namespace {

using planar_grid_test::CLOUDS;

/** A real Kinect / stereo scan, voxelized (unorganized, as in the pipeline). */
pcl::PointCloud<pcl::PointXYZ>::Ptr
realCloud(const std::string& file, float leaf_m)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr raw(new pcl::PointCloud<pcl::PointXYZ>);
  if (pcl::io::loadPCDFile(CLOUDS + "/" + file, *raw) != 0)
    throw planar_grid::Exception("cannot read " + file);
  pcl::PointCloud<pcl::PointXYZ>::Ptr out(new pcl::PointCloud<pcl::PointXYZ>);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(leaf_m, leaf_m, leaf_m);
  grid.setInputCloud(raw);
  grid.filter(*out);
  return out;
}

/** The kept indices of a statistical outlier filter: PCL's (the oracle) or ours. */
template <typename Filter>
pcl::Indices
keptBy(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& cloud,
       int mean_k,
       double std_mul,
       bool negative,
       const pcl::IndicesPtr& indices = nullptr)
{
  Filter sor;
  sor.setInputCloud(cloud);
  if (indices)
    sor.setIndices(indices);
  sor.setMeanK(mean_k);
  sor.setStddevMulThresh(std_mul);
  sor.setNegative(negative);
  pcl::Indices kept;
  sor.filter(kept);
  return kept;
}

using PCLFilter = pcl::StatisticalOutlierRemoval<pcl::PointXYZ>;
using FastFilter = planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ>;

} // namespace

TEST(FastStatisticalOutlierRemoval, KeepsExactlyWhatPCLKeepsOnRealScans)
{
  // Two real scans (Kinect office, textured-light stereo table), voxelized: for every
  // parameter set, the same kept indices as pcl::StatisticalOutlierRemoval, in order.
  for (const auto& [file, leaf] : {std::pair<std::string, float>{"office1.pcd", 0.03f},
                                   {"table_scene_mug_stereo_textured.pcd", 0.01f}}) {
    const auto cloud = realCloud(file, leaf);
    ASSERT_GT(cloud->size(), 5000u) << file;
    for (const int mean_k : {1, 8, 20, 50})
      for (const double std_mul : {0.0, 1.0, 2.0})
        for (const bool negative : {false, true}) {
          const auto expected = keptBy<PCLFilter>(cloud, mean_k, std_mul, negative);
          const auto got = keptBy<FastFilter>(cloud, mean_k, std_mul, negative);
          ASSERT_EQ(got, expected) << file << " mean_k " << mean_k << " std_mul "
                                   << std_mul << " negative " << negative;
        }
    // The filter does something: at mean_k 20, 2 sigma, some points go.
    const auto kept = keptBy<FastFilter>(cloud, 20, 2.0, false);
    EXPECT_LT(kept.size(), cloud->size()) << file;
    EXPECT_GT(kept.size(), cloud->size() * 9 / 10) << file;
  }
}

TEST(FastStatisticalOutlierRemoval, NonFinitePointsAndIndicesAsPCL)
{
  // Non-finite points mixed into an unorganized cloud, and a subset of indices: the
  // same result as PCL (a NaN point is kept: its mean distance counts as 0).
  auto cloud = realCloud("office1.pcd", 0.05f);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  for (std::size_t i = 0; i < cloud->size(); i += 97)
    (*cloud)[i].x = nan;
  cloud->is_dense = false;
  pcl::IndicesPtr subset(new pcl::Indices);
  for (std::size_t i = 0; i < cloud->size(); i += 3)
    subset->push_back(static_cast<pcl::index_t>(i));
  EXPECT_EQ(keptBy<FastFilter>(cloud, 10, 1.0, false),
            keptBy<PCLFilter>(cloud, 10, 1.0, false));
  EXPECT_EQ(keptBy<FastFilter>(cloud, 10, 1.0, false, subset),
            keptBy<PCLFilter>(cloud, 10, 1.0, false, subset));
  const auto kept = keptBy<FastFilter>(cloud, 10, 1.0, false);
  EXPECT_NE(std::find(kept.begin(), kept.end(), 97), kept.end());

  // The output cloud as PCL's filter(PointCloud&) builds it.
  planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ> fast;
  pcl::StatisticalOutlierRemoval<pcl::PointXYZ> reference;
  pcl::PointCloud<pcl::PointXYZ> a, b;
  fast.setInputCloud(cloud);
  fast.setMeanK(10);
  fast.setStddevMulThresh(1.0);
  fast.filter(a);
  reference.setInputCloud(cloud);
  reference.setMeanK(10);
  reference.setStddevMulThresh(1.0);
  reference.filter(b);
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i)
    ASSERT_TRUE(a[i].getVector3fMap() == b[i].getVector3fMap()
                || (std::isnan(a[i].x) && std::isnan(b[i].x)))
      << i;
}

TEST(FastStatisticalOutlierRemoval, LatticesDuplicatesAndScatteredPointsAsPCL)
{
  // Exact lattices (many equal distances, points on the search cells' faces), repeated
  // points, a sparse scatter far from the surfaces and a cloud smaller than mean_k:
  // the same kept indices as PCL at every mean_k, with the threshold at the mean
  // itself (std_mul 0), where any change in a mean distance would show.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (int i = 0; i < 60; ++i)
    for (int j = 0; j < 40; ++j) {
      cloud->push_back(pcl::PointXYZ(0.1f * i, 0.1f * j, 0.0f));  // floor
      cloud->push_back(pcl::PointXYZ(0.1f * i, 4.0f, 0.05f * j)); // wall, finer
    }
  for (std::size_t i = 0; i < cloud->size(); i += 7)
    cloud->push_back((*cloud)[i]); // repeated points
  std::uint32_t state = 12345u;
  const auto uniform = [&state](float lo, float hi) {
    state = state * 1664525u + 1013904223u;
    return lo + (hi - lo) * static_cast<float>(state >> 8) / 16777216.0f;
  };
  for (int i = 0; i < 300; ++i)
    cloud->push_back(
      pcl::PointXYZ(uniform(-5.0f, 11.0f), uniform(-5.0f, 9.0f), uniform(0.5f, 6.0f)));
  for (const int mean_k : {1, 5, 20, 60})
    for (const double std_mul : {0.0, 1.0})
      for (const bool negative : {false, true})
        ASSERT_EQ(keptBy<FastFilter>(cloud, mean_k, std_mul, negative),
                  keptBy<PCLFilter>(cloud, mean_k, std_mul, negative))
          << "mean_k " << mean_k << " std_mul " << std_mul << " negative " << negative;

  pcl::PointCloud<pcl::PointXYZ>::Ptr few(new pcl::PointCloud<pcl::PointXYZ>);
  for (int i = 0; i < 6; ++i)
    few->push_back(pcl::PointXYZ(0.3f * static_cast<float>(i * i), 0.0f, 0.1f * i));
  EXPECT_EQ(keptBy<FastFilter>(few, 10, 0.0, false),
            keptBy<PCLFilter>(few, 10, 0.0, false));
}

TEST(FastStatisticalOutlierRemoval, DensityFallingWithRangeAsPCL)
{
  // A road and a facade sampled as a stereo camera sees them: the spacing grows with
  // the range from 0.1 m to over 1 m, with 1 cm of noise. The near points are answered
  // by the 3 x 3 x 3 search cells, those a few times sparser than the median by the
  // 5 x 5 x 5 cells and the sparsest by the kd-tree; the threshold at the mean itself
  // (std_mul 0) shows any change in a mean distance.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  std::uint32_t state = 777u;
  const auto noise = [&state] {
    state = state * 1664525u + 1013904223u;
    return 0.01f * (static_cast<float>(state >> 8) / 16777216.0f - 0.5f);
  };
  for (float z = 2.0f; z < 40.0f; z += 0.1f * (1.0f + z * z / 64.0f)) {
    const float step = 0.1f * (1.0f + z * z / 64.0f);
    for (float x = -6.0f; x <= 6.0f; x += step)
      cloud->push_back(pcl::PointXYZ(x + noise(), 1.5f + noise(), z));
    for (float y = -4.0f; y <= 1.5f; y += step)
      cloud->push_back(pcl::PointXYZ(6.0f + noise(), y, z + noise()));
  }
  ASSERT_GT(cloud->size(), 2000u);
  for (const int mean_k : {5, 20})
    for (const double std_mul : {0.0, 2.0})
      ASSERT_EQ(keptBy<FastFilter>(cloud, mean_k, std_mul, false),
                keptBy<PCLFilter>(cloud, mean_k, std_mul, false))
        << "mean_k " << mean_k << " std_mul " << std_mul;
}

TEST(FastStatisticalOutlierRemoval, AnIsolatedPointIsRemovedAndReported)
{
  // A 10 x 10 lattice of 0.1 m and one point 5 m away: the far point is the outlier,
  // and getRemovedIndices() names it.
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j)
      cloud->push_back(pcl::PointXYZ(0.1f * i, 0.1f * j, 0.0f));
  cloud->push_back(pcl::PointXYZ(5.0f, 5.0f, 5.0f));
  planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ> sor(true);
  sor.setInputCloud(cloud);
  sor.setMeanK(4);
  sor.setStddevMulThresh(1.0);
  pcl::Indices kept;
  sor.filter(kept);
  EXPECT_EQ(kept.size(), 100u);
  ASSERT_EQ(sor.getRemovedIndices()->size(), 1u);
  EXPECT_EQ(sor.getRemovedIndices()->front(), 100);
}

TEST(FastStatisticalOutlierRemoval, ZeroNeighboursIsAnError)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->push_back(pcl::PointXYZ(0.0f, 0.0f, 0.0f));
  planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ> sor;
  sor.setInputCloud(cloud);
  sor.setMeanK(0);
  pcl::Indices kept;
  EXPECT_THROW(sor.filter(kept), planar_grid::Exception);
  // a multiplier that is not a number has no threshold; a finite one, even negative
  // (stricter than the mean), filters as PCL's does
  sor.setMeanK(1);
  sor.setStddevMulThresh(std::numeric_limits<double>::quiet_NaN());
  EXPECT_THROW(sor.filter(kept), planar_grid::Exception);
  sor.setStddevMulThresh(std::numeric_limits<double>::infinity());
  EXPECT_THROW(sor.filter(kept), planar_grid::Exception);
  sor.setStddevMulThresh(-1.0);
  EXPECT_NO_THROW(sor.filter(kept));
}
