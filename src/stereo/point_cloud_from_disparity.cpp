// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>

#include <opencv2/imgproc.hpp>

#include <cmath>
#include <limits>
#include <string>

namespace planar_grid {

void
disparityToPointCloud(const cv::Mat& disparity,
                      const cv::Mat& intensity,
                      const StereoCalibration& calibration,
                      double max_range_m,
                      pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  if (disparity.empty()) {
    cloud.clear(); // width = height = 0
    return;
  }
  if (disparity.type() != CV_32FC1)
    throw Exception("disparityToPointCloud: the disparity must be CV_32FC1");
  if (!intensity.empty()) {
    if (intensity.size() != disparity.size())
      throw Exception("disparityToPointCloud: the intensity image and the disparity "
                      "differ in size");
    if (intensity.type() != CV_8UC1 && intensity.type() != CV_8UC3)
      throw Exception("disparityToPointCloud: the intensity image must be CV_8UC1 or "
                      "CV_8UC3");
  }
  if (!point_cloud_from_disparity_ranges::MAX_RANGE.contains(max_range_m))
    throw Exception("disparityToPointCloud: "
                    + paramRangeMessage(
                      "max_range_m", point_cloud_from_disparity_ranges::MAX_RANGE, "m")
                    + ", got " + std::to_string(max_range_m));
  calibration.validate("disparityToPointCloud");

  cv::Mat grey;
  if (intensity.channels() == 3)
    cv::cvtColor(intensity, grey, cv::COLOR_BGR2GRAY);
  else
    grey = intensity;

  const int width = disparity.cols;
  const int height = disparity.rows;
  cloud.resize(static_cast<pcl::uindex_t>(width), static_cast<pcl::uindex_t>(height));
  cloud.is_dense = false;

  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float fb =
    static_cast<float>(calibration.focal_length_px * calibration.baseline_m);
  const float inv_f = static_cast<float>(1.0 / calibration.focal_length_px);
  const float cx = static_cast<float>(calibration.cx_px);
  const float cy = static_cast<float>(calibration.cy_px);
  const float max_range_sq = static_cast<float>(max_range_m * max_range_m);

  for (int v = 0; v < height; ++v) {
    const float* d_row = disparity.ptr<float>(v);
    const std::uint8_t* i_row = grey.empty() ? nullptr : grey.ptr<std::uint8_t>(v);
    pcl::PointXYZI* out = &cloud.points[static_cast<std::size_t>(v) * width];
    const float y_over_z = (static_cast<float>(v) - cy) * inv_f;
    for (int u = 0; u < width; ++u, ++out) {
      out->intensity = i_row ? static_cast<float>(i_row[u]) : 0.0f;
      const float d = d_row[u];
      if (d > 0.0f) { // false for NaN
        const float z = fb / d;
        const float x = (static_cast<float>(u) - cx) * inv_f * z;
        const float y = y_over_z * z;
        if (x * x + y * y + z * z <= max_range_sq) {
          out->x = x;
          out->y = y;
          out->z = z;
          continue;
        }
      }
      out->x = out->y = out->z = nan;
    }
  }
}

} // namespace planar_grid
