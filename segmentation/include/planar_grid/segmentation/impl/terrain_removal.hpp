// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/terrain_removal.h>

#include <pcl/common/centroid.h>
#include <pcl/common/point_tests.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <map>
#include <string>
#include <unordered_map>
#include <utility>

namespace planar_grid {

namespace terrain_removal_detail {

enum : std::uint8_t { UNSEEN, STANDS, LIES };

/** \brief A terrain cell's key in the ground plane's frame: floor(a . p / cell) in
 * the high 32 bits, floor(b . p / cell) in the low ones. */
inline std::uint64_t
cellKey(const Eigen::Vector3f& p,
        const Eigen::Vector3f& a1,
        const Eigen::Vector3f& a2,
        float inv_cell)
{
  const auto x = static_cast<std::int64_t>(std::floor(a1.dot(p) * inv_cell));
  const auto y = static_cast<std::int64_t>(std::floor(a2.dot(p) * inv_cell));
  return (static_cast<std::uint64_t>(x + (1 << 30)) << 32)
         | static_cast<std::uint64_t>(y + (1 << 30));
}

} // namespace terrain_removal_detail

template <typename PointT>
void
TerrainRemoval<PointT>::checkParameters() const
{
  const std::string bad = checkDeclaredRanges(getParamDeclarations(), params_);
  if (!bad.empty())
    throw Exception("TerrainRemoval: " + bad);
  if (!(up_.norm() > 0.0f) || !up_.allFinite())
    throw Exception("TerrainRemoval: the up axis must be finite and not zero");
  if (!origin_.allFinite())
    throw Exception("TerrainRemoval: the sensor origin must be finite");
}

template <typename PointT>
bool
TerrainRemoval<PointT>::upward(const PlanarSegments& planes,
                               std::size_t k,
                               Eigen::Vector4f& c) const
{
  const auto& values = planes[k].model_coefficients.values;
  if (values.size() != 4)
    return false;
  c = Eigen::Vector4f(values[0], values[1], values[2], values[3]);
  if (c.head<3>().dot(unit_up_) < 0.0f)
    c = -c; // normal up: the sensor's signed distance is its height above the plane
  return true;
}

template <typename PointT>
std::size_t
TerrainRemoval<PointT>::findGround(const PlanarSegments& planes) const
{
  const auto cos_eps = static_cast<float>(std::cos(params_.eps_angle_rad));
  for (std::size_t k = 0; k < planes.size(); ++k) {
    Eigen::Vector4f c;
    if (!upward(planes, k, c) || c.head<3>().dot(unit_up_) < cos_eps
        || c.head<3>().dot(origin_) + c[3] < params_.min_sensor_height_m)
      continue;
    return k;
  }
  return planes.size();
}

template <typename PointT>
std::vector<std::uint8_t>
TerrainRemoval<PointT>::terrainPlanes(const PointCloud& cloud,
                                      const PlanarSegments& planes,
                                      std::size_t ground) const
{
  std::vector<std::uint8_t> terrain(planes.size(), 0);
  terrain[ground] = 1;
  std::vector<float> lowest(planes.size(), 0.0f), level(planes.size());
  for (std::size_t k = 0; k < planes.size(); ++k) {
    float lo = std::numeric_limits<float>::max();
    double sum = 0.0;
    for (const auto i : planes[k].inliers.indices) {
      const float h = heightAboveGround(cloud[static_cast<std::size_t>(i)]);
      lo = std::min(lo, h);
      sum += h;
    }
    lowest[k] = lo;
    level[k] = planes[k].inliers.indices.empty()
                 ? 0.0f
                 : static_cast<float>(
                   sum / static_cast<double>(planes[k].inliers.indices.size()));
  }
  const auto cos_slope = static_cast<float>(std::cos(params_.terrain_max_slope_rad));
  for (bool joined = params_.terrain_max_slope_rad > 0.0; joined;) {
    joined = false;
    for (std::size_t k = 0; k < planes.size(); ++k) {
      Eigen::Vector4f c;
      if (terrain[k] || !upward(planes, k, c) || c.head<3>().dot(unit_up_) < cos_slope)
        continue;
      for (std::size_t t = 0; t < planes.size(); ++t)
        if (terrain[t] && lowest[k] <= level[t] + params_.terrain_max_step_m) {
          terrain[k] = 1;
          joined = true;
          break;
        }
    }
  }
  return terrain;
}

template <typename PointT>
std::vector<std::uint8_t>
TerrainRemoval<PointT>::standingInliers(const PointCloud& cloud,
                                        const PlanarSegments& planes,
                                        const std::vector<std::uint8_t>& terrain) const
{
  using namespace terrain_removal_detail;
  // Where eq. 11's band (the depth error) is wider than terrain_height, the foot of a
  // guardrail, a post or a bush falls in the road's band and stays, and does not raise
  // the terrain's height either. terrain_height 0 is the paper's rule: every inlier of
  // the ground goes.
  const auto terrain_height = static_cast<float>(params_.terrain_height_m);
  std::vector<std::uint8_t> standing(cloud.size(), UNSEEN);
  for (std::size_t k = 0; terrain_height > 0.0f && k < planes.size(); ++k) {
    Eigen::Vector4f c;
    if (!terrain[k] || !upward(planes, k, c))
      continue;
    const float norm = c.head<3>().norm();
    for (const auto i : planes[k].inliers.indices) {
      const auto j = static_cast<std::size_t>(i);
      const bool above =
        (c.head<3>().dot(cloud[j].getVector3fMap()) + c[3]) / norm > terrain_height;
      if (standing[j] != LIES)
        standing[j] = above ? STANDS : LIES;
    }
  }
  return standing;
}

template <typename PointT>
std::vector<std::uint8_t>
TerrainRemoval<PointT>::terrainPoints(const PointCloud& cloud,
                                      const PlanarSegments& planes,
                                      const std::vector<std::uint8_t>& terrain,
                                      const std::vector<std::uint8_t>& standing) const
{
  using namespace terrain_removal_detail;
  // The terrain's height per cell of terrain_cell_m (in the ground plane's frame): the
  // highest mean height of the terrain planes' inliers in that cell.
  Eigen::Vector3f a1 = unit_up_.unitOrthogonal();
  const Eigen::Vector3f normal = ground_.head<3>();
  a1 = (a1 - normal * normal.dot(a1)).normalized();
  const Eigen::Vector3f a2 = normal.cross(a1);
  const float inv_cell = static_cast<float>(1.0 / params_.terrain_cell_m);
  struct Level {
    double sum{0.0};
    std::size_t count{0};
  };
  std::unordered_map<std::uint64_t, float> cell_level;
  std::unordered_map<std::uint64_t, Level> plane_cell;
  std::vector<std::uint8_t> in_plane(cloud.size(), 0);
  for (std::size_t k = 0; k < planes.size(); ++k) {
    plane_cell.clear();
    for (const auto i : planes[k].inliers.indices) {
      const auto j = static_cast<std::size_t>(i);
      if (terrain[k] && standing[j] == STANDS)
        continue; // a loose point
      in_plane[j] = terrain[k] ? 2 : 1;
      if (terrain[k]) {
        Level& l = plane_cell[cellKey(cloud[j].getVector3fMap(), a1, a2, inv_cell)];
        l.sum += heightAboveGround(cloud[j]);
        ++l.count;
      }
    }
    for (const auto& kv : plane_cell) {
      const auto mean = static_cast<float>(kv.second.sum / kv.second.count);
      const auto it = cell_level.emplace(kv.first, mean).first;
      it->second = std::max(it->second, mean);
    }
  }
  // A point in no plane is terrain when it is at most terrain_height above the
  // terrain (or above the ground plane where no terrain plane reaches).
  const auto terrain_height = static_cast<float>(params_.terrain_height_m);
  std::vector<std::uint8_t> remove(cloud.size(), 0);
  for (std::size_t i = 0; i < cloud.size(); ++i) {
    if (in_plane[i] == 2) {
      remove[i] = params_.terrain_plane_tile_m > 0.0 ? 0 : 1;
      continue;
    }
    if (in_plane[i] == 1 || !pcl::isFinite(cloud[i]))
      continue;
    const auto it =
      cell_level.find(cellKey(cloud[i].getVector3fMap(), a1, a2, inv_cell));
    const float base = it == cell_level.end() ? 0.0f : std::max(0.0f, it->second);
    remove[i] = heightAboveGround(cloud[i]) <= base + terrain_height ? 1 : 0;
  }
  return remove;
}

template <typename PointT>
void
TerrainRemoval<PointT>::splitIntoTiles(const PointCloud& cloud,
                                       const std::vector<std::uint8_t>& terrain,
                                       PlanarSegments& planes,
                                       std::vector<std::uint8_t>& remove) const
{
  const double tile_m = params_.terrain_plane_tile_m;
  const auto cos_slope = static_cast<float>(std::cos(params_.terrain_max_slope_rad));
  PlanarSegments out;
  for (std::size_t k = 0; k < planes.size(); ++k) {
    if (!terrain[k]) {
      out.push_back(std::move(planes[k]));
      continue;
    }
    // the inliers leave the whole plane, whose other fields each tile's plane copies
    const std::vector<int> inliers = std::move(planes[k].inliers.indices);
    planes[k].inliers.indices.clear();
    std::map<std::pair<std::int64_t, std::int64_t>, std::vector<int>> tiles;
    for (const int i : inliers) {
      // the map's tiles (SurfaceLayer::Params::terrain_plane_tile_m): world x, y
      const auto& p = cloud[static_cast<std::size_t>(i)];
      tiles[{static_cast<std::int64_t>(std::floor(static_cast<double>(p.x) / tile_m)),
             static_cast<std::int64_t>(std::floor(static_cast<double>(p.y) / tile_m))}]
        .push_back(i);
    }
    const auto& values = planes[k].model_coefficients.values;
    const Eigen::Vector3f plane_normal(values[0], values[1], values[2]);
    for (auto& tile : tiles) {
      if (tile.second.size() < 3) {
        for (const int i : tile.second)
          remove[static_cast<std::size_t>(i)] = 1;
        continue;
      }
      Eigen::Vector4f centroid = Eigen::Vector4f::Zero();
      Eigen::Matrix3f covariance = Eigen::Matrix3f::Zero();
      if (pcl::computeMeanAndCovarianceMatrix(cloud, tile.second, covariance, centroid)
          == 0)
        continue;
      Eigen::Vector3f n = plane_normal;
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f> solver(covariance);
      const Eigen::Vector3f values3 = solver.eigenvalues();
      if (values3[1] > 4.0f * values3[0] && values3[0] >= 0.0f) {
        n = solver.eigenvectors().col(0);
        if (n.dot(plane_normal) < 0.0f)
          n = -n;
        if (n.dot(plane_normal) < cos_slope)
          n = plane_normal;
      }
      PlanarSegment segment = planes[k];
      segment.inliers.indices = std::move(tile.second);
      segment.centroid = centroid;
      segment.model_coefficients.values = {n.x(), n.y(), n.z(),
                                           -n.dot(centroid.head<3>())};
      out.push_back(std::move(segment));
    }
  }
  planes = std::move(out);
}

template <typename PointT>
bool
TerrainRemoval<PointT>::segment(const PointCloud& cloud,
                                PlanarSegments& planes,
                                std::vector<std::uint8_t>& terrain)
{
  checkParameters();
  unit_up_ = up_.normalized();
  terrain.assign(cloud.size(), 0);
  terrain_plane_count_ = 0;
  const std::size_t ground = findGround(planes);
  if (ground == planes.size())
    return false;
  upward(planes, ground, ground_);
  const std::vector<std::uint8_t> terrain_planes = terrainPlanes(cloud, planes, ground);
  const std::vector<std::uint8_t> standing =
    standingInliers(cloud, planes, terrain_planes);
  terrain = terrainPoints(cloud, planes, terrain_planes, standing);
  for (const auto t : terrain_planes)
    terrain_plane_count_ += t;

  if (params_.terrain_plane_tile_m > 0.0) {
    // A terrain plane keeps the inliers lying on it (not those standing above it,
    // which stay as loose points for the non-planar cells), and stays a plane, one
    // per tile: the approximation makes its planar cells, and the map knows them as
    // terrain by their normal.
    for (std::size_t k = 0; k < planes.size(); ++k) {
      if (!terrain_planes[k])
        continue;
      auto& indices = planes[k].inliers.indices;
      indices.erase(std::remove_if(indices.begin(), indices.end(),
                                   [&](int i) {
                                     return standing[static_cast<std::size_t>(i)]
                                            == terrain_removal_detail::STANDS;
                                   }),
                    indices.end());
    }
    splitIntoTiles(cloud, terrain_planes, planes, terrain);
    return true;
  }
  // The non-terrain planes keep their order; a plane already in place is not moved
  // onto itself (a self-move empties its coefficient and inlier vectors).
  std::size_t kept = 0;
  for (std::size_t k = 0; k < planes.size(); ++k) {
    if (terrain_planes[k])
      continue;
    if (kept != k)
      planes[kept] = std::move(planes[k]);
    ++kept;
  }
  planes.resize(kept);
  return true;
}

} // namespace planar_grid
