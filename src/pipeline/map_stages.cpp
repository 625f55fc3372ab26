// SPDX-License-Identifier: BSD-3-Clause
// The map (map_integration, Sec. III-F, Fig. 5c).
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/common/transforms.h>

#include <algorithm>
#include <cmath>
#include <limits>

#include "stages.h"

namespace planar_grid {
namespace stages {

namespace {

class MapIntegrationStage : public Stage {
public:
  /** How the explicit space layer sees a frame. */
  enum class SensorModel {
    AUTO,    // the disparity image's pinhole camera for stereo, rays for point clouds
    PINHOLE, // a pinhole camera: the disparity's, or a virtual one for point clouds
    RAYS     // a ray from the sensor origin to every point of the working cloud
  };

  MapIntegrationStage(const PlanarGridMap::Params& params,
                      SensorModel sensor_model,
                      int depth_width_px,
                      int depth_height_px,
                      double depth_focal_length_px,
                      double window_radius_m) :
      params_(params),
      sensor_model_(sensor_model), depth_width_px_(depth_width_px),
      depth_height_px_(depth_height_px),
      depth_focal_length_px_(static_cast<float>(depth_focal_length_px)),
      window_radius_m_(window_radius_m)
  {
    PlanarGridMap check(params_); // rejects bad parameters when the run is built
  }

  void start(PipelineState& state) override
  {
    state.map = std::make_shared<PlanarGridMap>(params_);
  }

  void getParameters(ParamValues& v) const override
  {
    const PlanarGridMap::Params& p = params_;
    v.set("resolution_m", p.resolution_m);
    v.set("max_range_m", p.space.max_range_m);
    v.set("surface_margin_m", p.space.surface_margin_m);
    v.set("prior", toString(p.space.prior));
    v.set("thickness_m", p.surface.thickness_m);
    v.set("plane_merge_angle_rad", p.surface.plane_merge_angle_rad);
    v.set("plane_merge_distance_m", p.surface.plane_merge_distance_m);
    v.set("close_gaps_cells", p.surface.close_gaps_cells);
    v.set("merge_rule", toString(p.surface.merge_rule));
    v.set("cover_density", p.surface.cover_density);
    v.set("absorb_distance_m", p.surface.absorb_distance_m);
    v.set("terrain_plane_tile_m", p.surface.terrain_plane_tile_m);
    v.set("terrain_cover_density", p.surface.terrain_cover_density);
    v.set("occupancy_thres", p.surface.occupancy_thres);
    v.set("feature_distance_m", p.surface.feature_distance_m);
    v.set("clear_non_planar", p.clear_non_planar);
    v.set("non_planar_min_occupied", p.non_planar_min_occupied);
    v.set("merge_non_planar", p.merge_non_planar);
    v.set("clear_planar", p.clear_planar);
    v.set("planes_replace_non_planar", p.planes_replace_non_planar);
    v.set("planes_absorb_overlapping", p.planes_absorb_overlapping);
    v.set("sensor_model",
          std::string(sensor_model_ == SensorModel::RAYS      ? "rays"
                      : sensor_model_ == SensorModel::PINHOLE ? "pinhole"
                                                              : "auto"));
    v.set("depth_width_px", depth_width_px_);
    v.set("depth_height_px", depth_height_px_);
    v.set("depth_focal_length_px", static_cast<double>(depth_focal_length_px_));
    v.set("window_radius_m", window_radius_m_);
  }

  void process(Frame& frame, PipelineState& state) override
  {
    if (!frame.has_pose)
      throw Exception("stage 'map_integration': frame " + frame.name + " has no pose");
    if (!frame.cloud_in_world_frame)
      throw Exception("stage 'map_integration' needs world-frame cells: put "
                      "'transform_to_world' (and the segmentation and cuboid stages) "
                      "before it");
    PlanarGridMap& map = *state.map;

    // The surface layer: the frame's cells, planes and feature occupancies.
    planes_.clear();
    for (const auto& plane : frame.planes)
      planes_.emplace_back(plane.model_coefficients.values.size() == 4
                             ? Eigen::Vector4f(plane.model_coefficients.values.data())
                             : Eigen::Vector4f::Zero());
    features_world_.clear();
    probabilities_.clear();
    if (!frame.feature_probabilities.empty()
        && frame.feature_probabilities.size() == frame.features.size()) {
      pcl::transformPointCloud(frame.features.points, features_world_,
                               frame.world_T_camera.cast<float>().matrix());
      probabilities_ = frame.feature_probabilities;
    }
    map.integrateSurface(frame.cuboids, planes_, features_world_, probabilities_);

    // The explicit space layer: the view's depth image through its pinhole camera, or
    // a ray from the sensor origin to every point.
    const bool rays = sensor_model_ == SensorModel::RAYS
                      || (sensor_model_ == SensorModel::AUTO && frame.disparity.empty()
                          && frame.depth_camera.width_px <= 0);
    if (rays) {
      // Every measured point: the ground and the points of no cell too.
      const Frame::Cloud& measured =
        frame.measured_cloud ? *frame.measured_cloud : *frame.cloud;
      rays_cloud_.clear();
      rays_cloud_.reserve(measured.size());
      for (const auto& p : measured.points)
        rays_cloud_.push_back(pcl::PointXYZ(p.x, p.y, p.z));
      depth_pixels_ = rays_cloud_.size();
      map.integratePointCloud(rays_cloud_,
                              frame.world_T_camera.translation().cast<float>());
    } else {
      if (!frame.disparity.empty())
        depthFromDisparity(frame);
      else
        depthFromCloud(frame);
      map.integrateDepthImage(depth_, frame.world_T_camera);
    }
    // The frame's place in its recording orders the map's views against those of
    // another segment's map when the two are merged.
    map.noteObservationOrder(frame.file_index);
    if (window_radius_m_ > 0.0) {
      // The rolling window: the map keeps the box of half-size window_radius_m around
      // the sensor in x and y (world z up), every height.
      const Eigen::Vector3f sensor = frame.world_T_camera.translation().cast<float>();
      const auto half = static_cast<float>(window_radius_m_);
      const float inf = std::numeric_limits<float>::infinity();
      map.removeOutside(Eigen::AlignedBox3f(
        Eigen::Vector3f(sensor.x() - half, sensor.y() - half, -inf),
        Eigen::Vector3f(sensor.x() + half, sensor.y() + half, inf)));
    }
    cuboids_ = map.getSurfaceLayer().getCuboidCount();
    // The block count is O(1); the map's bytes (a walk over every block) are
    // reported once, at the end of the run.
    space_blocks_ = map.getSpaceLayer().getBlockCount();
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("depth_pixels", static_cast<double>(depth_pixels_));
    values.emplace_back("map_cuboids", static_cast<double>(cuboids_));
    values.emplace_back("space_blocks", static_cast<double>(space_blocks_));
  }

private:
  /** Depth f B / d of every valid disparity (stereo input). */
  void depthFromDisparity(const Frame& frame)
  {
    const cv::Mat& disparity = frame.disparity;
    depth_ =
      DepthImage::fromDisparity(disparity.ptr<float>(0), disparity.cols, disparity.rows,
                                disparity.step, frame.calibration);
    depth_pixels_ = depth_.countValid();
  }

  /** Point-cloud input: the world cloud back in the sensor frame, rendered by the
   * depth camera it came from (depth-image input) or else by a virtual pinhole camera.
   */
  void depthFromCloud(const Frame& frame)
  {
    camera_cloud_.clear();
    const Eigen::Matrix4f camera_T_world =
      frame.world_T_camera.inverse().cast<float>().matrix();
    camera_cloud_.reserve(frame.cloud->size());
    for (const auto& p : frame.cloud->points) {
      pcl::PointXYZ q;
      q.getVector4fMap() = camera_T_world * Eigen::Vector4f(p.x, p.y, p.z, 1.0f);
      camera_cloud_.push_back(q);
    }
    PinholeView camera = frame.depth_camera;
    if (camera.width_px <= 0) // the virtual camera, its principal point in the centre
      camera = {depth_width_px_,
                depth_height_px_,
                depth_focal_length_px_,
                depth_focal_length_px_,
                0.5f * static_cast<float>(depth_width_px_),
                0.5f * static_cast<float>(depth_height_px_)};
    depth_ = DepthImage::fromPointCloud(
      camera_cloud_, camera.width_px, camera.height_px,
      static_cast<float>(camera.fx_px), static_cast<float>(camera.fy_px),
      static_cast<float>(camera.cx_px), static_cast<float>(camera.cy_px));
    depth_pixels_ = depth_.countValid();
  }

  PlanarGridMap::Params params_;
  SensorModel sensor_model_;
  int depth_width_px_;
  int depth_height_px_;
  float depth_focal_length_px_;
  double window_radius_m_;
  PlaneModels planes_;
  pcl::PointCloud<pcl::PointXYZ> features_world_;
  pcl::PointCloud<pcl::PointXYZ> camera_cloud_;
  pcl::PointCloud<pcl::PointXYZ> rays_cloud_;
  std::vector<float> probabilities_;
  DepthImage depth_;
  std::size_t depth_pixels_{0};
  std::size_t cuboids_{0};
  std::size_t space_blocks_{0};
};

} // namespace

StageInfo
mapIntegrationInfo()
{
  StageInfo info;
  info.type = "map_integration";
  info.description =
    "planar_grid::PlanarGridMap (paper Sec. III-F, Fig. 5c): merges each frame's "
    "world-frame cuboids into the map's planes (the occupancy of a cell is the mean "
    "probability of the features in it), and marks the voxels of the camera frustum "
    "free, occupied or unknown (occluded) from the depth image. Needs "
    "transform_to_world before it; the output section writes the map file.";
  info.needs_poses = true;
  const PlanarGridMap::Params d;
  namespace space = explicit_space_grid_ranges;
  namespace surface = surface_layer_ranges;
  info.params = {
    ParamSpec::real("resolution_m", d.resolution_m, surface::RESOLUTION, "m",
                    "Minimum cell size of both layers (the paper's 0.1 m).")
      .scalesWithCellSize(),
    ParamSpec::real("max_range_m", d.space.max_range_m, space::MAX_RANGE, "m",
                    "Depth up to which a view marks space."),
    ParamSpec::real("surface_margin_m", d.space.surface_margin_m, space::SURFACE_MARGIN,
                    "m",
                    "Half-thickness of the measured surface; 0: half a voxel "
                    "diagonal."),
    ParamSpec::choice("prior", toString(d.space.prior), {"unknown", "free"},
                      "State of space never inside a view (the paper: free)."),
    ParamSpec::real("thickness_m", d.surface.thickness_m, surface::THICKNESS, "m",
                    "Extrusion of the map's planar cuboids behind their face.")
      .scalesWithCellSize(),
    ParamSpec::real("plane_merge_angle_rad", d.surface.plane_merge_angle_rad,
                    surface::PLANE_MERGE_ANGLE, "rad",
                    "Largest normal angle between one plane's views."),
    ParamSpec::real("plane_merge_distance_m", d.surface.plane_merge_distance_m,
                    surface::PLANE_MERGE_DISTANCE, "m",
                    "Largest RMS distance of a view's faces (and of the plane's "
                    "evidence) to the least-squares plane of both."),
    ParamSpec::integer("close_gaps_cells", d.surface.close_gaps_cells,
                       surface::CLOSE_GAPS, "cells",
                       "Gaps of up to this many cells between observed cells of a "
                       "plane's row or column are filled before the merge; 0: none."),
    ParamSpec::choice("merge_rule", toString(d.surface.merge_rule),
                      {"paper", "min_rectangles", "density"},
                      "Cover of a plane's cells: the paper's runs stacked by equal "
                      "extent (Fig. 6b), the fewest exact rectangles, or rectangles "
                      "grown while at least cover_density of their cells are the "
                      "plane's (the paper's D_T applied to the merge)."),
    ParamSpec::real("cover_density", d.surface.cover_density, surface::COVER_DENSITY,
                    "share",
                    "merge_rule density: smallest share of a rectangle's cells "
                    "observed on the plane."),
    ParamSpec::real("occupancy_thres", d.surface.occupancy_thres,
                    surface::OCCUPANCY_THRES, "probability",
                    "Cells at or above it are occupied."),
    ParamSpec::real("feature_distance_m", d.surface.feature_distance_m,
                    surface::FEATURE_DISTANCE, "m",
                    "A feature counts for a plane cell within this distance."),
    ParamSpec::flag("clear_non_planar", d.clear_non_planar,
                    "Remove the non-planar cells a later view sees through (more "
                    "than half of their voxels observed free), as OctoMap's misses "
                    "clear a voxel hit before."),
    ParamSpec::real("non_planar_min_occupied", d.non_planar_min_occupied,
                    planar_grid_map_ranges::NON_PLANAR_MIN_OCCUPIED, "share",
                    "clear_non_planar: also remove a non-planar cell in a view when "
                    "the space layer holds fewer than this share of its voxels "
                    "occupied (free, or behind the surface from every view); 0: only "
                    "the free rule."),
    ParamSpec::flag("merge_non_planar", d.merge_non_planar,
                    "After each depth image, merge two touching non-planar cells in "
                    "the view into their bounding box when the space layer holds at "
                    "least non_planar_min_occupied of its voxels occupied and at most "
                    "half free (off when that share is 0)."),
    ParamSpec::flag("clear_planar", d.clear_planar,
                    "Remove the planes' raster cells a later view sees through (the "
                    "voxel of the cell and the one behind it observed free): a car "
                    "that drove away, a door that opened."),
    ParamSpec::flag("planes_replace_non_planar", d.planes_replace_non_planar,
                    "Remove the non-planar cells lying on a map plane (centre and "
                    "footprint within half a cell of its planar cuboids): the plane "
                    "represents that surface."),
    ParamSpec::flag("planes_absorb_overlapping", d.planes_absorb_overlapping,
                    "Move a map plane's rectangles lying on a plane with more "
                    "evidence (every cell's face within half a cell of its planar "
                    "cuboids, or within absorb_distance_m along the normal of a "
                    "parallel one) to that plane: a surface found as planes a few "
                    "degrees or decimetres apart is covered once."),
    ParamSpec::real("absorb_distance_m", d.surface.absorb_distance_m,
                    surface::ABSORB_DISTANCE, "m",
                    "planes_absorb_overlapping: largest distance along a stronger "
                    "parallel plane's normal at which a plane's cells are that "
                    "surface seen at another depth (about twice eq. 4's depth "
                    "error bound)."),
    ParamSpec::real("terrain_plane_tile_m", d.surface.terrain_plane_tile_m,
                    surface::TERRAIN_PLANE_TILE, "m",
                    "Side of the square tiles of the world's x, y plane that bound a "
                    "level map plane (normal within 0.3 rad of z): > 0, a level plane "
                    "joins and merges only with level planes of its tile and no two "
                    "level planes absorb each other's cells, so the terrain stays "
                    "planar per tile. Left out, it takes ground_removal's "
                    "terrain_plane_tile_m. 0: level planes are unbounded."),
    ParamSpec::real("terrain_cover_density", d.surface.terrain_cover_density,
                    surface::TERRAIN_COVER_DENSITY, "",
                    "With terrain_plane_tile_m > 0 and merge_rule density, the "
                    "cover_density of the level planes: a road or a floor, seen "
                    "sparsely, leaves many unobserved cells in its tiles that a loose "
                    "cover spans and marks occupied (1: observed cells only)."),
    ParamSpec::choice("sensor_model", "auto", {"auto", "pinhole", "rays"},
                      "How the explicit space layer sees a frame: pinhole = the "
                      "disparity image's camera (stereo), the depth image's camera "
                      "(Mapper::integrateDepth) or a virtual depth camera (other point "
                      "clouds, the depth_* keys); rays = a ray from the sensor origin "
                      "to every point of the working cloud, for any field of view (a "
                      "360 degree LiDAR scan); auto = pinhole for stereo and depth "
                      "images, rays for point clouds."),
    ParamSpec::integer("depth_width_px", 640, 1, 100000, "px",
                       "sensor_model pinhole, point clouds: width of the virtual depth "
                       "camera."),
    ParamSpec::integer(
      "depth_height_px", 480, 1, 100000, "px",
      "sensor_model pinhole, point clouds: height of the virtual depth "
      "camera."),
    ParamSpec::real("depth_focal_length_px", 525.0, 1.0, 100000.0, "px",
                    "sensor_model pinhole, point clouds: focal length of the virtual "
                    "depth camera."),
    ParamSpec::real("window_radius_m", 0.0, 0.0, 1e6, "m",
                    "Rolling window of a long run: after each frame the map keeps "
                    "only the box of half-size window_radius_m around the sensor in "
                    "x and y (world z up; every height) and frees the rest of both "
                    "layers (PlanarGridMap::removeOutside). 0: off, the map grows "
                    "with the run."),
  };
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    PlanarGridMap::Params p;
    p.resolution_m = v.getDouble("resolution_m");
    p.space.max_range_m = v.getDouble("max_range_m");
    p.space.surface_margin_m = v.getDouble("surface_margin_m");
    p.space.prior = spaceStateFromString(v.getChoice("prior"));
    p.surface.thickness_m = v.getDouble("thickness_m");
    p.surface.plane_merge_angle_rad = v.getDouble("plane_merge_angle_rad");
    p.surface.plane_merge_distance_m = v.getDouble("plane_merge_distance_m");
    p.surface.occupancy_thres = v.getDouble("occupancy_thres");
    p.surface.feature_distance_m = v.getDouble("feature_distance_m");
    p.surface.close_gaps_cells = v.getInt("close_gaps_cells");
    p.surface.merge_rule = surfaceMergeRuleFromString(v.getChoice("merge_rule"));
    p.surface.cover_density = v.getDouble("cover_density");
    p.surface.absorb_distance_m = v.getDouble("absorb_distance_m");
    p.surface.terrain_plane_tile_m = v.getDouble("terrain_plane_tile_m");
    p.surface.terrain_cover_density = v.getDouble("terrain_cover_density");
    p.clear_non_planar = v.getBool("clear_non_planar");
    p.non_planar_min_occupied = v.getDouble("non_planar_min_occupied");
    p.merge_non_planar = v.getBool("merge_non_planar");
    p.clear_planar = v.getBool("clear_planar");
    p.planes_replace_non_planar = v.getBool("planes_replace_non_planar");
    p.planes_absorb_overlapping = v.getBool("planes_absorb_overlapping");
    const std::string model = v.getChoice("sensor_model");
    const auto sensor_model = model == "rays" ? MapIntegrationStage::SensorModel::RAYS
                              : model == "pinhole"
                                ? MapIntegrationStage::SensorModel::PINHOLE
                                : MapIntegrationStage::SensorModel::AUTO;
    return std::make_unique<MapIntegrationStage>(
      p, sensor_model, v.getInt("depth_width_px"), v.getInt("depth_height_px"),
      v.getDouble("depth_focal_length_px"), v.getDouble("window_radius_m"));
  };
  return info;
}
} // namespace stages
} // namespace planar_grid
