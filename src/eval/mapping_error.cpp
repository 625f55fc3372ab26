// SPDX-License-Identifier: BSD-3-Clause
// The mapping error (accuracy) of a map against the ground-truth surface: samples of a
// voxel grid, boxes, cuboids or an octree, and their distances to the truth.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/mapping_error.h>

#include <pcl/console/print.h>
#include <pcl/search/kdtree.h>

#include <octomap/OcTree.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <string>
#include <unordered_map>
#include <utility>
#include <vector>

#include "mapping_error_impl.h"

namespace planar_grid {

struct GroundTruthSurface::Impl {
  pcl::search::KdTree<pcl::PointXYZ> tree{true};
  pcl::PointCloud<pcl::PointXYZ>::Ptr points{new pcl::PointCloud<pcl::PointXYZ>};
};

GroundTruthSurface::GroundTruthSurface(
  pcl::PointCloud<pcl::PointXYZ>::ConstPtr surface_points) :
    impl_(std::make_unique<Impl>())
{
  if (!surface_points)
    throw Exception("GroundTruthSurface: null surface_points");
  for (const auto& p : surface_points->points)
    if (std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z))
      impl_->points->push_back(p);
  if (impl_->points->empty())
    throw Exception("GroundTruthSurface: surface_points holds no finite point ("
                    + std::to_string(surface_points->size()) + " points)");
  impl_->tree.setInputCloud(impl_->points);
}

GroundTruthSurface::GroundTruthSurface(GroundTruthSurface&&) noexcept = default;
GroundTruthSurface&
GroundTruthSurface::operator=(GroundTruthSurface&&) noexcept = default;
GroundTruthSurface::~GroundTruthSurface() = default;

float
GroundTruthSurface::distance(const Eigen::Vector3f& point) const
{
  if (!point.allFinite())
    return std::numeric_limits<float>::infinity();
  pcl::Indices index(1);
  std::vector<float> squared_distance(1);
  pcl::PointXYZ query(point.x(), point.y(), point.z());
  if (impl_->tree.nearestKSearch(query, 1, index, squared_distance) < 1)
    return std::numeric_limits<float>::infinity();
  return std::sqrt(squared_distance[0]);
}

std::size_t
GroundTruthSurface::radiusSearch(const Eigen::Vector3f& point,
                                 double radius_m,
                                 pcl::Indices& indices) const
{
  indices.clear();
  if (!point.allFinite() || !(radius_m > 0.0))
    return 0;
  std::vector<float> squared_distances;
  const pcl::PointXYZ query(point.x(), point.y(), point.z());
  impl_->tree.radiusSearch(query, radius_m, indices, squared_distances);
  return indices.size();
}

std::size_t
GroundTruthSurface::size() const
{
  return impl_->points->size();
}

GroundTruthSurface::PointCloudConstPtr
GroundTruthSurface::getPoints() const
{
  return impl_->points;
}

namespace {

using detail::checkResolution;
using detail::checkTolerance;
using detail::samplesAlong;

/** \brief Counts one sample (when inside the region). */
struct Counter {
  const GroundTruthSurface& truth;
  double tolerance_m;
  const MappingErrorRegion* region;
  MappingError error;
  /** Whether the current cell has a counted sample. */
  bool cell_counted{false};

  void add(const Eigen::Vector3f& sample)
  {
    if (region != nullptr && !region->contains(sample))
      return;
    cell_counted = true;
    ++error.samples;
    if (static_cast<double>(truth.distance(sample)) > tolerance_m)
      ++error.erroneous;
  }

  /** Ends the samples of one cell: counts it when one of them was counted. */
  void closeCell()
  {
    error.cells += cell_counted;
    cell_counted = false;
  }
};

/** \brief Samples at the voxel centres of a box of n voxels of edge r from \a min_m
 * (the corner), in double. */
void
addVoxelLattice(const Eigen::Vector3d& min_m,
                const Eigen::Vector3i& n,
                double r,
                Counter& counter)
{
  for (int k = 0; k < n.z(); ++k)
    for (int j = 0; j < n.y(); ++j)
      for (int i = 0; i < n.x(); ++i)
        counter.add(
          (min_m + Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5) * r).cast<float>());
}

MappingError
voxels(const StandardVoxelGrid& grid,
       const GroundTruthSurface& truth,
       double tolerance_m,
       const MappingErrorRegion* region)
{
  checkTolerance(tolerance_m);
  Counter counter{truth, tolerance_m, region, {}};
  pcl::PointCloud<pcl::PointXYZ> centres;
  grid.getOccupiedCentres(centres);
  for (const auto& c : centres.points) {
    counter.add(c.getVector3fMap());
    counter.closeCell();
  }
  return counter.error;
}

MappingError
boxes(const AxisAlignedBoxes& boxes,
      double resolution_m,
      const GroundTruthSurface& truth,
      double tolerance_m,
      const MappingErrorRegion* region)
{
  checkResolution(resolution_m);
  checkTolerance(tolerance_m);
  Counter counter{truth, tolerance_m, region, {}};
  for (const auto& box : boxes)
    if (box.occupied) {
      addVoxelLattice(box.min_index.cast<double>() * resolution_m, box.size,
                      resolution_m, counter);
      counter.closeCell();
    }
  return counter.error;
}

MappingError
cuboids(const PlanarCuboids& cuboids,
        double occupancy_thres,
        double resolution_m,
        const GroundTruthSurface& truth,
        double tolerance_m,
        const MappingErrorRegion* region)
{
  checkResolution(resolution_m);
  checkTolerance(tolerance_m);
  if (!(occupancy_thres >= 0.0 && occupancy_thres <= 1.0))
    throw Exception("evaluateCuboids: occupancy_thres must be a probability in [0, 1], "
                    "got "
                    + std::to_string(occupancy_thres));
  Counter counter{truth, tolerance_m, region, {}};
  std::size_t skipped = 0;
  for (const auto& c : cuboids) {
    if (!(static_cast<double>(c.probability) >= occupancy_thres))
      continue;
    const std::int64_t nu = samplesAlong(c.width_m, resolution_m);
    const std::int64_t nv = samplesAlong(c.height_m, resolution_m);
    const std::int64_t nn = samplesAlong(c.thickness_m, resolution_m);
    if (nu == 0 || nv == 0 || nn == 0 || !c.centre.allFinite() || !c.normal.allFinite()
        || !c.horizontal_axis.allFinite()
        || static_cast<double>(nu) * static_cast<double>(nv) * static_cast<double>(nn)
             > 1e9) {
      ++skipped;
      continue;
    }
    const Eigen::Vector3d u = c.horizontal_axis.cast<double>();
    const Eigen::Vector3d v = c.verticalAxis().cast<double>();
    const Eigen::Vector3d n = c.normal.cast<double>();
    const Eigen::Vector3d centre = c.centre.cast<double>();
    const double w = c.width_m, h = c.height_m, t = c.thickness_m;
    for (std::int64_t k = 0; k < nn; ++k) {
      const double on = detail::sampleOffset(k, nn, t);
      for (std::int64_t j = 0; j < nv; ++j) {
        const double ov = detail::sampleOffset(j, nv, h);
        for (std::int64_t i = 0; i < nu; ++i) {
          const double ou = detail::sampleOffset(i, nu, w);
          counter.add((centre + ou * u + ov * v + on * n).cast<float>());
        }
      }
    }
    counter.closeCell();
  }
  if (skipped > 0)
    PCL_WARN(
      "[planar_grid::evaluateCuboids] %zu cuboids with non-finite fields or more "
      "than 1e9 samples skipped.\n",
      skipped);
  return counter.error;
}

MappingError
ocTree(const octomap::OcTree& tree,
       const GroundTruthSurface& truth,
       double tolerance_m,
       const MappingErrorRegion* region)
{
  checkTolerance(tolerance_m);
  Counter counter{truth, tolerance_m, region, {}};
  const double r = tree.getResolution();
  const unsigned depth = tree.getTreeDepth();
  for (auto it = tree.begin_leafs(), end = tree.end_leafs(); it != end; ++it) {
    if (!tree.isNodeOccupied(*it))
      continue;
    const int n = 1 << (depth - it.getDepth());
    const octomap::point3d centre = it.getCoordinate();
    const Eigen::Vector3d min_m = Eigen::Vector3d(centre.x(), centre.y(), centre.z())
                                  - Eigen::Vector3d::Constant(0.5 * it.getSize());
    addVoxelLattice(min_m, Eigen::Vector3i::Constant(n), r, counter);
    counter.closeCell();
  }
  return counter.error;
}

} // namespace

MappingError
evaluateVoxels(const StandardVoxelGrid& grid,
               const GroundTruthSurface& truth,
               double tolerance_m)
{
  return voxels(grid, truth, tolerance_m, nullptr);
}

MappingError
evaluateVoxels(const StandardVoxelGrid& grid,
               const GroundTruthSurface& truth,
               double tolerance_m,
               const MappingErrorRegion& region)
{
  return voxels(grid, truth, tolerance_m, &region);
}

MappingError
evaluateBoxes(const AxisAlignedBoxes& boxes_in,
              double resolution_m,
              const GroundTruthSurface& truth,
              double tolerance_m)
{
  return boxes(boxes_in, resolution_m, truth, tolerance_m, nullptr);
}

MappingError
evaluateBoxes(const AxisAlignedBoxes& boxes_in,
              double resolution_m,
              const GroundTruthSurface& truth,
              double tolerance_m,
              const MappingErrorRegion& region)
{
  return boxes(boxes_in, resolution_m, truth, tolerance_m, &region);
}

MappingError
evaluateCuboids(const PlanarCuboids& cuboids_in,
                double occupancy_thres,
                double resolution_m,
                const GroundTruthSurface& truth,
                double tolerance_m)
{
  return cuboids(cuboids_in, occupancy_thres, resolution_m, truth, tolerance_m,
                 nullptr);
}

MappingError
evaluateCuboids(const PlanarCuboids& cuboids_in,
                double occupancy_thres,
                double resolution_m,
                const GroundTruthSurface& truth,
                double tolerance_m,
                const MappingErrorRegion& region)
{
  return cuboids(cuboids_in, occupancy_thres, resolution_m, truth, tolerance_m,
                 &region);
}

MappingError
evaluateOcTree(const octomap::OcTree& tree,
               const GroundTruthSurface& truth,
               double tolerance_m)
{
  return ocTree(tree, truth, tolerance_m, nullptr);
}

MappingError
evaluateOcTree(const octomap::OcTree& tree,
               const GroundTruthSurface& truth,
               double tolerance_m,
               const MappingErrorRegion& region)
{
  return ocTree(tree, truth, tolerance_m, &region);
}

} // namespace planar_grid
