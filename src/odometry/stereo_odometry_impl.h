// SPDX-License-Identifier: BSD-3-Clause
// The stereo reprojection and epipolar refinements of StereoOdometry, shared by its
// estimate (stereo_odometry.cpp) and their definitions
// (stereo_odometry_refinement.cpp).
#pragma once

#include <planar_grid/core/stereo_calibration.h>

#include <pcl/types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <opencv2/core/types.hpp>

#include <array>
#include <vector>

namespace planar_grid {
namespace detail {

/** \brief The key points of one correspondence: previous left, previous right,
 * current left, current right. */
using StereoKeypoints = std::array<const cv::KeyPoint*, 4>;

/** \brief The point of a left and a right key point in the rectified left camera
 * frame (metres), with \a offset_px added to their disparity u_left - u_right:
 * z = f B / (d + offset), x = (u_left - cx) z / f, y = (v_left - cy) z / f, as
 * StereoFeatureMatcher triangulates with no offset. False when the corrected
 * disparity is below 0.1 px. */
bool triangulate(const cv::KeyPoint& left,
                 const cv::KeyPoint& right,
                 const StereoCalibration& calibration,
                 double offset_px,
                 Eigen::Vector3d& point);

/** \brief Stereo reprojection residuals of one correspondence: the previous point
 * projected into the current left and right images and the current point into the
 * previous ones, minus the matched key points (8 values, pixels). Both points are
 * triangulated from their key points with the disparity offset \a offset_px (true
 * disparity = measured + offset), and the right projections carry the same offset
 * (a measured right column is the true one + offset), so that the offset acts as the
 * difference of the two rectified cameras' principal point columns. False when a
 * disparity is too small or a point falls behind a camera. */
bool reprojectionResiduals(const Eigen::Isometry3d& previous_T_current,
                           const StereoCalibration& calibration,
                           double offset_px,
                           const StereoKeypoints& keypoints,
                           Eigen::Matrix<double, 8, 1>& residuals);

/** \brief The disparity offset of a reprojection refinement: its value (px) and its
 * information (1 / variance, px^-2, for residuals of unit variance in pixels). */
struct OffsetEstimate {
  double offset_px{0.0};
  double information{0.0};
};

/** \brief Gauss-Newton on the stereo reprojection error of the given correspondences,
 * with Huber weights (1 px) and numerical derivatives; 10 iterations at most. With
 * rotation_fixed only the translation changes. \a offset holds the disparity offset
 * the refinement starts from. With \a estimate_offset the offset is a seventh unknown
 * with the Gaussian prior \a prior (its information is the prior's weight), and
 * \a offset receives the estimate and its information (the prior's plus the data's,
 * the Schur complement of the motion); without it \a offset is left as it is. */
Eigen::Isometry3d refineReprojection(Eigen::Isometry3d motion,
                                     const StereoCalibration& calibration,
                                     const std::vector<StereoKeypoints>& keypoints,
                                     const pcl::Indices& inliers,
                                     bool rotation_fixed,
                                     bool estimate_offset,
                                     const OffsetEstimate& prior,
                                     OffsetEstimate& offset);

/** \brief Gauss-Newton on the Sampson distances of the left key points of the given
 * correspondences over the rotation and the translation direction (5 degrees of
 * freedom; numerical derivatives; Huber weights of threshold_px; each
 * correspondence weighted by (median size / size)^2 with size the larger of its two
 * key point sizes, as the localisation error grows with the detection scale). 10
 * iterations at most. */
void refineEpipolar(Eigen::Matrix3d& rotation,
                    Eigen::Vector3d& direction,
                    const StereoCalibration& calibration,
                    const std::vector<StereoKeypoints>& keypoints,
                    const pcl::Indices& inliers,
                    double threshold_px);

} // namespace detail
} // namespace planar_grid
