// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/param_declaration.h>

namespace planar_grid {
namespace stages {

/** \brief How map_integration's explicit space layer sees a frame. \ingroup pipeline */
enum class SensorModel {
  /** The disparity image's pinhole camera for stereo, rays for point clouds. */
  AUTO,
  /** A pinhole camera: the disparity's, or a virtual one for point clouds. */
  PINHOLE,
  /** A ray from the sensor origin to every point of the working cloud. */
  RAYS
};

/** \brief The map_integration stage's own parameters beside the map's: how it sees a
 * frame, the rolling window. The memory estimate of a run reads them as the stage
 * does. \ingroup pipeline */
struct MapStageParams {
  /** \brief How the explicit space layer sees a frame (sensor_model). */
  SensorModel sensor_model{SensorModel::AUTO};
  /** \brief Width of the virtual depth camera of point clouds, pixels. */
  int depth_width_px{640};
  /** \brief Height of the virtual depth camera of point clouds, pixels. */
  int depth_height_px{480};
  /** \brief Focal length of the virtual depth camera of point clouds, pixels. */
  double depth_focal_length_px{525.0};
  /** \brief Half-size of the rolling window around the sensor, metres (0: off). */
  double window_radius_m{0.0};
};

/** \brief The declarations of MapStageParams' keys (map_integration's keys after the
 * map's). \ingroup pipeline */
const ParamDeclarations<MapStageParams>& mapStageParamDeclarations();

} // namespace stages
} // namespace planar_grid
