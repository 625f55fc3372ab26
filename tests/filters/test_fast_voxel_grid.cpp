// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/fast_voxel_grid.h>

#include <pcl/common/io.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <cstring>
#include <limits>
#include <numeric>
#include <random>
#include <string>

#include "../test_constants.h"

namespace {

using planar_grid_test::CLOUDS;

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr
loadCloud(const std::string& file)
{
  typename pcl::PointCloud<PointT>::Ptr cloud(new pcl::PointCloud<PointT>);
  if (pcl::io::loadPCDFile(CLOUDS + "/" + file, *cloud) != 0)
    throw planar_grid::Exception("cannot read " + file);
  return cloud;
}

/** The output of a voxel filter: PCL's (the oracle) or ours. */
template <typename Filter, typename PointT>
pcl::PointCloud<PointT>
filteredBy(const typename pcl::PointCloud<PointT>::ConstPtr& cloud,
           float leaf_m,
           unsigned int min_points,
           const pcl::IndicesPtr& indices = nullptr)
{
  Filter grid;
  grid.setInputCloud(cloud);
  if (indices)
    grid.setIndices(indices);
  grid.setLeafSize(leaf_m, leaf_m, leaf_m);
  grid.setMinimumPointsNumberPerVoxel(min_points);
  pcl::PointCloud<PointT> out;
  grid.filter(out);
  return out;
}

/** Both clouds hold the same points bit for bit (every byte of every field of every
 * point; the padding of some point types is left uninitialized by their constructors),
 * in the same order. */
template <typename PointT>
void
expectSameBytes(const pcl::PointCloud<PointT>& got,
                const pcl::PointCloud<PointT>& expected,
                const std::string& what)
{
  ASSERT_EQ(got.size(), expected.size()) << what;
  EXPECT_EQ(got.width, expected.width) << what;
  EXPECT_EQ(got.height, expected.height) << what;
  EXPECT_EQ(got.is_dense, expected.is_dense) << what;
  const auto fields = pcl::getFields<PointT>();
  std::size_t differing = 0;
  for (std::size_t i = 0; i < got.size(); ++i) {
    const auto* a = reinterpret_cast<const std::uint8_t*>(&got[i]);
    const auto* b = reinterpret_cast<const std::uint8_t*>(&expected[i]);
    bool same = true;
    for (const auto& f : fields)
      same = same
             && std::memcmp(a + f.offset, b + f.offset,
                            f.count * pcl::getFieldSize(f.datatype))
                  == 0;
    differing += same ? 0 : 1;
  }
  EXPECT_EQ(differing, 0u) << what << ": points that differ of " << got.size();
}

template <typename PointT>
void
expectSameAsPCL(const typename pcl::PointCloud<PointT>::ConstPtr& cloud,
                const std::string& what)
{
  for (const float leaf : {0.01f, 0.03f, 0.1f})
    for (const unsigned int min_points : {0u, 3u}) {
      const auto expected =
        filteredBy<pcl::VoxelGrid<PointT>, PointT>(cloud, leaf, min_points);
      ASSERT_GT(expected.size(), 100u) << what << " leaf " << leaf;
      const auto got =
        filteredBy<planar_grid::FastVoxelGrid<PointT>, PointT>(cloud, leaf, min_points);
      expectSameBytes(got, expected,
                      what + " leaf " + std::to_string(leaf) + " min_points "
                        + std::to_string(min_points));
    }
}

} // namespace

TEST(FastVoxelGrid, SameCloudAsPCLOnRealScans)
{
  // An organized stereo scan with NaNs (x, y, z and colour) and a Kinect scan
  // (x, y, z); the leaf sizes put 1 to hundreds of points in a voxel.
  expectSameAsPCL<pcl::PointXYZRGB>(
    loadCloud<pcl::PointXYZRGB>("table_scene_mug_stereo_textured.pcd"), "table rgb");
  expectSameAsPCL<pcl::PointXYZ>(
    loadCloud<pcl::PointXYZ>("table_scene_mug_stereo_textured.pcd"), "table xyz");
  expectSameAsPCL<pcl::PointXYZ>(loadCloud<pcl::PointXYZ>("office1.pcd"), "office1");
}

TEST(FastVoxelGrid, SameCloudAsPCLWithIntensitiesAndIndices)
{
  // The main job's point type, with intensities of a real-valued spread, on an
  // organized cloud with NaNs; then on a random subset of its indices.
  const auto rgb = loadCloud<pcl::PointXYZRGB>("table_scene_mug_stereo_textured.pcd");
  pcl::PointCloud<pcl::PointXYZI>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZI>);
  cloud->resize(rgb->size());
  cloud->width = rgb->width;
  cloud->height = rgb->height;
  cloud->is_dense = false;
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> intensity(0.0f, 255.0f);
  for (std::size_t i = 0; i < rgb->size(); ++i) {
    (*cloud)[i].x = (*rgb)[i].x;
    (*cloud)[i].y = (*rgb)[i].y;
    (*cloud)[i].z = (*rgb)[i].z;
    (*cloud)[i].intensity = intensity(rng);
  }
  expectSameAsPCL<pcl::PointXYZI>(cloud, "table intensity");

  // Far from the origin (1000 km at 0.1 m: voxel coordinates beyond 2^23, where
  // single precision no longer holds fractions of a voxel).
  pcl::PointCloud<pcl::PointXYZI>::Ptr far(new pcl::PointCloud<pcl::PointXYZI>(*cloud));
  for (auto& p : far->points)
    p.x += 1.0e6f;
  const auto far_expected =
    filteredBy<pcl::VoxelGrid<pcl::PointXYZI>, pcl::PointXYZI>(far, 0.1f, 0);
  ASSERT_GT(far_expected.size(), 100u);
  expectSameBytes(
    filteredBy<planar_grid::FastVoxelGrid<pcl::PointXYZI>, pcl::PointXYZI>(far, 0.1f,
                                                                           0),
    far_expected, "table intensity, 1000 km away");

  pcl::IndicesPtr subset(new pcl::Indices);
  std::bernoulli_distribution keep(0.3);
  for (std::size_t i = 0; i < cloud->size(); ++i)
    if (keep(rng))
      subset->push_back(static_cast<int>(i));
  const auto expected =
    filteredBy<pcl::VoxelGrid<pcl::PointXYZI>, pcl::PointXYZI>(cloud, 0.01f, 2, subset);
  ASSERT_GT(expected.size(), 100u);
  expectSameBytes(
    filteredBy<planar_grid::FastVoxelGrid<pcl::PointXYZI>, pcl::PointXYZI>(cloud, 0.01f,
                                                                           2, subset),
    expected, "table intensity, indices");
}

TEST(FastVoxelGrid, CentroidsOfKnownVoxels)
{
  // Known truth: four points in two 1 m voxels, one alone in a third; with at least
  // two points per voxel, the two centroids in the order of their linear index (x
  // fastest, then y, then z over the bounding box).
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  cloud->push_back({0.25f, 1.5f, 0.5f});
  cloud->push_back({0.5f, 0.5f, 0.5f});
  cloud->push_back({nan, 0.5f, 0.5f});
  cloud->push_back({0.75f, 1.5f, 0.5f});
  cloud->push_back({0.25f, 0.25f, 0.5f});
  cloud->push_back({-2.5f, 0.5f, 0.5f});
  cloud->is_dense = false;
  planar_grid::FastVoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud);
  grid.setLeafSize(1.0f, 1.0f, 1.0f);
  grid.setMinimumPointsNumberPerVoxel(2);
  pcl::PointCloud<pcl::PointXYZ> out;
  grid.filter(out);
  ASSERT_EQ(out.size(), 2u);
  EXPECT_TRUE(out.is_dense);
  EXPECT_EQ(out.height, 1u);
  EXPECT_FLOAT_EQ(out[0].x, 0.375f);
  EXPECT_FLOAT_EQ(out[0].y, 0.375f);
  EXPECT_FLOAT_EQ(out[1].x, 0.5f);
  EXPECT_FLOAT_EQ(out[1].y, 1.5f);
  EXPECT_FLOAT_EQ(out[1].z, 0.5f);

  // Without finite points, no output.
  pcl::PointCloud<pcl::PointXYZ>::Ptr empty(new pcl::PointCloud<pcl::PointXYZ>);
  empty->push_back({nan, nan, nan});
  empty->is_dense = false;
  grid.setInputCloud(empty);
  grid.filter(out);
  EXPECT_TRUE(out.empty());
}

TEST(FastVoxelGrid, AVoxelEdgeThatIsNotPositiveAndFiniteIsAnError)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  cloud->push_back({0.25f, 0.25f, 0.25f});
  cloud->push_back({0.75f, 0.25f, 0.25f});
  planar_grid::FastVoxelGrid<pcl::PointXYZ> grid;
  grid.setInputCloud(cloud);
  pcl::PointCloud<pcl::PointXYZ> out;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float inf = std::numeric_limits<float>::infinity();
  for (const float bad : {0.0f, -1.0f, nan, inf}) {
    SCOPED_TRACE(bad);
    grid.setLeafSize(1.0f, 1.0f, bad); // one axis is enough
    EXPECT_THROW(grid.filter(out), planar_grid::Exception);
    planar_grid::FastVoxelGridParams params;
    params.leaf_size_m = static_cast<double>(bad);
    grid.setParams(params);
    EXPECT_THROW(grid.filter(out), planar_grid::Exception);
  }
  // any positive edge filters, as pcl::VoxelGrid's: one 1 m voxel, two of 0.5 m
  grid.setLeafSize(1.0f, 1.0f, 1.0f);
  grid.filter(out);
  EXPECT_EQ(out.size(), 1u);
  grid.setLeafSize(0.5f, 0.5f, 0.5f);
  grid.filter(out);
  EXPECT_EQ(out.size(), 2u);
}

TEST(FastVoxelGrid, CoordinatesBeyondTheIntRangeGiveWhatPCLGives)
{
  // One point 10^9 m away among near ones: its voxel coordinate (10^10 leaves) fits
  // no int, and the grid over the bounding box is too large, so PCL returns the input
  // unchanged (with a warning); ours must too, without computing the far point's voxel
  // in int arithmetic (the sanitizer build checks that).
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  for (int k = 0; k < 50; ++k)
    cloud->push_back({0.01f * static_cast<float>(k), 0.5f, 1.0f});
  cloud->push_back({1.0e9f, 0.5f, 1.0f});
  cloud->is_dense = true;
  const auto expected =
    filteredBy<pcl::VoxelGrid<pcl::PointXYZ>, pcl::PointXYZ>(cloud, 0.1f, 0);
  ASSERT_EQ(expected.size(), cloud->size());
  expectSameBytes(filteredBy<planar_grid::FastVoxelGrid<pcl::PointXYZ>, pcl::PointXYZ>(
                    cloud, 0.1f, 0),
                  expected, "a point 10^9 m away");

  // Points 10^12 m away, within one voxel's extent of each other: few voxels, but
  // their coordinates fit no int (where pcl::VoxelGrid's cast is undefined). Ours
  // passes the cloud through, as for a grid too large.
  pcl::PointCloud<pcl::PointXYZ>::Ptr far(new pcl::PointCloud<pcl::PointXYZ>);
  for (int k = 0; k < 5; ++k)
    far->push_back({1.0e12f, 0.01f * static_cast<float>(k), -1.0e12f});
  far->is_dense = true;
  const auto through =
    filteredBy<planar_grid::FastVoxelGrid<pcl::PointXYZ>, pcl::PointXYZ>(far, 0.1f, 0);
  expectSameBytes(through, *far, "5 points 10^12 m away");
}

// One filter kept for a stream of clouds (as the voxel_grid stage keeps it) reuses its
// buffers: a large cloud, a smaller one, the large one again, after releaseBuffers()
// too, each give PCL's output.
TEST(FastVoxelGrid, OneFilterForManyCloudsGivesWhatPCLGives)
{
  const auto large = loadCloud<pcl::PointXYZ>("table_scene_mug_stereo_textured.pcd");
  pcl::PointCloud<pcl::PointXYZ>::Ptr small(new pcl::PointCloud<pcl::PointXYZ>);
  for (std::size_t i = 0; i < large->size(); i += 7)
    small->push_back((*large)[i]);
  small->is_dense = false;
  planar_grid::FastVoxelGrid<pcl::PointXYZ> grid;
  grid.setLeafSize(0.01f, 0.01f, 0.01f);
  int step = 0;
  for (const auto& cloud : {large, small, large, small, large}) {
    if (step == 3)
      grid.releaseBuffers();
    const auto expected =
      filteredBy<pcl::VoxelGrid<pcl::PointXYZ>, pcl::PointXYZ>(cloud, 0.01f, 0);
    ASSERT_GT(expected.size(), 100u);
    grid.setInputCloud(cloud);
    pcl::PointCloud<pcl::PointXYZ> got;
    grid.filter(got);
    expectSameBytes(got, expected, "cloud " + std::to_string(step++));
  }
}
