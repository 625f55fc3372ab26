// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <string>

namespace planar_grid {

/** \brief The calibration file formats PlanarGrid reads. \ingroup stereo */
enum class CalibrationFormat {
  /** Karlsruhe stereo sequences' calib.txt: rows "P1_roi:" and "P2_roi:" (3x4,
   * row-major) for the cropped rectified images. */
  KARLSRUHE,
  /** KITTI odometry calib.txt: rows "P0:" and "P1:" (3x4, row-major), rectified; a
   * file without labels gives them as its first two rows of 12 numbers. */
  KITTI,
  /** A pair of ROS camera_info YAML files (rectified): left and right, with
   * image_width, image_height and projection_matrix (3x4); B = -P_right[0,3] /
   * P_right[0,0]. */
  ROS_CAMERA_INFO,
  /** A pair of EuRoC / Kalibr sensor.yaml files: intrinsics [fu, fv, cu, cv],
   * distortion, resolution and T_BS (camera to body); distorted and not rectified, so
   * they are rectified here with OpenCV: distortion_model radial-tangential (or radtan,
   * the default; k1 k2 p1 p2 [k3]) by stereoRectify with alpha = 0, equidistant
   * (fisheye; k1 k2 k3 k4) by fisheye::stereoRectify with balance = 0. Another model
   * is refused by name. */
  EUROC
};

/** \brief Parses "karlsruhe", "kitti", "ros_camera_info" or "euroc" (the names the
 * configuration uses); throws planar_grid::Exception listing the known names
 * otherwise. */
CalibrationFormat calibrationFormatFromString(const std::string& name);

/** \brief The name of \a format, as calibrationFormatFromString() reads it. */
std::string calibrationFormatName(CalibrationFormat format);

/** \brief Every calibration format's name, comma-separated (for messages). */
std::string knownCalibrationFormats();

/** \brief Undistortion and rectification maps for a raw stereo pair (empty for pairs
 * that are already rectified). \ingroup stereo */
struct StereoRectifier {
  /** \brief cv::initUndistortRectifyMap x map (CV_32FC1), left camera, pixels. */
  cv::Mat map_left_x;
  /** \brief cv::initUndistortRectifyMap y map (CV_32FC1), left camera, pixels. */
  cv::Mat map_left_y;
  /** \brief cv::initUndistortRectifyMap x map (CV_32FC1), right camera, pixels. */
  cv::Mat map_right_x;
  /** \brief cv::initUndistortRectifyMap y map (CV_32FC1), right camera, pixels. */
  cv::Mat map_right_y;

  /** \brief True when the pair needs no rectification. */
  bool empty() const { return map_left_x.empty(); }

  /** \brief Remaps a raw pair into the rectified pair (bilinear); copies when empty().
   * \param[in] left raw left image, the size the calibration was made for
   * \param[in] right raw right image, same size
   * \param[out] left_rectified rectified left image
   * \param[out] right_rectified rectified right image */
  void rectify(const cv::Mat& left,
               const cv::Mat& right,
               cv::Mat& left_rectified,
               cv::Mat& right_rectified) const;
};

/** \brief A calibrated stereo camera: the rectified intrinsics and, for raw pairs, the
 * maps that rectify its images. \ingroup stereo */
struct StereoCameraModel {
  /** \brief Rectified intrinsics (f, cx, cy in px, baseline in m, image size). */
  StereoCalibration calibration;
  /** \brief Maps for raw (unrectified) pairs; empty for rectified ones. */
  StereoRectifier rectifier;
  /** \brief Rotation from the raw left camera to the rectified left camera, R1 of
   * cv::stereoRectify: x_rect = rectified_R_left * x_left_raw (both x right, y down,
   * z forward). Identity for formats that are already rectified. The pose of the
   * rectified camera is therefore body_T_left * rectified_R_left^T. */
  Eigen::Matrix3d rectified_R_left{Eigen::Matrix3d::Identity()};
  /** \brief Pose of the raw left camera in the body (IMU) frame, EuRoC T_BS of the
   * left camera: a left-camera point p is at body_T_left * p in the body frame.
   * Identity for formats without extrinsics. */
  Eigen::Isometry3d body_T_left{Eigen::Isometry3d::Identity()};

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief Loads a stereo calibration.
 * \param[in] format the file format
 * \param[in] path the calibration file (KARLSRUHE, KITTI) or the left camera's file
 *            (ROS_CAMERA_INFO, EUROC)
 * \param[in] right_path the right camera's file (ROS_CAMERA_INFO, EUROC); ignored
 * otherwise \return the rectified model; its calibration passes
 * StereoCalibration::validate() \throws planar_grid::IOError naming the file (and the
 * field) when the file is missing, unreadable, lacks a field, names a camera or
 * distortion model that is not rectified here, or gives a non-positive focal length or
 * baseline; with the file and line (text formats) when a row or field
 * is given twice, or the baseline lies outside [0.001, 100] m; naming the right
 * camera's file (line) and the value when, in a rectified format (KARLSRUHE, KITTI,
 * ROS_CAMERA_INFO), the right projection's focal lengths fx, fy or principal point cx,
 * cy (pixels) differ from the left's by more than 1e-4 of their value: the cameras of a
 * rectified pair share them, and the baseline would be wrong */
StereoCameraModel loadStereoCalibration(CalibrationFormat format,
                                        const std::string& path,
                                        const std::string& right_path = "");

} // namespace planar_grid
