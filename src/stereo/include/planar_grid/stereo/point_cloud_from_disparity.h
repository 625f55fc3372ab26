// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/core/stereo_calibration.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <opencv2/core/mat.hpp>

namespace planar_grid {

/** \brief The valid range of disparityToPointCloud()'s parameter (the stage
 * stereo_disparity's max_range_m). */
namespace point_cloud_from_disparity_ranges {
/** \brief Largest Euclidean range of a point kept: (0, 1000] m. */
inline constexpr ParamRange MAX_RANGE = ParamRange::openMin(0.0, 1000.0);
} // namespace point_cloud_from_disparity_ranges

/** \brief Reprojects a disparity image into an organized cloud in the left camera frame
 * (x right, y down, z forward, metres): z = f B / d, x = (u - cx) z / f,
 * y = (v - cy) z / f. \ingroup stereo
 * \param[in] disparity CV_32FC1 disparity in pixels (NaN or <= 0 = invalid)
 * \param[in] intensity CV_8UC1 or CV_8UC3 image of the same size whose grey value
 *            (0..255) fills the intensity field; may be empty (intensity 0)
 * \param[in] calibration rectified intrinsics
 * \param[in] max_range_m points farther than this (Euclidean range, metres) are
 * invalid; within point_cloud_from_disparity_ranges::MAX_RANGE \param[out] cloud width
 * x height organized cloud, is_dense = false; invalid pixels are NaN (PCL's convention)
 * \throws planar_grid::Exception when the sizes or types do not match or max_range_m is
 * out of its range */
void disparityToPointCloud(const cv::Mat& disparity,
                           const cv::Mat& intensity,
                           const StereoCalibration& calibration,
                           double max_range_m,
                           pcl::PointCloud<pcl::PointXYZI>& cloud);

} // namespace planar_grid
