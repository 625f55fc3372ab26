// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/stereo/calibration_io.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>

#include <glob.h>
#include <opencv2/imgcodecs.hpp>

#include <algorithm>
#include <filesystem>
#include <iomanip>
#include <sstream>

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

private:
  std::string pattern_, prefix_, suffix_;
  int width_{0};
  char fill_{'0'};
};

cv::Mat
readImage(const std::string& path)
{
  std::error_code ec;
  if (!fs::exists(path, ec))
    throw IOError(path + ": image not found");
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
};

class StereoSequenceSource : public FrameSourceBase {
public:
  explicit StereoSequenceSource(const InputConfig& input) :
      left_(input.left_images), right_(input.right_images),
      first_index_(input.first_index)
  {
    const CalibrationFormat format =
      calibrationFormatFromString(input.calibration_format);
    model_ = loadStereoCalibration(format, input.calibration_file,
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

    if (input.poses_format == "karlsruhe_insdata") {
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
    } else if (input.poses_format == "kitti")
      poses_ = loadKittiPoses(input.poses_file);
    if (input.poses_format == "euroc_groundtruth")
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
    description_ =
      std::to_string(count_) + " stereo pairs " + left_.format(first_index_)
      + " ... (f = " + std::to_string(model_.calibration.focal_length_px)
      + " px, B = " + std::to_string(model_.calibration.baseline_m) + " m)";
  }

  std::size_t size() const override { return count_; }

  void load(std::size_t i, Frame& frame) const override
  {
    const int index = first_index_ + static_cast<int>(i);
    const std::string left_path = left_.format(index);
    const std::string right_path = right_.format(index);
    cv::Mat left = readImage(left_path);
    cv::Mat right = readImage(right_path);
    if (left.size() != right.size())
      throw IOError(right_path + ": size " + std::to_string(right.cols) + "x"
                    + std::to_string(right.rows) + " differs from the left image's "
                    + std::to_string(left.cols) + "x" + std::to_string(left.rows));
    const auto& calib = model_.calibration;
    if (model_.rectifier.empty() && calib.width > 0 && calib.height > 0
        && (left.cols != calib.width || left.rows != calib.height))
      throw IOError(left_path + ": size " + std::to_string(left.cols) + "x"
                    + std::to_string(left.rows) + " differs from the calibration's "
                    + std::to_string(calib.width) + "x" + std::to_string(calib.height));
    if (!model_.rectifier.empty()) {
      if (left.size() != model_.rectifier.map_left_x.size())
        throw IOError(left_path + ": size differs from the calibration's image size");
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
};

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
    if (input.poses_format == "kitti") {
      poses_ = loadKittiPoses(input.poses_file);
      if (poses_.size() < files_.size())
        throw IOError(input.poses_file + ": has " + std::to_string(poses_.size())
                      + " poses, but there are " + std::to_string(files_.size())
                      + " PCD files");
      poses_.resize(files_.size());
    } else if (input.poses_format == "viewpoint") {
      for (const auto& f : files_)
        poses_.push_back(loadPCDViewpoint(f));
    }
    description_ =
      std::to_string(files_.size()) + " PCD files " + files_.front() + " ...";
  }

  std::size_t size() const override { return files_.size(); }

  void load(std::size_t i, Frame& frame) const override
  {
    const std::string& path = files_[i];
    Frame::Cloud::Ptr cloud(new Frame::Cloud);
    // Read the blob first: PCL's conversion indexes point 0 of an empty cloud (UB that
    // UBSan reports), so a PCD without points is converted only when it has some.
    pcl::PCLPointCloud2 blob;
    if (pcl::io::loadPCDFile(path, blob) < 0)
      throw IOError(path + ": cannot read the PCD file");
    if (static_cast<std::size_t>(blob.width) * blob.height > 0)
      pcl::fromPCLPointCloud2(blob, *cloud);
    frame = Frame();
    frame.sequence_number = i;
    frame.file_index = static_cast<int>(i);
    frame.name = fs::path(path).filename().string();
    // The points are in the sensor frame; the VIEWPOINT is the sensor pose (PCL).
    cloud->sensor_origin_ = Eigen::Vector4f(0, 0, 0, 1);
    cloud->sensor_orientation_ = Eigen::Quaternionf::Identity();
    frame.cloud = cloud;
    assignPose(i, frame);
  }

private:
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

private:
  std::unique_ptr<FrameSource> source_;
  std::size_t count_;
  Eigen::Vector3d offset_m_;
  Trajectory poses_;
  std::string description_;
};

std::unique_ptr<FrameSource>
createFrameSource(const InputConfig& input)
{
  std::unique_ptr<FrameSource> source;
  if (input.type == InputConfig::Type::PCD_FILES)
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
