// SPDX-License-Identifier: BSD-3-Clause
// The parameters of SACMultiPlaneSegmentation and their one declaration each.
#pragma once

#include <planar_grid/core/param_declaration.h>

#include <string>

namespace planar_grid {

/** \brief The sample consensus estimator used for every plane hypothesis.
 * \ingroup segmentation */
enum class SACMethod {
  /** \brief pcl::RandomSampleConsensus (the paper's multi-RANSAC, Sec. III-C). */
  RANSAC,
  /** \brief pcl::MEstimatorSampleConsensus (truncated quadratic cost). */
  MSAC,
  /** \brief pcl::ProgressiveSampleConsensus; the sample order is taken as the quality
   * order (a seeded shuffle unless the sample cloud is already sorted). */
  PROSAC
};

/** \brief The name of \a method: "ransac", "msac" or "prosac" (the stage key
 * multi_plane_segmentation.method and the Python keyword). \ingroup segmentation */
const std::string& sacMethodName(SACMethod method);

/** \brief The estimator named \a name ("ransac", "msac" or "prosac").
 * \throws planar_grid::Exception for any other name */
SACMethod sacMethodFromName(const std::string& name);

/** \brief The parameters of SACMultiPlaneSegmentation that the pipeline's
 * multi_plane_segmentation stage sets, named by their keys (with the unit as suffix);
 * their ranges are sac_multi_plane_segmentation_ranges' and their declarations
 * sacMultiPlaneSegmentationParamDeclarations(). The defaults are the pipeline's
 * tuned values (Karlsruhe stereo); each setter of the class documents its member.
 * What describes the sensor of a frame (the depth noise coefficient, the up axis)
 * has setters only: the stage sets it from each frame's calibration and pose.
 * \ingroup segmentation */
struct SACMultiPlaneSegmentationParams {
  /** \brief d_T of eq. 11, meters (the paper's value). */
  double distance_threshold_m{0.05};
  /** \brief Whether the depth noise is projected on each plane's normal. */
  bool depth_noise_along_sight{false};
  /** \brief Sample consensus threshold on the sample cloud, meters. */
  double sample_distance_threshold_m{0.1};
  /** \brief Largest number of planes. */
  int max_planes{8};
  /** \brief Fewest dense inliers of a kept plane. */
  int min_inliers{500};
  /** \brief Fewest sample inliers of a hypothesis. */
  int min_sample_inliers{15};
  /** \brief Remaining sample fraction below which the loop stops. */
  double min_remaining_fraction{0.05};
  /** \brief Sample consensus iteration cap. */
  int max_iterations{1000};
  /** \brief Probability of drawing at least one outlier-free sample, (0, 1). */
  double probability{0.99};
  /** \brief Sample consensus estimator. */
  SACMethod method{SACMethod::RANSAC};
  /** \brief Refit planes to their dense inliers. */
  bool optimize_coefficients{true};
  /** \brief Also hypothesise each plane from a dense subsample. */
  bool dense_hypothesis{true};
  /** \brief Local optimisation (LO-RANSAC) iterations per plane (0: none). */
  int lo_iterations{50};
  /** \brief Merge near-duplicate planes. */
  bool merge_planes{true};
  /** \brief Merge angle threshold, radians. */
  double merge_angle_rad{0.1};
  /** \brief Merge offset threshold, meters. */
  double merge_distance_m{0.1};
  /** \brief Seed of the subsample and shuffles. */
  unsigned seed{0};
  /** \brief Size of the input subsample the hypotheses come from when no sample
   * cloud is set, points. */
  int max_sample_size{20000};
  /** \brief Largest ratio of visibility conflicts to inliers (0: no test). */
  double max_visibility_conflict_ratio{0.0};
  /** \brief Distance off a plane, beyond eq. 11, of a conflicting point, meters. */
  double visibility_margin_m{0.3};
  /** \brief Footprint cell edge of the visibility and shell tests, meters. */
  double visibility_cell_m{0.2};
  /** \brief Smallest distance of a plane from the sensor origin, meters (0: no
   * test). */
  double min_sensor_distance_m{0.0};
  /** \brief Least height of the sensor above a level plane that the normal and
   * cluster tests spare as terrain, meters (0: any level plane below it). */
  double min_sensor_height_m{0.3};
  /** \brief Largest ratio of the points more than 0.3 m below a level plane, under
   * its inliers, to its inliers, for the normal and cluster tests to spare it as
   * terrain (1: no test). */
  double max_terrain_below_ratio{0.05};
  /** \brief Fewest inliers of a footprint cluster (0: no test). */
  int min_cluster_size{0};
  /** \brief Footprint cell edge of the cluster test, meters. */
  double cluster_cell_m{0.2};
  /** \brief Largest ratio of shell points to inliers (0: no test). */
  double max_shell_ratio{0.0};
  /** \brief Smallest shell width of the shell test, meters. */
  double shell_width_m{0.1};
  /** \brief Whether the inlier-only points count towards min_inliers. */
  bool count_inlier_only_points{true};
  /** \brief Largest distance of an inlier-only point, meters (0: eq. 11's). */
  double inlier_only_distance_threshold_m{0.0};
  /** \brief Largest angle of the normal test, radians (0: no test). */
  double max_normal_angle_rad{0.5};
  /** \brief Cell edge of the grid normal estimation, meters. */
  double normal_cell_m{0.2};
  /** \brief Smallest share of a hypothesis' support agreeing in normal (0: no
   * test). */
  double min_normal_agreement{0.35};
};

/** \brief The one declaration of each SACMultiPlaneSegmentationParams member (key
 * with unit, range, meaning), in the order documented. \ingroup segmentation */
const ParamDeclarations<SACMultiPlaneSegmentationParams>&
sacMultiPlaneSegmentationParamDeclarations();

} // namespace planar_grid
