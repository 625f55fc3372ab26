// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/odometry/trajectory_io.h>

#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace planar_grid {

/** \brief Relative translation error for one segment length (see
 * relativeTranslationError()). \ingroup odometry */
struct RelativeTranslationError {
  /** \brief Segment length along the ground-truth path, metres. */
  double segment_length_m{0.0};
  /** \brief Number of segments (start frames) of this length. */
  std::size_t segments{0};
  /** \brief Mean over the segments of |error| / segment_length_m, percent. */
  double mean_error_percent{0.0};
};

/** \brief Rigid alignment (rotation and translation, no scale; Umeyama, Eigen::umeyama)
 * of the estimated camera positions onto the ground-truth positions, least squares.
 * Orientations are not used (the Karlsruhe INS angles are not trustworthy).
 * \param[in] estimated estimated poses world_T_camera
 * \param[in] ground_truth ground-truth poses, same frames and count
 * \return gt_T_est: ground-truth-world position = gt_T_est * estimated position
 * \throws planar_grid::Exception when the counts differ or are below 3
 * \ingroup odometry */
Eigen::Isometry3d alignPositions(const Trajectory& estimated,
                                 const Trajectory& ground_truth);

/** \brief Absolute trajectory error: root mean square of |gt_T_est * p_est(i) -
 * p_gt(i)| over all frames after alignPositions(), metres.
 * \param[in] estimated estimated poses
 * \param[in] ground_truth ground-truth poses, same frames and count (>= 3)
 * \return the RMSE, metres
 * \throws planar_grid::Exception when the counts differ or are below 3
 * \ingroup odometry */
double absoluteTrajectoryError(const Trajectory& estimated,
                               const Trajectory& ground_truth);

/** \brief Relative translation error, the KITTI odometry metric restricted to
 * positions. For each segment length L and every start frame i, the end frame j is the
 * first frame whose ground-truth path length from i (sum of the steps |p_gt(k+1) -
 * p_gt(k)|) is at least L; start frames with no such j are skipped. The segment error
 * is |R (p_est(j) - p_est(i)) - (p_gt(j) - p_gt(i))| / L, where R is the rotation of
 * alignPositions() (one global rotation; the ground-truth orientations are not used).
 * \param[in] estimated estimated poses
 * \param[in] ground_truth ground-truth poses, same frames and count (>= 3)
 * \param[in] segment_lengths_m the lengths L, metres (> 0)
 * \return one entry per length, in the given order (segments = 0 and error 0 when the
 * path is shorter than L)
 * \throws planar_grid::Exception when the counts differ or are below 3, or a length is
 * not positive
 * \ingroup odometry */
std::vector<RelativeTranslationError>
relativeTranslationError(const Trajectory& estimated,
                         const Trajectory& ground_truth,
                         const std::vector<double>& segment_lengths_m);

/** \brief Mean segment error over all segments of all lengths (each segment counts
 * once), percent; 0 when there is no segment. \param[in] errors the output of
 * relativeTranslationError() \ingroup odometry */
double
meanRelativeTranslationError(const std::vector<RelativeTranslationError>& errors);

/** \brief Diagnostic trajectory that separates direction from length errors: the
 * positions of \a estimated re-chained with each step's direction from \a estimated
 * and its length from \a reference (|p_ref(k) - p_ref(k-1)|); orientations are those
 * of \a estimated. A zero-length estimated step stays zero. RTE and ATE of the result
 * against the reference measure the direction (heading) errors alone.
 * \param[in] estimated estimated poses
 * \param[in] reference reference poses, same frames and count (>= 3)
 * \return the re-chained poses (first pose = estimated[0])
 * \throws planar_grid::Exception when the counts differ or are below 3
 * \ingroup odometry */
Trajectory withReferenceStepLengths(const Trajectory& estimated,
                                    const Trajectory& reference);

/** \brief Moves each position by a lever arm fixed to the direction of travel: \a
 * forward_m along the horizontal (x, y) direction of the track at that frame (central
 * difference of the neighbouring positions; one-sided at the ends) and \a left_m to
 * its left (z up). For evaluating against a position sensor (GPS/INS) mounted away
 * from the camera when its orientation is not trustworthy. Orientations are kept.
 * \param[in] trajectory poses with z up (e.g. Karlsruhe insdata.txt), >= 2
 * \param[in] forward_m offset along the track, metres
 * \param[in] left_m offset to the left of the track, metres
 * \return the moved poses
 * \throws planar_grid::Exception when there are fewer than 2 poses
 * \ingroup odometry */
Trajectory
offsetAlongTrack(const Trajectory& trajectory, double forward_m, double left_m);

} // namespace planar_grid
