// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/odometry/cloud_registration.h>

#include <pcl/common/transforms.h>
#include <pcl/console/print.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/registration/gicp.h>
#include <pcl/registration/sample_consensus_prerejective.h>
#include <pcl/search/kdtree.h>

#include <cmath>
#include <cstdlib>
#include <vector>

namespace planar_grid {

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;
using Features = pcl::PointCloud<pcl::FPFHSignature33>;

Cloud::Ptr
downsample(const Cloud& cloud, double leaf_size_m)
{
  Cloud::Ptr finite(new Cloud);
  pcl::Indices kept;
  pcl::removeNaNFromPointCloud(cloud, *finite, kept);
  Cloud::Ptr out(new Cloud);
  pcl::VoxelGrid<pcl::PointXYZ> grid;
  const auto leaf = static_cast<float>(leaf_size_m);
  grid.setLeafSize(leaf, leaf, leaf);
  grid.setInputCloud(finite);
  grid.filter(*out);
  return out;
}

Normals::Ptr
normalsOf(const Cloud::ConstPtr& cloud, double radius_m)
{
  pcl::NormalEstimation<pcl::PointXYZ, pcl::Normal> estimation;
  estimation.setInputCloud(cloud);
  estimation.setSearchMethod(
    pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  estimation.setRadiusSearch(radius_m);
  Normals::Ptr normals(new Normals);
  estimation.compute(*normals);
  return normals;
}

Features::Ptr
featuresOf(const Cloud::ConstPtr& cloud,
           const Normals::ConstPtr& normals,
           double radius_m)
{
  pcl::FPFHEstimation<pcl::PointXYZ, pcl::Normal, pcl::FPFHSignature33> estimation;
  estimation.setInputCloud(cloud);
  estimation.setInputNormals(normals);
  estimation.setSearchMethod(
    pcl::search::KdTree<pcl::PointXYZ>::Ptr(new pcl::search::KdTree<pcl::PointXYZ>));
  estimation.setRadiusSearch(radius_m);
  Features::Ptr features(new Features);
  estimation.compute(*features);
  return features;
}

/** Two GICP passes (coarse, then fine at a quarter of the correspondence distance)
 * from \a guess. */
Eigen::Matrix4f
refine(const Cloud::ConstPtr& source,
       const Cloud::ConstPtr& target,
       const Eigen::Matrix4f& guess,
       const CloudRegistrationParams& params,
       bool& converged)
{
  Eigen::Matrix4f transform = guess;
  converged = true;
  for (const double distance : {params.max_correspondence_distance_m,
                                0.25 * params.max_correspondence_distance_m}) {
    pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
    gicp.setInputSource(source);
    gicp.setInputTarget(target);
    gicp.setMaxCorrespondenceDistance(distance);
    gicp.setMaximumIterations(params.max_iterations);
    gicp.setTransformationEpsilon(1e-8);
    Cloud aligned;
    gicp.align(aligned, transform);
    converged = converged && gicp.hasConverged();
    transform = gicp.getFinalTransformation();
  }
  return transform;
}

/** Overlap and point-to-plane residual of \a source moved by \a transform. */
void
score(const Cloud& source,
      const pcl::KdTreeFLANN<pcl::PointXYZ>& tree,
      const Cloud& target,
      const Normals& target_normals,
      const Eigen::Matrix4f& transform,
      double inlier_distance_m,
      double& overlap,
      double& residual_m)
{
  Cloud moved;
  pcl::transformPointCloud(source, moved, transform);
  pcl::Indices index(1);
  std::vector<float> squared(1);
  const double max_squared = inlier_distance_m * inlier_distance_m;
  double sum = 0.0;
  std::size_t count = 0;
  for (const auto& p : moved.points) {
    if (tree.nearestKSearch(p, 1, index, squared) != 1 || squared[0] > max_squared)
      continue;
    const auto k = static_cast<std::size_t>(index[0]);
    const Eigen::Vector3f n = target_normals[k].getNormalVector3fMap();
    // A target point without a normal (too few neighbours) counts by its distance.
    const double d = std::isfinite(n.x())
                       ? n.dot(p.getVector3fMap() - target[k].getVector3fMap())
                       : std::sqrt(static_cast<double>(squared[0]));
    sum += d * d;
    ++count;
  }
  overlap = moved.empty()
              ? 0.0
              : static_cast<double>(count) / static_cast<double>(moved.size());
  residual_m = count == 0 ? 0.0 : std::sqrt(sum / static_cast<double>(count));
}

} // namespace

CloudRegistrationResult
registerCloud(const pcl::PointCloud<pcl::PointXYZ>& source,
              const pcl::PointCloud<pcl::PointXYZ>& target,
              const Eigen::Isometry3d& initial_guess,
              const CloudRegistrationParams& params)
{
  CloudRegistrationResult result;
  result.target_T_source = initial_guess;
  const Cloud::Ptr source_down = downsample(source, params.leaf_size_m);
  const Cloud::Ptr target_down = downsample(target, params.leaf_size_m);
  if (source_down->size() < 10 || target_down->size() < 10) {
    PCL_WARN("[planar_grid::registerCloud] Too few points to register (%zu source, %zu "
             "target).\n",
             source_down->size(), target_down->size());
    return result;
  }
  const Normals::Ptr target_normals = normalsOf(target_down, 3.0 * params.leaf_size_m);
  pcl::KdTreeFLANN<pcl::PointXYZ> tree;
  tree.setInputCloud(target_down);

  bool converged = false;
  Eigen::Matrix4f best = refine(
    source_down, target_down, initial_guess.matrix().cast<float>(), params, converged);
  score(*source_down, tree, *target_down, *target_normals, best,
        params.inlier_distance_m, result.overlap, result.residual_m);
  result.converged = converged;

  if (params.feature_initial_guess && result.overlap < params.feature_guess_overlap) {
    const Cloud::Ptr source_coarse = downsample(source, params.feature_leaf_size_m);
    const Cloud::Ptr target_coarse = downsample(target, params.feature_leaf_size_m);
    const Features::Ptr source_features =
      featuresOf(source_coarse, normalsOf(source_coarse, params.normal_radius_m),
                 params.feature_radius_m);
    const Features::Ptr target_features =
      featuresOf(target_coarse, normalsOf(target_coarse, params.normal_radius_m),
                 params.feature_radius_m);
    pcl::SampleConsensusPrerejective<pcl::PointXYZ, pcl::PointXYZ, pcl::FPFHSignature33>
      alignment;
    alignment.setInputSource(source_coarse);
    alignment.setSourceFeatures(source_features);
    alignment.setInputTarget(target_coarse);
    alignment.setTargetFeatures(target_features);
    alignment.setMaximumIterations(params.feature_max_iterations);
    alignment.setNumberOfSamples(3);
    alignment.setCorrespondenceRandomness(5);
    alignment.setSimilarityThreshold(0.9f);
    alignment.setMaxCorrespondenceDistance(2.5 * params.feature_leaf_size_m);
    alignment.setInlierFraction(0.25f);
    // SampleConsensusPrerejective draws its samples with std::rand: seeding it here
    // makes the guess, and so the registration, reproducible.
    std::srand(params.seed);
    Cloud aligned;
    alignment.align(aligned);
    if (alignment.hasConverged()) {
      bool feature_converged = false;
      const Eigen::Matrix4f candidate =
        refine(source_down, target_down, alignment.getFinalTransformation(), params,
               feature_converged);
      double overlap = 0.0, residual_m = 0.0;
      score(*source_down, tree, *target_down, *target_normals, candidate,
            params.inlier_distance_m, overlap, residual_m);
      if (overlap > result.overlap) {
        best = candidate;
        result.overlap = overlap;
        result.residual_m = residual_m;
        result.converged = feature_converged;
        result.feature_guess_used = true;
      }
    }
  }
  result.target_T_source.matrix() = best.cast<double>();
  // Re-orthonormalise: the float product of GICP's iterations drifts by ~1e-7.
  const Eigen::Quaterniond q(result.target_T_source.rotation());
  result.target_T_source.linear() = q.normalized().toRotationMatrix();
  return result;
}

} // namespace planar_grid
