// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_pipeline's snapshots (built with the viewer): the world cloud, the
// planes, the cuboids (also along the street) and the map, rendered after the run.

#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/output_transaction.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/street_camera.h>

#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <functional>
#include <numeric>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

#include "cli.h"
#include "planar_grid_pipeline.h"

using namespace pcl::console;

namespace pipeline_tool {

namespace {

/** The street camera of output.street_view: fixed, or following \a trajectory. Nothing,
 * with a warning, when it follows the trajectory and there is no pose. \a description
 * says where it is, for the snapshots' labels. */
std::optional<planar_grid::CameraParameters>
streetViewCamera(const planar_grid::StreetViewConfig& view,
                 const planar_grid::Trajectory& trajectory,
                 std::string& description)
{
  const Eigen::Vector3d up(view.up[0], view.up[1], view.up[2]);
  std::ostringstream text;
  text.precision(3);
  if (view.fixed) {
    planar_grid::CameraParameters camera;
    camera.position = Eigen::Vector3d(view.position_m.data());
    camera.focal_point = Eigen::Vector3d(view.focal_point_m.data());
    camera.view_up = up;
    camera.view_angle_deg = view.view_angle_deg;
    text << "fixed camera at (" << camera.position.transpose() << ") m";
    description = text.str();
    return camera;
  }
  if (trajectory.empty()) {
    print_warn("No camera pose for the street view (no frame had a pose): the street "
               "snapshots are skipped.\n");
    return std::nullopt;
  }
  planar_grid::StreetCameraParameters parameters;
  parameters.pose_fraction = view.pose_fraction;
  parameters.pitch_rad = view.pitch_rad;
  parameters.look_ahead_m = view.look_ahead_m;
  parameters.view_angle_deg = view.view_angle_deg;
  parameters.world_up = up;
  const std::size_t index =
    planar_grid::streetCameraPoseIndex(trajectory.size(), view.pose_fraction);
  text << "street view from behind pose " << index << " of " << trajectory.size()
       << ", " << view.pitch_rad * 180.0 / M_PI << " deg down, " << view.look_ahead_m
       << " m ahead";
  description = text.str();
  return planar_grid::streetCamera(trajectory, parameters);
}

} // namespace

/** Renders the configured snapshots: the world cloud by height with the trajectory, the
 * planes one colour each over the world cloud in grey, the cuboids by plane (also seen
 * along the street) and the map by occupancy. */
void
saveSnapshots(const planar_grid::PipelineConfig& config,
              const std::string& config_path,
              const planar_grid::PipelineRunner& runner,
              planar_grid::RunReport& report,
              planar_grid::OutputTransaction& outputs)
{
  const auto& state = runner.state();
  const auto preset = config.output.snapshot_camera == "oblique"
                        ? planar_grid::CameraPreset::OBLIQUE
                        : planar_grid::CameraPreset::TOP;
  // The cells: the map's merged cuboids when a map was built (built here), else every
  // frame's (used in place).
  planar_grid::PlanarCuboids map_cuboids;
  if (state.map)
    map_cuboids = state.map->getSurfaceLayer().getCuboids();
  const planar_grid::PlanarCuboids& cuboids = state.map ? map_cuboids : state.cuboids;
  std::optional<planar_grid::CameraParameters> street;
  std::string street_description;
  if (config.output.snapshot_camera == "street"
      || (!config.output.cuboids_street_snapshot.empty() && !cuboids.empty())) {
    street = streetViewCamera(config.output.street_view, runner.trajectory(),
                              street_description);
    if (street) {
      print_info("Street camera: ");
      printValue(street_description);
      print_info(": position (%.2f, %.2f, %.2f) m, focal point (%.2f, %.2f, %.2f) m\n",
                 street->position.x(), street->position.y(), street->position.z(),
                 street->focal_point.x(), street->focal_point.y(),
                 street->focal_point.z());
    } else if (config.output.snapshot_camera == "street") {
      print_warn("snapshot_camera street without a pose: the snapshots use top.\n");
    }
  }
  const bool all_street = config.output.snapshot_camera == "street" && street;
  std::vector<Eigen::Vector3d> positions;
  for (const auto& pose : runner.trajectory())
    positions.push_back(pose.translation());
  const Eigen::Vector3d grey(0.8, 0.8, 0.8), dark(0.1, 0.1, 0.1);
  // One snapshot: white background, the content, the trajectory, a label, the preset
  // camera or, when \a along_street, the street camera; \a add_content draws the
  // content and returns the label.
  const auto render =
    [&](const std::string& name, const std::string& kind, bool along_street,
        const std::function<std::string(planar_grid::SceneRenderer&)>& add_content) {
      if (name.empty())
        return;
      {
        planar_grid::SceneRenderer renderer;
        renderer.setBackground(Eigen::Vector3d(1.0, 1.0, 1.0));
        const std::string label = add_content(renderer);
        if (positions.size() > 1)
          renderer.addTrajectory(positions);
        renderer.addText(config_path + ": " + label, dark);
        if (along_street) {
          renderer.addText(street_description, dark);
          renderer.setCamera(*street);
        } else {
          renderer.setCamera(preset);
        }
        report.outputs.emplace_back(
          kind, outputs.write(name, [&](const std::string& path) {
            renderer.saveSnapshot(path, config.output.snapshot_size_px[0],
                                  config.output.snapshot_size_px[1]);
          }));
      }
      // VTK's buffers of this snapshot go back to the kernel before the next one.
      planar_grid::cli::releaseFreedMemory();
    };
  const std::string frames_and_points = std::to_string(report.frames) + " frames, "
                                        + std::to_string(report.world_cloud_points)
                                        + " points";

  render(config.output.snapshot, "snapshot", all_street,
         [&](planar_grid::SceneRenderer& r) {
           if (!state.world_cloud->empty())
             r.addPointCloud(*state.world_cloud, planar_grid::ColorMode::HEIGHT, 2.0);
           return frames_and_points;
         });

  const planar_grid::PlaneRegistry& planes = *state.planes;
  if (!planes.getInlierCloud().empty())
    render(
      config.output.planes_snapshot, "planes_snapshot", all_street,
      [&](planar_grid::SceneRenderer& r) {
        if (!state.world_cloud->empty())
          r.addPointCloud(*state.world_cloud, planar_grid::ColorMode::SOLID, 1.0, grey);
        // Colour the largest run-wide planes (by inliers merged over the run), one
        // colour each; smaller ones (car sides, bushes) stay grey so the facades
        // stand out.
        constexpr std::size_t COLOURED_PLANES = 24;
        std::vector<std::size_t> order(planes.size());
        std::iota(order.begin(), order.end(), 0);
        std::sort(order.begin(), order.end(), [&planes](std::size_t a, std::size_t b) {
          return planes.getInlierCounts()[a] > planes.getInlierCounts()[b];
        });
        std::vector<int> colour_of(order.size(), -1);
        for (std::size_t k = 0; k < std::min(order.size(), COLOURED_PLANES); ++k)
          colour_of[order[k]] = static_cast<int>(k);
        pcl::PointCloud<pcl::PointXYZI> labelled;
        labelled.reserve(planes.getInlierCloud().size());
        for (const auto& p : planes.getInlierCloud().points) {
          if (p.label >= colour_of.size() || colour_of[p.label] < 0)
            continue;
          pcl::PointXYZI q;
          q.getVector3fMap() = p.getVector3fMap();
          q.intensity = static_cast<float>(colour_of[p.label]);
          labelled.push_back(q);
        }
        r.addPointCloud(labelled, planar_grid::ColorMode::LABEL, 2.0);
        return frames_and_points + ", " + std::to_string(planes.size())
               + " planes (the 24 largest coloured)";
      });

  const auto add_cuboids = [&](planar_grid::SceneRenderer& r) {
    r.addCuboids(cuboids);
    std::size_t planar = 0;
    for (const auto& c : cuboids)
      planar += c.is_planar;
    return std::to_string(cuboids.size()) + (state.map ? " map" : "") + " cuboids ("
           + std::to_string(planar) + " planar, coloured by plane; non-planar grey)";
  };
  if (!cuboids.empty()) {
    render(config.output.cuboids_snapshot, "cuboids_snapshot", all_street, add_cuboids);
    if (street)
      render(config.output.cuboids_street_snapshot, "cuboids_street_snapshot", true,
             add_cuboids);
  }

  if (state.map)
    render(config.output.map_snapshot, "map_snapshot", all_street,
           [&](planar_grid::SceneRenderer& r) {
             const auto drawn = r.addMap(*state.map);
             return std::to_string(drawn.cuboids)
                    + " cuboids coloured by occupancy (blue 0, green 0.5, red 1), "
                    + std::to_string(drawn.occupied_voxel_boxes)
                    + " other occupied voxels grey, "
                    + (drawn.unknown_boxes > 0
                         ? std::string("occluded (unknown) space violet")
                         : std::string("space never measured free or occupied is "
                                       "unknown (prior), not drawn"));
           });
}

} // namespace pipeline_tool
