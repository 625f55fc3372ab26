// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/map/plane_association.h>

#include <pcl/ModelCoefficients.h>
#include <pcl/PointIndices.h>
#include <pcl/memory.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/StdVector>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <unordered_map>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each PlaneRegistryParams member, declared once: the
 * PlaneRegistry checks its parameters against them and the pipeline's accumulate stage
 * takes them as the ranges of its keys. \ingroup map */
namespace plane_registry_ranges {
/** \brief eps_angle_rad: [0, 1.5708] radians (up to a right angle). */
inline constexpr ParamRange EPS_ANGLE = ParamRange::closed(0.0, 1.5708);
/** \brief distance_threshold_m: [0, 10] meters. */
inline constexpr ParamRange DISTANCE_THRESHOLD = ParamRange::closed(0.0, 10.0);
/** \brief leaf_size_m: [0, 10] meters (0 keeps every point). */
inline constexpr ParamRange LEAF_SIZE = ParamRange::closed(0.0, 10.0);
} // namespace plane_registry_ranges

/** \brief PlaneRegistry's parameters; their ranges are plane_registry_ranges'.
 * \ingroup map */
struct PlaneRegistryParams {
  /** \brief Largest angle between the normal of an observed plane and that of a
   * registered plane it joins, either orientation, radians, in [0, 1.5708]. */
  double eps_angle_rad{PlaneAssociationCriteria{}.eps_angle_rad};
  /** \brief Largest difference of the offsets d of an observed plane (oriented like
   * the registered one) and a registered plane it joins, meters, in [0, 10]. */
  double distance_threshold_m{0.2};
  /** \brief Edge of the voxels of downsample(), meters, in [0, 10]; 0 keeps every
   * point. */
  double leaf_size_m{0.1};
};

/** \brief The run-wide planes of a sequence of frames: each frame's planes are
 * associated with the planes registered so far, so that one physical surface seen in
 * many frames is one plane with one id. The paper segments the planes of each frame
 * (Sec. III-C) and does not say how those of successive frames relate; this
 * association by coefficients is ours (docs/METHOD.md).
 *
 * addPlane() takes a plane of a frame (its model_coefficients [a, b, c, d] and its
 * inliers in the frame's cloud, all in the world frame) and returns its run-wide id:
 * the registered plane whose normal is within eps_angle_rad (either orientation) and
 * whose offset d is within distance_threshold_m (PlaneAssociation with
 * PlaneOrientation::EITHER and PlaneDistance::OFFSET; the nearest offset, the lowest
 * id on a tie), whose model_coefficients become the inlier-weighted mean of the two
 * (averageModelCoefficients()); a new plane when none matches. The ids are 0, 1, ... in
 * the order the planes were first seen, and the id of a plane is the index of its
 * model_coefficients and inlier count.
 *
 * The inliers are kept in one cloud, each point labelled with its run-wide id. It
 * grows with every frame until downsample() keeps one point per voxel of leaf_size_m,
 * the one nearest the voxel's centre (labels are not averaged), and cropToWindow()
 * drops the points outside a box around the sensor (the rolling window of a long run).
 *
 * On degenerate input addPlane() registers nothing and returns -1: a plane without four
 * coefficients, with a non-finite or zero normal, or with an inlier index outside the
 * cloud.
 *
 * Usage (the planes of each frame's world-frame cloud as parallel vectors, as
 * SACMultiPlaneSegmentation::segment() gives them):
 * \code
 * planar_grid::PlaneRegistry planes;
 * std::vector<int> plane_ids; // per plane of the frame, its run-wide id
 * planes.addPlanes(*cloud, model_coefficients, inliers, plane_ids);
 * // ... every frame, then
 * planes.downsample();
 * const auto& labelled = planes.getInlierCloud(); // labels: the run-wide ids
 * \endcode
 * \ingroup map */
class PlaneRegistry {
public:
  /** \brief Shared pointer to a PlaneRegistry. */
  using Ptr = std::shared_ptr<PlaneRegistry>;
  /** \brief Shared pointer to a const PlaneRegistry. */
  using ConstPtr = std::shared_ptr<const PlaneRegistry>;
  /** \brief The labelled inlier cloud's type: the label is the run-wide plane id. */
  using PointCloud = pcl::PointCloud<pcl::PointXYZL>;
  /** \brief Shared pointer to a labelled cloud. */
  using PointCloudPtr = PointCloud::Ptr;
  /** \brief Shared pointer to a const labelled cloud. */
  using PointCloudConstPtr = PointCloud::ConstPtr;
  /** \brief The parameters (PlaneRegistryParams). */
  using Params = PlaneRegistryParams;
  /** \brief model_coefficients [a, b, c, d] per plane (aligned allocator, as
   * fixed-size vectorizable Eigen types need in a std::vector). */
  using PlaneModels =
    std::vector<Eigen::Vector4f, Eigen::aligned_allocator<Eigen::Vector4f>>;

  /** \brief An empty registry with the default parameters. */
  PlaneRegistry();
  /** \brief An empty registry with \a params.
   * \throws planar_grid::Exception naming the parameter for a value out of its range */
  explicit PlaneRegistry(const Params& params);

  // The inlier cloud can be large: a registry is moved, not copied.
  PlaneRegistry(const PlaneRegistry&) = delete;
  PlaneRegistry& operator=(const PlaneRegistry&) = delete;
  /** \brief Takes the planes and points of \a other. */
  PlaneRegistry(PlaneRegistry&& other) = default;
  /** \brief Takes the planes and points of \a other. */
  PlaneRegistry& operator=(PlaneRegistry&& other) = default;
  ~PlaneRegistry() = default;

  /** \brief Sets the parameters; the planes registered so far stay. A new leaf_size_m
   * applies from the next downsample() on.
   * \throws planar_grid::Exception naming the parameter for a value out of its range
   * (the registry then keeps its parameters) */
  void setParams(const Params& params);
  /** \brief The parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Registers one plane of a frame and appends its inliers to the inlier
   * cloud, labelled with its run-wide id.
   * \param[in] cloud the frame's points, world frame, meters (N points)
   * \param[in] model_coefficients [a, b, c, d], unit normal, d in meters, world frame
   * \param[in] inliers indices of the plane's points in \a cloud, each in [0, N); their
   * number is the plane's weight in the mean of the coefficients
   * \return the run-wide id (>= 0), or -1 (PCL_WARN, nothing registered) for
   * degenerate input (see the class description) */
  template <typename PointT>
  int addPlane(const pcl::PointCloud<PointT>& cloud,
               const pcl::ModelCoefficients& model_coefficients,
               const pcl::PointIndices& inliers);

  /** \brief Registers the planes of a frame, in order (addPlane() each).
   * \param[in] cloud the frame's points, world frame, meters
   * \param[in] model_coefficients per plane, [a, b, c, d] (unit normal, d in meters)
   * \param[in] inliers per plane, parallel to \a model_coefficients, indices in
   * \a cloud
   * \param[out] plane_ids per plane, its run-wide id, or -1 when it was not registered
   * (degenerate input); empty (PCL_ERROR, nothing registered) when the two vectors have
   * different lengths */
  template <typename PointT>
  void addPlanes(const pcl::PointCloud<PointT>& cloud,
                 const std::vector<pcl::ModelCoefficients>& model_coefficients,
                 const std::vector<pcl::PointIndices>& inliers,
                 std::vector<int>& plane_ids);

  /** \brief The association alone: the run-wide id of a plane with
   * \a model_coefficients and \a inlier_count inliers, registering or updating it as
   * addPlane() does, without adding points to the inlier cloud.
   * \param[in] model_coefficients [a, b, c, d], unit normal, d in meters, world frame
   * \param[in] inlier_count the plane's weight in the mean of the coefficients
   * \return the run-wide id (>= 0), or -1 (PCL_WARN, nothing registered) for
   * non-finite coefficients or a zero normal */
  int associate(const Eigen::Vector4f& model_coefficients, std::size_t inlier_count);

  /** \brief Drops the inlier cloud's points outside the box of half-size
   * \a window_half_size_m around \a sensor_origin in x and y, at every height (world z
   * up); the planes stay registered.
   * \param[in] sensor_origin the sensor's position, world frame, meters
   * \param[in] window_half_size_m half the box's side, meters (>= 0) */
  void cropToWindow(const Eigen::Vector3d& sensor_origin, double window_half_size_m);

  /** \brief Keeps one point of the inlier cloud per voxel of leaf_size_m (voxel
   * floor(p / leaf_size_m) per axis): the one nearest the voxel's centre, the first on
   * a tie, as pcl::UniformSampling with the leaf size as its radius keeps; non-finite
   * points go. The points kept stay in the order their voxels were first seen. Only
   * the points added since the last call are visited: each point kept then holds its
   * voxel as the nearest of all the points seen there. Nothing happens with a
   * leaf_size_m of 0. */
  void downsample();

  /** \brief The number of registered planes. */
  [[nodiscard]] std::size_t size() const { return model_coefficients_.size(); }
  /** \brief Whether no plane is registered. */
  [[nodiscard]] bool empty() const { return model_coefficients_.empty(); }

  /** \brief Each plane's model_coefficients [a, b, c, d] (unit normal, d in meters),
   * world frame, indexed by run-wide id. */
  const PlaneModels& getModelCoefficients() const { return model_coefficients_; }
  /** \brief Each plane's number of inliers merged into it so far (its weight in the
   * mean of the coefficients), indexed by run-wide id. */
  const std::vector<std::size_t>& getInlierCounts() const { return inlier_counts_; }
  /** \brief The inliers of every plane, world frame, meters, each labelled with its
   * run-wide id (after downsample(): one per voxel). */
  const PointCloud& getInlierCloud() const { return inlier_cloud_; }

  /** \brief Replaces the registry's planes and inlier cloud (a saved run's, e.g. a
   * checkpoint's); the parameters stay.
   * \param[in] model_coefficients per plane [a, b, c, d], finite, unit normal
   * \param[in] inlier_counts per plane, parallel to \a model_coefficients
   * \param[in] inlier_cloud the labelled inliers, each label < the number of planes
   * \throws planar_grid::Exception when the two vectors have different lengths, a model
   * is not finite or a label is not a plane's id (the registry is then unchanged) */
  void setPlanes(PlaneModels model_coefficients,
                 std::vector<std::size_t> inlier_counts,
                 PointCloud inlier_cloud);

  /** \brief Removes every plane and point; the parameters stay. */
  void clear();

  PCL_MAKE_ALIGNED_OPERATOR_NEW

private:
  /** \brief The inlier cloud's point \a p, labelled \a id, appended. */
  template <typename PointT> void appendInlier(const PointT& p, std::uint32_t id)
  {
    pcl::PointXYZL q;
    q.getVector3fMap() = p.getVector3fMap();
    q.label = id;
    inlier_cloud_.push_back(q);
  }

  /** \brief A voxel of downsample(): floor(p / leaf_size_m) per axis. */
  struct Leaf {
    std::int32_t x, y, z;
    bool operator==(const Leaf& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  /** \brief Hash of a Leaf (the spatial hash of Teschner et al.). */
  struct LeafHash {
    std::size_t operator()(const Leaf& l) const;
  };

  /** \brief Forgets the voxels of the last downsample(): the next one visits every
   * point (after the points moved or were replaced). */
  void resetLeaves();

  /** \brief The parameters. */
  Params params_;
  /** \brief The association built from params_. */
  PlaneAssociation association_;
  /** \brief Each plane's model_coefficients, by run-wide id. */
  PlaneModels model_coefficients_;
  /** \brief Each plane's inlier count, by run-wide id. */
  std::vector<std::size_t> inlier_counts_;
  /** \brief The labelled inliers. */
  PointCloud inlier_cloud_;
  /** \brief The voxels of the last downsample() and the index of the point each
   * keeps, valid for the first sampled_points_ points of inlier_cloud_. */
  std::unordered_map<Leaf, std::uint32_t, LeafHash> leaves_;
  /** \brief Points of inlier_cloud_ that downsample() has visited. */
  std::size_t sampled_points_{0};
};

/** \brief Drops the points of \a cloud outside the box of half-size
 * \a window_half_size_m around \a sensor_origin in x and y, at every height (world z
 * up), keeping the others' order; the cloud becomes unorganized. The rolling window of
 * the accumulated clouds (PlaneRegistry::cropToWindow(), the pipeline's accumulate
 * stage). \ingroup map
 * \param[in,out] cloud points in the world frame, meters
 * \param[in] sensor_origin the sensor's position, world frame, meters
 * \param[in] window_half_size_m half the box's side, meters (>= 0) */
template <typename PointT>
void cropToWindowXY(pcl::PointCloud<PointT>& cloud,
                    const Eigen::Vector3d& sensor_origin,
                    double window_half_size_m);

} // namespace planar_grid

#include <planar_grid/map/impl/plane_registry.hpp>
