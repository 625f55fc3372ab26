// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <opencv2/core/mat.hpp>

#include <memory>

namespace cv {
class StereoSGBM;
}

namespace planar_grid {

/** \brief Dense disparity of a rectified pair with OpenCV's semi-global block matching
 * (cv::StereoSGBM, Hirschmueller 2008). \ingroup stereo */
class DisparityEstimator {
public:
  /** \brief cv::StereoSGBM parameters; names follow OpenCV's, units in the suffix. */
  struct Params {
    /** Smallest disparity searched, px. */
    int min_disparity_px{0};
    /** Number of disparities searched, px; a positive multiple of 16. */
    int num_disparities_px{128};
    /** Matched block side, px; odd, 1..11. */
    int block_size_px{5};
    /** Smoothness penalty for disparity changes of 1 px; 0 = 8 * channels * block^2. */
    int p1{0};
    /** Smoothness penalty for larger changes; 0 = 32 * channels * block^2; > p1. */
    int p2{0};
    /** Left-right check tolerance, px; < 0 disables it. */
    int disp12_max_diff_px{1};
    /** Clip of the x-derivative pre-filter. */
    int pre_filter_cap{63};
    /** Margin in percent by which the best cost must win; 0..100. */
    int uniqueness_ratio_percent{10};
    /** Largest speckle region treated as noise, px; 0 disables speckle filtering. */
    int speckle_window_size_px{100};
    /** Largest disparity variation inside a connected component, px. */
    int speckle_range_px{2};
    /** Full 8-direction SGBM (slower) instead of 5 directions
     * (cv::StereoSGBM::MODE_SGBM). */
    bool full_dp{false};
  };

  /** \brief Throws planar_grid::Exception for parameters OpenCV would reject. */
  explicit DisparityEstimator(const Params& params);
  /** \brief Uses the default Params. (Two constructors rather than a default argument:
   * GCC rejects `= Params()` for a nested struct with member initialisers.) */
  DisparityEstimator();
  ~DisparityEstimator();
  /** \brief Moves the matcher and its parameters; \a other is left empty. */
  DisparityEstimator(DisparityEstimator&& other) noexcept;
  /** \brief Moves the matcher and its parameters; \a other is left empty.
   * \return *this */
  DisparityEstimator& operator=(DisparityEstimator&& other) noexcept;

  /** \brief Computes the disparity of the left image.
   * \param[in] left rectified left image, CV_8UC1 or CV_8UC3
   * \param[in] right rectified right image, same size and type
   * \param[out] disparity CV_32FC1, left image size, in pixels; pixels without a valid
   *             match are NaN
   * \throws planar_grid::Exception when the images are empty or differ in size or type
   * \note Colour input is converted to grey first (P1/P2 defaults assume one channel).
   *       A textureless region gets min_disparity_px (SGBM's tie-break), which for the
   *       default 0 means "infinitely far" and is dropped by disparityToPointCloud().
   * \note Not thread-safe on one object: cv::StereoSGBM keeps work buffers. */
  void compute(const cv::Mat& left, const cv::Mat& right, cv::Mat& disparity) const;

  /** \brief The parameters in use. */
  const Params& getParams() const { return params_; }

private:
  Params params_;
  cv::Ptr<cv::StereoSGBM> sgbm_;
};

} // namespace planar_grid
