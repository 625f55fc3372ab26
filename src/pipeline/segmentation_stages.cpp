// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/common/transforms.h>
#include <pcl/console/print.h>

#include <cmath>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class MultiPlaneSegmentationStage : public Stage {
public:
  MultiPlaneSegmentationStage(const ParamValues& v) :
      use_features_(v.getChoice("sample") == "features")
  {
    segmentation_.setDistanceThreshold(v.getDouble("distance_threshold_m"));
    segmentation_.setSampleDistanceThreshold(
      v.getDouble("sample_distance_threshold_m"));
    segmentation_.setMaxPlanes(v.getInt("max_planes"));
    segmentation_.setMinInliers(v.getInt("min_inliers"));
    segmentation_.setMinSampleInliers(v.getInt("min_sample_inliers"));
    segmentation_.setMinRemainingFraction(v.getDouble("min_remaining_fraction"));
    segmentation_.setMaxIterations(v.getInt("max_iterations"));
    const std::string& method = v.getChoice("method");
    segmentation_.setMethodType(method == "msac"     ? SACMethod::MSAC
                                : method == "prosac" ? SACMethod::PROSAC
                                                     : SACMethod::RANSAC);
    segmentation_.setOptimizeCoefficients(v.getBool("optimize_coefficients"));
    segmentation_.setDenseHypothesis(v.getBool("dense_hypothesis"));
    segmentation_.setLocalOptimizationIterations(v.getInt("lo_iterations"));
    segmentation_.setMergePlanes(v.getBool("merge_planes"));
    segmentation_.setMergeAngleThreshold(v.getDouble("merge_angle_rad"));
    segmentation_.setMergeDistanceThreshold(v.getDouble("merge_distance_m"));
    segmentation_.setSeed(static_cast<unsigned>(v.getInt("seed")));
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    requirePoints(frame, "multi_plane_segmentation");
    segmentation_.setInputCloud(frame.cloud);
    segmentation_.setUpAxis(upAxis(frame));
    pcl::PointCloud<pcl::PointXYZI>::Ptr sample;
    if (use_features_) {
      if (frame.features.size() < 3)
        throw Exception("multi_plane_segmentation with sample: features needs the "
                        "'feature_matching' stage before it (frame "
                        + frame.name + " has " + std::to_string(frame.features.size())
                        + " features)");
      // The features are in the camera frame; bring them to the cloud's frame.
      sample.reset(new pcl::PointCloud<pcl::PointXYZI>);
      sample->resize(frame.features.points.size());
      for (std::size_t i = 0; i < sample->size(); ++i)
        (*sample)[i].getVector3fMap() = frame.features.points[i].getVector3fMap();
      if (frame.cloud_in_world_frame)
        pcl::transformPointCloud(*sample, *sample,
                                 frame.world_T_camera.cast<float>().matrix());
    }
    segmentation_.setSampleCloud(sample);
    segmentation_.segment(frame.planes);
    if (frame.planes.empty())
      PCL_WARN("[planar_grid::multi_plane_segmentation] No plane found in frame %s.\n",
               frame.name.c_str());
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    std::size_t inliers = 0;
    for (const auto& plane : frame.planes)
      inliers += plane.inliers.indices.size();
    values.emplace_back("planes", static_cast<double>(frame.planes.size()));
    values.emplace_back("plane_inliers", static_cast<double>(inliers));
  }

private:
  SACMultiPlaneSegmentation<pcl::PointXYZI> segmentation_;
  bool use_features_;
};

class GroundRemovalStage : public Stage {
public:
  GroundRemovalStage(double eps_angle_rad, double min_sensor_height_m) :
      cos_eps_(std::cos(eps_angle_rad)), min_sensor_height_m_(min_sensor_height_m)
  {}

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    requirePoints(frame, "ground_removal");
    frame.has_ground = false;
    removed_ = 0;
    const Eigen::Vector3f up = upAxis(frame);
    const Eigen::Vector3f origin = sensorOrigin(frame);
    // The dominant plane (planes are sorted by inlier count) that faces up within
    // eps_angle and lies at least min_sensor_height below the sensor.
    std::size_t ground = frame.planes.size();
    Eigen::Vector4f coefficients = Eigen::Vector4f::Zero();
    for (std::size_t k = 0; k < frame.planes.size(); ++k) {
      const auto& values = frame.planes[k].model_coefficients.values;
      if (values.size() != 4)
        continue;
      Eigen::Vector4f c(values[0], values[1], values[2], values[3]);
      if (c.head<3>().dot(up) < 0.0f)
        c = -c; // normal up: the sensor's signed distance is its height above the plane
      if (c.head<3>().dot(up) < cos_eps_)
        continue;
      if (c.head<3>().dot(origin) + c[3] < min_sensor_height_m_)
        continue;
      ground = k;
      coefficients = c;
      break;
    }
    if (ground == frame.planes.size())
      return;

    frame.has_ground = true;
    frame.ground_coefficients = coefficients;
    const auto& ground_indices = frame.planes[ground].inliers.indices;
    removed_ = ground_indices.size();
    auto& cloud = *frame.cloud;
    if (cloud.isOrganized()) {
      // Keep the image structure: ground points become NaN, other indices stay valid.
      const float nan = std::numeric_limits<float>::quiet_NaN();
      for (const auto i : ground_indices)
        cloud[static_cast<std::size_t>(i)].x = cloud[static_cast<std::size_t>(i)].y =
          cloud[static_cast<std::size_t>(i)].z = nan;
      cloud.is_dense = false;
    } else {
      // Compact the cloud and renumber the other planes' inliers.
      std::vector<int> new_index(cloud.size(), 0);
      for (const auto i : ground_indices)
        new_index[static_cast<std::size_t>(i)] = -1;
      Frame::Cloud::Ptr out(new Frame::Cloud);
      out->header = cloud.header;
      out->sensor_origin_ = cloud.sensor_origin_;
      out->sensor_orientation_ = cloud.sensor_orientation_;
      out->reserve(cloud.size() - ground_indices.size());
      for (std::size_t i = 0; i < cloud.size(); ++i) {
        if (new_index[i] < 0)
          continue;
        new_index[i] = static_cast<int>(out->size());
        out->push_back(cloud[i]);
      }
      out->is_dense = cloud.is_dense;
      for (std::size_t k = 0; k < frame.planes.size(); ++k) {
        if (k == ground)
          continue;
        for (auto& i : frame.planes[k].inliers.indices)
          i = new_index[static_cast<std::size_t>(i)];
      }
      frame.cloud = out;
    }
    frame.planes.erase(frame.planes.begin() + static_cast<std::ptrdiff_t>(ground));
  }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("ground_found", frame.has_ground ? 1.0 : 0.0);
    values.emplace_back("ground_points", static_cast<double>(removed_));
  }

private:
  float cos_eps_;
  float min_sensor_height_m_;
  std::size_t removed_{0};
};

} // namespace

StageInfo
multiPlaneSegmentationInfo()
{
  StageInfo info;
  info.type = "multi_plane_segmentation";
  info.description =
    "planar_grid::SACMultiPlaneSegmentation (paper Sec. III-C, eqs. 1-3, 11): "
    "multi-RANSAC planes hypothesised on the 3D key features (or the cloud) with PCL's "
    "plane model, dense inliers within distance_threshold_m (d_T) of each plane. Up "
    "axis: "
    "world +z after transform_to_world, else the camera's -y.";
  info.params = {
    ParamSpec::real(
      "distance_threshold_m", 0.05, 0.001, 1.0, "m",
      "d_T of eq. 11: dense points this close to a plane are its inliers."),
    ParamSpec::real(
      "sample_distance_threshold_m", 0.1, 0.001, 1.0, "m",
      "RANSAC inlier threshold on the sample (stereo features are noisier)."),
    ParamSpec::integer("max_planes", 8, 1, 100, "", "Most planes per frame."),
    ParamSpec::integer("min_inliers", 500, 3, 100000000, "",
                       "A plane needs at least this many dense inliers.")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::POINTS_PER_AREA),
    ParamSpec::integer("min_sample_inliers", 15, 3, 1000000, "",
                       "A hypothesis needs at least this many sample inliers."),
    ParamSpec::real("min_remaining_fraction", 0.05, 0.0, 1.0, "",
                    "Stop when less than this fraction of the sample remains."),
    ParamSpec::integer("max_iterations", 1000, 1, 1000000, "",
                       "RANSAC iterations per plane."),
    ParamSpec::choice("method", "ransac", {"ransac", "msac", "prosac"},
                      "PCL sample consensus estimator."),
    ParamSpec::flag("optimize_coefficients", true,
                    "Least-squares refit of each plane on its dense inliers."),
    ParamSpec::flag("dense_hypothesis", true,
                    "Each round also hypothesises a plane from a dense subsample; the "
                    "one with more inliers is kept."),
    ParamSpec::integer("lo_iterations", 50, 0, 100000, "",
                       "Local optimisation (LO-RANSAC) samples per plane; 0 = off."),
    ParamSpec::flag("merge_planes", true, "Merge near-duplicate planes."),
    ParamSpec::real("merge_angle_rad", 0.1, 0.0, 1.5708, "rad",
                    "Planes whose normals differ less than this may merge."),
    ParamSpec::real("merge_distance_m", 0.1, 0.0, 10.0, "m",
                    "... and whose offsets differ less than this."),
    ParamSpec::choice("sample", "features", {"features", "cloud"},
                      "Hypotheses from the 3D key features (paper) or the cloud."),
    ParamSpec::integer("seed", 0, 0, 2147483647, "",
                       "Random seed (reproducible runs)."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<MultiPlaneSegmentationStage>(v);
  };
  return info;
}

StageInfo
groundRemovalInfo()
{
  StageInfo info;
  info.type = "ground_removal";
  info.description =
    "Removes the ground before the approximation (paper Sec. III-F): the dominant "
    "plane "
    "from multi_plane_segmentation whose normal is within eps_angle_rad of the up axis "
    "and that lies at least min_sensor_height_m below the sensor; its coefficients are "
    "kept with the frame.";
  info.params = {
    ParamSpec::real("eps_angle_rad", 0.2, 0.0, 1.5708, "rad",
                    "Largest angle between the ground normal and the up axis."),
    ParamSpec::real("min_sensor_height_m", 0.3, 0.0, 100.0, "m",
                    "The sensor must be at least this high above the ground plane."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    return std::make_unique<GroundRemovalStage>(v.getDouble("eps_angle_rad"),
                                                v.getDouble("min_sensor_height_m"));
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
