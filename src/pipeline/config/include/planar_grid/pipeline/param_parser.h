// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/param_table.h>

#include <string>
#include <vector>

namespace YAML {
class Node;
} // namespace YAML

namespace planar_grid {

/** \brief Parses a stage's `params:` map strictly against its table: an unknown key, a
 * value of the wrong type, or an out-of-range value is a planar_grid::ConfigError at
 * the value's file:line:col, saying what was expected. Missing keys take their
 * defaults. \param[in] node the `params` map (may be null/absent: all defaults)
 * \param[in] specs the stage's table
 * \param[in] file the YAML file, for messages
 * \param[in] stage_type the stage, for messages \ingroup pipeline */
ParamValues parseParams(const YAML::Node& node,
                        const std::vector<ParamSpec>& specs,
                        const std::string& file,
                        const std::string& stage_type);

} // namespace planar_grid
