// SPDX-License-Identifier: BSD-3-Clause
// The ground truth of a dataset of the map comparison (TruthConfig: points, a
// disparity image or the REFERENCE voxels) and the frames' views for its mapped range.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/mapping_error.h>

#include <pcl/io/pcd_io.h>

#include <opencv2/imgcodecs.hpp>

#include <cstdint>
#include <memory>
#include <string>

#include "map_comparison_lane.h"

namespace planar_grid {
namespace detail {

/** The view of \a frame for the mapped range: its pose and, for stereo input, its
 * image (the calibration's size, else the left image's). */
RangeView
rangeView(const Frame& frame)
{
  RangeView view;
  view.world_T_camera = frame.world_T_camera;
  const StereoCalibration& c = frame.calibration;
  if (c.focal_length_px > 0.0) {
    view.focal_length_px = c.focal_length_px;
    view.cx_px = c.cx_px;
    view.cy_px = c.cy_px;
    view.width_px = c.width > 0 ? c.width : frame.left.cols;
    view.height_px = c.height > 0 ? c.height : frame.left.rows;
  }
  return view;
}

/** The ground truth of \a ds (TruthConfig); \a first_frame gives the DISPARITY truth
 * its calibration and pose, \a reference holds the REFERENCE voxels. */
std::unique_ptr<GroundTruthSurface>
buildTruth(const DatasetConfig& ds,
           const Frame& first_frame,
           const ReferenceVoxels& reference,
           std::string& truth_kind)
{
  pcl::PointCloud<pcl::PointXYZ>::Ptr truth_points(new pcl::PointCloud<pcl::PointXYZ>);
  truth_kind = "truth";
  switch (ds.truth.type) {
    case TruthConfig::Type::POINTS:
      if (pcl::io::loadPCDFile(ds.truth.file, *truth_points) != 0)
        throw IOError(ds.truth.file + ": cannot read the truth points (PCD)");
      break;
    case TruthConfig::Type::DISPARITY: {
      const cv::Mat gt = cv::imread(ds.truth.file, cv::IMREAD_UNCHANGED);
      if (gt.empty() || gt.type() != CV_8UC1)
        throw IOError(ds.truth.file + ": not an 8-bit disparity image");
      const StereoCalibration& c = first_frame.calibration;
      const Eigen::Matrix4f world_T = first_frame.world_T_camera.matrix().cast<float>();
      for (int v = 0; v < gt.rows; ++v)
        for (int u = 0; u < gt.cols; ++u) {
          const int d = gt.at<std::uint8_t>(v, u);
          if (d == 0)
            continue;
          const double z = c.depthFromDisparity(d);
          const Eigen::Vector4f p(
            static_cast<float>((u - c.cx_px) * z / c.focal_length_px),
            static_cast<float>((v - c.cy_px) * z / c.focal_length_px),
            static_cast<float>(z), 1.0f);
          const Eigen::Vector4f q = world_T * p;
          truth_points->push_back(pcl::PointXYZ(q.x(), q.y(), q.z()));
        }
      break;
    }
    case TruthConfig::Type::REFERENCE:
      reference.getPoints(ds.truth.min_views, *truth_points);
      truth_kind = "reference";
      break;
  }
  if (truth_points->empty())
    throw Exception("dataset " + ds.name + ": the truth has no points");
  return std::make_unique<GroundTruthSurface>(truth_points);
}

} // namespace detail
} // namespace planar_grid
