// SPDX-License-Identifier: BSD-3-Clause
// The comparison configuration file: its YAML schema, parsed strictly.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/eval/map_comparison.h>
#include <planar_grid/eval/map_comparison_config.h>
#include <planar_grid/eval/mapping_error.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <limits>
#include <utility>
#include <vector>

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

/** Whether the stage registry declares \a type a front-end stage, which does not
 * depend on the cell size and so runs once per frame for all sizes. */
bool
isFrontEnd(const std::string& type)
{
  const StageInfo* info = findStage(type);
  return info && info->role == StageRole::FRONT_END;
}

ComparisonConfig
parseComparison(const YAML::Node& root, const std::string& path)
{
  const YamlReader r(path, fs::path(path).parent_path().string());
  const auto count = [&r](const YAML::Node& node, long long min,
                          const std::string& what) {
    return static_cast<std::size_t>(r.integerValue(node, min, 100000000, what));
  };
  ComparisonConfig config;
  config.source_file = path;
  r.checkKeys(
    root,
    {"environment", "resolutions_m", "tolerance_cells", "places", "datasets", "output"},
    "the evaluation configuration");
  const auto parsePlaces = [&](const YAML::Node& places, std::size_t& places_count,
                               double& radius_m) {
    r.checkKeys(places, {"count", "radius_m"}, "places");
    if (places["count"])
      places_count = count(places["count"], 0, "places.count");
    if (places["radius_m"])
      radius_m = r.realValue(places["radius_m"], 0.0, 1000.0, "places.radius_m");
  };
  if (const YAML::Node places = root["places"])
    parsePlaces(places, config.places, config.place_radius_m);
  if (root["environment"]) {
    config.environment = r.string(root, "environment", "the configuration");
    if (config.environment != "indoor" && config.environment != "outdoor")
      r.fail(root["environment"], "environment must be indoor or outdoor");
  }
  if (const YAML::Node res = root["resolutions_m"]) {
    if (!res.IsSequence() || res.size() == 0)
      r.fail(res, "resolutions_m must be a non-empty list of cell sizes in meters");
    config.resolutions_m.clear();
    for (const auto& v : res)
      config.resolutions_m.push_back(
        r.realValue(v, 0.01, 10.0, "resolutions_m entries"));
  }
  if (root["tolerance_cells"])
    config.tolerance_cells =
      r.realValue(root["tolerance_cells"], 0.1, 10.0, "tolerance_cells");
  if (const YAML::Node out = root["output"]) {
    r.checkKeys(out, {"folder", "save_maps"}, "output");
    config.output_folder = r.string(out, "folder", "output");
    config.save_maps = r.boolean(out, "save_maps", false, "output");
  }
  const YAML::Node datasets = root["datasets"];
  if (!datasets || !datasets.IsSequence() || datasets.size() == 0)
    r.fail(datasets ? datasets : root, "datasets must be a non-empty list");
  for (const auto& node : datasets) {
    r.checkKeys(node,
                {"name", "pipeline", "set", "frames", "truth", "tilt_deg", "places"},
                "a dataset");
    DatasetConfig ds;
    ds.places = config.places;
    ds.place_radius_m = config.place_radius_m;
    if (const YAML::Node places = node["places"])
      parsePlaces(places, ds.places, ds.place_radius_m);
    ds.name = r.string(node, "name", "a dataset");
    ds.pipeline_file = r.resolve(r.string(node, "pipeline", "dataset " + ds.name));
    // Stage parameters replaced as planar_grid_pipeline's --set does, so that a
    // variant of a pipeline is evaluated without a copy of its file.
    std::vector<std::string> overrides;
    if (const YAML::Node set = node["set"]) {
      if (!set.IsSequence())
        r.fail(set, "dataset " + ds.name + ".set must be a list of STAGE.KEY=VALUE");
      for (const auto& item : set) {
        if (!item.IsScalar())
          r.fail(item, "dataset " + ds.name + ".set entries are STAGE.KEY=VALUE");
        overrides.push_back(item.as<std::string>());
      }
    }
    ds.pipeline = loadPipelineConfig(ds.pipeline_file, overrides);
    if (const YAML::Node frames = node["frames"]) {
      r.checkKeys(frames, {"first", "count", "step"}, "dataset " + ds.name + ".frames");
      if (frames["first"])
        ds.first_frame = count(frames["first"], 0, "frames.first");
      if (frames["count"])
        ds.frame_count = count(frames["count"], 0, "frames.count");
      if (frames["step"])
        ds.frame_step = count(frames["step"], 1, "frames.step");
    }
    const YAML::Node truth = node["truth"];
    if (!truth)
      r.fail(node, "dataset " + ds.name
                     + " needs a truth (type: points, disparity or "
                       "reference)");
    r.checkKeys(truth, {"type", "file", "leaf_size_m", "min_views", "max_range_m"},
                "dataset " + ds.name + ".truth");
    const std::string type = r.string(truth, "type", "truth");
    if (type == "points")
      ds.truth.type = TruthConfig::Type::POINTS;
    else if (type == "disparity")
      ds.truth.type = TruthConfig::Type::DISPARITY;
    else if (type == "reference")
      ds.truth.type = TruthConfig::Type::REFERENCE;
    else
      r.fail(truth["type"], "truth.type must be points, disparity or reference");
    if (ds.truth.type != TruthConfig::Type::REFERENCE)
      ds.truth.file = r.resolve(r.string(truth, "file", "truth"));
    else if (truth["file"])
      r.fail(truth["file"], "truth.file is not used by type reference");
    if (truth["leaf_size_m"])
      ds.truth.leaf_size_m =
        r.realValue(truth["leaf_size_m"], 0.005, 1.0, "truth.leaf_size_m");
    if (truth["min_views"])
      ds.truth.min_views = count(truth["min_views"], 1, "truth.min_views");
    if (truth["max_range_m"])
      ds.truth.max_range_m =
        r.realValue(truth["max_range_m"], 0.1, 1000.0, "truth.max_range_m");
    if ((truth["leaf_size_m"] || truth["min_views"] || truth["max_range_m"])
        && ds.truth.type != TruthConfig::Type::REFERENCE)
      r.fail(truth,
             "truth.leaf_size_m, truth.min_views and truth.max_range_m are for type "
             "reference");
    if (node["tilt_deg"])
      ds.tilt_deg = r.realValue(node["tilt_deg"], 0.0, 90.0, "tilt_deg");
    // The front end comes first: the split into shared and per-size stages needs it.
    bool back = false;
    for (const auto& sc : ds.pipeline.stages) {
      if (!isFrontEnd(sc.type))
        back = true;
      else if (back)
        throw ConfigError(ds.pipeline_file, sc.line, sc.column,
                          "stage '" + sc.type
                            + "' must come before the cell-size stages for the "
                              "evaluation (it runs once per frame for all sizes)");
    }
    config.datasets.push_back(std::move(ds));
  }
  return config;
}

} // namespace

ComparisonConfig
loadComparisonConfig(const std::string& path)
{
  const YAML::Node root = loadYamlDocument(readConfigFile(path), path);
  try {
    return parseComparison(root, path);
  } catch (const YAML::Exception& e) {
    throw ConfigError(path, e.mark.is_null() ? 0 : e.mark.line + 1,
                      e.mark.is_null() ? 0 : e.mark.column + 1, e.msg);
  }
}

} // namespace planar_grid
