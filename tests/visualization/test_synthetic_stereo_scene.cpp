// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/synthetic_stereo_scene.h>

#include <pcl/io/pcd_io.h>

#include <gtest/gtest.h>
#include <opencv2/imgcodecs.hpp>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

namespace {

namespace fs = std::filesystem;
using planar_grid::SyntheticPlane;
using planar_grid::SyntheticSceneKind;
using planar_grid::SyntheticStereoScene;

/** \brief Parameters of a scene of \a kind with yaw and lean, radians. */
SyntheticStereoScene::Params
sceneParams(SyntheticSceneKind kind, double yaw_rad, double lean_rad, int frames = 4)
{
  SyntheticStereoScene::Params params;
  params.kind = kind;
  params.scene_yaw_rad = yaw_rad;
  params.wall_lean_rad = lean_rad;
  params.frame_count = frames;
  return params;
}

/** \brief The plane called \a name; fails the test when there is none. */
const SyntheticPlane&
planeNamed(const SyntheticStereoScene& scene, const std::string& name)
{
  for (const auto& plane : scene.getPlanes())
    if (plane.name == name)
      return plane;
  ADD_FAILURE() << "no plane '" << name << "'";
  return scene.getPlanes().front();
}

/** \brief Area of a convex polygon, m^2 (fan of triangles). */
double
polygonArea(const SyntheticPlane& plane)
{
  Eigen::Vector3d sum = Eigen::Vector3d::Zero();
  for (std::size_t k = 1; k + 1 < plane.polygon.size(); ++k)
    sum += (plane.polygon[k] - plane.polygon[0])
             .cross(plane.polygon[k + 1] - plane.polygon[0]);
  return 0.5 * sum.norm();
}

/** \brief Brute-force ray casting, written independently of the scene's code: the
 * nearest intersection of the ray o + t d (t > 0) with the planes' convex polygons.
 * \return t of the hit (+inf when none); \a plane_index gets the polygon hit */
double
castRay(const SyntheticStereoScene& scene,
        const Eigen::Vector3d& origin,
        const Eigen::Vector3d& direction,
        int& plane_index)
{
  double best = std::numeric_limits<double>::infinity();
  plane_index = -1;
  const auto& planes = scene.getPlanes();
  for (std::size_t k = 0; k < planes.size(); ++k) {
    const Eigen::Vector3d n = planes[k].model_coefficients.head<3>();
    const double denominator = n.dot(direction);
    if (std::abs(denominator) < 1e-12)
      continue;
    const double t = -(n.dot(origin) + planes[k].model_coefficients[3]) / denominator;
    if (!(t > 0.0) || t >= best)
      continue;
    const Eigen::Vector3d p = origin + t * direction;
    // Inside the convex polygon: on the inner side of every edge (counter-clockwise
    // about n).
    bool inside = true;
    const auto& polygon = planes[k].polygon;
    for (std::size_t e = 0; e < polygon.size() && inside; ++e) {
      const Eigen::Vector3d& a = polygon[e];
      const Eigen::Vector3d& b = polygon[(e + 1) % polygon.size()];
      inside = (b - a).cross(p - a).dot(n) >= 0.0;
    }
    if (inside) {
      best = t;
      plane_index = static_cast<int>(k);
    }
  }
  return best;
}

/** \brief The ray of pixel (u, v) of the left camera of \a frame, world frame, with
 * camera z component 1 (so that t is the z depth). */
void
pixelRay(const SyntheticStereoScene& scene,
         std::size_t frame,
         double u,
         double v,
         Eigen::Vector3d& origin,
         Eigen::Vector3d& direction)
{
  const auto& calibration = scene.getCalibration();
  const Eigen::Isometry3d pose = scene.getCameraPose(frame);
  origin = pose.translation();
  direction =
    pose.linear()
    * Eigen::Vector3d((u - calibration.cx_px) / calibration.focal_length_px,
                      (v - calibration.cy_px) / calibration.focal_length_px, 1.0);
}

/** \brief Rendering tests: skipped without an X display, each with its own folder. */
class SyntheticStereoSceneTest : public ::testing::Test {
protected:
  void SetUp() override
  {
    if (!planar_grid::hasDisplay())
      GTEST_SKIP() << "no X display; run under xvfb-run -a";
    dir_ = fs::temp_directory_path()
           / (std::string("planar_grid_test_synthetic_")
              + ::testing::UnitTest::GetInstance()->current_test_info()->name() + "_"
              + std::to_string(::getpid()));
    fs::create_directories(dir_);
  }

  void TearDown() override
  {
    std::error_code ec;
    if (!dir_.empty())
      fs::remove_all(dir_, ec);
  }

  /** \brief A per-test folder, removed afterwards. */
  fs::path dir_;
};

TEST(SyntheticStereoScene, PlanesHaveUnitNormalsFacingTheCameraPath)
{
  for (const auto kind : {SyntheticSceneKind::CORRIDOR, SyntheticSceneKind::ROOM}) {
    const SyntheticStereoScene scene(sceneParams(kind, 0.4, 0.2));
    ASSERT_GE(scene.getPlanes().size(), 10u);
    const Eigen::Vector3d camera = scene.getCameraPose(0).translation();
    for (const auto& plane : scene.getPlanes()) {
      const Eigen::Vector3d n = plane.model_coefficients.head<3>();
      EXPECT_NEAR(n.norm(), 1.0, 1e-12) << plane.name;
      ASSERT_GE(plane.polygon.size(), 3u) << plane.name;
      for (const auto& corner : plane.polygon)
        EXPECT_NEAR(n.dot(corner) + plane.model_coefficients[3], 0.0, 1e-9)
          << plane.name;
      // Walls, floor and ceiling face the camera (their normal points into the free
      // space the camera is in).
      if (plane.name.find("wall") != std::string::npos || plane.name == "floor"
          || plane.name == "ceiling") {
        EXPECT_GT(n.dot(camera) + plane.model_coefficients[3], 0.0) << plane.name;
      }
    }
    // The floor is z = 0 with the normal up, whatever the yaw.
    const auto& floor = planeNamed(scene, "floor");
    EXPECT_NEAR((floor.model_coefficients - Eigen::Vector4d(0, 0, 1, 0)).norm(), 0.0,
                1e-12);
    EXPECT_NEAR(floor.tilt_rad, 0.0, 1e-9);
    // The camera is level at 1.2 m.
    EXPECT_NEAR(camera.z(), 1.2, 1e-12);
  }
}

TEST(SyntheticStereoScene, YawRotatesCoefficientsAndPosesAboutZ)
{
  // Same scene at yaw 0 and 0.5 rad: every normal turns by Rz(0.5), d stays (the
  // rotation is about the origin), the camera poses turn with the scene, and a wall's
  // tilt to the map axes becomes 0.5 rad (< pi/4, so the nearest axis is still its
  // own).
  const double yaw = 0.5;
  const double lean = 0.2;
  const SyntheticStereoScene straight(sceneParams(SyntheticSceneKind::ROOM, 0.0, lean));
  const SyntheticStereoScene turned(sceneParams(SyntheticSceneKind::ROOM, yaw, lean));
  const Eigen::Matrix3d rz = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).matrix();
  ASSERT_EQ(straight.getPlanes().size(), turned.getPlanes().size());
  for (std::size_t k = 0; k < straight.getPlanes().size(); ++k) {
    const auto& a = straight.getPlanes()[k];
    const auto& b = turned.getPlanes()[k];
    ASSERT_EQ(a.name, b.name);
    const Eigen::Vector3d na = a.model_coefficients.head<3>();
    const Eigen::Vector3d nb = b.model_coefficients.head<3>();
    EXPECT_NEAR((rz * na - nb).norm(), 0.0, 1e-12) << a.name;
    EXPECT_NEAR(a.model_coefficients[3], b.model_coefficients[3], 1e-12) << a.name;
    EXPECT_EQ(a.texture_seed, b.texture_seed) << a.name;
  }
  for (const char* wall : {"left_wall", "right_wall", "near_wall"}) {
    EXPECT_NEAR(planeNamed(straight, wall).tilt_rad, 0.0, 1e-9) << wall;
    EXPECT_NEAR(planeNamed(turned, wall).tilt_rad, yaw, 1e-9) << wall;
  }
  // The far wall leans by `lean` from vertical, top away from the camera: its normal
  // (into the room, -x) tilts up, n = (-cos l, 0, sin l), through the foot x = 8 m.
  const auto& far_wall = planeNamed(straight, "far_wall");
  EXPECT_NEAR(
    (far_wall.model_coefficients
     - Eigen::Vector4d(-std::cos(lean), 0.0, std::sin(lean), 8.0 * std::cos(lean)))
      .norm(),
    0.0, 1e-12);
  EXPECT_NEAR(far_wall.tilt_rad, lean, 1e-9);
  // The ramp's slope is 15 degrees.
  EXPECT_NEAR(planeNamed(straight, "ramp_top").tilt_rad, 15.0 * M_PI / 180.0, 1e-9);
  for (std::size_t i = 0; i < straight.getFrameCount(); ++i)
    EXPECT_NEAR((turned.getCameraPose(i).matrix()
                 - (Eigen::Isometry3d(rz) * straight.getCameraPose(i)).matrix())
                  .norm(),
                0.0, 1e-12);
}

TEST(SyntheticStereoScene, SamplePointsLieOnTheSurfacesAtTheRequestedDensity)
{
  const SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::ROOM, 0.3, 0.2));
  pcl::PointCloud<pcl::PointXYZ> cloud;
  const double spacing = 0.05;
  scene.samplePoints(spacing, cloud);
  // One point per spacing^2 of surface, plus the grid rows on the polygons' edges.
  double area = 0.0;
  for (const auto& plane : scene.getPlanes())
    area += polygonArea(plane);
  const double expected = area / (spacing * spacing);
  EXPECT_GT(static_cast<double>(cloud.size()), 0.97 * expected);
  EXPECT_LT(static_cast<double>(cloud.size()), 1.08 * expected);
  EXPECT_EQ(cloud.width, cloud.size());
  // Every point on a surface; float storage of coordinates up to ~10 m: 1e-6 m.
  double worst = 0.0;
  for (std::size_t i = 0; i < cloud.size(); i += 7)
    worst = std::max(worst,
                     scene.distanceToSurface(cloud[i].getVector3fMap().cast<double>()));
  EXPECT_LT(worst, 5e-6);
}

TEST(SyntheticStereoScene, DistanceToSurfaceIsPointToPolygon)
{
  const SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::ROOM, 0.0, 0.0));
  // 1 m in front of the near wall (x = 0), 1.5 m from floor and ceiling.
  EXPECT_NEAR(scene.distanceToSurface(Eigen::Vector3d(1.0, 0.0, 1.5)), 1.0, 1e-12);
  // 1 m behind the near wall, inside its outline: the plane distance.
  EXPECT_NEAR(scene.distanceToSurface(Eigen::Vector3d(-1.0, 0.0, 1.5)), 1.0, 1e-12);
  // Beyond the corner of the near and right walls (the vertical edge x = 0, y = -3):
  // distance to the edge, sqrt(1 + 1), not to either infinite plane (1).
  EXPECT_NEAR(scene.distanceToSurface(Eigen::Vector3d(-1.0, -4.0, 1.5)), std::sqrt(2.0),
              1e-12);
  // Above the table top (z = 0.75) at its centre.
  EXPECT_NEAR(scene.distanceToSurface(Eigen::Vector3d(6.0, -1.8, 0.95)), 0.2, 1e-12);
  EXPECT_TRUE(
    std::isinf(scene.distanceToSurface(Eigen::Vector3d(std::nan(""), 0.0, 0.0))));
}

TEST(SyntheticStereoScene, InvalidParametersThrow)
{
  using planar_grid::Exception;
  const auto make = [](auto change) {
    SyntheticStereoScene::Params params;
    change(params);
    SyntheticStereoScene scene(params);
  };
  EXPECT_THROW(make([](auto& p) { p.wall_lean_rad = 0.6; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.frame_count = 0; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.step_m = -0.1; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.focal_length_px = 0.0; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.baseline_m = -0.5; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.scene_yaw_rad = std::nan(""); }), Exception);
  EXPECT_THROW(make([](auto& p) { p.width_px = 8; }), Exception);
  EXPECT_THROW(make([](auto& p) { p.texel_m = 0.0; }), Exception);
  // The room's path must end by x = 5 m: 0.8 m + 29 * 0.15 m = 5.15 m does not.
  EXPECT_THROW(make([](auto& p) {
                 p.kind = SyntheticSceneKind::ROOM;
                 p.frame_count = 30;
               }),
               Exception);
  EXPECT_NO_THROW(make([](auto& p) {
    p.kind = SyntheticSceneKind::ROOM;
    p.frame_count = 29;
  }));
  EXPECT_THROW(planar_grid::syntheticSceneKindFromString("hall"), Exception);
  EXPECT_EQ(planar_grid::syntheticSceneKindFromString("room"),
            SyntheticSceneKind::ROOM);

  const SyntheticStereoScene scene(
    sceneParams(SyntheticSceneKind::CORRIDOR, 0.0, 0.0, 3));
  EXPECT_THROW(scene.getCameraPose(3), Exception);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  EXPECT_THROW(scene.samplePoints(0.0, cloud), Exception);
  EXPECT_THROW(scene.samplePoints(1e-5, cloud), Exception); // billions of points
  // The frame is checked before the display.
  SyntheticStereoScene renderable(sceneParams(SyntheticSceneKind::ROOM, 0.0, 0.0, 2));
  cv::Mat left, right;
  EXPECT_THROW(renderable.render(2, left, right), Exception);
}

TEST_F(SyntheticStereoSceneTest, ZBufferDepthEqualsRayCasting)
{
  // A turned corridor with a leaning wall, from frame 2; every 8th pixel whose ray and
  // its 8 neighbours' rays hit the same polygon (not at an edge, where rasterisation
  // may pick either side).
  SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::CORRIDOR, 0.3, 0.15));
  const std::size_t frame = 2;
  cv::Mat left, right, depth;
  scene.render(frame, left, right, &depth);
  ASSERT_EQ(depth.type(), CV_32FC1);
  ASSERT_EQ(depth.rows, 372);
  ASSERT_EQ(depth.cols, 1344);
  ASSERT_EQ(left.type(), CV_8UC1);
  ASSERT_EQ(right.size(), left.size());

  int compared = 0;
  double worst_excess = -1.0, worst_error = 0.0;
  for (int v = 1; v < depth.rows - 1; v += 8)
    for (int u = 1; u < depth.cols - 1; u += 8) {
      Eigen::Vector3d origin, direction;
      int index = -1;
      pixelRay(scene, frame, u, v, origin, direction);
      const double z = castRay(scene, origin, direction, index);
      ASSERT_TRUE(std::isfinite(z)) << "the corridor is closed: every ray hits";
      bool interior = true;
      for (int dv = -1; dv <= 1 && interior; ++dv)
        for (int du = -1; du <= 1 && interior; ++du) {
          int neighbour = -1;
          pixelRay(scene, frame, u + du, v + dv, origin, direction);
          castRay(scene, origin, direction, neighbour);
          interior = neighbour == index;
        }
      if (!interior)
        continue;
      // 1 mm plus two steps of the 24-bit depth buffer at depth z: the window depth
      // is (1/n - 1/z) / (1/n - 1/f) with n = 0.1 m, f = 100 m, so one step is
      // z^2 (1/n - 1/f) 2^-24 (0.24 mm at 20 m).
      const double tolerance =
        1e-3 + 2.0 * z * z * (1.0 / 0.1 - 1.0 / 100.0) * 0x1.0p-24;
      const double error = std::abs(depth.at<float>(v, u) - z);
      worst_error = std::max(worst_error, error);
      worst_excess = std::max(worst_excess, error - tolerance);
      EXPECT_LE(error, tolerance) << "pixel (" << u << ", " << v << "), z = " << z;
      ++compared;
    }
  std::cout << "[ measured ] z-buffer vs ray casting: " << compared
            << " pixels, largest error " << worst_error * 1e3 << " mm\n";
  EXPECT_GT(compared, 5000); // of 168 x 47 = 7896 sampled pixels
}

TEST_F(SyntheticStereoSceneTest, SGBMDisparityMatchesTheTruth)
{
  // The pipeline's stereo (OpenCV SGBM, 128 disparities, 5 px blocks, as
  // config/karlsruhe.yaml) on frame 0 of the corridor against d = f B / z. Pixels
  // counted: truth disparity in [2, 126] px (SGBM searches 0..127; the near walls have
  // up to 300 px) and column >= 128 (SGBM leaves the first 128 columns empty). Of
  // those, the pixels whose surface point the right camera sees too (ray cast from
  // the right camera; the pillars and boxes hide parts of the right wall from one
  // camera only) are the matchable ones.
  SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::CORRIDOR, 0.0, 0.0));
  cv::Mat left, right, depth;
  scene.render(0, left, right, &depth);
  planar_grid::DisparityEstimator estimator;
  cv::Mat disparity;
  estimator.compute(left, right, disparity);
  const auto& calibration = scene.getCalibration();
  const double fb = calibration.focal_length_px * calibration.baseline_m;
  const Eigen::Isometry3d pose = scene.getCameraPose(0);
  const Eigen::Vector3d right_centre =
    pose * Eigen::Vector3d(calibration.baseline_m, 0.0, 0.0);

  struct Counts {
    std::size_t measurable{0}, valid{0}, bad1{0};
    double abs_error_sum{0.0};
  } all, matchable;
  for (int v = 0; v < depth.rows; ++v)
    for (int u = 128; u < depth.cols; ++u) {
      const float z = depth.at<float>(v, u);
      if (!(z > 0.0f))
        continue;
      const double truth = fb / z;
      if (truth < 2.0 || truth > 126.0)
        continue;
      Eigen::Vector3d origin, direction;
      pixelRay(scene, 0, u, v, origin, direction);
      const Eigen::Vector3d point = origin + static_cast<double>(z) * direction;
      int index = -1;
      const double to_point = (point - right_centre).norm();
      const double hit =
        castRay(scene, right_centre, (point - right_centre) / to_point, index);
      const bool seen_by_both = hit > to_point - 0.01;
      const float d = disparity.at<float>(v, u);
      const bool valid = std::isfinite(d) && d > 0.0f;
      const double error = valid ? std::abs(d - truth) : 0.0;
      for (Counts* counts : {&all, seen_by_both ? &matchable : nullptr}) {
        if (counts == nullptr)
          continue;
        ++counts->measurable;
        if (!valid)
          continue;
        ++counts->valid;
        counts->abs_error_sum += error;
        counts->bad1 += error > 1.0 ? 1 : 0;
      }
    }
  ASSERT_GT(matchable.measurable, 100000u);
  const auto report = [](const char* what, const Counts& c) {
    std::cout << "[ measured ] SGBM on the corridor, frame 0, " << what << ": "
              << c.measurable << " pixels, density "
              << static_cast<double>(c.valid) / static_cast<double>(c.measurable)
              << ", bad-1 "
              << static_cast<double>(c.bad1) / static_cast<double>(c.valid)
              << ", mean |error| " << c.abs_error_sum / static_cast<double>(c.valid)
              << " px\n";
  };
  report("all in range", all);
  report("seen by both cameras", matchable);
  // Measured (seed 1): seen by both, density 0.84 and bad-1 2.6 %; all in range, 0.79
  // and 3.0 %. Most bad pixels are on the right wall, which the right camera (0.57 m
  // nearer to it) sees compressed to half the width, and on the faces seen edge-on.
  // The floor and ceiling are good to 1 %, with a bias of -0.2 / +0.2 px: the
  // one-pass MODE_SGBM aggregates only along paths from the left and from above, and
  // their disparity grows / shrinks downwards (full_dp, 8 paths, removes it: -0.25 px
  // becomes 0.0005 px on the central floor).
  EXPECT_GT(static_cast<double>(matchable.valid)
              / static_cast<double>(matchable.measurable),
            0.8);
  EXPECT_LT(static_cast<double>(matchable.bad1) / static_cast<double>(matchable.valid),
            0.04);
  EXPECT_GT(static_cast<double>(all.valid) / static_cast<double>(all.measurable), 0.75);
  EXPECT_LT(static_cast<double>(all.bad1) / static_cast<double>(all.valid), 0.05);
}

TEST_F(SyntheticStereoSceneTest, SIFTFeaturesMatchAndLieOnTheSurfaces)
{
  // StereoFeatureMatcher (SIFT, as the pipeline) on frame 0 of the room; the features,
  // triangulated and moved to the world, must lie on the true surfaces up to the
  // stereo depth error (z^2 / (f B) * 0.5 px: 8 cm at 7 m).
  SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::ROOM, 0.0, 0.2));
  cv::Mat left, right;
  scene.render(0, left, right);
  planar_grid::StereoFeatureMatcher matcher;
  planar_grid::StereoFeatures features;
  matcher.match(left, right, scene.getCalibration(), features);
  const Eigen::Isometry3d pose = scene.getCameraPose(0);
  std::vector<double> distances;
  for (const auto& p : features.points)
    distances.push_back(
      scene.distanceToSurface(pose * p.getVector3fMap().cast<double>()));
  ASSERT_FALSE(distances.empty());
  std::sort(distances.begin(), distances.end());
  const double median = distances[distances.size() / 2];
  const double p90 = distances[distances.size() * 9 / 10];
  std::cout << "[ measured ] SIFT on the room, frame 0: " << features.size()
            << " matches, distance to the true surface: median " << median * 1e3
            << " mm, 90th percentile " << p90 * 1e3 << " mm\n";
  EXPECT_GT(features.size(), 500u);
  EXPECT_LT(median, 0.02);
  EXPECT_LT(p90, 0.1);
}

TEST_F(SyntheticStereoSceneTest, ImagesDoNotDependOnTheYaw)
{
  // The yaw turns the scene and the path together: the same images up to rounding in
  // the rasteriser (a few pixels on polygon edges).
  SyntheticStereoScene straight(sceneParams(SyntheticSceneKind::ROOM, 0.0, 0.1));
  SyntheticStereoScene turned(sceneParams(SyntheticSceneKind::ROOM, 0.7, 0.1));
  cv::Mat a_left, a_right, b_left, b_right;
  straight.render(1, a_left, a_right);
  turned.render(1, b_left, b_right);
  cv::Mat diff;
  cv::absdiff(a_left, b_left, diff);
  const double mean = cv::mean(diff)[0];
  std::cout << "[ measured ] yaw 0 vs 0.7 rad: mean |difference| " << mean
            << " grey levels\n";
  EXPECT_LT(mean, 1.0);
  // The images are textured (SGBM and SIFT need contrast everywhere).
  cv::Scalar image_mean, image_stddev;
  cv::meanStdDev(a_left, image_mean, image_stddev);
  EXPECT_GT(image_stddev[0], 25.0);
}

TEST_F(SyntheticStereoSceneTest, WrittenSequenceLoadsThroughThePipelineConfig)
{
  SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::ROOM, 0.25, 0.1, 2));
  scene.writeSequence(dir_.string());
  for (const char* file : {"calib.txt", "poses.txt", "truth.pcd", "scene.json",
                           "pipeline.yaml", "left/000000.png", "right/000001.png"})
    EXPECT_TRUE(fs::exists(dir_ / file)) << file;

  // The config loader is strict: every stage and key of pipeline.yaml must be valid.
  const planar_grid::PipelineConfig config =
    planar_grid::loadPipelineConfig((dir_ / "pipeline.yaml").string());
  EXPECT_GE(config.stages.size(), 10u);
  EXPECT_EQ(fs::path(config.output.folder), dir_ / "output");
  const auto source = planar_grid::createFrameSource(config.input);
  ASSERT_EQ(source->size(), 2u);
  planar_grid::Frame frame;
  source->load(1, frame);

  // Exactly the rendered images, calibration and pose (shortest round-trip numbers).
  cv::Mat left, right;
  scene.render(1, left, right);
  ASSERT_EQ(frame.left.size(), left.size());
  EXPECT_EQ(cv::norm(frame.left, left, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(frame.right, right, cv::NORM_INF), 0.0);
  const auto& expected = scene.getCalibration();
  EXPECT_EQ(frame.calibration.focal_length_px, expected.focal_length_px);
  EXPECT_EQ(frame.calibration.cx_px, expected.cx_px);
  EXPECT_EQ(frame.calibration.cy_px, expected.cy_px);
  EXPECT_DOUBLE_EQ(frame.calibration.baseline_m, expected.baseline_m);
  ASSERT_TRUE(frame.has_pose);
  EXPECT_EQ((frame.world_T_camera.matrix() - scene.getCameraPose(1).matrix())
              .cwiseAbs()
              .maxCoeff(),
            0.0);

  // The truth cloud is samplePoints() at 2 cm.
  pcl::PointCloud<pcl::PointXYZ> truth, sampled;
  ASSERT_EQ(pcl::io::loadPCDFile((dir_ / "truth.pcd").string(), truth), 0);
  scene.samplePoints(0.02, sampled);
  EXPECT_EQ(truth.size(), sampled.size());

  // scene.json names every plane with its coefficients.
  std::ifstream json_file(dir_ / "scene.json");
  std::stringstream json;
  json << json_file.rdbuf();
  for (const auto& plane : scene.getPlanes())
    EXPECT_NE(json.str().find("\"" + plane.name + "\""), std::string::npos)
      << plane.name;
  EXPECT_NE(json.str().find("model_coefficients"), std::string::npos);
}

TEST(SyntheticStereoScene, WithoutDisplayRenderThrows)
{
  if (planar_grid::hasDisplay())
    GTEST_SKIP() << "a display is available";
  SyntheticStereoScene scene(sceneParams(SyntheticSceneKind::ROOM, 0.0, 0.0, 2));
  cv::Mat left, right;
  EXPECT_THROW(scene.render(0, left, right), planar_grid::Exception);
}

} // namespace
