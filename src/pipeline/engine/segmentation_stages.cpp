// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/segmentation/terrain_removal.h>
#include <planar_grid/stereo/disparity_normals.h>

#include <pcl/common/centroid.h>
#include <pcl/common/point_tests.h>
#include <pcl/common/transforms.h>
#include <pcl/console/print.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <map>
#include <memory>
#include <unordered_map>
#include <unordered_set>
#include <vector>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

/** Where multi_plane_segmentation draws its plane hypotheses from. */
enum class PlaneSample {
  FEATURES, // the frame's 3D key features (the paper)
  CLOUD     // a subsample of the frame's cloud
};

/** Where the normal test's normals come from. */
enum class NormalSource {
  AUTO, // the frame's disparity image; no normal test without one
  CLOUD // the segmentation's grid normals of the cloud
};

/** The stage's own parameters beside SACMultiPlaneSegmentation's: the frame's data it
 * feeds the class (the stereo depth noise, the sample, the disparity normals). */
struct MultiPlaneStageParams {
  double depth_noise_disparity_px{0.0};
  PlaneSample sample{PlaneSample::FEATURES};
  NormalSource normal_source{NormalSource::AUTO};
  double normal_window_m{DisparityNormalParams{}.window_radius_m};
};

const ParamDeclarations<MultiPlaneStageParams>&
multiPlaneStageParamDeclarations()
{
  using P = MultiPlaneStageParams;
  static const ParamDeclarations<P> table = {
    declareReal<P>(
      "depth_noise_disparity_px",
      [](auto& p) -> auto& { return p.depth_noise_disparity_px; },
      ParamRange::closed(0.0, 10.0), "px",
      "Stereo input: Delta d of eq. 4; a dense point is an inlier within max(d_T, "
      "Delta z) with Delta z = r^2 Delta d / (B f) at its range r (0: fixed d_T)."),
    declareNamedChoice<P, PlaneSample>(
      "sample", [](auto& p) -> auto& { return p.sample; },
      {{"features", PlaneSample::FEATURES}, {"cloud", PlaneSample::CLOUD}},
      "Hypotheses from the 3D key features (paper) or the cloud; on pcd_files input "
      "the default is cloud (no stereo features)."),
    declareNamedChoice<P, NormalSource>(
      "normal_source", [](auto& p) -> auto& { return p.normal_source; },
      {{"auto", NormalSource::AUTO}, {"cloud", NormalSource::CLOUD}},
      "Where the normal test's normals come from: auto, the frame's disparity image (a "
      "plane fitted to the disparities around each point's pixel, "
      "planar_grid::estimateDisparityNormals); frames without one (point clouds, depth "
      "images) get no normal test; cloud, the points of the normal_cell_m grid, for "
      "every input (for clouds whose noise is well below normal_cell_m)."),
    declareReal<P>(
      "normal_window_m", [](auto& p) -> auto& { return p.normal_window_m; },
      disparity_normals_ranges::WINDOW_RADIUS, "m",
      "Disparity normals: half-width of the window around a point's pixel, on the "
      "surface at the point's depth (f r / z pixels, 4 to 60)."),
  };
  return table;
}

/** The stage's parameter list: the class's table in its order, each stage key
 * beside the class key it goes with. */
std::vector<ParamSpec>
multiPlaneSegmentationParamSpecs()
{
  auto specs = paramSpecs(sacMultiPlaneSegmentationParamDeclarations());
  const auto local = paramSpecs(multiPlaneStageParamDeclarations());
  insertParamSpec(specs, "distance_threshold_m", local.at(0));
  insertParamSpec(specs, "merge_distance_m", local.at(1));
  insertParamSpec(specs, "normal_cell_m", local.at(2));
  insertParamSpec(specs, "normal_source", local.at(3));
  return specs;
}

class MultiPlaneSegmentationStage : public Stage {
public:
  MultiPlaneSegmentationStage(const SACMultiPlaneSegmentationParams& params,
                              const MultiPlaneStageParams& stage_params) :
      segmentation_(params),
      params_(params), stage_params_(stage_params)
  {
    disparity_normals_.window_radius_m = stage_params_.normal_window_m;
  }

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    inlier_only_ = 0;
    inlier_only_taken_ = 0;
    far_joined_ = 0;
    if (!hasPoints(frame, "multi_plane_segmentation")) {
      frame.planes.clear();
      return;
    }
    segmentation_.setInputCloud(frame.cloud);
    segmentation_.setUpAxis(upAxis(frame));
    // Eq. 4's stereo depth error Delta z = z^2 Delta d / (B f) widens eq. 11 with
    // range: the coefficient is Delta z at 1 m (none without a stereo calibration).
    const double coefficient =
      stage_params_.depth_noise_disparity_px > 0.0
        ? frame.calibration.depthError(1.0, stage_params_.depth_noise_disparity_px)
        : 0.0;
    segmentation_.setDepthNoiseCoefficient(
      std::isfinite(coefficient) && coefficient > 0.0 ? coefficient : 0.0);
    pcl::PointCloud<pcl::PointXYZI>::Ptr sample;
    // A frame with fewer than 3 features (blur, fog, no texture) cannot sample a plane
    // from them: its planes are sampled from its points, as with sample: points.
    if (sampleFeatures() && frame.features.size() < 3)
      PCL_WARN("[planar_grid::multi_plane_segmentation] frame %s has %zu matched "
               "features, too few to sample planes from: sampled from its points.\n",
               frame.name.c_str(), frame.features.size());
    if (sampleFeatures() && frame.features.size() >= 3) {
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
    // The points beyond depth_error_filter's cell bound may only join planes.
    pcl::IndicesPtr inlier_only;
    if (std::isfinite(frame.inlier_only_depth_m)) {
      const Eigen::RowVector4f depth_row = cameraTCloud(frame).matrix().row(2);
      const auto& cloud = *frame.cloud;
      inlier_only.reset(new pcl::Indices);
      for (std::size_t i = 0; i < cloud.size(); ++i)
        if (pcl::isFinite(cloud[i])
            && depth_row.dot(cloud[i].getVector4fMap()) > frame.inlier_only_depth_m)
          inlier_only->push_back(static_cast<pcl::index_t>(i));
    }
    segmentation_.setInlierOnlyIndices(inlier_only);
    // auto: the normal test on the frames with a disparity image only; the normals a
    // grid fits to a noisy stereo or depth cloud turn with its depth noise.
    const bool test_normals = params_.max_normal_angle_rad > 0.0
                              && (stage_params_.normal_source != NormalSource::AUTO
                                  || !frame.disparity.empty());
    segmentation_.setMaxNormalAngle(test_normals ? params_.max_normal_angle_rad : 0.0);
    segmentation_.setNormalFunction(test_normals ? disparityNormalFunction(frame)
                                                 : nullptr);
    segmentation_.segment(frame.planes);
    // The function holds the frame's cloud and disparity image.
    segmentation_.setNormalFunction(nullptr);
    if (inlier_only) {
      // The inlier-only points no plane took make no cells.
      std::vector<std::uint8_t> drop(frame.cloud->size(), 0);
      for (const auto i : *inlier_only)
        drop[static_cast<std::size_t>(i)] = 1;
      for (const auto& plane : frame.planes)
        for (const auto i : plane.inliers.indices)
          drop[static_cast<std::size_t>(i)] = 0;
      inlier_only_ = inlier_only->size();
      inlier_only_taken_ = inlier_only_ - removePoints(frame, drop);
      frame.inlier_only_depth_m = std::numeric_limits<float>::infinity();
      far_joined_ = removeFarPointsOnPlanes(frame, coefficient);
    }
    if (frame.planes.empty())
      PCL_WARN("[planar_grid::multi_plane_segmentation] No plane found in frame %s.\n",
               frame.name.c_str());
  }

  bool countsCloudPoints() const override { return false; }

  void getParameters(ParamValues& v) const override
  {
    reportParams(sacMultiPlaneSegmentationParamDeclarations(), params_, v);
    reportParams(multiPlaneStageParamDeclarations(), stage_params_, v);
  }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    std::size_t inliers = 0;
    for (const auto& plane : frame.planes)
      inliers += plane.inliers.indices.size();
    values.emplace_back("planes", static_cast<double>(frame.planes.size()));
    values.emplace_back("plane_inliers", static_cast<double>(inliers));
    if (inlier_only_ > 0) {
      values.emplace_back("inlier_only_points", static_cast<double>(inlier_only_));
      values.emplace_back("inlier_only_taken", static_cast<double>(inlier_only_taken_));
      if (frame.far_cloud)
        values.emplace_back("far_points_joined", static_cast<double>(far_joined_));
    }
    if (segmentation_.getMaxVisibilityConflictRatio() > 0.0) {
      values.emplace_back(
        "visibility_dropped",
        static_cast<double>(segmentation_.getVisibilityRejectedCount()));
      values.emplace_back(
        "visibility_removed",
        static_cast<double>(segmentation_.getVisibilityRemovedCount()));
    }
    if (segmentation_.getMinSensorDistance() > 0.0) {
      values.emplace_back(
        "sensor_plane_dropped",
        static_cast<double>(segmentation_.getSensorPlaneRejectedCount()));
      values.emplace_back(
        "sensor_plane_removed",
        static_cast<double>(segmentation_.getSensorPlaneRemovedCount()));
    }
    if (segmentation_.getMinClusterSize() > 0) {
      values.emplace_back("cluster_dropped",
                          static_cast<double>(segmentation_.getClusterRejectedCount()));
      values.emplace_back("cluster_removed",
                          static_cast<double>(segmentation_.getClusterRemovedCount()));
    }
    if (params_.max_normal_angle_rad > 0.0) {
      values.emplace_back("normal_dropped",
                          static_cast<double>(segmentation_.getNormalRejectedCount()));
      values.emplace_back("normal_removed",
                          static_cast<double>(segmentation_.getNormalRemovedCount()));
    }
    if (segmentation_.getMaxShellRatio() > 0.0) {
      values.emplace_back("shell_dropped",
                          static_cast<double>(segmentation_.getShellRejectedCount()));
      values.emplace_back("shell_removed",
                          static_cast<double>(segmentation_.getShellRemovedCount()));
    }
  }

private:
  /** Whether the hypotheses come from the frame's key features. */
  bool sampleFeatures() const { return stage_params_.sample == PlaneSample::FEATURES; }

  /** The normals of the normal test from the frame's disparity image (in the cloud's
   * frame), each fitted when the test first asks for it; empty where the segmentation
   * fits them to the cloud (normal_source cloud, or no disparity image). */
  SACMultiPlaneSegmentation<pcl::PointXYZI>::NormalFunction
  disparityNormalFunction(const Frame& frame) const
  {
    if (stage_params_.normal_source != NormalSource::AUTO || frame.disparity.empty()
        || !(frame.calibration.focal_length_px > 0.0)
        || !(frame.calibration.baseline_m > 0.0))
      return nullptr;
    const Eigen::Affine3f camera_T_cloud = cameraTCloud(frame);
    const Eigen::Matrix3f cloud_R_camera = camera_T_cloud.linear().transpose();
    const DisparityNormalEstimator estimator(frame.disparity, frame.calibration,
                                             disparity_normals_);
    return [estimator, cloud = Frame::Cloud::ConstPtr(frame.cloud), camera_T_cloud,
            cloud_R_camera](pcl::index_t i) -> Eigen::Vector3f {
      const Eigen::Vector3f point =
        camera_T_cloud * (*cloud)[static_cast<std::size_t>(i)].getVector3fMap();
      return cloud_R_camera * estimator.compute(point);
    };
  }

  /** The far points (depth_error_filter's far_levels, not thinned by voxel_grid) that
   * a plane takes out of the frame's far cloud, so that range_adaptive_cells maps no
   * cell where a planar cell stands. A far point joins a plane by the rule its
   * inlier-only points follow: it lies within their eq. 11 threshold of the plane
   * (\a coefficient: eq. 4's depth error at 1 m), and its projection falls within one
   * cluster_cell_m cell of a cell of the plane's inliers. Terrain planes (facing up
   * within 0.3 rad, below the sensor) take none: range_adaptive_cells has its own
   * rule for the far terrain, which keeps what stands on it. \return the points
   * taken */
  std::size_t removeFarPointsOnPlanes(Frame& frame, double coefficient) const
  {
    if (!frame.far_cloud || frame.far_cloud->empty() || frame.planes.empty())
      return 0;
    const auto& far = *frame.far_cloud;
    const auto& cloud = *frame.cloud;
    const Eigen::Affine3f cloud_T_camera = cameraTCloud(frame).inverse();
    const Eigen::Vector3f origin = sensorOrigin(frame);
    const auto d_t = static_cast<float>(segmentation_.getDistanceThreshold());
    const auto cap = static_cast<float>(segmentation_.getInlierOnlyDistanceThreshold());
    const auto c = static_cast<float>(coefficient);
    const double inv_cell = 1.0 / segmentation_.getClusterCell();
    std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> points(
      far.size());
    const bool along_sight = segmentation_.getDepthNoiseAlongSight();
    const Eigen::Vector3f up = upAxis(frame).normalized();
    for (std::size_t i = 0; i < far.size(); ++i)
      points[i] = cloud_T_camera * far[i].getVector3fMap();
    const auto threshold = [&](std::size_t i, const Eigen::Vector3f& n) {
      const Eigen::Vector3f ray = points[i] - origin;
      float error = c * ray.squaredNorm();
      if (along_sight)
        error *= std::abs(n.dot(ray.normalized()));
      const float t = std::max(d_t, error);
      return cap > 0.0f ? std::min(t, cap) : t;
    };
    std::vector<std::uint8_t> joined(far.size(), 0);
    std::unordered_set<std::uint64_t> footprint;
    for (const auto& plane : frame.planes) {
      const auto& v = plane.model_coefficients.values;
      if (v.size() != 4 || plane.inliers.indices.empty())
        continue;
      const Eigen::Vector3f n(v[0], v[1], v[2]);
      // With the normal turned up, the sensor's signed distance is its height.
      const float side = n.dot(up) < 0.0f ? -1.0f : 1.0f;
      if (side * n.dot(up) > std::cos(0.3f) && side * (n.dot(origin) + v[3]) > 0.0f)
        continue;
      const Eigen::Vector3f a1 = n.unitOrthogonal();
      const Eigen::Vector3f a2 = n.cross(a1);
      const auto key = [&](const Eigen::Vector3f& p, std::int64_t dx, std::int64_t dy) {
        const auto x = static_cast<std::int64_t>(std::floor(a1.dot(p) * inv_cell)) + dx;
        const auto y = static_cast<std::int64_t>(std::floor(a2.dot(p) * inv_cell)) + dy;
        return (static_cast<std::uint64_t>(x + (1 << 30)) << 32)
               | static_cast<std::uint64_t>(y + (1 << 30));
      };
      footprint.clear();
      for (const auto i : plane.inliers.indices)
        for (std::int64_t dx = -1; dx <= 1; ++dx)
          for (std::int64_t dy = -1; dy <= 1; ++dy)
            footprint.insert(
              key(cloud[static_cast<std::size_t>(i)].getVector3fMap(), dx, dy));
      for (std::size_t i = 0; i < far.size(); ++i)
        if (!joined[i] && std::abs(n.dot(points[i]) + v[3]) <= threshold(i, n)
            && footprint.count(key(points[i], 0, 0)) > 0)
          joined[i] = 1;
    }
    auto kept = std::make_shared<Frame::Cloud>();
    std::vector<std::uint8_t> kept_levels;
    for (std::size_t i = 0; i < far.size(); ++i)
      if (!joined[i]) {
        kept->push_back(far[i]);
        kept_levels.push_back(frame.far_levels[i]);
      }
    const std::size_t taken = far.size() - kept->size();
    // A new cloud: the old one may be shared with copies of the frame.
    frame.far_cloud = std::move(kept);
    frame.far_levels = std::move(kept_levels);
    return taken;
  }

  SACMultiPlaneSegmentation<pcl::PointXYZI> segmentation_;
  /** The configured parameters (process() turns the normal test off per frame). */
  SACMultiPlaneSegmentationParams params_;
  MultiPlaneStageParams stage_params_;
  DisparityNormalParams disparity_normals_;
  std::size_t inlier_only_{0};
  std::size_t inlier_only_taken_{0};
  std::size_t far_joined_{0};
};

using TerrainParams = TerrainRemovalParams;

/** The ground_removal stage: planar_grid::TerrainRemoval on the frame's cloud and
 * planes (up axis and sensor origin the frame's); the ground's coefficients are kept
 * with the frame and the terrain points leave its cloud. */
class GroundRemovalStage : public Stage {
public:
  explicit GroundRemovalStage(const TerrainParams& p) : terrain_(p) {}

  void process(Frame& frame, PipelineState& /*state*/) override
  {
    frame.has_ground = false;
    removed_ = 0;
    terrain_planes_ = 0;
    if (!hasPoints(frame, "ground_removal"))
      return;
    terrain_.setUpAxis(upAxis(frame));
    terrain_.setSensorOrigin(sensorOrigin(frame));
    std::vector<std::uint8_t> remove;
    if (!terrain_.segment(*frame.cloud, frame.planes, remove))
      return;
    frame.has_ground = true;
    frame.ground_coefficients = terrain_.getGroundCoefficients();
    terrain_planes_ = terrain_.getTerrainPlaneCount();
    removed_ = removePoints(frame, remove);
  }

  void getParameters(ParamValues& v) const override
  {
    reportParams(terrainRemovalParamDeclarations(), terrain_.getParams(), v);
  }

  void counters(const Frame& frame,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("ground_found", frame.has_ground ? 1.0 : 0.0);
    values.emplace_back("ground_points", static_cast<double>(removed_));
    values.emplace_back("terrain_planes", static_cast<double>(terrain_planes_));
  }

private:
  TerrainRemoval<pcl::PointXYZI> terrain_;
  std::size_t removed_{0};
  std::size_t terrain_planes_{0};
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
  info.params = multiPlaneSegmentationParamSpecs();
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    SACMultiPlaneSegmentationParams params;
    assignParams(sacMultiPlaneSegmentationParamDeclarations(), v, params);
    MultiPlaneStageParams stage_params;
    assignParams(multiPlaneStageParamDeclarations(), v, stage_params);
    return std::make_unique<MultiPlaneSegmentationStage>(params, stage_params);
  };
  return info;
}

StageInfo
groundRemovalInfo()
{
  StageInfo info;
  info.type = "ground_removal";
  info.description =
    "planar_grid::TerrainRemoval: removes the terrain before the approximation (paper "
    "Sec. III-F, its second "
    "assumption): the ground is the dominant plane from multi_plane_segmentation whose "
    "normal is within eps_angle_rad of the up axis and that lies at least "
    "min_sensor_height_m below the sensor (its coefficients are kept with the frame); "
    "every plane within terrain_max_slope_rad of the up axis whose lowest inlier is "
    "within terrain_max_step_m of a terrain plane's mean height is terrain too "
    "(sidewalks, lawns, ramps), and so is every point in no plane that lies at most "
    "terrain_height_m above the terrain (per terrain_cell_m cell). Inliers of the "
    "other planes (walls, down to their feet) and points higher up (cars, poles) "
    "stay.";
  info.params = paramSpecs(terrainRemovalParamDeclarations());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    TerrainParams p;
    assignParams(terrainRemovalParamDeclarations(), v, p);
    return std::make_unique<GroundRemovalStage>(p);
  };
  return info;
}

} // namespace stages
} // namespace planar_grid
