// SPDX-License-Identifier: BSD-3-Clause
// The descriptor matching of StereoOdometry between two frames' stereo features: by
// descriptor alone, or among the current features near each previous feature's
// projection by a predicted motion.
#include <planar_grid/core/counting_sort.h>
#include <planar_grid/odometry/stereo_odometry.h>

#include <pcl/console/print.h>

#include <opencv2/core.hpp>
#include <opencv2/core/hal/hal.hpp>
#include <opencv2/features2d.hpp>

#include <algorithm>
#include <cmath>
#include <limits>
#include <vector>

namespace planar_grid {

namespace {

/** \brief True when the two frames' descriptors can be compared (same type and
 * length); otherwise warns, naming \a caller. Empty descriptors are not comparable
 * and not warned about. */
bool
comparableDescriptors(const cv::Mat& previous,
                      const cv::Mat& current,
                      const char* caller)
{
  if (previous.empty() || current.empty())
    return false;
  if (previous.type() == current.type() && previous.cols == current.cols)
    return true;
  PCL_WARN("[planar_grid::StereoOdometry::%s] The two frames' descriptors differ in "
           "type or length; no matches.\n",
           caller);
  return false;
}

/** \brief Lowe's ratio test and the distance bound on a previous feature's best match:
 * \a best and \a second are its best and second-best descriptor distances, \a second
 * infinite when it has a single candidate (which passes the ratio test). */
bool
passesRatioAndDistance(float best, float second, const StereoOdometry::Params& params)
{
  if (std::isfinite(second) && !(best < params.ratio * second))
    return false;
  return !(params.max_descriptor_distance > 0.0
           && best > params.max_descriptor_distance);
}

} // namespace

void
StereoOdometry::matchDescriptors(const StereoFeatures& previous,
                                 const StereoFeatures& current,
                                 std::vector<cv::DMatch>& matches) const
{
  matches.clear();
  if (!comparableDescriptors(previous.descriptors, current.descriptors,
                             "matchDescriptors"))
    return;
  const int norm =
    previous.descriptors.depth() == CV_8U ? cv::NORM_HAMMING : cv::NORM_L2;
  cv::BFMatcher matcher(norm, false);
  std::vector<std::vector<cv::DMatch>> knn;
  matcher.knnMatch(previous.descriptors, current.descriptors, knn, 2);
  std::vector<cv::DMatch> reverse;
  if (params_.mutual_check)
    matcher.match(current.descriptors, previous.descriptors, reverse);

  for (const auto& candidates : knn) {
    if (candidates.empty())
      continue;
    const cv::DMatch& best = candidates[0];
    // A single candidate (the other frame has one feature) passes the ratio test.
    const float second = candidates.size() > 1 ? candidates[1].distance
                                               : std::numeric_limits<float>::infinity();
    if (!passesRatioAndDistance(best.distance, second, params_))
      continue;
    if (params_.mutual_check
        && (best.trainIdx >= static_cast<int>(reverse.size())
            || reverse[static_cast<std::size_t>(best.trainIdx)].trainIdx
                 != best.queryIdx))
      continue;
    matches.push_back(best);
  }
}

void
StereoOdometry::matchDescriptorsProjected(const StereoFeatures& previous,
                                          const StereoFeatures& current,
                                          const Eigen::Isometry3d& current_T_previous,
                                          const StereoCalibration& calibration,
                                          double search_radius_px,
                                          std::vector<cv::DMatch>& matches) const
{
  matches.clear();
  const cv::Mat& query = previous.descriptors;
  const cv::Mat& train = current.descriptors;
  if (!comparableDescriptors(query, train, "matchDescriptorsProjected"))
    return;
  if (!(search_radius_px > 0.0) || !(calibration.focal_length_px > 0.0))
    return;
  const std::size_t n_query =
    std::min(static_cast<std::size_t>(query.rows), previous.points.size());
  const std::size_t n_train =
    std::min(static_cast<std::size_t>(train.rows), current.keypoints_left.size());
  const bool hamming = query.depth() == CV_8U;
  const auto distance = [&](std::size_t i, std::size_t j) {
    if (hamming)
      return static_cast<float>(
        cv::hal::normHamming(query.ptr<uchar>(static_cast<int>(i)),
                             train.ptr<uchar>(static_cast<int>(j)), query.cols));
    return std::sqrt(cv::normL2Sqr<float, float>(query.ptr<float>(static_cast<int>(i)),
                                                 train.ptr<float>(static_cast<int>(j)),
                                                 query.cols));
  };

  // The current key points in square cells of edge search_radius_px (a counting sort,
  // so that each cell lists its features in ascending order): the features within the
  // radius of a projection are in the 3 x 3 cells around it.
  const double cell = search_radius_px;
  float max_u = 0.0f, max_v = 0.0f;
  for (std::size_t j = 0; j < n_train; ++j) {
    max_u = std::max(max_u, current.keypoints_left[j].pt.x);
    max_v = std::max(max_v, current.keypoints_left[j].pt.y);
  }
  const auto cellOf = [cell](double value) {
    return static_cast<long>(std::floor(value / cell));
  };
  const long cols = cellOf(std::max(0.0f, max_u)) + 1;
  const long rows = cellOf(std::max(0.0f, max_v)) + 1;
  std::vector<std::uint32_t> cell_of(n_train);
  for (std::size_t j = 0; j < n_train; ++j) {
    const cv::Point2f& pt = current.keypoints_left[j].pt;
    const long c = std::min(cols - 1, std::max(0L, cellOf(pt.x)));
    const long r = std::min(rows - 1, std::max(0L, cellOf(pt.y)));
    cell_of[j] = static_cast<std::uint32_t>(r * cols + c);
  }
  std::vector<std::uint32_t> start, sorted;
  countingSort(cell_of, static_cast<std::size_t>(cols * rows), start, sorted);

  // One pass over the (previous, current) pairs within the radius: each previous
  // feature's best and second-best candidate, and each current feature's best
  // previous feature (ties go to the lower index, as in a brute-force search).
  constexpr float NONE = std::numeric_limits<float>::max();
  std::vector<float> reverse_distance(n_train, NONE);
  std::vector<std::uint32_t> reverse_best(n_train, 0);
  struct Candidate {
    float best{NONE};
    float second{NONE};
    std::uint32_t train{0};
  };
  std::vector<Candidate> forward(n_query);
  const double radius_sq = search_radius_px * search_radius_px;
  const double f = calibration.focal_length_px;
  for (std::size_t i = 0; i < n_query; ++i) {
    const pcl::PointXYZ& p = previous.points[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Vector3d x = current_T_previous * Eigen::Vector3d(p.x, p.y, p.z);
    if (!(x.z() > 0.0))
      continue; // behind the current camera
    const double u = f * x.x() / x.z() + calibration.cx_px;
    const double v = f * x.y() / x.z() + calibration.cy_px;
    const long c0 = std::max(0L, cellOf(u - search_radius_px));
    const long c1 = std::min(cols - 1, cellOf(u + search_radius_px));
    const long r0 = std::max(0L, cellOf(v - search_radius_px));
    const long r1 = std::min(rows - 1, cellOf(v + search_radius_px));
    Candidate& candidate = forward[i];
    for (long r = r0; r <= r1; ++r)
      for (long c = c0; c <= c1; ++c) {
        const auto k = static_cast<std::size_t>(r * cols + c);
        for (std::uint32_t s = start[k]; s < start[k + 1]; ++s) {
          const std::uint32_t j = sorted[s];
          const cv::Point2f& pt = current.keypoints_left[j].pt;
          const double du = pt.x - u, dv = pt.y - v;
          if (du * du + dv * dv > radius_sq)
            continue;
          const float d = distance(i, j);
          if (d < candidate.best || (d == candidate.best && j < candidate.train)) {
            candidate.second = candidate.best;
            candidate.best = d;
            candidate.train = j;
          } else if (d < candidate.second) {
            candidate.second = d;
          }
          if (d < reverse_distance[j]) {
            reverse_distance[j] = d;
            reverse_best[j] = static_cast<std::uint32_t>(i);
          }
        }
      }
  }

  for (std::size_t i = 0; i < n_query; ++i) {
    const Candidate& candidate = forward[i];
    if (candidate.best == NONE)
      continue;
    // A single candidate passes the ratio test, as in matchDescriptors().
    const float second = candidate.second == NONE
                           ? std::numeric_limits<float>::infinity()
                           : candidate.second;
    if (!passesRatioAndDistance(candidate.best, second, params_))
      continue;
    if (params_.mutual_check && reverse_best[candidate.train] != i)
      continue;
    matches.emplace_back(static_cast<int>(i), static_cast<int>(candidate.train),
                         candidate.best);
  }
}

} // namespace planar_grid
