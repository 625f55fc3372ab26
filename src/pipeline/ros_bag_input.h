// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/yaml_reader.h>

#include <yaml-cpp/yaml.h>

#include <memory>

namespace planar_grid {

/** \brief Parses an input map of type ros_bag (docs/INPUTS.md): the bag file, the
 * stereo topics (images and CameraInfo) or the PointCloud2 topic, frame_count and
 * input.poses (format tf, odometry for stereo, or none).
 * \throws planar_grid::ConfigError at the key's line:col, also when the build has no
 * ROS bag support */
InputConfig parseRosBagInput(const YamlReader& reader, const YAML::Node& node);

/** \brief The frames of a ROS bag input: checks, before any frame, that the bag opens,
 * that each configured topic is in it with the right message type, that the stereo
 * pairs and their CameraInfo are there, and (poses format tf) that every frame's pose
 * is found in the transforms.
 * \throws planar_grid::IOError naming the bag and the topic;
 * planar_grid::ConfigError when the build has no ROS bag support */
std::unique_ptr<FrameSource> createRosBagSource(const InputConfig& input);

} // namespace planar_grid
