// SPDX-License-Identifier: BSD-3-Clause
// The template bodies of SACMultiPlaneSegmentation: the parameter checks and the
// multi-plane segmentation; the helpers are in sac_multi_plane_segmentation_detail.hpp,
// the tests a plane must pass and the merge in sac_multi_plane_segmentation_tests.hpp.
#pragma once

#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation_detail.hpp>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/common/centroid.h>
#include <pcl/common/eigen.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>
#include <pcl/point_types.h>
#include <pcl/sample_consensus/msac.h>
#include <pcl/sample_consensus/prosac.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_plane.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <numeric>
#include <random>
#include <string>

namespace planar_grid {

template <typename PointT>
const char*
SACMultiPlaneSegmentation<PointT>::checkParameters() const
{
  namespace ranges = sac_multi_plane_segmentation_ranges;
  // One message per range, written from the range once (static: the returned pointer
  // stays valid).
  static const std::array<std::string, 28> messages{
    paramRangeMessage("distance_threshold", ranges::DISTANCE_THRESHOLD, "m"),
    paramRangeMessage("sample_distance_threshold", ranges::SAMPLE_DISTANCE_THRESHOLD,
                      "m"),
    paramRangeMessage("depth_noise_coefficient", ranges::DEPTH_NOISE_COEFFICIENT,
                      "1/m"),
    paramRangeMessage("max_planes", ranges::MAX_PLANES),
    paramRangeMessage("min_inliers", ranges::MIN_INLIERS),
    paramRangeMessage("min_sample_inliers", ranges::MIN_SAMPLE_INLIERS),
    paramRangeMessage("min_remaining_fraction", ranges::MIN_REMAINING_FRACTION),
    paramRangeMessage("max_iterations", ranges::MAX_ITERATIONS),
    paramRangeMessage("probability", ranges::PROBABILITY),
    paramRangeMessage("merge_angle_threshold", ranges::MERGE_ANGLE_THRESHOLD, "rad"),
    paramRangeMessage("merge_distance_threshold", ranges::MERGE_DISTANCE_THRESHOLD,
                      "m"),
    "up_axis must be finite and non-zero",
    paramRangeMessage("max_sample_size", ranges::MAX_SAMPLE_SIZE),
    paramRangeMessage("lo_iterations", ranges::LO_ITERATIONS),
    paramRangeMessage("max_visibility_conflict_ratio",
                      ranges::MAX_VISIBILITY_CONFLICT_RATIO),
    paramRangeMessage("visibility_margin", ranges::VISIBILITY_MARGIN, "m"),
    paramRangeMessage("visibility_cell", ranges::VISIBILITY_CELL, "m"),
    paramRangeMessage("min_sensor_distance", ranges::MIN_SENSOR_DISTANCE, "m"),
    paramRangeMessage("min_terrain_sensor_height", ranges::MIN_TERRAIN_SENSOR_HEIGHT,
                      "m"),
    paramRangeMessage("max_terrain_below_ratio", ranges::MAX_TERRAIN_BELOW_RATIO),
    paramRangeMessage("min_cluster_size", ranges::MIN_CLUSTER_SIZE),
    paramRangeMessage("cluster_cell", ranges::CLUSTER_CELL, "m"),
    paramRangeMessage("max_shell_ratio", ranges::MAX_SHELL_RATIO),
    paramRangeMessage("shell_width", ranges::SHELL_WIDTH, "m"),
    paramRangeMessage("inlier_only_distance_threshold",
                      ranges::INLIER_ONLY_DISTANCE_THRESHOLD, "m"),
    paramRangeMessage("max_normal_angle", ranges::MAX_NORMAL_ANGLE, "rad"),
    paramRangeMessage("normal_cell", ranges::NORMAL_CELL, "m"),
    paramRangeMessage("min_normal_agreement", ranges::MIN_NORMAL_AGREEMENT)};
  const std::array<bool, 28> valid{
    ranges::DISTANCE_THRESHOLD.contains(params_.distance_threshold_m),
    ranges::SAMPLE_DISTANCE_THRESHOLD.contains(params_.sample_distance_threshold_m),
    ranges::DEPTH_NOISE_COEFFICIENT.contains(depth_noise_coefficient_),
    ranges::MAX_PLANES.contains(params_.max_planes),
    ranges::MIN_INLIERS.contains(params_.min_inliers),
    ranges::MIN_SAMPLE_INLIERS.contains(params_.min_sample_inliers),
    ranges::MIN_REMAINING_FRACTION.contains(params_.min_remaining_fraction),
    ranges::MAX_ITERATIONS.contains(params_.max_iterations),
    ranges::PROBABILITY.contains(params_.probability),
    ranges::MERGE_ANGLE_THRESHOLD.contains(params_.merge_angle_rad),
    ranges::MERGE_DISTANCE_THRESHOLD.contains(params_.merge_distance_m),
    up_axis_.allFinite() && up_axis_.norm() > 0.0f,
    ranges::MAX_SAMPLE_SIZE.contains(params_.max_sample_size),
    ranges::LO_ITERATIONS.contains(params_.lo_iterations),
    ranges::MAX_VISIBILITY_CONFLICT_RATIO.contains(
      params_.max_visibility_conflict_ratio),
    ranges::VISIBILITY_MARGIN.contains(params_.visibility_margin_m),
    ranges::VISIBILITY_CELL.contains(params_.visibility_cell_m),
    ranges::MIN_SENSOR_DISTANCE.contains(params_.min_sensor_distance_m),
    ranges::MIN_TERRAIN_SENSOR_HEIGHT.contains(params_.min_sensor_height_m),
    ranges::MAX_TERRAIN_BELOW_RATIO.contains(params_.max_terrain_below_ratio),
    ranges::MIN_CLUSTER_SIZE.contains(params_.min_cluster_size),
    ranges::CLUSTER_CELL.contains(params_.cluster_cell_m),
    ranges::MAX_SHELL_RATIO.contains(params_.max_shell_ratio),
    ranges::SHELL_WIDTH.contains(params_.shell_width_m),
    ranges::INLIER_ONLY_DISTANCE_THRESHOLD.contains(
      params_.inlier_only_distance_threshold_m),
    ranges::MAX_NORMAL_ANGLE.contains(params_.max_normal_angle_rad),
    ranges::NORMAL_CELL.contains(params_.normal_cell_m),
    ranges::MIN_NORMAL_AGREEMENT.contains(params_.min_normal_agreement)};
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (!valid[i])
      return messages[i].c_str();
  return nullptr;
}

template <typename PointT>
bool
SACMultiPlaneSegmentation<PointT>::initCompute()
{
  if (!pcl::PCLBase<PointT>::initCompute()) {
    PCL_ERROR("[planar_grid::%s::segment] No input cloud given.\n",
              getClassName().c_str());
    return false;
  }
  const char* bad = checkParameters();
  if (bad != nullptr) {
    PCL_ERROR("[planar_grid::%s::segment] Invalid parameter: %s.\n",
              getClassName().c_str(), bad);
    pcl::PCLBase<PointT>::deinitCompute();
    return false;
  }
  if (normals_ && normals_->size() != input_->size()) {
    PCL_ERROR("[planar_grid::%s::segment] The input normals hold %zu normals for %zu "
              "input points.\n",
              getClassName().c_str(), normals_->size(), input_->size());
    pcl::PCLBase<PointT>::deinitCompute();
    return false;
  }
  return true;
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::segment(PlanarSegments& planes)
{
  planes.clear();
  if (!initCompute())
    return;
  applySegmentation(planes);
  this->deinitCompute();
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::segment(
  std::vector<pcl::ModelCoefficients>& model_coefficients,
  std::vector<pcl::PointIndices>& inliers)
{
  model_coefficients.clear();
  inliers.clear();
  PlanarSegments planes;
  segment(planes);
  model_coefficients.reserve(planes.size());
  inliers.reserve(planes.size());
  for (auto& plane : planes) {
    model_coefficients.push_back(std::move(plane.model_coefficients));
    inliers.push_back(std::move(plane.inliers));
  }
}

namespace detail {

/** \brief Slab half-width of the local dense refinement, in units of d_T. */
constexpr float LOCAL_SLAB_FACTOR = 10.0f;
/** \brief Subsample size of the local dense refinement and of the dense hypothesis,
 * in points. */
constexpr std::size_t LOCAL_SAMPLE_SIZE = 5000;
/** \brief Largest tilt of a terrain plane that the cluster test spares, in radians. */
constexpr float TERRAIN_TILT = 0.3f;
/** \brief Fewest points of a grid normal's 3 x 3 x 3 cell block. */
constexpr std::size_t MIN_NORMAL_POINTS = 6;

} // namespace detail

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::collectDensePoints(const Eigen::Vector3f& origin,
                                                      float d_t,
                                                      detail::DensePoints& dense) const
{
  // The unassigned finite input points (within the indices), struct of arrays.
  // The inlier-only points come after the others (dense.primary).
  std::vector<std::uint8_t> inlier_only;
  if (inlier_only_indices_ && !inlier_only_indices_->empty()) {
    inlier_only.assign(input_->size(), 0);
    for (const auto i : *inlier_only_indices_)
      if (i >= 0 && static_cast<std::size_t>(i) < input_->size())
        inlier_only[static_cast<std::size_t>(i)] = 1;
  }
  dense.x.reserve(indices_->size());
  dense.y.reserve(indices_->size());
  dense.z.reserve(indices_->size());
  dense.index.reserve(indices_->size());
  const auto addPoint = [&](pcl::index_t i) {
    const PointT& p = (*input_)[i];
    if (!pcl::isXYZFinite(p))
      return;
    dense.x.push_back(p.x);
    dense.y.push_back(p.y);
    dense.z.push_back(p.z);
    dense.index.push_back(i);
  };
  for (const auto i : *indices_)
    if (inlier_only.empty() || !inlier_only[static_cast<std::size_t>(i)])
      addPoint(i);
  dense.primary = dense.size();
  if (!inlier_only.empty())
    for (std::size_t i = 0; i < inlier_only.size(); ++i)
      if (inlier_only[i]) {
        inlier_only[i] = 0; // each index once
        addPoint(static_cast<pcl::index_t>(i));
      }
  if (params_.max_normal_angle_rad > 0.0) {
    // The normal test's normals: the given ones, else fitted on a grid of the points.
    const std::size_t n = dense.size();
    if (normals_) {
      dense.nx.resize(n);
      dense.ny.resize(n);
      dense.nz.resize(n);
      for (std::size_t k = 0; k < n; ++k) {
        const pcl::Normal& normal =
          (*normals_)[static_cast<std::size_t>(dense.index[k])];
        dense.setNormal(
          k, Eigen::Vector3f(normal.normal_x, normal.normal_y, normal.normal_z));
      }
    } else if (normal_function_) {
      // Asked for when the normal test first examines a point.
      for (auto* v : {&dense.nx, &dense.ny, &dense.nz})
        v->assign(n, std::numeric_limits<float>::quiet_NaN());
      dense.normal_known.assign(n, 0);
      dense.normal_of = normal_function_;
    } else {
      detail::estimateGridNormals(
        dense.x, dense.y, dense.z, static_cast<float>(params_.normal_cell_m),
        detail::MIN_NORMAL_POINTS, dense.nx, dense.ny, dense.nz);
    }
    dense.min_normal_cos = static_cast<float>(std::cos(params_.max_normal_angle_rad));
    dense.use_normals = true;
  }
  // Terrain planes are spared by the normal and cluster tests: a road's disparity is
  // the sparsest and noisiest of a street's surfaces, and ground_removal takes the
  // terrain out whole. A level plane with the frame's floor under it is no terrain.
  dense.terrain_up = up_axis_.normalized();
  dense.terrain_origin = origin;
  dense.terrain_cos = std::cos(detail::TERRAIN_TILT);
  dense.terrain_min_height = static_cast<float>(params_.min_sensor_height_m);
  dense.terrain_max_below_ratio = static_cast<float>(params_.max_terrain_below_ratio);
  if (params_.max_terrain_below_ratio < 1.0)
    dense.setTerrainFrame();
  if (depth_noise_coefficient_ > 0.0) {
    // Eq. 11 at the stereo depth error of each point's range (eq. 4's Delta z).
    const auto coefficient = static_cast<float>(depth_noise_coefficient_);
    dense.threshold.resize(dense.size());
    for (std::size_t k = 0; k < dense.size(); ++k) {
      const float r2 =
        (Eigen::Vector3f(dense.x[k], dense.y[k], dense.z[k]) - origin).squaredNorm();
      dense.threshold[k] = std::max(d_t, coefficient * r2);
    }
  }
  if (params_.inlier_only_distance_threshold_m > 0.0 && dense.primary < dense.size()) {
    // A planar cell spans its inliers' depth along the normal: the inlier-only points
    // join within a bound of their own, so that their noise does not thicken it.
    if (dense.threshold.empty())
      dense.threshold.assign(dense.size(), d_t);
    const auto cap = static_cast<float>(params_.inlier_only_distance_threshold_m);
    for (std::size_t k = dense.primary; k < dense.size(); ++k)
      dense.threshold[k] = std::min(dense.threshold[k], cap);
  }
  if (params_.depth_noise_along_sight && depth_noise_coefficient_ > 0.0) {
    // The thresholds above are each point's largest; selectInliers() projects the
    // depth error on each plane's normal within them.
    const auto coefficient = static_cast<float>(depth_noise_coefficient_);
    const std::size_t n = dense.size();
    dense.depth_error.resize(n);
    dense.ray_x.resize(n);
    dense.ray_y.resize(n);
    dense.ray_z.resize(n);
    dense.floor.assign(n, d_t);
    dense.cap = dense.threshold;
    for (std::size_t k = 0; k < n; ++k) {
      const Eigen::Vector3f ray =
        Eigen::Vector3f(dense.x[k], dense.y[k], dense.z[k]) - origin;
      const float r = ray.norm();
      const Eigen::Vector3f u =
        r > 0.0f ? Eigen::Vector3f(ray / r) : Eigen::Vector3f::Zero();
      dense.depth_error[k] = coefficient * r * r;
      dense.ray_x[k] = u.x();
      dense.ray_y[k] = u.y();
      dense.ray_z[k] = u.z();
    }
  }
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::drawSample(const detail::DensePoints& dense,
                                              std::mt19937& rng,
                                              pcl::Indices& sample) const
{
  if (sample_cloud_) {
    for (std::size_t i = 0; i < sample_cloud_->size(); ++i)
      if (pcl::isXYZFinite((*sample_cloud_)[i]))
        sample.push_back(static_cast<pcl::index_t>(i));
    return;
  }
  sample.assign(dense.index.begin(),
                dense.index.begin() + static_cast<std::ptrdiff_t>(dense.primary));
  const auto wanted = std::min(sample.size(), std::size_t(params_.max_sample_size));
  for (std::size_t k = 0; k < wanted; ++k) { // partial Fisher-Yates
    std::uniform_int_distribution<std::size_t> pick(k, sample.size() - 1);
    std::swap(sample[k], sample[pick(rng)]);
  }
  sample.resize(wanted);
  std::sort(sample.begin(), sample.end());
}

template <typename PointT>
bool
SACMultiPlaneSegmentation<PointT>::estimateSamplePlane(
  const PointCloudConstPtr& sample_cloud,
  pcl::Indices& remaining,
  float sample_t,
  const Eigen::Vector3f& origin,
  std::mt19937& rng,
  pcl::Indices& sac_inliers,
  Eigen::Vector4f& plane) const
{
  // The seed reaches PCL's fixed-seed (12345) estimators through the sample order.
  std::shuffle(remaining.begin(), remaining.end(), rng);
  auto model =
    std::make_shared<detail::QuietPlaneModel<PointT>>(sample_cloud, remaining);
  model->setEarlyExit(params_.method == SACMethod::RANSAC);
  std::shared_ptr<pcl::SampleConsensus<PointT>> sac;
  switch (params_.method) {
    case SACMethod::MSAC:
      sac = std::make_shared<pcl::MEstimatorSampleConsensus<PointT>>(model);
      break;
    case SACMethod::PROSAC:
      sac = std::make_shared<pcl::ProgressiveSampleConsensus<PointT>>(model);
      break;
    case SACMethod::RANSAC:
    default:
      sac = std::make_shared<pcl::RandomSampleConsensus<PointT>>(model);
      break;
  }
  sac->setDistanceThreshold(sample_t);
  sac->setMaxIterations(params_.max_iterations);
  sac->setProbability(params_.probability);
  if (!sac->computeModel())
    return false;
  Eigen::VectorXf coefficients;
  sac->getModelCoefficients(coefficients);
  sac->getInliers(sac_inliers);
  if (coefficients.size() != 4 || !coefficients.allFinite()
      || static_cast<int>(sac_inliers.size()) < params_.min_sample_inliers)
    return false;
  plane = coefficients.head<4>();
  plane /= plane.head<3>().norm();
  detail::orientTowards(plane, origin);
  return true;
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::refineOnDenseSlab(detail::DensePoints& dense,
                                                     float sample_t,
                                                     float d_t,
                                                     const Eigen::Vector3f& origin,
                                                     std::mt19937& rng,
                                                     RoundBuffers& buffers,
                                                     Eigen::Vector4f& plane) const
{
  // The sample (stereo features) is noisy, so its plane can be tilted against the
  // dense surface. RANSAC at d_T on a seeded subsample of the unassigned dense points
  // within a wide slab around the hypothesis re-estimates it where the dense points
  // are.
  const float slab = std::max(sample_t, detail::LOCAL_SLAB_FACTOR * d_t);
  if (dense.select(plane, slab) < 3)
    return;
  // Store positions of the slab points, a seeded subsample of them, as SoA.
  auto& slab_points = buffers.slab_points;
  slab_points.clear();
  for (std::size_t k = 0; k < dense.primary; ++k)
    if (dense.mask[k])
      slab_points.push_back(k);
  // The inlier-only points refine no plane.
  const std::size_t wanted =
    slab_points.size() < 3 ? 0
                           : std::min(slab_points.size(), detail::LOCAL_SAMPLE_SIZE);
  for (std::size_t k = 0; k < wanted; ++k) {
    std::uniform_int_distribution<std::size_t> pick(k, slab_points.size() - 1);
    std::swap(slab_points[k], slab_points[pick(rng)]);
  }
  buffers.local_x.resize(wanted);
  buffers.local_y.resize(wanted);
  buffers.local_z.resize(wanted);
  for (std::size_t k = 0; k < wanted; ++k) {
    buffers.local_x[k] = dense.x[slab_points[k]];
    buffers.local_y[k] = dense.y[slab_points[k]];
    buffers.local_z[k] = dense.z[slab_points[k]];
  }
  Eigen::Vector4f local_plane;
  if (detail::ransacPlane(buffers.local_x, buffers.local_y, buffers.local_z, d_t,
                          params_.max_iterations, params_.probability, rng, local_plane)
      > 0) {
    plane = local_plane;
    detail::orientTowards(plane, origin);
  }
}

template <typename PointT>
bool
SACMultiPlaneSegmentation<PointT>::tryDenseHypothesis(detail::DensePoints& dense,
                                                      float d_t,
                                                      const Eigen::Vector3f& origin,
                                                      std::mt19937& rng,
                                                      RoundBuffers& buffers,
                                                      Eigen::Vector4f& plane) const
{
  // A plain RANSAC at d_T on a seeded subsample (drawn with replacement) of all
  // unassigned dense points; the plane with more eq. 11 inliers over the store is
  // kept. It finds the large planes the sample has few points on (a road with little
  // texture).
  if (!params_.dense_hypothesis || dense.primary < 3)
    return false;
  const std::size_t n = dense.primary;
  const std::size_t wanted = std::min(n, detail::LOCAL_SAMPLE_SIZE);
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  buffers.local_x.resize(wanted);
  buffers.local_y.resize(wanted);
  buffers.local_z.resize(wanted);
  for (std::size_t k = 0; k < wanted; ++k) {
    const std::size_t j = pick(rng);
    buffers.local_x[k] = dense.x[j];
    buffers.local_y[k] = dense.y[j];
    buffers.local_z[k] = dense.z[j];
  }
  Eigen::Vector4f dense_plane;
  if (detail::ransacPlane(buffers.local_x, buffers.local_y, buffers.local_z, d_t,
                          params_.max_iterations, params_.probability, rng, dense_plane)
        > 0
      && dense.selectInliers(dense_plane, d_t) > dense.selectInliers(plane, d_t)) {
    plane = dense_plane;
    detail::orientTowards(plane, origin);
    return true;
  }
  return false;
}

template <typename PointT>
std::size_t
SACMultiPlaneSegmentation<PointT>::selectDenseInliers(detail::DensePoints& dense,
                                                      float d_t,
                                                      const Eigen::Vector3f& origin,
                                                      std::mt19937& rng,
                                                      Eigen::Vector4f& plane,
                                                      pcl::Indices& inliers) const
{
  // Local optimisation (LO-RANSAC) of the kept hypothesis on all unassigned points.
  if (params_.lo_iterations > 0) {
    detail::optimizePlane(dense.x, dense.y, dense.z, dense.primary, d_t,
                          params_.lo_iterations, rng, plane);
    detail::orientTowards(plane, origin);
  }
  // Eq. 11 over the unassigned dense points; refit (PCA) and reselect.
  std::size_t count = dense.selectInliers(plane, d_t);
  if (params_.optimize_coefficients && count >= 3) {
    dense.selected(inliers);
    Eigen::Vector4f refit, centroid;
    if (detail::fitPlanePCA(*input_, inliers, refit, centroid)) {
      detail::orientTowards(refit, origin);
      plane = refit;
      count = dense.selectInliers(plane, d_t);
    }
  }
  return count;
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::removeSampleOnPlane(
  const PointCloud& sample_cloud,
  const Eigen::Vector4f& plane,
  float sample_t,
  const std::vector<std::uint8_t>& sample_taken,
  pcl::Indices& remaining) const
{
  remaining.erase(std::remove_if(remaining.begin(), remaining.end(),
                                 [&](pcl::index_t i) {
                                   if (sample_taken[i])
                                     return true;
                                   const PointT& p = sample_cloud[i];
                                   return std::abs(plane[0] * p.x + plane[1] * p.y
                                                   + plane[2] * p.z + plane[3])
                                          <= sample_t;
                                 }),
                  remaining.end());
}

template <typename PointT>
std::size_t
SACMultiPlaneSegmentation<PointT>::supportCount(const detail::DensePoints& dense,
                                                std::size_t count) const
{
  // The mask holds the plane's inliers wherever this is called.
  if (params_.count_inlier_only_points || dense.primary == dense.size())
    return count;
  return static_cast<std::size_t>(std::count(
    dense.mask.begin(), dense.mask.begin() + static_cast<std::ptrdiff_t>(dense.primary),
    std::uint8_t(1)));
}

template <typename PointT>
void
SACMultiPlaneSegmentation<PointT>::applySegmentation(PlanarSegments& planes)
{
  planes.clear();
  counts_ = PlaneTestCounts{};
  const Eigen::Vector3f origin = input_->sensor_origin_.template head<3>();
  const Eigen::Vector3f up = up_axis_.normalized();
  const auto d_t = static_cast<float>(params_.distance_threshold_m);
  const auto sample_t = static_cast<float>(getSampleDistanceThreshold());
  std::mt19937 rng(params_.seed);

  detail::DensePoints dense;
  collectDensePoints(origin, d_t, dense);
  // Every finite input point, for the visibility test (dense loses the planes'
  // inliers as they are taken).
  detail::DensePoints all;
  if (params_.max_visibility_conflict_ratio > 0.0 || params_.max_shell_ratio > 0.0)
    all = dense;
  if (dense.size() < 3) {
    PCL_WARN("[planar_grid::%s::segment] Fewer than 3 finite input points (%zu).\n",
             getClassName().c_str(), dense.size());
    return;
  }

  // The sample the hypotheses come from: the sample cloud, or a seeded subsample.
  PointCloudConstPtr sample_cloud = sample_cloud_ ? sample_cloud_ : input_;
  pcl::Indices remaining;
  drawSample(dense, rng, remaining);
  const std::size_t initial_sample = remaining.size();
  if (initial_sample < 3) {
    PCL_WARN("[planar_grid::%s::segment] Fewer than 3 finite sample points (%zu).\n",
             getClassName().c_str(), initial_sample);
    return;
  }

  // Colinear (or coincident) samples span no plane: PCA's middle eigenvalue is ~0.
  if (!detail::spansPlane(*sample_cloud, remaining)) {
    PCL_WARN("[planar_grid::%s::segment] The sample points are colinear.\n",
             getClassName().c_str());
    return;
  }

  std::vector<std::uint8_t> sample_taken(sample_cloud->size(), 0);
  pcl::Indices sac_inliers;
  RoundBuffers buffers;
  const int max_rounds = 3 * params_.max_planes;
  for (int round = 0;
       round < max_rounds && static_cast<int>(planes.size()) < params_.max_planes;
       ++round) {
    if (remaining.size() < 3
        || static_cast<double>(remaining.size())
             < params_.min_remaining_fraction * initial_sample)
      break;
    // What is left of the sample may be colinear (e.g. features along one edge): every
    // minimal sample would be degenerate, so stop instead of drawing in vain.
    if (!detail::spansPlane(*sample_cloud, remaining)) {
      PCL_DEBUG("[planar_grid::%s::segment] The remaining %zu sample points are "
                "colinear; stopping.\n",
                getClassName().c_str(), remaining.size());
      break;
    }
    Eigen::Vector4f plane;
    if (!estimateSamplePlane(sample_cloud, remaining, sample_t, origin, rng,
                             sac_inliers, plane))
      break;

    PlanarSegment segment;
    if (params_.optimize_coefficients)
      refineOnDenseSlab(dense, sample_t, d_t, origin, rng, buffers, plane);
    const bool dense_won = tryDenseHypothesis(dense, d_t, origin, rng, buffers, plane);
    std::size_t count =
      selectDenseInliers(dense, d_t, origin, rng, plane, segment.inliers.indices);

    // Remove the sample inliers: the estimator's (unless the dense hypothesis won: they
    // lie on another plane, which a later round can still find), and those of the
    // final plane.
    if (!dense_won)
      for (const auto i : sac_inliers)
        sample_taken[i] = 1;
    const std::size_t sample_before = remaining.size();
    removeSampleOnPlane(*sample_cloud, plane, sample_t, sample_taken, remaining);

    if (dense.testsNormals(plane) && !passesNormalAgreement(dense, plane, d_t)) {
      ++counts_.normal_rejected;
      continue;
    }
    // The visibility and shell tests read every point's threshold for this plane.
    all.setPlaneThresholds(plane);
    if (!passesPlaneTests(dense, all, plane, origin, d_t, count))
      continue;
    dense.selected(segment.inliers.indices);
    dense.removeSelected();
    segment.model_coefficients.values.assign(plane.data(), plane.data() + 4);
    segment.sample_inliers =
      dense_won ? sample_before - remaining.size() : sac_inliers.size();
    planes.push_back(std::move(segment));
  }

  // Merge near-duplicate planes (normals within eps_angle, offsets within distance).
  if (params_.merge_planes)
    mergeDuplicatePlanes(planes, origin);
  // Per-plane extras: sorted inliers, centroid, eqs. 2-3 tilt, headers.
  describePlanes(planes, up);
  if (planes.empty())
    PCL_WARN("[planar_grid::%s::segment] No plane with >= %d inliers.\n",
             getClassName().c_str(), params_.min_inliers);
}

} // namespace planar_grid

#define PLANAR_GRID_INSTANTIATE_SACMultiPlaneSegmentation(T) \
  template class planar_grid::SACMultiPlaneSegmentation<T>;

// The tests of a hypothesis and the merge (they use the constants above).
#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation_tests.hpp>
