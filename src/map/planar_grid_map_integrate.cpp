// SPDX-License-Identifier: BSD-3-Clause
// PlanarGridMap::integrate(): one frame into both layers (Sec. III-F, Fig. 5c).
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <cmath>
#include <limits>
#include <string>

namespace planar_grid {

namespace {

/** Throws for a frame integrate() cannot take, before the map changes. */
void
checkMapFrame(const MapFrame& frame)
{
  const std::string where = "PlanarGridMap::integrate: ";
  if ((frame.depth == nullptr) == (frame.rays == nullptr))
    throw Exception(where
                    + (frame.depth == nullptr
                         ? "no space measurement: set the frame's depth image or rays"
                         : "both a depth image and rays: set exactly one"));
  if (frame.depth && !frame.depth->isConsistent()) {
    const DepthImage& depth = *frame.depth;
    throw Exception(where + "inconsistent depth image: " + std::to_string(depth.width)
                    + " x " + std::to_string(depth.height) + " pixels (both > 0) with "
                    + std::to_string(depth.depth_m.size())
                    + " depths, or intrinsics not finite with positive focal lengths");
  }
  const std::size_t features = frame.features ? frame.features->size() : 0;
  const std::size_t probabilities =
    frame.probabilities ? frame.probabilities->size() : 0;
  if (features != probabilities)
    throw Exception(where + std::to_string(features) + " feature points but "
                    + std::to_string(probabilities)
                    + " probabilities: give one probability per feature point");
  if (!frame.world_T_sensor.matrix().allFinite())
    throw Exception(where + "the sensor pose world_T_sensor is not finite");
  if (!std::isfinite(frame.observation_order))
    throw Exception(where + "the observation order must be finite");
  if (!(frame.window_half_size_m >= 0.0) || !std::isfinite(frame.window_half_size_m))
    throw Exception(where + "window_half_size_m must be finite and >= 0 (0: off)");
}

} // namespace

MapWindowRemoval
PlanarGridMap::integrate(const MapFrame& frame)
{
  checkMapFrame(frame);
  static const PlanarCuboids NO_CUBOIDS;
  static const PlaneModels NO_PLANES;
  static const pcl::PointCloud<pcl::PointXYZ> NO_FEATURES;
  static const std::vector<float> NO_PROBABILITIES;

  // The surface layer: the frame's cells, planes and feature occupancies.
  integrateSurface(frame.cuboids ? *frame.cuboids : NO_CUBOIDS,
                   frame.planes ? *frame.planes : NO_PLANES,
                   frame.features ? *frame.features : NO_FEATURES,
                   frame.probabilities ? *frame.probabilities : NO_PROBABILITIES);

  // The explicit space layer: the view's depth image through its pinhole camera, or
  // a ray from the sensor origin to every point.
  const Eigen::Vector3f sensor_origin =
    frame.world_T_sensor.translation().cast<float>();
  if (frame.depth)
    integrateDepthImage(*frame.depth, frame.world_T_sensor);
  else
    integratePointCloud(*frame.rays, sensor_origin);

  // The frame's place in its recording orders the map's views against those of
  // another map when the two are merged.
  noteObservationOrder(frame.observation_order);
  if (frame.window_half_size_m <= 0.0)
    return {};
  // The rolling window: the box of half-size window_half_size_m around the sensor in
  // x and y (world z up), every height.
  const auto half = static_cast<float>(frame.window_half_size_m);
  const float inf = std::numeric_limits<float>::infinity();
  return removeOutside(Eigen::AlignedBox3f(
    Eigen::Vector3f(sensor_origin.x() - half, sensor_origin.y() - half, -inf),
    Eigen::Vector3f(sensor_origin.x() + half, sensor_origin.y() + half, inf)));
}

} // namespace planar_grid
