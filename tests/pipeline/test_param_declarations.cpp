// SPDX-License-Identifier: BSD-3-Clause
// An algorithm's parameters are declared once (PlanarGridMap::getParamDeclarations(),
// TerrainRemoval::getParamDeclarations(), ...): its stage's list, the parsing into the
// class and the stage's echo come from that table.
#include <planar_grid/filters/depth_error_filter.h>
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/fast_voxel_grid.h>
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/stereo_odometry.h>
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/segmentation/terrain_removal.h>
#include <planar_grid/stereo/disparity_estimator.h>
#include <planar_grid/stereo/stereo_feature_matcher.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/point_types.h>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <map>
#include <memory>
#include <string>
#include <variant>
#include <vector>

namespace {

using planar_grid::ParamSpec;
using planar_grid::ParamValue;
using planar_grid::ParamValues;
using planar_grid::PlanarGridMap;
using MapDeclaration = planar_grid::ParamDeclaration<PlanarGridMap::Params>;
using TerrainDeclaration =
  planar_grid::ParamDeclaration<planar_grid::TerrainRemovalParams>;

const planar_grid::StageInfo&
stage(const std::string& type)
{
  const auto& registry = planar_grid::stageRegistry();
  const auto it = std::find_if(registry.begin(), registry.end(),
                               [&type](const auto& info) { return info.type == type; });
  if (it == registry.end())
    throw std::runtime_error("no stage " + type);
  return *it;
}

const planar_grid::StageInfo&
mapStage()
{
  return stage("map_integration");
}

/** A valid value of \a d other than its default, as YAML text and as a value. */
template <typename Params>
std::pair<std::string, ParamValue>
otherValue(const planar_grid::ParamDeclaration<Params>& d)
{
  using Declaration = planar_grid::ParamDeclaration<Params>;
  const ParamValue value = d.get(Params{});
  switch (d.type) {
    case Declaration::Type::BOOL:
      return {std::get<bool>(value) ? "false" : "true", !std::get<bool>(value)};
    case Declaration::Type::CHOICE:
      for (const auto& name : d.choices)
        if (name != std::get<std::string>(value))
          return {name, name};
      break;
    case Declaration::Type::INT: {
      const int v = std::get<int>(value);
      // + 2 first: an odd window size stays odd.
      for (const int candidate : {v + 2, v + 1, v - 1})
        if (d.range.contains(candidate))
          return {std::to_string(candidate), candidate};
      break;
    }
    case Declaration::Type::DOUBLE: {
      const double v = std::get<double>(value);
      // Values whose decimal text is exact enough to compare after YAML.
      for (const double candidate : {v * 2.0, v * 0.5, v + 0.25, 0.5, 1.0, 0.75})
        if (candidate != v && d.range.contains(candidate))
          return {planar_grid::formatParamNumber(candidate), candidate};
      break;
    }
  }
  throw std::runtime_error("no other value for " + d.key);
}

/** Every declaration of \a table is in \a stage_params as declared, with the
 * class's default; every key once. */
template <typename Params>
void
expectListedAsDeclared(const planar_grid::ParamDeclarations<Params>& table,
                       const std::vector<ParamSpec>& params)
{
  using Declaration = planar_grid::ParamDeclaration<Params>;
  for (const Declaration& d : table) {
    SCOPED_TRACE(d.key);
    const auto spec = std::find_if(params.begin(), params.end(),
                                   [&d](const ParamSpec& s) { return s.key == d.key; });
    ASSERT_NE(spec, params.end()) << "the stage does not list it";
    EXPECT_EQ(static_cast<int>(spec->type), static_cast<int>(d.type));
    EXPECT_EQ(spec->unit, d.unit);
    EXPECT_EQ(spec->description, d.description);
    EXPECT_EQ(spec->choices, d.choices);
    EXPECT_EQ(spec->cell_size_scaling, d.cell_size_scaling);
    if (d.type == Declaration::Type::DOUBLE || d.type == Declaration::Type::INT) {
      EXPECT_EQ(spec->range.min, d.range.min);
      EXPECT_EQ(spec->range.max, d.range.max);
      EXPECT_EQ(spec->range.min_open, d.range.min_open);
      EXPECT_EQ(spec->range.max_open, d.range.max_open);
    }
    // The stage's default is the class's: the member's initializer.
    const ParamValues stage_defaults = planar_grid::defaultParams({*spec});
    EXPECT_EQ(stage_defaults.values().at(d.key), d.get(Params{}));
  }
  for (std::size_t i = 0; i < table.size(); ++i)
    for (std::size_t j = i + 1; j < table.size(); ++j)
      EXPECT_NE(table[i].key, table[j].key);
}

/** The stage's keys in their order. */
std::vector<std::string>
keysOf(const std::vector<ParamSpec>& params)
{
  std::vector<std::string> keys;
  for (const auto& spec : params)
    keys.push_back(spec.key);
  return keys;
}

/** A non-default value of each declaration of \a table (\a other_values where the
 * class ties it to another parameter), given to \a stage_type as YAML, reaches the
 * class (\a make_class builds it from the parsed Params and
 * \a get_params reads them back) with every other member at its default, and comes
 * back in the stage's echo. */
template <typename Params, typename MakeClass, typename GetParams>
void
expectEachValueReachesTheClassAndTheEcho(
  const planar_grid::ParamDeclarations<Params>& table,
  const std::string& stage_type,
  MakeClass make_class,
  GetParams get_params,
  const std::map<std::string, std::pair<std::string, ParamValue>>& other_values = {})
{
  const auto& info = stage(stage_type);
  for (const auto& d : table) {
    SCOPED_TRACE(d.key);
    const auto given = other_values.find(d.key);
    const auto [text, value] =
      given != other_values.end() ? given->second : otherValue(d);
    const ParamValues parsed = planar_grid::parseParams(
      YAML::Load("{" + d.key + ": " + text + "}"), info.params, "s.yaml", info.type);
    Params params;
    planar_grid::assignParams(table, parsed, params);
    const auto object = make_class(params);
    for (const auto& other : table)
      EXPECT_EQ(other.get(get_params(object)),
                other.key == d.key ? value : other.get(Params{}))
        << other.key;
    ParamValues held;
    info.create(parsed)->getParameters(held);
    EXPECT_EQ(held.values().at(d.key), value);
  }
}

TEST(ParamDeclarations, MultiPlaneSegmentationIsTheSegmentationsTableAndItsOwn)
{
  using Segmentation = planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ>;
  const auto& table = Segmentation::getParamDeclarations();
  const auto& params = stage("multi_plane_segmentation").params;
  ASSERT_EQ(table.size(), 33u);
  expectListedAsDeclared(table, params);
  // A default-constructed class holds the table's defaults (the pipeline's).
  const Segmentation defaults;
  for (const auto& d : table)
    EXPECT_EQ(d.get(defaults.getParams()), d.get(Segmentation::Params{})) << d.key;
  EXPECT_EQ(defaults.getMaxNormalAngle(), 0.5);
  EXPECT_EQ(defaults.getSampleDistanceThreshold(), 0.1);
  // The stage's own keys stand beside the class keys they go with, in the order
  // docs/STAGES.md documents.
  const std::vector<std::string> expected{"distance_threshold_m",
                                          "depth_noise_disparity_px",
                                          "depth_noise_along_sight",
                                          "sample_distance_threshold_m",
                                          "max_planes",
                                          "min_inliers",
                                          "min_sample_inliers",
                                          "min_remaining_fraction",
                                          "max_iterations",
                                          "probability",
                                          "method",
                                          "optimize_coefficients",
                                          "dense_hypothesis",
                                          "lo_iterations",
                                          "merge_planes",
                                          "merge_angle_rad",
                                          "merge_distance_m",
                                          "sample",
                                          "seed",
                                          "max_sample_size",
                                          "max_visibility_conflict_ratio",
                                          "visibility_margin_m",
                                          "visibility_cell_m",
                                          "min_sensor_distance_m",
                                          "min_sensor_height_m",
                                          "max_terrain_below_ratio",
                                          "min_cluster_size",
                                          "cluster_cell_m",
                                          "max_shell_ratio",
                                          "shell_width_m",
                                          "count_inlier_only_points",
                                          "inlier_only_distance_threshold_m",
                                          "max_normal_angle_rad",
                                          "normal_cell_m",
                                          "normal_source",
                                          "normal_window_m",
                                          "min_normal_agreement"};
  EXPECT_EQ(keysOf(params), expected);
  expectEachValueReachesTheClassAndTheEcho(
    table, "multi_plane_segmentation",
    [](const Segmentation::Params& p) { return Segmentation(p); },
    [](const Segmentation& s) { return s.getParams(); });
  // The class's setters write the same members.
  Segmentation segmentation;
  segmentation.setMaxNormalAngle(0.0);
  segmentation.setMinTerrainSensorHeight(1.5);
  segmentation.setSeed(9u);
  segmentation.setProbability(0.95);
  segmentation.setMaxSampleSize(5000);
  EXPECT_EQ(segmentation.getParams().probability, 0.95);
  EXPECT_EQ(segmentation.getParams().max_sample_size, 5000);
  EXPECT_EQ(segmentation.getParams().max_normal_angle_rad, 0.0);
  EXPECT_EQ(segmentation.getParams().min_sensor_height_m, 1.5);
  EXPECT_EQ(segmentation.getParams().seed, 9u);
}

TEST(ParamDeclarations, KLOccupancyFilterIsTheFiltersTableAndItsOwn)
{
  using Filter = planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ>;
  const auto& table = Filter::getParamDeclarations();
  const auto& params = stage("kl_occupancy_filter").params;
  ASSERT_EQ(table.size(), 12u);
  expectListedAsDeclared(table, params);
  // A default-constructed filter holds the table's defaults (the pipeline's).
  const Filter defaults;
  for (const auto& d : table)
    EXPECT_EQ(d.get(defaults.getParams()), d.get(Filter::Params{})) << d.key;
  EXPECT_EQ(defaults.getAssociationRadius(), 0.1);
  // The stage's sensor model follows the update rule; its matching and motion keys
  // come last, in the order docs/STAGES.md documents.
  const std::vector<std::string> expected{"update_rule",
                                          "range_error_model",
                                          "disparity_error_px",
                                          "depth_error_coefficient_per_m",
                                          "range_error_m",
                                          "association_radius_m",
                                          "neighbourhood_size_m",
                                          "clamping_thres_min",
                                          "clamping_thres_max",
                                          "occupancy_thres",
                                          "kl_offset_nats",
                                          "prob_hit",
                                          "prob_miss",
                                          "match_ratio",
                                          "search_radius_px",
                                          "max_hamming_distance_bits",
                                          "use_motion_likelihood",
                                          "sigma_translation_m",
                                          "sigma_rotation_rad"};
  EXPECT_EQ(keysOf(params), expected);
  expectEachValueReachesTheClassAndTheEcho(
    table, "kl_occupancy_filter",
    [](const Filter::Params& p) {
      auto filter = std::make_unique<Filter>();
      filter->setParams(p);
      return filter;
    },
    [](const std::unique_ptr<Filter>& f) { return f->getParams(); });
}

TEST(ParamDeclarations, FilterStagesAreTheFiltersTables)
{
  using VoxelGrid = planar_grid::FastVoxelGrid<pcl::PointXYZ>;
  using OutlierRemoval = planar_grid::FastStatisticalOutlierRemoval<pcl::PointXYZ>;
  using DepthError = planar_grid::DepthErrorFilter<pcl::PointXYZ>;
  // voxel_grid and statistical_outlier_removal are their filter's table alone.
  ASSERT_EQ(VoxelGrid::getParamDeclarations().size(), 2u);
  expectListedAsDeclared(VoxelGrid::getParamDeclarations(), stage("voxel_grid").params);
  EXPECT_EQ(stage("voxel_grid").params.size(), 2u);
  ASSERT_EQ(OutlierRemoval::getParamDeclarations().size(), 2u);
  expectListedAsDeclared(OutlierRemoval::getParamDeclarations(),
                         stage("statistical_outlier_removal").params);
  EXPECT_EQ(stage("statistical_outlier_removal").params.size(), 2u);
  // depth_error_filter: the filter's two, then the stage's own two.
  ASSERT_EQ(DepthError::getParamDeclarations().size(), 2u);
  expectListedAsDeclared(DepthError::getParamDeclarations(),
                         stage("depth_error_filter").params);
  EXPECT_EQ(keysOf(stage("depth_error_filter").params),
            (std::vector<std::string>{"disparity_error_px", "max_depth_error_m",
                                      "max_plane_depth_error_m", "far_levels"}));
  // A default-constructed filter holds the table's defaults (the pipeline's).
  const VoxelGrid grid;
  for (const auto& d : VoxelGrid::getParamDeclarations())
    EXPECT_EQ(d.get(grid.getParams()), d.get(VoxelGrid::Params{})) << d.key;
  EXPECT_EQ(grid.getLeafSize().x(), 0.05f);
  const OutlierRemoval removal;
  for (const auto& d : OutlierRemoval::getParamDeclarations())
    EXPECT_EQ(d.get(removal.getParams()), d.get(OutlierRemoval::Params{})) << d.key;
  EXPECT_EQ(removal.getMeanK(), 20);
  const DepthError depth;
  for (const auto& d : DepthError::getParamDeclarations())
    EXPECT_EQ(d.get(depth.getParams()), d.get(DepthError::Params{})) << d.key;
  // Each value reaches the filter and the stage's echo.
  expectEachValueReachesTheClassAndTheEcho(
    VoxelGrid::getParamDeclarations(), "voxel_grid",
    [](const VoxelGrid::Params& p) {
      auto filter = std::make_unique<VoxelGrid>();
      filter->setParams(p);
      return filter;
    },
    [](const std::unique_ptr<VoxelGrid>& f) { return f->getParams(); });
  expectEachValueReachesTheClassAndTheEcho(
    OutlierRemoval::getParamDeclarations(), "statistical_outlier_removal",
    [](const OutlierRemoval::Params& p) {
      auto filter = std::make_unique<OutlierRemoval>();
      filter->setParams(p);
      return filter;
    },
    [](const std::unique_ptr<OutlierRemoval>& f) { return f->getParams(); });
  expectEachValueReachesTheClassAndTheEcho(
    DepthError::getParamDeclarations(), "depth_error_filter",
    [](const DepthError::Params& p) {
      auto filter = std::make_unique<DepthError>();
      filter->setParams(p);
      return filter;
    },
    [](const std::unique_ptr<DepthError>& f) { return f->getParams(); });
}

TEST(ParamDeclarations, PlanarCuboidApproximationIsTheApproximationsTable)
{
  using Approximation = planar_grid::PlanarCuboidApproximation<pcl::PointXYZ>;
  const auto& table = Approximation::getParamDeclarations();
  const auto& params = stage("planar_cuboid_approximation").params;
  ASSERT_EQ(table.size(), 7u);
  expectListedAsDeclared(table, params);
  EXPECT_EQ(params.size(), table.size());
  const Approximation defaults;
  for (const auto& d : table)
    EXPECT_EQ(d.get(defaults.getParams()), d.get(Approximation::Params{})) << d.key;
  EXPECT_EQ(defaults.getNonPlanarDensityThreshold(), 0.25);
  expectEachValueReachesTheClassAndTheEcho(
    table, "planar_cuboid_approximation",
    [](const Approximation::Params& p) { return std::make_unique<Approximation>(p); },
    [](const std::unique_ptr<Approximation>& a) { return a->getParams(); });
}

TEST(ParamDeclarations, VisualOdometryIsStereoOdometrysTableAndItsOwn)
{
  using Odometry = planar_grid::StereoOdometry;
  const auto& table = Odometry::getParamDeclarations();
  const auto& params = stage("visual_odometry").params;
  ASSERT_EQ(table.size(), 12u);
  expectListedAsDeclared(table, params);
  const std::vector<std::string> expected{"ratio",
                                          "distance_threshold_m",
                                          "reprojection_threshold_px",
                                          "max_iterations",
                                          "min_inliers",
                                          "reprojection_refinement",
                                          "epipolar_refinement",
                                          "epipolar_threshold_px",
                                          "seed",
                                          "estimate_disparity_offset",
                                          "disparity_offset_px",
                                          "disparity_offset_sigma_px",
                                          "disparity_offset_memory",
                                          "initial_height_m",
                                          "initial_pitch_rad"};
  EXPECT_EQ(keysOf(params), expected);
  expectEachValueReachesTheClassAndTheEcho(
    table, "visual_odometry",
    [](const Odometry::Params& p) { return std::make_unique<Odometry>(p); },
    [](const std::unique_ptr<Odometry>& o) { return o->getParams(); });
}

TEST(ParamDeclarations, FeatureMatchingIsTheMatchersTable)
{
  using Matcher = planar_grid::StereoFeatureMatcher;
  const auto& table = Matcher::getParamDeclarations();
  const auto& params = stage("feature_matching").params;
  ASSERT_EQ(table.size(), 10u);
  expectListedAsDeclared(table, params);
  EXPECT_EQ(params.size(), table.size());
  expectEachValueReachesTheClassAndTheEcho(
    table, "feature_matching",
    [](const Matcher::Params& p) { return std::make_unique<Matcher>(p); },
    [](const std::unique_ptr<Matcher>& m) { return m->getParams(); });
}

TEST(ParamDeclarations, StereoDisparityIsTheEstimatorsTableAndItsOwn)
{
  using Estimator = planar_grid::DisparityEstimator;
  const auto& table = Estimator::getParamDeclarations();
  const auto& params = stage("stereo_disparity").params;
  ASSERT_EQ(table.size(), 19u);
  expectListedAsDeclared(table, params);
  // The estimator's keys, then the stage's range and frame selection.
  std::vector<std::string> expected;
  for (const auto& d : table)
    expected.push_back(d.key);
  for (const char* key :
       {"max_range_m", "frame_selection", "every_n_frames", "keyframe_translation_m",
        "keyframe_rotation_rad", "keyframe_max_gap_frames"})
    expected.emplace_back(key);
  EXPECT_EQ(keysOf(params), expected);
  // The disparity count is a multiple of 16 * downscale (128 at the defaults), and p2
  // exceeds p1 (8 * 5^2 = 200 when left at 0).
  expectEachValueReachesTheClassAndTheEcho(
    table, "stereo_disparity",
    [](const Estimator::Params& p) { return std::make_unique<Estimator>(p); },
    [](const std::unique_ptr<Estimator>& e) { return e->getParams(); },
    {{"num_disparities_px", {"144", 144}},
     {"downscale", {"2", 2}},
     {"p2", {"1000", 1000}}});
}

TEST(ParamDeclarations, MapIntegrationListsEveryMapParameterAsDeclared)
{
  ASSERT_GE(PlanarGridMap::getParamDeclarations().size(), 20u);
  expectListedAsDeclared(PlanarGridMap::getParamDeclarations(), mapStage().params);
}

TEST(ParamDeclarations, GroundRemovalIsTerrainRemovalsTable)
{
  const auto& table =
    planar_grid::TerrainRemoval<pcl::PointXYZ>::getParamDeclarations();
  ASSERT_EQ(table.size(), 7u);
  expectListedAsDeclared(table, stage("ground_removal").params);
  // The stage lists nothing else, and each value reaches the class and the echo.
  EXPECT_EQ(stage("ground_removal").params.size(), table.size());
  for (const TerrainDeclaration& d : table) {
    SCOPED_TRACE(d.key);
    const auto [text, value] = otherValue(d);
    const auto& info = stage("ground_removal");
    const ParamValues parsed = planar_grid::parseParams(
      YAML::Load("{" + d.key + ": " + text + "}"), info.params, "g.yaml", info.type);
    planar_grid::TerrainRemovalParams params;
    planar_grid::assignParams(table, parsed, params);
    const planar_grid::TerrainRemoval<pcl::PointXYZ> removal(params);
    EXPECT_EQ(d.get(removal.getParams()), value);
    ParamValues held;
    info.create(parsed)->getParameters(held);
    EXPECT_EQ(held.values().at(d.key), value);
  }
}

TEST(ParamDeclarations, RangesAreCheckedFromTheTable)
{
  const auto& table =
    planar_grid::TerrainRemoval<pcl::PointXYZ>::getParamDeclarations();
  planar_grid::TerrainRemovalParams params;
  EXPECT_EQ(planar_grid::checkDeclaredRanges(table, params), "");
  params.terrain_cell_m = 0.0;
  EXPECT_EQ(planar_grid::checkDeclaredRanges(table, params),
            "terrain_cell_m must be in [0.05, 100] m, got 0");
  // The class's own check is the table's.
  planar_grid::TerrainRemoval<pcl::PointXYZ> removal(params);
  pcl::PointCloud<pcl::PointXYZ> cloud;
  planar_grid::PlanarSegments planes;
  std::vector<std::uint8_t> terrain;
  try {
    removal.segment(cloud, planes, terrain);
    ADD_FAILURE() << "no error";
  } catch (const planar_grid::Exception& e) {
    EXPECT_EQ(std::string(e.what()),
              "TerrainRemoval: terrain_cell_m must be in [0.05, 100] m, got 0");
  }
}

TEST(ParamDeclarations, EachValueReachesTheMapAndTheStageEcho)
{
  const auto& info = mapStage();
  for (const MapDeclaration& d : PlanarGridMap::getParamDeclarations()) {
    SCOPED_TRACE(d.key);
    const auto [text, value] = otherValue(d);
    const ParamValues parsed = planar_grid::parseParams(
      YAML::Load("{" + d.key + ": " + text + "}"), info.params, "map.yaml", info.type);
    // Into the map: this member changes, every other keeps its default.
    PlanarGridMap::Params params;
    planar_grid::assignParams(PlanarGridMap::getParamDeclarations(), parsed, params);
    const PlanarGridMap map(params);
    for (const MapDeclaration& other : PlanarGridMap::getParamDeclarations())
      EXPECT_EQ(other.get(map.getParams()),
                other.key == d.key ? value : other.get(PlanarGridMap::Params{}))
        << other.key;
    // Through the stage, whose echo reports it.
    const auto stage = info.create(parsed);
    ParamValues held;
    stage->getParameters(held);
    EXPECT_EQ(held.values().at(d.key), value);
  }
}

/** Setting a choice of \a table to a name that is none of its choices throws and
 * leaves the member as it was. */
template <typename Params>
void
expectUnknownChoiceRefused(const planar_grid::ParamDeclarations<Params>& table)
{
  using Declaration = planar_grid::ParamDeclaration<Params>;
  Params params;
  for (const Declaration& d : table)
    if (d.type == Declaration::Type::CHOICE) {
      SCOPED_TRACE(d.key);
      EXPECT_THROW(d.set(params, std::string("no_such_name")), planar_grid::Exception);
      EXPECT_EQ(d.get(params), d.get(Params{}));
    }
}

TEST(ParamDeclarations, AChoiceThatIsNoneOfTheNamesIsRefused)
{
  expectUnknownChoiceRefused(PlanarGridMap::getParamDeclarations());
  expectUnknownChoiceRefused(
    planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ>::getParamDeclarations());
  expectUnknownChoiceRefused(
    planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ>::getParamDeclarations());
  expectUnknownChoiceRefused(planar_grid::StereoFeatureMatcher::getParamDeclarations());
}

} // namespace

namespace {

enum class Shade { LIGHT, DARK };

struct ShadeParams {
  Shade shade{Shade::LIGHT};
};

} // namespace

TEST(ParamDeclarations, NamedChoiceReadsAndWritesEveryNameOfItsOneTable)
{
  const auto declaration = planar_grid::declareNamedChoice<ShadeParams, Shade>(
    "shade", [](auto& p) -> auto& { return p.shade; },
    {{"light", Shade::LIGHT}, {"dark", Shade::DARK}}, "Which shade.");
  EXPECT_EQ(declaration.choices, (std::vector<std::string>{"light", "dark"}));
  ShadeParams params;
  EXPECT_EQ(std::get<std::string>(declaration.get(params)), "light");
  declaration.set(params, ParamValue(std::string("dark")));
  EXPECT_EQ(params.shade, Shade::DARK);
  EXPECT_EQ(std::get<std::string>(declaration.get(params)), "dark");
  try {
    declaration.set(params, ParamValue(std::string("grey")));
    FAIL() << "a name that is none of the table's was accepted";
  } catch (const planar_grid::Exception& e) {
    EXPECT_EQ(std::string(e.what()), "Unknown shade 'grey' (light, dark)");
  }
  EXPECT_EQ(params.shade, Shade::DARK);
}
