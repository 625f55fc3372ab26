// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/counting_sort.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>
#include <opencv2/imgproc.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "grey_image.h"

namespace planar_grid {

namespace {

/** \brief Descriptor distance: L2 for SIFT (CV_32F rows), Hamming for ORB (CV_8U). */
float
descriptorDistance(const cv::Mat& a, int row_a, const cv::Mat& b, int row_b)
{
  if (a.type() == CV_32F)
    return std::sqrt(
      cv::hal::normL2Sqr_(a.ptr<float>(row_a), b.ptr<float>(row_b), a.cols));
  return static_cast<float>(cv::hal::normHamming(a.ptr<std::uint8_t>(row_a),
                                                 b.ptr<std::uint8_t>(row_b), a.cols));
}

/** \brief ORB's patch side, px (its default; the descriptor samples within it). */
constexpr int ORB_PATCH_SIZE_PX = 31;

/** \brief Margin without ORB_GRID key points, px: the upright BRIEF pattern reaches 13
 * px from the key point and cv::ORB smooths with a 7x7 Gaussian, so 16 px keeps every
 * sample inside the image. */
constexpr int ORB_GRID_BORDER_PX = 16;

/** \brief The windows and costs of refineRightColumn(), kept from one match to the
 * next so that a frame's matches allocate them once. */
struct RefineScratch {
  cv::Mat left_window, right_strip;
  std::vector<double> cost;
};

/** \brief Sub-pixel column of the right image's match of the left key point \a left_pt
 * (rectified pair, so on the left key point's row): the zero-mean SSD between the
 * window around \a left_pt and the right image's windows at integer shifts
 * -search..+search from column \a right_x, then the vertex of the parabola through the
 * costs at the best shift and its two neighbours. Windows are cut with
 * cv::getRectSubPix (bilinear, border replicated). \return false when the best shift is
 * at the end of the search range, the costs have no strict minimum there, or the best
 * cost exceeds half the left window's zero-mean energy (no reliable sub-pixel match) */
bool
refineRightColumn(const cv::Mat& left,
                  const cv::Mat& right,
                  const cv::Point2f& left_pt,
                  float right_x,
                  int window_px,
                  int search_px,
                  RefineScratch& scratch,
                  float& refined_x)
{
  cv::Mat& left_window = scratch.left_window;
  cv::Mat& right_strip = scratch.right_strip;
  cv::getRectSubPix(left, cv::Size(window_px, window_px), left_pt, left_window, CV_32F);
  cv::getRectSubPix(right, cv::Size(window_px + 2 * search_px, window_px),
                    cv::Point2f(right_x, left_pt.y), right_strip, CV_32F);
  const int shifts = 2 * search_px + 1;
  std::vector<double>& cost = scratch.cost;
  cost.assign(static_cast<std::size_t>(shifts), 0.0);
  const double n = static_cast<double>(window_px) * window_px;
  for (int k = 0; k < shifts; ++k) {
    // Zero-mean SSD = sum (l - r)^2 - n (mean_l - mean_r)^2: robust to a brightness
    // offset between the two cameras.
    double sum_sq = 0.0, sum = 0.0;
    for (int r = 0; r < window_px; ++r) {
      const float* l = left_window.ptr<float>(r);
      const float* q = right_strip.ptr<float>(r) + k;
      for (int c = 0; c < window_px; ++c) {
        const double d = static_cast<double>(l[c]) - q[c];
        sum_sq += d * d;
        sum += d;
      }
    }
    cost[static_cast<std::size_t>(k)] = sum_sq - sum * sum / n;
  }
  const auto best =
    static_cast<int>(std::min_element(cost.begin(), cost.end()) - cost.begin());
  if (best == 0 || best == shifts - 1)
    return false;
  // The windows must agree: a best cost above half the left window's own zero-mean
  // energy (normalised cross-correlation below about 0.75) is a descriptor mismatch
  // or a window without texture, not a sub-pixel match.
  double energy = 0.0, left_sum = 0.0;
  for (int r = 0; r < window_px; ++r) {
    const float* l = left_window.ptr<float>(r);
    for (int c = 0; c < window_px; ++c) {
      energy += static_cast<double>(l[c]) * l[c];
      left_sum += l[c];
    }
  }
  energy -= left_sum * left_sum / n;
  if (!(cost[static_cast<std::size_t>(best)] <= 0.5 * energy))
    return false;
  const double c_minus = cost[static_cast<std::size_t>(best - 1)];
  const double c_0 = cost[static_cast<std::size_t>(best)];
  const double c_plus = cost[static_cast<std::size_t>(best + 1)];
  const double curvature = c_minus - 2.0 * c_0 + c_plus;
  if (!(curvature > 0.0))
    return false;
  const double offset = 0.5 * (c_minus - c_plus) / curvature;
  refined_x = right_x + static_cast<float>(best - search_px + offset);
  return true;
}

} // namespace

FeatureType
featureTypeFromString(const std::string& name)
{
  if (name == "sift")
    return FeatureType::SIFT;
  if (name == "orb")
    return FeatureType::ORB;
  if (name == "orb_grid")
    return FeatureType::ORB_GRID;
  throw Exception("unknown feature type '" + name
                  + "'; known types: sift, orb, orb_grid");
}

const std::vector<std::string>&
featureTypeNames()
{
  static const std::vector<std::string> names{"sift", "orb", "orb_grid"};
  return names;
}

std::string
featureTypeName(FeatureType type)
{
  for (const auto& name : featureTypeNames())
    if (featureTypeFromString(name) == type)
      return name;
  throw Exception("feature type " + std::to_string(static_cast<int>(type))
                  + " has no name");
}

const ParamDeclarations<StereoFeatureMatcher::Params>&
StereoFeatureMatcher::getParamDeclarations()
{
  using P = StereoFeatureMatcher::Params;
  namespace ranges = stereo_feature_matcher_ranges;
  static const ParamDeclarations<P> table = {
    declareChoice<P>(
      "feature_type", [](auto& p) -> auto& { return p.feature_type; },
      featureTypeNames(), featureTypeName, featureTypeFromString,
      "Detector and descriptor: sift (sub-pixel, slow), orb (OpenCV defaults, "
      "quantised disparities), orb_grid (fast front end for the odometry)."),
    declareInteger<P>(
      "max_features", [](auto& p) -> auto& { return p.max_features; },
      ranges::MAX_FEATURES, "",
      "Most key points detected per image (orb_grid: in the left image, spread evenly "
      "over the grid cells; the right image keeps up to twice as many)."),
    declareReal<P>(
      "ratio", [](auto& p) -> auto& { return p.ratio; }, ranges::RATIO, "",
      "Lowe's ratio test: best / second-best distance below this."),
    declareReal<P>(
      "max_row_difference_px", [](auto& p) -> auto& { return p.max_row_difference_px; },
      ranges::MAX_ROW_DIFFERENCE, "px",
      "Largest row difference of a match (rectified images)."),
    declareReal<P>(
      "max_disparity_px", [](auto& p) -> auto& { return p.max_disparity_px; },
      ranges::MAX_DISPARITY, "px", "Largest disparity accepted."),
    declareReal<P>(
      "max_range_m", [](auto& p) -> auto& { return p.max_range_m; }, ranges::MAX_RANGE,
      "m", "Features farther than this are dropped."),
    declareInteger<P>(
      "bucket_size_px", [](auto& p) -> auto& { return p.bucket_size_px; },
      ranges::BUCKET_SIZE, "px",
      "orb_grid: side of the square grid cells; each keeps its strongest FAST corners "
      "(even coverage)."),
    declareInteger<P>(
      "fast_threshold", [](auto& p) -> auto& { return p.fast_threshold; },
      ranges::FAST_THRESHOLD, "grey levels",
      "orb_grid: cv::FAST segment-test threshold (8-bit intensity difference)."),
    declareInteger<P>(
      "subpixel_window_px", [](auto& p) -> auto& { return p.subpixel_window_px; },
      ranges::SUBPIXEL_WINDOW, "px",
      "orb_grid: window side of the sub-pixel disparity refinement (zero-mean SSD "
      "parabola along the row); odd."),
    declareInteger<P>(
      "subpixel_search_px", [](auto& p) -> auto& { return p.subpixel_search_px; },
      ranges::SUBPIXEL_SEARCH, "px",
      "orb_grid: the refinement searches +- this many columns around the matched right "
      "key point; a minimum at the end drops the match."),
  };
  return table;
}

void
detectGridFastKeypoints(const cv::Mat& grey,
                        int bucket_size_px,
                        int max_per_cell,
                        int fast_threshold,
                        int border_px,
                        std::vector<cv::KeyPoint>& keypoints)
{
  keypoints.clear();
  const std::string prefix = "detectGridFastKeypoints: ";
  if (bucket_size_px < 1)
    throw Exception(prefix + "bucket_size_px must be >= 1");
  if (max_per_cell < 1)
    throw Exception(prefix + "max_per_cell must be >= 1");
  if (!stereo_feature_matcher_ranges::FAST_THRESHOLD.contains(fast_threshold))
    throw Exception(prefix
                    + paramRangeMessage("fast_threshold",
                                        stereo_feature_matcher_ranges::FAST_THRESHOLD));
  if (border_px < 0)
    throw Exception(prefix + "border_px must be >= 0");
  if (grey.empty())
    return;
  if (grey.type() != CV_8UC1)
    throw Exception(prefix + "the image must be CV_8UC1");

  // cv::FAST tests no pixel within 3 px of the image's edge, and its non-maximum
  // suppression compares a corner with its 8 neighbours. A corner kept here (at least
  // border_px from the edge) and its neighbours are decided by the pixels within 4 px
  // of it, so cv::FAST over the image less a margin of border_px - 4 px finds the same
  // corners there, with the same scores, in the same order, without testing the
  // margin's pixels.
  const int margin =
    std::max(0, std::min({border_px - 4, (grey.cols - 1) / 2, (grey.rows - 1) / 2}));
  const cv::Rect inner(margin, margin, grey.cols - 2 * margin, grey.rows - 2 * margin);
  std::vector<cv::KeyPoint> corners;
  cv::FAST(grey(inner), corners, fast_threshold, true);
  for (cv::KeyPoint& corner : corners) {
    corner.pt.x += static_cast<float>(margin);
    corner.pt.y += static_cast<float>(margin);
  }
  const int cols = (grey.cols + bucket_size_px - 1) / bucket_size_px;
  const int rows = (grey.rows + bucket_size_px - 1) / bucket_size_px;
  const auto n_cells = static_cast<std::size_t>(cols * rows);
  // The corners sorted into their cells by a counting sort, in cv::FAST's order within
  // each cell: every cell's corners are one range of one array.
  std::vector<std::size_t> cell_of(corners.size(), n_cells); // n_cells: in the border
  for (std::size_t i = 0; i < corners.size(); ++i) {
    const int x = static_cast<int>(corners[i].pt.x);
    const int y = static_cast<int>(corners[i].pt.y);
    if (x < border_px || y < border_px || x >= grey.cols - border_px
        || y >= grey.rows - border_px)
      continue;
    cell_of[i] =
      static_cast<std::size_t>((y / bucket_size_px) * cols + x / bucket_size_px);
  }
  std::vector<std::size_t> cell_begin, in_cells;
  countingSort(cell_of, n_cells, cell_begin, in_cells);
  // Each cell's corners as small records of their response and index in cv::FAST's
  // output (so in cv::FAST's order within each cell).
  struct Ranked {
    float response;
    std::uint32_t index;
  };
  std::vector<Ranked> ranked(in_cells.size());
  for (std::size_t k = 0; k < in_cells.size(); ++k)
    ranked[k] = {corners[in_cells[k]].response,
                 static_cast<std::uint32_t>(in_cells[k])};
  const auto cap = static_cast<std::size_t>(max_per_cell);
  // Each cell's strongest corners, equal responses in cv::FAST's order (so the result
  // is deterministic): the first cap of its corners ordered by response, then by
  // index. That order is total, so selecting the first cap and sorting only those
  // gives them exactly (without a stable sort's temporary buffer and without ordering
  // the cell's weaker corners).
  const auto stronger = [](const Ranked& a, const Ranked& b) {
    return a.response > b.response || (a.response == b.response && a.index < b.index);
  };
  for (std::size_t c = 0; c < n_cells; ++c) {
    const auto first = ranked.begin() + static_cast<std::ptrdiff_t>(cell_begin[c]);
    const auto last = ranked.begin() + static_cast<std::ptrdiff_t>(cell_begin[c + 1]);
    const auto kept =
      first + std::min<std::ptrdiff_t>(last - first, static_cast<std::ptrdiff_t>(cap));
    if (kept != last)
      std::nth_element(first, kept, last, stronger);
    std::sort(first, kept, stronger);
    for (auto it = first; it != kept; ++it) {
      cv::KeyPoint k = corners[it->index];
      k.size = static_cast<float>(ORB_PATCH_SIZE_PX);
      k.angle = 0.0f;
      k.octave = 0;
      k.class_id = -1;
      keypoints.push_back(k);
    }
  }
}

StereoFeatureMatcher::StereoFeatureMatcher() : StereoFeatureMatcher(Params()) {}

StereoFeatureMatcher::StereoFeatureMatcher(const Params& params) : params_(params)
{
  namespace ranges = stereo_feature_matcher_ranges;
  const std::string prefix = "StereoFeatureMatcher: ";
  // \a what: a condition the range cannot say, and whether the value meets it.
  const auto check = [&prefix](const char* name, double value, const ParamRange& range,
                               const char* unit, const char* what = "",
                               bool meets_what = true) {
    if (!meets_what || !range.contains(value))
      throw Exception(prefix + name + " must be " + what + "in "
                      + formatParamRange(range, unit) + ", got "
                      + formatParamNumber(value));
  };
  check("max_features", params_.max_features, ranges::MAX_FEATURES, "");
  check("ratio", params_.ratio, ranges::RATIO, "");
  check("max_row_difference_px", params_.max_row_difference_px,
        ranges::MAX_ROW_DIFFERENCE, "px");
  check("max_disparity_px", params_.max_disparity_px, ranges::MAX_DISPARITY, "px");
  check("max_range_m", params_.max_range_m, ranges::MAX_RANGE, "m");
  check("bucket_size_px", params_.bucket_size_px, ranges::BUCKET_SIZE, "px");
  check("fast_threshold", params_.fast_threshold, ranges::FAST_THRESHOLD, "");
  check("subpixel_window_px", params_.subpixel_window_px, ranges::SUBPIXEL_WINDOW, "px",
        "odd and ", params_.subpixel_window_px % 2 != 0);
  check("subpixel_search_px", params_.subpixel_search_px, ranges::SUBPIXEL_SEARCH,
        "px");
}

namespace {

/** \brief Key points and descriptors of one grey image pair: FAST corners per grid
 * cell with upright one-level ORB descriptors (orb_grid), or the detector's own
 * (SIFT, ORB). */
void
detectAndDescribe(const cv::Mat& grey_left,
                  const cv::Mat& grey_right,
                  const StereoFeatureMatcher::Params& params,
                  std::vector<cv::KeyPoint>& keypoints_left,
                  std::vector<cv::KeyPoint>& keypoints_right,
                  cv::Mat& descriptors_left,
                  cv::Mat& descriptors_right)
{
  if (params.feature_type == FeatureType::ORB_GRID) {
    const int cells =
      ((grey_left.cols + params.bucket_size_px - 1) / params.bucket_size_px)
      * ((grey_left.rows + params.bucket_size_px - 1) / params.bucket_size_px);
    const int per_cell = (params.max_features + cells - 1) / cells;
    // The right image keeps twice as many corners per cell: its cells hold other scene
    // parts than the left ones (disparity), and a left corner whose right twin was cut
    // cannot be matched.
    detectGridFastKeypoints(grey_left, params.bucket_size_px, per_cell,
                            params.fast_threshold, ORB_GRID_BORDER_PX, keypoints_left);
    detectGridFastKeypoints(grey_right, params.bucket_size_px, 2 * per_cell,
                            params.fast_threshold, ORB_GRID_BORDER_PX, keypoints_right);
    // One level, upright (the key points carry angle 0); edgeThreshold = the border
    // above, so cv::ORB drops none of the key points.
    const cv::Ptr<cv::ORB> orb =
      cv::ORB::create(params.max_features, 1.2f, 1, ORB_GRID_BORDER_PX, 0, 2,
                      cv::ORB::HARRIS_SCORE, ORB_PATCH_SIZE_PX, params.fast_threshold);
    orb->compute(grey_left, keypoints_left, descriptors_left);
    orb->compute(grey_right, keypoints_right, descriptors_right);
    return;
  }
  cv::Ptr<cv::Feature2D> detector;
  if (params.feature_type == FeatureType::SIFT)
    detector = cv::SIFT::create(params.max_features);
  else
    detector = cv::ORB::create(params.max_features);
  detector->detectAndCompute(grey_left, cv::noArray(), keypoints_left,
                             descriptors_left);
  detector->detectAndCompute(grey_right, cv::noArray(), keypoints_right,
                             descriptors_right);
}

/** \brief The right key point each left key point keeps (-1: none): the best
 * descriptor on the epipolar band (rows within max_row_difference_px, disparity in
 * (0, max_disparity_px]) that passes Lowe's ratio test, and that no other left key
 * point matches more closely (uniqueness). */
std::vector<int>
epipolarMatches(const std::vector<cv::KeyPoint>& keypoints_left,
                const std::vector<cv::KeyPoint>& keypoints_right,
                const cv::Mat& descriptors_left,
                const cv::Mat& descriptors_right,
                int height,
                const StereoFeatureMatcher::Params& params)
{
  // Right key points bucketed by integer row, so that each left key point only looks at
  // the rows within max_row_difference_px of its own: one array in row order (a
  // counting sort, so each row keeps the key points' order), the coordinates copied
  // beside each index so that the band test reads them in sequence.
  struct RowPoint {
    float x, y;
    int j;
  };
  std::vector<std::size_t> row_of(keypoints_right.size());
  for (std::size_t j = 0; j < keypoints_right.size(); ++j)
    row_of[j] = static_cast<std::size_t>(std::clamp(
      static_cast<int>(std::lround(keypoints_right[j].pt.y)), 0, height - 1));
  std::vector<std::size_t> row_begin, in_rows;
  countingSort(row_of, static_cast<std::size_t>(height), row_begin, in_rows);
  std::vector<RowPoint> by_row(in_rows.size());
  for (std::size_t b = 0; b < in_rows.size(); ++b) {
    const cv::Point2f& pt = keypoints_right[in_rows[b]].pt;
    by_row[b] = {pt.x, pt.y, static_cast<int>(in_rows[b])};
  }
  const float max_dy = static_cast<float>(params.max_row_difference_px);
  const float max_disparity = static_cast<float>(params.max_disparity_px);
  const float ratio = static_cast<float>(params.ratio);
  const float infinity = std::numeric_limits<float>::infinity();
  // Best right match per left key point (-1: none), and the owner of each right key
  // point (uniqueness: the left key point with the smallest distance keeps it).
  std::vector<int> match_of_left(keypoints_left.size(), -1);
  std::vector<int> owner_of_right(keypoints_right.size(), -1);
  std::vector<float> owner_distance(keypoints_right.size(), infinity);
  for (std::size_t i = 0; i < keypoints_left.size(); ++i) {
    const cv::Point2f& pl = keypoints_left[i].pt;
    const int first_row = std::max(0, static_cast<int>(std::floor(pl.y - max_dy)) - 1);
    const int last_row =
      std::min(height - 1, static_cast<int>(std::ceil(pl.y + max_dy)) + 1);
    float best = infinity, second = infinity;
    int best_j = -1;
    // The rows first_row .. last_row are one range of by_row, in row order.
    const std::size_t band_begin =
      first_row <= last_row ? row_begin[static_cast<std::size_t>(first_row)] : 0;
    const std::size_t band_end =
      first_row <= last_row ? row_begin[static_cast<std::size_t>(last_row) + 1] : 0;
    for (std::size_t b = band_begin; b < band_end; ++b) {
      const RowPoint& pr = by_row[b];
      const float disparity = pl.x - pr.x;
      if (std::abs(pl.y - pr.y) > max_dy || !(disparity > 0.0f)
          || disparity > max_disparity)
        continue;
      const float distance = descriptorDistance(descriptors_left, static_cast<int>(i),
                                                descriptors_right, pr.j);
      if (distance < best) {
        second = best;
        best = distance;
        best_j = pr.j;
      } else if (distance < second) {
        second = distance;
      }
    }
    // Lowe's ratio test; a single candidate on the epipolar band passes (second = inf).
    if (best_j < 0 || !(best < ratio * second))
      continue;
    match_of_left[i] = best_j;
    const std::size_t j = static_cast<std::size_t>(best_j);
    if (best < owner_distance[j]) {
      owner_distance[j] = best;
      owner_of_right[j] = static_cast<int>(i);
    }
  }
  for (std::size_t i = 0; i < keypoints_left.size(); ++i) {
    const int j = match_of_left[i];
    if (j >= 0 && owner_of_right[static_cast<std::size_t>(j)] != static_cast<int>(i))
      match_of_left[i] = -1;
  }
  return match_of_left;
}

} // namespace

void
StereoFeatureMatcher::match(const cv::Mat& left,
                            const cv::Mat& right,
                            const StereoCalibration& calibration,
                            StereoFeatures& features) const
{
  features = StereoFeatures();
  if (left.empty() || right.empty())
    throw Exception("StereoFeatureMatcher::match: empty input image");
  if (left.size() != right.size())
    throw Exception("StereoFeatureMatcher::match: the left and right images differ in "
                    "size");
  if ((left.type() != CV_8UC1 && left.type() != CV_8UC3) || left.type() != right.type())
    throw Exception("StereoFeatureMatcher::match: images must both be CV_8UC1 or both "
                    "CV_8UC3");
  calibration.validate("StereoFeatureMatcher::match");

  const cv::Mat grey_left = detail::toGrey(left);
  const cv::Mat grey_right = detail::toGrey(right);
  std::vector<cv::KeyPoint> keypoints_left, keypoints_right;
  cv::Mat descriptors_left, descriptors_right;
  detectAndDescribe(grey_left, grey_right, params_, keypoints_left, keypoints_right,
                    descriptors_left, descriptors_right);
  if (keypoints_left.empty() || keypoints_right.empty())
    return;
  const std::vector<int> match_of_left =
    epipolarMatches(keypoints_left, keypoints_right, descriptors_left,
                    descriptors_right, left.rows, params_);

  // The matches triangulated (orb_grid: the right column refined to sub-pixel first)
  // within max_disparity_px and max_range_m.
  const bool grid = params_.feature_type == FeatureType::ORB_GRID;
  const double f = calibration.focal_length_px;
  const double fb = f * calibration.baseline_m;
  const double max_range_sq = params_.max_range_m * params_.max_range_m;
  std::vector<int> kept;
  kept.reserve(keypoints_left.size());
  RefineScratch scratch;
  for (std::size_t i = 0; i < keypoints_left.size(); ++i) {
    const int j = match_of_left[i];
    if (j < 0)
      continue;
    const cv::KeyPoint& kl = keypoints_left[i];
    cv::KeyPoint kr = keypoints_right[static_cast<std::size_t>(j)];
    if (grid) {
      float refined_x = 0.0f;
      if (!refineRightColumn(grey_left, grey_right, kl.pt, kr.pt.x,
                             params_.subpixel_window_px, params_.subpixel_search_px,
                             scratch, refined_x))
        continue;
      kr.pt = cv::Point2f(refined_x, kl.pt.y);
    }
    const double disparity = static_cast<double>(kl.pt.x) - kr.pt.x;
    if (!(disparity > 0.0) || disparity > params_.max_disparity_px)
      continue;
    const double z = fb / disparity;
    const double x = (kl.pt.x - calibration.cx_px) * z / f;
    const double y = (kl.pt.y - calibration.cy_px) * z / f;
    if (x * x + y * y + z * z > max_range_sq)
      continue;
    kept.push_back(static_cast<int>(i));
    features.points.push_back(pcl::PointXYZ(
      static_cast<float>(x), static_cast<float>(y), static_cast<float>(z)));
    features.keypoints_left.push_back(kl);
    features.keypoints_right.push_back(kr);
    features.disparities.push_back(static_cast<float>(disparity));
  }

  features.descriptors.create(static_cast<int>(kept.size()), descriptors_left.cols,
                              descriptors_left.type());
  for (std::size_t k = 0; k < kept.size(); ++k)
    descriptors_left.row(kept[k]).copyTo(features.descriptors.row(static_cast<int>(k)));
  features.points.width = static_cast<std::uint32_t>(features.points.size());
  features.points.height = 1;
  features.points.is_dense = true;
}

namespace {

void
putKeypoints(ByteWriter& w, const std::vector<cv::KeyPoint>& keypoints)
{
  w.put(static_cast<std::uint64_t>(keypoints.size()));
  for (const auto& k : keypoints) {
    w.put(k.pt.x);
    w.put(k.pt.y);
    w.put(k.size);
    w.put(k.angle);
    w.put(k.response);
    w.put(static_cast<std::int32_t>(k.octave));
    w.put(static_cast<std::int32_t>(k.class_id));
  }
}

void
getKeypoints(ByteReader& r, std::vector<cv::KeyPoint>& keypoints)
{
  keypoints.resize(r.getCount(7 * 4, "keypoint"));
  for (auto& k : keypoints) {
    k.pt.x = r.get<float>();
    k.pt.y = r.get<float>();
    k.size = r.get<float>();
    k.angle = r.get<float>();
    k.response = r.get<float>();
    k.octave = r.get<std::int32_t>();
    k.class_id = r.get<std::int32_t>();
  }
}

} // namespace

void
putStereoFeatures(ByteWriter& w, const StereoFeatures& f)
{
  w.put(static_cast<std::uint64_t>(f.points.size()));
  for (const auto& p : f.points) {
    w.put(p.x);
    w.put(p.y);
    w.put(p.z);
  }
  putKeypoints(w, f.keypoints_left);
  putKeypoints(w, f.keypoints_right);
  w.putVector(f.disparities);
  const cv::Mat d =
    f.descriptors.isContinuous() ? f.descriptors : f.descriptors.clone();
  w.put(static_cast<std::int32_t>(d.rows));
  w.put(static_cast<std::int32_t>(d.cols));
  w.put(static_cast<std::int32_t>(d.type()));
  w.putBytes(d.data, d.empty() ? 0 : d.total() * d.elemSize());
}

void
getStereoFeatures(ByteReader& r, StereoFeatures& f)
{
  f = StereoFeatures();
  const std::size_t n = r.getCount(3 * 4, "feature point");
  f.points.resize(n);
  for (auto& p : f.points) {
    p.x = r.get<float>();
    p.y = r.get<float>();
    p.z = r.get<float>();
  }
  getKeypoints(r, f.keypoints_left);
  getKeypoints(r, f.keypoints_right);
  r.getVector(f.disparities, "disparity");
  const auto rows = r.get<std::int32_t>();
  const auto cols = r.get<std::int32_t>();
  const auto type = r.get<std::int32_t>();
  std::size_t size = 0;
  const std::uint8_t* data = r.getBytes(size, "descriptor");
  if (rows < 0 || cols < 0 || (type != CV_8U && type != CV_32F))
    r.fail("invalid descriptor matrix");
  const std::size_t element = type == CV_8U ? 1 : 4;
  if (size != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols) * element)
    r.fail("descriptor bytes do not match their size");
  if (rows > 0 && cols > 0)
    cv::Mat(rows, cols, type, const_cast<std::uint8_t*>(data)).copyTo(f.descriptors);
  if (f.keypoints_left.size() != n || f.descriptors.rows != static_cast<int>(n))
    r.fail("feature arrays of different lengths");
}

} // namespace planar_grid
