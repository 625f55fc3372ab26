// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node's node, shared by its sources: the frames' intake, the worker
// and the services (planar_grid_ros_node.cpp), the parameters
// (planar_grid_ros_node_params.cpp) and the publishers
// (planar_grid_ros_node_publish.cpp).
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/pipeline_config.h>
#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
#include <planar_grid/PlanarGridConfig.h>
#endif

#include <message_filters/subscriber.h>
#include <message_filters/sync_policies/approximate_time.h>
#include <message_filters/synchronizer.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
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

#include <atomic>
#include <chrono>
#include <condition_variable>
#include <cstdint>
#include <deque>
#include <memory>
#include <mutex>
#include <string>
#include <thread>

namespace ros_node {

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

class PlanarGridNode {
public:
  PlanarGridNode(ros::NodeHandle& nh, ros::NodeHandle& pnh);

  ~PlanarGridNode();

private:
  using SyncPolicy =
    message_filters::sync_policies::ApproximateTime<sensor_msgs::Image,
                                                    sensor_msgs::Image,
                                                    sensor_msgs::CameraInfo,
                                                    sensor_msgs::CameraInfo>;
  using Sync = message_filters::Synchronizer<SyncPolicy>;

  /** The parameters, with the values dynamic_reconfigure last set, read under their
   * lock. */
  NodeParams liveParams() const;

  /** The 2D map's band (~pointcloud_min_z, ~pointcloud_max_z as last set), read under
   * its lock. */
  planar_grid::OccupancyGrid2DParams gridParams() const;

#ifdef PLANAR_GRID_HAVE_DYNAMIC_RECONFIGURE
  /** The dynamic_reconfigure server on the node's private namespace, holding the
   * values the node runs with (its start parameters and the configuration's), so that
   * rqt_reconfigure and `dynparam get` show them. */
  void startReconfigureServer();

  /** A dynamic_reconfigure request: takes the new values (the server has clamped
   * each to its range) for the next frame and the next publication, logs what
   * changed, and asks for the 2D map again when its band changed. A band upside down
   * (min not below max) is refused: the band keeps its values, which the server then
   * reports back. */
  void onReconfigure(planar_grid::PlanarGridConfig& config);
#endif

  /** Whether the pipeline has a stage of \a type. */
  bool hasStage(const std::string& type) const;

  /** ~resolution and ~sensor_model/max_range (octomap_server's names): the map's voxel
   * edge and the depth up to which a view marks space, meters. They replace the
   * configuration's map_integration resolution_m and max_range_m (the resolution also
   * planar_cuboid_approximation's min_cell_size_m, which the map's raster shares), and
   * the configuration is validated again with them, as the pipeline tool's --set does.
   * \throws planar_grid::Exception naming the parameter for a value out of range, a
   * pipeline without map_integration, or a configuration they do not fit */
  void applyMapParams();

  /** ~frame_id (octomap_server's name) or ~fixed_frame: the map's frame; either
   * replaces the configuration's poses.parent_frame. Both set must agree.
   * \throws planar_grid::Exception for two different frames or an empty one */
  void readFrameParams();

  /** ~pointcloud_min_z and ~pointcloud_max_z (octomap_server's names): the ends of the
   * 2D map's height band, meters above its reference (the terrain the views saw, or
   * z_ref_m: output.map_grid_2d_band); they replace the configuration's z_min_m and
   * z_max_m.
   * \throws planar_grid::Exception for an end out of range or min >= max */
  void applyBandParams();

  /** Prints the values the node runs with, under octomap_server's names, and where
   * each comes from. */
  void logEffectiveParams() const;

  void onStereo(const sensor_msgs::ImageConstPtr& left,
                const sensor_msgs::ImageConstPtr& right,
                const sensor_msgs::CameraInfoConstPtr& left_info,
                const sensor_msgs::CameraInfoConstPtr& right_info);

  void onCloud(const sensor_msgs::PointCloud2ConstPtr& cloud);

  /** Queues a frame for the worker and returns at once (callbacks never block on
   * mapping); drops the oldest waiting frame when the queue is full. */
  void enqueue(PendingFrame&& frame);

  void work();

  /** The frame's world_T_sensor from TF at the message's stamp. */
  Eigen::Isometry3d lookUpPose(const std_msgs::Header& header);

  /** Whether the node is shutting down (its destructor, or ROS after SIGINT). */
  bool stopRequested();

  void mapFrame(const PendingFrame& frame);

  /** The pose the visual odometry estimated for the frame, \a world_T_camera (meters,
   * the map's z-up frame): on /tf as fixed_frame -> sensor frame and on ~odometry as
   * nav_msgs/Odometry (header.frame_id the map's frame, child_frame_id the sensor
   * frame), both stamped with the left image's stamp. The Odometry's twist is the
   * motion from the previous mapped frame to this one divided by the time between
   * their stamps, in the sensor frame (m/s, rad/s; zero for the first frame after a
   * start or a reset); its covariances are not estimated and stay zero. */
  void publishPose(const std_msgs::Header& header,
                   const Eigen::Isometry3d& world_T_camera);

  /** The map's cuboids, occupied voxels and 2D obstacle map, each only when its topic
   * has subscribers (the latched message goes to later ones). Runs on the integrating
   * thread, between frames. */
  void publishMap(const ros::Time& stamp);

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
  void publishSpace();

  /** One CUBE marker per cuboid: namespace planar (coloured by plane) or non_planar
   * (grey), after a DELETEALL that removes the previous frame's. */
  void publishCuboids(const planar_grid::PlanarGridMap& map, const ros::Time& stamp);

  /** The centres of the space layer's occupied voxels (x, y, z float32, meters). */
  void publishOccupiedCells(const planar_grid::PlanarGridMap& map,
                            const ros::Time& stamp);

  /** The obstacles of the configured height band
   * (PlanarGridMap::computeOccupancyGrid2D): 0 free, 100 occupied, -1 unknown. */
  void publishGrid(const planar_grid::PlanarGridMap& map, const ros::Time& stamp);

  /** ~octomap_binary and ~octomap_full, each when it has subscribers. A failed
   * export is logged and the next map version tries again. */
  void publishOctoMaps(const ros::Time& stamp);

  /** The map as octomap_msgs/Octomap: the tree PlanarGridMap::exportOctoMap() writes
   * to map.bt (binary: each node's maximum-likelihood state) or map.ot (full: each
   * node's log-odds, the cuboids' probabilities), built in memory under the map's
   * shared lock (PlanarGridMap::toOcTree) and serialized as octomap_msgs'
   * conversions.h does (binaryMapToMsg: OcTree::writeBinaryData; fullMapToMsg:
   * OcTree::writeData), with id "OcTree", the tree's resolution in meters, and the
   * map's frame and the last mapped frame's stamp in the header. */
  octomap_msgs::Octomap octomapMessage(const ros::Time& stamp, bool binary) const;

  /** Whether the frame was dense: stereo_disparity gave it a disparity (every frame
   * without that stage, or with every frame dense). */
  static bool isKeyframe(const planar_grid::FrameStats& stats);

  void publishStats(const PendingFrame& frame,
                    const planar_grid::FrameStats& stats,
                    bool keyframe,
                    double publish_ms);

  /** ~save_map: map.pgmap, map.bt and map_cuboids.ply in ~output_folder (read at the
   * call), each written atomically, under the map's shared lock. */
  bool onSave(std_srvs::Trigger::Request& /*request*/,
              std_srvs::Trigger::Response& response);

  /** ~reset: empties the map between two frames (the worker does it) and drops the
   * frames waiting. */
  bool onReset(std_srvs::Trigger::Request& /*request*/,
               std_srvs::Trigger::Response& response);

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

} // namespace ros_node
