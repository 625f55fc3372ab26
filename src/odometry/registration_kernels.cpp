// SPDX-License-Identifier: BSD-3-Clause
// The calls into PCL's header-only registration classes, in a unit of their own: the
// classes are instantiated here and nowhere else, so that this unit alone carries their
// compile time, and the sanitizer build compiles it like the PCL libraries it stands
// beside (optimised, without instrumentation; src/odometry/CMakeLists.txt).
#include "registration_kernels.h"

#include <pcl/registration/gicp.h>
#include <pcl/registration/sample_consensus_prerejective.h>

#include <cstdlib>

namespace planar_grid {
namespace detail {

Eigen::Matrix4f
alignGeneralizedICP(const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& source,
                    const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& target,
                    const Eigen::Matrix4f& guess,
                    double max_correspondence_distance_m,
                    int max_iterations,
                    bool& converged)
{
  pcl::GeneralizedIterativeClosestPoint<pcl::PointXYZ, pcl::PointXYZ> gicp;
  gicp.setInputSource(source);
  gicp.setInputTarget(target);
  gicp.setMaxCorrespondenceDistance(max_correspondence_distance_m);
  gicp.setMaximumIterations(max_iterations);
  gicp.setTransformationEpsilon(1e-8);
  pcl::PointCloud<pcl::PointXYZ> aligned;
  gicp.align(aligned, guess);
  converged = gicp.hasConverged();
  return gicp.getFinalTransformation();
}

bool
alignFeatureCorrespondences(
  const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& source,
  const pcl::PointCloud<pcl::FPFHSignature33>::ConstPtr& source_features,
  const pcl::PointCloud<pcl::PointXYZ>::ConstPtr& target,
  const pcl::PointCloud<pcl::FPFHSignature33>::ConstPtr& target_features,
  int max_iterations,
  double max_correspondence_distance_m,
  unsigned seed,
  Eigen::Matrix4f& transform)
{
  pcl::SampleConsensusPrerejective<pcl::PointXYZ, pcl::PointXYZ, pcl::FPFHSignature33>
    alignment;
  alignment.setInputSource(source);
  alignment.setSourceFeatures(source_features);
  alignment.setInputTarget(target);
  alignment.setTargetFeatures(target_features);
  alignment.setMaximumIterations(max_iterations);
  alignment.setNumberOfSamples(3);
  alignment.setCorrespondenceRandomness(5);
  alignment.setSimilarityThreshold(0.9f);
  alignment.setMaxCorrespondenceDistance(max_correspondence_distance_m);
  alignment.setInlierFraction(0.25f);
  // SampleConsensusPrerejective draws its samples with std::rand.
  std::srand(seed);
  pcl::PointCloud<pcl::PointXYZ> aligned;
  alignment.align(aligned);
  transform = alignment.getFinalTransformation();
  return alignment.hasConverged();
}

} // namespace detail
} // namespace planar_grid
