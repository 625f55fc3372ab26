// SPDX-License-Identifier: BSD-3-Clause
// The accumulate stage's plane cloud: one point per voxel of leaf_size_m, the one
// nearest the voxel's centre, as pcl::UniformSampling keeps over the whole
// accumulated cloud, while the stage visits only the points added since its last
// sampling.
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <pcl/filters/uniform_sampling.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <memory>
#include <random>
#include <tuple>
#include <vector>

namespace {

using Labelled = pcl::PointCloud<pcl::PointXYZL>;

/** The points as sorted (x, y, z, label) tuples: the set, whatever the order. */
std::vector<std::tuple<float, float, float, std::uint32_t>>
sortedPoints(const Labelled& cloud)
{
  std::vector<std::tuple<float, float, float, std::uint32_t>> out;
  for (const auto& p : cloud.points)
    out.emplace_back(p.x, p.y, p.z, p.label);
  std::sort(out.begin(), out.end());
  return out;
}

} // namespace

// 23 frames of a wall and a floor plane with jittered points that revisit the same
// voxels (0.1 m), sampled every 4th frame and once more at the end, through a rolling
// window: after every sampling the plane cloud is exactly
// pcl::UniformSampling's output over every inlier the frames gave (the window's crop
// applied to that oracle too).
TEST(AccumulateStage, PlaneCloudIsTheUniformSamplingOfEveryInlier)
{
  const auto* info = planar_grid::findStage("accumulate");
  ASSERT_NE(info, nullptr);
  for (const double window_radius_m : {0.0, 3.0}) {
    SCOPED_TRACE(window_radius_m);
    planar_grid::ParamValues v = planar_grid::defaultParams(info->params);
    v.set("leaf_size_m", 0.1);
    v.set("downsample_every_n_frames", 4);
    v.set("window_radius_m", window_radius_m);
    auto stage = info->create(v);
    planar_grid::PipelineState state;
    Labelled::Ptr all(new Labelled);
    std::mt19937 rng(3);
    std::uniform_real_distribution<float> along(0.0f, 4.0f), jitter(-0.002f, 0.002f);
    for (int f = 0; f < 23; ++f) {
      planar_grid::Frame frame;
      frame.cloud.reset(new planar_grid::Frame::Cloud);
      frame.cloud_in_world_frame = true;
      frame.has_pose = true;
      frame.world_T_camera = Eigen::Isometry3d::Identity();
      frame.world_T_camera.translation() = Eigen::Vector3d(0.1 * f, 0.0, 1.5);
      planar_grid::PlanarSegment wall, floor;
      wall.model_coefficients.values = {0.0f, 1.0f, 0.0f, -4.0f};
      floor.model_coefficients.values = {0.0f, 0.0f, 1.0f, 0.0f};
      for (int i = 0; i < 400; ++i) {
        pcl::PointXYZI p;
        // on a 2 cm lattice plus jitter, so voxels get several candidates
        const float u = std::round(along(rng) * 50.0f) / 50.0f + jitter(rng);
        const float w = std::round(along(rng) * 50.0f) / 50.0f + jitter(rng);
        p.getVector3fMap() = i % 2 == 0 ? Eigen::Vector3f(u + 0.1f * f, 4.0f, w)
                                        : Eigen::Vector3f(u + 0.1f * f, w, 0.0f);
        (i % 2 == 0 ? wall : floor)
          .inliers.indices.push_back(static_cast<int>(frame.cloud->size()));
        frame.cloud->push_back(p);
      }
      frame.planes.push_back(wall);
      frame.planes.push_back(floor);
      stage->process(frame, state);
      // the oracle's cloud: every inlier with the run-wide label the stage gave it
      for (std::size_t k = 0; k < frame.planes.size(); ++k)
        for (const int i : frame.planes[k].inliers.indices) {
          pcl::PointXYZL q;
          q.getVector3fMap() =
            (*frame.cloud)[static_cast<std::size_t>(i)].getVector3fMap();
          q.label = static_cast<std::uint32_t>(k); // wall 0, floor 1: the first ids
          all->push_back(q);
        }
      const bool sampled = (f + 1) % 4 == 0 || f == 22;
      if (f == 22)
        stage->finish(state);
      if (!sampled)
        continue;
      // (the last sampling, at the end of the run, samples without a crop)
      if (window_radius_m > 0.0 && (f + 1) % 4 == 0) {
        const Eigen::Vector3d c = frame.world_T_camera.translation();
        auto& pts = all->points;
        pts.erase(std::remove_if(pts.begin(), pts.end(),
                                 [&](const pcl::PointXYZL& p) {
                                   return !(std::abs(p.x - c.x()) <= window_radius_m
                                            && std::abs(p.y - c.y())
                                                 <= window_radius_m);
                                 }),
                  pts.end());
        all->width = static_cast<std::uint32_t>(pts.size());
        all->height = 1;
      }
      pcl::UniformSampling<pcl::PointXYZL> sampling;
      sampling.setRadiusSearch(0.1);
      sampling.setInputCloud(all);
      Labelled::Ptr expected(new Labelled);
      sampling.filter(*expected);
      ASSERT_GT(expected->size(), 100u);
      EXPECT_EQ(sortedPoints(state.planes->getInlierCloud()), sortedPoints(*expected))
        << "frame " << f;
      all = expected; // the oracle goes on from its own sampling, as the stage did
    }
  }
}
