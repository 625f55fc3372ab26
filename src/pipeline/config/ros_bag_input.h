// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

namespace planar_grid {

/** \brief Parses an input map of type ros_bag (docs/INPUTS.md): the bag file, the
 * stereo topics (images and CameraInfo) or the PointCloud2 topic, frame_count and
 * input.poses (format tf, odometry for stereo, or none).
 * \throws planar_grid::ConfigError at the key's line:col, also when the build has no
 * ROS bag support */
InputConfig parseRosBagInput(const YamlReader& reader, const YAML::Node& node);

} // namespace planar_grid
