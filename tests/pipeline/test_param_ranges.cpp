// SPDX-License-Identifier: BSD-3-Clause
// The stage tables and the library classes read one declaration of each parameter's
// range: for every stage parameter that a class takes, the table's range is the
// class's, a value just outside it is refused by both the configuration parser and the
// class, and a value at its inside edges is accepted by both.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/map/explicit_space_grid.h>
#include <planar_grid/map/surface_layer.h>
#include <planar_grid/odometry/stereo_odometry.h>
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/point_cloud_from_disparity.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <iomanip>
#include <limits>
#include <memory>
#include <set>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace {

using planar_grid::ParamRange;
using planar_grid::ParamSpec;

/** One stage parameter that a class takes: its stage and key, the class's declared
 * range, and whether the class accepts a value (the value set on an object that is
 * otherwise default and valid). */
struct ClassParam {
  std::string stage;
  std::string key;
  ParamRange range;
  std::function<bool(double)> class_accepts;
  /** False where the class's other rules (odd sizes, p2 > p1, the mode's block
   * sizes) refuse some values inside the range: only the refusals are compared. */
  bool inside_edges_accepted{true};
};

using Segmentation = planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ>;
using Approximation = planar_grid::PlanarCuboidApproximation<pcl::PointXYZ>;
/** The filter with its parameter check public, as the Python binding exposes it. */
class Filter : public planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ> {
public:
  using planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ>::checkParameters;
};

int
toInt(double value)
{
  return static_cast<int>(value);
}

/** Whether constructing from \a make's object throws planar_grid::Exception. */
template <typename Make>
bool
constructs(Make make)
{
  try {
    make();
    return true;
  } catch (const planar_grid::Exception&) {
    return false;
  }
}

template <typename Set>
std::function<bool(double)>
segmentation(Set set)
{
  return [set](double v) {
    Segmentation s;
    set(s, v);
    return s.checkParameters() == nullptr;
  };
}

template <typename Set>
std::function<bool(double)>
approximation(Set set)
{
  return [set](double v) {
    Approximation a;
    set(a, v);
    return a.checkParameters() == nullptr;
  };
}

template <typename Set>
std::function<bool(double)>
filter(Set set)
{
  return [set](double v) {
    Filter f;
    f.setStereoParameters(500.0, 0.5);
    set(f, v);
    return f.checkParameters() == nullptr;
  };
}

template <typename Set>
std::function<bool(double)>
odometry(Set set)
{
  return [set](double v) {
    planar_grid::StereoOdometry::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::StereoOdometry odometry(p); });
  };
}

template <typename Set>
std::function<bool(double)>
motionModel(Set set)
{
  return [set](double v) {
    planar_grid::ConstantVelocityMotionModel::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::ConstantVelocityMotionModel model(p); });
  };
}

template <typename Set>
std::function<bool(double)>
disparity(Set set)
{
  return [set](double v) {
    planar_grid::DisparityEstimator::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::DisparityEstimator estimator(p); });
  };
}

template <typename Set>
std::function<bool(double)>
matcher(Set set)
{
  return [set](double v) {
    planar_grid::StereoFeatureMatcher::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::StereoFeatureMatcher m(p); });
  };
}

template <typename Set>
std::function<bool(double)>
surfaceLayer(Set set)
{
  return [set](double v) {
    planar_grid::SurfaceLayer::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::SurfaceLayer layer(p); });
  };
}

template <typename Set>
std::function<bool(double)>
spaceGrid(Set set)
{
  return [set](double v) {
    planar_grid::ExplicitSpaceGrid::Params p;
    set(p, v);
    return constructs([&p] { planar_grid::ExplicitSpaceGrid grid(p); });
  };
}

/** Whether FastStatisticalOutlierRemoval filters three points with \a mean_k (it
 * checks the value when it starts). */
bool
outlierRemovalAccepts(double mean_k)
{
  planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ> f;
  f.setMeanK(toInt(mean_k));
  auto cloud = std::make_shared<pcl::PointCloud<pcl::PointXYZ>>();
  for (int i = 0; i < 3; ++i)
    cloud->push_back(pcl::PointXYZ(static_cast<float>(i), 0.0f, 0.0f));
  f.setInputCloud(cloud);
  pcl::Indices kept;
  return constructs([&] { f.filter(kept); });
}

std::vector<ClassParam>
classParams()
{
  namespace seg = planar_grid::sac_multi_plane_segmentation_ranges;
  namespace cub = planar_grid::planar_cuboid_approximation_ranges;
  namespace kl = planar_grid::kl_divergence_occupancy_filter_ranges;
  namespace odo = planar_grid::stereo_odometry_ranges;
  namespace cvm = planar_grid::constant_velocity_motion_model_ranges;
  namespace dis = planar_grid::disparity_estimator_ranges;
  namespace fm = planar_grid::stereo_feature_matcher_ranges;
  namespace sl = planar_grid::surface_layer_ranges;
  namespace esg = planar_grid::explicit_space_grid_ranges;
  using S = Segmentation;
  using A = Approximation;
  using O = planar_grid::StereoOdometry::Params;
  using M = planar_grid::ConstantVelocityMotionModel::Params;
  using D = planar_grid::DisparityEstimator::Params;
  using F = planar_grid::StereoFeatureMatcher::Params;
  using L = planar_grid::SurfaceLayer::Params;
  using G = planar_grid::ExplicitSpaceGrid::Params;
  const std::string mps = "multi_plane_segmentation";
  const std::string pca = "planar_cuboid_approximation";
  const std::string klf = "kl_occupancy_filter";
  const std::string vo = "visual_odometry";
  const std::string sd = "stereo_disparity";
  const std::string mi = "map_integration";
  return {
    {mps, "distance_threshold_m", seg::DISTANCE_THRESHOLD,
     segmentation([](S& s, double v) { s.setDistanceThreshold(v); })},
    {mps, "sample_distance_threshold_m", seg::SAMPLE_DISTANCE_THRESHOLD,
     segmentation([](S& s, double v) { s.setSampleDistanceThreshold(v); })},
    {mps, "max_planes", seg::MAX_PLANES,
     segmentation([](S& s, double v) { s.setMaxPlanes(toInt(v)); })},
    {mps, "min_inliers", seg::MIN_INLIERS,
     segmentation([](S& s, double v) { s.setMinInliers(toInt(v)); })},
    {mps, "min_sample_inliers", seg::MIN_SAMPLE_INLIERS,
     segmentation([](S& s, double v) { s.setMinSampleInliers(toInt(v)); })},
    {mps, "min_remaining_fraction", seg::MIN_REMAINING_FRACTION,
     segmentation([](S& s, double v) { s.setMinRemainingFraction(v); })},
    {mps, "max_iterations", seg::MAX_ITERATIONS,
     segmentation([](S& s, double v) { s.setMaxIterations(toInt(v)); })},
    {mps, "lo_iterations", seg::LO_ITERATIONS,
     segmentation([](S& s, double v) { s.setLocalOptimizationIterations(toInt(v)); })},
    {mps, "merge_angle_rad", seg::MERGE_ANGLE_THRESHOLD,
     segmentation([](S& s, double v) { s.setMergeAngleThreshold(v); })},
    {mps, "merge_distance_m", seg::MERGE_DISTANCE_THRESHOLD,
     segmentation([](S& s, double v) { s.setMergeDistanceThreshold(v); })},
    {mps, "max_visibility_conflict_ratio", seg::MAX_VISIBILITY_CONFLICT_RATIO,
     segmentation([](S& s, double v) { s.setMaxVisibilityConflictRatio(v); })},
    {mps, "visibility_margin_m", seg::VISIBILITY_MARGIN,
     segmentation([](S& s, double v) { s.setVisibilityMargin(v); })},
    {mps, "visibility_cell_m", seg::VISIBILITY_CELL,
     segmentation([](S& s, double v) { s.setVisibilityCell(v); })},
    {mps, "min_sensor_distance_m", seg::MIN_SENSOR_DISTANCE,
     segmentation([](S& s, double v) { s.setMinSensorDistance(v); })},
    {mps, "min_sensor_height_m", seg::MIN_TERRAIN_SENSOR_HEIGHT,
     segmentation([](S& s, double v) { s.setMinTerrainSensorHeight(v); })},
    {mps, "max_terrain_below_ratio", seg::MAX_TERRAIN_BELOW_RATIO,
     segmentation([](S& s, double v) { s.setMaxTerrainBelowRatio(v); })},
    {mps, "min_cluster_size", seg::MIN_CLUSTER_SIZE,
     segmentation([](S& s, double v) { s.setMinClusterSize(toInt(v)); })},
    {mps, "cluster_cell_m", seg::CLUSTER_CELL,
     segmentation([](S& s, double v) { s.setClusterCell(v); })},
    {mps, "max_shell_ratio", seg::MAX_SHELL_RATIO,
     segmentation([](S& s, double v) { s.setMaxShellRatio(v); })},
    {mps, "shell_width_m", seg::SHELL_WIDTH,
     segmentation([](S& s, double v) { s.setShellWidth(v); })},
    {mps, "inlier_only_distance_threshold_m", seg::INLIER_ONLY_DISTANCE_THRESHOLD,
     segmentation([](S& s, double v) { s.setInlierOnlyDistanceThreshold(v); })},

    {pca, "min_cell_size_m", cub::MIN_CELL_SIZE,
     approximation([](A& a, double v) { a.setMinCellSize(v); })},
    {pca, "density_threshold", cub::DENSITY_THRESHOLD,
     approximation([](A& a, double v) { a.setDensityThreshold(v); })},
    {pca, "non_planar_density_threshold", cub::NON_PLANAR_DENSITY_THRESHOLD,
     approximation([](A& a, double v) { a.setNonPlanarDensityThreshold(v); })},
    {pca, "min_width_m", cub::MIN_WIDTH,
     approximation([](A& a, double v) { a.setMinWidth(v); })},
    {pca, "min_height_m", cub::MIN_HEIGHT,
     approximation([](A& a, double v) { a.setMinHeight(v); })},
    {pca, "thickness_m", cub::THICKNESS,
     approximation([](A& a, double v) { a.setThickness(v); })},
    {pca, "min_points_per_cell", cub::MIN_POINTS_PER_CELL,
     approximation([](A& a, double v) { a.setMinPointsPerCell(toInt(v)); })},

    {klf, "disparity_error_px", kl::DISPARITY_ERROR,
     filter([](Filter& f, double v) { f.setDisparityError(v); })},
    {klf, "depth_error_coefficient_per_m", kl::DEPTH_ERROR_COEFFICIENT,
     filter([](Filter& f, double v) { f.setDepthErrorCoefficient(v); })},
    {klf, "range_error_m", kl::RANGE_ERROR,
     filter([](Filter& f, double v) { f.setRangeError(v); })},
    {klf, "association_radius_m", kl::ASSOCIATION_RADIUS,
     filter([](Filter& f, double v) { f.setAssociationRadius(v); })},
    {klf, "neighbourhood_size_m", kl::NEIGHBOURHOOD_SIZE,
     filter([](Filter& f, double v) { f.setNeighbourhoodSize(v); })},
    {klf, "clamping_thres_min", kl::CLAMPING_THRES_MIN,
     filter([](Filter& f, double v) { f.setClampingThresMin(v); })},
    {klf, "clamping_thres_max", kl::CLAMPING_THRES_MAX,
     filter([](Filter& f, double v) { f.setClampingThresMax(v); })},
    {klf, "occupancy_thres", kl::OCCUPANCY_THRES,
     filter([](Filter& f, double v) { f.setOccupancyThres(v); })},
    {klf, "kl_offset_nats", kl::KL_OFFSET,
     filter([](Filter& f, double v) { f.setKLOffset(v); })},
    {klf, "prob_hit", kl::PROB_HIT,
     filter([](Filter& f, double v) { f.setProbHit(v); })},
    {klf, "prob_miss", kl::PROB_MISS,
     filter([](Filter& f, double v) { f.setProbMiss(v); })},
    {klf, "match_ratio", odo::RATIO, odometry([](O& p, double v) { p.ratio = v; })},
    {klf, "sigma_translation_m", cvm::SIGMA_TRANSLATION,
     motionModel([](M& p, double v) { p.sigma_translation_m = v; })},
    {klf, "sigma_rotation_rad", cvm::SIGMA_ROTATION,
     motionModel([](M& p, double v) { p.sigma_rotation_rad = v; })},

    {vo, "ratio", odo::RATIO, odometry([](O& p, double v) { p.ratio = v; })},
    {vo, "distance_threshold_m", odo::DISTANCE_THRESHOLD,
     odometry([](O& p, double v) { p.distance_threshold_m = v; })},
    {vo, "reprojection_threshold_px", odo::REPROJECTION_THRESHOLD,
     odometry([](O& p, double v) { p.reprojection_threshold_px = v; })},
    {vo, "max_iterations", odo::MAX_ITERATIONS,
     odometry([](O& p, double v) { p.max_iterations = toInt(v); })},
    {vo, "min_inliers", odo::MIN_INLIERS,
     odometry([](O& p, double v) { p.min_inliers = toInt(v); })},
    {vo, "epipolar_threshold_px", odo::EPIPOLAR_THRESHOLD,
     odometry([](O& p, double v) { p.epipolar_threshold_px = v; })},
    {vo, "disparity_offset_px", odo::DISPARITY_OFFSET,
     odometry([](O& p, double v) { p.disparity_offset_px = v; })},
    {vo, "disparity_offset_sigma_px", odo::DISPARITY_OFFSET_SIGMA,
     odometry([](O& p, double v) { p.disparity_offset_sigma_px = v; })},
    {vo, "disparity_offset_memory", odo::DISPARITY_OFFSET_MEMORY,
     odometry([](O& p, double v) { p.disparity_offset_memory = v; })},

    {sd, "downscale", dis::DOWNSCALE, disparity([](D& p, double v) {
       p.downscale = toInt(v);
       p.num_disparities_px = 64;
     })},
    {sd, "row_downscale", dis::ROW_DOWNSCALE,
     disparity([](D& p, double v) { p.row_downscale = toInt(v); })},
    {sd, "num_threads", dis::NUM_THREADS,
     disparity([](D& p, double v) { p.num_threads = toInt(v); })},
    {sd, "min_disparity_px", dis::MIN_DISPARITY,
     disparity([](D& p, double v) { p.min_disparity_px = toInt(v); })},
    {sd, "num_disparities_px", dis::NUM_DISPARITIES,
     disparity([](D& p, double v) { p.num_disparities_px = toInt(v); }), false},
    {sd, "block_size_px", dis::BLOCK_SIZE,
     disparity([](D& p, double v) { p.block_size_px = toInt(v); }), false},
    {sd, "p1", dis::P1, disparity([](D& p, double v) { p.p1 = toInt(v); }), false},
    {sd, "p2", dis::P2, disparity([](D& p, double v) { p.p2 = toInt(v); }), false},
    {sd, "disp12_max_diff_px", dis::DISP12_MAX_DIFF,
     disparity([](D& p, double v) { p.disp12_max_diff_px = toInt(v); })},
    {sd, "pre_filter_cap", dis::PRE_FILTER_CAP,
     disparity([](D& p, double v) { p.pre_filter_cap = toInt(v); })},
    {sd, "uniqueness_ratio_percent", dis::UNIQUENESS_RATIO,
     disparity([](D& p, double v) { p.uniqueness_ratio_percent = toInt(v); })},
    {sd, "speckle_window_size_px", dis::SPECKLE_WINDOW_SIZE,
     disparity([](D& p, double v) { p.speckle_window_size_px = toInt(v); })},
    {sd, "speckle_range_px", dis::SPECKLE_RANGE,
     disparity([](D& p, double v) { p.speckle_range_px = toInt(v); })},
    {sd, "bm_pre_filter_cap", dis::BM_PRE_FILTER_CAP, disparity([](D& p, double v) {
       p.algorithm = planar_grid::DisparityAlgorithm::BLOCK_MATCHING;
       p.bm_pre_filter_cap = toInt(v);
     })},
    {sd, "bm_pre_filter_size_px", dis::BM_PRE_FILTER_SIZE,
     disparity([](D& p, double v) {
       p.algorithm = planar_grid::DisparityAlgorithm::BLOCK_MATCHING;
       p.bm_pre_filter_size_px = toInt(v);
     })},
    {sd, "bm_texture_threshold", dis::BM_TEXTURE_THRESHOLD,
     disparity([](D& p, double v) {
       p.algorithm = planar_grid::DisparityAlgorithm::BLOCK_MATCHING;
       p.bm_texture_threshold = toInt(v);
     })},
    {sd, "max_range_m", planar_grid::point_cloud_from_disparity_ranges::MAX_RANGE,
     [](double v) {
       // A 1 x 1 disparity image, reprojected with a valid calibration.
       planar_grid::StereoCalibration calibration;
       calibration.focal_length_px = 500.0;
       calibration.baseline_m = 0.5;
       pcl::PointCloud<pcl::PointXYZI> cloud;
       return constructs([&] {
         planar_grid::disparityToPointCloud(cv::Mat(1, 1, CV_32FC1, cv::Scalar(10.0f)),
                                            cv::Mat(), calibration, v, cloud);
       });
     }},

    {"feature_matching", "max_features", fm::MAX_FEATURES,
     matcher([](F& p, double v) { p.max_features = toInt(v); })},
    {"feature_matching", "ratio", fm::RATIO,
     matcher([](F& p, double v) { p.ratio = v; })},
    {"feature_matching", "max_row_difference_px", fm::MAX_ROW_DIFFERENCE,
     matcher([](F& p, double v) { p.max_row_difference_px = v; })},
    {"feature_matching", "max_disparity_px", fm::MAX_DISPARITY,
     matcher([](F& p, double v) { p.max_disparity_px = v; })},
    {"feature_matching", "max_range_m", fm::MAX_RANGE,
     matcher([](F& p, double v) { p.max_range_m = v; })},
    {"feature_matching", "bucket_size_px", fm::BUCKET_SIZE,
     matcher([](F& p, double v) { p.bucket_size_px = toInt(v); })},
    {"feature_matching", "fast_threshold", fm::FAST_THRESHOLD,
     matcher([](F& p, double v) { p.fast_threshold = toInt(v); })},
    {"feature_matching", "subpixel_window_px", fm::SUBPIXEL_WINDOW,
     matcher([](F& p, double v) { p.subpixel_window_px = toInt(v); })},
    {"feature_matching", "subpixel_search_px", fm::SUBPIXEL_SEARCH,
     matcher([](F& p, double v) { p.subpixel_search_px = toInt(v); })},
    {"cloud_features", "max_features", fm::MAX_FEATURES,
     matcher([](F& p, double v) { p.max_features = toInt(v); })},
    {"cloud_features", "bucket_size_px", fm::BUCKET_SIZE,
     matcher([](F& p, double v) { p.bucket_size_px = toInt(v); })},
    {"cloud_features", "fast_threshold", fm::FAST_THRESHOLD,
     matcher([](F& p, double v) { p.fast_threshold = toInt(v); })},
    {"cloud_features", "max_range_m", fm::MAX_RANGE,
     matcher([](F& p, double v) { p.max_range_m = v; })},

    {mi, "resolution_m", sl::RESOLUTION,
     surfaceLayer([](L& p, double v) { p.resolution_m = v; })},
    {mi, "thickness_m", sl::THICKNESS,
     surfaceLayer([](L& p, double v) { p.thickness_m = v; })},
    {mi, "plane_merge_angle_rad", sl::PLANE_MERGE_ANGLE,
     surfaceLayer([](L& p, double v) { p.plane_merge_angle_rad = v; })},
    {mi, "plane_merge_distance_m", sl::PLANE_MERGE_DISTANCE,
     surfaceLayer([](L& p, double v) { p.plane_merge_distance_m = v; })},
    {mi, "close_gaps_cells", sl::CLOSE_GAPS,
     surfaceLayer([](L& p, double v) { p.close_gaps_cells = toInt(v); })},
    {mi, "cover_density", sl::COVER_DENSITY,
     surfaceLayer([](L& p, double v) { p.cover_density = v; })},
    {mi, "occupancy_thres", sl::OCCUPANCY_THRES,
     surfaceLayer([](L& p, double v) { p.occupancy_thres = v; })},
    {mi, "feature_distance_m", sl::FEATURE_DISTANCE,
     surfaceLayer([](L& p, double v) { p.feature_distance_m = v; })},
    {mi, "absorb_distance_m", sl::ABSORB_DISTANCE,
     surfaceLayer([](L& p, double v) { p.absorb_distance_m = v; })},
    {mi, "terrain_plane_tile_m", sl::TERRAIN_PLANE_TILE,
     surfaceLayer([](L& p, double v) { p.terrain_plane_tile_m = v; })},
    {mi, "terrain_cover_density", sl::TERRAIN_COVER_DENSITY,
     surfaceLayer([](L& p, double v) { p.terrain_cover_density = v; })},
    {mi, "min_plane_cells", sl::MIN_PLANE_CELLS,
     surfaceLayer([](L& p, double v) { p.min_plane_cells = toInt(v); })},
    {mi, "max_range_m", esg::MAX_RANGE,
     spaceGrid([](G& p, double v) { p.max_range_m = v; })},
    {mi, "surface_margin_m", esg::SURFACE_MARGIN,
     spaceGrid([](G& p, double v) { p.surface_margin_m = v; })},
    {"statistical_outlier_removal", "mean_k",
     planar_grid::fast_statistical_outlier_removal_ranges::MEAN_K,
     outlierRemovalAccepts},
  };
}

/** The values just outside \a range (an open end itself, else one step beyond it: the
 * next integer for an INT parameter, a relative 1e-9 for a real one) and just inside
 * it (a closed end itself, else one step within). The real step is not the next double,
 * whose subnormal neighbours of 0 a YAML number does not round-trip. */
struct Edges {
  std::vector<double> outside;
  std::vector<double> inside;
};

Edges
edges(const ParamRange& range, bool integer)
{
  const auto step = [integer](double end) {
    return integer ? 1.0 : 1e-9 * std::max(1.0, std::abs(end));
  };
  Edges e;
  if (std::isfinite(range.min)) {
    e.outside.push_back(range.min_open ? range.min : range.min - step(range.min));
    e.inside.push_back(range.min_open ? range.min + step(range.min) : range.min);
  }
  if (std::isfinite(range.max)) {
    e.outside.push_back(range.max_open ? range.max : range.max + step(range.max));
    e.inside.push_back(range.max_open ? range.max - step(range.max) : range.max);
  }
  return e;
}

/** Whether the stage's parser accepts \a value for \a key (a YAML scalar written with
 * every digit, so that it reads back as the same double). */
bool
parserAccepts(const ParamSpec& spec, const std::string& stage, double value)
{
  std::ostringstream text;
  text << spec.key << ": " << std::setprecision(17) << value;
  try {
    const auto info = planar_grid::findStage(stage);
    planar_grid::parseParams(YAML::Load(text.str()), info->params, "t.yaml", stage);
    return true;
  } catch (const planar_grid::ConfigError&) {
    return false;
  }
}

bool
sameRange(const ParamRange& a, const ParamRange& b)
{
  return a.min == b.min && a.max == b.max && a.min_open == b.min_open
         && a.max_open == b.max_open;
}

} // namespace

TEST(ParamRange, ContainsHonoursOpenEndsAndRefusesNonFinite)
{
  constexpr ParamRange r = ParamRange::openMin(0.0, 10.0);
  static_assert(!r.contains(0.0) && r.contains(10.0), "(0, 10] at compile time");
  EXPECT_TRUE(r.contains(1e-300));
  EXPECT_FALSE(r.contains(std::nextafter(10.0, 11.0)));
  EXPECT_FALSE(r.contains(std::numeric_limits<double>::quiet_NaN()));
  const ParamRange unbounded = ParamRange::openMax(0.0, ParamRange::UNBOUNDED);
  EXPECT_TRUE(unbounded.contains(1e300));
  EXPECT_FALSE(unbounded.contains(std::numeric_limits<double>::infinity()));
  EXPECT_FALSE(unbounded.contains(-std::numeric_limits<double>::infinity()));
  EXPECT_TRUE(ParamRange::open(0.0, 1.0).contains(0.5));
  EXPECT_FALSE(ParamRange::open(0.0, 1.0).contains(1.0));
}

TEST(ParamRange, WritesIntervals)
{
  EXPECT_EQ(planar_grid::formatParamRange(ParamRange::openMin(0.0, 10.0), "m"),
            "(0, 10] m");
  EXPECT_EQ(planar_grid::formatParamRange(ParamRange::closed(3, 100000000)),
            "[3, 100000000]");
  EXPECT_EQ(planar_grid::formatParamRange(ParamRange::open(0.5, 1.0)), "(0.5, 1)");
  EXPECT_EQ(planar_grid::formatParamRange(
              ParamRange::openMax(0.0, ParamRange::UNBOUNDED), "1/m"),
            "[0, inf) 1/m");
  EXPECT_EQ(planar_grid::paramRangeMessage("distance_threshold",
                                           ParamRange::openMin(0.0, 1.0), "m"),
            "distance_threshold must be in (0, 1] m");
}

TEST(ParamRange, ParserWritesTheIntervalOfARefusedValue)
{
  const auto info = planar_grid::findStage("multi_plane_segmentation");
  ASSERT_NE(info, nullptr);
  try {
    planar_grid::parseParams(YAML::Load("distance_threshold_m: 0"), info->params,
                             "t.yaml", info->type);
    FAIL() << "distance_threshold_m = 0 was accepted";
  } catch (const planar_grid::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("= 0 is out of range (0, 1] m"),
              std::string::npos)
      << e.what();
  }
  EXPECT_NE(planar_grid::describeParams(info->params).find("range (0, 1] m"),
            std::string::npos);
}

TEST(ParamRange, StageTablesAndClassesAgree)
{
  std::set<std::pair<std::string, std::string>> seen;
  for (const ClassParam& c : classParams()) {
    SCOPED_TRACE(c.stage + "." + c.key);
    EXPECT_TRUE(seen.insert({c.stage, c.key}).second) << "listed twice";
    const auto info = planar_grid::findStage(c.stage);
    ASSERT_NE(info, nullptr);
    const auto spec = std::find_if(info->params.begin(), info->params.end(),
                                   [&c](const ParamSpec& s) { return s.key == c.key; });
    ASSERT_NE(spec, info->params.end());
    // The table holds the class's declaration.
    EXPECT_TRUE(sameRange(spec->range, c.range))
      << planar_grid::formatParamRange(spec->range) << " against "
      << planar_grid::formatParamRange(c.range);
    const Edges e = edges(c.range, spec->type == ParamSpec::Type::INT);
    ASSERT_FALSE(e.outside.empty());
    for (const double v : e.outside) {
      EXPECT_FALSE(parserAccepts(*spec, c.stage, v)) << "parser took " << v;
      EXPECT_FALSE(c.class_accepts(v)) << "class took " << v;
    }
    if (!c.inside_edges_accepted)
      continue;
    for (const double v : e.inside) {
      EXPECT_TRUE(parserAccepts(*spec, c.stage, v)) << "parser refused " << v;
      EXPECT_TRUE(c.class_accepts(v)) << "class refused " << v;
    }
  }
}
