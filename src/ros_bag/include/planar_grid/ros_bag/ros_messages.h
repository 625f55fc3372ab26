// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <geometry_msgs/Transform.h>
#include <geometry_msgs/TransformStamped.h>
#include <opencv2/core/mat.hpp>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>

#include <string>

/** \file
 * The ROS 1 messages the pipeline reads, as its own types: one owner for the ROS bag
 * input of the pipeline, the ROS node and the bag tools (tools/ros). Part of the
 * planar_grid_ros_bag library, which is built and installed with the ROS bag input only
 * (PLANAR_GRID_WITH_ROS_BAG and Debian's ROS 1 packages); including it needs the ROS
 * message headers (sensor_msgs, geometry_msgs). \ingroup ros_bag */

namespace planar_grid {
namespace ros_messages {

/** \brief A sensor_msgs/Image as an 8-bit grey image (copied out of the message);
 * colour encodings (bgr8, rgb8, bgra8, rgba8) are turned grey with cv::cvtColor.
 * \param[in] image the message: mono8, bgr8, rgb8, bgra8 or rgba8
 * \param[in] where the message's origin, for the error text
 * \return a CV_8UC1 image of the message's size, px
 * \throws planar_grid::IOError for another encoding or a size that does not match
 * the data */
cv::Mat greyImage(const sensor_msgs::Image& image, const std::string& where);

/** \brief The working cloud of a sensor_msgs/PointCloud2 (meters, the message's
 * frame): intensity when it has one, the grey of its colour when it has rgb, else 0.
 * x, y, z and intensity of any numeric datatype (double, integer) are read as floats.
 * \throws planar_grid::IOError for a cloud without x, y, z, big-endian data, a size
 * that does not match the data, or an x/y/z/intensity field with COUNT > 1 */
void cloudFromMessage(const sensor_msgs::PointCloud2& msg,
                      const std::string& where,
                      pcl::PointCloud<pcl::PointXYZI>& cloud);

/** \brief The calibration of a rectified pair from its two CameraInfo projection
 * matrices P: f = P_left[0][0], cx = P_left[0][2], cy = P_left[1][2] (px),
 * B = -P_right[0][3] / P_right[0][0] (m; ROS stores Tx = -f B in the right P); the
 * image size from the left CameraInfo (0 x 0: not given).
 * \param[in] left the left camera's CameraInfo
 * \param[in] right the right camera's CameraInfo
 * \param[in] right_where the right CameraInfo's origin, for the error text
 * \throws planar_grid::IOError when the two sizes differ, when the two P differ in f,
 * cx or cy (the pair is not rectified) or the calibration is invalid */
StereoCalibration calibrationFromCameraInfo(const sensor_msgs::CameraInfo& left,
                                            const sensor_msgs::CameraInfo& right,
                                            const std::string& right_where);

/** \brief A geometry_msgs/Transform as parent_T_child, meters.
 * \throws planar_grid::IOError when the rotation is not a unit quaternion (norm off
 * by more than 1e-3; it is normalized otherwise) */
Eigen::Isometry3d isometryFromTransform(const geometry_msgs::Transform& transform,
                                        const std::string& where);

/** \brief \a parent_T_child (meters) as a geometry_msgs/TransformStamped from
 * \a parent to \a child at \a stamp (the rotation as a unit quaternion). */
geometry_msgs::TransformStamped
transformStamped(const Eigen::Isometry3d& parent_T_child,
                 const std::string& parent,
                 const std::string& child,
                 const ros::Time& stamp);

/** \brief The CameraInfo of one camera of a rectified pair: its size from
 * \a calibration (0 x 0 when not given) and P = [f 0 cx Tx; 0 f cy 0; 0 0 1 0], with
 * Tx = 0 for the left camera and -f B (px m) for the right one. */
sensor_msgs::CameraInfo cameraInfo(const StereoCalibration& calibration,
                                   double tx,
                                   const ros::Time& stamp,
                                   const std::string& frame_id);

/** \brief An 8-bit grey image (CV_8UC1) as a mono8 sensor_msgs/Image (copied). */
sensor_msgs::Image
monoImage(const cv::Mat& grey, const ros::Time& stamp, const std::string& frame_id);

} // namespace ros_messages
} // namespace planar_grid
