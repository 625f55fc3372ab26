// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_range.h>
#include <planar_grid/core/stereo_calibration.h>

#include <Eigen/Core>
#include <Eigen/StdVector>
#include <opencv2/core/mat.hpp>

#include <vector>

namespace planar_grid {

/** \brief The valid ranges of DisparityNormalParams. */
namespace disparity_normals_ranges {
/** \brief Half-width of the fitting window on the surface: (0, 10] m. */
inline constexpr ParamRange WINDOW_RADIUS = ParamRange::openMin(0.0, 10.0);
/** \brief Bounds of the fitting window's half-width in the image: [1, 200] px. */
inline constexpr ParamRange WINDOW_RADIUS_PX = ParamRange::closed(1, 200);
/** \brief Smallest share of the window's pixels that take part: (0, 1]. */
inline constexpr ParamRange MIN_VALID_FRACTION = ParamRange::openMin(0.0, 1.0);
} // namespace disparity_normals_ranges

/** \brief Parameters of estimateDisparityNormals(). \ingroup stereo */
struct DisparityNormalParams {
  /** \brief Half-width of the square window around a point's pixel, in meters on a
   * fronto-parallel surface at the point's depth z: f window_radius_m / z pixels,
   * within [min_window_radius_px, max_window_radius_px]. The disparity noise is about
   * the same everywhere, so a window of a fixed metric size gives about the same
   * normal noise near and far. */
  double window_radius_m{0.2};
  /** \brief Smallest half-width of the window, in pixels. */
  int min_window_radius_px{4};
  /** \brief Largest half-width of the window, in pixels; wider windows are read at a
   * stride that keeps about 15 x 15 pixels. */
  int max_window_radius_px{60};
  /** \brief A window needs at least this share of the pixels it reads valid and near
   * the point's own disparity (within 20 %, at least 2 px). */
  double min_valid_fraction{0.5};
};

/** \brief The surface normal of one point at a time from a disparity image: the fit of
 * estimateDisparityNormals() for a single point, for callers that need the normals of
 * only some points (the normal test of SACMultiPlaneSegmentation asks for a plane's
 * inliers alone). The image is shared (cv::Mat's reference count), not copied.
 * \ingroup stereo */
class DisparityNormalEstimator {
public:
  /** \brief Checks the inputs once (estimateDisparityNormals()' image, calibration and
   * parameters).
   * \throws planar_grid::Exception as estimateDisparityNormals() */
  DisparityNormalEstimator(const cv::Mat& disparity,
                           const StereoCalibration& calibration,
                           const DisparityNormalParams& params);

  /** \brief The unit normal (camera frame, toward the camera) of \a point_camera
   * (left camera frame, meters), or NaN where estimateDisparityNormals() gives NaN.
   * Equal to estimateDisparityNormals()' normal of the same point, bit for bit. */
  Eigen::Vector3f compute(const Eigen::Vector3f& point_camera) const;

private:
  cv::Mat disparity_;
  StereoCalibration calibration_;
  DisparityNormalParams params_;
};

/** \brief Surface normals of points seen in a rectified stereo pair, from the disparity
 * image around each point's pixel. A plane in space is a plane in (u, v, disparity):
 * with d = a u + b v + c fitted by least squares over the window, the plane's normal
 * in the camera frame is proportional to (a f, b f, c + a cx + b cy). Disparity noise
 * is about the same at every pixel, unlike the depth noise of the points (eq. 4), so
 * this fit stays a surface's own at range where a fit to the 3D points turns to the
 * lines of sight. The window takes the valid pixels whose disparity lies within 20 %
 * (at least 2 px) of the point's own, f B / z, so that an object in front of a wall
 * does not tilt the wall's normals. \ingroup stereo
 * \param[in] disparity CV_32FC1 disparity in pixels (NaN or <= 0 = invalid), the
 * image the points come from
 * \param[in] calibration rectified intrinsics and baseline
 * \param[in] points_camera points in the left camera frame (x right, y down, z
 * forward), meters
 * \param[in] params the window and the surface test
 * \param[out] normals one unit normal per point, camera frame, oriented toward the
 * camera; NaN where the point projects outside the image, lies behind it, or its
 * window fails the surface test
 * \throws planar_grid::Exception when the disparity is not CV_32FC1, the calibration
 * has no positive focal length and baseline, or a parameter is out of its range */
void estimateDisparityNormals(
  const cv::Mat& disparity,
  const StereoCalibration& calibration,
  const std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>&
    points_camera,
  const DisparityNormalParams& params,
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>>& normals);

} // namespace planar_grid
