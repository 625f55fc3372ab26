// SPDX-License-Identifier: BSD-3-Clause
// Key features of point-cloud frames (cloud_features): the feature occupancy of the
// paper (Sec. III-D/E) for inputs without a stereo pair.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>

#include <pcl/filters/uniform_sampling.h>

#include <opencv2/core.hpp>
#include <opencv2/features2d.hpp>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** Margin without orb_grid key points, px: the upright BRIEF pattern of a 31 px patch
 * reaches 15 px from its key point (the stereo front end's value). */
constexpr int ORB_GRID_BORDER_PX = 16;
/** cv::ORB's patch side, px (its default). */
constexpr int ORB_PATCH_SIZE_PX = 31;

/** Where a frame's key features come from. */
enum class FeatureSource {
  AUTO,  // the image of an organized cloud that has one, the points otherwise
  IMAGE, // key points on the organized cloud's image, lifted through its points
  POINTS // the cloud's points, one per cube of point_spacing_m
};

/** \brief The grey image of an organized cloud: one 8-bit pixel per point, from the
 * intensity field (a colour cloud's grey, pcl::PointXYZRGBtoXYZI). Intensities outside
 * [0, 255] (a scanner's own scale) are stretched to it; non-finite ones are 0.
 * \return an empty image when the cloud is not organized or its intensity is the same
 * everywhere (bare x y z: no image) */
cv::Mat
intensityImage(const Frame::Cloud& cloud)
{
  if (!cloud.isOrganized() || cloud.empty())
    return cv::Mat();
  float lo = std::numeric_limits<float>::infinity();
  float hi = -lo;
  for (const auto& p : cloud.points)
    if (std::isfinite(p.intensity)) {
      lo = std::min(lo, p.intensity);
      hi = std::max(hi, p.intensity);
    }
  if (!(hi > lo))
    return cv::Mat();
  float scale = 1.0f, offset = 0.0f;
  if (lo < 0.0f || hi > 255.0f) {
    scale = 255.0f / (hi - lo);
    offset = -lo * scale;
  }
  cv::Mat grey(static_cast<int>(cloud.height), static_cast<int>(cloud.width), CV_8UC1);
  for (int row = 0; row < grey.rows; ++row) {
    auto* out = grey.ptr<std::uint8_t>(row);
    for (int col = 0; col < grey.cols; ++col) {
      const float v = cloud.at(col, row).intensity;
      out[col] = std::isfinite(v) ? cv::saturate_cast<std::uint8_t>(v * scale + offset)
                                  : std::uint8_t{0};
    }
  }
  return grey;
}

class CloudFeaturesStage : public Stage {
public:
  CloudFeaturesStage(FeatureSource source,
                     const StereoFeatureMatcher::Params& detector,
                     double point_spacing_m) :
      source_(source),
      params_(detector), point_spacing_m_(point_spacing_m)
  {
    if (params_.feature_type == FeatureType::ORB_GRID)
      detector_ = cv::ORB::create(params_.max_features, 1.2f, 1, ORB_GRID_BORDER_PX, 0,
                                  2, cv::ORB::HARRIS_SCORE, ORB_PATCH_SIZE_PX,
                                  params_.fast_threshold);
    else if (params_.feature_type == FeatureType::ORB)
      detector_ = cv::ORB::create(params_.max_features);
    else
      detector_ = cv::SIFT::create(params_.max_features);
  }

  bool isFrameLocal() const override { return true; }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    frame.features = StereoFeatures();
    from_image_ = false;
    requirePoints(frame, "cloud_features");
    // The features are in the camera (sensor) frame, as the stereo front end gives
    // them; a cloud already moved to the world is taken back by its pose.
    camera_T_cloud_ = Eigen::Affine3f::Identity();
    if (frame.cloud_in_world_frame)
      camera_T_cloud_ = frame.world_T_camera.inverse().cast<float>();
    if (source_ != FeatureSource::POINTS) {
      const cv::Mat grey = intensityImage(*frame.cloud);
      if (!grey.empty()) {
        fromImage(grey, *frame.cloud, frame.features);
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

  /** Key points on the cloud's image, each lifted to the point of its pixel; key
   * points on a pixel without a finite point, or beyond max_range_m, are dropped. */
  void fromImage(const cv::Mat& grey, const Frame::Cloud& cloud, StereoFeatures& out)
  {
    keypoints_.clear();
    descriptors_.release();
    if (params_.feature_type == FeatureType::ORB_GRID) {
      const int bucket = params_.bucket_size_px;
      const int cells =
        ((grey.cols + bucket - 1) / bucket) * ((grey.rows + bucket - 1) / bucket);
      const int per_cell = (params_.max_features + cells - 1) / cells;
      detectGridFastKeypoints(grey, bucket, per_cell, params_.fast_threshold,
                              ORB_GRID_BORDER_PX, keypoints_);
      detector_->compute(grey, keypoints_, descriptors_);
    } else {
      detector_->detectAndCompute(grey, cv::noArray(), keypoints_, descriptors_);
    }
    std::vector<int> rows;
    for (std::size_t k = 0; k < keypoints_.size(); ++k) {
      const cv::KeyPoint& kp = keypoints_[k];
      const int col = static_cast<int>(std::lround(kp.pt.x));
      const int row = static_cast<int>(std::lround(kp.pt.y));
      if (col < 0 || row < 0 || col >= static_cast<int>(cloud.width)
          || row >= static_cast<int>(cloud.height))
        continue;
      pcl::PointXYZ q;
      if (!toCamera(cloud.at(col, row), q))
        continue;
      out.points.push_back(q);
      out.keypoints_left.push_back(kp);
      rows.push_back(static_cast<int>(k));
    }
    out.descriptors.create(static_cast<int>(rows.size()), descriptors_.cols,
                           descriptors_.type());
    for (std::size_t k = 0; k < rows.size(); ++k)
      descriptors_.row(rows[k]).copyTo(out.descriptors.row(static_cast<int>(k)));
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

  FeatureSource source_;
  StereoFeatureMatcher::Params params_;
  double point_spacing_m_;
  cv::Ptr<cv::Feature2D> detector_;
  Eigen::Affine3f camera_T_cloud_{Eigen::Affine3f::Identity()};
  std::vector<cv::KeyPoint> keypoints_;
  cv::Mat descriptors_;
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
  const StereoFeatureMatcher::Params f;
  info.params = {
    ParamSpec::choice("source", "auto", {"auto", "image", "points"},
                      "image: key points on the organized cloud's image (an error "
                      "when a frame has none); points: the cloud's points; auto: "
                      "image when the frame's cloud is organized and carries colour or "
                      "intensity, points otherwise."),
    ParamSpec::choice("feature_type", "orb_grid", {"sift", "orb", "orb_grid"},
                      "Detector and descriptor on the image: orb_grid (FAST corners "
                      "bucketed over a grid, upright ORB), orb (OpenCV defaults), "
                      "sift."),
    ParamSpec::integer("max_features", 1000, 10, 100000, "",
                       "Most key points detected on the image (orb_grid: spread "
                       "evenly over the grid cells)."),
    ParamSpec::integer("bucket_size_px", f.bucket_size_px, 8, 1024, "px",
                       "orb_grid: side of the square grid cells."),
    ParamSpec::integer("fast_threshold", f.fast_threshold, 1, 255, "grey levels",
                       "orb_grid: cv::FAST segment-test threshold."),
    ParamSpec::real("max_range_m", f.max_range_m, 0.1, 1000.0, "m",
                    "Features farther than this from the sensor are dropped."),
    ParamSpec::real("point_spacing_m", 0.1, 0.005, 100.0, "m",
                    "source points: edge of the cubes of which one point each is a "
                    "feature."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    StereoFeatureMatcher::Params p;
    p.feature_type = featureTypeFromString(v.getChoice("feature_type"));
    p.max_features = v.getInt("max_features");
    p.bucket_size_px = v.getInt("bucket_size_px");
    p.fast_threshold = v.getInt("fast_threshold");
    p.max_range_m = v.getDouble("max_range_m");
    const std::string source = v.getChoice("source");
    return std::make_unique<CloudFeaturesStage>(source == "image" ? FeatureSource::IMAGE
                                                : source == "points"
                                                  ? FeatureSource::POINTS
                                                  : FeatureSource::AUTO,
                                                p, v.getDouble("point_spacing_m"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
