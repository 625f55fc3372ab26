// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>

#include <Eigen/Geometry>

#include <cmath>
#include <cstdint>
#include <limits>
#include <random>
#include <utility>

namespace planar_grid_test {

/** \brief Pinhole intrinsics of an organized cloud, px. */
struct Intrinsics {
  double fx{0.0}, fy{0.0}, cx{0.0}, cy{0.0};
};

/** \brief The intrinsics of an organized cloud's camera: u = fx x / z + cx and
 * v = fy y / z + cy fitted by least squares over its finite points. */
template <typename PointT>
Intrinsics
fitIntrinsics(const pcl::PointCloud<PointT>& cloud)
{
  // Normal equations of the two straight lines u(x/z) and v(y/z).
  double su = 0, sa = 0, saa = 0, sau = 0, sv = 0, sb = 0, sbb = 0, sbv = 0, n = 0;
  for (std::uint32_t row = 0; row < cloud.height; ++row)
    for (std::uint32_t col = 0; col < cloud.width; ++col) {
      const auto& p = cloud.at(col, row);
      if (!std::isfinite(p.z) || p.z <= 0.0f)
        continue;
      const double a = p.x / p.z, b = p.y / p.z;
      su += col;
      sa += a;
      saa += a * a;
      sau += a * col;
      sv += row;
      sb += b;
      sbb += b * b;
      sbv += b * row;
      n += 1;
    }
  Intrinsics k;
  k.fx = (n * sau - sa * su) / (n * saa - sa * sa);
  k.cx = (su - k.fx * sa) / n;
  k.fy = (n * sbv - sb * sv) / (n * sbb - sb * sb);
  k.cy = (sv - k.fy * sb) / n;
  return k;
}

/** \brief What the camera of \a cloud sees from the pose \a first_T_second (the second
 * camera in the first's frame): every point, with its colour or intensity, moved into
 * the second camera's frame and projected with \a k into a new organized image of the
 * same size, the nearest point per pixel kept (z-buffer). Pixels that no point reaches
 * are NaN with zero colour, except a hole of one pixel between points (the
 * resampling's, not a real shadow), which takes its nearest neighbour's point. */
template <typename PointT>
pcl::PointCloud<PointT>
reproject(const pcl::PointCloud<PointT>& cloud,
          const Intrinsics& k,
          const Eigen::Isometry3d& first_T_second)
{
  const float nan = std::numeric_limits<float>::quiet_NaN();
  PointT empty;
  empty.x = empty.y = empty.z = nan;
  pcl::PointCloud<PointT> out;
  out.resize(cloud.size(), empty);
  out.width = cloud.width;
  out.height = cloud.height;
  out.is_dense = false;
  const Eigen::Affine3f second_T_first = first_T_second.inverse().cast<float>();
  const int w = static_cast<int>(cloud.width), h = static_cast<int>(cloud.height);
  for (const auto& p : cloud.points) {
    if (!std::isfinite(p.z))
      continue;
    PointT q = p;
    q.getVector3fMap() = second_T_first * p.getVector3fMap();
    if (q.z <= 0.1f)
      continue;
    const int u = static_cast<int>(std::lround(k.fx * q.x / q.z + k.cx));
    const int v = static_cast<int>(std::lround(k.fy * q.y / q.z + k.cy));
    if (u < 0 || v < 0 || u >= w || v >= h)
      continue;
    auto& slot = out.at(u, v);
    if (!std::isfinite(slot.z) || q.z < slot.z)
      slot = q;
  }
  const pcl::PointCloud<PointT> sparse = out;
  for (int v = 1; v + 1 < h; ++v)
    for (int u = 1; u + 1 < w; ++u) {
      if (std::isfinite(sparse.at(u, v).z))
        continue;
      const PointT* nearest = nullptr;
      int valid = 0;
      for (const auto& [du, dv] : {std::pair{-1, 0}, {1, 0}, {0, -1}, {0, 1}}) {
        const auto& n = sparse.at(u + du, v + dv);
        if (!std::isfinite(n.z))
          continue;
        ++valid;
        if (!nearest || n.z < nearest->z)
          nearest = &n;
      }
      if (valid >= 3)
        out.at(u, v) = *nearest;
    }
  return out;
}

/** \brief \a cloud's image on a plane (a poster of the scene): every pixel's ray,
 * through \a k, meets the plane normal . p = distance_m, and the pixel's point moves
 * there with its colour or intensity; then Kinect-like depth noise along the rays
 * (sigma = depth_noise_per_m z^2, seeded). */
template <typename PointT>
void
projectOntoPlane(pcl::PointCloud<PointT>& cloud,
                 const Intrinsics& k,
                 const Eigen::Vector3d& normal,
                 double distance_m)
{
  for (std::uint32_t v = 0; v < cloud.height; ++v)
    for (std::uint32_t u = 0; u < cloud.width; ++u) {
      const Eigen::Vector3d ray((u - k.cx) / k.fx, (v - k.cy) / k.fy, 1.0);
      cloud.at(u, v).getVector3fMap() =
        (ray * (distance_m / normal.dot(ray))).template cast<float>();
    }
}

/** \brief Depth noise along the rays of a depth camera: each finite point is scaled by
 * 1 + depth_noise_per_m z n, n standard normal (seeded by \a seed), so its depth error
 * has sigma = depth_noise_per_m z^2 (metres). */
template <typename PointT>
void
addDepthNoise(pcl::PointCloud<PointT>& cloud, float depth_noise_per_m, unsigned seed)
{
  std::mt19937 rng(seed);
  std::normal_distribution<float> unit(0.0f, 1.0f);
  for (auto& p : cloud.points)
    if (std::isfinite(p.z))
      p.getVector3fMap() *= 1.0f + depth_noise_per_m * p.z * unit(rng);
}

/** \brief A camera pan: a turn of \a yaw_rad about the camera's y axis (down), a 0.05
 * rad tilt about its x axis and a step, as a hand-held RGB-D sweep makes
 * (first_T_second). */
inline Eigen::Isometry3d
panMotion(double yaw_rad, const Eigen::Vector3d& translation_m)
{
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitY())
                * Eigen::AngleAxisd(0.05, Eigen::Vector3d::UnitX()))
                 .toRotationMatrix();
  t.translation() = translation_m;
  return t;
}

} // namespace planar_grid_test
