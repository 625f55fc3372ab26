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

/** The YAML names of the sample consensus estimators, in SACMethod's order. */
const std::vector<std::string>&
sacMethodNames()
{
  static const std::vector<std::string> names{"ransac", "msac", "prosac"};
  return names;
}

const std::string&
sacMethodName(SACMethod method)
{
  return sacMethodNames()[static_cast<std::size_t>(method)];
}

SACMethod
sacMethodFromName(const std::string& name)
{
  const auto& names = sacMethodNames();
  const auto it = std::find(names.begin(), names.end(), name);
  // The parser admits only the table's choices, which are these names.
  return static_cast<SACMethod>(it == names.end() ? 0 : it - names.begin());
}

class MultiPlaneSegmentationStage : public Stage {
public:
  MultiPlaneSegmentationStage(const ParamValues& v) :
      use_features_(v.getChoice("sample") == "features"),
      depth_noise_disparity_px_(v.getDouble("depth_noise_disparity_px"))
  {
    segmentation_.setDistanceThreshold(v.getDouble("distance_threshold_m"));
    segmentation_.setSampleDistanceThreshold(
      v.getDouble("sample_distance_threshold_m"));
    segmentation_.setMaxPlanes(v.getInt("max_planes"));
    segmentation_.setMinInliers(v.getInt("min_inliers"));
    segmentation_.setMinSampleInliers(v.getInt("min_sample_inliers"));
    segmentation_.setMinRemainingFraction(v.getDouble("min_remaining_fraction"));
    segmentation_.setMaxIterations(v.getInt("max_iterations"));
    segmentation_.setMethodType(sacMethodFromName(v.getChoice("method")));
    segmentation_.setOptimizeCoefficients(v.getBool("optimize_coefficients"));
    segmentation_.setDenseHypothesis(v.getBool("dense_hypothesis"));
    segmentation_.setLocalOptimizationIterations(v.getInt("lo_iterations"));
    segmentation_.setMergePlanes(v.getBool("merge_planes"));
    segmentation_.setMergeAngleThreshold(v.getDouble("merge_angle_rad"));
    segmentation_.setMergeDistanceThreshold(v.getDouble("merge_distance_m"));
    segmentation_.setSeed(static_cast<unsigned>(v.getInt("seed")));
    segmentation_.setMaxVisibilityConflictRatio(
      v.getDouble("max_visibility_conflict_ratio"));
    segmentation_.setVisibilityMargin(v.getDouble("visibility_margin_m"));
    segmentation_.setVisibilityCell(v.getDouble("visibility_cell_m"));
    segmentation_.setMinSensorDistance(v.getDouble("min_sensor_distance_m"));
    segmentation_.setMinTerrainSensorHeight(v.getDouble("min_sensor_height_m"));
    segmentation_.setMinClusterSize(v.getInt("min_cluster_size"));
    segmentation_.setClusterCell(v.getDouble("cluster_cell_m"));
    segmentation_.setMaxShellRatio(v.getDouble("max_shell_ratio"));
    segmentation_.setShellWidth(v.getDouble("shell_width_m"));
    segmentation_.setCountInlierOnlyPoints(v.getBool("count_inlier_only_points"));
    segmentation_.setInlierOnlyDistanceThreshold(
      v.getDouble("inlier_only_distance_threshold_m"));
    segmentation_.setDepthNoiseAlongSight(v.getBool("depth_noise_along_sight"));
    max_normal_angle_rad_ = v.getDouble("max_normal_angle_rad");
    segmentation_.setNormalCell(v.getDouble("normal_cell_m"));
    segmentation_.setMinNormalAgreement(v.getDouble("min_normal_agreement"));
    use_disparity_normals_ = v.getChoice("normal_source") == "auto";
    disparity_normals_.window_radius_m = v.getDouble("normal_window_m");
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
      depth_noise_disparity_px_ > 0.0
        ? frame.calibration.depthError(1.0, depth_noise_disparity_px_)
        : 0.0;
    segmentation_.setDepthNoiseCoefficient(
      std::isfinite(coefficient) && coefficient > 0.0 ? coefficient : 0.0);
    pcl::PointCloud<pcl::PointXYZI>::Ptr sample;
    // A frame with fewer than 3 features (blur, fog, no texture) cannot sample a plane
    // from them: its planes are sampled from its points, as with sample: points.
    if (use_features_ && frame.features.size() < 3)
      PCL_WARN("[planar_grid::multi_plane_segmentation] frame %s has %zu matched "
               "features, too few to sample planes from: sampled from its points.\n",
               frame.name.c_str(), frame.features.size());
    if (use_features_ && frame.features.size() >= 3) {
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
    const bool test_normals = max_normal_angle_rad_ > 0.0
                              && (!use_disparity_normals_ || !frame.disparity.empty());
    segmentation_.setMaxNormalAngle(test_normals ? max_normal_angle_rad_ : 0.0);
    segmentation_.setInputNormals(test_normals ? disparityNormals(frame) : nullptr);
    segmentation_.segment(frame.planes);
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
    const auto& s = segmentation_;
    v.set("distance_threshold_m", s.getDistanceThreshold());
    v.set("depth_noise_disparity_px", depth_noise_disparity_px_);
    v.set("depth_noise_along_sight", s.getDepthNoiseAlongSight());
    v.set("sample_distance_threshold_m", s.getSampleDistanceThreshold());
    v.set("max_planes", s.getMaxPlanes());
    v.set("min_inliers", s.getMinInliers());
    v.set("min_sample_inliers", s.getMinSampleInliers());
    v.set("min_remaining_fraction", s.getMinRemainingFraction());
    v.set("max_iterations", s.getMaxIterations());
    v.set("method", sacMethodName(s.getMethodType()));
    v.set("optimize_coefficients", s.getOptimizeCoefficients());
    v.set("dense_hypothesis", s.getDenseHypothesis());
    v.set("lo_iterations", s.getLocalOptimizationIterations());
    v.set("merge_planes", s.getMergePlanes());
    v.set("merge_angle_rad", s.getMergeAngleThreshold());
    v.set("merge_distance_m", s.getMergeDistanceThreshold());
    v.set("sample", std::string(use_features_ ? "features" : "cloud"));
    v.set("seed", static_cast<int>(s.getSeed()));
    v.set("max_visibility_conflict_ratio", s.getMaxVisibilityConflictRatio());
    v.set("visibility_margin_m", s.getVisibilityMargin());
    v.set("visibility_cell_m", s.getVisibilityCell());
    v.set("min_sensor_distance_m", s.getMinSensorDistance());
    v.set("min_sensor_height_m", s.getMinTerrainSensorHeight());
    v.set("min_cluster_size", s.getMinClusterSize());
    v.set("cluster_cell_m", s.getClusterCell());
    v.set("max_shell_ratio", s.getMaxShellRatio());
    v.set("shell_width_m", s.getShellWidth());
    v.set("count_inlier_only_points", s.getCountInlierOnlyPoints());
    v.set("inlier_only_distance_threshold_m", s.getInlierOnlyDistanceThreshold());
    v.set("max_normal_angle_rad", max_normal_angle_rad_);
    v.set("normal_cell_m", s.getNormalCell());
    v.set("min_normal_agreement", s.getMinNormalAgreement());
    v.set("normal_source", std::string(use_disparity_normals_ ? "auto" : "cloud"));
    v.set("normal_window_m", disparity_normals_.window_radius_m);
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
    if (max_normal_angle_rad_ > 0.0) {
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
  /** The normals of the normal test from the frame's disparity image (in the cloud's
   * frame), or nullptr where the segmentation fits them to the cloud (normal_source
   * cloud, or no disparity image). */
  pcl::PointCloud<pcl::Normal>::ConstPtr disparityNormals(const Frame& frame) const
  {
    if (!use_disparity_normals_ || frame.disparity.empty()
        || !(frame.calibration.focal_length_px > 0.0)
        || !(frame.calibration.baseline_m > 0.0))
      return nullptr;
    const auto& cloud = *frame.cloud;
    const Eigen::Affine3f camera_T_cloud = cameraTCloud(frame);
    std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> points(
      cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i)
      points[i] = camera_T_cloud * cloud[i].getVector3fMap();
    std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> normals;
    estimateDisparityNormals(frame.disparity, frame.calibration, points,
                             disparity_normals_, normals);
    const Eigen::Matrix3f cloud_R_camera = camera_T_cloud.linear().transpose();
    auto out = std::make_shared<pcl::PointCloud<pcl::Normal>>();
    out->resize(cloud.size());
    for (std::size_t i = 0; i < cloud.size(); ++i) {
      const Eigen::Vector3f n = cloud_R_camera * normals[i];
      (*out)[i] = pcl::Normal(n.x(), n.y(), n.z());
    }
    return out;
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
  double max_normal_angle_rad_{0.0};
  bool use_disparity_normals_{true};
  DisparityNormalParams disparity_normals_;
  bool use_features_;
  double depth_noise_disparity_px_;
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
  // The defaults are the class's, except where a row says otherwise.
  const SACMultiPlaneSegmentation<pcl::PointXYZI> d;
  namespace ranges = sac_multi_plane_segmentation_ranges;
  info.params = {
    ParamSpec::real(
      "distance_threshold_m", d.getDistanceThreshold(), ranges::DISTANCE_THRESHOLD, "m",
      "d_T of eq. 11: dense points this close to a plane are its inliers."),
    ParamSpec::real(
      "depth_noise_disparity_px", 0.0, 0.0, 10.0, "px",
      "Stereo input: Delta d of eq. 4; a dense point is an inlier within max(d_T, "
      "Delta z) with Delta z = r^2 Delta d / (B f) at its range r (0: fixed d_T)."),
    ParamSpec::flag(
      "depth_noise_along_sight", d.getDepthNoiseAlongSight(),
      "With depth_noise_disparity_px: a point is an inlier within max(d_T, Delta z "
      "|n . u|), Delta z projected on the plane's normal n from the point's line of "
      "sight u (stereo displaces points along it): a road seen at a grazing angle "
      "keeps about d_T and no longer takes what stands on it at range."),
    ParamSpec::real(
      "sample_distance_threshold_m", 0.1, ranges::SAMPLE_DISTANCE_THRESHOLD, "m",
      "RANSAC inlier threshold on the sample (stereo features are noisier). The "
      "pipeline's value; the class defaults to its dense distance threshold."),
    ParamSpec::integer("max_planes", d.getMaxPlanes(), ranges::MAX_PLANES, "",
                       "Most planes per frame."),
    ParamSpec::integer("min_inliers", d.getMinInliers(), ranges::MIN_INLIERS, "",
                       "A plane needs at least this many dense inliers.")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::POINTS_PER_AREA),
    ParamSpec::integer("min_sample_inliers", d.getMinSampleInliers(),
                       ranges::MIN_SAMPLE_INLIERS, "",
                       "A hypothesis needs at least this many sample inliers."),
    ParamSpec::real("min_remaining_fraction", d.getMinRemainingFraction(),
                    ranges::MIN_REMAINING_FRACTION, "",
                    "Stop when less than this fraction of the sample remains."),
    ParamSpec::integer("max_iterations", d.getMaxIterations(), ranges::MAX_ITERATIONS,
                       "", "RANSAC iterations per plane."),
    ParamSpec::choice("method", sacMethodName(d.getMethodType()), sacMethodNames(),
                      "PCL sample consensus estimator."),
    ParamSpec::flag("optimize_coefficients", d.getOptimizeCoefficients(),
                    "Least-squares refit of each plane on its dense inliers."),
    ParamSpec::flag("dense_hypothesis", d.getDenseHypothesis(),
                    "Each round also hypothesises a plane from a dense subsample; the "
                    "one with more inliers is kept."),
    ParamSpec::integer("lo_iterations", d.getLocalOptimizationIterations(),
                       ranges::LO_ITERATIONS, "",
                       "Local optimisation (LO-RANSAC) samples per plane; 0 = off."),
    ParamSpec::flag("merge_planes", d.getMergePlanes(), "Merge near-duplicate planes."),
    ParamSpec::real("merge_angle_rad", d.getMergeAngleThreshold(),
                    ranges::MERGE_ANGLE_THRESHOLD, "rad",
                    "Planes whose normals differ less than this may merge."),
    ParamSpec::real("merge_distance_m", d.getMergeDistanceThreshold(),
                    ranges::MERGE_DISTANCE_THRESHOLD, "m",
                    "... and whose offsets differ less than this."),
    ParamSpec::choice("sample", "features", {"features", "cloud"},
                      "Hypotheses from the 3D key features (paper) or the cloud; on "
                      "pcd_files input the default is cloud (no stereo features)."),
    ParamSpec::integer("seed", static_cast<int>(d.getSeed()), 0, 2147483647, "",
                       "Random seed (reproducible runs)."),
    ParamSpec::real("max_visibility_conflict_ratio", d.getMaxVisibilityConflictRatio(),
                    ranges::MAX_VISIBILITY_CONFLICT_RATIO, "",
                    "Visibility test: where, around a 3 x 3 cell neighbourhood of a "
                    "plane's footprint, more than this many points per inlier are seen "
                    "through the plane or hide it from the camera (a slab through a "
                    "tree's canopy), those inliers leave the plane; 0 = no test."),
    ParamSpec::real("visibility_margin_m", d.getVisibilityMargin(),
                    ranges::VISIBILITY_MARGIN, "m",
                    "A point conflicts with a plane only this much (plus its eq. 11 "
                    "threshold) off it."),
    ParamSpec::real("visibility_cell_m", d.getVisibilityCell(), ranges::VISIBILITY_CELL,
                    "m",
                    "Cell edge of a plane's footprint in the visibility and the shell "
                    "tests."),
    ParamSpec::real("min_sensor_distance_m", d.getMinSensorDistance(),
                    ranges::MIN_SENSOR_DISTANCE, "m",
                    "Sensor plane test: a plane passing closer than this to the "
                    "sensor is dropped and its inliers go to no later plane (it "
                    "contains the lines of sight, along which stereo smears every "
                    "object: a vertical sheet through a tree trunk, a horizontal one "
                    "at the camera's height); 0 = no test."),
    ParamSpec::real("min_sensor_height_m", TerrainParams{}.min_sensor_height_m,
                    ranges::MIN_TERRAIN_SENSOR_HEIGHT, "m",
                    "The normal and cluster tests spare a level plane as terrain only "
                    "when the sensor lies more than this above it (a level plane just "
                    "below the camera is no ground: spared, it takes a stripe of every "
                    "wall at its height); 0: every level plane below the sensor. Left "
                    "out, it takes ground_removal's min_sensor_height_m (the same "
                    "default)."),
    ParamSpec::integer("min_cluster_size", d.getMinClusterSize(),
                       ranges::MIN_CLUSTER_SIZE, "",
                       "Cluster test: the inliers of each connected cluster of a "
                       "plane's footprint (cluster_cell_m cells, a one-cell gap "
                       "bridged) holding fewer than this many leave the plane (a plane "
                       "through separate trunks, or slicing car bodies); 0 = no test.")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::POINTS_PER_AREA),
    ParamSpec::real("cluster_cell_m", d.getClusterCell(), ranges::CLUSTER_CELL, "m",
                    "Footprint cell edge of the cluster test (at least the voxel "
                    "edge of a voxelised cloud).")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::CELL_SIZE),
    ParamSpec::real("max_shell_ratio", d.getMaxShellRatio(), ranges::MAX_SHELL_RATIO,
                    "",
                    "Shell test: where, around a 3 x 3 cell neighbourhood of a plane's "
                    "footprint, twice the smaller of the two sides' counts of points "
                    "just beyond the eq. 11 threshold t (between t and t + max(t, "
                    "shell_width_m) off the plane) exceeds this many per inlier (a "
                    "slab through a canopy, a stripe across a facade or a car), those "
                    "inliers leave the plane; 0 = no test."),
    ParamSpec::real("shell_width_m", d.getShellWidth(), ranges::SHELL_WIDTH, "m",
                    "Smallest width of the shell test's shell (a voxelised cloud's "
                    "surface points lie in layers one voxel apart).")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::CELL_SIZE),
    ParamSpec::flag("count_inlier_only_points", d.getCountInlierOnlyPoints(),
                    "The points beyond depth_error_filter's cell bound (kept by its "
                    "max_plane_depth_error_m) count towards min_inliers, so that a "
                    "plane the key features make may stand on them alone; false: a "
                    "plane needs min_inliers nearer points, which they only extend."),
    ParamSpec::real("inlier_only_distance_threshold_m",
                    d.getInlierOnlyDistanceThreshold(),
                    ranges::INLIER_ONLY_DISTANCE_THRESHOLD, "m",
                    "Those points join a plane within the smaller of this and their "
                    "eq. 11 threshold (a planar cell is as thick as its inliers' "
                    "spread); 0: eq. 11's."),
    ParamSpec::real("max_normal_angle_rad", 0.5, ranges::MAX_NORMAL_ANGLE, "rad",
                    "Normal test: a point is an inlier only when its surface normal "
                    "(fitted to the points of the 3 x 3 x 3 normal_cell_m cells around "
                    "it, or to the disparities around its pixel, normal_source) lies "
                    "within this angle of the plane's normal; a point without a normal "
                    "(too few neighbours) is judged by distance alone (a canopy's or a "
                    "pole's points scatter in normal, a wall's agree). Terrain planes "
                    "(within 0.3 rad of level, below the sensor) are spared. The "
                    "pipeline's value; the class defaults to 0 (no test)."),
    ParamSpec::real("normal_cell_m", d.getNormalCell(), ranges::NORMAL_CELL, "m",
                    "Cell edge of the normal estimation (about twice the voxel edge: "
                    "a stereo surface is as thick as its depth noise).")
      .scalesWithCellSize(ParamSpec::CellSizeScaling::LENGTH),
    ParamSpec::choice("normal_source", "auto", {"auto", "cloud"},
                      "Where the normal test's normals come from: auto, the frame's "
                      "disparity image (a plane fitted to the disparities around each "
                      "point's pixel, planar_grid::estimateDisparityNormals); frames "
                      "without one (point clouds, depth images) get no normal test; "
                      "cloud, the points of the normal_cell_m grid, for every input "
                      "(for clouds whose noise is well below normal_cell_m)."),
    ParamSpec::real("normal_window_m", DisparityNormalParams{}.window_radius_m,
                    disparity_normals_ranges::WINDOW_RADIUS, "m",
                    "Disparity normals: half-width of the window around a point's "
                    "pixel, on the surface at the point's depth (f r / z pixels, 4 to "
                    "60)."),
    ParamSpec::real(
      "min_normal_agreement", 0.35, ranges::MIN_NORMAL_AGREEMENT, "",
      "Normal test: a hypothesis whose inliers by distance agree with its "
      "normal less often than this is dropped (a plane through "
      "vegetation, clutter, or across a surface at an angle). The "
      "pipeline's value; the class defaults to 0 (no test)."),
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
