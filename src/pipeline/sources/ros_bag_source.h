// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/input_config.h>

#include <memory>

namespace planar_grid {

/** \brief The frames of a ROS bag input: checks, before any frame, that the bag opens,
 * that each configured topic is in it with the right message type, that the stereo
 * pairs and their CameraInfo are there, and (poses format tf) that every frame's pose
 * is found in the transforms.
 * \throws planar_grid::IOError naming the bag and the topic;
 * planar_grid::ConfigError when the build has no ROS bag support */
std::unique_ptr<FrameSource> createRosBagSource(const InputConfig& input);

} // namespace planar_grid
