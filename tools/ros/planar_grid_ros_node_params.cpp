// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node's parameters: octomap_server's names read at start over the
// configuration's values, checked, logged, and changed through dynamic_reconfigure
// while the node runs.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/pipeline_config.h>

#include <ros/ros.h>

#include <algorithm>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <vector>

#include "planar_grid_ros_node.h"

namespace ros_node {

namespace {

/** \throws planar_grid::Exception "~name must be in RANGE unit (given: value)" when
 * \a value lies outside \a range. */
void
checkRange(const std::string& name,
           double value,
           const planar_grid::ParamRange& range,
           const std::string& unit,
           const std::string& note = "")
{
  if (!range.contains(value))
    throw planar_grid::Exception(
      "planar_grid_ros_node: " + planar_grid::paramRangeMessage("~" + name, range, unit)
      + " (given: " + planar_grid::formatParamNumber(value) + ")" + note);
}

} // namespace

NodeParams
PlanarGridNode::liveParams() const
{
  const std::lock_guard<std::mutex> lock(live_mutex_);
  return params_;
}

planar_grid::OccupancyGrid2DParams
PlanarGridNode::gridParams() const
{
  const std::lock_guard<std::mutex> lock(live_mutex_);
  return grid_params_;
}

#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
void
PlanarGridNode::startReconfigureServer()
{
  reconfigure_server_ =
    std::make_unique<dynamic_reconfigure::Server<planar_grid::PlanarGridConfig>>(
      reconfigure_mutex_, pnh_);
  planar_grid::PlanarGridConfig config;
  config.pointcloud_min_z = grid_params_.z_min_m;
  config.pointcloud_max_z = grid_params_.z_max_m;
  config.publish_every = params_.publish_every;
  config.map_2d_period = params_.map_2d_period_s;
  config.octomap_period = params_.octomap_period_s;
  config.tf_timeout = params_.tf_timeout_s;
  reconfigure_server_->updateConfig(config);
  reconfigure_server_->setCallback(
    [this](planar_grid::PlanarGridConfig& c, std::uint32_t) { onReconfigure(c); });
}

void
PlanarGridNode::onReconfigure(planar_grid::PlanarGridConfig& config)
{
  std::ostringstream changes;
  bool band_changed = false;
  {
    const std::lock_guard<std::mutex> lock(live_mutex_);
    if (!(config.pointcloud_min_z < config.pointcloud_max_z)) {
      ROS_WARN_STREAM("planar_grid_ros_node: dynamic_reconfigure: the 2D map's band "
                      "must have pointcloud_min_z ("
                      << planar_grid::formatParamNumber(config.pointcloud_min_z)
                      << " m) below pointcloud_max_z ("
                      << planar_grid::formatParamNumber(config.pointcloud_max_z)
                      << " m): the band stays "
                      << planar_grid::formatParamNumber(grid_params_.z_min_m) << " to "
                      << planar_grid::formatParamNumber(grid_params_.z_max_m) << " m");
      config.pointcloud_min_z = grid_params_.z_min_m;
      config.pointcloud_max_z = grid_params_.z_max_m;
    }
    const auto note = [&changes](const char* name, double before, double after,
                                 const char* unit) {
      if (before != after)
        changes << (changes.tellp() > 0 ? ", " : "") << name << " "
                << planar_grid::formatParamNumber(after) << unit;
    };
    note("pointcloud_min_z", grid_params_.z_min_m, config.pointcloud_min_z, " m");
    note("pointcloud_max_z", grid_params_.z_max_m, config.pointcloud_max_z, " m");
    note("publish_every", params_.publish_every, config.publish_every, "");
    note("map_2d_period", params_.map_2d_period_s, config.map_2d_period, " s");
    note("octomap_period", params_.octomap_period_s, config.octomap_period, " s");
    note("tf_timeout", params_.tf_timeout_s, config.tf_timeout, " s");
    band_changed = grid_params_.z_min_m != config.pointcloud_min_z
                   || grid_params_.z_max_m != config.pointcloud_max_z;
    grid_params_.z_min_m = config.pointcloud_min_z;
    grid_params_.z_max_m = config.pointcloud_max_z;
    params_.publish_every = config.publish_every;
    params_.map_2d_period_s = config.map_2d_period;
    params_.octomap_period_s = config.octomap_period;
    params_.tf_timeout_s = config.tf_timeout;
  }
  if (changes.tellp() > 0)
    ROS_INFO_STREAM("planar_grid_ros_node: dynamic_reconfigure: " << changes.str());
  {
    // The publisher thread takes the new periods now (it may be waiting for the end
    // of an old one) and publishes the 2D map in its new band.
    const std::lock_guard<std::mutex> lock(publish_mutex_);
    reconfigured_ = true;
    grid_refresh_ = grid_refresh_ || band_changed;
  }
  publish_cv_.notify_one();
}

#endif

bool
PlanarGridNode::hasStage(const std::string& type) const
{
  return std::any_of(config_.stages.begin(), config_.stages.end(),
                     [&type](const auto& stage) { return stage.type == type; });
}

void
PlanarGridNode::applyMapParams()
{
  double resolution_m = 0.0;
  double max_range_m = 0.0;
  const std::string number = "a number, meters";
  const bool has_resolution = readParam(pnh_, "resolution", resolution_m, number);
  const bool has_max_range =
    readParam(pnh_, "sensor_model/max_range", max_range_m, number);
  if (!has_resolution && !has_max_range)
    return;
  if (!hasStage("map_integration"))
    throw planar_grid::Exception(
      "planar_grid_ros_node: ~resolution and ~sensor_model/max_range set the "
      "map_integration stage's resolution_m and max_range_m, and the pipeline of "
      + params_.config_path + " has no map_integration stage");
  std::vector<std::string> overrides;
  if (has_resolution) {
    checkRange("resolution", resolution_m,
               planar_grid::surface_layer_ranges::RESOLUTION, "m");
    const std::string value = planar_grid::formatParamNumber(resolution_m);
    // A file with a top-level cell_size_m: every key of the cell follows it; else
    // the map's and the cells' own keys.
    if (config_.cell_size_m > 0.0)
      overrides.push_back("cell_size_m=" + value);
    else {
      overrides.push_back("map_integration.resolution_m=" + value);
      if (hasStage("planar_cuboid_approximation"))
        overrides.push_back("planar_cuboid_approximation.min_cell_size_m=" + value);
    }
    resolution_source_ = "~resolution";
  }
  if (has_max_range) {
    checkRange("sensor_model/max_range", max_range_m,
               planar_grid::explicit_space_grid_ranges::MAX_RANGE, "m",
               "; octomap_server's -1 (no limit) has no counterpart: give the depth "
               "up to which a view marks space");
    overrides.push_back("map_integration.max_range_m="
                        + planar_grid::formatParamNumber(max_range_m));
    max_range_source_ = "~sensor_model/max_range";
  }
  try {
    config_ = planar_grid::loadPipelineConfig(params_.config_path, overrides);
  } catch (const planar_grid::ConfigError& e) {
    throw planar_grid::Exception(
      "planar_grid_ros_node: ~resolution or ~sensor_model/max_range does not fit the "
      "configuration "
      + params_.config_path + ": " + e.what());
  }
}

void
PlanarGridNode::readFrameParams()
{
  std::string fixed_frame;
  std::string frame_id;
  const bool has_fixed_frame =
    readParam(pnh_, "fixed_frame", fixed_frame, "a string (a TF frame)");
  const bool has_frame_id =
    readParam(pnh_, "frame_id", frame_id, "a string (a TF frame)");
  if (has_fixed_frame && has_frame_id && fixed_frame != frame_id)
    throw planar_grid::Exception(
      "planar_grid_ros_node: ~frame_id ('" + frame_id + "') and ~fixed_frame ('"
      + fixed_frame + "') both name the map's frame and differ: set one of them");
  if (has_frame_id) {
    params_.fixed_frame = frame_id;
    frame_source_ = "~frame_id";
  } else if (has_fixed_frame) {
    params_.fixed_frame = fixed_frame;
    frame_source_ = "~fixed_frame";
  }
  if (params_.fixed_frame.empty())
    throw planar_grid::Exception("planar_grid_ros_node: the map's frame ("
                                 + frame_source_ + ") is empty");
}

void
PlanarGridNode::applyBandParams()
{
  const std::string number = "a number, meters";
  const auto& range = planar_grid::occupancy_grid_2d_ranges::Z_BAND;
  if (readParam(pnh_, "pointcloud_min_z", grid_params_.z_min_m, number)) {
    checkRange("pointcloud_min_z", grid_params_.z_min_m, range, "m");
    band_source_ = "~pointcloud_min_z";
  }
  if (readParam(pnh_, "pointcloud_max_z", grid_params_.z_max_m, number)) {
    checkRange("pointcloud_max_z", grid_params_.z_max_m, range, "m");
    band_source_ = band_source_.empty() ? "~pointcloud_max_z"
                                        : "~pointcloud_min_z, ~pointcloud_max_z";
  }
  if (!(grid_params_.z_min_m < grid_params_.z_max_m))
    throw planar_grid::Exception(
      "planar_grid_ros_node: the 2D map's band must have ~pointcloud_min_z ("
      + planar_grid::formatParamNumber(grid_params_.z_min_m)
      + " m) below ~pointcloud_max_z ("
      + planar_grid::formatParamNumber(grid_params_.z_max_m) + " m)");
}

void
PlanarGridNode::logEffectiveParams() const
{
  const auto stageValue = [this](const std::string& key) {
    for (const auto& stage : config_.stages)
      if (stage.type == "map_integration")
        return planar_grid::formatParamNumber(stage.params.getDouble(key)) + " m";
    return std::string("none (no map_integration stage)");
  };
  const std::string reference =
    grid_params_.above_terrain
      ? "above the terrain the views saw"
      : "above z = " + planar_grid::formatParamNumber(grid_params_.z_ref_m) + " m";
  ROS_INFO_STREAM(
    "planar_grid_ros_node: frame_id "
    << params_.fixed_frame << " (" << frame_source_ << "); resolution "
    << stageValue("resolution_m") << " (" << resolution_source_
    << "); sensor_model/max_range " << stageValue("max_range_m") << " ("
    << max_range_source_ << "); pointcloud_min_z "
    << planar_grid::formatParamNumber(grid_params_.z_min_m) << " m, pointcloud_max_z "
    << planar_grid::formatParamNumber(grid_params_.z_max_m) << " m, " << reference
    << " ("
    << (band_source_.empty() ? std::string("the configuration's band") : band_source_)
    << "); latch " << (params_.latch ? "true" : "false"));
}

} // namespace ros_node
