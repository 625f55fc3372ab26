// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/cloud_registration.h>

#include <pcl/common/io.h>
#include <pcl/common/transforms.h>
#include <pcl/console/time.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types_conversion.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <limits>
#include <utility>
#include <vector>

#include "../test_constants.h"
#include "reprojected_view.h"
#include "synthetic_room.h"

namespace {

using planar_grid_test::PI;

/** \brief Angle of the rotation between two poses, radians. */
double
rotationError(const Eigen::Isometry3d& a, const Eigen::Isometry3d& b)
{
  return Eigen::AngleAxisd(a.rotation().transpose() * b.rotation()).angle();
}

/** \brief A known target_T_source: yaw, a little roll, and a translation. */
Eigen::Isometry3d
knownMotion(double yaw_rad, const Eigen::Vector3d& translation_m)
{
  Eigen::Isometry3d t = Eigen::Isometry3d::Identity();
  t.linear() = (Eigen::AngleAxisd(yaw_rad, Eigen::Vector3d::UnitZ())
                * Eigen::AngleAxisd(0.03, Eigen::Vector3d::UnitX()))
                 .toRotationMatrix();
  t.translation() = translation_m;
  return t;
}

} // namespace

TEST(CloudRegistration, SmallMotionIsRecoveredByGICP)
{
  // The room seen from a sensor moved by a known transform: the source is the room in
  // the moved sensor's frame, so target_T_source is that transform.
  const auto target = planar_grid_test::syntheticRoom();
  const Eigen::Isometry3d truth = knownMotion(0.2, Eigen::Vector3d(0.3, -0.2, 0.05));
  pcl::PointCloud<pcl::PointXYZ> source;
  pcl::transformPointCloud(target, source, truth.inverse().cast<float>().matrix());

  planar_grid::CloudRegistrationParams params;
  const auto result =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  // 0.2 rad and 0.36 m are within GICP's reach from the identity, so no feature guess
  // is needed; the answer is exact up to the 3 mm noise and the 5 cm voxels: 0.2 deg
  // and 1 cm.
  EXPECT_FALSE(result.feature_guess_used);
  EXPECT_LT(rotationError(result.target_T_source, truth), 0.2 * PI / 180.0);
  EXPECT_LT((result.target_T_source.translation() - truth.translation()).norm(), 0.01);
  // Same room, all of it seen: nearly every point overlaps, and the residual is the
  // noise (3 mm), not a misalignment.
  EXPECT_GT(result.overlap, 0.95);
  EXPECT_LT(result.residual_m, 0.01);
  EXPECT_TRUE(result.converged);
}

TEST(CloudRegistration, LargeMotionNeedsTheFeatureGuess)
{
  // 1.2 rad (69 deg) and 1.5 m: GICP from the identity falls into a wrong minimum;
  // the FPFH + SampleConsensusPrerejective guess brings it home.
  const auto target = planar_grid_test::syntheticRoom();
  const Eigen::Isometry3d truth = knownMotion(1.2, Eigen::Vector3d(1.0, 1.1, 0.0));
  pcl::PointCloud<pcl::PointXYZ> source;
  pcl::transformPointCloud(target, source, truth.inverse().cast<float>().matrix());

  planar_grid::CloudRegistrationParams params;
  params.seed = 3;
  const auto result =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  EXPECT_TRUE(result.feature_guess_used);
  EXPECT_LT(rotationError(result.target_T_source, truth), 0.2 * PI / 180.0);
  EXPECT_LT((result.target_T_source.translation() - truth.translation()).norm(), 0.01);
  EXPECT_GT(result.overlap, 0.95);
  EXPECT_LT(result.residual_m, 0.01);

  // Without the guess the same pair is not registered: the overlap stays low.
  params.feature_initial_guess = false;
  const auto plain =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  EXPECT_LT(plain.overlap, result.overlap);
}

TEST(CloudRegistration, DegenerateInputGivesTheGuess)
{
  const auto room = planar_grid_test::syntheticRoom();
  const pcl::PointCloud<pcl::PointXYZ> empty;
  const Eigen::Isometry3d guess(Eigen::Translation3d(1.0, 2.0, 3.0));
  for (const auto* pair : {&empty, &room}) {
    const auto result =
      planar_grid::registerCloud(*pair, pair == &empty ? room : empty, guess,
                                 planar_grid::CloudRegistrationParams());
    EXPECT_TRUE(result.target_T_source.isApprox(guess));
    EXPECT_EQ(result.overlap, 0.0);
  }
  // All-NaN points count as none.
  pcl::PointCloud<pcl::PointXYZ> nan_cloud;
  nan_cloud.resize(50, pcl::PointXYZ(NAN, NAN, NAN));
  nan_cloud.is_dense = false;
  const auto result = planar_grid::registerCloud(
    nan_cloud, room, guess, planar_grid::CloudRegistrationParams());
  EXPECT_EQ(result.overlap, 0.0);
}

TEST(CloudRegistration, WithoutImageFeaturesTheCloudsAloneAreRegistered)
{
  // Features without descriptors (a scan's points, or no image at all) give no image
  // guess: the result is registerCloud()'s without features, bit for bit (an 8 cm
  // grid keeps the three registrations short).
  const auto target = planar_grid_test::syntheticRoom(0.08f);
  const Eigen::Isometry3d truth = knownMotion(0.2, Eigen::Vector3d(0.3, -0.2, 0.05));
  pcl::PointCloud<pcl::PointXYZ> source;
  pcl::transformPointCloud(target, source, truth.inverse().cast<float>().matrix());
  planar_grid::StereoFeatures none, points_only;
  points_only.points.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));
  points_only.keypoints_left.emplace_back(cv::Point2f(-1.0f, -1.0f), 1.0f);
  const planar_grid::CloudRegistrationParams params;
  const auto plain =
    planar_grid::registerCloud(source, target, Eigen::Isometry3d::Identity(), params);
  for (const auto* features : {&none, &points_only}) {
    const auto result = planar_grid::registerCloud(
      source, target, Eigen::Isometry3d::Identity(), params, *features, *features);
    EXPECT_FALSE(result.image_feature_guess_used);
    EXPECT_EQ(result.image_feature_inliers, 0u);
    EXPECT_TRUE(result.target_T_source.isApprox(plain.target_T_source, 0.0));
    EXPECT_EQ(result.overlap, plain.overlap);
  }
}

TEST(CloudRegistration, InvalidImageFeatureParametersAreRefused)
{
  // Features with descriptors on both sides make the image guess run; its parameters
  // out of range are a programmer's error, refused before any work.
  const auto room = planar_grid_test::syntheticRoom(0.2f);
  planar_grid::StereoFeatures features;
  features.points.push_back(pcl::PointXYZ(1.0f, 2.0f, 3.0f));
  features.keypoints_left.emplace_back(cv::Point2f(10.0f, 20.0f), 31.0f);
  features.descriptors = cv::Mat::zeros(1, 32, CV_8U);
  planar_grid::CloudRegistrationParams params;
  params.image_feature_min_inliers = 2;
  EXPECT_THROW(planar_grid::registerCloud(room, room, Eigen::Isometry3d::Identity(),
                                          params, features, features),
               planar_grid::Exception);
  params.image_feature_min_inliers = 20;
  params.image_feature_distance_m = 0.0;
  EXPECT_THROW(planar_grid::registerCloud(room, room, Eigen::Isometry3d::Identity(),
                                          params, features, features),
               planar_grid::Exception);
}

namespace {

using CloudI = pcl::PointCloud<pcl::PointXYZI>;
using planar_grid_test::fitIntrinsics;
using planar_grid_test::Intrinsics;
using planar_grid_test::panMotion;
using planar_grid_test::reproject;

/** \brief office1.pcd (Kinect, 640x480, colour) with its colour as grey intensity, as
 * the pipeline reads it; empty when the data folder does not hold it. */
CloudI
loadOffice1()
{
  const std::string path =
    std::string(PLANAR_GRID_DATA_DIR) + "/pcl_clouds/office1.pcd";
  CloudI out;
  pcl::PointCloud<pcl::PointXYZRGB> rgb;
  if (!std::filesystem::exists(path) || pcl::io::loadPCDFile(path, rgb) != 0)
    return out;
  pcl::PointCloudXYZRGBtoXYZI(rgb, out);
  out.width = rgb.width;
  out.height = rgb.height;
  out.is_dense = false;
  return out;
}

pcl::PointCloud<pcl::PointXYZ>
xyzOf(const CloudI& cloud)
{
  pcl::PointCloud<pcl::PointXYZ> out;
  pcl::copyPointCloud(cloud, out);
  return out;
}

} // namespace

// office1's Kinect view and the view from a second camera pose, rendered from
// office1's own points and colours (a real scene, a known motion): the second view
// registered onto the first gives that pose. The image feature guess matches the two
// colour images' key features and starts GICP at the right place.
TEST(CloudRegistration, Office1ReprojectedViewIsRegisteredFromImageFeatures)
{
  const CloudI office1 = loadOffice1();
  if (office1.empty())
    GTEST_SKIP() << "office1.pcd not found";
  const Intrinsics k = fitIntrinsics(office1);
  // The Kinect's: about 525 px, the principal point near the image centre.
  EXPECT_NEAR(k.fx, 525.0, 15.0);
  EXPECT_NEAR(k.fy, 525.0, 15.0);
  // A 25 deg pan and 0.32 m: GICP from the identity does not reach it (registerCloud
  // without features needs its FPFH guess for this pair).
  const Eigen::Isometry3d truth =
    panMotion(25.0 * PI / 180.0, Eigen::Vector3d(0.3, 0.0, 0.1));
  const CloudI view = reproject(office1, k, truth);

  planar_grid::StereoFeatureMatcher::Params detector;
  detector.feature_type = planar_grid::FeatureType::ORB_GRID;
  planar_grid::StereoFeatures target_features, source_features;
  planar_grid::computeCloudImageFeatures(
    office1, planar_grid::cloudIntensityImage(office1), detector,
    Eigen::Affine3f::Identity(), target_features);
  planar_grid::computeCloudImageFeatures(view, planar_grid::cloudIntensityImage(view),
                                         detector, Eigen::Affine3f::Identity(),
                                         source_features);
  ASSERT_GT(target_features.size(), 500u);
  ASSERT_GT(source_features.size(), 100u);

  planar_grid::CloudRegistrationParams params;
  const auto result = planar_grid::registerCloud(xyzOf(view), xyzOf(office1),
                                                 Eigen::Isometry3d::Identity(), params,
                                                 source_features, target_features);
  std::printf("office1 pan 25 deg: rotation error %.3f deg, translation error %.4f m, "
              "overlap %.2f, residual %.4f m, %zu inliers\n",
              rotationError(result.target_T_source, truth) * 180.0 / PI,
              (result.target_T_source.translation() - truth.translation()).norm(),
              result.overlap, result.residual_m, result.image_feature_inliers);
  EXPECT_TRUE(result.image_feature_guess_used);
  // The office's geometry fixes every direction: GICP refines the features' motion.
  EXPECT_FALSE(result.image_feature_motion_kept);
  // 42 inliers measured: half of the second view shows what office1 did not see.
  EXPECT_GE(result.image_feature_inliers, 30u);
  EXPECT_LT(rotationError(result.target_T_source, truth), 0.5 * PI / 180.0);
  EXPECT_LT((result.target_T_source.translation() - truth.translation()).norm(), 0.02);
}

// Measurement (docs/INPUTS.md): office1 and its view from a camera panned by 5 to 45
// degrees, each with its own depth noise, registered from the identity without and
// with the image feature guess.
TEST(CloudRegistration, Office1PanSweepMeasurement)
{
  const CloudI clean = loadOffice1();
  if (clean.empty() || !std::getenv("PLANAR_GRID_MEASURE"))
    GTEST_SKIP() << "set PLANAR_GRID_MEASURE=1 to run (office1.pcd needed)";
  const Intrinsics k = fitIntrinsics(clean);
  // Each view with its own Kinect depth noise (sigma = 0.0016 z^2 m, seeded), so that
  // the two clouds' points differ as two captures' do.
  CloudI office1 = clean;
  planar_grid_test::addDepthNoise(office1, 0.0016f, 11);
  planar_grid::StereoFeatureMatcher::Params detector;
  detector.feature_type = planar_grid::FeatureType::ORB_GRID;
  planar_grid::StereoFeatures target_features;
  planar_grid::computeCloudImageFeatures(
    office1, planar_grid::cloudIntensityImage(office1), detector,
    Eigen::Affine3f::Identity(), target_features);
  for (const double yaw_deg : {5.0, 10.0, 15.0, 20.0, 25.0, 30.0, 35.0, 40.0, 45.0}) {
    const Eigen::Isometry3d truth = panMotion(
      yaw_deg * PI / 180.0, Eigen::Vector3d(0.012 * yaw_deg, 0.0, 0.004 * yaw_deg));
    CloudI view = reproject(clean, k, truth);
    planar_grid_test::addDepthNoise(view, 0.0016f, 12);
    planar_grid::StereoFeatures source_features;
    planar_grid::computeCloudImageFeatures(view, planar_grid::cloudIntensityImage(view),
                                           detector, Eigen::Affine3f::Identity(),
                                           source_features);
    planar_grid::CloudRegistrationParams params;
    for (const bool with_features : {false, true}) {
      pcl::console::TicToc timer;
      timer.tic();
      const auto result =
        with_features
          ? planar_grid::registerCloud(xyzOf(view), xyzOf(office1),
                                       Eigen::Isometry3d::Identity(), params,
                                       source_features, target_features)
          : planar_grid::registerCloud(xyzOf(view), xyzOf(office1),
                                       Eigen::Isometry3d::Identity(), params);
      std::printf(
        "pan %4.1f deg %s: rotation error %7.3f deg, translation error %.4f m, "
        "overlap %.2f, residual %.4f m, guess %s, %zu inliers, %.0f ms\n",
        yaw_deg, with_features ? "image+FPFH" : "FPFH      ",
        rotationError(result.target_T_source, truth) * 180.0 / PI,
        (result.target_T_source.translation() - truth.translation()).norm(),
        result.overlap, result.residual_m,
        result.image_feature_guess_used ? "image"
        : result.feature_guess_used     ? "FPFH "
                                        : "none ",
        result.image_feature_inliers, timer.toc());
    }
  }
}

// office1's colour image on a plane (a poster of the office on a wall, 2.5 m ahead,
// tilted by 10 deg), seen again after a 0.25 m step along the plane and a 3 deg turn
// about its normal. A plane's geometry fixes only three of the six degrees of freedom:
// GICP slides along it from wherever it starts, and the FPFH features of a plane are
// all alike, so the cloud alone gives a wrong motion with a perfect overlap. The
// image's key features fix the step.
TEST(CloudRegistration, TexturedPlaneIsRegisteredOnlyThroughItsImageFeatures)
{
  CloudI poster = loadOffice1();
  if (poster.empty())
    GTEST_SKIP() << "office1.pcd not found";
  const Intrinsics k = fitIntrinsics(poster);
  const Eigen::Vector3d normal =
    Eigen::Vector3d(0.0, std::sin(10.0 * PI / 180.0), std::cos(10.0 * PI / 180.0));
  planar_grid_test::projectOntoPlane(poster, k, normal, 2.5);
  const Eigen::Vector3d along = normal.cross(Eigen::Vector3d::UnitY()).normalized();
  Eigen::Isometry3d truth = Eigen::Isometry3d::Identity();
  truth.linear() = Eigen::AngleAxisd(3.0 * PI / 180.0, normal).toRotationMatrix();
  truth.translation() = 0.25 * along;
  CloudI view = reproject(poster, k, truth);
  // Each view gets its own Kinect depth noise along the rays (sigma = 0.0016 z^2 m,
  // 1 cm at 2.5 m; seeded).
  planar_grid_test::addDepthNoise(poster, 0.0016f, 11);
  planar_grid_test::addDepthNoise(view, 0.0016f, 12);

  planar_grid::StereoFeatureMatcher::Params detector;
  detector.feature_type = planar_grid::FeatureType::ORB_GRID;
  planar_grid::StereoFeatures target_features, source_features;
  planar_grid::computeCloudImageFeatures(
    poster, planar_grid::cloudIntensityImage(poster), detector,
    Eigen::Affine3f::Identity(), target_features);
  planar_grid::computeCloudImageFeatures(view, planar_grid::cloudIntensityImage(view),
                                         detector, Eigen::Affine3f::Identity(),
                                         source_features);
  planar_grid::CloudRegistrationParams params;
  const auto with_features = planar_grid::registerCloud(
    xyzOf(view), xyzOf(poster), Eigen::Isometry3d::Identity(), params, source_features,
    target_features);
  const auto without = planar_grid::registerCloud(
    xyzOf(view), xyzOf(poster), Eigen::Isometry3d::Identity(), params);
  const auto print = [&truth](const char* what,
                              const planar_grid::CloudRegistrationResult& r) {
    std::printf("office1 poster, %s: rotation error %.3f deg, translation error %.4f "
                "m, overlap %.2f, residual %.4f m, %zu image feature inliers\n",
                what, rotationError(r.target_T_source, truth) * 180.0 / PI,
                (r.target_T_source.translation() - truth.translation()).norm(),
                r.overlap, r.residual_m, r.image_feature_inliers);
  };
  print("image features", with_features);
  print("GICP + FPFH", without);
  EXPECT_TRUE(with_features.image_feature_guess_used);
  // GICP's refinement turned the features' motion about the plane's normal (by about
  // 3 deg): the check on the matched features keeps the features' motion.
  EXPECT_TRUE(with_features.image_feature_motion_kept);
  EXPECT_LT(rotationError(with_features.target_T_source, truth), 0.5 * PI / 180.0);
  EXPECT_LT((with_features.target_T_source.translation() - truth.translation()).norm(),
            0.02);
  // The cloud alone: GICP stays near its start along the plane, and the result looks
  // perfect by overlap; it is the failure the image features remove.
  EXPECT_GT((without.target_T_source.translation() - truth.translation()).norm(), 0.1);
  EXPECT_GT(without.overlap, 0.6);
}
