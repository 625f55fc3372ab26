// SPDX-License-Identifier: BSD-3-Clause
#pragma once
// Parts of the pipeline configuration's parser shared by its source files
// (pipeline_config.cpp, pipeline_config_input.cpp, pipeline_config_output.cpp); not
// installed.
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <array>
#include <string>

namespace YAML {
class Node;
} // namespace YAML

namespace planar_grid {
namespace config_parse {

/** \brief Three finite numbers in [-1e6, 1e6] from the list \a node; fails through \a r
 * (file, line:col) otherwise. */
std::array<double, 3>
vector3(const YamlReader& r, const YAML::Node& node, const std::string& what);

/** \brief The Euclidean norm of \a v. */
double norm(const std::array<double, 3>& v);

/** \brief The `input:` map \a node: a stereo sequence, PCD files or a ROS bag, with
 * its poses and repeat; fails through \a r (file, line:col) on any error. */
InputConfig parseInput(const YamlReader& r, const YAML::Node& node);

/** \brief The `output:` map \a node, checked against the \a input it writes for. */
OutputConfig
parseOutput(const YamlReader& r, const YAML::Node& node, const InputConfig& input);

} // namespace config_parse
} // namespace planar_grid
