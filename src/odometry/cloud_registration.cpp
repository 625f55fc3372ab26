// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/cloud_registration.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include <pcl/common/transforms.h>
#include <pcl/console/print.h>
#include <pcl/features/fpfh.h>
#include <pcl/features/normal_3d.h>
#include <pcl/filters/filter.h>
#include <pcl/filters/voxel_grid.h>
#include <pcl/kdtree/kdtree_flann.h>
#include <pcl/search/kdtree.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <vector>

#include "registration_kernels.h"

namespace planar_grid {

namespace {

using Cloud = pcl::PointCloud<pcl::PointXYZ>;
using Normals = pcl::PointCloud<pcl::Normal>;
using Features = pcl::PointCloud<pcl::FPFHSignature33>;

/** Margin without orb_grid key points, px: the upright BRIEF pattern of a 31 px patch
 * reaches 15 px from its key point (the stereo front end's value). */
constexpr int ORB_GRID_BORDER_PX = 16;
/** cv::ORB's patch side, px (its default). */
constexpr int ORB_PATCH_SIZE_PX = 31;

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
    bool pass_converged = false;
    transform = detail::alignGeneralizedICP(source, target, transform, distance,
                                            params.max_iterations, pass_converged);
    converged = converged && pass_converged;
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

/** Where the kept registration started from. */
enum class Guess { INITIAL, IMAGE_FEATURES, FPFH };

/** The FPFH guess: features of both clouds at feature_leaf_size_m matched by
 * pcl::SampleConsensusPrerejective (seeded); false when it does not converge. */
bool
fpfhGuess(const Cloud& source,
          const Cloud& target,
          const CloudRegistrationParams& params,
          Eigen::Matrix4f& guess)
{
  const Cloud::Ptr source_coarse = downsample(source, params.feature_leaf_size_m);
  const Cloud::Ptr target_coarse = downsample(target, params.feature_leaf_size_m);
  const Features::Ptr source_features =
    featuresOf(source_coarse, normalsOf(source_coarse, params.normal_radius_m),
               params.feature_radius_m);
  const Features::Ptr target_features =
    featuresOf(target_coarse, normalsOf(target_coarse, params.normal_radius_m),
               params.feature_radius_m);
  return detail::alignFeatureCorrespondences(
    source_coarse, source_features, target_coarse, target_features,
    params.feature_max_iterations, 2.5 * params.feature_leaf_size_m, params.seed,
    guess);
}

CloudRegistrationResult
registerWithGuesses(const Cloud& source,
                    const Cloud& target,
                    const Eigen::Isometry3d& initial_guess,
                    const CloudRegistrationParams& params,
                    const StereoFeatures* source_features,
                    const StereoFeatures* target_features)
{
  const bool image_guess = params.image_feature_guess && source_features
                           && target_features && !source_features->descriptors.empty()
                           && !target_features->descriptors.empty();
  if (image_guess
      && (!(params.image_feature_distance_m > 0.0)
          || params.image_feature_min_inliers < 3))
    throw Exception("registerCloud: image_feature_distance_m must be > 0 and "
                    "image_feature_min_inliers >= 3");
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

  // Each guess is refined by GICP and scored; the result with the largest overlap is
  // kept (the first one tried on a tie).
  bool have_result = false;
  Eigen::Matrix4f best = initial_guess.matrix().cast<float>();
  const auto consider = [&](const Eigen::Matrix4f& candidate, bool converged,
                            Guess kind) {
    double overlap = 0.0, residual_m = 0.0;
    score(*source_down, tree, *target_down, *target_normals, candidate,
          params.inlier_distance_m, overlap, residual_m);
    if (have_result && !(overlap > result.overlap))
      return;
    have_result = true;
    best = candidate;
    result.overlap = overlap;
    result.residual_m = residual_m;
    result.converged = converged;
    result.feature_guess_used = kind == Guess::FPFH;
    result.image_feature_guess_used = kind == Guess::IMAGE_FEATURES;
  };
  const auto tryGuess = [&](const Eigen::Matrix4f& guess, Guess kind) {
    bool converged = false;
    const Eigen::Matrix4f candidate =
      refine(source_down, target_down, guess, params, converged);
    consider(candidate, converged, kind);
  };

  if (image_guess) {
    // The stereo odometry's motion estimate without a calibration: matching, RANSAC
    // and the least-squares fit on the inliers, all in 3D.
    StereoOdometry::Params odometry_params;
    odometry_params.distance_threshold_m = params.image_feature_distance_m;
    odometry_params.min_inliers = params.image_feature_min_inliers;
    odometry_params.seed = params.seed;
    const StereoOdometry odometry(odometry_params);
    // previous = target, current = source: previous_T_current is target_T_source.
    const OdometryResult motion = odometry.estimate(*target_features, *source_features);
    if (motion.valid) {
      result.image_feature_inliers = motion.inliers;
      const Eigen::Matrix4f feature_motion =
        motion.previous_T_current.matrix().cast<float>();
      bool converged = false;
      const Eigen::Matrix4f refined =
        refine(source_down, target_down, feature_motion, params, converged);
      // GICP slides freely along what the clouds' geometry leaves open (a plane, a
      // corridor's axis) and can carry the matched features apart there; the
      // features' own motion is then kept.
      std::vector<cv::DMatch> matches;
      odometry.matchDescriptors(*target_features, *source_features, matches);
      const auto agreeing = [&](const Eigen::Matrix4f& transform) {
        const float max_squared = static_cast<float>(params.image_feature_distance_m
                                                     * params.image_feature_distance_m);
        std::size_t count = 0;
        for (const auto& m : matches) {
          const Eigen::Vector3f moved =
            (transform
             * source_features->points[static_cast<std::size_t>(m.trainIdx)]
                 .getVector3fMap()
                 .homogeneous())
              .head<3>();
          count += (moved
                    - target_features->points[static_cast<std::size_t>(m.queryIdx)]
                        .getVector3fMap())
                     .squaredNorm()
                   <= max_squared;
        }
        return count;
      };
      const std::size_t before = agreeing(feature_motion);
      const std::size_t after = agreeing(refined);
      result.image_feature_motion_kept = 5 * after < 4 * before;
      consider(result.image_feature_motion_kept ? feature_motion : refined, converged,
               Guess::IMAGE_FEATURES);
    }
  }
  if (!have_result || result.overlap < params.feature_guess_overlap)
    tryGuess(initial_guess.matrix().cast<float>(), Guess::INITIAL);
  if (params.feature_initial_guess && result.overlap < params.feature_guess_overlap) {
    Eigen::Matrix4f guess;
    if (fpfhGuess(source, target, params, guess))
      tryGuess(guess, Guess::FPFH);
  }
  result.target_T_source.matrix() = best.cast<double>();
  // Re-orthonormalise: the float product of GICP's iterations drifts by ~1e-7.
  const Eigen::Quaterniond q(result.target_T_source.rotation());
  result.target_T_source.linear() = q.normalized().toRotationMatrix();
  return result;
}

} // namespace

CloudRegistrationResult
registerCloud(const pcl::PointCloud<pcl::PointXYZ>& source,
              const pcl::PointCloud<pcl::PointXYZ>& target,
              const Eigen::Isometry3d& initial_guess,
              const CloudRegistrationParams& params)
{
  return registerWithGuesses(source, target, initial_guess, params, nullptr, nullptr);
}

CloudRegistrationResult
registerCloud(const pcl::PointCloud<pcl::PointXYZ>& source,
              const pcl::PointCloud<pcl::PointXYZ>& target,
              const Eigen::Isometry3d& initial_guess,
              const CloudRegistrationParams& params,
              const StereoFeatures& source_features,
              const StereoFeatures& target_features)
{
  return registerWithGuesses(source, target, initial_guess, params, &source_features,
                             &target_features);
}

cv::Mat
cloudIntensityImage(const pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  if (!cloud.isOrganized() || cloud.empty())
    return cv::Mat();
  float lo = std::numeric_limits<float>::infinity();
  float hi = -lo;
  for (const auto& p : cloud.points)
    if (std::isfinite(p.intensity)) {
      lo = std::min(lo, p.intensity);
      hi = std::max(hi, p.intensity);
    }
  if (!(hi > lo))
    return cv::Mat();
  float scale = 1.0f, offset = 0.0f;
  if (lo < 0.0f || hi > 255.0f) {
    scale = 255.0f / (hi - lo);
    offset = -lo * scale;
  }
  cv::Mat grey(static_cast<int>(cloud.height), static_cast<int>(cloud.width), CV_8UC1);
  for (int row = 0; row < grey.rows; ++row) {
    auto* out = grey.ptr<std::uint8_t>(row);
    for (int col = 0; col < grey.cols; ++col) {
      const float v = cloud.at(col, row).intensity;
      out[col] = std::isfinite(v) ? cv::saturate_cast<std::uint8_t>(v * scale + offset)
                                  : std::uint8_t{0};
    }
  }
  return grey;
}

void
computeCloudImageFeatures(const pcl::PointCloud<pcl::PointXYZI>& cloud,
                          const cv::Mat& grey,
                          const StereoFeatureMatcher::Params& params,
                          const Eigen::Affine3f& camera_T_cloud,
                          StereoFeatures& features)
{
  features = StereoFeatures();
  if (grey.empty())
    return;
  std::vector<cv::KeyPoint> keypoints;
  cv::Mat descriptors;
  if (params.feature_type == FeatureType::ORB_GRID) {
    const int bucket = params.bucket_size_px;
    const int cells =
      ((grey.cols + bucket - 1) / bucket) * ((grey.rows + bucket - 1) / bucket);
    const int per_cell = (params.max_features + cells - 1) / cells;
    detectGridFastKeypoints(grey, bucket, per_cell, params.fast_threshold,
                            ORB_GRID_BORDER_PX, keypoints);
    cv::ORB::create(params.max_features, 1.2f, 1, ORB_GRID_BORDER_PX, 0, 2,
                    cv::ORB::HARRIS_SCORE, ORB_PATCH_SIZE_PX, params.fast_threshold)
      ->compute(grey, keypoints, descriptors);
  } else if (params.feature_type == FeatureType::ORB) {
    cv::ORB::create(params.max_features)
      ->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);
  } else {
    cv::SIFT::create(params.max_features)
      ->detectAndCompute(grey, cv::noArray(), keypoints, descriptors);
  }
  const auto max_squared = static_cast<float>(params.max_range_m * params.max_range_m);
  std::vector<int> rows;
  for (std::size_t k = 0; k < keypoints.size(); ++k) {
    const cv::KeyPoint& kp = keypoints[k];
    const int col = static_cast<int>(std::lround(kp.pt.x));
    const int row = static_cast<int>(std::lround(kp.pt.y));
    if (col < 0 || row < 0 || col >= static_cast<int>(cloud.width)
        || row >= static_cast<int>(cloud.height))
      continue;
    const pcl::PointXYZI& p = cloud.at(col, row);
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)))
      continue;
    pcl::PointXYZ q;
    q.getVector3fMap() = camera_T_cloud * p.getVector3fMap();
    if (q.getVector3fMap().squaredNorm() > max_squared)
      continue;
    features.points.push_back(q);
    features.keypoints_left.push_back(kp);
    rows.push_back(static_cast<int>(k));
  }
  features.descriptors.create(static_cast<int>(rows.size()), descriptors.cols,
                              descriptors.type());
  for (std::size_t k = 0; k < rows.size(); ++k)
    descriptors.row(rows[k]).copyTo(features.descriptors.row(static_cast<int>(k)));
}

} // namespace planar_grid
