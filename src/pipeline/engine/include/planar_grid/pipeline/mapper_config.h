// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/param_table.h>

#include <string>
#include <vector>

namespace planar_grid {

/** \brief One stage of a Mapper: a stage type of the registry (stageRegistry()) and its
 * parameters. \ingroup pipeline */
struct StageSpec {
  /** \brief Stage type, a name of the stage registry (e.g. "stereo_disparity"). */
  std::string type;
  /** \brief Parameter values by key of the stage's table (StageInfo::params), each in
   * its key's unit; a key left out takes the table's default. */
  ParamValues params;
  /** \brief 1-based line of the stage in the file it was read from, named in errors (0
   * when it comes from no file). */
  int line{0};
  /** \brief 1-based column of the stage in that file (0 when unknown). */
  int column{0};
};

/** \brief What a Mapper is built from: its stages, in run order. Nothing about where
 * frames come from: the caller hands each frame to the Mapper. The frames it takes
 * follow from the stages: stereo pairs when a stage reads stereo images (e.g.
 * stereo_disparity), point clouds (and depth images) otherwise.
 *
 * A pipeline configuration file gives one through toMapperConfig() and
 * loadMapperConfig() (pipeline_config.h), after its strict checks.
 * \ingroup pipeline */
struct MapperConfig {
  /** \brief The stages, in run order; one of them must make the map
   * (map_integration). */
  std::vector<StageSpec> stages;
  /** \brief What messages call the pipeline: the configuration file it was read from,
   * or empty. */
  std::string name;
};

} // namespace planar_grid
