// SPDX-License-Identifier: BSD-3-Clause
// Key features of point-cloud frames (cloud_features): the feature occupancy of the
// paper (Sec. III-D/E) for inputs without a stereo pair.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/cloud_registration.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/filters/uniform_sampling.h>

#include <opencv2/core.hpp>

#include <cmath>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** Where a frame's key features come from. */
enum class FeatureSource {
  AUTO,  // the image of an organized cloud that has one, the points otherwise
  IMAGE, // key points on the organized cloud's image, lifted through its points
  POINTS // the cloud's points, one per cube of point_spacing_m
};

/** The detector's parameters on a cloud's image: orb_grid, 1000 key points (the
 * matcher's stereo defaults are sift and 2000). */
StereoFeatureMatcher::Params
cloudDetectorDefaults()
{
  StereoFeatureMatcher::Params detector;
  detector.feature_type = FeatureType::ORB_GRID;
  detector.max_features = 1000;
  return detector;
}

/** The stage's parameters: the source, the five StereoFeatureMatcher parameters that
 * detect key points on a cloud's image (with this stage's defaults and meanings:
 * no right image, no disparity), and the spacing of point features. */
struct CloudFeaturesParams {
  FeatureSource source{FeatureSource::AUTO};
  StereoFeatureMatcher::Params detector{cloudDetectorDefaults()};
  double point_spacing_m{0.1};
};

const ParamDeclarations<CloudFeaturesParams>&
cloudFeaturesParamDeclarations()
{
  using P = CloudFeaturesParams;
  namespace ranges = stereo_feature_matcher_ranges;
  const auto feature_type_name = [](FeatureType type) {
    return featureTypeName(type);
  };
  static const ParamDeclarations<P> table = {
    declareNamedChoice<P, FeatureSource>(
      "source", [](auto& p) -> auto& { return p.source; },
      {{"auto", FeatureSource::AUTO},
       {"image", FeatureSource::IMAGE},
       {"points", FeatureSource::POINTS}},
      "image: key points on the organized cloud's image (an error when a frame has "
      "none); points: the cloud's points; auto: image when the frame's cloud is "
      "organized and carries colour or intensity, points otherwise."),
    declareChoice<P>(
      "feature_type", [](auto& p) -> auto& { return p.detector.feature_type; },
      featureTypeNames(), feature_type_name, featureTypeFromString,
      "Detector and descriptor on the image: orb_grid (FAST corners bucketed over a "
      "grid, upright ORB), orb (OpenCV defaults), sift. The stage's value; the matcher "
      "defaults to sift."),
    declareInteger<P>(
      "max_features", [](auto& p) -> auto& { return p.detector.max_features; },
      ranges::MAX_FEATURES, "",
      "Most key points detected on the image (orb_grid: spread evenly over the grid "
      "cells). The stage's value; the matcher defaults to "
        + std::to_string(StereoFeatureMatcher::Params().max_features) + "."),
    declareInteger<P>(
      "bucket_size_px", [](auto& p) -> auto& { return p.detector.bucket_size_px; },
      ranges::BUCKET_SIZE, "px", "orb_grid: side of the square grid cells."),
    declareInteger<P>(
      "fast_threshold", [](auto& p) -> auto& { return p.detector.fast_threshold; },
      ranges::FAST_THRESHOLD, "grey levels",
      "orb_grid: cv::FAST segment-test threshold."),
    declareReal<P>(
      "max_range_m", [](auto& p) -> auto& { return p.detector.max_range_m; },
      ranges::MAX_RANGE, "m",
      "Features farther than this from the sensor are dropped."),
    declareReal<P>(
      "point_spacing_m", [](auto& p) -> auto& { return p.point_spacing_m; },
      ParamRange::closed(0.005, 100.0), "m",
      "source points: edge of the cubes of which one point each is a feature."),
  };
  return table;
}

class CloudFeaturesStage : public Stage {
public:
  explicit CloudFeaturesStage(const CloudFeaturesParams& p) :
      stage_params_(p), source_(p.source), params_(p.detector),
      point_spacing_m_(p.point_spacing_m)
  {}

  bool isFrameLocal() const override { return true; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(cloudFeaturesParamDeclarations(), stage_params_, v);
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    frame.features = StereoFeatures();
    from_image_ = false;
    if (!hasPoints(frame, "cloud_features"))
      return;
    // The features are in the camera (sensor) frame, as the stereo front end gives
    // them; a cloud already moved to the world is taken back by its pose.
    camera_T_cloud_ = cameraTCloud(frame);
    if (source_ != FeatureSource::POINTS) {
      const cv::Mat grey = cloudIntensityImage(*frame.cloud);
      if (!grey.empty()) {
        // The same features as the registration of unposed PCD sequences uses.
        computeCloudImageFeatures(*frame.cloud, grey, params_, camera_T_cloud_,
                                  frame.features);
        from_image_ = true;
        return;
      }
      if (source_ == FeatureSource::IMAGE)
        throw Exception(
          "stage 'cloud_features' (source: image): frame " + frame.name
          + (frame.cloud->isOrganized()
               ? " has no image: its cloud carries no colour or intensity"
               : " is not an organized cloud (put cloud_features before voxel_grid "
                 "and the other filters; an unorganized scan takes source: points)"));
    }
    fromPoints(*frame.cloud, frame.features);
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("features", static_cast<double>(frame.features.size()));
    values.emplace_back("from_image", from_image_ ? 1.0 : 0.0);
  }

private:
  /** \a p in the camera frame as \a q; false when \a p is not finite or lies beyond
   * max_range_m. */
  bool toCamera(const pcl::PointXYZI& p, pcl::PointXYZ& q) const
  {
    if (!(std::isfinite(p.x) && std::isfinite(p.y) && std::isfinite(p.z)))
      return false;
    q.getVector3fMap() = camera_T_cloud_ * p.getVector3fMap();
    return q.getVector3fMap().squaredNorm()
           <= static_cast<float>(params_.max_range_m * params_.max_range_m);
  }

  /** One point per cube of point_spacing_m (pcl::UniformSampling keeps the point
   * nearest each cube's centre), without descriptors; the key point of each is at
   * (-1, -1) (no image) and its class_id numbers it. */
  void fromPoints(const Frame::Cloud& cloud, StereoFeatures& out)
  {
    pcl::UniformSampling<pcl::PointXYZI> sampling;
    sampling.setInputCloud(cloud.makeShared());
    sampling.setRadiusSearch(point_spacing_m_);
    sampled_.clear();
    sampling.filter(sampled_);
    for (const auto& p : sampled_.points) {
      pcl::PointXYZ q;
      if (!toCamera(p, q))
        continue;
      out.points.push_back(q);
      out.keypoints_left.emplace_back(cv::Point2f(-1.0f, -1.0f), 1.0f, -1.0f, 0.0f, 0,
                                      static_cast<int>(out.keypoints_left.size()));
    }
  }

  CloudFeaturesParams stage_params_;
  FeatureSource source_;
  StereoFeatureMatcher::Params params_;
  double point_spacing_m_;
  Eigen::Affine3f camera_T_cloud_{Eigen::Affine3f::Identity()};
  Frame::Cloud sampled_;
  bool from_image_{false};
};

} // namespace

StageInfo
cloudFeaturesInfo()
{
  StageInfo info;
  info.type = "cloud_features";
  info.description =
    "Key features of a point-cloud frame, for kl_occupancy_filter without stereo: on "
    "an organized cloud with colour or intensity, key points (orb_grid, orb or sift, "
    "as feature_matching) detected on the cloud's own image and lifted to 3D through "
    "the point of their pixel; on any other cloud (a LiDAR scan), its points, one per "
    "cube of point_spacing_m (pcl::UniformSampling), without descriptors. Put it "
    "before voxel_grid and the other filters, which unorganize the cloud.";
  info.params = paramSpecs(cloudFeaturesParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    CloudFeaturesParams p;
    assignParams(cloudFeaturesParamDeclarations(), v, p);
    return std::make_unique<CloudFeaturesStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
