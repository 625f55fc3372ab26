// SPDX-License-Identifier: BSD-3-Clause
// Shared by the benchmarks: one real Karlsruhe stereo frame as SGBM disparity and an
// organized cloud, the way the pipeline's stereo_disparity stage makes it.
#pragma once

#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>

#include <opencv2/imgcodecs.hpp>

#include <cstdio>
#include <string>

namespace planar_grid {
namespace bench {

/** \brief A rectified Karlsruhe pair with its calibration. */
struct KarlsruhePair {
  cv::Mat left, right;
  StereoCameraModel model;
  bool ok{false};
};

/** \brief Loads frame \a index of ../shared/data/karlsruhe_2010_03_09_drive_0023
 * (PLANAR_GRID_DATA_DIR); ok is false when the images are missing. */
inline KarlsruhePair
loadKarlsruhePair(int index)
{
  KarlsruhePair pair;
  const std::string dir =
    std::string(PLANAR_GRID_DATA_DIR) + "/karlsruhe_2010_03_09_drive_0023";
  char name[32];
  std::snprintf(name, sizeof(name), "%06d.png", index);
  pair.left = cv::imread(dir + "/left/I1_" + name, cv::IMREAD_GRAYSCALE);
  pair.right = cv::imread(dir + "/right/I2_" + name, cv::IMREAD_GRAYSCALE);
  if (pair.left.empty() || pair.right.empty())
    return pair;
  pair.model = loadStereoCalibration(CalibrationFormat::KARLSRUHE, dir + "/calib.txt");
  pair.ok = true;
  return pair;
}

/** \brief The organized SGBM cloud (default DisparityEstimator, 128 disparities) of a
 * pair, cut at \a max_range_m. */
inline void
denseCloud(const KarlsruhePair& pair,
           double max_range_m,
           pcl::PointCloud<pcl::PointXYZI>& cloud)
{
  cv::Mat disparity;
  DisparityEstimator().compute(pair.left, pair.right, disparity);
  disparityToPointCloud(disparity, pair.left, pair.model.calibration, max_range_m,
                        cloud);
}

} // namespace bench
} // namespace planar_grid
