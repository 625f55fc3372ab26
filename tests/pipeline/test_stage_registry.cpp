// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/pipeline/param_parser.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_config_writer.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <fstream>
#include <set>
#include <sstream>
#include <string>
#include <variant>

#include "../test_constants.h"

namespace {

using planar_grid::ParamValues;

using planar_grid_test::SOURCE_DIR;

/** The text of a file, or "" when it cannot be read. */
std::string
readFile(const std::string& path)
{
  std::ifstream in(path);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

/** Whether two parameter values are the same: numbers within float precision (some
 * stages hold a value as a float), everything else exactly. */
bool
sameValue(const std::variant<double, int, bool, std::string>& a,
          const std::variant<double, int, bool, std::string>& b)
{
  if (std::holds_alternative<double>(a) && std::holds_alternative<double>(b)) {
    const double x = std::get<double>(a);
    const double y = std::get<double>(b);
    return std::abs(x - y) <= 1e-6 * std::max(1.0, std::abs(y));
  }
  return a == b;
}

} // namespace

TEST(StageRegistry, StageFromAnEmptyParamsMapHoldsTheTableDefaults)
{
  // The stage without parameters.
  const std::set<std::string> without_getters{"transform_to_world"};
  std::size_t checked = 0;
  for (const auto& info : planar_grid::stageRegistry()) {
    SCOPED_TRACE(info.type);
    const ParamValues defaults =
      planar_grid::parseParams(YAML::Load("{}"), info.params, "empty.yaml", info.type);
    const auto stage = info.create(defaults);
    ASSERT_TRUE(stage);
    ParamValues held;
    stage->getParameters(held);
    if (without_getters.count(info.type) == 0) {
      EXPECT_FALSE(held.values().empty()) << "the stage reads back no parameter";
    }
    // Every stage's echo is made from its tables: each key of its list reads back.
    EXPECT_EQ(held.values().size(), info.params.size());
    for (const auto& [key, value] : held.values()) {
      SCOPED_TRACE(key);
      const auto it = defaults.values().find(key);
      ASSERT_NE(it, defaults.values().end()) << "not a key of the stage's table";
      EXPECT_TRUE(sameValue(value, it->second))
        << "the stage holds " << held.toString(key) << ", its table's default is "
        << defaults.toString(key);
      ++checked;
    }
  }
  // The keys read back (all 169): a stage that stops reporting shows here.
  EXPECT_GE(checked, 169u);
}

TEST(StageRegistry, ExampleConfigHoldsTheGeneratedStageList)
{
  const std::string generated = planar_grid::defaultPipelineYaml();
  const std::string example = readFile(SOURCE_DIR + "/config/example.yaml");
  ASSERT_FALSE(example.empty());
  // The section runs from the generated text's first line to its last line.
  const std::string first = generated.substr(0, generated.find('\n') + 1);
  const std::string last =
    generated.substr(generated.rfind('\n', generated.size() - 2) + 1);
  const auto begin = example.find(first);
  const auto end = begin == std::string::npos ? begin : example.find(last, begin);
  const std::string hint =
    "config/example.yaml's stage list differs from the stage tables; regenerate it "
    "with `bash scripts/update_example_config.sh build/tools/planar_grid_pipeline` "
    "(it replaces the section with `planar_grid_pipeline --print-default-pipeline`)";
  ASSERT_NE(begin, std::string::npos) << hint << " (no generated section found)";
  ASSERT_NE(end, std::string::npos) << hint << " (the section's last line is missing)";
  EXPECT_EQ(example.substr(begin, end + last.size() - begin), generated) << hint;
}

TEST(StageRegistry, GeneratedPipelineLoadsWithEveryDefault)
{
  // A stereo input whose poses come from visual_odometry gives every stage what it
  // needs.
  const std::string yaml = "input:\n"
                           "  type: stereo_sequence\n"
                           "  left_images: left/%06d.png\n"
                           "  right_images: right/%06d.png\n"
                           "  calibration: {format: karlsruhe, file: calib.txt}\n"
                           "  poses: {format: odometry}\n"
                           + planar_grid::defaultPipelineYaml();
  const auto config = planar_grid::parsePipelineConfig(yaml, "generated.yaml", "/base");
  const auto& registry = planar_grid::stageRegistry();
  ASSERT_EQ(config.stages.size(), registry.size());
  for (std::size_t i = 0; i < registry.size(); ++i) {
    SCOPED_TRACE(registry[i].type);
    EXPECT_EQ(config.stages[i].type, registry[i].type);
    const ParamValues defaults = planar_grid::defaultParams(registry[i].params);
    ASSERT_EQ(config.stages[i].params.values().size(), defaults.values().size());
    for (const auto& [key, value] : defaults.values()) {
      SCOPED_TRACE(key);
      EXPECT_TRUE(sameValue(config.stages[i].params.values().at(key), value));
    }
  }
}
