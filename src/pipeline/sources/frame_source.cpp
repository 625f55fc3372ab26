// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/input_file.h>
#include <planar_grid/core/pcd_file_check.h>
#include <planar_grid/odometry/cloud_registration.h>
#include <planar_grid/odometry/floor_alignment.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/stereo_pair_check.h>
#include <planar_grid/stereo/calibration_io.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/common/transforms.h>
#include <pcl/console/print.h>
#include <pcl/console/time.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>

#include <glob.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <filesystem>
#include <iomanip>
#include <sstream>
#include <utility>

#include "ros_bag_source.h"

namespace planar_grid {

namespace {

namespace fs = std::filesystem;

/** A file-name pattern with one %d / %0Nd field, formatted without printf. */
class IndexPattern {
public:
  explicit IndexPattern(const std::string& pattern) : pattern_(pattern)
  {
    const auto pos = pattern.find('%');
    std::size_t i = pos + 1;
    bool zero = false;
    if (i < pattern.size() && pattern[i] == '0') {
      zero = true;
      ++i;
    }
    int width = 0;
    while (i < pattern.size() && std::isdigit(static_cast<unsigned char>(pattern[i])))
      width = width * 10 + (pattern[i++] - '0');
    if (pos == std::string::npos || i >= pattern.size() || pattern[i] != 'd'
        || pattern.find('%', i + 1) != std::string::npos || width > 12)
      throw IOError(pattern
                    + ": a file pattern needs exactly one index field, %d or %0Nd");
    prefix_ = pattern.substr(0, pos);
    suffix_ = pattern.substr(i + 1);
    width_ = width;
    fill_ = zero ? '0' : ' ';
  }

  std::string format(int index) const
  {
    std::ostringstream out;
    out << prefix_ << std::setw(width_) << std::setfill(fill_) << index << suffix_;
    return out.str();
  }

  /** The largest index whose file exists in the pattern's folder (the name formatted
   * exactly as format() writes it), or -1 when there is none or the index field is
   * not in the file name itself. */
  int lastIndexOnDisk() const
  {
    if (suffix_.find('/') != std::string::npos)
      return -1;
    const fs::path prefix_path(prefix_);
    const std::string name_prefix = prefix_path.filename().string();
    const fs::path folder =
      prefix_path.has_parent_path() ? prefix_path.parent_path() : fs::path(".");
    int last = -1;
    std::error_code ec;
    for (fs::directory_iterator it(folder, ec), end; !ec && it != end;
         it.increment(ec)) {
      const std::string name = it->path().filename().string();
      if (name.size() <= name_prefix.size() + suffix_.size()
          || name.compare(0, name_prefix.size(), name_prefix) != 0
          || name.compare(name.size() - suffix_.size(), suffix_.size(), suffix_) != 0)
        continue;
      const std::string field = name.substr(
        name_prefix.size(), name.size() - name_prefix.size() - suffix_.size());
      const auto digit = field.find_first_not_of(' ');
      // At most 9 digits: the index is an int.
      if (digit == std::string::npos || field.size() - digit > 9
          || !std::all_of(field.begin() + static_cast<std::ptrdiff_t>(digit),
                          field.end(),
                          [](unsigned char c) { return std::isdigit(c) != 0; }))
        continue;
      const int index = std::stoi(field.substr(digit));
      if (index > last && fs::path(format(index)).filename().string() == name)
        last = index;
    }
    return last;
  }

private:
  std::string pattern_, prefix_, suffix_;
  int width_{0};
  char fill_{'0'};
};

/** Throws an IOError unless \a path is a non-empty regular file: reading a pipe would
 * block for ever, a folder or an empty file is no image. \a what names the image
 * ("left image"); \a missing is the message's tail for a missing file. */
void
checkImageFile(const std::string& path,
               const std::string& what,
               const std::string& missing)
{
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw IOError(path + ": " + what + " not found" + missing);
  checkRegularFile(path, what);
  if (fs::file_size(path, ec) == 0)
    throw IOError(path + ": the " + what + " is empty (0 bytes)");
}

cv::Mat
readImage(const std::string& path)
{
  checkImageFile(path, "image", "");
  cv::Mat image = cv::imread(path, cv::IMREAD_GRAYSCALE);
  if (image.empty())
    throw IOError(path + ": cannot read the image (unreadable or not an image)");
  return image;
}

/** What both sources share: the poses of their frames and a description. */
class FrameSourceBase : public FrameSource {
public:
  std::string describe() const override { return description_; }

  const Trajectory& poses() const override { return poses_; }

  std::vector<InputFile> files() const override { return files_read_; }

protected:
  /** Gives frame \a i its pose when the input has poses. */
  void assignPose(std::size_t i, Frame& frame) const
  {
    frame.has_pose = !poses_.empty();
    if (frame.has_pose)
      frame.world_T_camera = poses_[i];
  }

  Trajectory poses_;
  std::string description_;
  /** Every file the input reads, for files(). */
  std::vector<InputFile> files_read_;
};

class StereoSequenceSource : public FrameSourceBase {
public:
  explicit StereoSequenceSource(const InputConfig& input) :
      left_(input.left_images), right_(input.right_images),
      first_index_(input.first_index)
  {
    model_ = loadStereoCalibration(input.calibration_format, input.calibration_file,
                                   input.calibration_right_file);

    if (input.frame_count > 0)
      count_ = static_cast<std::size_t>(input.frame_count);
    else {
      std::error_code ec;
      while (fs::exists(left_.format(first_index_ + static_cast<int>(count_)), ec))
        ++count_;
    }
    if (count_ == 0)
      throw IOError(left_.format(first_index_)
                    + ": no left image found (input.left_images)");

    if (input.poses_format == PoseFormat::KARLSRUHE_INSDATA) {
      poses_ = loadKarlsruheInsData(input.poses_file);
      // The insdata poses are level along the track, at the GPS/INS position. The
      // camera looks down by camera_pitch_rad (a rotation about its x axis) and sits
      // camera_height_m above the road, which then lies at world z = 0.
      const Eigen::Isometry3d mount(
        Eigen::AngleAxisd(-input.camera_pitch_rad, Eigen::Vector3d::UnitX()));
      for (auto& pose : poses_) {
        pose = pose * mount;
        pose.translation().z() += input.camera_height_m;
      }
    } else if (input.poses_format == PoseFormat::KITTI)
      poses_ = loadKittiPoses(input.poses_file);
    if (input.poses_format == PoseFormat::EUROC_GROUNDTRUTH)
      loadEurocPoses(input.poses_file);
    else if (!poses_.empty()) {
      const std::size_t needed = static_cast<std::size_t>(first_index_) + count_;
      if (poses_.size() < needed)
        throw IOError(input.poses_file + ": has " + std::to_string(poses_.size())
                      + " poses, but the frames need " + std::to_string(needed)
                      + " (first_index + frame count)");
      poses_.erase(poses_.begin(), poses_.begin() + first_index_);
      poses_.resize(count_);
    }
    checkImagesPresent(input.frame_count);
    checkFirstFrame(input.calibration_file);
    files_read_.push_back(
      {input.calibration_file, "the calibration (input.calibration.file)"});
    if (!input.calibration_right_file.empty())
      files_read_.push_back(
        {input.calibration_right_file,
         "the right camera's calibration (input.calibration.right_file)"});
    if (!input.poses_file.empty())
      files_read_.push_back({input.poses_file, "the poses file (input.poses.file)"});
    for (std::size_t i = 0; i < count_; ++i) {
      const int index = first_index_ + static_cast<int>(i);
      files_read_.push_back({left_.format(index), "a left image (input.left_images)"});
      files_read_.push_back(
        {right_.format(index), "a right image (input.right_images)"});
    }
    description_ =
      std::to_string(count_) + " stereo pairs " + left_.format(first_index_)
      + " ... (f = " + std::to_string(model_.calibration.focal_length_px)
      + " px, B = " + std::to_string(model_.calibration.baseline_m) + " m)";
  }

  std::size_t size() const override { return count_; }

  std::vector<InputFile> frameFiles(std::size_t i) const override
  {
    const int index = first_index_ + static_cast<int>(i);
    return {{left_.format(index), "the left image (input.left_images)"},
            {right_.format(index), "the right image (input.right_images)"}};
  }

  void load(std::size_t i, Frame& frame) const override
  {
    const int index = first_index_ + static_cast<int>(i);
    const std::string left_path = left_.format(index);
    const std::string right_path = right_.format(index);
    cv::Mat left = readImage(left_path);
    cv::Mat right = readImage(right_path);
    checkImageSizes(left_path, left.size(), right_path, right.size());
    const auto& calib = model_.calibration;
    if (!model_.rectifier.empty()) {
      model_.rectifier.rectify(left, right, frame.left, frame.right);
    } else {
      frame.left = left;
      frame.right = right;
    }
    frame.file_index = index;
    frame.name = fs::path(left_path).filename().string();
    frame.calibration = calib;
    frame.cloud.reset();
    frame.cloud_in_world_frame = false;
    assignPose(i, frame);
  }

private:
  /** Throws an IOError naming the first image of the frames that is missing, before
   * any frame is read. With \a frame_count 0 the frames end at the first missing left
   * image, so a left image past that gap means an image is missing in the middle of
   * the sequence, not that the sequence ended. */
  void checkImagesPresent(int frame_count) const
  {
    const int end = first_index_ + static_cast<int>(count_);
    if (frame_count == 0) {
      const int last = left_.lastIndexOnDisk();
      if (last >= end)
        throw IOError(left_.format(end) + ": left image not found, but the sequence "
                      + "goes on to " + left_.format(last)
                      + " (input.frame_count 0 takes every frame from first_index; an "
                        "image is missing in the middle of the sequence)");
    }
    for (int index = first_index_; index < end; ++index) {
      const std::string left_path = left_.format(index);
      checkImageFile(left_path, "left image",
                     " (frame " + std::to_string(index - first_index_) + " of the "
                       + std::to_string(count_) + " of input.frame_count)");
      checkImageFile(right_.format(index), "right image",
                     " (its left image " + left_path + " exists)");
    }
  }

  bool camera(StereoCalibration& calibration) const override
  {
    calibration = model_.calibration;
    calibration.width = image_size_.width;
    calibration.height = image_size_.height;
    return image_size_.width > 0 && image_size_.height > 0;
  }

  /** The size every image must have: the calibration's when it gives one (ROS
   * camera_info, EuRoC), else the first frame's (Karlsruhe and KITTI rows give none),
   * inside which the principal point must then lie. Reads the first pair, so that a
   * wrong size fails before the first frame is processed. */
  void checkFirstFrame(const std::string& calibration_file)
  {
    const std::string left_path = left_.format(first_index_);
    const std::string right_path = right_.format(first_index_);
    const cv::Mat left_image = readImage(left_path);
    const cv::Mat right_image = readImage(right_path);
    const cv::Size left = left_image.size();
    const cv::Size right = right_image.size();
    const auto& calib = model_.calibration;
    if (!model_.rectifier.empty()) {
      image_size_ = model_.rectifier.map_left_x.size();
      image_size_source_ = "the calibration's (" + calibration_file + ")";
    } else if (calib.width > 0 && calib.height > 0) {
      image_size_ = cv::Size(calib.width, calib.height);
      image_size_source_ = "the calibration's (" + calibration_file + ")";
    } else {
      image_size_ = left;
      image_size_source_ = "the first frame's (" + left_path + ")";
      if (!(calib.cx_px >= 0.0 && calib.cx_px < left.width && calib.cy_px >= 0.0
            && calib.cy_px < left.height)) {
        std::ostringstream text;
        text << left_path << ": size " << sizeText(left)
             << ", but the principal point (" << calib.cx_px << ", " << calib.cy_px
             << ") px of the calibration (" << calibration_file
             << ") lies outside the image: the images are not the "
             << "ones the calibration was made for";
        throw IOError(text.str());
      }
    }
    checkImageSizes(left_path, left, right_path, right);
    const std::string off_centre = calib.principalPointWarning(
      image_size_.width, image_size_.height, calibration_file);
    if (!off_centre.empty())
      PCL_WARN("[planar_grid::FrameSource] %s\n", off_centre.c_str());
    // Swapped or doubled images would run to the end and map next to nothing.
    if (model_.rectifier.empty()) {
      checkStereoPairOrder(left_image, right_image, left_path, right_path);
    } else {
      cv::Mat left_rectified, right_rectified;
      model_.rectifier.rectify(left_image, right_image, left_rectified,
                               right_rectified);
      checkStereoPairOrder(left_rectified, right_rectified, left_path, right_path);
    }
  }

  static std::string sizeText(const cv::Size& size)
  {
    return std::to_string(size.width) + "x" + std::to_string(size.height) + " px";
  }

  /** Throws an IOError naming the image and both sizes when the right image's size
   * differs from the left's, or the left's from image_size_. */
  void checkImageSizes(const std::string& left_path,
                       const cv::Size& left,
                       const std::string& right_path,
                       const cv::Size& right) const
  {
    if (right != left)
      throw IOError(right_path + ": size " + sizeText(right)
                    + " differs from the left image's " + sizeText(left) + " ("
                    + left_path + ")");
    if (left != image_size_)
      throw IOError(left_path + ": size " + sizeText(left) + " differs from "
                    + image_size_source_ + " " + sizeText(image_size_));
  }

  /** Fills poses_ (one per frame) from EuRoC world_T_body poses keyed by image index:
   * the pipeline's camera is the rectified left camera, so world_T_camera =
   * world_T_body * body_T_left * rectified_R_left^T. */
  void loadEurocPoses(const std::string& path)
  {
    const IndexedPoses body_poses = loadEurocBodyPoses(path);
    Eigen::Isometry3d left_T_rectified = Eigen::Isometry3d::Identity();
    left_T_rectified.linear() = model_.rectified_R_left.transpose();
    const Eigen::Isometry3d body_T_camera = model_.body_T_left * left_T_rectified;
    for (std::size_t k = 0; k < count_; ++k) {
      const int index = first_index_ + static_cast<int>(k);
      const auto pose = body_poses.find(index);
      if (pose == body_poses.end())
        throw IOError(path + ": no pose for image index " + std::to_string(index) + " ("
                      + left_.format(index) + ")");
      poses_.push_back(pose->second * body_T_camera);
    }
  }

  IndexPattern left_, right_;
  int first_index_;
  std::size_t count_{0};
  StereoCameraModel model_;
  /** The size of every image, pixels, and where it comes from (for the messages). */
  cv::Size image_size_;
  std::string image_size_source_;
};

/** Reads a PCD file into the working cloud type. PCL's conversion warns once per
 * missing field, so a cloud without intensity is read as the fields it has: colour
 * becomes the grey intensity (pcl::PointXYZRGBtoXYZI), bare XYZ gets intensity 0. */
void
loadPCDCloud(const std::string& path, Frame::Cloud& cloud)
{
  // PCL's reader trusts the header: checked first (points declared against the data
  // held, x/y/z present, the compressed sizes, the VIEWPOINT).
  checkPCDFile(path);
  // Read the blob first: PCL's conversion indexes point 0 of an empty cloud (UB that
  // UBSan reports), so a PCD without points is converted only when it has some.
  pcl::PCLPointCloud2 blob;
  int read = -1;
  try {
    read = pcl::io::loadPCDFile(path, blob);
  } catch (const std::exception& e) {
    throw IOError(path + ": cannot read the PCD file (" + e.what() + ")");
  }
  if (read < 0)
    throw IOError(path + ": cannot read the PCD file");
  checkPointCloudBlob(blob, path);
  // PCL leaves a field of another datatype than the point type's at 0: double or
  // integer coordinates would all become the origin.
  convertFieldsToFloat(blob, {"x", "y", "z", "intensity"}, path);
  intensityCloudFromBlob(blob, cloud);
}

class PCDFileSource : public FrameSourceBase {
public:
  explicit PCDFileSource(const InputConfig& input)
  {
    for (const auto& pattern : input.pcd_files) {
      glob_t g{};
      const int rc = ::glob(pattern.c_str(), 0, nullptr, &g);
      std::vector<std::string> matched;
      if (rc == 0)
        for (std::size_t k = 0; k < g.gl_pathc; ++k)
          matched.emplace_back(g.gl_pathv[k]);
      ::globfree(&g);
      if (matched.empty())
        throw IOError(pattern + ": no PCD file matches (input.files)");
      std::sort(matched.begin(), matched.end());
      files_.insert(files_.end(), matched.begin(), matched.end());
    }
    description_ =
      std::to_string(files_.size()) + " PCD files " + files_.front() + " ...";
    for (const auto& file : files_)
      files_read_.push_back({file, "a PCD file (input.files)"});
    if (!input.poses_file.empty())
      files_read_.push_back({input.poses_file, "the poses file (input.poses.file)"});
    if (input.poses_format == PoseFormat::KITTI) {
      poses_ = loadKittiPoses(input.poses_file);
      // Pose i is file i's (in name order): with a file missing from the sequence
      // every later pose would belong to the wrong cloud.
      if (poses_.size() != files_.size())
        throw IOError(input.poses_file + ": has " + std::to_string(poses_.size())
                      + " poses, but there are " + std::to_string(files_.size())
                      + " PCD files; pose i is the i-th file's (in name order), so "
                        "the counts must be equal (is a PCD file missing?)");
    } else if (input.poses_format == PoseFormat::VIEWPOINT)
      poseFromViewpoints(input);
    else if (input.poses_format == PoseFormat::REGISTRATION)
      poseByRegistration(input);
  }

  std::size_t size() const override { return files_.size(); }

  std::vector<InputFile> frameFiles(std::size_t i) const override
  {
    return {{files_[i], "the PCD file (input.files)"}};
  }

  void load(std::size_t i, Frame& frame) const override
  {
    const std::string& path = files_[i];
    Frame::Cloud::Ptr cloud(new Frame::Cloud);
    loadPCDCloud(path, *cloud);
    frame = Frame();
    frame.sequence_number = i;
    frame.file_index = static_cast<int>(i);
    frame.name = fs::path(path).filename().string();
    // The points are in the sensor frame; the pose is world_T_sensor.
    cloud->sensor_origin_ = Eigen::Vector4f(0, 0, 0, 1);
    cloud->sensor_orientation_ = Eigen::Quaternionf::Identity();
    frame.cloud = cloud;
    assignPose(i, frame);
  }

private:
  /** The sensor frame's up and forward directions when no pose gives them: sensor_up
   * when given; else an organized cloud, or one with the VIEWPOINT of PCL's depth
   * camera grabbers, is a camera's optical frame (up -y, forward z), and any other a
   * z-up scanner's (up z, forward x). */
  void sensorAxes(const InputConfig& input,
                  const Frame::Cloud& first,
                  const Eigen::Isometry3d& viewpoint,
                  Eigen::Vector3d& up,
                  Eigen::Vector3d& forward) const
  {
    const bool grabber =
      (viewpoint.linear() - Eigen::Matrix3d::Identity()).norm() > 1e-6;
    if (first.height > 1 || grabber) {
      up = -Eigen::Vector3d::UnitY();
      forward = Eigen::Vector3d::UnitZ();
    } else {
      up = Eigen::Vector3d::UnitZ();
      forward = Eigen::Vector3d::UnitX();
    }
    if (input.has_sensor_up) {
      up = Eigen::Vector3d(input.sensor_up.data()).normalized();
      // Any axis not along up serves as the forward direction.
      if (std::abs(up.dot(forward)) > 0.9)
        forward =
          std::abs(up.x()) < 0.9 ? Eigen::Vector3d::UnitX() : Eigen::Vector3d::UnitY();
    }
  }

  /** world_T_sensor of a sensor whose cloud \a points (its own frame) fixes "up": the
   * floor below it levels it (origin on the floor), or input.sensor_up does (origin at
   * the sensor). */
  Eigen::Isometry3d levelled(const InputConfig& input,
                             const pcl::PointCloud<pcl::PointXYZ>& points,
                             const Eigen::Vector3d& up,
                             const Eigen::Vector3d& forward,
                             const std::string& what) const
  {
    if (input.has_sensor_up) {
      const Eigen::Vector4f horizontal(static_cast<float>(up.x()),
                                       static_cast<float>(up.y()),
                                       static_cast<float>(up.z()), 0.0f);
      return levelSensorPose(horizontal, forward);
    }
    Eigen::Vector4f floor;
    std::size_t inliers = 0;
    if (!estimateFloorPlane(points, Eigen::Vector3f::Zero(), up.cast<float>(),
                            FloorEstimationParams(), floor, inliers)) {
      PCL_WARN("[planar_grid::FrameSource] %s: no floor or ground plane found to tell "
               "which way is up; the sensor frame's nominal up (%g, %g, %g) is taken. "
               "Set input.sensor_up to give it.\n",
               what.c_str(), up.x(), up.y(), up.z());
      return levelSensorPose(Eigen::Vector4f(static_cast<float>(up.x()),
                                             static_cast<float>(up.y()),
                                             static_cast<float>(up.z()), 0.0f),
                             forward);
    }
    const double tilt_deg =
      std::acos(std::min(
        1.0, static_cast<double>(floor.head<3>().cast<double>().dot(up.normalized()))))
      * 180.0 / M_PI;
    PCL_INFO("[planar_grid::FrameSource] %s: floor %.2f m below the sensor, its normal "
             "%.1f deg from the sensor's nominal up; levelled on it.\n",
             what.c_str(), static_cast<double>(floor[3]), tilt_deg);
    return levelSensorPose(floor, forward);
  }

  /** Poses from the VIEWPOINTs: PCL writes them in the y-up world of its visualizer.
   * Identical ones (PCL's constant defaults, or one pose repeated) fix no motion, and
   * a single file with a default VIEWPOINT is levelled on its floor. */
  void poseFromViewpoints(const InputConfig& input)
  {
    Trajectory viewpoints;
    for (const auto& f : files_)
      viewpoints.push_back(loadPCDViewpoint(f));
    bool identical = true;
    for (const auto& v : viewpoints)
      identical =
        identical
        && (v.matrix() - viewpoints.front().matrix()).cwiseAbs().maxCoeff() < 1e-6;
    if (files_.size() > 1 && identical)
      throw IOError(files_.front() + " ... (" + std::to_string(files_.size())
                    + " PCD files): every VIEWPOINT is the same, so the motion between "
                      "the frames is unknown and their clouds would be stacked "
                      "unregistered; set input.poses.format to registration, or give "
                      "the poses (format kitti)");
    if (isDefaultPCDViewpoint(viewpoints.front())) {
      if (input.has_sensor_up || files_.size() == 1) {
        Frame::Cloud cloud;
        loadPCDCloud(files_.front(), cloud);
        pcl::PointCloud<pcl::PointXYZ> points;
        pcl::copyPointCloud(cloud, points);
        Eigen::Vector3d up, forward;
        sensorAxes(input, cloud, viewpoints.front(), up, forward);
        poses_.push_back(levelled(input, points, up, forward, files_.front()));
        return;
      }
    } else if (input.has_sensor_up)
      throw IOError(files_.front()
                    + ": input.sensor_up is not used: the VIEWPOINTs are poses that "
                      "fix the up direction");
    const Eigen::Isometry3d z_up_T_y_up = zUpWorldFrom(WorldConvention::Y_UP);
    for (const auto& v : viewpoints)
      poses_.push_back(z_up_T_y_up * v);
  }

  /** Poses by frame-to-frame registration (GICP, FPFH guess), levelled on the floor of
   * the registered clouds. */
  void poseByRegistration(const InputConfig& input)
  {
    CloudRegistrationParams params;
    params.leaf_size_m = input.registration_leaf_size_m;
    params.max_correspondence_distance_m =
      input.registration_max_correspondence_distance_m;
    params.feature_initial_guess = input.registration_feature_initial_guess;
    pcl::console::TicToc timer;
    timer.tic();
    Frame::Cloud first;
    loadPCDCloud(files_.front(), first);
    pcl::PointCloud<pcl::PointXYZ>::Ptr previous(new pcl::PointCloud<pcl::PointXYZ>);
    pcl::copyPointCloud(first, *previous);
    // An organized cloud with colour or intensity gives key features on its image
    // (the cloud_features stage's, orb_grid), whose matched motion is GICP's first
    // initial guess; a cloud without an image gives none.
    StereoFeatureMatcher::Params detector;
    detector.feature_type = FeatureType::ORB_GRID;
    const auto imageFeatures = [&detector](const Frame::Cloud& cloud,
                                           StereoFeatures& features) {
      computeCloudImageFeatures(cloud, cloudIntensityImage(cloud), detector,
                                Eigen::Affine3f::Identity(), features);
    };
    StereoFeatures previous_features;
    imageFeatures(first, previous_features);
    // The registered clouds in the first sensor's frame, for the floor.
    pcl::PointCloud<pcl::PointXYZ> merged = *previous;
    Trajectory first_T_sensor{Eigen::Isometry3d::Identity()};
    Eigen::Isometry3d motion = Eigen::Isometry3d::Identity();
    std::size_t flagged = 0;
    for (std::size_t i = 1; i < files_.size(); ++i) {
      Frame::Cloud cloud;
      loadPCDCloud(files_[i], cloud);
      pcl::PointCloud<pcl::PointXYZ>::Ptr current(new pcl::PointCloud<pcl::PointXYZ>);
      pcl::copyPointCloud(cloud, *current);
      StereoFeatures features;
      imageFeatures(cloud, features);
      // Start from the previous frame's motion (a steadily panning or moving sensor)
      // where the image features give no guess.
      const CloudRegistrationResult result =
        registerCloud(*current, *previous, motion, params, features, previous_features);
      motion = result.target_T_source;
      first_T_sensor.push_back(first_T_sensor.back() * motion);
      const bool bad = !(result.residual_m <= input.registration_max_residual_m)
                       || result.overlap < 0.2;
      flagged += bad;
      const std::string name = fs::path(files_[i]).filename().string();
      const std::string onto = fs::path(files_[i - 1]).filename().string();
      std::string guess;
      if (result.image_feature_guess_used)
        guess = " (image feature guess, " + std::to_string(result.image_feature_inliers)
                + " inliers"
                + (result.image_feature_motion_kept
                     ? "; their motion kept: GICP slid along the geometry)"
                     : ")");
      else if (result.feature_guess_used)
        guess = " (FPFH initial guess)";
      if (bad)
        PCL_WARN("[planar_grid::FrameSource] Registered %s onto %s: residual %.4f m, "
                 "overlap %.2f%s; FLAGGED: residual above input.poses.max_residual_m "
                 "or overlap below 0.2.\n",
                 name.c_str(), onto.c_str(), result.residual_m, result.overlap,
                 guess.c_str());
      else
        PCL_INFO("[planar_grid::FrameSource] Registered %s onto %s: residual %.4f m, "
                 "overlap %.2f%s.\n",
                 name.c_str(), onto.c_str(), result.residual_m, result.overlap,
                 guess.c_str());
      pcl::PointCloud<pcl::PointXYZ> moved;
      pcl::transformPointCloud(*current, moved,
                               first_T_sensor.back().cast<float>().matrix());
      merged += moved;
      previous = current;
      previous_features = std::move(features);
    }
    Eigen::Vector3d up, forward;
    sensorAxes(input, first, loadPCDViewpoint(files_.front()), up, forward);
    const Eigen::Isometry3d world_T_first =
      levelled(input, merged, up, forward, files_.front() + " (registered)");
    for (const auto& pose : first_T_sensor)
      poses_.push_back(world_T_first * pose);
    PCL_INFO("[planar_grid::FrameSource] Registered %zu PCD files [done, %g ms; %zu "
             "flagged]\n",
             files_.size(), timer.toc(), flagged);
    description_ += " (registered, " + std::to_string(flagged) + " flagged)";
  }

  std::vector<std::string> files_;
};

} // namespace

/** The frames of another source, repeated count times; pass k's positions are offset
 * by k times the offset. */
class RepeatedSource : public FrameSource {
public:
  RepeatedSource(std::unique_ptr<FrameSource> source,
                 std::size_t count,
                 const Eigen::Vector3d& offset_m) :
      source_(std::move(source)),
      count_(count), offset_m_(offset_m)
  {
    const std::size_t n = source_->size();
    for (std::size_t pass = 0; pass < count_ && !source_->poses().empty(); ++pass)
      for (std::size_t i = 0; i < n; ++i) {
        Eigen::Isometry3d pose = source_->poses()[i];
        pose.translation() += static_cast<double>(pass) * offset_m_;
        poses_.push_back(pose);
      }
    std::ostringstream text;
    text << source_->describe() << ", " << count_ << " passes, offset ["
         << offset_m_.x() << ", " << offset_m_.y() << ", " << offset_m_.z()
         << "] m per pass";
    description_ = text.str();
  }

  std::size_t size() const override { return source_->size() * count_; }

  void load(std::size_t i, Frame& frame) const override
  {
    const std::size_t n = source_->size();
    const std::size_t pass = i / n;
    source_->load(i % n, frame);
    if (frame.has_pose)
      frame.world_T_camera.translation() += static_cast<double>(pass) * offset_m_;
    if (pass > 0)
      frame.name += " (pass " + std::to_string(pass + 1) + ")";
  }

  std::string describe() const override { return description_; }

  const Trajectory& poses() const override { return poses_; }

  std::vector<InputFile> files() const override { return source_->files(); }

  std::vector<InputFile> frameFiles(std::size_t i) const override
  {
    return source_->frameFiles(i % source_->size());
  }

  bool camera(StereoCalibration& calibration) const override
  {
    return source_->camera(calibration);
  }

private:
  std::unique_ptr<FrameSource> source_;
  std::size_t count_;
  Eigen::Vector3d offset_m_;
  Trajectory poses_;
  std::string description_;
};

bool
rosBagSupported()
{
#ifdef PLANAR_GRID_HAVE_ROS_BAG
  return true;
#else
  return false;
#endif
}

// Without the ROS bag library (src/ros_bag) the configuration already refuses a bag
// input; a configuration made in code is refused here.
#ifndef PLANAR_GRID_HAVE_ROS_BAG
std::unique_ptr<FrameSource>
createRosBagSource(const InputConfig& input)
{
  throw ConfigError("", 0, 0,
                    input.ros_bag.file
                      + ": this build of PlanarGrid has no ROS bag support "
                        "(librosbag-storage-dev was not found when it was configured)");
}
#endif

std::unique_ptr<FrameSource>
createFrameSource(const InputConfig& input)
{
  std::unique_ptr<FrameSource> source;
  if (!input.ros_bag.file.empty())
    source = createRosBagSource(input);
  else if (input.type == InputConfig::Type::PCD_FILES)
    source = std::make_unique<PCDFileSource>(input);
  else
    source = std::make_unique<StereoSequenceSource>(input);
  if (input.repeat_count > 1)
    source = std::make_unique<RepeatedSource>(
      std::move(source), static_cast<std::size_t>(input.repeat_count),
      Eigen::Vector3d(input.repeat_offset_m[0], input.repeat_offset_m[1],
                      input.repeat_offset_m[2]));
  return source;
}

} // namespace planar_grid
