// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/odometry/stereo_odometry.h>
#include <planar_grid/stereo/calibration_io.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <functional>
#include <limits>
#include <map>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include "../test_constants.h"

namespace {

using planar_grid::KLDivergenceOccupancyFilter;
using planar_grid::OccupancyUpdateRule;

/** \brief Tolerance of probabilities that went through the float log-odds store. */
constexpr double PROB_TOL = 1e-5;

template <typename PointT>
PointT
makePoint(float x, float y, float z)
{
  PointT p;
  p.x = x;
  p.y = y;
  p.z = z;
  return p;
}

template <typename PointT>
typename pcl::PointCloud<PointT>::Ptr
makeCloud(const std::vector<Eigen::Vector3f>& xyz)
{
  typename pcl::PointCloud<PointT>::Ptr cloud(new pcl::PointCloud<PointT>);
  for (const Eigen::Vector3f& v : xyz)
    cloud->push_back(makePoint<PointT>(v.x(), v.y(), v.z()));
  return cloud;
}

/** \brief Two features in one 4 m cell of the sensor frame, on a line slightly off the
 * optical axis: X1 = (0.5, 0.5, 9), X2 = (0.5, 0.5, 11) m.
 * r1 = sqrt(0.5 + 81) = 9.027735, r2 = sqrt(0.5 + 121) = 11.022704, r_bar = 10.025219.
 * With f = 100 px, B = 0.5 m, dd = 0.5 px:
 *   dz1 = 81 / 50 * 0.5 = 0.81 m, dr1 = (10.025219 / 9) 0.81 = 0.902270 m,
 *   t1 = (9.027735 - 10.025219) / 0.902270 = -1.105528, p1 = exp(-t1^2 / 2) = 0.542756;
 *   dz2 = 121 / 50 * 0.5 = 1.21 m, dr2 = (10.025219 / 11) 1.21 = 1.102774 m,
 *   t2 = (11.022704 - 10.025219) / 1.102774 = 0.904522, p2 = exp(-t2^2 / 2) = 0.664261.
 */
const std::vector<Eigen::Vector3f> TWO_FEATURES = {{0.5f, 0.5f, 9.0f},
                                                   {0.5f, 0.5f, 11.0f}};
constexpr double TWO_P1 = 0.542756;
constexpr double TWO_P2 = 0.664261;

template <typename PointT>
class KLDivergenceOccupancyFilterTyped : public ::testing::Test {
protected:
  using Filter = KLDivergenceOccupancyFilter<PointT>;
  using Cloud = pcl::PointCloud<PointT>;

  /** \brief A filter with f = 100 px, B = 0.5 m and 4 m neighbourhood cells. */
  static Filter makeFilter()
  {
    Filter filter;
    typename Filter::Params params;
    params.neighbourhood_size_m = 4.0;
    filter.setParams(params);
    filter.setStereoParameters(100.0, 0.5);
    return filter;
  }

  /** \brief Integrates \a xyz with \a ids as one frame; returns the kept indices. */
  static pcl::Indices frame(Filter& filter,
                            const std::vector<Eigen::Vector3f>& xyz,
                            const std::vector<std::int64_t>& ids,
                            double motion_likelihood = 1.0)
  {
    filter.setInputCloud(makeCloud<PointT>(xyz));
    filter.setTrackIds(ids);
    filter.setMotionLikelihood(motion_likelihood);
    pcl::Indices kept;
    filter.filter(kept);
    return kept;
  }
};

using PointTypes = ::testing::Types<pcl::PointXYZ, pcl::PointXYZI, pcl::PointXYZRGB>;
TYPED_TEST_SUITE(KLDivergenceOccupancyFilterTyped, PointTypes);

} // namespace

// ---------------------------------------------------------------------------------
// Free functions

TEST(KLDivergenceOccupancyFilter, RangeOccupancyProbabilityHandComputed)
{
  // r = 10.5, r_bar = 10, z = 10 m, f = 100 px, B = 0.5 m, dd = 0.5 px:
  // dz = 100 / 50 * 0.5 = 1 m, dr = (10 / 10) 1 = 1 m, p = exp(-0.5 * 0.5^2) =
  // 0.882497.
  EXPECT_NEAR(planar_grid::rangeOccupancyProbability(10.5, 10.0, 10.0, 100.0, 0.5, 0.5),
              0.882497, 1e-6);
  // Symmetric in r - r_bar; 1 at r = r_bar (a feature alone in its cell).
  EXPECT_NEAR(planar_grid::rangeOccupancyProbability(9.5, 10.0, 10.0, 100.0, 0.5, 0.5),
              0.882497, 1e-6);
  EXPECT_EQ(planar_grid::rangeOccupancyProbability(7.0, 7.0, 7.0, 100.0, 0.5, 0.5),
            1.0);
  // Invalid arguments give 0.
  EXPECT_EQ(planar_grid::rangeOccupancyProbability(10.5, 10.0, 0.0, 100.0, 0.5, 0.5),
            0.0);
  EXPECT_EQ(planar_grid::rangeOccupancyProbability(10.5, 10.0, 10.0, 0.0, 0.5, 0.5),
            0.0);
  EXPECT_EQ(planar_grid::rangeOccupancyProbability(
              std::numeric_limits<double>::quiet_NaN(), 10.0, 10.0, 100.0, 0.5, 0.5),
            0.0);
}

TEST(KLDivergenceOccupancyFilter, KLUpdateHandComputed)
{
  // p = 0.8, q = 0.6: D = 0.8 ln(0.8 / 0.6) + 0.2 ln(0.2 / 0.4)
  //                     = 0.8 * 0.2876821 - 0.2 * 0.6931472 = 0.0915162 nats;
  // p > 0.5, so E = D and the update is exp(-0.0915162) = 0.9125465.
  EXPECT_NEAR(planar_grid::bernoulliKLDivergence(0.8, 0.6), 0.0915162, 1e-7);
  EXPECT_NEAR(planar_grid::klDivergenceUpdate(0.8, 0.6, 1.07), 0.9125465, 1e-7);
  // p = 0.3, q = 0.2: D = 0.3 ln(1.5) + 0.7 ln(0.7 / 0.8)
  //                     = 0.3 * 0.4054651 - 0.7 * 0.1335314 = 0.0281676 nats;
  // both <= 0.5, so E = D + 1.07 = 1.0981676 and the update is 0.3334816.
  EXPECT_NEAR(planar_grid::bernoulliKLDivergence(0.3, 0.2), 0.0281676, 1e-7);
  EXPECT_NEAR(planar_grid::klDivergenceUpdate(0.3, 0.2, 1.07), 0.3334816, 1e-7);
  // D(p || p) = 0, D >= 0.
  EXPECT_NEAR(planar_grid::bernoulliKLDivergence(0.37, 0.37), 0.0, 1e-15);
  EXPECT_GT(planar_grid::bernoulliKLDivergence(0.37, 0.9), 0.0);
}

TEST(KLDivergenceOccupancyFilter, KLEpsilonGuardKeepsDivergenceFinite)
{
  // q = 0 and q = 1 are moved to 1e-9 and 1 - 1e-9: finite, large divergences.
  const double d0 = planar_grid::bernoulliKLDivergence(0.7, 0.0);
  const double d1 = planar_grid::bernoulliKLDivergence(0.7, 1.0);
  EXPECT_TRUE(std::isfinite(d0));
  EXPECT_TRUE(std::isfinite(d1));
  // 0.7 ln(0.7 / 1e-9) + 0.3 ln(0.3 / (1 - 1e-9)) = 0.7 * 20.3663 - 0.3 * 1.20397.
  EXPECT_NEAR(d0, 0.7 * std::log(0.7e9) + 0.3 * std::log(0.3), 1e-6);
  // p = 0 and p = 1 use 0 ln 0 = 0.
  EXPECT_NEAR(planar_grid::bernoulliKLDivergence(1.0, 0.5), std::log(2.0), 1e-12);
  EXPECT_NEAR(planar_grid::bernoulliKLDivergence(0.0, 0.5), std::log(2.0), 1e-12);
  EXPECT_GT(planar_grid::klDivergenceUpdate(0.7, 0.0, 1.07), 0.0);
}

TEST(KLDivergenceOccupancyFilter, UpdateRuleNames)
{
  using planar_grid::occupancyUpdateRuleFromString;
  EXPECT_EQ(occupancyUpdateRuleFromString("kl_divergence"),
            OccupancyUpdateRule::KL_DIVERGENCE);
  EXPECT_EQ(occupancyUpdateRuleFromString("log_odds"), OccupancyUpdateRule::LOG_ODDS);
  for (const OccupancyUpdateRule rule :
       {OccupancyUpdateRule::KL_DIVERGENCE, OccupancyUpdateRule::LOG_ODDS})
    EXPECT_EQ(occupancyUpdateRuleFromString(planar_grid::toString(rule)), rule);
  EXPECT_THROW(occupancyUpdateRuleFromString("kl"), planar_grid::Exception);
}

// ---------------------------------------------------------------------------------
// The filter on synthetic features

TYPED_TEST(KLDivergenceOccupancyFilterTyped, FirstObservationIsEq4)
{
  auto filter = TestFixture::makeFilter();
  const pcl::Indices kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  const std::vector<float>& p = filter.getProbabilities();
  ASSERT_EQ(p.size(), 2u);
  // Hand-computed in the comment of TWO_FEATURES; both above 0.5, both kept.
  EXPECT_NEAR(p[0], TWO_P1, PROB_TOL);
  EXPECT_NEAR(p[1], TWO_P2, PROB_TOL);
  EXPECT_EQ(kept, (pcl::Indices{0, 1}));
  EXPECT_EQ(filter.getTrackCount(), 2u);
  float track_p = 0.0f;
  ASSERT_TRUE(filter.getTrackProbability(1, track_p));
  EXPECT_NEAR(track_p, TWO_P2, PROB_TOL);
  EXPECT_FALSE(filter.getTrackProbability(7, track_p));
  EXPECT_EQ(filter.getAssignedTrackIds(), (std::vector<std::int64_t>{0, 1}));
  EXPECT_GT(filter.getMemoryBytes(), 0u);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, AloneInCellIsClampedToMax)
{
  // A feature alone in its cell has r = r_bar, p = 1, clamped to 0.971.
  auto filter = TestFixture::makeFilter();
  TestFixture::frame(filter, {{0.5f, 0.5f, 5.0f}}, {3});
  EXPECT_NEAR(filter.getProbabilities()[0], 0.971, PROB_TOL);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, OneKLUpdateHandComputed)
{
  auto filter = TestFixture::makeFilter();
  TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  // Second frame, same geometry, m = 0.8:
  // track 1: p = 0.664261, q = 0.664261 * 0.8 = 0.531408;
  //   D = 0.664261 ln(0.664261 / 0.531408) + 0.335739 ln(0.335739 / 0.468592)
  //     = 0.664261 * 0.223143 - 0.335739 * 0.333398 = 0.036291 nats,
  //   p > 0.5 so E = D, exp(-E) = 0.964359 (inside the clamps);
  // track 0: p = 0.542756, q = 0.434205, D = 0.023713 nats, exp(-D) = 0.976566,
  //   clamped to 0.971 (p > 0.5, so no A although q <= 0.5).
  TestFixture::frame(filter, TWO_FEATURES, {0, 1}, 0.8);
  const std::vector<float>& p = filter.getProbabilities();
  EXPECT_NEAR(p[1], 0.964359, PROB_TOL);
  EXPECT_NEAR(p[0], 0.971, PROB_TOL);
  EXPECT_EQ(filter.getTrackCount(), 2u);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, FilterTwiceUpdatesOnce)
{
  auto filter = TestFixture::makeFilter();
  TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  TestFixture::frame(filter, TWO_FEATURES, {0, 1}, 0.8);
  pcl::Indices again;
  filter.filter(again); // same cloud, indices, ids: re-selects only
  typename TestFixture::Cloud out;
  filter.filter(out);
  float p = 0.0f;
  ASSERT_TRUE(filter.getTrackProbability(1, p));
  // Still the single update of OneKLUpdateHandComputed (a second update from 0.964359
  // with q = 0.531408 would give exp(-0.184) = 0.83).
  EXPECT_NEAR(p, 0.964359, PROB_TOL);
  EXPECT_EQ(again, (pcl::Indices{0, 1}));
  EXPECT_EQ(out.size(), 2u);
  // Changing the threshold re-selects without an update.
  auto params = filter.getParams();
  params.occupancy_thres = 0.97;
  filter.setParams(params);
  filter.filter(again);
  EXPECT_EQ(again, (pcl::Indices{0})); // 0.971 kept, 0.964 not
  ASSERT_TRUE(filter.getTrackProbability(1, p));
  EXPECT_NEAR(p, 0.964359, PROB_TOL);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, ConsistentObservationsRiseTowardMax)
{
  // Identical frames: track 1 starts at p0 = 0.664261. The first re-observation has
  // q = p0 = p, D = 0, exp(0) = 1 -> clamped to 0.971. From there the KL rule
  // alternates: D(0.971 || 0.664261) = 0.2976 nats -> 0.7426, then D(0.7426 ||
  // 0.664261) = 0.0045 -> 0.971 again. It never falls back to p0.
  auto filter = TestFixture::makeFilter();
  TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  const double p0 = filter.getProbabilities()[1];
  double sum = 0.0;
  for (int k = 1; k <= 8; ++k) {
    TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    const double p = filter.getProbabilities()[1];
    if (k == 1) {
      EXPECT_NEAR(p, 0.971, PROB_TOL);
    }
    EXPECT_GT(p, p0 + 0.05) << "frame " << k;
    EXPECT_NEAR(p, k % 2 == 1 ? 0.971 : 0.7426, 1e-4) << "frame " << k;
    sum += p;
  }
  EXPECT_GT(sum / 8.0, 0.85);

  // The log-odds rule rises monotonically to the clamp (q = p0 >= 0.5: hits).
  auto log_odds = TestFixture::makeFilter();
  auto params = log_odds.getParams();
  params.update_rule = OccupancyUpdateRule::LOG_ODDS;
  log_odds.setParams(params);
  TestFixture::frame(log_odds, TWO_FEATURES, {0, 1});
  double previous = log_odds.getProbabilities()[1];
  for (int k = 1; k <= 6; ++k) {
    TestFixture::frame(log_odds, TWO_FEATURES, {0, 1});
    const double p = log_odds.getProbabilities()[1];
    EXPECT_GE(p, previous - 1e-7);
    previous = p;
  }
  EXPECT_NEAR(previous, 0.971, PROB_TOL);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, RetainTracksKeepsTheListedTracksExactly)
{
  // Two filters see the same frames with frame-to-frame ids, as the pipeline's
  // descriptor tracks: feature 0 continues track 0 throughout, feature 1 starts a new
  // track in every frame. One filter retains the frame's ids after each frame: its
  // probabilities equal the other's bit for bit, and it holds two tracks, not one
  // per frame.
  auto all = TestFixture::makeFilter();
  auto retained = TestFixture::makeFilter();
  for (std::int64_t k = 0; k < 6; ++k) {
    const std::vector<std::int64_t> ids = {0, 100 + k};
    TestFixture::frame(all, TWO_FEATURES, ids);
    TestFixture::frame(retained, TWO_FEATURES, ids);
    ASSERT_EQ(retained.getProbabilities(), all.getProbabilities()) << "frame " << k;
    EXPECT_EQ(retained.retainTracks(ids), k == 0 ? 0u : 1u) << "frame " << k;
    EXPECT_EQ(retained.getTrackCount(), 2u);
  }
  EXPECT_EQ(all.getTrackCount(), 7u);
  EXPECT_EQ(retained.getNextTrackId(), all.getNextTrackId());
  float p = 0.0f;
  EXPECT_TRUE(retained.getTrackProbability(0, p));
  EXPECT_FALSE(retained.getTrackProbability(100, p)); // forgotten
  EXPECT_TRUE(all.getTrackProbability(100, p));
  // A forgotten id seen again starts over at eq. 4's probability, where the unpruned
  // filter updates its old track.
  TestFixture::frame(all, TWO_FEATURES, {100, 1});
  TestFixture::frame(retained, TWO_FEATURES, {100, 1});
  EXPECT_NEAR(retained.getProbabilities()[0], TWO_P1, PROB_TOL);
  EXPECT_NE(all.getProbabilities()[0], retained.getProbabilities()[0]);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, MismatchedTrackFallsBelowHalf)
{
  // f = 700 px, B = 0.5 m: dz(10 m) = 100 / 350 * 0.5 = 0.143 m. Four features in one
  // 4 m cell near z = 10 m; track 9 sits at the cell's mean range in frame 1
  // (p ~ 1 -> 0.971). In frame 2 its match is at z = 11.5 m while the others stay:
  // r_bar = 10.375 m, dr = 0.17 m, t = 6.6 -> p_new ~ 0 -> 0.1192, and
  // D(0.971 || 0.1192) = 1.9377 nats -> exp(-1.9377) = 0.1440.
  auto filter = TestFixture::makeFilter();
  filter.setStereoParameters(700.0, 0.5);
  const std::vector<std::int64_t> ids = {1, 2, 3, 9};
  TestFixture::frame(
    filter,
    {{0.f, 0.1f, 9.9f}, {0.f, 0.1f, 10.0f}, {0.f, 0.1f, 10.1f}, {0.f, 0.1f, 10.f}},
    ids);
  EXPECT_NEAR(filter.getProbabilities()[3], 0.971, PROB_TOL);
  const pcl::Indices kept = TestFixture::frame(
    filter,
    {{0.f, 0.1f, 9.9f}, {0.f, 0.1f, 10.0f}, {0.f, 0.1f, 10.1f}, {0.f, 0.1f, 11.5f}},
    ids);
  float p = 0.0f;
  ASSERT_TRUE(filter.getTrackProbability(9, p));
  EXPECT_LT(p, 0.5f);
  EXPECT_NEAR(p, 0.1440, 1e-3);
  for (const pcl::index_t index : kept)
    EXPECT_NE(index, 3);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, LowPAndQLandAtOrBelowOffset)
{
  // f = 150 px scales t by 1.5: p1 = 0.542756^2.25 = 0.252848, p2 = 0.664261^2.25 =
  // 0.398347, both <= 0.5. Re-observed with m = 1 (q = p, D = 0): E = A = 1.07 ->
  // exp(-1.07) = 0.343009; with m = 0.5 (q = p / 2, D > 0): below it.
  auto filter = TestFixture::makeFilter();
  filter.setStereoParameters(150.0, 0.5);
  TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  EXPECT_NEAR(filter.getProbabilities()[0], 0.252848, PROB_TOL);
  EXPECT_NEAR(filter.getProbabilities()[1], 0.398347, PROB_TOL);
  const pcl::Indices kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  EXPECT_TRUE(kept.empty());
  EXPECT_NEAR(filter.getProbabilities()[0], std::exp(-1.07), PROB_TOL);
  EXPECT_NEAR(filter.getProbabilities()[1], std::exp(-1.07), PROB_TOL);
  TestFixture::frame(filter, TWO_FEATURES, {0, 1}, 0.5);
  for (const float p : filter.getProbabilities()) {
    EXPECT_LE(p, std::exp(-1.07) + PROB_TOL);
    EXPECT_GE(p, 0.1192 - PROB_TOL);
  }
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, SetNegativeInvertsSelection)
{
  // Features 0, 1: the low pair of LowPAndQLandAtOrBelowOffset (0.25, 0.40), moved to
  // another cell; feature 2 alone (0.971); feature 3 NaN (never kept).
  const float nan = std::numeric_limits<float>::quiet_NaN();
  const std::vector<Eigen::Vector3f> xyz = {
    {0.5f, 0.5f, 9.0f}, {0.5f, 0.5f, 11.0f}, {6.f, 0.5f, 5.f}, {nan, nan, nan}};
  auto filter = TestFixture::makeFilter();
  filter.setStereoParameters(150.0, 0.5);
  auto cloud = makeCloud<TypeParam>(xyz);
  cloud->is_dense = false;
  filter.setInputCloud(cloud);
  pcl::Indices kept;
  filter.filter(kept);
  EXPECT_EQ(kept, (pcl::Indices{2}));

  KLDivergenceOccupancyFilter<TypeParam> negative(true); // extract removed indices
  negative.setParams(filter.getParams());
  negative.setStereoParameters(150.0, 0.5);
  negative.setNegative(true);
  negative.setInputCloud(cloud);
  negative.filter(kept);
  EXPECT_EQ(kept, (pcl::Indices{0, 1}));
  EXPECT_EQ(*negative.getRemovedIndices(), (pcl::Indices{2, 3}));
  EXPECT_EQ(negative.getProbabilities()[3], 0.0f);
  EXPECT_EQ(negative.getAssignedTrackIds()[3], -1);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, AssociationByPosition)
{
  // Frame 1: 30 features on a grid (world frame, still camera). Frame 2: the same
  // features moved by < 5 cm in reverse order, plus one far away. Without ids each
  // feature of frame 2 must join the track of its frame-1 feature (radius 0.2 m, the
  // grid step 0.5 m), and the probabilities must equal those of a filter given the
  // true ids.
  std::vector<Eigen::Vector3f> first;
  for (int i = 0; i < 30; ++i)
    first.emplace_back(0.5f * static_cast<float>(i % 5) - 1.0f,
                       0.5f * static_cast<float>((i / 5) % 3) - 0.5f,
                       6.0f + 0.5f * static_cast<float>(i / 15));
  std::mt19937 rng(7);
  std::uniform_real_distribution<float> jitter(-0.025f, 0.025f);
  std::vector<Eigen::Vector3f> second;
  std::vector<std::int64_t> second_truth;
  for (int i = 29; i >= 0; --i) {
    second.push_back(first[i] + Eigen::Vector3f(jitter(rng), jitter(rng), jitter(rng)));
    second_truth.push_back(i);
  }
  second.emplace_back(30.f, 0.f, 30.f);
  second_truth.push_back(30);
  std::vector<std::int64_t> first_truth(30);
  for (int i = 0; i < 30; ++i)
    first_truth[i] = i;

  auto by_position = TestFixture::makeFilter();
  by_position.setAssociationRadius(0.2);
  auto by_id = TestFixture::makeFilter();
  TestFixture::frame(by_position, first, {});
  TestFixture::frame(by_id, first, first_truth);
  EXPECT_EQ(by_position.getAssignedTrackIds(), first_truth);
  TestFixture::frame(by_position, second, {}, 0.9);
  TestFixture::frame(by_id, second, second_truth, 0.9);
  EXPECT_EQ(by_position.getAssignedTrackIds(), second_truth);
  EXPECT_EQ(by_position.getTrackCount(), 31u);
  ASSERT_EQ(by_position.getProbabilities().size(), by_id.getProbabilities().size());
  for (std::size_t i = 0; i < second.size(); ++i)
    EXPECT_NEAR(by_position.getProbabilities()[i], by_id.getProbabilities()[i], 1e-7);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, WorldFrameMatchesCameraFrame)
{
  // 200 features in the camera frame, each inside a 1 m cell at least 5 cm from its
  // faces (so that the float transform cannot move one across a face). Two frames with
  // ids; the second frame moves half the features a little. The world-frame copy holds
  // R X + t with the pose in sensor_origin_ / sensor_orientation_.
  std::mt19937 rng(42);
  std::uniform_int_distribution<int> cell_xy(-3, 2);
  std::uniform_int_distribution<int> cell_z(2, 7);
  std::uniform_real_distribution<float> inside(0.05f, 0.95f);
  std::vector<Eigen::Vector3f> frame1, frame2;
  std::vector<std::int64_t> ids;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3f x(static_cast<float>(cell_xy(rng)) + inside(rng),
                            static_cast<float>(cell_xy(rng)) + inside(rng),
                            static_cast<float>(cell_z(rng)) + inside(rng));
    frame1.push_back(x);
    Eigen::Vector3f y = x;
    if (i % 2 == 0)
      y.z() = std::floor(y.z()) + inside(rng);
    frame2.push_back(y);
    ids.push_back(100 + i);
  }
  const Eigen::Quaternionf rotation(
    Eigen::AngleAxisf(0.3f, Eigen::Vector3f(0.2f, -1.0f, 0.1f).normalized()));
  const Eigen::Vector3f translation(4.0f, -1.5f, 12.0f);

  auto camera = TestFixture::makeFilter();
  auto world = TestFixture::makeFilter();
  auto params = camera.getParams();
  params.neighbourhood_size_m = 1.0;
  camera.setParams(params);
  world.setParams(params);
  for (const auto* xyz : {&frame1, &frame2}) {
    TestFixture::frame(camera, *xyz, ids, 0.9);
    std::vector<Eigen::Vector3f> moved;
    for (const Eigen::Vector3f& x : *xyz)
      moved.push_back(rotation * x + translation);
    auto cloud = makeCloud<TypeParam>(moved);
    cloud->sensor_origin_ =
      Eigen::Vector4f(translation.x(), translation.y(), translation.z(), 0.0f);
    cloud->sensor_orientation_ = rotation;
    world.setInputCloud(cloud);
    world.setTrackIds(ids);
    world.setMotionLikelihood(0.9);
    pcl::Indices kept;
    world.filter(kept);
    ASSERT_EQ(camera.getProbabilities().size(), world.getProbabilities().size());
    for (std::size_t i = 0; i < xyz->size(); ++i)
      EXPECT_NEAR(camera.getProbabilities()[i], world.getProbabilities()[i], 1e-4)
        << "feature " << i;
  }
  // The data exercise the update: some tracks are below 0.5, some above.
  int low = 0;
  for (const float p : camera.getProbabilities())
    low += p < 0.5f ? 1 : 0;
  EXPECT_GT(low, 0);
  EXPECT_LT(low, 200);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, LogOddsRuleHandComputed)
{
  // Track 1 starts at p0 = 0.664261, log-odds ln(0.664261 / 0.335739) = 0.682339.
  // Four frames with q = p0 >= 0.5: + ln(0.7 / 0.3) = +0.847298 each:
  //   1.529637 (0.821953), 2.376935 (0.915051), 3.224233 (0.961736),
  //   4.071531 -> clamped to ln(0.971 / 0.029) = 3.511031 (0.971).
  // Then m = 0.5: q = 0.332130 < 0.5, a miss: + ln(0.4 / 0.6) = -0.405465:
  //   3.105566 (0.957122).
  auto filter = TestFixture::makeFilter();
  auto params = filter.getParams();
  params.update_rule = OccupancyUpdateRule::LOG_ODDS;
  filter.setParams(params);
  TestFixture::frame(filter, TWO_FEATURES, {0, 1});
  EXPECT_NEAR(filter.getProbabilities()[1], 0.664261, PROB_TOL);
  const double expected[] = {0.821953, 0.915051, 0.961736, 0.971};
  for (const double p : expected) {
    TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    EXPECT_NEAR(filter.getProbabilities()[1], p, PROB_TOL);
  }
  TestFixture::frame(filter, TWO_FEATURES, {0, 1}, 0.5);
  EXPECT_NEAR(filter.getProbabilities()[1], 0.957122, PROB_TOL);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, UntrackedAndUnseenFeatures)
{
  // Id -1: eq. 4 but no track. A track not seen in a frame keeps its probability.
  auto filter = TestFixture::makeFilter();
  TestFixture::frame(filter, TWO_FEATURES, {-1, 1});
  EXPECT_EQ(filter.getTrackCount(), 1u);
  EXPECT_NEAR(filter.getProbabilities()[0], TWO_P1, PROB_TOL);
  EXPECT_EQ(filter.getAssignedTrackIds()[0], -1);
  TestFixture::frame(filter, {{5.f, 5.f, 20.f}}, {2});
  float p = 0.0f;
  ASSERT_TRUE(filter.getTrackProbability(1, p));
  EXPECT_NEAR(p, TWO_P2, PROB_TOL);
  // The same id twice in one frame: one update, both points get the track's value.
  TestFixture::frame(filter, TWO_FEATURES, {1, 1});
  EXPECT_EQ(filter.getProbabilities()[0], filter.getProbabilities()[1]);
  filter.reset();
  EXPECT_EQ(filter.getTrackCount(), 0u);
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, DegenerateInputGivesEmptyOutput)
{
  using FilterType = typename TestFixture::Filter;
  pcl::Indices kept{42};
  // No input.
  {
    FilterType filter = TestFixture::makeFilter();
    kept.clear();
    filter.filter(kept);
    EXPECT_TRUE(kept.empty());
  }
  // Empty cloud.
  {
    FilterType filter = TestFixture::makeFilter();
    kept = TestFixture::frame(filter, {}, {});
    EXPECT_TRUE(kept.empty());
    EXPECT_EQ(filter.getTrackCount(), 0u);
  }
  // All NaN, and points behind the camera (z <= 0).
  {
    FilterType filter = TestFixture::makeFilter();
    const float nan = std::numeric_limits<float>::quiet_NaN();
    kept = TestFixture::frame(
      filter, {{nan, nan, nan}, {0.f, 0.f, -3.f}, {1.f, 1.f, 0.f}}, {0, 1, 2});
    EXPECT_TRUE(kept.empty());
    EXPECT_EQ(filter.getTrackCount(), 0u);
    EXPECT_EQ(filter.getProbabilities(), std::vector<float>(3, 0.0f));
    filter.setNegative(true);
    filter.filter(kept);
    EXPECT_TRUE(kept.empty());
  }
  // Track ids of the wrong size: empty, tracks untouched.
  {
    FilterType filter = TestFixture::makeFilter();
    TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1, 2});
    EXPECT_TRUE(kept.empty());
    EXPECT_EQ(filter.getProbabilities(), std::vector<float>(2, 0.0f));
    float p = 0.0f;
    ASSERT_TRUE(filter.getTrackProbability(1, p));
    EXPECT_NEAR(p, TWO_P2, PROB_TOL);
  }
  // Stereo parameters not set.
  {
    FilterType filter;
    kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    EXPECT_TRUE(kept.empty());
    EXPECT_EQ(filter.getTrackCount(), 0u);
  }
  // Invalid parameters and motion likelihoods.
  using Params = typename FilterType::Params;
  const std::vector<void (*)(Params&)> breakers = {
    [](Params& p) { p.disparity_error_px = 0.0; },
    [](Params& p) { p.neighbourhood_size_m = -1.0; },
    [](Params& p) {
      p.neighbourhood_size_m = std::numeric_limits<double>::quiet_NaN();
    },
    [](Params& p) { p.clamping_thres_min = 0.6; },
    [](Params& p) { p.clamping_thres_max = 1.0; },
    [](Params& p) { p.occupancy_thres = 1.5; },
    [](Params& p) { p.kl_offset_nats = -1.0; },
    [](Params& p) { p.update_rule = static_cast<OccupancyUpdateRule>(7); },
    [](Params& p) { p.prob_hit = 0.4; },
    [](Params& p) { p.prob_miss = 0.6; },
    [](Params& p) { p.association_radius_m = 0.0; },
  };
  for (std::size_t b = 0; b < breakers.size(); ++b) {
    FilterType filter = TestFixture::makeFilter();
    Params params = filter.getParams();
    breakers[b](params);
    filter.setParams(params);
    kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    EXPECT_TRUE(kept.empty()) << "breaker " << b;
    EXPECT_EQ(filter.getTrackCount(), 0u) << "breaker " << b;
  }
  for (const double m : {-0.1, 1.5, std::numeric_limits<double>::quiet_NaN()}) {
    FilterType filter = TestFixture::makeFilter();
    kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1}, m);
    EXPECT_TRUE(kept.empty()) << "m = " << m;
  }
  // m = 0 is valid (an underflowed likelihood): q = 0 is guarded, p drops.
  {
    FilterType filter = TestFixture::makeFilter();
    TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    TestFixture::frame(filter, TWO_FEATURES, {0, 1}, 0.0);
    for (const float p : filter.getProbabilities())
      EXPECT_NEAR(p, 0.1192, PROB_TOL);
  }
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, SettersAndGettersMatchParams)
{
  using FilterType = typename TestFixture::Filter;
  FilterType filter;
  // The documented defaults, and the log-odds forms OctoMap's defaults have.
  EXPECT_EQ(filter.getDisparityError(), 0.5);
  EXPECT_EQ(filter.getNeighbourhoodSize(), 0.5);
  EXPECT_EQ(filter.getOccupancyThres(), 0.5);
  EXPECT_EQ(filter.getKLOffset(), 1.07);
  EXPECT_EQ(filter.getUpdateRule(), OccupancyUpdateRule::KL_DIVERGENCE);
  EXPECT_EQ(filter.getRangeErrorModel(), planar_grid::RangeErrorModel::STEREO);
  EXPECT_EQ(filter.getAssociationRadius(), 0.1);
  EXPECT_EQ(filter.getDepthErrorCoefficient(), 0.0016);
  EXPECT_EQ(filter.getRangeError(), 0.03);
  EXPECT_NEAR(filter.getClampingThresMinLogOdds(), std::log(0.1192 / 0.8808), 1e-12);
  EXPECT_NEAR(filter.getClampingThresMaxLogOdds(), std::log(0.971 / 0.029), 1e-12);
  EXPECT_NEAR(filter.getOccupancyThresLogOdds(), 0.0, 1e-12);
  EXPECT_NEAR(filter.getProbHitLogOdds(), std::log(0.7 / 0.3), 1e-12);
  EXPECT_NEAR(filter.getProbMissLogOdds(), std::log(0.4 / 0.6), 1e-12);

  filter.setDisparityError(0.25);
  filter.setNeighbourhoodSize(2.0);
  filter.setClampingThresMin(0.2);
  filter.setClampingThresMax(0.9);
  filter.setOccupancyThres(0.6);
  filter.setKLOffset(0.5);
  filter.setUpdateRule(OccupancyUpdateRule::LOG_ODDS);
  filter.setProbHit(0.8);
  filter.setProbMiss(0.3);
  filter.setAssociationRadius(0.3);
  filter.setRangeErrorModel(planar_grid::RangeErrorModel::RANGE);
  filter.setDepthErrorCoefficient(0.002);
  filter.setRangeError(0.05);
  const auto& p = filter.getParams();
  EXPECT_EQ(p.disparity_error_px, 0.25);
  EXPECT_EQ(p.neighbourhood_size_m, 2.0);
  EXPECT_EQ(p.clamping_thres_min, 0.2);
  EXPECT_EQ(p.clamping_thres_max, 0.9);
  EXPECT_EQ(p.occupancy_thres, 0.6);
  EXPECT_EQ(p.kl_offset_nats, 0.5);
  EXPECT_EQ(p.update_rule, OccupancyUpdateRule::LOG_ODDS);
  EXPECT_EQ(p.prob_hit, 0.8);
  EXPECT_EQ(p.prob_miss, 0.3);
  EXPECT_EQ(p.association_radius_m, 0.3);
  EXPECT_EQ(p.range_error_model, planar_grid::RangeErrorModel::RANGE);
  EXPECT_EQ(p.depth_error_coefficient_per_m, 0.002);
  EXPECT_EQ(p.range_error_m, 0.05);
  EXPECT_NEAR(filter.getClampingThresMinLogOdds(), std::log(0.2 / 0.8), 1e-12);
  EXPECT_NEAR(filter.getClampingThresMaxLogOdds(), std::log(0.9 / 0.1), 1e-12);
  EXPECT_NEAR(filter.getOccupancyThresLogOdds(), std::log(0.6 / 0.4), 1e-12);

  // A filter set up by the setters updates as one set up by Params: the log-odds
  // rule over two frames, hand-checked against the rule.
  FilterType by_setters = TestFixture::makeFilter();
  by_setters.setUpdateRule(OccupancyUpdateRule::LOG_ODDS);
  by_setters.setProbHit(0.8);
  TestFixture::frame(by_setters, TWO_FEATURES, {0, 1});
  TestFixture::frame(by_setters, TWO_FEATURES, {0, 1});
  // p_new = TWO_P1 / TWO_P2 >= 0.5 both times: a hit each, log_odds(p) + log_odds(0.8).
  const auto logOdds = [](double q) {
    return std::log(q / (1.0 - q));
  };
  const double expected[2] = {1.0 / (1.0 + std::exp(-(logOdds(TWO_P1) + logOdds(0.8)))),
                              1.0
                                / (1.0 + std::exp(-(logOdds(TWO_P2) + logOdds(0.8))))};
  ASSERT_EQ(by_setters.getProbabilities().size(), 2u);
  for (std::size_t k = 0; k < 2; ++k)
    EXPECT_NEAR(by_setters.getProbabilities()[k], expected[k], PROB_TOL) << k;
}

TYPED_TEST(KLDivergenceOccupancyFilterTyped, InvalidSettersGiveEmptyOutput)
{
  using FilterType = typename TestFixture::Filter;
  const double nan = std::numeric_limits<double>::quiet_NaN();
  const std::vector<std::function<void(FilterType&)>> invalid = {
    [](FilterType& f) { f.setDisparityError(0.0); },
    [nan](FilterType& f) { f.setDisparityError(nan); },
    [](FilterType& f) { f.setNeighbourhoodSize(-1.0); },
    [](FilterType& f) { f.setClampingThresMin(0.5); },
    [](FilterType& f) { f.setClampingThresMax(0.5); },
    [](FilterType& f) { f.setOccupancyThres(-0.1); },
    [](FilterType& f) { f.setKLOffset(-0.5); },
    [](FilterType& f) { f.setUpdateRule(static_cast<OccupancyUpdateRule>(9)); },
    [](FilterType& f) { f.setProbHit(0.5); },
    [](FilterType& f) { f.setProbMiss(0.5); },
    [](FilterType& f) { f.setAssociationRadius(0.0); },
    [](FilterType& f) {
      f.setRangeErrorModel(static_cast<planar_grid::RangeErrorModel>(9));
    },
    [](FilterType& f) { f.setDepthErrorCoefficient(0.0); },
    [](FilterType& f) { f.setRangeError(-0.03); },
  };
  for (std::size_t i = 0; i < invalid.size(); ++i) {
    FilterType filter = TestFixture::makeFilter();
    invalid[i](filter);
    const pcl::Indices kept = TestFixture::frame(filter, TWO_FEATURES, {0, 1});
    EXPECT_TRUE(kept.empty()) << i;
    EXPECT_EQ(filter.getTrackCount(), 0u) << i;
  }
}

// ---------------------------------------------------------------------------------
// Real data: two consecutive Karlsruhe stereo frames

namespace {

using planar_grid_test::KARLSRUHE_DIR;

/** \brief The stereo features (the default StereoFeatureMatcher) of Karlsruhe frames
 * 10 and 11. */
void
loadKarlsruheFeatures(const planar_grid::StereoCalibration& calibration,
                      planar_grid::StereoFeatures (&frames)[2])
{
  const planar_grid::StereoFeatureMatcher matcher;
  for (int k = 0; k < 2; ++k) {
    char name[32];
    std::snprintf(name, sizeof(name), "%06d.png", 10 + k);
    const cv::Mat left =
      cv::imread(KARLSRUHE_DIR + "/left/I1_" + name, cv::IMREAD_GRAYSCALE);
    const cv::Mat right =
      cv::imread(KARLSRUHE_DIR + "/right/I2_" + name, cv::IMREAD_GRAYSCALE);
    ASSERT_FALSE(left.empty());
    ASSERT_FALSE(right.empty());
    matcher.match(left, right, calibration, frames[k]);
    ASSERT_GT(frames[k].size(), 200u);
  }
}

} // namespace

TEST(KLDivergenceOccupancyFilter, KarlsruheConsecutiveFrames)
{
  const planar_grid::StereoCameraModel model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::KARLSRUHE, KARLSRUHE_DIR + "/calib.txt");
  const planar_grid::StereoCalibration& calibration = model.calibration;
  planar_grid::StereoFeatures frames[2];
  loadKarlsruheFeatures(calibration, frames);
  ASSERT_FALSE(HasFatalFailure());

  // Track ids: frame 10 feature i is track i; a frame-11 feature matched to it by
  // descriptor continues it, the others start tracks n0 + j.
  planar_grid::StereoOdometry odometry;
  odometry.setCalibration(calibration);
  std::vector<cv::DMatch> matches;
  odometry.matchDescriptors(frames[0], frames[1], matches);
  ASSERT_GT(matches.size(), 100u);
  const planar_grid::OdometryResult motion = odometry.estimate(frames[0], frames[1]);
  ASSERT_TRUE(motion.valid) << motion.reason;
  const std::size_t n0 = frames[0].size();
  const std::size_t n1 = frames[1].size();
  std::vector<std::int64_t> ids0(n0), ids1(n1);
  for (std::size_t i = 0; i < n0; ++i)
    ids0[i] = static_cast<std::int64_t>(i);
  for (std::size_t j = 0; j < n1; ++j)
    ids1[j] = static_cast<std::int64_t>(n0 + j);
  for (const cv::DMatch& match : matches)
    ids1[static_cast<std::size_t>(match.trainIdx)] = match.queryIdx;

  // Frame 10 in its camera frame (the world frame); frame 11 in the world frame with
  // its camera pose previous_T_current in sensor_origin_ / sensor_orientation_.
  const Eigen::Isometry3f pose = motion.previous_T_current.cast<float>();
  KLDivergenceOccupancyFilter<pcl::PointXYZ> filter;
  filter.setStereoParameters(calibration.focal_length_px, calibration.baseline_m);
  auto cloud0 = frames[0].points.makeShared();
  filter.setInputCloud(cloud0);
  filter.setTrackIds(ids0);
  pcl::Indices kept0;
  filter.filter(kept0);
  const std::vector<float> p0 = filter.getProbabilities();

  auto cloud1 = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (const pcl::PointXYZ& point : frames[1].points) {
    const Eigen::Vector3f x = pose * point.getVector3fMap();
    cloud1->push_back(pcl::PointXYZ(x.x(), x.y(), x.z()));
  }
  const Eigen::Vector3f origin = pose.translation();
  cloud1->sensor_origin_ = Eigen::Vector4f(origin.x(), origin.y(), origin.z(), 0.0f);
  cloud1->sensor_orientation_ = Eigen::Quaternionf(pose.rotation());
  filter.setInputCloud(cloud1);
  filter.setTrackIds(ids1);
  pcl::Indices kept1;
  filter.filter(kept1);
  const std::vector<float>& p1 = filter.getProbabilities();

  // Every feature is valid and inside the clamps in both frames.
  const double thres_min = filter.getParams().clamping_thres_min;
  const double thres_max = filter.getParams().clamping_thres_max;
  const double p_min = thres_min - PROB_TOL;
  const double p_max = thres_max + PROB_TOL;
  for (const float p : p0) {
    EXPECT_GE(p, p_min);
    EXPECT_LE(p, p_max);
  }
  for (const float p : p1) {
    EXPECT_GE(p, p_min);
    EXPECT_LE(p, p_max);
  }
  EXPECT_EQ(filter.getTrackCount(), n0 + n1 - matches.size());

  // Oracle: eq. 4 recomputed by brute force in each camera frame (cells of
  // neighbourhood_size_m, grouped with std::map), then the KL update of the frame-10
  // probability for the re-observed tracks. The filter's frame 11 came through the
  // world frame, so this also checks the pose path on real data.
  const double size_m = filter.getParams().neighbourhood_size_m;
  const auto eq4 = [&](const pcl::PointCloud<pcl::PointXYZ>& points) {
    std::map<std::array<long, 3>, std::pair<double, int>> cells;
    const auto key = [&](const pcl::PointXYZ& x) {
      return std::array<long, 3>{static_cast<long>(std::floor(x.x / size_m)),
                                 static_cast<long>(std::floor(x.y / size_m)),
                                 static_cast<long>(std::floor(x.z / size_m))};
    };
    for (const pcl::PointXYZ& x : points) {
      auto& cell = cells[key(x)];
      cell.first += x.getVector3fMap().cast<double>().norm();
      ++cell.second;
    }
    std::vector<double> p;
    for (const pcl::PointXYZ& x : points) {
      const auto& cell = cells[key(x)];
      const double value = planar_grid::rangeOccupancyProbability(
        x.getVector3fMap().cast<double>().norm(), cell.first / cell.second, x.z,
        calibration.focal_length_px, calibration.baseline_m, 0.5);
      p.push_back(std::min(std::max(value, thres_min), thres_max));
    }
    return p;
  };
  const std::vector<double> oracle0 = eq4(frames[0].points);
  const std::vector<double> oracle1 = eq4(frames[1].points);
  std::size_t mismatches = 0, at_max = 0;
  for (std::size_t i = 0; i < n0; ++i) {
    mismatches += std::abs(p0[i] - oracle0[i]) > 1e-4 ? 1 : 0;
    at_max += p0[i] >= thres_max - PROB_TOL ? 1 : 0;
  }
  for (std::size_t j = 0; j < n1; ++j) {
    double expected = oracle1[j];
    if (ids1[j] < static_cast<std::int64_t>(n0)) {
      const double p = oracle0[static_cast<std::size_t>(ids1[j])];
      expected = std::min(
        std::max(planar_grid::klDivergenceUpdate(p, expected, 1.07), thres_min),
        thres_max);
    }
    mismatches += std::abs(p1[j] - expected) > 1e-4 ? 1 : 0;
  }
  // A feature within ~1e-6 m of a cell face may fall on the other side after the
  // float pose round trip; allow two.
  EXPECT_LE(mismatches, 2u);

  // Re-observed tracks, split by whether the two 3D positions agree after the motion
  // within three stereo depth errors (3 z^2 / (B f) * 0.5 px, + 5 cm).
  std::size_t consistent = 0, consistent_high = 0, inconsistent = 0,
              inconsistent_high = 0;
  for (const cv::DMatch& match : matches) {
    const auto i = static_cast<std::size_t>(match.queryIdx);
    const auto j = static_cast<std::size_t>(match.trainIdx);
    const Eigen::Vector3f a = (*cloud0)[i].getVector3fMap();
    const Eigen::Vector3f b = (*cloud1)[j].getVector3fMap();
    const double z = std::max((*cloud0)[i].z, frames[1].points[j].z);
    const double tolerance =
      0.05 + 3.0 * z * z / (calibration.baseline_m * calibration.focal_length_px) * 0.5;
    const bool high = p1[j] >= 0.5f;
    if ((a - b).norm() <= tolerance) {
      ++consistent;
      consistent_high += high ? 1 : 0;
    } else {
      ++inconsistent;
      inconsistent_high += high ? 1 : 0;
    }
  }
  std::printf("[ Karlsruhe ] features %zu / %zu (%zu at the upper clamp in frame 10), "
              "re-observed %zu (consistent %zu, %zu >= 0.5; inconsistent %zu, %zu >= "
              "0.5), kept %zu / %zu, %zu bytes\n",
              n0, n1, at_max, matches.size(), consistent, consistent_high, inconsistent,
              inconsistent_high, kept0.size(), kept1.size(), filter.getMemoryBytes());
  ASSERT_GT(consistent, 100u);
  EXPECT_GT(static_cast<double>(consistent_high) / static_cast<double>(consistent),
            0.8);
  // Eq. 4 measures a feature against its neighbourhood's mean range, not against its
  // own earlier position: most features are alone in their 0.5 m cell (r = r_bar,
  // p = 1 -> 0.971) in both frames and keep 0.971, consistent or not. So the split
  // above is reported, not asserted to separate (docs/METHOD.md).
  EXPECT_GT(at_max, n0 / 2);
}

TEST(StereoOdometry, ProjectedMatchingOnKarlsruheFrames)
{
  const planar_grid::StereoCameraModel model = planar_grid::loadStereoCalibration(
    planar_grid::CalibrationFormat::KARLSRUHE, KARLSRUHE_DIR + "/calib.txt");
  const planar_grid::StereoCalibration& calibration = model.calibration;
  planar_grid::StereoFeatures frames[2];
  loadKarlsruheFeatures(calibration, frames);
  ASSERT_FALSE(HasFatalFailure());
  planar_grid::StereoOdometry odometry;
  odometry.setCalibration(calibration);
  const planar_grid::OdometryResult motion = odometry.estimate(frames[0], frames[1]);
  ASSERT_TRUE(motion.valid) << motion.reason;
  const Eigen::Isometry3d current_T_previous = motion.previous_T_current.inverse();
  std::vector<cv::DMatch> brute_force;
  odometry.matchDescriptors(frames[0], frames[1], brute_force);
  ASSERT_GT(brute_force.size(), 100u);
  const auto pairs = [](const std::vector<cv::DMatch>& matches) {
    std::vector<std::pair<int, int>> out;
    for (const auto& m : matches)
      out.emplace_back(m.queryIdx, m.trainIdx);
    std::sort(out.begin(), out.end());
    return out;
  };

  // A window wider than the image holds every feature: the brute-force matches.
  std::vector<cv::DMatch> guided;
  odometry.matchDescriptorsProjected(frames[0], frames[1], current_T_previous,
                                     calibration, 1e5, guided);
  EXPECT_EQ(pairs(guided), pairs(brute_force));

  // A 20 px window: every match is where the motion projects its feature, and most of
  // the brute-force matches that lie there are found again.
  odometry.matchDescriptorsProjected(frames[0], frames[1], current_T_previous,
                                     calibration, 20.0, guided);
  ASSERT_GT(guided.size(), 100u);
  const auto residual_px = [&](const cv::DMatch& m) {
    const pcl::PointXYZ& p = frames[0].points[static_cast<std::size_t>(m.queryIdx)];
    const Eigen::Vector3d x = current_T_previous * Eigen::Vector3d(p.x, p.y, p.z);
    const cv::Point2f& kp =
      frames[1].keypoints_left[static_cast<std::size_t>(m.trainIdx)].pt;
    return std::hypot(
      calibration.focal_length_px * x.x() / x.z() + calibration.cx_px - kp.x,
      calibration.focal_length_px * x.y() / x.z() + calibration.cy_px - kp.y);
  };
  for (const auto& m : guided)
    EXPECT_LE(residual_px(m), 20.0);
  const auto guided_pairs = pairs(guided);
  std::size_t inside = 0, found = 0;
  for (const auto& m : brute_force) {
    if (residual_px(m) > 20.0)
      continue;
    ++inside;
    found += std::binary_search(guided_pairs.begin(), guided_pairs.end(),
                                std::make_pair(m.queryIdx, m.trainIdx))
               ? 1
               : 0;
  }
  ASSERT_GT(inside, 100u);
  EXPECT_GE(static_cast<double>(found), 0.9 * static_cast<double>(inside));

  // No window, or no focal length: no matches.
  odometry.matchDescriptorsProjected(frames[0], frames[1], current_T_previous,
                                     calibration, 0.0, guided);
  EXPECT_TRUE(guided.empty());
  odometry.matchDescriptorsProjected(frames[0], frames[1], current_T_previous,
                                     planar_grid::StereoCalibration(), 20.0, guided);
  EXPECT_TRUE(guided.empty());
}
