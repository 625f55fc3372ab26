// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node: live mapping in ROS 1 (docs/ROS.md). Subscribes to a rectified
// stereo pair with its CameraInfos, or to a PointCloud2; takes each frame's pose from
// TF (or from the pipeline's visual odometry, broadcast on TF); maps the frame with
// planar_grid::Mapper on a worker thread; publishes the map after each frame.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/version.h>

#include <geometry_msgs/TransformStamped.h>
#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nlohmann/json.hpp>
#include <ros/ros.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <std_srvs/Trigger.h>
#include <tf2_ros/buffer.h>
#include <tf2_ros/transform_broadcaster.h>
#include <tf2_ros/transform_listener.h>
#include <visualization_msgs/MarkerArray.h>

#include <array>
#include <atomic>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <cstdio>
#include <cstring>
#include <deque>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

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

/** The node's parameters (private namespace); each defaults from the configuration. */
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
  /** Folder of ~save_map's files. */
  std::string output_folder{"."};
};

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
    const auto& bag = config_.input.ros_bag;
    if (!bag.parent_frame.empty())
      params_.fixed_frame = bag.parent_frame;
    if (!bag.child_frame.empty())
      params_.sensor_frame = bag.child_frame;
    pnh_.param("fixed_frame", params_.fixed_frame, params_.fixed_frame);
    pnh_.param("sensor_frame", params_.sensor_frame, params_.sensor_frame);
    pnh_.param("max_queued_frames", params_.max_queued_frames,
               params_.max_queued_frames);
    pnh_.param("tf_timeout", params_.tf_timeout_s, params_.tf_timeout_s);
    pnh_.param("publish_every", params_.publish_every, params_.publish_every);
    pnh_.param("map_2d_period", params_.map_2d_period_s, params_.map_2d_period_s);
    pnh_.param("output_folder", params_.output_folder, params_.output_folder);
    if (params_.max_queued_frames < 0 || params_.publish_every < 1
        || !(params_.tf_timeout_s >= 0.0) || !(params_.map_2d_period_s >= 0.0))
      throw planar_grid::Exception(
        "planar_grid_ros_node: ~max_queued_frames must be >= 0, ~publish_every >= 1 "
        "and ~tf_timeout, ~map_2d_period >= 0");
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

    markers_pub_ = pnh_.advertise<visualization_msgs::MarkerArray>("cuboids", 1, true);
    occupied_pub_ = pnh_.advertise<sensor_msgs::PointCloud2>("occupied_cells", 1, true);
    grid_pub_ = pnh_.advertise<nav_msgs::OccupancyGrid>("map_2d", 1, true);
    stats_pub_ = pnh_.advertise<std_msgs::String>("frame_stats", 100);
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
        std::chrono::duration<double>(std::min(params_.tf_timeout_s, 1e9)));
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
        broadcastPose(header, stats.world_T_camera);
      } else
        stats = mapper_->integrateStereo(left, right, calibration, lookUpPose(header));
    }
    ++mapped_;
    const bool keyframe = isKeyframe(stats);
    if (keyframe)
      ++keyframes_;
    const Clock::time_point publish_start = Clock::now();
    if (mapped_ % static_cast<std::uint64_t>(params_.publish_every) == 0)
      publishMap(header.stamp);
    publishStats(
      frame, stats, keyframe,
      std::chrono::duration<double, std::milli>(Clock::now() - publish_start).count());
  }

  void broadcastPose(const std_msgs::Header& header, const Eigen::Isometry3d& pose)
  {
    tf_broadcaster_.sendTransform(planar_grid::ros_messages::transformStamped(
      pose, params_.fixed_frame,
      params_.sensor_frame.empty() ? header.frame_id : params_.sensor_frame,
      header.stamp));
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

  /** The publisher thread: the occupied cells after each frame (frames that come
   * faster are coalesced) and the 2D map at most once per ~map_2d_period and after the
   * last frame of a burst, read from the map under its shared lock (Mapper::readMap())
   * while the worker maps the next frame. */
  void publishSpace()
  {
    std::uint64_t published = 0;
    std::uint64_t grid_published = 0;
    Clock::time_point last_grid{};
    const auto period = std::chrono::duration_cast<Clock::duration>(
      std::chrono::duration<double>(params_.map_2d_period_s));
    for (;;) {
      std::uint64_t version = 0;
      ros::Time stamp;
      {
        std::unique_lock<std::mutex> lock(publish_mutex_);
        const auto ready = [&] {
          return stopping_publisher_ || map_version_ != published;
        };
        if (grid_published == map_version_)
          publish_cv_.wait(lock, ready);
        else
          publish_cv_.wait_until(lock, last_grid + period, ready);
        if (stopping_publisher_)
          return;
        version = map_version_;
        stamp = map_stamp_;
      }
      const bool cells = version != published && occupied_pub_.getNumSubscribers() > 0;
      const bool grid = version != grid_published && Clock::now() >= last_grid + period
                        && grid_pub_.getNumSubscribers() > 0;
      if (cells || grid) {
        const auto map = mapper_->readMap();
        const auto timed = [](std::atomic<double>& ms, const auto& publish) {
          const Clock::time_point start = Clock::now();
          publish();
          ms = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
        };
        if (cells)
          timed(occupied_ms_, [&] { publishOccupiedCells(*map, stamp); });
        if (grid)
          timed(map_2d_ms_, [&] { publishGrid(*map, stamp); });
      }
      published = version;
      if (grid || Clock::now() >= last_grid + period) {
        grid_published = version;
        last_grid = Clock::now();
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
    const planar_grid::OccupancyGrid2D grid = map.computeOccupancyGrid2D(grid_params_);
    nav_msgs::OccupancyGrid msg;
    msg.header.frame_id = params_.fixed_frame;
    msg.header.stamp = stamp;
    msg.info.map_load_time = stamp;
    msg.info.resolution = static_cast<float>(grid.resolution_m);
    msg.info.width = static_cast<std::uint32_t>(grid.width);
    msg.info.height = static_cast<std::uint32_t>(grid.height);
    msg.info.origin.position.x = grid.origin.x();
    msg.info.origin.position.y = grid.origin.y();
    msg.info.origin.position.z =
      grid_params_.above_terrain ? 0.0 : grid_params_.z_ref_m;
    msg.info.origin.orientation.w = 1.0;
    msg.data = grid.cells;
    grid_pub_.publish(msg);
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
    j["exclusive_ms"] = stats.exclusive_ms;
    j["planes"] = stats.planes;
    j["cuboids"] = stats.cuboids;
    j["map_cuboids"] = stats.map_cuboids;
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
      {
        const auto map = mapper_->readMap();
        map->exportOctoMap((dir / "map.bt").string());
        map->exportMesh((dir / "map_cuboids.ply").string());
      }
      response.success = true;
      response.message = "wrote map.pgmap, map.bt and map_cuboids.ply in " + folder
                         + " (" + std::to_string(mapped_) + " frames)";
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
  planar_grid::OccupancyGrid2DParams grid_params_;
  std::unique_ptr<planar_grid::Mapper> mapper_;
  bool odometry_{false};
  /** Wall time of the last frame's markers, ms. */
  double cuboids_ms_{0.0};

  /** Transforms of the last minute: with frames queued, a frame may be mapped long
   * after its pose arrived. */
  tf2_ros::Buffer tf_buffer_{ros::Duration(60.0)};
  std::unique_ptr<tf2_ros::TransformListener> tf_listener_;
  tf2_ros::TransformBroadcaster tf_broadcaster_;
  ros::Publisher markers_pub_, occupied_pub_, grid_pub_, stats_pub_;
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
  /** Wall time of the publisher's last occupied cells and 2D map, ms. */
  std::atomic<double> occupied_ms_{0.0}, map_2d_ms_{0.0};
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
  "publishes the map after each frame.\n"
  "\n"
  "Private parameters:\n"
  "  ~config             the pipeline's YAML file (required)\n"
  "  ~fixed_frame        world frame of the map and of the published topics\n"
  "                      (default: the configuration's, else world)\n"
  "  ~sensor_frame       the camera's frame (default: the messages' frame_id)\n"
  "  ~max_queued_frames  frames kept waiting while one is mapped; 0: no limit (1)\n"
  "  ~tf_timeout         longest wait for a frame's transform, s (0.5)\n"
  "  ~publish_every      publish the map every N mapped frames (1)\n"
  "  ~map_2d_period      shortest time between two 2D maps, s (2.0)\n"
  "  ~output_folder      folder of ~save_map's files (.)\n"
  "\n"
  "Subscribes: left/image_rect, right/image_rect, left/camera_info,\n"
  "  right/camera_info, or cloud (PointCloud2) for a pcd_files configuration\n"
  "  (or the configuration's ros_bag topics).\n"
  "Publishes: ~cuboids (MarkerArray), ~occupied_cells (PointCloud2), ~map_2d\n"
  "  (OccupancyGrid), ~frame_stats (String, JSON per frame).\n"
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
