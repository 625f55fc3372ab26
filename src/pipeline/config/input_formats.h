// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <string>
#include <vector>

namespace planar_grid {

/** \brief Reads `format` of the input.poses map \a poses through
 * poseFormatFromString(), the one parser of pose format names.
 * \param[in] reader the configuration file's reader, for messages
 * \param[in] poses the input.poses map
 * \param[in] allowed the formats this kind of input reads, in the order listed in
 * messages
 * \param[in] input_kind the input in messages ("input", "ros_bag input")
 * \return the format
 * \throws planar_grid::ConfigError at the value's line:col when it names no pose
 * format or one that \a allowed does not hold, listing \a allowed */
PoseFormat readPoseFormat(const YamlReader& reader,
                          const YAML::Node& poses,
                          const std::vector<PoseFormat>& allowed,
                          const std::string& input_kind);

} // namespace planar_grid
