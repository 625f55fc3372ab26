// SPDX-License-Identifier: BSD-3-Clause
// planar_grid_ros_node's publishers: the visual odometry's pose, the map's cuboids,
// occupied cells, 2D map and OctoMaps (on the publisher thread, throttled) and the
// frame statistics.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/ros_bag/ros_messages.h>

#include <geometry_msgs/TransformStamped.h>
#include <nav_msgs/OccupancyGrid.h>
#include <nav_msgs/Odometry.h>
#include <nlohmann/json.hpp>
#include <octomap/OcTree.h>
#include <octomap_msgs/Octomap.h>
#include <ros/ros.h>
#include <sensor_msgs/PointCloud2.h>
#include <std_msgs/String.h>
#include <visualization_msgs/MarkerArray.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <mutex>
#include <sstream>
#include <string>
#include <utility>

#include "planar_grid_ros_node.h"

namespace ros_node {

namespace {

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

} // namespace

void
PlanarGridNode::publishPose(const std_msgs::Header& header,
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

void
PlanarGridNode::publishMap(const ros::Time& stamp)
{
  const Clock::time_point start = Clock::now();
  if (markers_pub_.getNumSubscribers() > 0)
    publishCuboids(*mapper_->getMap(), stamp);
  cuboids_ms_ = std::chrono::duration<double, std::milli>(Clock::now() - start).count();
  {
    std::lock_guard<std::mutex> lock(publish_mutex_);
    map_stamp_ = stamp;
    ++map_version_;
  }
  publish_cv_.notify_one();
}

void
PlanarGridNode::publishSpace()
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
    for (auto [taken, product] : {std::pair{grid_now, &grid}, {octomap_now, &octomap}})
      if (taken) {
        product->version = version;
        product->last = Clock::now();
      }
  }
}

void
PlanarGridNode::publishCuboids(const planar_grid::PlanarGridMap& map,
                               const ros::Time& stamp)
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

void
PlanarGridNode::publishOccupiedCells(const planar_grid::PlanarGridMap& map,
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

void
PlanarGridNode::publishGrid(const planar_grid::PlanarGridMap& map,
                            const ros::Time& stamp)
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

void
PlanarGridNode::publishOctoMaps(const ros::Time& stamp)
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

octomap_msgs::Octomap
PlanarGridNode::octomapMessage(const ros::Time& stamp, bool binary) const
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

bool
PlanarGridNode::isKeyframe(const planar_grid::FrameStats& stats)
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

void
PlanarGridNode::publishStats(const PendingFrame& frame,
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
  j["map_cells"] = stats.map_cells;
  // This thread is the map's only writer, so its count is the frame's; the covers it
  // builds are those the cuboid markers use.
  j["map_cuboids"] = mapper_->getMap()->getSurfaceLayer().getCuboidCount();
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

} // namespace ros_node
