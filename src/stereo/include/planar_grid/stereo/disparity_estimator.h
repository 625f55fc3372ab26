// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>
#include <planar_grid/core/param_range.h>

#include <opencv2/core/mat.hpp>

#include <memory>
#include <string>

namespace cv {
class StereoMatcher;
}

namespace planar_grid {

/** \brief The valid range of each integer DisparityEstimator::Params member, declared
 * once: the DisparityEstimator constructor tests the values against them (with the
 * conditions a range cannot say: odd sizes, multiples of downscale) and the pipeline's
 * disparity stage table takes them as its ranges. \ingroup stereo */
namespace disparity_estimator_ranges {
/** \brief Image scale divisor: [1, 2]. */
inline constexpr ParamRange DOWNSCALE = ParamRange::closed(1, 2);
/** \brief Row divisor: [1, 2]. */
inline constexpr ParamRange ROW_DOWNSCALE = ParamRange::closed(1, 2);
/** \brief OpenCV threads (0: OpenCV's setting): [0, 64]. */
inline constexpr ParamRange NUM_THREADS = ParamRange::closed(0, 64);
/** \brief Smallest disparity searched: [-256, 256] pixels. */
inline constexpr ParamRange MIN_DISPARITY = ParamRange::closed(-256, 256);
/** \brief Number of disparities searched: [16, 512] pixels. */
inline constexpr ParamRange NUM_DISPARITIES = ParamRange::closed(16, 512);
/** \brief Matched block side of the SGBM modes: [1, 11] pixels (odd). */
inline constexpr ParamRange BLOCK_SIZE_SGBM = ParamRange::closed(1, 11);
/** \brief Matched block side of BLOCK_MATCHING: [5, 21] pixels (odd). */
inline constexpr ParamRange BLOCK_SIZE_BLOCK_MATCHING = ParamRange::closed(5, 21);
/** \brief Matched block side of any mode: [1, 21] pixels. */
inline constexpr ParamRange BLOCK_SIZE =
  ParamRange::closed(BLOCK_SIZE_SGBM.min, BLOCK_SIZE_BLOCK_MATCHING.max);
/** \brief SGBM penalty of 1 px changes (0: OpenCV's): [0, 100000]. */
inline constexpr ParamRange P1 = ParamRange::closed(0, 100000);
/** \brief SGBM penalty of larger changes (0: OpenCV's): [0, 400000]. */
inline constexpr ParamRange P2 = ParamRange::closed(0, 400000);
/** \brief Left-right check tolerance (-1: no check): [-1, 64] pixels. */
inline constexpr ParamRange DISP12_MAX_DIFF = ParamRange::closed(-1, 64);
/** \brief SGBM modes: clip of the x-derivative pre-filter: [1, 63]. */
inline constexpr ParamRange PRE_FILTER_CAP = ParamRange::closed(1, 63);
/** \brief Margin by which the best cost must win: [0, 100] percent. */
inline constexpr ParamRange UNIQUENESS_RATIO = ParamRange::closed(0, 100);
/** \brief Largest speckle region (0: no filtering): [0, 10000] pixels. */
inline constexpr ParamRange SPECKLE_WINDOW_SIZE = ParamRange::closed(0, 10000);
/** \brief Largest disparity variation inside a speckle: [0, 64] pixels. */
inline constexpr ParamRange SPECKLE_RANGE = ParamRange::closed(0, 64);
/** \brief BLOCK_MATCHING: clip of the pre-filter output: [1, 31]. */
inline constexpr ParamRange BM_PRE_FILTER_CAP = ParamRange::closed(1, 31);
/** \brief BLOCK_MATCHING: normalized-response window side: [5, 255] pixels (odd). */
inline constexpr ParamRange BM_PRE_FILTER_SIZE = ParamRange::closed(5, 255);
/** \brief BLOCK_MATCHING: texture threshold (0: no check): [0, 100000]. */
inline constexpr ParamRange BM_TEXTURE_THRESHOLD = ParamRange::closed(0, 100000);
} // namespace disparity_estimator_ranges

/** \brief Dense stereo matchers wrapped by DisparityEstimator. All are OpenCV
 * (calib3d, no contrib). \ingroup stereo */
enum class DisparityAlgorithm {
  /** cv::StereoSGBM, MODE_SGBM: semi-global block matching (Hirschmueller 2008) along 5
   * directions; single-threaded. */
  SGBM,
  /** cv::StereoSGBM, MODE_SGBM_3WAY: 3 directions per pass, parallel over image
   * stripes (cv::parallel_for_). */
  SGBM_3WAY,
  /** cv::StereoSGBM, MODE_HH: the full 8-direction SGM (slowest, most memory). */
  SGBM_HH,
  /** cv::StereoSGBM, MODE_HH4: 4 directions, parallel over rows and columns. */
  SGBM_HH4,
  /** cv::StereoBM: local sum-of-absolute-differences block matching (Konolige 1997)
   * with a texture threshold; parallel over stripes. */
  BLOCK_MATCHING
};

/** \brief Parses "sgbm", "sgbm_3way", "sgbm_hh", "sgbm_hh4" or "block_matching".
 * \throws planar_grid::Exception for any other name, listing the known ones */
DisparityAlgorithm disparityAlgorithmFromString(const std::string& name);

/** \brief The name disparityAlgorithmFromString() parses back to \a algorithm. */
std::string toString(DisparityAlgorithm algorithm);

/** \brief StereoBM's pre-filter of both images (cv::StereoBM::PREFILTER_*).
 * \ingroup stereo */
enum class BlockMatchingPreFilter {
  /** Horizontal Sobel derivative, clipped to +-bm_pre_filter_cap (PREFILTER_XSOBEL).
   */
  XSOBEL,
  /** Each pixel minus the mean of its bm_pre_filter_size_px window, clipped to
   * +-bm_pre_filter_cap (PREFILTER_NORMALIZED_RESPONSE). */
  NORMALIZED_RESPONSE
};

/** \brief Parses "xsobel" or "normalized_response".
 * \throws planar_grid::Exception for any other name */
BlockMatchingPreFilter blockMatchingPreFilterFromString(const std::string& name);

/** \brief The name blockMatchingPreFilterFromString() parses back to \a pre_filter. */
std::string toString(BlockMatchingPreFilter pre_filter);

/** \brief Dense disparity of a rectified pair with one of OpenCV's matchers:
 * semi-global block matching (cv::StereoSGBM, Hirschmueller 2008, in four modes) or
 * local block matching (cv::StereoBM), optionally on half-resolution images.
 *
 * The output is always a CV_32FC1 image of the input's size whose values are
 * disparities in pixels of the input images; NaN marks pixels without a valid match.
 * Results depend only on the parameters and the images: within the ranges enforced
 * here, OpenCV 4.6's matchers give the same output for any thread count and on every
 * call (checked by tests on 1 and 2 threads, and for SGBM_3WAY on 1, 3, 4 and 8:
 * OpenCV always cuts the image into 4 stripes for it, whatever the thread count).
 * \ingroup stereo */
class DisparityEstimator {
public:
  /** \brief Matcher parameters; names follow OpenCV's, units in the suffix. Every
   * length in pixels refers to the input images unless stated otherwise. */
  struct Params {
    /** Which OpenCV matcher runs. */
    DisparityAlgorithm algorithm{DisparityAlgorithm::SGBM};
    /** Image scale divisor, in disparity_estimator_ranges::DOWNSCALE. With 2 both
     * images are shrunk by half (cv::resize, INTER_AREA), matched with half the
     * disparity range, and the disparities are scaled back: the output has the input's
     * size and disparities in input pixels. About 5-10x faster, but the sub-pixel step
     * is 1/8 px instead of 1/16 px and the sub-pixel error about twice as large (0.22
     * against 0.09 px median on a synthetic slanted plane). */
    int downscale{1};
    /** Row divisor, in disparity_estimator_ranges::ROW_DOWNSCALE (only with downscale
     * 1). With 2 both images are shrunk to half their rows (cv::resize, INTER_AREA:
     * each matched row is the mean of two input rows) and matched with the full
     * disparity range; the disparity image is brought back to the input's rows.
     * Columns, disparities and the sub-pixel step (1/16 px) stay those of the input, so
     * depth precision is kept, while the matching cost halves; the vertical detail is
     * that of half the rows. The speckle area is halved. */
    int row_downscale{1};
    /** OpenCV threads used while computing (cv::setNumThreads for the duration of
     * compute(), then restored); 0 leaves OpenCV's process-wide setting (by default
     * the number of cores). Affects speed only, never the result. In
     * disparity_estimator_ranges::NUM_THREADS. The setting is process-wide: with
     * another thread running OpenCV code at the same time, leave 0 here and call
     * cv::setNumThreads once beforehand. OpenCV runs a parallel loop on the calling
     * thread alone while another thread is inside one (a process-wide flag), so the
     * matching uses the threads only when no other OpenCV parallel loop is running; the
     * result is the same either way. */
    int num_threads{0};
    /** Smallest disparity searched, px; in disparity_estimator_ranges::MIN_DISPARITY
     * and a multiple of \a downscale. */
    int min_disparity_px{0};
    /** Number of disparities searched, px; in
     * disparity_estimator_ranges::NUM_DISPARITIES and a multiple of 16 * downscale. */
    int num_disparities_px{128};
    /** Matched block side, px of the matched (possibly downscaled) image; odd, in
     * disparity_estimator_ranges::BLOCK_SIZE_SGBM for the SGBM modes,
     * disparity_estimator_ranges::BLOCK_SIZE_BLOCK_MATCHING for BLOCK_MATCHING
     * (OpenCV 4.6's StereoBM falls back to a generic path above 21 that gives different
     * results from run to run). */
    int block_size_px{5};
    /** SGBM smoothness penalty for disparity changes of 1 px; 0 = 8 * block^2 (OpenCV's
     * recommendation for one channel); in disparity_estimator_ranges::P1. Ignored by
     * BLOCK_MATCHING. */
    int p1{0};
    /** SGBM penalty for larger changes; 0 = 32 * block^2; > p1, in
     * disparity_estimator_ranges::P2. Ignored by
     * BLOCK_MATCHING. */
    int p2{0};
    /** Left-right check tolerance, px; in disparity_estimator_ranges::DISP12_MAX_DIFF;
     * -1 disables it. Halved (rounded up) for downscale 2. */
    int disp12_max_diff_px{1};
    /** SGBM modes: clip of the x-derivative pre-filter, in
     * disparity_estimator_ranges::PRE_FILTER_CAP. (BLOCK_MATCHING uses
     * bm_pre_filter_cap.) */
    int pre_filter_cap{63};
    /** Margin in percent by which the best cost must win; in
     * disparity_estimator_ranges::UNIQUENESS_RATIO. */
    int uniqueness_ratio_percent{10};
    /** Largest speckle region treated as noise, px (an area: divided by 4 for
     * downscale 2); in disparity_estimator_ranges::SPECKLE_WINDOW_SIZE; 0 disables
     * speckle filtering. */
    int speckle_window_size_px{100};
    /** Largest disparity variation inside a connected component, px (halved, rounded
     * up, for downscale 2); in disparity_estimator_ranges::SPECKLE_RANGE. */
    int speckle_range_px{2};
    /** Legacy switch for full 8-direction SGBM: true is the same as algorithm SGBM_HH
     * and is only valid with algorithm SGBM. */
    bool full_dp{false};
    /** BLOCK_MATCHING only: the pre-filter of both images. */
    BlockMatchingPreFilter bm_pre_filter{BlockMatchingPreFilter::XSOBEL};
    /** BLOCK_MATCHING only: clip of the pre-filter output, in
     * disparity_estimator_ranges::BM_PRE_FILTER_CAP (OpenCV 4.6's
     * StereoBM takes a generic path above 31 that gives different results from run to
     * run; 31 is OpenCV's default). */
    int bm_pre_filter_cap{31};
    /** BLOCK_MATCHING only: window side of the NORMALIZED_RESPONSE pre-filter, px of
     * the matched image; odd, in disparity_estimator_ranges::BM_PRE_FILTER_SIZE. */
    int bm_pre_filter_size_px{9};
    /** BLOCK_MATCHING only: a pixel whose block has a sum of absolute pre-filtered
     * values below this is invalid (textureless); 0 disables the check. In
     * disparity_estimator_ranges::BM_TEXTURE_THRESHOLD. */
    int bm_texture_threshold{10};
  };

  /** \brief The one declaration (key with unit, range, meaning) of each Params
   * member, in the order documented: the stereo_disparity stage, its reference and
   * the defaults (the members' initializers) are made from it. */
  static const ParamDeclarations<Params>& getParamDeclarations();

  /** \brief Builds the matcher.
   * \param[in] params the parameters
   * \throws planar_grid::Exception for parameters OpenCV would reject or that are
   *         outside the ranges documented in Params (e.g. an even block size) */
  explicit DisparityEstimator(const Params& params);
  /** \brief Uses the default Params (5-direction SGBM, 128 disparities, block 5).
   * (Two constructors rather than a default argument: GCC rejects `= Params()` for a
   * nested struct with member initialisers.) */
  DisparityEstimator();
  ~DisparityEstimator();
  /** \brief Moves the matcher and its parameters; \a other is left empty. */
  DisparityEstimator(DisparityEstimator&& other) noexcept;
  /** \brief Moves the matcher and its parameters; \a other is left empty.
   * \return *this */
  DisparityEstimator& operator=(DisparityEstimator&& other) noexcept;

  /** \brief Throws planar_grid::Exception, naming the width and the parameter, when
   * images \a width_px pixels wide are not wider than num_disparities_px +
   * |min_disparity_px|: no column of them can be matched, and OpenCV's StereoSGBM
   * (MODE_SGBM_3WAY) aborts the process on them. compute() checks every pair; a
   * caller that knows the width before the first pair (a calibration's image size, a
   * CameraInfo) can refuse it earlier. */
  void checkImageWidth(int width_px) const;

  /** \brief Computes the disparity of the left image.
   * \param[in] left rectified left image, CV_8UC1 or CV_8UC3
   * \param[in] right rectified right image, same size and type
   * \param[out] disparity CV_32FC1, left image size, in pixels of the input images;
   *             pixels without a valid match are NaN
   * \throws planar_grid::Exception when the images are empty or differ in size or type,
   *         or are too small for the block size (BLOCK_MATCHING)
   * \note Colour input is converted to grey first (P1/P2 defaults assume one channel).
   *       With the SGBM modes a textureless region gets min_disparity_px (SGBM's
   *       tie-break), which for the default 0 means "infinitely far" and is dropped by
   *       disparityToPointCloud(); BLOCK_MATCHING marks it NaN (texture threshold).
   * \note The band of num_disparities_px columns at the left edge has no match and is
   *       NaN.
   * \note Not thread-safe on one object: the OpenCV matcher keeps work buffers. With
   *       num_threads > 0 it changes OpenCV's process-wide thread count while it runs,
   *       so other threads should not change it at the same time. */
  void compute(const cv::Mat& left, const cv::Mat& right, cv::Mat& disparity) const;

  /** \brief The parameters in use. */
  const Params& getParams() const { return params_; }

private:
  /** \brief Matches the (possibly downscaled) grey pair into OpenCV's CV_16S disparity
   * (16 * px, invalid below min_disparity * 16). */
  void computeFixedPoint(const cv::Mat& left_grey,
                         const cv::Mat& right_grey,
                         cv::Mat& fixed_point) const;

  /** \brief The parameters as given. */
  Params params_;
  /** \brief cv::StereoSGBM or cv::StereoBM, configured for the matched image scale. */
  cv::Ptr<cv::StereoMatcher> matcher_;
};

} // namespace planar_grid
