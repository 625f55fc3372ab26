// SPDX-License-Identifier: BSD-3-Clause
// Shared by the benchmarks: a real Karlsruhe frame made ground-free the way the
// pipeline does it (SGBM cloud to 30 m, 0.1 m VoxelGrid, SACMultiPlaneSegmentation,
// ground planes removed), in the camera frame, with its disparity and features input.
#pragma once

#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>

#include <map>

#include "karlsruhe_frame.h"

namespace planar_grid {
namespace bench {

using Cloud = pcl::PointCloud<pcl::PointXYZI>;

constexpr double DISTANCE_THRESHOLD_M = 0.05; // the paper's d_T (eq. 11)
constexpr double MAX_RANGE_M = 30.0;
constexpr double GROUND_EPS_RAD = 15.0 * M_PI / 180.0;

/** \brief One ground-free scene: points, planes (ground candidates removed). */
struct Scene {
  Cloud::Ptr cloud{new Cloud};
  planar_grid::PlanarSegments planes;
  /** \brief The stereo pair and its SGBM disparity (karlsruhe() only). */
  KarlsruhePair pair;
  cv::Mat disparity;
  /** \brief Every finite point before the VoxelGrid (SGBM to MAX_RANGE_M for
   * karlsruhe()). */
  Cloud::Ptr dense{new Cloud};
  bool ok{false};
};

/** \brief Removes the points of the ground-candidate planes (up = -y, camera frame)
 * from the cloud and returns the other planes re-indexed. */
inline void
removeGround(const Cloud& in, const planar_grid::PlanarSegments& planes, Scene& out)
{
  const Eigen::Vector3f up(0.0f, -1.0f, 0.0f);
  std::vector<int> new_index(in.size(), 0);
  for (const auto& p : planes)
    if (planar_grid::isGroundCandidate(p, up, GROUND_EPS_RAD))
      for (const auto i : p.inliers.indices)
        new_index[i] = -1;
  for (std::size_t i = 0; i < in.size(); ++i)
    if (new_index[i] == 0) {
      new_index[i] = static_cast<int>(out.cloud->size());
      out.cloud->push_back(in[i]);
    }
  for (const auto& p : planes) {
    if (planar_grid::isGroundCandidate(p, up, GROUND_EPS_RAD))
      continue;
    planar_grid::PlanarSegment q = p;
    q.inliers.indices.clear();
    for (const auto i : p.inliers.indices)
      q.inliers.indices.push_back(new_index[i]);
    out.planes.push_back(q);
  }
  out.ok = !out.cloud->empty();
}

inline void
segmentAndRemoveGround(const Cloud::Ptr& cloud, Scene& out)
{
  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI> seg;
  // Eq. 11 by distance alone, the sample threshold d_T (the class's defaults are
  // the pipeline's normal test and 0.1 m sample threshold).
  seg.setMaxNormalAngle(0.0);
  seg.setMinNormalAgreement(0.0);
  seg.setMinTerrainSensorHeight(0.0);
  seg.setSampleDistanceThreshold(DISTANCE_THRESHOLD_M);
  seg.setInputCloud(cloud);
  seg.setUpAxis(Eigen::Vector3f(0.0f, -1.0f, 0.0f));
  seg.setDistanceThreshold(DISTANCE_THRESHOLD_M);
  seg.setMinInliers(100);
  planar_grid::PlanarSegments planes;
  seg.segment(planes);
  removeGround(*cloud, planes, out);
}

/** \brief Drops the non-finite points of \a cloud (kept in out.dense), voxelises them
 * with pcl::VoxelGrid at \a leaf_size_m and segments the result with the ground
 * removed.
 */
inline void
voxeliseAndSegment(const Cloud& cloud, float leaf_size_m, Scene& out)
{
  Cloud::Ptr finite(new Cloud);
  pcl::Indices unused;
  pcl::removeNaNFromPointCloud(cloud, *finite, unused);
  out.dense = finite;
  Cloud::Ptr voxelised(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZI> voxel_grid;
  voxel_grid.setInputCloud(finite);
  voxel_grid.setLeafSize(leaf_size_m, leaf_size_m, leaf_size_m);
  voxel_grid.filter(*voxelised);
  segmentAndRemoveGround(voxelised, out);
}

inline const Scene&
karlsruhe(int frame)
{
  static std::map<int, Scene> scenes;
  auto it = scenes.find(frame);
  if (it != scenes.end())
    return it->second;
  Scene& out = scenes[frame];
  const auto pair = loadKarlsruhePair(frame);
  if (!pair.ok)
    return out;
  out.pair = pair;
  DisparityEstimator().compute(pair.left, pair.right, out.disparity);
  Cloud dense;
  disparityToPointCloud(out.disparity, pair.left, pair.model.calibration, MAX_RANGE_M,
                        dense);
  voxeliseAndSegment(dense, 0.1f, out);
  return out;
}

} // namespace bench
} // namespace planar_grid
