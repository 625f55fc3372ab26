// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include <string>
#include <vector>

namespace planar_grid {

class ByteReader;
class ByteWriter;

/** \brief Key feature detectors. The paper uses SURF, which is patented and absent from
 * Debian's OpenCV; SIFT is the default, ORB the fast option. \ingroup stereo */
enum class FeatureType { SIFT, ORB };

/** \brief Parses "sift" or "orb"; throws planar_grid::Exception otherwise. */
FeatureType featureTypeFromString(const std::string& name);

/** \brief Key feature points matched left to right and triangulated (paper Sec. III-C:
 * the 3D features that feed the plane and occupancy estimation). Parallel arrays: the
 * i-th entry of each belongs to the same feature. \ingroup stereo */
struct StereoFeatures {
  /** \brief 3D positions in the left camera frame (x right, y down, z forward), metres.
   */
  pcl::PointCloud<pcl::PointXYZ> points;
  /** \brief Key points in the left image (px). */
  std::vector<cv::KeyPoint> keypoints_left;
  /** \brief Matched key points in the right image (px). */
  std::vector<cv::KeyPoint> keypoints_right;
  /** \brief Disparity u_left - u_right, px (> 0). */
  std::vector<float> disparities;
  /** \brief One descriptor row per feature (CV_32F for SIFT, CV_8U for ORB). */
  cv::Mat descriptors;

  /** \brief Returns the number of matched features (the size of every vector). */
  std::size_t size() const { return keypoints_left.size(); }
};

/** \brief Appends \a features to a little-endian byte section (pipeline checkpoints):
 * u64 point count and per point f32 x, y, z (metres); the left, then the right key
 * points, each as u64 count and per key point f32 pt.x, pt.y, size, angle, response,
 * i32 octave, class_id; the disparities as u64 byte count and f32 values (px); the
 * descriptors as i32 rows, cols, OpenCV type, u64 byte count and the row-major bytes.
 * \param[out] w the writer appended to
 * \param[in] features the features
 * \ingroup stereo */
void putStereoFeatures(ByteWriter& w, const StereoFeatures& features);

/** \brief Reads what putStereoFeatures() wrote.
 * \param[in,out] r the reader
 * \param[out] features replaced by the features read
 * \throws planar_grid::IOError on truncated or inconsistent data (a descriptor type
 * other than CV_8U or CV_32F, bytes that do not match the matrix size, points, left key
 * points and descriptor rows of different lengths)
 * \ingroup stereo */
void getStereoFeatures(ByteReader& r, StereoFeatures& features);

/** \brief Detects key points in both images, matches each left descriptor to the right
 * image along the epipolar row (|dy| <= max_row_difference_px,
 * 0 < disparity <= max_disparity_px) with Lowe's ratio test, and triangulates the
 * matches with the disparity. Uses OpenCV's SIFT or ORB. \ingroup stereo \note A left
 * key point with a single candidate in its epipolar band passes the ratio test. Each
 * right key point is used at most once: the match with the smaller descriptor distance
 * keeps it. Right key points are bucketed by row, so the cost is about N_left x
 * (candidates per band), not N_left x N_right. \note ORB key points are integer
 * positions on pyramid levels of scale 1.2^level, so ORB disparities are quantised
 * to 1.2^level px; SIFT's are sub-pixel. */
class StereoFeatureMatcher {
public:
  /** \brief Parameters with their defaults and valid ranges. */
  struct Params {
    /** Detector and descriptor. */
    FeatureType feature_type{FeatureType::SIFT};
    /** Most key points detected per image. */
    int max_features{2000};
    /** Lowe's ratio: best / second-best descriptor distance must be below it; (0, 1].
     */
    double ratio{0.8};
    /** Largest row difference of a match, px (rectified images). */
    double max_row_difference_px{1.0};
    /** Largest disparity accepted, px. */
    double max_disparity_px{128.0};
    /** Features farther than this (Euclidean range, metres) are dropped. */
    double max_range_m{40.0};
  };

  /** \brief Throws planar_grid::Exception for out-of-range parameters. */
  explicit StereoFeatureMatcher(const Params& params);
  /** \brief Uses the default Params. (Two constructors rather than a default argument:
   * GCC rejects `= Params()` for a nested struct with member initialisers.) */
  StereoFeatureMatcher();

  /** \brief Detects, matches and triangulates.
   * \param[in] left rectified left image, CV_8UC1 or CV_8UC3
   * \param[in] right rectified right image, same size and type
   * \param[in] calibration rectified intrinsics
   * \param[out] features the matched features (empty when none)
   * \throws planar_grid::Exception when the images are empty or differ in size */
  void match(const cv::Mat& left,
             const cv::Mat& right,
             const StereoCalibration& calibration,
             StereoFeatures& features) const;

  /** \brief Returns the parameters. */
  const Params& getParams() const { return params_; }

private:
  Params params_;
};

} // namespace planar_grid
