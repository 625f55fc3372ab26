// SPDX-License-Identifier: BSD-3-Clause
// The map (map_integration, Sec. III-F, Fig. 5c).
#include <planar_grid/core/byte_io.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/map_stage_params.h>

#include <pcl/common/transforms.h>

#include "stages.h"

namespace planar_grid {
namespace stages {

const ParamDeclarations<MapStageParams>&
mapStageParamDeclarations()
{
  using P = MapStageParams;
  static const ParamDeclarations<P> table = {
    declareNamedChoice<P, SensorModel>(
      "sensor_model", [](auto& p) -> auto& { return p.sensor_model; },
      {{"auto", SensorModel::AUTO},
       {"pinhole", SensorModel::PINHOLE},
       {"rays", SensorModel::RAYS}},
      "How the explicit space layer sees a frame: pinhole = the disparity image's "
      "camera (stereo), the depth image's camera (Mapper::integrateDepth) or a virtual "
      "depth camera (other point clouds, the depth_* keys); rays = a ray from the "
      "sensor origin to every point of the working cloud, for any field of view (a 360 "
      "degree LiDAR scan); auto = pinhole for stereo and depth images, rays for point "
      "clouds."),
    declareInteger<P>(
      "depth_width_px", [](auto& p) -> auto& { return p.depth_width_px; },
      ParamRange::closed(1, 100000), "px",
      "sensor_model pinhole, point clouds: width of the virtual depth camera."),
    declareInteger<P>(
      "depth_height_px", [](auto& p) -> auto& { return p.depth_height_px; },
      ParamRange::closed(1, 100000), "px",
      "sensor_model pinhole, point clouds: height of the virtual depth camera."),
    declareReal<P>(
      "depth_focal_length_px", [](auto& p) -> auto& { return p.depth_focal_length_px; },
      ParamRange::closed(1.0, 100000.0), "px",
      "sensor_model pinhole, point clouds: focal length of the virtual depth camera."),
    declareReal<P>(
      "window_radius_m", [](auto& p) -> auto& { return p.window_radius_m; },
      ParamRange::closed(0.0, 1e6), "m",
      "Rolling window of a long run: after each frame the map keeps only the box of "
      "half-size window_radius_m around the sensor in x and y (world z up; every "
      "height) and frees the rest of both layers (PlanarGridMap::removeOutside). 0: "
      "off, the map grows with the run."),
  };
  return table;
}

namespace {

class MapIntegrationStage : public Stage {
public:
  MapIntegrationStage(const PlanarGridMap::Params& params,
                      const MapStageParams& stage_params) :
      params_(params),
      stage_params_(stage_params)
  {
    PlanarGridMap check(params_); // rejects bad parameters when the run is built
  }

  void start(PipelineState& state) override
  {
    state.map = std::make_shared<PlanarGridMap>(params_);
  }

  void getParameters(ParamValues& v) const override
  {
    reportParams(PlanarGridMap::getParamDeclarations(), params_, v);
    reportParams(mapStageParamDeclarations(), stage_params_, v);
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

    // The surface layer's input: the frame's cells, planes and feature occupancies.
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
    MapFrame map_frame;
    map_frame.cuboids = &frame.cuboids;
    map_frame.planes = &planes_;
    map_frame.features = &features_world_;
    map_frame.probabilities = &probabilities_;
    map_frame.world_T_sensor = frame.world_T_camera;
    map_frame.observation_order = static_cast<double>(frame.file_index);
    map_frame.window_half_size_m = stage_params_.window_radius_m;

    // The explicit space layer's input: the view's depth image through its pinhole
    // camera, or a ray from the sensor origin to every point.
    const bool rays =
      stage_params_.sensor_model == SensorModel::RAYS
      || (stage_params_.sensor_model == SensorModel::AUTO && frame.disparity.empty()
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
      map_frame.rays = &rays_cloud_;
    } else {
      if (!frame.disparity.empty())
        depthFromDisparity(frame);
      else
        depthFromCloud(frame);
      map_frame.depth = &depth_;
    }
    map.integrate(map_frame);
    // Both counts are cheap: the cells are counted, not merged into cuboids (the
    // covers are built when the cuboids are read), and the block count is O(1); the
    // map's cuboids and bytes are reported once, at the end of the run.
    cells_ = map.getSurfaceLayer().getCellCount();
    space_blocks_ = map.getSpaceLayer().getBlockCount();
  }

  bool countsCloudPoints() const override { return false; }

  void counters(const Frame& /*frame*/,
                std::vector<std::pair<std::string, double>>& values) const override
  {
    values.emplace_back("depth_pixels", static_cast<double>(depth_pixels_));
    values.emplace_back("map_cells", static_cast<double>(cells_));
    values.emplace_back("space_blocks", static_cast<double>(space_blocks_));
  }

private:
  /** Depth f B / d of every valid disparity (stereo input). */
  void depthFromDisparity(const Frame& frame)
  {
    const cv::Mat& disparity = frame.disparity;
    // In place: the frames' depth images share one buffer.
    depth_.assignFromDisparity(disparity.ptr<float>(0), disparity.cols, disparity.rows,
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
    if (camera.width_px <= 0) {
      // the virtual camera, its principal point in the centre
      const auto focal_length_px =
        static_cast<float>(stage_params_.depth_focal_length_px);
      camera = {stage_params_.depth_width_px,
                stage_params_.depth_height_px,
                focal_length_px,
                focal_length_px,
                0.5f * static_cast<float>(stage_params_.depth_width_px),
                0.5f * static_cast<float>(stage_params_.depth_height_px)};
    }
    depth_ = DepthImage::fromPointCloud(
      camera_cloud_, camera.width_px, camera.height_px,
      static_cast<float>(camera.fx_px), static_cast<float>(camera.fy_px),
      static_cast<float>(camera.cx_px), static_cast<float>(camera.cy_px));
    depth_pixels_ = depth_.countValid();
  }

  PlanarGridMap::Params params_;
  MapStageParams stage_params_;
  PlaneModels planes_;
  pcl::PointCloud<pcl::PointXYZ> features_world_;
  pcl::PointCloud<pcl::PointXYZ> camera_cloud_;
  pcl::PointCloud<pcl::PointXYZ> rays_cloud_;
  std::vector<float> probabilities_;
  DepthImage depth_;
  std::size_t depth_pixels_{0};
  std::size_t cells_{0};
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
  // The map's own parameters, then those of the stage: how it sees a frame.
  info.params = paramSpecs(PlanarGridMap::getParamDeclarations());
  const std::vector<ParamSpec> stage_specs = paramSpecs(mapStageParamDeclarations());
  info.params.insert(info.params.end(), stage_specs.begin(), stage_specs.end());
  info.create = [](const ParamValues& v) -> std::unique_ptr<Stage> {
    PlanarGridMap::Params p;
    assignParams(PlanarGridMap::getParamDeclarations(), v, p);
    MapStageParams stage_params;
    assignParams(mapStageParamDeclarations(), v, stage_params);
    return std::make_unique<MapIntegrationStage>(p, stage_params);
  };
  return info;
}
} // namespace stages
} // namespace planar_grid
