// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node: live mapping in ROS 1 (docs/ROS.md). Subscribes to a rectified
// stereo pair with its CameraInfos, or to a PointCloud2; takes each frame's pose from
// TF (or from the pipeline's visual odometry, published on TF and as
// nav_msgs/Odometry); maps the frame with
// planar_grid::Mapper on a worker thread; publishes the map after each frame, also as
// octomap_msgs/Octomap. Takes octomap_server's parameter names where they mean the
// same; the ones that can change while it runs also through dynamic_reconfigure.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/param_range.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/version.h>
#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
#include <planar_grid/PlanarGridConfig.h>
#endif

#include <geometry_msgs/TransformStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <nlohmann/json.hpp>
#include <octomap/OcTree.h>
#include <octomap_msgs/Octomap.h>
#include <ros/ros.h>
#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
#include <dynamic_reconfigure/server.h>
#endif
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <array>
#include <atomic>
#include <cerrno>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

#include "ros_messages.h"

namespace {

using Clock = std::chrono::steady_clock;

/** One frame as it arrived: the messages and the wall time of their arrival. */
struct PendingFrame {
  sensor_msgs::ImageConstPtr left, right;
  sensor_msgs::CameraInfoConstPtr left_info, right_info;
  sensor_msgs::PointCloud2ConstPtr cloud;
  Clock::time_point arrival;
  std::uint64_t sequence{0};
};

/** The node's parameters (private namespace); each defaults from the configuration.
 * tf_timeout_s, publish_every, map_2d_period_s and octomap_period_s change while the
 * node runs (dynamic_reconfigure); the others are fixed at start. */
struct NodeParams {
  std::string config_path;
  /** The world frame of the map and of the published topics. */
  std::string fixed_frame{"world"};
  /** The camera's (sensor's) frame; empty: the messages' header frame_id. */
  std::string sensor_frame;
  /** Frames kept waiting while one is mapped; when full, the oldest is dropped.
   * 0: no limit (every frame is mapped; latency grows when they come faster). */
  int max_queued_frames{1};
  /** Longest wait for the frame's transform, seconds. */
  double tf_timeout_s{0.5};
  /** Publish the map every this many mapped frames (1: after each). */
  int publish_every{1};
  /** Shortest time between two 2D maps, seconds (0: after every frame). */
  double map_2d_period_s{2.0};
  /** Shortest time between two OctoMaps (~octomap_binary, ~octomap_full), seconds
   * (0: after every frame). */
  double octomap_period_s{2.0};
  /** Folder of ~save_map's files. */
  std::string output_folder{"."};
  /** Publish the map topics latched (octomap_server's ~latch): a subscriber that comes
   * later gets the last message at once. */
  bool latch{true};
};

/** Reads the private parameter \a name into \a value when it is set.
 * \param[in] expected what the parameter must hold, for the error ("a number, meters")
 * \return whether it is set
 * \throws planar_grid::Exception naming the parameter when it holds another type */
template <typename T>
bool
readParam(const ros::NodeHandle& pnh,
          const std::string& name,
          T& value,
          const std::string& expected)
{
  if (!pnh.hasParam(name))
    return false;
  if (!pnh.getParam(name, value))
    throw planar_grid::Exception("planar_grid_ros_node: ~" + name + " must be "
                                 + expected);
  return true;
}

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

/** A colour per plane (golden-ratio hues), grey for non-planar cells. */
std_msgs::ColorRGBA
planeColour(int plane_id)
{
  std_msgs::ColorRGBA c;
  c.a = 1.0f;
  if (plane_id < 0) {
    c.r = c.g = c.b = 0.6f;
    return c;
  }
  const double h = std::fmod(0.618033988749895 * plane_id, 1.0) * 6.0;
  const double x = 1.0 - std::abs(std::fmod(h, 2.0) - 1.0);
  const int sector = static_cast<int>(h);
  const double rgb[6][3] = {{1, x, 0}, {x, 1, 0}, {0, 1, x},
                            {0, x, 1}, {x, 0, 1}, {1, 0, x}};
  // Lighter than full saturation, so that the edges of neighbouring cells show.
  c.r = static_cast<float>(0.25 + 0.75 * rgb[sector][0]);
  c.g = static_cast<float>(0.25 + 0.75 * rgb[sector][1]);
  c.b = static_cast<float>(0.25 + 0.75 * rgb[sector][2]);
  return c;
}

class PlanarGridNode {
public:
  PlanarGridNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) : nh_(nh), pnh_(pnh)
  {
    if (!pnh_.getParam("config", params_.config_path))
      throw planar_grid::Exception(
        "planar_grid_ros_node: the private parameter ~config (the pipeline's YAML "
        "file) is not set");
    config_ = planar_grid::loadPipelineConfig(params_.config_path);
    applyMapParams();
    const auto& bag = config_.input.ros_bag;
    if (!bag.parent_frame.empty()) {
      params_.fixed_frame = bag.parent_frame;
      frame_source_ = "the configuration's poses.parent_frame";
    }
    if (!bag.child_frame.empty())
      params_.sensor_frame = bag.child_frame;
    readFrameParams();
    pnh_.param("sensor_frame", params_.sensor_frame, params_.sensor_frame);
    pnh_.param("max_queued_frames", params_.max_queued_frames,
               params_.max_queued_frames);
    pnh_.param("tf_timeout", params_.tf_timeout_s, params_.tf_timeout_s);
    pnh_.param("publish_every", params_.publish_every, params_.publish_every);
    pnh_.param("map_2d_period", params_.map_2d_period_s, params_.map_2d_period_s);
    pnh_.param("octomap_period", params_.octomap_period_s, params_.octomap_period_s);
    pnh_.param("output_folder", params_.output_folder, params_.output_folder);
    readParam(pnh_, "latch", params_.latch, "true or false");
    if (params_.max_queued_frames < 0 || params_.publish_every < 1
        || !(params_.tf_timeout_s >= 0.0) || !(params_.map_2d_period_s >= 0.0)
        || !(params_.octomap_period_s >= 0.0))
      throw planar_grid::Exception(
        "planar_grid_ros_node: ~max_queued_frames must be >= 0, ~publish_every >= 1 "
        "and ~tf_timeout, ~map_2d_period, ~octomap_period >= 0");
    mapper_ = std::make_unique<planar_grid::Mapper>(config_);
    for (const auto& stage : config_.stages)
      odometry_ = odometry_ || stage.type == "visual_odometry";
    grid_params_ = config_.output.map_grid_2d_band;
    if (config_.output.map_grid_2d.empty()) {
      // No band configured: obstacles 0.3 to 2.0 m above the terrain the views saw.
      grid_params_.above_terrain = true;
      grid_params_.z_min_m = 0.3;
      grid_params_.z_max_m = 2.0;
    }
    applyBandParams();
    logEffectiveParams();
    if (odometry_)
      ROS_INFO_STREAM("planar_grid_ros_node: each frame's pose from the pipeline's "
                      "visual_odometry stage, published on /tf ("
                      << params_.fixed_frame << " -> "
                      << (params_.sensor_frame.empty()
                            ? std::string("the images' frame")
                            : params_.sensor_frame)
                      << ") and on " << pnh_.resolveName("odometry"));

    markers_pub_ =
      pnh_.advertise<visualization_msgs::MarkerArray>("cuboids", 1, params_.latch);
    occupied_pub_ =
      pnh_.advertise<sensor_msgs::PointCloud2>("occupied_cells", 1, params_.latch);
    grid_pub_ = pnh_.advertise<nav_msgs::OccupancyGrid>("map_2d", 1, params_.latch);
    octomap_binary_pub_ =
      pnh_.advertise<octomap_msgs::Octomap>("octomap_binary", 1, params_.latch);
    octomap_full_pub_ =
      pnh_.advertise<octomap_msgs::Octomap>("octomap_full", 1, params_.latch);
    stats_pub_ = pnh_.advertise<std_msgs::String>("frame_stats", 100);
    if (odometry_)
      odometry_pub_ = pnh_.advertise<nav_msgs::Odometry>("odometry", 100);
    save_srv_ = pnh_.advertiseService("save_map", &PlanarGridNode::onSave, this);
    reset_srv_ = pnh_.advertiseService("reset", &PlanarGridNode::onReset, this);
    tf_listener_ = std::make_unique<tf2_ros::TransformListener>(tf_buffer_, nh_);

    const std::string topic = [&bag](const std::string& name, const char* fallback) {
      return name.empty() ? std::string(fallback) : name;
    }(bag.cloud_topic, "cloud");
    if (config_.input.type == planar_grid::InputConfig::Type::PCD_FILES) {
      cloud_sub_ = nh_.subscribe(topic, 5, &PlanarGridNode::onCloud, this);
      ROS_INFO_STREAM("planar_grid_ros_node: mapping " << nh_.resolveName(topic));
    } else {
      const auto name = [](const std::string& configured, const char* fallback) {
        return configured.empty() ? std::string(fallback) : configured;
      };
      // Keeping every frame (~max_queued_frames 0) holds every message until it is
      // paired: roscpp's queues without a bound (0) and a deep pairing queue; else
      // the transport may drop messages while the worker has the CPU.
      const bool keep_all = params_.max_queued_frames == 0;
      const std::uint32_t queue = keep_all ? 0 : 5;
      left_sub_.subscribe(nh_, name(bag.left_image_topic, "left/image_rect"), queue);
      right_sub_.subscribe(nh_, name(bag.right_image_topic, "right/image_rect"), queue);
      left_info_sub_.subscribe(nh_, name(bag.left_info_topic, "left/camera_info"),
                               queue);
      right_info_sub_.subscribe(nh_, name(bag.right_info_topic, "right/camera_info"),
                                queue);
      sync_ = std::make_unique<Sync>(SyncPolicy(keep_all ? 1000 : 10), left_sub_,
                                     right_sub_, left_info_sub_, right_info_sub_);
      sync_->registerCallback(&PlanarGridNode::onStereo, this);
      // Left images that never became a pair are counted (frame_stats "unpaired").
      left_sub_.registerCallback(
        [this](const sensor_msgs::ImageConstPtr&) { ++left_images_; });
      ROS_INFO_STREAM("planar_grid_ros_node: mapping the pair "
                      << left_sub_.getTopic() << " / " << right_sub_.getTopic());
    }
#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
    startReconfigureServer();
    ROS_INFO_STREAM("planar_grid_ros_node: dynamic_reconfigure on "
                    << pnh_.getNamespace()
                    << ": pointcloud_min_z, pointcloud_max_z, publish_every, "
                       "map_2d_period, octomap_period, tf_timeout");
#endif
    worker_ = std::thread([this] { work(); });
    publisher_ = std::thread([this] { publishSpace(); });
  }

  ~PlanarGridNode()
  {
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      stopping_ = true;
    }
    queue_cv_.notify_all();
    if (worker_.joinable())
      worker_.join();
    {
      std::lock_guard<std::mutex> lock(publish_mutex_);
      stopping_publisher_ = true;
    }
    publish_cv_.notify_all();
    if (publisher_.joinable())
      publisher_.join();
    ROS_INFO_STREAM("planar_grid_ros_node: " << mapped_ << " frames mapped, "
                                             << dropped_ << " dropped, " << failed_
                                             << " failed");
  }

private:
  using SyncPolicy =
    message_filters::sync_policies::ApproximateTime<sensor_msgs::Image,
                                                    sensor_msgs::Image,
                                                    sensor_msgs::CameraInfo,
                                                    sensor_msgs::CameraInfo>;
  using Sync = message_filters::Synchronizer<SyncPolicy>;

  /** The parameters, with the values dynamic_reconfigure last set, read under their
   * lock. */
  NodeParams liveParams() const
  {
    const std::lock_guard<std::mutex> lock(live_mutex_);
    return params_;
  }

  /** The 2D map's band (~pointcloud_min_z, ~pointcloud_max_z as last set), read under
   * its lock. */
  planar_grid::OccupancyGrid2DParams gridParams() const
  {
    const std::lock_guard<std::mutex> lock(live_mutex_);
    return grid_params_;
  }

#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
  /** The dynamic_reconfigure server on the node's private namespace, holding the
   * values the node runs with (its start parameters and the configuration's), so that
   * rqt_reconfigure and `dynparam get` show them. */
  void startReconfigureServer()
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

  /** A dynamic_reconfigure request: takes the new values (the server has clamped
   * each to its range) for the next frame and the next publication, logs what
   * changed, and asks for the 2D map again when its band changed. A band upside down
   * (min not below max) is refused: the band keeps its values, which the server then
   * reports back. */
  void onReconfigure(planar_grid::PlanarGridConfig& config)
  {
    std::ostringstream changes;
    bool band_changed = false;
    {
      const std::lock_guard<std::mutex> lock(live_mutex_);
      if (!(config.pointcloud_min_z < config.pointcloud_max_z)) {
        ROS_WARN_STREAM(
          "planar_grid_ros_node: dynamic_reconfigure: the 2D map's band "
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

  /** Whether the pipeline has a stage of \a type. */
  bool hasStage(const std::string& type) const
  {
    return std::any_of(config_.stages.begin(), config_.stages.end(),
                       [&type](const auto& stage) { return stage.type == type; });
  }

  /** ~resolution and ~sensor_model/max_range (octomap_server's names): the map's voxel
   * edge and the depth up to which a view marks space, meters. They replace the
   * configuration's map_integration resolution_m and max_range_m (the resolution also
   * planar_cuboid_approximation's min_cell_size_m, which the map's raster shares), and
   * the configuration is validated again with them, as the pipeline tool's --set does.
   * \throws planar_grid::Exception naming the parameter for a value out of range, a
   * pipeline without map_integration, or a configuration they do not fit */
  void applyMapParams()
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
      overrides.push_back("map_integration.resolution_m=" + value);
      if (hasStage("planar_cuboid_approximation"))
        overrides.push_back("planar_cuboid_approximation.min_cell_size_m=" + value);
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

  /** ~frame_id (octomap_server's name) or ~fixed_frame: the map's frame; either
   * replaces the configuration's poses.parent_frame. Both set must agree.
   * \throws planar_grid::Exception for two different frames or an empty one */
  void readFrameParams()
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

  /** ~pointcloud_min_z and ~pointcloud_max_z (octomap_server's names): the ends of the
   * 2D map's height band, meters above its reference (the terrain the views saw, or
   * z_ref_m: output.map_grid_2d_band); they replace the configuration's z_min_m and
   * z_max_m.
   * \throws planar_grid::Exception for an end out of range or min >= max */
  void applyBandParams()
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

  /** Prints the values the node runs with, under octomap_server's names, and where
   * each comes from. */
  void logEffectiveParams() const
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

  void onStereo(const sensor_msgs::ImageConstPtr& left,
                const sensor_msgs::ImageConstPtr& right,
                const sensor_msgs::CameraInfoConstPtr& left_info,
                const sensor_msgs::CameraInfoConstPtr& right_info)
  {
    PendingFrame frame;
    frame.left = left;
    frame.right = right;
    frame.left_info = left_info;
    frame.right_info = right_info;
    enqueue(std::move(frame));
  }

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud)
  {
    PendingFrame frame;
    frame.cloud = cloud;
    enqueue(std::move(frame));
  }

  /** Queues a frame for the worker and returns at once (callbacks never block on
   * mapping); drops the oldest waiting frame when the queue is full. */
  void enqueue(PendingFrame&& frame)
  {
    frame.arrival = Clock::now();
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      frame.sequence = received_++;
      queue_.push_back(std::move(frame));
      if (params_.max_queued_frames > 0
          && queue_.size() > static_cast<std::size_t>(params_.max_queued_frames)) {
        queue_.pop_front();
        ++dropped_;
      }
    }
    queue_cv_.notify_one();
  }

  void work()
  {
    for (;;) {
      PendingFrame frame;
      {
        std::unique_lock<std::mutex> lock(queue_mutex_);
        queue_cv_.wait(
          lock, [this] { return stopping_ || reset_requested_ || !queue_.empty(); });
        if (stopping_)
          return;
        if (reset_requested_) {
          queue_.clear();
          lock.unlock();
          mapper_->reset();
          has_previous_pose_ = false;
          lock.lock();
          reset_requested_ = false;
          reset_cv_.notify_all();
          continue;
        }
        frame = std::move(queue_.front());
        queue_.pop_front();
      }
      try {
        mapFrame(frame);
      } catch (const std::exception& e) {
        ++failed_;
        ROS_ERROR_STREAM("planar_grid_ros_node: frame " << frame.sequence << ": "
                                                        << e.what());
      }
    }
  }

  /** The frame's world_T_sensor from TF at the message's stamp. */
  Eigen::Isometry3d lookUpPose(const std_msgs::Header& header)
  {
    const std::string& sensor =
      params_.sensor_frame.empty() ? header.frame_id : params_.sensor_frame;
    // Waits for the transform in short slices, so that a shutdown (SIGINT) ends the
    // wait however long ~tf_timeout is.
    const auto deadline =
      Clock::now()
      + std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(std::min(liveParams().tf_timeout_s, 1e9)));
    const ros::Duration slice(0.05);
    while (!tf_buffer_.canTransform(params_.fixed_frame, sensor, header.stamp, slice)) {
      if (stopRequested())
        throw planar_grid::Exception("the node stops: no longer waiting for TF '"
                                     + params_.fixed_frame + "' -> '" + sensor + "'");
      if (Clock::now() >= deadline)
        break; // lookupTransform() below throws with tf2's reason
    }
    const geometry_msgs::TransformStamped t =
      tf_buffer_.lookupTransform(params_.fixed_frame, sensor, header.stamp);
    return planar_grid::ros_messages::isometryFromTransform(
      t.transform, "TF '" + params_.fixed_frame + "' -> '" + sensor + "'");
  }

  /** Whether the node is shutting down (its destructor, or ROS after SIGINT). */
  bool stopRequested()
  {
    if (!ros::ok())
      return true;
    const std::lock_guard<std::mutex> lock(queue_mutex_);
    return stopping_;
  }

  void mapFrame(const PendingFrame& frame)
  {
    const std_msgs::Header& header =
      frame.cloud ? frame.cloud->header : frame.left->header;
    planar_grid::FrameStats stats;
    if (frame.cloud) {
      planar_grid::Frame::Cloud cloud;
      planar_grid::ros_messages::cloudFromMessage(*frame.cloud, "cloud", cloud);
      stats = mapper_->integrateCloud(cloud, lookUpPose(header));
    } else {
      const cv::Mat left =
        planar_grid::ros_messages::greyImage(*frame.left, "left image");
      const cv::Mat right =
        planar_grid::ros_messages::greyImage(*frame.right, "right image");
      const planar_grid::StereoCalibration calibration =
        planar_grid::ros_messages::calibrationFromCameraInfo(
          *frame.left_info, *frame.right_info, "right CameraInfo");
      if (odometry_) {
        stats = mapper_->integrateStereo(left, right, calibration);
        publishPose(header, stats.world_T_camera);
      } else
        stats = mapper_->integrateStereo(left, right, calibration, lookUpPose(header));
    }
    ++mapped_;
    const bool keyframe = isKeyframe(stats);
    if (keyframe)
      ++keyframes_;
    const Clock::time_point publish_start = Clock::now();
    if (mapped_ % static_cast<std::uint64_t>(liveParams().publish_every) == 0)
      publishMap(header.stamp);
    publishStats(
      frame, stats, keyframe,
      std::chrono::duration<double, std::milli>(Clock::now() - publish_start).count());
  }

  /** The pose the visual odometry estimated for the frame, \a world_T_camera (meters,
   * the map's z-up frame): on /tf as fixed_frame -> sensor frame and on ~odometry as
   * nav_msgs/Odometry (header.frame_id the map's frame, child_frame_id the sensor
   * frame), both stamped with the left image's stamp. The Odometry's twist is the
   * motion from the previous mapped frame to this one divided by the time between
   * their stamps, in the sensor frame (m/s, rad/s; zero for the first frame after a
   * start or a reset); its covariances are not estimated and stay zero. */
  void publishPose(const std_msgs::Header& header,
                   const Eigen::Isometry3d& world_T_camera)
  {
    const geometry_msgs::TransformStamped transform =
      planar_grid::ros_messages::transformStamped(
        world_T_camera, params_.fixed_frame,
        params_.sensor_frame.empty() ? header.frame_id : params_.sensor_frame,
        header.stamp);
    tf_broadcaster_.sendTransform(transform);
    nav_msgs::Odometry odometry;
    odometry.header = transform.header;
    odometry.child_frame_id = transform.child_frame_id;
    odometry.pose.pose.position.x = transform.transform.translation.x;
    odometry.pose.pose.position.y = transform.transform.translation.y;
    odometry.pose.pose.position.z = transform.transform.translation.z;
    odometry.pose.pose.orientation = transform.transform.rotation;
    if (has_previous_pose_ && header.stamp > previous_stamp_) {
      const double dt_s = (header.stamp - previous_stamp_).toSec();
      const Eigen::Vector3d linear =
        world_T_camera.linear().transpose()
        * (world_T_camera.translation() - previous_pose_.translation()) / dt_s;
      // The axis of the rotation between the two frames is the same vector in either
      // camera's coordinates, so the rotation vector is the angular velocity in the
      // current one.
      const Eigen::AngleAxisd rotation(previous_pose_.linear().transpose()
                                       * world_T_camera.linear());
      const Eigen::Vector3d angular = rotation.axis() * (rotation.angle() / dt_s);
      odometry.twist.twist.linear.x = linear.x();
      odometry.twist.twist.linear.y = linear.y();
      odometry.twist.twist.linear.z = linear.z();
      odometry.twist.twist.angular.x = angular.x();
      odometry.twist.twist.angular.y = angular.y();
      odometry.twist.twist.angular.z = angular.z();
    }
    odometry_pub_.publish(odometry);
    previous_pose_ = world_T_camera;
    previous_stamp_ = header.stamp;
    has_previous_pose_ = true;
  }

  /** The map's cuboids, occupied voxels and 2D obstacle map, each only when its topic
   * has subscribers (the latched message goes to later ones). Runs on the integrating
   * thread, between frames. */
  void publishMap(const ros::Time& stamp)
  {
    const Clock::time_point start = Clock::now();
    if (markers_pub_.getNumSubscribers() > 0)
      publishCuboids(*mapper_->getMap(), stamp);
    cuboids_ms_ =
      std::chrono::duration<double, std::milli>(Clock::now() - start).count();
    {
      std::lock_guard<std::mutex> lock(publish_mutex_);
      map_stamp_ = stamp;
      ++map_version_;
    }
    publish_cv_.notify_one();
  }

  /** A map product published at most once per period: the map version it last
   * took (published, or passed over without subscribers) and when. */
  struct Throttled {
    Clock::duration period;
    std::uint64_t version{0};
    Clock::time_point last{};

    /** Whether \a map_version waits for this product. */
    bool pending(std::uint64_t map_version) const { return version != map_version; }
    /** When the product may be published again. */
    Clock::time_point due() const { return last + period; }
    /** Whether \a map_version is to be taken now: pending and the period over. */
    bool ready(std::uint64_t map_version, Clock::time_point now) const
    {
      return pending(map_version) && now >= due();
    }
  };

  /** The publisher thread: the occupied cells after each frame (frames that come
   * faster are coalesced); the 2D map and the OctoMaps at most once per
   * ~map_2d_period and ~octomap_period, and after the last frame of a burst. The
   * occupied cells and the 2D map are read from the map under one shared lock
   * (Mapper::readMap()), each OctoMap under its own, while the worker maps the next
   * frame. */
  void publishSpace()
  {
    const auto seconds = [](double s) {
      return std::chrono::duration_cast<Clock::duration>(
        std::chrono::duration<double>(s));
    };
    std::uint64_t published = 0;
    Throttled grid{seconds(liveParams().map_2d_period_s)};
    Throttled octomap{seconds(liveParams().octomap_period_s)};
    for (;;) {
      std::uint64_t version = 0;
      ros::Time stamp;
      {
        std::unique_lock<std::mutex> lock(publish_mutex_);
        const auto ready = [&] {
          return stopping_publisher_ || map_version_ != published || reconfigured_;
        };
        // A 2D map or OctoMap held back by its period is published when it ends.
        const bool grid_pending = grid.pending(map_version_);
        const bool octomap_pending = octomap.pending(map_version_);
        if (grid_pending || octomap_pending)
          publish_cv_.wait_until(lock,
                                 grid_pending && octomap_pending
                                   ? std::min(grid.due(), octomap.due())
                                   : (grid_pending ? grid.due() : octomap.due()),
                                 ready);
        else
          publish_cv_.wait(lock, ready);
        if (stopping_publisher_)
          return;
        if (reconfigured_) {
          // The periods as dynamic_reconfigure set them count from now on, also for
          // a map version that waits; a new 2D band makes the map's 2D map again.
          reconfigured_ = false;
          const NodeParams live = liveParams();
          grid.period = seconds(live.map_2d_period_s);
          octomap.period = seconds(live.octomap_period_s);
          if (grid_refresh_) {
            grid_refresh_ = false;
            grid.version = 0;
            grid.last = Clock::time_point{};
          }
        }
        version = map_version_;
        stamp = map_stamp_;
      }
      const Clock::time_point now = Clock::now();
      const bool grid_now = grid.ready(version, now);
      const bool octomap_now = octomap.ready(version, now);
      const bool cells = version != published && occupied_pub_.getNumSubscribers() > 0;
      const bool grid_published = grid_now && grid_pub_.getNumSubscribers() > 0;
      const bool octomap_published = octomap_now
                                     && (octomap_binary_pub_.getNumSubscribers() > 0
                                         || octomap_full_pub_.getNumSubscribers() > 0);
      const auto timed = [](std::atomic<double>& ms, const auto& publish) {
        const Clock::time_point start = Clock::now();
        publish();
        ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
      };
      if (cells || grid_published) {
        const auto map = mapper_->readMap();
        if (cells)
          timed(occupied_ms_, [&] { publishOccupiedCells(*map, stamp); });
        if (grid_published)
          timed(map_2d_ms_, [&] { publishGrid(*map, stamp); });
      }
      if (octomap_published)
        timed(octomap_ms_, [&] { publishOctoMaps(stamp); });
      published = version;
      for (auto [taken, product] :
           {std::pair{grid_now, &grid}, {octomap_now, &octomap}})
        if (taken) {
          product->version = version;
          product->last = Clock::now();
        }
    }
  }

  /** One CUBE marker per cuboid: namespace planar (coloured by plane) or non_planar
   * (grey), after a DELETEALL that removes the previous frame's. */
  void publishCuboids(const planar_grid::PlanarGridMap& map, const ros::Time& stamp)
  {
    visualization_msgs::MarkerArray markers;
    visualization_msgs::Marker clear;
    clear.header.frame_id = params_.fixed_frame;
    clear.header.stamp = stamp;
    clear.action = visualization_msgs::Marker::DELETEALL;
    markers.markers.push_back(clear);
    const planar_grid::PlanarCuboids cuboids = map.getSurfaceLayer().getCuboids();
    markers.markers.reserve(cuboids.size() + 1);
    int id = 0;
    for (const auto& c : cuboids) {
      visualization_msgs::Marker m;
      m.header = clear.header;
      m.ns = c.is_planar ? "planar" : "non_planar";
      m.id = id++;
      m.type = visualization_msgs::Marker::CUBE;
      m.action = visualization_msgs::Marker::ADD;
      Eigen::Matrix3f axes;
      axes.col(0) = c.horizontal_axis;
      axes.col(1) = c.verticalAxis();
      axes.col(2) = c.normal;
      const Eigen::Quaternionf q(axes);
      m.pose.orientation.w = q.w();
      m.pose.orientation.x = q.x();
      m.pose.orientation.y = q.y();
      m.pose.orientation.z = q.z();
      m.pose.position.x = c.centre.x();
      m.pose.position.y = c.centre.y();
      m.pose.position.z = c.centre.z();
      // RViz draws no zero-size box: the thinnest side gets 1 mm.
      m.scale.x = std::max(1e-3f, c.width_m);
      m.scale.y = std::max(1e-3f, c.height_m);
      m.scale.z = std::max(1e-3f, c.thickness_m);
      m.color = planeColour(c.is_planar ? c.plane_id : -1);
      markers.markers.push_back(m);
    }
    markers_pub_.publish(markers);
  }

  /** The centres of the space layer's occupied voxels (x, y, z float32, meters). */
  void publishOccupiedCells(const planar_grid::PlanarGridMap& map,
                            const ros::Time& stamp)
  {
    const auto& space = map.getSpaceLayer();
    sensor_msgs::PointCloud2 occupied;
    occupied.header.frame_id = params_.fixed_frame;
    occupied.header.stamp = stamp;
    occupied.height = 1;
    for (const char* name : {"x", "y", "z"}) {
      sensor_msgs::PointField f;
      f.name = name;
      f.offset = static_cast<std::uint32_t>(4 * occupied.fields.size());
      f.datatype = sensor_msgs::PointField::FLOAT32;
      f.count = 1;
      occupied.fields.push_back(f);
    }
    occupied.point_step = 12;
    occupied.is_dense = true;
    occupied.data.reserve(12 * space.getVoxelCount(planar_grid::SpaceState::OCCUPIED));
    space.forEachVoxelIn(planar_grid::SpaceState::OCCUPIED,
                         [&](const planar_grid::ExplicitSpaceGrid::VoxelKey& key) {
                           const Eigen::Vector3f p = space.toCentre(key);
                           const auto* bytes =
                             reinterpret_cast<const std::uint8_t*>(p.data());
                           occupied.data.insert(occupied.data.end(), bytes, bytes + 12);
                         });
    occupied.width = static_cast<std::uint32_t>(occupied.data.size() / 12);
    occupied.row_step = static_cast<std::uint32_t>(occupied.data.size());
    occupied_pub_.publish(occupied);
  }

  /** The obstacles of the configured height band
   * (PlanarGridMap::computeOccupancyGrid2D): 0 free, 100 occupied, -1 unknown. */
  void publishGrid(const planar_grid::PlanarGridMap& map, const ros::Time& stamp)
  {
    const planar_grid::OccupancyGrid2DParams band = gridParams();
    const planar_grid::OccupancyGrid2D grid = map.computeOccupancyGrid2D(band);
    nav_msgs::OccupancyGrid msg;
    msg.header.frame_id = params_.fixed_frame;
    msg.header.stamp = stamp;
    msg.info.map_load_time = stamp;
    msg.info.resolution = static_cast<float>(grid.resolution_m);
    msg.info.width = static_cast<std::uint32_t>(grid.width);
    msg.info.height = static_cast<std::uint32_t>(grid.height);
    msg.info.origin.position.x = grid.origin.x();
    msg.info.origin.position.y = grid.origin.y();
    msg.info.origin.position.z = band.above_terrain ? 0.0 : band.z_ref_m;
    msg.info.origin.orientation.w = 1.0;
    msg.data = grid.cells;
    grid_pub_.publish(msg);
  }

  /** ~octomap_binary and ~octomap_full, each when it has subscribers. A failed
   * export is logged and the next map version tries again. */
  void publishOctoMaps(const ros::Time& stamp)
  {
    for (const bool binary : {true, false}) {
      ros::Publisher& publisher = binary ? octomap_binary_pub_ : octomap_full_pub_;
      if (publisher.getNumSubscribers() == 0)
        continue;
      try {
        publisher.publish(octomapMessage(stamp, binary));
      } catch (const std::exception& e) {
        ROS_ERROR_STREAM("planar_grid_ros_node: " << publisher.getTopic() << ": "
                                                  << e.what());
      }
    }
  }

  /** The map as octomap_msgs/Octomap: the tree PlanarGridMap::exportOctoMap() writes
   * to map.bt (binary: each node's maximum-likelihood state) or map.ot (full: each
   * node's log-odds, the cuboids' probabilities), built in memory under the map's
   * shared lock (PlanarGridMap::toOcTree) and serialized as octomap_msgs'
   * conversions.h does (binaryMapToMsg: OcTree::writeBinaryData; fullMapToMsg:
   * OcTree::writeData), with id "OcTree", the tree's resolution in meters, and the
   * map's frame and the last mapped frame's stamp in the header. */
  octomap_msgs::Octomap octomapMessage(const ros::Time& stamp, bool binary) const
  {
    octomap::OcTree tree(0.1);
    {
      const auto map = mapper_->readMap();
      map->toOcTree(tree, binary);
    }
    octomap_msgs::Octomap msg;
    msg.header.frame_id = params_.fixed_frame;
    msg.header.stamp = stamp;
    msg.binary = binary;
    msg.id = tree.getTreeType();
    msg.resolution = tree.getResolution();
    std::stringstream data;
    if (binary)
      tree.writeBinaryData(data);
    else
      tree.writeData(data);
    const std::string bytes = data.str();
    msg.data.assign(bytes.begin(), bytes.end());
    return msg;
  }

  /** Whether the frame was dense: stereo_disparity gave it a disparity (every frame
   * without that stage, or with every frame dense). */
  static bool isKeyframe(const planar_grid::FrameStats& stats)
  {
    for (const auto& stage : stats.stages)
      if (stage.type == "stereo_disparity") {
        for (const auto& [name, value] : stage.counters)
          if (name == "dense_frames")
            return value > 0.0;
        return true;
      }
    return true;
  }

  void publishStats(const PendingFrame& frame,
                    const planar_grid::FrameStats& stats,
                    bool keyframe,
                    double publish_ms)
  {
    const double latency_ms =
      std::chrono::duration<double, std::milli>(Clock::now() - frame.arrival).count();
    std::size_t queued = 0;
    std::uint64_t dropped = 0;
    std::uint64_t pairs = 0;
    {
      std::lock_guard<std::mutex> lock(queue_mutex_);
      queued = queue_.size();
      dropped = dropped_;
      pairs = received_;
    }
    nlohmann::json j;
    j["received"] = frame.sequence;
    // Left images that no pair took (yet): lost before a frame was formed (a right
    // image or a CameraInfo missing or too late for the pairing), or still waiting for
    // their partners.
    const std::uint64_t left_images = left_images_.load();
    j["unpaired"] =
      cloud_sub_ ? std::uint64_t{0} : left_images - std::min(left_images, pairs);
    j["mapped"] = mapped_.load();
    j["keyframe"] = keyframe;
    j["keyframes"] = keyframes_.load();
    j["dropped"] = dropped;
    j["failed"] = failed_.load();
    j["queued"] = queued;
    j["latency_ms"] = latency_ms;
    j["total_ms"] = stats.total_ms;
    j["publish_ms"] = publish_ms;
    j["cuboids_ms"] = cuboids_ms_;
    j["last_occupied_cells_ms"] = occupied_ms_.load();
    j["last_map_2d_ms"] = map_2d_ms_.load();
    j["last_octomap_ms"] = octomap_ms_.load();
    j["exclusive_ms"] = stats.exclusive_ms;
    j["planes"] = stats.planes;
    j["cuboids"] = stats.cuboids;
    j["map_cuboids"] = stats.map_cuboids;
    if (odometry_)
      for (const auto& stage : stats.stages)
        if (stage.type == "visual_odometry")
          for (const auto& [name, value] : stage.counters) {
            // The frame's motion from its inliers, or the constant-velocity prediction
            // when there were too few (flagged).
            if (name == "inliers")
              j["odometry_inliers"] = static_cast<std::int64_t>(value);
            else if (name == "flagged")
              j["odometry_flagged"] = value > 0.0;
          }
    std_msgs::String msg;
    msg.data = j.dump();
    stats_pub_.publish(msg);
  }

  /** ~save_map: map.pgmap, map.bt and map_cuboids.ply in ~output_folder (read at the
   * call), each written atomically, under the map's shared lock. */
  bool onSave(std_srvs::Trigger::Request& /*request*/,
              std_srvs::Trigger::Response& response)
  {
    std::string folder = params_.output_folder;
    pnh_.getParam("output_folder", folder);
    try {
      namespace fs = std::filesystem;
      fs::create_directories(folder);
      const fs::path dir(folder);
      mapper_->save((dir / "map.pgmap").string());
      planar_grid::OctoMapExportSummary octomap;
      {
        const auto map = mapper_->readMap();
        octomap = map->exportOctoMap((dir / "map.bt").string());
        map->exportMesh((dir / "map_cuboids.ply").string());
      }
      response.success = true;
      response.message = "wrote map.pgmap, map.bt and map_cuboids.ply in " + folder
                         + " (" + std::to_string(mapped_)
                         + " frames); map.bt: " + std::to_string(octomap.nodes)
                         + " nodes, " + std::to_string(octomap.leaf_nodes) + " leaves, "
                         + std::to_string(octomap.occupied_leaves) + " occupied, "
                         + std::to_string(octomap.free_leaves) + " free";
    } catch (const std::exception& e) {
      response.success = false;
      response.message = e.what();
    }
    return true;
  }

  /** ~reset: empties the map between two frames (the worker does it) and drops the
   * frames waiting. */
  bool onReset(std_srvs::Trigger::Request& /*request*/,
               std_srvs::Trigger::Response& response)
  {
    std::unique_lock<std::mutex> lock(queue_mutex_);
    reset_requested_ = true;
    queue_cv_.notify_one();
    reset_cv_.wait(lock, [this] { return !reset_requested_ || stopping_; });
    mapped_ = 0;
    keyframes_ = 0;
    response.success = true;
    response.message = "the map is empty";
    return true;
  }

  ros::NodeHandle& nh_;
  ros::NodeHandle& pnh_;
  NodeParams params_;
  planar_grid::PipelineConfig config_;
  /** The 2D map's band; with params_' live values, guarded by live_mutex_ once the
   * node runs. */
  planar_grid::OccupancyGrid2DParams grid_params_;
  mutable std::mutex live_mutex_;
#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
  boost::recursive_mutex reconfigure_mutex_;
  std::unique_ptr<dynamic_reconfigure::Server<planar_grid::PlanarGridConfig>>
    reconfigure_server_;
#endif
  std::unique_ptr<planar_grid::Mapper> mapper_;
  bool odometry_{false};
  /** Where the map's frame, resolution, maximum range and 2D band come from, as the
   * start-up line prints them ("" for the band: the configuration). */
  std::string frame_source_{"default"};
  std::string resolution_source_{"the configuration"};
  std::string max_range_source_{"the configuration"};
  std::string band_source_;
  /** Wall time of the last frame's markers, ms. */
  double cuboids_ms_{0.0};

  /** Transforms of the last minute: with frames queued, a frame may be mapped long
   * after its pose arrived. */
  tf2_ros::Buffer tf_buffer_{ros::Duration(60.0)};
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  ros::Publisher markers_pub_, occupied_pub_, grid_pub_, stats_pub_;
  ros::Publisher octomap_binary_pub_, octomap_full_pub_;
  /** ~odometry: the visual odometry's pose per frame (with a visual_odometry stage). */
  ros::Publisher odometry_pub_;
  /** The last pose published on ~odometry and its stamp (the worker's own). */
  Eigen::Isometry3d previous_pose_{Eigen::Isometry3d::Identity()};
  ros::Time previous_stamp_;
  bool has_previous_pose_{false};
  ros::ServiceServer save_srv_, reset_srv_;
  ros::Subscriber cloud_sub_;
  message_filters::Subscriber<sensor_msgs::Image> left_sub_, right_sub_;
  message_filters::Subscriber<sensor_msgs::CameraInfo> left_info_sub_, right_info_sub_;
  std::unique_ptr<Sync> sync_;

  std::mutex queue_mutex_;
  std::condition_variable queue_cv_, reset_cv_;
  std::deque<PendingFrame> queue_;
  bool stopping_{false};
  bool reset_requested_{false};
  std::uint64_t received_{0};
  /** Left images received (stereo input), paired or not. */
  std::atomic<std::uint64_t> left_images_{0};
  std::uint64_t dropped_{0};
  std::atomic<std::uint64_t> mapped_{0};
  std::atomic<std::uint64_t> keyframes_{0};
  std::atomic<std::uint64_t> failed_{0};
  std::thread worker_;

  std::mutex publish_mutex_;
  std::condition_variable publish_cv_;
  /** Frames mapped (the worker counts), and the stamp of the last one. */
  std::uint64_t map_version_{0};
  ros::Time map_stamp_;
  bool stopping_publisher_{false};
  /** dynamic_reconfigure changed the parameters; the 2D band among them: publish the
   * current map's 2D map again. */
  bool reconfigured_{false};
  bool grid_refresh_{false};
  /** Wall time of the publisher's last occupied cells, 2D map and OctoMaps, ms. */
  std::atomic<double> occupied_ms_{0.0}, map_2d_ms_{0.0}, octomap_ms_{0.0};
  std::thread publisher_;
};

/** What --help prints: how to start the node, its private parameters, topics and
 * services (docs/ROS.md has the whole description). */
constexpr const char* USAGE =
  "Usage: planar_grid_ros_node _config:=/abs/FILE.yaml [_NAME:=VALUE]...\n"
  "       ROS_PACKAGE_PATH=PREFIX/share roslaunch planar_grid planar_grid.launch \\\n"
  "         config:=/abs/FILE.yaml\n"
  "\n"
  "Live mapping in ROS 1: maps each rectified stereo pair (or PointCloud2) with the\n"
  "pipeline of FILE.yaml, its pose from TF or from the pipeline's visual odometry, "
  "and\n"
  "publishes the map after each frame. A stereo camera alone:\n"
  "       ROS_PACKAGE_PATH=PREFIX/share roslaunch planar_grid "
  "planar_grid_stereo.launch\n"
  "\n"
  "Private parameters:\n"
  "  ~config             the pipeline's YAML file (required)\n"
  "  ~frame_id           world frame of the map and of the published topics\n"
  "                      (default: the configuration's, else world); also\n"
  "                      ~fixed_frame\n"
  "  ~sensor_frame       the camera's frame (default: the messages' frame_id)\n"
  "  ~max_queued_frames  frames kept waiting while one is mapped; 0: no limit (1)\n"
  "  ~tf_timeout         longest wait for a frame's transform, s (0.5)\n"
  "  ~publish_every      publish the map every N mapped frames (1)\n"
  "  ~map_2d_period      shortest time between two 2D maps, s (2.0)\n"
  "  ~octomap_period     shortest time between two OctoMaps, s (2.0)\n"
  "  ~output_folder      folder of ~save_map's files (.)\n"
  "  ~resolution         the map's voxel edge, m (the configuration's)\n"
  "  ~sensor_model/max_range\n"
  "                      depth up to which a view marks space, m (the\n"
  "                      configuration's)\n"
  "  ~pointcloud_min_z, ~pointcloud_max_z\n"
  "                      the 2D map's height band above its reference, m\n"
  "                      (the configuration's, else 0.3, 2.0 above the terrain)\n"
  "  ~latch              publish the map topics latched (true)\n"
  "  dynamic_reconfigure changes ~pointcloud_min_z, ~pointcloud_max_z,\n"
  "  ~publish_every, ~map_2d_period, ~octomap_period and ~tf_timeout while it runs\n"
  "  (when built with it).\n"
  "\n"
  "Subscribes: left/image_rect, right/image_rect, left/camera_info,\n"
  "  right/camera_info, or cloud (PointCloud2) for a pcd_files configuration\n"
  "  (or the configuration's ros_bag topics).\n"
  "Publishes: ~cuboids (MarkerArray), ~occupied_cells (PointCloud2), ~map_2d\n"
  "  (OccupancyGrid), ~octomap_binary, ~octomap_full (octomap_msgs/Octomap),\n"
  "  ~frame_stats (String, JSON per frame); with a visual_odometry stage the pose\n"
  "  it estimated on /tf (frame_id -> the images' frame) and ~odometry\n"
  "  (nav_msgs/Odometry), stamped with the image's stamp.\n"
  "Services: ~save_map, ~reset (std_srvs/Trigger).\n"
  "\n"
  "Options:\n"
  "  -h, --help     print this text and exit\n"
  "      --version  print the version and exit\n";

} // namespace

int
main(int argc, char** argv)
{
  // Answered before ros::init, which would wait for a ROS master.
  for (int i = 1; i < argc; ++i) {
    if (std::strcmp(argv[i], "--version") == 0) {
      std::printf("planar_grid_ros_node %s\n", PLANAR_GRID_VERSION_STRING);
      return 0;
    }
    if (std::strcmp(argv[i], "--help") == 0 || std::strcmp(argv[i], "-h") == 0) {
      std::fputs(USAGE, stdout);
      return 0;
    }
  }
  ros::init(argc, argv, "planar_grid");
  ros::NodeHandle nh;
  ros::NodeHandle pnh("~");
  try {
    PlanarGridNode node(nh, pnh);
    // Two threads: a service call (save, reset) never holds up the subscriptions.
    ros::AsyncSpinner spinner(2);
    spinner.start();
    ros::waitForShutdown();
  } catch (const std::exception& e) {
    ROS_FATAL_STREAM(e.what());
    return 1;
  }
  return 0;
}
