// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>

#include <gtest/gtest.h>
#include <yaml-cpp/yaml.h>

#include <algorithm>
#include <cmath>
#include <set>
#include <string>
#include <variant>

namespace {

using planar_grid::ParamValues;

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
  // Stages whose objects expose no parameter through getters.
  const std::set<std::string> without_getters{"transform_to_world", "visual_odometry"};
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
  // The keys read back (of about 150): a stage that stops reporting shows here.
  EXPECT_GE(checked, 130u);
}
