// SPDX-License-Identifier: BSD-3-Clause
// The map_integration stage's own parameters beside the map's (private to the
// pipeline library): how the stage sees a frame, the rolling window.
#pragma once

#include <planar_grid/core/param_declaration.h>

namespace planar_grid {
namespace stages {

/** How the explicit space layer sees a frame. */
enum class SensorModel {
  AUTO,    // the disparity image's pinhole camera for stereo, rays for point clouds
  PINHOLE, // a pinhole camera: the disparity's, or a virtual one for point clouds
  RAYS     // a ray from the sensor origin to every point of the working cloud
};

/** The stage's own parameters beside the map's: how it sees a frame, the window. */
struct MapStageParams {
  SensorModel sensor_model{SensorModel::AUTO};
  int depth_width_px{640};
  int depth_height_px{480};
  double depth_focal_length_px{525.0};
  double window_radius_m{0.0};
};

/** The declarations of MapStageParams' keys (map_integration's keys after the map's).
 */
const ParamDeclarations<MapStageParams>& mapStageParamDeclarations();

} // namespace stages
} // namespace planar_grid
