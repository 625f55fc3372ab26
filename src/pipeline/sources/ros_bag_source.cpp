// SPDX-License-Identifier: BSD-3-Clause
#include "ros_bag_source.h"

#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/stereo_pair_check.h>
#include <planar_grid/ros_bag/ros_bag_file.h>
#include <planar_grid/ros_bag/ros_messages.h>
#include <planar_grid/ros_bag/transform_table.h>

#include <pcl/console/print.h>

#include <rosbag/bag.h>
#include <rosbag/view.h>
#include <sensor_msgs/CameraInfo.h>
#include <sensor_msgs/Image.h>
#include <sensor_msgs/PointCloud2.h>
#include <tf2_msgs/TFMessage.h>

#include <algorithm>
#include <cmath>
#include <filesystem>
#include <mutex>
#include <sstream>

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

/** A header stamp in seconds. */
double
seconds(const ros::Time& stamp)
{
  return stamp.toSec();
}

std::string
stampText(double t)
{
  std::ostringstream out;
  out.precision(15);
  out << t << " s";
  return out.str();
}

/** The frames of a ROS bag: stereo pairs or clouds, kept as the bag's messages and
 * read when loaded. */
class RosBagSource : public FrameSource {
public:
  explicit RosBagSource(const InputConfig& input) :
      config_(input.ros_bag), bag_(input.ros_bag.file)
  {
    name_ = fs::path(config_.file).filename().string();
    stereo_ = input.type == InputConfig::Type::STEREO_SEQUENCE;
    if (stereo_)
      indexStereo();
    else
      indexClouds();
    if (input.frame_count > 0
        && static_cast<std::size_t>(input.frame_count) < stamps_.size())
      resize(static_cast<std::size_t>(input.frame_count));
    if (input.poses_format == PoseFormat::TF)
      readPoses();
    if (stereo_ && !stamps_.empty()) {
      // The first pair before any frame runs: swapped topics or one camera's images
      // on both would run to the end and map next to nothing.
      Frame first;
      load(0, first);
      const std::string at = bag_.path() + ": ";
      checkStereoPairOrder(first.left, first.right, at + config_.left_image_topic,
                           at + config_.right_image_topic);
      const std::string off_centre = first.calibration.principalPointWarning(
        first.left.cols, first.left.rows, at + config_.left_info_topic);
      if (!off_centre.empty())
        PCL_WARN("[planar_grid::FrameSource] %s\n", off_centre.c_str());
    }
    std::ostringstream text;
    if (stereo_)
      text << stamps_.size() << " stereo pairs from " << config_.file << " ("
           << config_.left_image_topic << ", " << config_.right_image_topic
           << "; f = " << calibration_.focal_length_px
           << " px, B = " << calibration_.baseline_m << " m)";
    else
      text << stamps_.size() << " clouds from " << config_.file << " ("
           << config_.cloud_topic << ")";
    if (!poses_.empty())
      text << ", poses " << config_.parent_frame << " -> " << config_.child_frame;
    description_ = text.str();
  }

  std::size_t size() const override { return stamps_.size(); }

  void load(std::size_t i, Frame& frame) const override
  {
    const std::lock_guard<std::mutex> lock(mutex_);
    try {
      loadMessages(i, frame);
    } catch (const rosbag::BagException& e) {
      throw IOError(bag_.path() + ": cannot read frame " + std::to_string(i) + " ("
                    + e.what() + ")");
    } catch (const ros::Exception& e) {
      throw IOError(bag_.path() + ": cannot read frame " + std::to_string(i) + " ("
                    + e.what() + ")");
    }
  }

  std::string describe() const override { return description_; }

  const Trajectory& poses() const override { return poses_; }

  std::vector<InputFile> files() const override
  {
    return {{config_.file, "the ROS bag (input.file)"}};
  }

  bool camera(StereoCalibration& calibration) const override
  {
    calibration = calibration_;
    return stereo_ && calibration_.width > 0 && calibration_.height > 0;
  }

private:
  void loadMessages(std::size_t i, Frame& frame) const
  {
    frame = Frame();
    frame.sequence_number = i;
    frame.file_index = static_cast<int>(i);
    if (stereo_) {
      const std::string where = bag_.path() + ": " + config_.left_image_topic;
      frame.left = readImage(left_[i], config_.left_image_topic);
      frame.right = readImage(right_[i], config_.right_image_topic);
      // A CameraInfo of size 0x0 does not give the size.
      const bool sized = calibration_.width > 0 && calibration_.height > 0;
      if ((sized
           && (frame.left.cols != calibration_.width
               || frame.left.rows != calibration_.height))
          || frame.right.size() != frame.left.size())
        throw IOError(
          where + ": pair " + std::to_string(i) + " at " + stampText(stamps_[i])
          + " has images of " + std::to_string(frame.left.cols) + "x"
          + std::to_string(frame.left.rows) + " and " + std::to_string(frame.right.cols)
          + "x" + std::to_string(frame.right.rows) + "; the CameraInfo says "
          + std::to_string(calibration_.width) + "x"
          + std::to_string(calibration_.height));
      frame.calibration = calibration_;
      frame.name = name_ + " " + config_.left_image_topic + " #" + std::to_string(i);
    } else {
      const auto msg = clouds_[i].instantiate<sensor_msgs::PointCloud2>();
      const std::string where = bag_.path() + ": " + config_.cloud_topic;
      if (!msg)
        throw IOError(where + ": message " + std::to_string(i) + " cannot be read");
      Frame::Cloud::Ptr cloud(new Frame::Cloud);
      ros_messages::cloudFromMessage(*msg, where + " at " + stampText(stamps_[i]),
                                     *cloud);
      cloud->sensor_origin_ = Eigen::Vector4f(0, 0, 0, 1);
      cloud->sensor_orientation_ = Eigen::Quaternionf::Identity();
      frame.cloud = cloud;
      frame.name = name_ + " " + config_.cloud_topic + " #" + std::to_string(i);
    }
    frame.has_pose = !poses_.empty();
    if (frame.has_pose)
      frame.world_T_camera = poses_[i];
  }

  cv::Mat readImage(const rosbag::MessageInstance& m, const std::string& topic) const
  {
    const std::string where = bag_.path() + ": " + topic;
    const auto image = m.instantiate<sensor_msgs::Image>();
    if (!image)
      throw IOError(where + ": a message cannot be read as sensor_msgs/Image");
    return ros_messages::greyImage(*image, where + " at "
                                             + stampText(seconds(image->header.stamp)));
  }

  /** The first CameraInfo of \a topic. */
  sensor_msgs::CameraInfo cameraInfo(const std::string& topic, const std::string& key)
  {
    bag_.require(topic, "sensor_msgs/CameraInfo", key);
    rosbag::View view(bag_.bag(), rosbag::TopicQuery(topic));
    for (const auto& m : view)
      if (const auto info = m.instantiate<sensor_msgs::CameraInfo>())
        return *info;
    throw IOError(bag_.path() + ": topic '" + topic + "' (" + key
                  + ") has no CameraInfo message");
  }

  /** Pairs each left image with the right one nearest in time (header stamps) within
   * the tolerance, and reads the calibration from the CameraInfo. */
  void indexStereo()
  {
    bag_.require(config_.left_image_topic, "sensor_msgs/Image", "input.left_image");
    bag_.require(config_.right_image_topic, "sensor_msgs/Image", "input.right_image");
    const auto left_info =
      cameraInfo(config_.left_info_topic, "input.left_camera_info");
    const auto right_info =
      cameraInfo(config_.right_info_topic, "input.right_camera_info");
    const std::string right_where = bag_.path() + ": " + config_.right_info_topic;
    calibration_ =
      ros_messages::calibrationFromCameraInfo(left_info, right_info, right_where);

    // MessageInstance is not assignable: the messages stay where they were read and
    // their positions are sorted by stamp.
    std::vector<rosbag::MessageInstance> messages;
    // Stamps in nanoseconds: a double holds a stamp of today only to 0.2 us.
    std::vector<std::pair<std::int64_t, std::size_t>> lefts, rights;
    rosbag::View view(bag_.bag(),
                      rosbag::TopicQuery(std::vector<std::string>{
                        config_.left_image_topic, config_.right_image_topic}));
    for (const auto& m : view) {
      const auto image = m.instantiate<sensor_msgs::Image>();
      if (!image)
        continue;
      auto& list = m.getTopic() == config_.left_image_topic ? lefts : rights;
      list.emplace_back(static_cast<std::int64_t>(image->header.stamp.toNSec()),
                        messages.size());
      messages.push_back(m);
    }
    std::stable_sort(lefts.begin(), lefts.end());
    std::stable_sort(rights.begin(), rights.end());
    std::size_t r = 0, unpaired = 0;
    const auto tolerance =
      static_cast<std::int64_t>(std::llround(config_.pair_tolerance_s * 1e9));
    const auto distance = [](std::int64_t a, std::int64_t b) {
      return a > b ? a - b : b - a;
    };
    for (const auto& [t, k] : lefts) {
      while (r < rights.size() && rights[r].first < t - tolerance)
        ++r;
      // The nearest right image within the tolerance (the next one may be nearer).
      std::size_t best = r;
      if (r + 1 < rights.size()
          && distance(rights[r + 1].first, t) < distance(rights[r].first, t))
        best = r + 1;
      if (best < rights.size() && distance(rights[best].first, t) <= tolerance) {
        stamps_.push_back(seconds(ros::Time().fromNSec(static_cast<std::uint64_t>(t))));
        left_.push_back(messages[k]);
        right_.push_back(messages[rights[best].second]);
        r = best + 1;
      } else
        ++unpaired;
    }
    if (stamps_.empty())
      throw IOError(bag_.path() + ": no stereo pair: " + std::to_string(lefts.size())
                    + " images on " + config_.left_image_topic + " and "
                    + std::to_string(rights.size()) + " on " + config_.right_image_topic
                    + " have no header stamps within "
                    + std::to_string(config_.pair_tolerance_s)
                    + " s of each other (input.max_pair_time_difference_s)");
    if (unpaired > 0)
      PCL_WARN("[planar_grid::FrameSource] %s: %zu of %zu left images have no right "
               "image within %g s; they are skipped.\n",
               bag_.path().c_str(), unpaired, lefts.size(), config_.pair_tolerance_s);
  }

  void indexClouds()
  {
    bag_.require(config_.cloud_topic, "sensor_msgs/PointCloud2", "input.cloud");
    rosbag::View view(bag_.bag(), rosbag::TopicQuery(config_.cloud_topic));
    std::vector<rosbag::MessageInstance> messages;
    std::vector<std::pair<double, std::size_t>> clouds;
    for (const auto& m : view)
      if (const auto cloud = m.instantiate<sensor_msgs::PointCloud2>()) {
        clouds.emplace_back(seconds(cloud->header.stamp), messages.size());
        messages.push_back(m);
      }
    if (clouds.empty())
      throw IOError(bag_.path() + ": topic '" + config_.cloud_topic
                    + "' (input.cloud) has no message");
    std::stable_sort(clouds.begin(), clouds.end());
    for (const auto& [t, k] : clouds) {
      stamps_.push_back(t);
      clouds_.push_back(messages[k]);
    }
  }

  void resize(std::size_t n)
  {
    stamps_.resize(n);
    // pop_back: MessageInstance is not assignable, which erase would need.
    for (auto* list : {&left_, &right_, &clouds_})
      while (list->size() > n)
        list->pop_back();
  }

  /** world_T_camera of every frame: parent_frame_T_child_frame at its stamp. */
  void readPoses()
  {
    bag_.require(config_.tf_topic, "tf2_msgs/TFMessage", "input.poses.topic");
    std::vector<std::string> topics{config_.tf_topic};
    if (bag_.has(config_.tf_static_topic)) {
      bag_.require(config_.tf_static_topic, "tf2_msgs/TFMessage",
                   "input.poses.static_topic");
      topics.push_back(config_.tf_static_topic);
    }
    TransformTable table;
    rosbag::View view(bag_.bag(), rosbag::TopicQuery(topics));
    for (const auto& m : view)
      if (const auto tf = m.instantiate<tf2_msgs::TFMessage>())
        table.add(*tf, m.getTopic() == config_.tf_static_topic,
                  bag_.path() + ": " + m.getTopic());
    table.sort();
    const std::string where = bag_.path() + ": " + config_.tf_topic;
    for (const double t : stamps_)
      poses_.push_back(table.lookup(config_.parent_frame, config_.child_frame, t,
                                    config_.tf_tolerance_s, where));
  }

  InputConfig::RosBag config_;
  /** rosbag reads through one file handle: loads are serialised. */
  mutable std::mutex mutex_;
  mutable RosBagFile bag_;
  std::string name_;
  bool stereo_{true};
  StereoCalibration calibration_;
  std::vector<double> stamps_;
  std::vector<rosbag::MessageInstance> left_, right_, clouds_;
  Trajectory poses_;
  std::string description_;
};

} // namespace

std::unique_ptr<FrameSource>
createRosBagSource(const InputConfig& input)
{
  try {
    return std::make_unique<RosBagSource>(input);
  } catch (const rosbag::BagException& e) {
    throw IOError(input.ros_bag.file + ": cannot read the ROS bag (" + e.what() + ")");
  } catch (const ros::Exception& e) {
    throw IOError(input.ros_bag.file + ": cannot read a message of the ROS bag ("
                  + e.what() + ")");
  }
}

} // namespace planar_grid
