// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/core/stereo_calibration.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <opencv2/core/mat.hpp>
#include <opencv2/core/types.hpp>

#include <string>
#include <vector>

namespace planar_grid {

/** \brief The valid range of each numeric StereoFeatureMatcher::Params member,
 * declared once: the StereoFeatureMatcher constructor tests the values against them
 * and the pipeline's feature_matching and cloud_features stage tables take them as
 * their ranges. \ingroup stereo */
namespace stereo_feature_matcher_ranges {
/** \brief Most key points per image: [1, 100000]. */
inline constexpr ParamRange MAX_FEATURES = ParamRange::closed(1, 100000);
/** \brief Lowe's ratio: (0, 1]. */
inline constexpr ParamRange RATIO = ParamRange::openMin(0.0, 1.0);
/** \brief Largest row difference of a match: [0, 10] pixels. */
inline constexpr ParamRange MAX_ROW_DIFFERENCE = ParamRange::closed(0.0, 10.0);
/** \brief Largest disparity accepted: (0, 1024] pixels. */
inline constexpr ParamRange MAX_DISPARITY = ParamRange::openMin(0.0, 1024.0);
/** \brief Largest range of a feature: (0, 1000000] metres; its end keeps every match
 * (0.0005 px of disparity at f B = 500 px m). */
inline constexpr ParamRange MAX_RANGE = ParamRange::openMin(0.0, 1e6);
/** \brief ORB_GRID: side of the grid cells: [8, 1024] pixels. */
inline constexpr ParamRange BUCKET_SIZE = ParamRange::closed(8, 1024);
/** \brief ORB_GRID: cv::FAST threshold: [1, 255] grey levels. */
inline constexpr ParamRange FAST_THRESHOLD = ParamRange::closed(1, 255);
/** \brief ORB_GRID: sub-pixel refinement window side: [3, 31] pixels (odd). */
inline constexpr ParamRange SUBPIXEL_WINDOW = ParamRange::closed(3, 31);
/** \brief ORB_GRID: sub-pixel refinement search: [1, 8] pixels. */
inline constexpr ParamRange SUBPIXEL_SEARCH = ParamRange::closed(1, 8);
} // namespace stereo_feature_matcher_ranges

class ByteReader;
class ByteWriter;

/** \brief Key feature detectors. The paper uses SURF, which is patented and absent from
 * Debian's OpenCV; SIFT is the default, ORB the fast option, ORB_GRID the fast front
 * end for the odometry. \ingroup stereo */
enum class FeatureType {
  /** OpenCV cv::SIFT: sub-pixel, scale-invariant, L2 descriptors (slow). */
  SIFT,
  /** OpenCV cv::ORB at its defaults: 8 pyramid levels of scale 1.2, FAST corners ranked
   * by the Harris response over the whole image, oriented BRIEF; integer positions on
   * each level, so disparities are quantised. */
  ORB,
  /** cv::FAST corners at full resolution, bucketed over a grid of square cells (at most
   * ceil(max_features / cells) per cell, strongest first) so that the whole image is
   * covered, upright ORB descriptors (cv::ORB::compute, one level, angle 0: rectified
   * cameras on a car do not roll), and the disparity of every match refined to
   * sub-pixel by a parabola through the zero-mean SSD of a window along the rectified
   * row. */
  ORB_GRID
};

/** \brief Parses "sift", "orb" or "orb_grid"; throws planar_grid::Exception otherwise.
 */
FeatureType featureTypeFromString(const std::string& name);

/** \brief The names of the feature types ("sift", "orb", "orb_grid"), each the name
 * featureTypeFromString() reads. \ingroup stereo */
const std::vector<std::string>& featureTypeNames();

/** \brief The name of \a type (one of featureTypeNames()). \ingroup stereo */
std::string featureTypeName(FeatureType type);

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

/** \brief FAST corners bucketed over a grid (the ORB_GRID detector): cv::FAST with
 * non-maximum suppression on the whole image, then in every bucket_size_px square cell
 * (the last column and row of cells are cut by the image) the \a max_per_cell corners
 * with the highest FAST response (ties: the earlier corner in cv::FAST's row-major
 * order). Corners closer than \a border_px to the image border are dropped first.
 * \param[in] grey 8-bit grey image (CV_8UC1), any size
 * \param[in] bucket_size_px side of the cells, px, >= 1
 * \param[in] max_per_cell most corners kept per cell, >= 1
 * \param[in] fast_threshold cv::FAST threshold, grey levels, in [1, 255]
 * \param[in] border_px margin without corners, px, >= 0
 * \param[out] keypoints the corners, cell by cell (row-major over the cells), strongest
 * first in each cell; integer positions (px), octave 0, angle 0, size 31 px (the ORB
 * patch), response = FAST score
 * \throws planar_grid::Exception when \a grey is not CV_8UC1 or a parameter is out of
 * range (an empty image gives no corners)
 * \ingroup stereo */
void detectGridFastKeypoints(const cv::Mat& grey,
                             int bucket_size_px,
                             int max_per_cell,
                             int fast_threshold,
                             int border_px,
                             std::vector<cv::KeyPoint>& keypoints);

/** \brief Detects key points in both images, matches each left descriptor to the right
 * image along the epipolar row (|dy| <= max_row_difference_px,
 * 0 < disparity <= max_disparity_px) with Lowe's ratio test, and triangulates the
 * matches with the disparity. Uses OpenCV's SIFT or ORB. \ingroup stereo \note A left
 * key point with a single candidate in its epipolar band passes the ratio test. Each
 * right key point is used at most once: the match with the smaller descriptor distance
 * keeps it. Right key points are bucketed by row, so the cost is about N_left x
 * (candidates per band), not N_left x N_right. \note ORB key points are integer
 * positions on pyramid levels of scale 1.2^level, so ORB disparities are quantised
 * to 1.2^level px; SIFT's are sub-pixel. \note ORB_GRID refines each match: the right
 * key point's column is moved to the sub-pixel minimum of the zero-mean sum of squared
 * differences between a subpixel_window_px square around the left key point and the
 * right image along the left key point's row (shifts of at most subpixel_search_px
 * around the matched right key point, then a parabola through the three costs around
 * the best shift), and its row is set to the left key point's row. Matches whose best
 * shift lies at the end of the search range, whose cost has no minimum, or whose best
 * cost exceeds half the left window's zero-mean energy (the windows disagree: a
 * descriptor mismatch or no texture along the row) are dropped.
 * The left key points stay at integer pixel positions. */
class StereoFeatureMatcher {
public:
  /** \brief Parameters with their defaults and valid ranges. */
  struct Params {
    /** Detector and descriptor. */
    FeatureType feature_type{FeatureType::SIFT};
    /** Most key points detected per image; in
     * stereo_feature_matcher_ranges::MAX_FEATURES. */
    int max_features{2000};
    /** Lowe's ratio: best / second-best descriptor distance must be below it; in
     * stereo_feature_matcher_ranges::RATIO. */
    double ratio{0.8};
    /** Largest row difference of a match, px (rectified images); in
     * stereo_feature_matcher_ranges::MAX_ROW_DIFFERENCE. */
    double max_row_difference_px{1.0};
    /** Largest disparity accepted, px; in stereo_feature_matcher_ranges::MAX_DISPARITY.
     */
    double max_disparity_px{128.0};
    /** Features farther than this (Euclidean range, metres) are dropped; in
     * stereo_feature_matcher_ranges::MAX_RANGE. */
    double max_range_m{40.0};
    /** ORB_GRID: side of the square grid cells over which the key points are
     * bucketed, px; in stereo_feature_matcher_ranges::BUCKET_SIZE. The cells of the
     * last column and row are cut by the image border. */
    int bucket_size_px{32};
    /** ORB_GRID: cv::FAST threshold (intensity difference of the segment test, grey
     * levels of an 8-bit image); in stereo_feature_matcher_ranges::FAST_THRESHOLD. Low,
     * since bucketing keeps only the strongest corners of each cell. */
    int fast_threshold{10};
    /** ORB_GRID: side of the square window of the sub-pixel disparity refinement, px;
     * odd, in stereo_feature_matcher_ranges::SUBPIXEL_WINDOW. */
    int subpixel_window_px{9};
    /** ORB_GRID: the refinement searches the right image's row within +-this many
     * columns of the matched right key point, px; in
     * stereo_feature_matcher_ranges::SUBPIXEL_SEARCH. */
    int subpixel_search_px{2};
  };

  /** \brief The one declaration (key with unit, range, meaning) of each Params
   * member, in the order documented: the feature_matching stage, its reference and
   * the defaults (the members' initializers) are made from it. */
  static const ParamDeclarations<Params>& getParamDeclarations();

  /** \brief Throws planar_grid::Exception for out-of-range parameters (the ORB_GRID
   * ones are checked for every feature type). */
  explicit StereoFeatureMatcher(const Params& params);
  /** \brief Uses the default Params. (Two constructors rather than a default argument:
   * GCC rejects `= Params()` for a nested struct with member initialisers.) */
  StereoFeatureMatcher();

  /** \brief Detects, matches and triangulates.
   * \param[in] left rectified left image, CV_8UC1 or CV_8UC3
   * \param[in] right rectified right image, same size and type
   * \param[in] calibration rectified intrinsics
   * \param[out] features the matched features (empty when none)
   * \throws planar_grid::Exception when the images are empty or differ in size
   * \note SIFT: cv::SIFT::detectAndCompute; ORB: cv::ORB::detectAndCompute; ORB_GRID:
   * cv::FAST, cv::ORB::compute and cv::getRectSubPix (the refinement windows). */
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
