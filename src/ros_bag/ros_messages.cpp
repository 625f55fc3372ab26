// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/ros_bag/ros_messages.h>

#include <pcl/PCLPointCloud2.h>

#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>

namespace planar_grid {
namespace ros_messages {

cv::Mat
greyImage(const sensor_msgs::Image& image, const std::string& where)
{
  int channels = 0;
  int code = -1;
  const std::string& e = image.encoding;
  if (e == "mono8" || e == "8UC1")
    channels = 1;
  else if (e == "bgr8" || e == "rgb8") {
    channels = 3;
    code = e == "bgr8" ? cv::COLOR_BGR2GRAY : cv::COLOR_RGB2GRAY;
  } else if (e == "bgra8" || e == "rgba8") {
    channels = 4;
    code = e == "bgra8" ? cv::COLOR_BGRA2GRAY : cv::COLOR_RGBA2GRAY;
  } else
    throw IOError(where + ": image encoding '" + e
                  + "' is not read; expected mono8, bgr8, rgb8, bgra8 or rgba8");
  const std::size_t row = static_cast<std::size_t>(image.width) * channels;
  if (image.width == 0 || image.height == 0 || image.step < row
      || image.data.size() < static_cast<std::size_t>(image.step) * image.height)
    throw IOError(where + ": the image's size " + std::to_string(image.width) + "x"
                  + std::to_string(image.height) + " (step "
                  + std::to_string(image.step) + ") does not match its "
                  + std::to_string(image.data.size()) + " bytes");
  const cv::Mat view(static_cast<int>(image.height), static_cast<int>(image.width),
                     CV_8UC(channels), const_cast<std::uint8_t*>(image.data.data()),
                     image.step);
  cv::Mat grey;
  if (code < 0)
    grey = view.clone();
  else
    cv::cvtColor(view, grey, code);
  return grey;
}

namespace {

/** A sensor_msgs/PointCloud2 as PCL's blob: the same fields, field for field. */
pcl::PCLPointCloud2
toPCLBlob(const sensor_msgs::PointCloud2& msg)
{
  pcl::PCLPointCloud2 blob;
  blob.header.frame_id = msg.header.frame_id;
  blob.header.seq = msg.header.seq;
  blob.header.stamp = msg.header.stamp.toNSec() / 1000;
  blob.height = msg.height;
  blob.width = msg.width;
  for (const auto& f : msg.fields) {
    pcl::PCLPointField field;
    field.name = f.name;
    field.offset = f.offset;
    field.datatype = f.datatype;
    field.count = f.count;
    blob.fields.push_back(field);
  }
  blob.is_bigendian = msg.is_bigendian;
  blob.point_step = msg.point_step;
  blob.row_step = msg.row_step;
  blob.data = msg.data;
  blob.is_dense = msg.is_dense;
  return blob;
}

} // namespace

/** The working cloud of a PointCloud2: intensity when it has one, the grey of its
 * colour (pcl::PointXYZRGBtoXYZI) when it has rgb, else intensity 0. */
void
cloudFromMessage(const sensor_msgs::PointCloud2& msg,
                 const std::string& where,
                 pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  pcl::PCLPointCloud2 blob = toPCLBlob(msg);
  const auto has = [&blob](const std::string& name) {
    return std::any_of(blob.fields.begin(), blob.fields.end(),
                       [&name](const pcl::PCLPointField& f) { return f.name == name; });
  };
  for (const char* axis : {"x", "y", "z"})
    if (!has(axis))
      throw IOError(where + ": the PointCloud2 has no field '" + axis + "'");
  if (blob.is_bigendian)
    throw IOError(where + ": big-endian PointCloud2 data is not read");
  checkPointCloudBlob(blob, where);
  // pcl::fromPCLPointCloud2 leaves a field of another datatype than the point type's
  // at 0: double or integer coordinates would all become the origin.
  convertFieldsToFloat(blob, {"x", "y", "z", "intensity"}, where);
  intensityCloudFromBlob(blob, cloud);
}

StereoCalibration
calibrationFromCameraInfo(const sensor_msgs::CameraInfo& left,
                          const sensor_msgs::CameraInfo& right,
                          const std::string& right_where)
{
  if (right.width != left.width || right.height != left.height)
    throw IOError(right_where + ": image size " + std::to_string(right.width) + "x"
                  + std::to_string(right.height)
                  + " differs from the left CameraInfo's (" + std::to_string(left.width)
                  + "x" + std::to_string(left.height) + ")");
  const auto& pl = left.P;
  const auto& pr = right.P;
  if (std::abs(pr[0] - pl[0]) > 1e-6 * std::abs(pl[0])
      || std::abs(pr[2] - pl[2]) > 1e-6 * std::abs(pl[0])
      || std::abs(pr[6] - pl[6]) > 1e-6 * std::abs(pl[0]))
    throw IOError(right_where
                  + ": the projection P differs from the left one's in "
                    "f, cx or cy: the pair is not rectified (give the "
                    "rectified images' topics and CameraInfo)");
  StereoCalibration calibration;
  calibration.focal_length_px = pl[0];
  calibration.cx_px = pl[2];
  calibration.cy_px = pl[6];
  calibration.baseline_m = -pr[3] / pr[0];
  calibration.width = static_cast<int>(left.width);
  calibration.height = static_cast<int>(left.height);
  calibration.validate(right_where);
  return calibration;
}

Eigen::Isometry3d
isometryFromTransform(const geometry_msgs::Transform& transform,
                      const std::string& where)
{
  const auto& q = transform.rotation;
  const auto& p = transform.translation;
  const Eigen::Quaterniond rotation(q.w, q.x, q.y, q.z);
  if (!(std::abs(rotation.norm() - 1.0) < 1e-3))
    throw IOError(where + ": the rotation is not a unit quaternion");
  Eigen::Isometry3d pose = Eigen::Isometry3d::Identity();
  pose.linear() = rotation.normalized().toRotationMatrix();
  pose.translation() = Eigen::Vector3d(p.x, p.y, p.z);
  return pose;
}

geometry_msgs::TransformStamped
transformStamped(const Eigen::Isometry3d& parent_T_child,
                 const std::string& parent,
                 const std::string& child,
                 const ros::Time& stamp)
{
  geometry_msgs::TransformStamped t;
  t.header.stamp = stamp;
  t.header.frame_id = parent;
  t.child_frame_id = child;
  const Eigen::Quaterniond q(parent_T_child.linear());
  t.transform.rotation.w = q.w();
  t.transform.rotation.x = q.x();
  t.transform.rotation.y = q.y();
  t.transform.rotation.z = q.z();
  t.transform.translation.x = parent_T_child.translation().x();
  t.transform.translation.y = parent_T_child.translation().y();
  t.transform.translation.z = parent_T_child.translation().z();
  return t;
}

sensor_msgs::CameraInfo
cameraInfo(const StereoCalibration& calibration,
           double tx,
           const ros::Time& stamp,
           const std::string& frame_id)
{
  const auto& c = calibration;
  sensor_msgs::CameraInfo info;
  info.header.stamp = stamp;
  info.header.frame_id = frame_id;
  info.width = static_cast<std::uint32_t>(std::max(0, c.width));
  info.height = static_cast<std::uint32_t>(std::max(0, c.height));
  info.P = {c.focal_length_px, 0.0, c.cx_px, tx,  0.0, c.focal_length_px,
            c.cy_px,           0.0, 0.0,     0.0, 1.0, 0.0};
  return info;
}

sensor_msgs::Image
monoImage(const cv::Mat& grey, const ros::Time& stamp, const std::string& frame_id)
{
  sensor_msgs::Image image;
  image.header.stamp = stamp;
  image.header.frame_id = frame_id;
  image.height = static_cast<std::uint32_t>(grey.rows);
  image.width = static_cast<std::uint32_t>(grey.cols);
  image.encoding = "mono8";
  image.step = image.width;
  const cv::Mat packed = grey.isContinuous() ? grey : grey.clone();
  image.data.assign(packed.datastart, packed.dataend);
  return image;
}

} // namespace ros_messages
} // namespace planar_grid
