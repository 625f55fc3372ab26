// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>

namespace planar_grid {

/** \brief The valid range of each SACMultiPlaneSegmentation parameter, declared once:
 * checkParameters() tests the values against them and the pipeline's
 * multi_plane_segmentation stage table takes them as its ranges. \ingroup segmentation
 */
namespace sac_multi_plane_segmentation_ranges {
/** \brief Dense inlier distance threshold d_T of eq. 11: (0, 1] meters. */
inline constexpr ParamRange DISTANCE_THRESHOLD = ParamRange::openMin(0.0, 1.0);
/** \brief Sample inlier distance threshold: (0, 1] meters. */
inline constexpr ParamRange SAMPLE_DISTANCE_THRESHOLD = ParamRange::openMin(0.0, 1.0);
/** \brief Depth noise coefficient Delta d / (B f): [0, inf) 1/m. */
inline constexpr ParamRange DEPTH_NOISE_COEFFICIENT =
  ParamRange::openMax(0.0, ParamRange::UNBOUNDED);
/** \brief Most planes per cloud: [1, 100]. */
inline constexpr ParamRange MAX_PLANES = ParamRange::closed(1, 100);
/** \brief Fewest dense inliers of a plane: [3, 100000000]. */
inline constexpr ParamRange MIN_INLIERS = ParamRange::closed(3, 100000000);
/** \brief Fewest sample inliers of a hypothesis: [3, 1000000]. */
inline constexpr ParamRange MIN_SAMPLE_INLIERS = ParamRange::closed(3, 1000000);
/** \brief Remaining sample fraction below which the search stops: [0, 1). */
inline constexpr ParamRange MIN_REMAINING_FRACTION = ParamRange::openMax(0.0, 1.0);
/** \brief Sample consensus iterations per plane: [1, 1000000]. */
inline constexpr ParamRange MAX_ITERATIONS = ParamRange::closed(1, 1000000);
/** \brief Sample consensus probability: (0, 1). */
inline constexpr ParamRange PROBABILITY = ParamRange::open(0.0, 1.0);
/** \brief Local optimisation samples per plane: [0, 100000]. */
inline constexpr ParamRange LO_ITERATIONS = ParamRange::closed(0, 100000);
/** \brief Largest normal angle of planes that merge: [0, 1.5708] radians (pi/2 as
 * configurations write it). */
inline constexpr ParamRange MERGE_ANGLE_THRESHOLD = ParamRange::closed(0.0, 1.5708);
/** \brief Largest offset difference of planes that merge: [0, 10] meters. */
inline constexpr ParamRange MERGE_DISTANCE_THRESHOLD = ParamRange::closed(0.0, 10.0);
/** \brief Most sample points: [3, inf). */
inline constexpr ParamRange MAX_SAMPLE_SIZE =
  ParamRange::openMax(3, ParamRange::UNBOUNDED);
/** \brief Visibility test, conflicting points per inlier: [0, 1000]. */
inline constexpr ParamRange MAX_VISIBILITY_CONFLICT_RATIO =
  ParamRange::closed(0.0, 1000.0);
/** \brief Visibility test margin: [0, 100] meters. */
inline constexpr ParamRange VISIBILITY_MARGIN = ParamRange::closed(0.0, 100.0);
/** \brief Footprint cell edge of the visibility and shell tests: (0, 100] meters. */
inline constexpr ParamRange VISIBILITY_CELL = ParamRange::openMin(0.0, 100.0);
/** \brief Sensor plane test distance: [0, 100] meters. */
inline constexpr ParamRange MIN_SENSOR_DISTANCE = ParamRange::closed(0.0, 100.0);
/** \brief setMinTerrainSensorHeight(), meters. */
inline constexpr ParamRange MIN_TERRAIN_SENSOR_HEIGHT = ParamRange::closed(0.0, 100.0);
/** \brief setMaxTerrainBelowRatio(), points per inlier: [0, 1]. */
inline constexpr ParamRange MAX_TERRAIN_BELOW_RATIO = ParamRange::closed(0.0, 1.0);
/** \brief Cluster test, fewest inliers of a cluster: [0, 100000000]. */
inline constexpr ParamRange MIN_CLUSTER_SIZE = ParamRange::closed(0, 100000000);
/** \brief Footprint cell edge of the cluster test: (0, 100] meters. */
inline constexpr ParamRange CLUSTER_CELL = ParamRange::openMin(0.0, 100.0);
/** \brief Shell test, shell points per inlier: [0, 1000]. */
inline constexpr ParamRange MAX_SHELL_RATIO = ParamRange::closed(0.0, 1000.0);
/** \brief Smallest shell width of the shell test: [0, 100] meters. */
inline constexpr ParamRange SHELL_WIDTH = ParamRange::closed(0.0, 100.0);
/** \brief Distance threshold of the inlier-only points: [0, 10] meters. */
inline constexpr ParamRange INLIER_ONLY_DISTANCE_THRESHOLD =
  ParamRange::closed(0.0, 10.0);
/** \brief Normal test, largest angle between an inlier's normal and its plane's:
 * [0, pi/2] radians (0: no test). */
inline constexpr ParamRange MAX_NORMAL_ANGLE = ParamRange::closed(0.0, 1.5708);
/** \brief Cell edge of the normal estimation: (0, 100] meters. */
inline constexpr ParamRange NORMAL_CELL = ParamRange::openMin(0.0, 100.0);
/** \brief Normal test, share of a hypothesis' eq. 11 support that must agree in normal:
 * [0, 1]. */
inline constexpr ParamRange MIN_NORMAL_AGREEMENT = ParamRange::closed(0.0, 1.0);
} // namespace sac_multi_plane_segmentation_ranges

} // namespace planar_grid
