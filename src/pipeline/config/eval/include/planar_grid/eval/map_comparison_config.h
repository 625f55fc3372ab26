// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/eval/map_comparison.h>

#include <string>

namespace planar_grid {

/** \brief Reads an evaluation configuration (schema in config/eval_outdoor.yaml).
 * Strict like the pipeline's: unknown keys, wrong types and out-of-range values are
 * ConfigError at file:line:col; the pipeline files are loaded too.
 * \throws planar_grid::ConfigError, planar_grid::IOError \ingroup eval */
ComparisonConfig loadComparisonConfig(const std::string& path);

} // namespace planar_grid
