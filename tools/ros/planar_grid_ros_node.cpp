// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node: live mapping in ROS 1 (docs/ROS.md). Subscribes to a rectified
// stereo pair with its CameraInfos, or to a PointCloud2; takes each frame's pose from
// TF (or from the pipeline's visual odometry, published on TF and as
// nav_msgs/Odometry); maps the frame with
// planar_grid::Mapper on a worker thread; publishes the map after each frame, also as
// octomap_msgs/Octomap. Takes octomap_server's parameter names where they mean the
// same; the ones that can change while it runs also through dynamic_reconfigure.
// This file: the frames' intake, the worker and the services; the parameters are read
// in planar_grid_ros_node_params.cpp, the map is published in
// planar_grid_ros_node_publish.cpp.
#include "planar_grid_ros_node.h"

#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/ros_bag/ros_messages.h>
#include <planar_grid/version.h>

#include <geometry_msgs/TransformStamped.h>
#include <ros/ros.h>

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <string>
#include <utility>

namespace ros_node {

PlanarGridNode::PlanarGridNode(ros::NodeHandle& nh, ros::NodeHandle& pnh) :
    nh_(nh), pnh_(pnh)
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
  pnh_.param("max_queued_frames", params_.max_queued_frames, params_.max_queued_frames);
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
  mapper_ = std::make_unique<planar_grid::Mapper>(planar_grid::toMapperConfig(config_));
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
                    << (params_.sensor_frame.empty() ? std::string("the images' frame")
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
    left_info_sub_.subscribe(nh_, name(bag.left_info_topic, "left/camera_info"), queue);
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

PlanarGridNode::~PlanarGridNode()
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
  ROS_INFO_STREAM("planar_grid_ros_node: " << mapped_ << " frames mapped, " << dropped_
                                           << " dropped, " << failed_ << " failed");
}

void
PlanarGridNode::onStereo(const sensor_msgs::ImageConstPtr& left,
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

void
PlanarGridNode::onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud)
{
  PendingFrame frame;
  frame.cloud = cloud;
  enqueue(std::move(frame));
}

void
PlanarGridNode::enqueue(PendingFrame&& frame)
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

void
PlanarGridNode::work()
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

Eigen::Isometry3d
PlanarGridNode::lookUpPose(const std_msgs::Header& header)
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

bool
PlanarGridNode::stopRequested()
{
  if (!ros::ok())
    return true;
  const std::lock_guard<std::mutex> lock(queue_mutex_);
  return stopping_;
}

void
PlanarGridNode::mapFrame(const PendingFrame& frame)
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

bool
PlanarGridNode::onSave(std_srvs::Trigger::Request& /*request*/,
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
    response.message = "wrote map.pgmap, map.bt and map_cuboids.ply in " + folder + " ("
                       + std::to_string(mapped_)
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

bool
PlanarGridNode::onReset(std_srvs::Trigger::Request& /*request*/,
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

} // namespace ros_node

namespace {

using ros_node::PlanarGridNode;

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
