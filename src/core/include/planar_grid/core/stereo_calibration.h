// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

namespace planar_grid {

/** \brief Intrinsics of a rectified stereo pair: both cameras share the focal length
 * and principal point, and the right camera sits baseline_m along +x of the left one.
 *
 * A pixel (u, v) of the left image with disparity d (px) lies at
 * z = focal_length_px * baseline_m / d, x = (u - cx_px) z / focal_length_px,
 * y = (v - cy_px) z / focal_length_px in the left camera frame (x right, y down,
 * z forward, metres). \ingroup core */
struct StereoCalibration {
  /** \brief Smallest baseline of a stereo rig, in metres: phone and endoscope cameras
   * have a few millimetres; below, a wrong unit or a corrupt value. */
  static constexpr double MIN_BASELINE_M = 1e-3;
  /** \brief Largest baseline of a stereo rig, in metres: wide-baseline rigs have a few
   * tens; above, a wrong unit (millimetres read as metres) or a corrupt value. */
  static constexpr double MAX_BASELINE_M = 100.0;

  /** \brief Focal length of the rectified cameras, in pixels (> 0). */
  double focal_length_px{0.0};
  /** \brief Principal point column, in pixels. */
  double cx_px{0.0};
  /** \brief Principal point row, in pixels. */
  double cy_px{0.0};
  /** \brief Distance between the two optical centres, in metres (> 0). */
  double baseline_m{0.0};
  /** \brief Image width in pixels (0 when not known from the calibration file). */
  int width{0};
  /** \brief Image height in pixels (0 when not known from the calibration file). */
  int height{0};

  /** \brief Throws planar_grid::IOError naming \a source when the focal length or
   * baseline is not a finite positive number, the baseline lies outside
   * [MIN_BASELINE_M, MAX_BASELINE_M], or the image size is negative. Every source
   * holds a calibration to it: the file readers, Mapper and the ROS node's
   * CameraInfo.
   * \param[in] source the file the calibration came from, for the message */
  void validate(const std::string& source) const;

  /** \brief Largest distance of the principal point from the images' centre, as a
   * share of the width (cx) or the height (cy), before principalPointWarning() warns:
   * rectification keeps it near the centre. */
  static constexpr double MAX_PRINCIPAL_POINT_OFFSET = 0.15;

  /** \brief A warning when the principal point lies farther than
   * MAX_PRINCIPAL_POINT_OFFSET of the image's side from the centre of images of
   * \a width_px x \a height_px, which usually means the calibration of another crop
   * of the images (e.g. Karlsruhe's `P1` for the cropped `P1_roi` images: cy 264 px in
   * 372 px high images, 21 % of the height off the centre); empty otherwise.
   * \param[in] width_px, height_px the images' size, px
   * \param[in] source the calibration's origin, for the message */
  std::string
  principalPointWarning(int width_px, int height_px, const std::string& source) const;

  /** \brief Depth in metres of a disparity in pixels (z = f B / d); +inf for d <= 0. */
  double depthFromDisparity(double disparity_px) const;

  /** \brief Stereo depth error in metres at depth z for a disparity error in pixels:
   * dz = z^2 / (B f) * dd (paper, Sec. III-D, after eq. 4). */
  double depthError(double depth_m, double disparity_error_px = 0.5) const;
};

} // namespace planar_grid
