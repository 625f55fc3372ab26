// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/disparity_estimator.h>

#include <opencv2/calib3d.hpp>
#include <opencv2/core/utility.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>

#include "grey_image.h"

namespace planar_grid {

namespace {

const std::string ALGORITHM_NAMES =
  "sgbm, sgbm_3way, sgbm_hh, sgbm_hh4, block_matching";

/** \brief SGBM's smoothness penalties for one grey channel: OpenCV's recommended
 * 8 * block^2 and 32 * block^2 unless set. */
int
effectiveP1(const DisparityEstimator::Params& params)
{
  return params.p1 > 0 ? params.p1 : 8 * params.block_size_px * params.block_size_px;
}

int
effectiveP2(const DisparityEstimator::Params& params)
{
  return params.p2 > 0 ? params.p2 : 32 * params.block_size_px * params.block_size_px;
}

/** \brief A length along the disparity axis at the matched scale: \a value_px / \a
 * downscale rounded up, so that a tolerance never shrinks to 0; negative values (a
 * disabled check) stay negative. */
int
scaledTolerance(int value_px, int downscale)
{
  if (value_px <= 0)
    return value_px;
  return (value_px + downscale - 1) / downscale;
}

bool
isOdd(int value)
{
  return value % 2 != 0;
}

/** The message of a parameter outside its declared range (with \a what, the
 * conditions a range cannot say, before it), with the value given. */
std::string
outOfRange(const std::string& name,
           const ParamRange& range,
           int value,
           const char* what)
{
  return name + " must be " + what + "in " + formatParamRange(range) + ", got "
         + std::to_string(value);
}

void
validateParams(const DisparityEstimator::Params& params)
{
  namespace ranges = disparity_estimator_ranges;
  const std::string prefix = "DisparityEstimator: ";
  // \a odd: whether the value meets the condition \a what says beside the range.
  const auto check = [&prefix](const char* name, int value, const ParamRange& range,
                               const char* what, bool odd = true) {
    if (!odd || !range.contains(value))
      throw Exception(prefix + outOfRange(name, range, value, what));
  };
  check("downscale", params.downscale, ranges::DOWNSCALE, "");
  check("row_downscale", params.row_downscale, ranges::ROW_DOWNSCALE, "");
  if (params.row_downscale == 2 && params.downscale != 1)
    throw Exception(prefix
                    + "row_downscale 2 needs downscale 1 (downscale 2 already "
                      "halves the rows)");
  check("num_threads", params.num_threads, ranges::NUM_THREADS, "");
  const int disparity_step = 16 * params.downscale;
  check("num_disparities_px", params.num_disparities_px, ranges::NUM_DISPARITIES, "");
  if (params.num_disparities_px % disparity_step != 0)
    throw Exception(prefix + "num_disparities_px must be a multiple of "
                    + std::to_string(disparity_step) + " (16 * downscale), got "
                    + std::to_string(params.num_disparities_px));
  check("min_disparity_px", params.min_disparity_px, ranges::MIN_DISPARITY, "");
  if (params.min_disparity_px % params.downscale != 0)
    throw Exception(prefix + "min_disparity_px must be a multiple of downscale, got "
                    + std::to_string(params.min_disparity_px));
  check("uniqueness_ratio_percent", params.uniqueness_ratio_percent,
        ranges::UNIQUENESS_RATIO, "");
  check("speckle_window_size_px", params.speckle_window_size_px,
        ranges::SPECKLE_WINDOW_SIZE, "");
  check("speckle_range_px", params.speckle_range_px, ranges::SPECKLE_RANGE, "");
  check("disp12_max_diff_px", params.disp12_max_diff_px, ranges::DISP12_MAX_DIFF, "");
  if (params.full_dp && params.algorithm != DisparityAlgorithm::SGBM)
    throw Exception(prefix
                    + "full_dp is the legacy spelling of algorithm sgbm_hh and "
                      "is only valid with algorithm sgbm, not "
                    + toString(params.algorithm));

  if (params.algorithm == DisparityAlgorithm::BLOCK_MATCHING) {
    // Above block 21 or pre-filter cap 31 OpenCV 4.6's StereoBM leaves its SIMD path
    // for a generic one whose output changes from run to run (measured on Karlsruhe:
    // up to ~100 pixels differ between two identical calls).
    check("block_size_px", params.block_size_px, ranges::BLOCK_SIZE_BLOCK_MATCHING,
          "odd and ", isOdd(params.block_size_px));
    check("bm_pre_filter_cap", params.bm_pre_filter_cap, ranges::BM_PRE_FILTER_CAP, "");
    check("bm_pre_filter_size_px", params.bm_pre_filter_size_px,
          ranges::BM_PRE_FILTER_SIZE, "odd and ", isOdd(params.bm_pre_filter_size_px));
    check("bm_texture_threshold", params.bm_texture_threshold,
          ranges::BM_TEXTURE_THRESHOLD, "");
    return;
  }
  check("block_size_px", params.block_size_px, ranges::BLOCK_SIZE_SGBM, "odd and ",
        isOdd(params.block_size_px));
  check("pre_filter_cap", params.pre_filter_cap, ranges::PRE_FILTER_CAP, "");
  check("p1", params.p1, ranges::P1, "");
  check("p2", params.p2, ranges::P2, "");
  if (effectiveP2(params) <= effectiveP1(params))
    throw Exception(prefix + "p2 (" + std::to_string(effectiveP2(params))
                    + ") must be greater than p1 ("
                    + std::to_string(effectiveP1(params)) + ")");
}

int
sgbmMode(const DisparityEstimator::Params& params)
{
  switch (params.algorithm) {
    case DisparityAlgorithm::SGBM_3WAY:
      return cv::StereoSGBM::MODE_SGBM_3WAY;
    case DisparityAlgorithm::SGBM_HH:
      return cv::StereoSGBM::MODE_HH;
    case DisparityAlgorithm::SGBM_HH4:
      return cv::StereoSGBM::MODE_HH4;
    default:
      return params.full_dp ? cv::StereoSGBM::MODE_HH : cv::StereoSGBM::MODE_SGBM;
  }
}

/** \brief Sets OpenCV's process-wide thread count for one scope and restores it; no-op
 * for 0 or when the count is already the requested one (re-creating OpenCV's thread
 * pool is not free). */
class ScopedOpenCVThreads {
public:
  explicit ScopedOpenCVThreads(int num_threads)
  {
    if (num_threads <= 0)
      return;
    const int current = cv::getNumThreads();
    if (current == num_threads)
      return;
    previous_ = current;
    cv::setNumThreads(num_threads);
  }
  ~ScopedOpenCVThreads()
  {
    if (previous_ > 0)
      cv::setNumThreads(previous_);
  }
  ScopedOpenCVThreads(const ScopedOpenCVThreads&) = delete;
  ScopedOpenCVThreads& operator=(const ScopedOpenCVThreads&) = delete;

private:
  int previous_{0};
};

/** \brief OpenCV's CV_16S fixed-point disparity (16 * px, values below
 * min_disparity * 16 invalid) as px times \a scale, NaN where invalid. */
void
fixedPointToFloat(const cv::Mat& fixed_point,
                  int min_disparity_px,
                  float scale,
                  cv::Mat& disparity)
{
  const int min_valid = min_disparity_px * 16;
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const float factor = scale / 16.0f;
  disparity.create(fixed_point.size(), CV_32FC1);
  for (int v = 0; v < fixed_point.rows; ++v) {
    const short* in = fixed_point.ptr<short>(v);
    float* out = disparity.ptr<float>(v);
    for (int u = 0; u < fixed_point.cols; ++u)
      out[u] = in[u] < min_valid ? nan : static_cast<float>(in[u]) * factor;
  }
}

/** \brief \a image in grey, shrunk by exactly 2 in its rows (and in its columns when \a
 * columns): an odd side is padded by one replicated pixel first, so that input pixel u
 * lies in shrunk pixel u / 2; cv::resize with INTER_AREA (each shrunk pixel the mean of
 * the input pixels it covers). */
cv::Mat
shrinkByTwo(const cv::Mat& image, bool columns)
{
  cv::Mat grey = detail::toGrey(image);
  const int pad_bottom = grey.rows % 2;
  const int pad_right = columns ? grey.cols % 2 : 0;
  if (pad_right != 0 || pad_bottom != 0)
    cv::copyMakeBorder(grey, grey, 0, pad_bottom, 0, pad_right, cv::BORDER_REPLICATE);
  cv::Mat half;
  cv::resize(grey, half, cv::Size(columns ? grey.cols / 2 : grey.cols, grey.rows / 2),
             0.0, 0.0, cv::INTER_AREA);
  return half;
}

/** \brief The half rows around row v of an image twice as tall as \a half: row v sits
 * at half-row coordinate v / 2 - 0.25, between \a before and \a after (clamped at the
 * borders) with \a weight on \a after, inside \a containing. */
struct HalfRows {
  const float* before;
  const float* after;
  const float* containing;
  float weight;
};

HalfRows
halfRowsOf(const cv::Mat& half, int v)
{
  // v even: between half rows v/2 - 1 and v/2, weight 0.75 on the later; v odd:
  // between (v-1)/2 and (v+1)/2, weight 0.25 on the later.
  const int last_row = half.rows - 1;
  const int y0 = (v % 2 == 0) ? v / 2 - 1 : v / 2;
  return {half.ptr<float>(std::clamp(y0, 0, last_row)),
          half.ptr<float>(std::clamp(y0 + 1, 0, last_row)),
          half.ptr<float>(std::min(v / 2, last_row)), (v % 2 == 0) ? 0.75f : 0.25f};
}

/** \brief Upsamples a half-resolution disparity image (already in full-resolution px)
 * by exactly 2 into \a full (size \a full_size, at most twice \a half's).
 *
 * Full pixel u sits at half-resolution coordinate u / 2 - 0.25 (pixel centres). It is
 * interpolated bilinearly when its four half-resolution neighbours are valid and span
 * at most 2 px (a smooth surface); otherwise it takes the half-resolution pixel that
 * contains it, so that depth edges stay sharp and NaN does not spread. */
void
upsampleDisparity(const cv::Mat& half, const cv::Size& full_size, cv::Mat& full)
{
  const float max_span_px = 2.0f;
  full.create(full_size, CV_32FC1);
  const int last_col = half.cols - 1;
  for (int v = 0; v < full.rows; ++v) {
    const HalfRows rows = halfRowsOf(half, v);
    const float wy = rows.weight;
    const float* row0 = rows.before;
    const float* row1 = rows.after;
    const float* nearest_row = rows.containing;
    float* out = full.ptr<float>(v);
    for (int u = 0; u < full.cols; ++u) {
      const int x0 = (u % 2 == 0) ? u / 2 - 1 : u / 2;
      const float wx = (u % 2 == 0) ? 0.75f : 0.25f;
      const int xa = std::clamp(x0, 0, last_col);
      const int xb = std::clamp(x0 + 1, 0, last_col);
      const float d00 = row0[xa], d01 = row0[xb], d10 = row1[xa], d11 = row1[xb];
      const bool all_valid =
        !std::isnan(d00) && !std::isnan(d01) && !std::isnan(d10) && !std::isnan(d11);
      const float lo = std::min(std::min(d00, d01), std::min(d10, d11));
      const float hi = std::max(std::max(d00, d01), std::max(d10, d11));
      if (all_valid && hi - lo <= max_span_px)
        out[u] = (1.0f - wy) * ((1.0f - wx) * d00 + wx * d01)
                 + wy * ((1.0f - wx) * d10 + wx * d11);
      else
        out[u] = nearest_row[std::min(u / 2, last_col)];
    }
  }
}

/** \brief Brings a disparity image matched on half the rows back to \a rows rows (at
 * most twice \a half's).
 *
 * Input row v sits at half-row coordinate v / 2 - 0.25. It is interpolated linearly
 * between the two nearest half rows when both are valid and differ by at most 2 px
 * (a smooth surface: the road's disparity grows about 0.36 px per input row on
 * Karlsruhe); otherwise it takes the half row that contains it, so that depth edges
 * stay sharp and NaN does not spread. */
void
upsampleDisparityRows(const cv::Mat& half, int rows, cv::Mat& full)
{
  const float max_span_px = 2.0f;
  full.create(rows, half.cols, CV_32FC1);
  for (int v = 0; v < rows; ++v) {
    const HalfRows near = halfRowsOf(half, v);
    float* out = full.ptr<float>(v);
    for (int u = 0; u < half.cols; ++u) {
      const float d0 = near.before[u], d1 = near.after[u];
      // NaN fails the comparison, so an invalid neighbour takes the nearest row.
      if (std::abs(d1 - d0) <= max_span_px)
        out[u] = (1.0f - near.weight) * d0 + near.weight * d1;
      else
        out[u] = near.containing[u];
    }
  }
}

} // namespace

DisparityAlgorithm
disparityAlgorithmFromString(const std::string& name)
{
  if (name == "sgbm")
    return DisparityAlgorithm::SGBM;
  if (name == "sgbm_3way")
    return DisparityAlgorithm::SGBM_3WAY;
  if (name == "sgbm_hh")
    return DisparityAlgorithm::SGBM_HH;
  if (name == "sgbm_hh4")
    return DisparityAlgorithm::SGBM_HH4;
  if (name == "block_matching")
    return DisparityAlgorithm::BLOCK_MATCHING;
  throw Exception("unknown disparity algorithm '" + name
                  + "'; known algorithms: " + ALGORITHM_NAMES);
}

std::string
toString(DisparityAlgorithm algorithm)
{
  switch (algorithm) {
    case DisparityAlgorithm::SGBM:
      return "sgbm";
    case DisparityAlgorithm::SGBM_3WAY:
      return "sgbm_3way";
    case DisparityAlgorithm::SGBM_HH:
      return "sgbm_hh";
    case DisparityAlgorithm::SGBM_HH4:
      return "sgbm_hh4";
    case DisparityAlgorithm::BLOCK_MATCHING:
      return "block_matching";
  }
  return "sgbm";
}

BlockMatchingPreFilter
blockMatchingPreFilterFromString(const std::string& name)
{
  if (name == "xsobel")
    return BlockMatchingPreFilter::XSOBEL;
  if (name == "normalized_response")
    return BlockMatchingPreFilter::NORMALIZED_RESPONSE;
  throw Exception("unknown block matching pre-filter '" + name
                  + "'; known pre-filters: xsobel, normalized_response");
}

std::string
toString(BlockMatchingPreFilter pre_filter)
{
  return pre_filter == BlockMatchingPreFilter::XSOBEL ? "xsobel"
                                                      : "normalized_response";
}

DisparityEstimator::DisparityEstimator() : DisparityEstimator(Params()) {}

DisparityEstimator::DisparityEstimator(const Params& params) : params_(params)
{
  validateParams(params_);
  // The matcher works at the matched scale: disparities, disparity tolerances and the
  // speckle area shrink with the image; block and pre-filter windows are in matched
  // pixels by definition.
  const int s = params_.downscale;
  const int min_disparity = params_.min_disparity_px / s;
  const int num_disparities = params_.num_disparities_px / s;
  const int disp12_max_diff = scaledTolerance(params_.disp12_max_diff_px, s);
  const int speckle_window =
    params_.speckle_window_size_px / (s * s * params_.row_downscale);
  const int speckle_range = scaledTolerance(params_.speckle_range_px, s);
  if (params_.algorithm == DisparityAlgorithm::BLOCK_MATCHING) {
    cv::Ptr<cv::StereoBM> bm =
      cv::StereoBM::create(num_disparities, params_.block_size_px);
    bm->setMinDisparity(min_disparity);
    bm->setPreFilterType(params_.bm_pre_filter == BlockMatchingPreFilter::XSOBEL
                           ? cv::StereoBM::PREFILTER_XSOBEL
                           : cv::StereoBM::PREFILTER_NORMALIZED_RESPONSE);
    bm->setPreFilterSize(params_.bm_pre_filter_size_px);
    bm->setPreFilterCap(params_.bm_pre_filter_cap);
    bm->setTextureThreshold(params_.bm_texture_threshold);
    bm->setUniquenessRatio(params_.uniqueness_ratio_percent);
    bm->setDisp12MaxDiff(disp12_max_diff);
    bm->setSpeckleWindowSize(speckle_window);
    bm->setSpeckleRange(speckle_range);
    matcher_ = bm;
  } else {
    matcher_ = cv::StereoSGBM::create(
      min_disparity, num_disparities, params_.block_size_px, effectiveP1(params_),
      effectiveP2(params_), disp12_max_diff, params_.pre_filter_cap,
      params_.uniqueness_ratio_percent, speckle_window, speckle_range,
      sgbmMode(params_));
  }
}

void
DisparityEstimator::checkImageWidth(int width_px) const
{
  // At the matched scale (downscale 2 pads an odd width by one pixel).
  const int s = params_.downscale;
  const int matched_width = (width_px + s - 1) / s;
  const int range =
    params_.num_disparities_px / s + std::abs(params_.min_disparity_px / s);
  if (matched_width <= range)
    throw Exception("DisparityEstimator: the images are " + std::to_string(width_px)
                    + " px wide, not wider than num_disparities_px ("
                    + std::to_string(params_.num_disparities_px)
                    + ") + |min_disparity_px| ("
                    + std::to_string(std::abs(params_.min_disparity_px))
                    + "): no column can be matched (OpenCV's StereoSGBM aborts on such "
                      "images); lower num_disparities_px below the width");
}

DisparityEstimator::~DisparityEstimator() = default;
DisparityEstimator::DisparityEstimator(DisparityEstimator&&) noexcept = default;
DisparityEstimator&
DisparityEstimator::operator=(DisparityEstimator&&) noexcept = default;

void
DisparityEstimator::computeFixedPoint(const cv::Mat& left_grey,
                                      const cv::Mat& right_grey,
                                      cv::Mat& fixed_point) const
{
  if (params_.algorithm == DisparityAlgorithm::BLOCK_MATCHING
      && std::min(left_grey.rows, left_grey.cols) < params_.block_size_px)
    throw Exception("DisparityEstimator::compute: the "
                    + std::string(params_.downscale == 2 ? "downscaled " : "")
                    + "images are smaller than block_size_px");
  const ScopedOpenCVThreads threads(params_.num_threads);
  matcher_->compute(left_grey, right_grey, fixed_point);
}

void
DisparityEstimator::compute(const cv::Mat& left,
                            const cv::Mat& right,
                            cv::Mat& disparity) const
{
  if (left.empty() || right.empty())
    throw Exception("DisparityEstimator::compute: empty input image");
  if (left.size() != right.size())
    throw Exception("DisparityEstimator::compute: the left and right images differ in "
                    "size");
  if (left.type() != right.type())
    throw Exception("DisparityEstimator::compute: the left and right images differ in "
                    "type");
  if (left.type() != CV_8UC1 && left.type() != CV_8UC3)
    throw Exception("DisparityEstimator::compute: images must be CV_8UC1 or CV_8UC3");
  checkImageWidth(left.cols);

  cv::Mat fixed_point; // CV_16S, disparity * 16
  if (params_.row_downscale == 2) {
    // Half the rows: pad an odd row count by one replicated row so that input row v
    // is in half row v / 2, match, bring the rows back and crop the padding.
    computeFixedPoint(shrinkByTwo(left, false), shrinkByTwo(right, false), fixed_point);
    cv::Mat half_disparity;
    fixedPointToFloat(fixed_point, params_.min_disparity_px, 1.0f, half_disparity);
    cv::Mat padded;
    upsampleDisparityRows(half_disparity, 2 * fixed_point.rows, padded);
    padded(cv::Rect(0, 0, left.cols, left.rows)).copyTo(disparity);
    return;
  }
  if (params_.downscale == 1) {
    computeFixedPoint(detail::toGrey(left), detail::toGrey(right), fixed_point);
    fixedPointToFloat(fixed_point, params_.min_disparity_px, 1.0f, disparity);
    return;
  }

  // Half resolution: pad an odd side by one replicated pixel so that the shrink is
  // exactly 2 (pixel u of the input covers half pixel u / 2), match, convert to input
  // pixels (x 2), upsample and crop the padding.
  computeFixedPoint(shrinkByTwo(left, true), shrinkByTwo(right, true), fixed_point);
  cv::Mat half_disparity;
  fixedPointToFloat(fixed_point, params_.min_disparity_px / 2, 2.0f, half_disparity);
  cv::Mat padded;
  upsampleDisparity(half_disparity,
                    cv::Size(2 * fixed_point.cols, 2 * fixed_point.rows), padded);
  padded(cv::Rect(0, 0, left.cols, left.rows)).copyTo(disparity);
}

const ParamDeclarations<DisparityEstimator::Params>&
DisparityEstimator::getParamDeclarations()
{
  using P = DisparityEstimator::Params;
  namespace ranges = disparity_estimator_ranges;
  const auto algorithm_name = [](DisparityAlgorithm a) {
    return toString(a);
  };
  const auto pre_filter_name = [](BlockMatchingPreFilter f) {
    return toString(f);
  };
  static const ParamDeclarations<P> table = {
    declareChoice<P>(
      "algorithm", [](auto& p) -> auto& { return p.algorithm; },
      {"sgbm", "sgbm_3way", "sgbm_hh", "sgbm_hh4", "block_matching"}, algorithm_name,
      disparityAlgorithmFromString,
      "OpenCV matcher: StereoSGBM 5-path (single-threaded), 3-way (parallel), 8-path, "
      "4-path, or StereoBM (local SAD, parallel)."),
    declareInteger<P>(
      "downscale", [](auto& p) -> auto& { return p.downscale; }, ranges::DOWNSCALE, "",
      "Image scale divisor: 2 matches half-resolution images; the output stays full "
      "resolution, in full-resolution px."),
    declareInteger<P>(
      "row_downscale", [](auto& p) -> auto& { return p.row_downscale; },
      ranges::ROW_DOWNSCALE, "",
      "Row divisor (with downscale 1): 2 matches the images at half their rows and "
      "full width, so disparities keep their 1/16 px step at half the matching cost; "
      "the output stays full size."),
    declareInteger<P>(
      "num_threads", [](auto& p) -> auto& { return p.num_threads; },
      ranges::NUM_THREADS, "",
      "OpenCV threads for the whole run (OpenCV's setting is process-wide: every "
      "stage's OpenCV calls use it), set before the first frame and restored after the "
      "last; speed only, never the result; 0 = leave OpenCV's setting."),
    declareInteger<P>(
      "min_disparity_px", [](auto& p) -> auto& { return p.min_disparity_px; },
      ranges::MIN_DISPARITY, "px",
      "Smallest disparity searched; a multiple of downscale."),
    declareInteger<P>(
      "num_disparities_px", [](auto& p) -> auto& { return p.num_disparities_px; },
      ranges::NUM_DISPARITIES, "px",
      "Number of disparities searched; a multiple of 16 * downscale."),
    declareInteger<P>(
      "block_size_px", [](auto& p) -> auto& { return p.block_size_px; },
      ranges::BLOCK_SIZE, "px",
      "Matched block side in matched-image px; odd, 1..11 for the SGBM modes, 5..21 "
      "for block_matching."),
    declareInteger<P>(
      "p1", [](auto& p) -> auto& { return p.p1; }, ranges::P1, "",
      "SGBM penalty for 1 px disparity changes; 0 = 8*channels*block^2."),
    declareInteger<P>(
      "p2", [](auto& p) -> auto& { return p.p2; }, ranges::P2, "",
      "SGBM penalty for larger changes; 0 = 32*channels*block^2."),
    declareInteger<P>(
      "disp12_max_diff_px", [](auto& p) -> auto& { return p.disp12_max_diff_px; },
      ranges::DISP12_MAX_DIFF, "px",
      "Left-right consistency tolerance; -1 disables the check."),
    declareInteger<P>(
      "pre_filter_cap", [](auto& p) -> auto& { return p.pre_filter_cap; },
      ranges::PRE_FILTER_CAP, "", "SGBM modes: clip of the x-derivative pre-filter."),
    declareInteger<P>(
      "uniqueness_ratio_percent",
      [](auto& p) -> auto& { return p.uniqueness_ratio_percent; },
      ranges::UNIQUENESS_RATIO, "percent", "Margin by which the best cost must win."),
    declareInteger<P>(
      "speckle_window_size_px",
      [](auto& p) -> auto& { return p.speckle_window_size_px; },
      ranges::SPECKLE_WINDOW_SIZE, "px",
      "Largest speckle region removed as noise; 0 disables."),
    declareInteger<P>(
      "speckle_range_px", [](auto& p) -> auto& { return p.speckle_range_px; },
      ranges::SPECKLE_RANGE, "px",
      "Largest disparity variation inside a speckle component."),
    declareFlag<P>(
      "full_dp", [](auto& p) -> auto& { return p.full_dp; },
      "Legacy: true = algorithm sgbm_hh (only with algorithm sgbm)."),
    declareChoice<P>(
      "bm_pre_filter", [](auto& p) -> auto& { return p.bm_pre_filter; },
      {"xsobel", "normalized_response"}, pre_filter_name,
      blockMatchingPreFilterFromString, "block_matching: pre-filter of both images."),
    declareInteger<P>(
      "bm_pre_filter_cap", [](auto& p) -> auto& { return p.bm_pre_filter_cap; },
      ranges::BM_PRE_FILTER_CAP, "",
      "block_matching: clip of the pre-filter output (above 31 OpenCV 4.6's StereoBM "
      "is not repeatable)."),
    declareInteger<P>(
      "bm_pre_filter_size_px", [](auto& p) -> auto& { return p.bm_pre_filter_size_px; },
      ranges::BM_PRE_FILTER_SIZE, "px",
      "block_matching: normalized_response window side; odd."),
    declareInteger<P>(
      "bm_texture_threshold", [](auto& p) -> auto& { return p.bm_texture_threshold; },
      ranges::BM_TEXTURE_THRESHOLD, "",
      "block_matching: blocks with less pre-filtered texture (sum of absolute values) "
      "are invalid; 0 disables."),
  };
  return table;
}

} // namespace planar_grid
