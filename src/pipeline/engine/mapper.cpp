// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/stereo_pair_check.h>

#include <pcl/common/io.h>
#include <pcl/console/print.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <utility>

#include "stage_run.h"

namespace planar_grid {

namespace {

double
msSince(std::chrono::steady_clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t)
    .count();
}

bool
contains(const std::vector<StageData>& data, StageData d)
{
  return std::find(data.begin(), data.end(), d) != data.end();
}

/** The frames a mapper takes, in messages. */
std::string
inputName(bool stereo)
{
  return stereo ? "stereo pairs (a stage of it reads stereo images)"
                : "point clouds (no stage of it reads stereo images)";
}

/** The value of counter \a name in \a counters, 0 when absent. */
double
counterValue(const std::vector<std::pair<std::string, double>>& counters,
             const std::string& name)
{
  for (const auto& [key, value] : counters)
    if (key == name)
      return value;
  return 0.0;
}

} // namespace

Mapper::Mapper(const MapperConfig& config) : Mapper(config, StageChecks::LIVE) {}

Mapper::Mapper(const MapperConfig& config, StageChecks checks) : config_(config)
{
  if (checks == StageChecks::PIPELINE) {
    // The loader checked the stages against the input and filled in their parameters.
    for (const StageSpec& spec : config_.stages)
      addStage(spec, *findStage(spec.type));
    // Starting a stage may change what the process shares (e.g. OpenCV's thread
    // count), so the stages start with the run, at reset().
    return;
  }
  // Every stage's needs must come from the frames or an earlier stage; the poses come
  // with the frames unless a stage estimates them, which integrate() checks per frame.
  std::vector<const StageInfo*> infos;
  for (const StageSpec& spec : config_.stages) {
    const StageInfo* info = findStage(spec.type);
    if (!info)
      throw ConfigError(config_.name, spec.line, spec.column,
                        "unknown stage type '" + spec.type
                          + "'; known types: " + knownStageTypes());
    infos.push_back(info);
    takes_stereo_ = takes_stereo_ || contains(info->needs, StageData::STEREO_IMAGES);
  }
  std::vector<StageData> available{
    takes_stereo_ ? StageData::STEREO_IMAGES : StageData::CLOUD, StageData::POSES};
  bool has_map = false;
  for (std::size_t s = 0; s < config_.stages.size(); ++s) {
    StageSpec& spec = config_.stages[s];
    const StageInfo& info = *infos[s];
    // The keys the spec leaves out take the table's defaults.
    ParamValues params = defaultParams(info.params);
    for (const auto& [key, value] : spec.params.values()) {
      if (params.values().count(key) == 0)
        throw ConfigError(config_.name, spec.line, spec.column,
                          "stage '" + spec.type + "' has no parameter '" + key
                            + "'; its parameters:\n" + describeParams(info.params));
      params.set(key, value);
    }
    spec.params = std::move(params);
    for (const StageNeed& need : stageNeeds(info, spec.params))
      if (!contains(available, need.data))
        throw ConfigError(config_.name, spec.line, spec.column,
                          "stage '" + spec.type + "' needs " + stageDataName(need.data)
                            + ", which neither the frames nor an earlier stage give"
                            + (need.param.empty()
                                 ? std::string()
                                 : "; or use " + need.param + ": " + need.alternative));
    for (const StageData d : info.produces)
      available.push_back(d);
    addStage(spec, info);
    has_map = has_map || writes_map_.back();
  }
  if (!has_map)
    throw Exception("Mapper: " + pipelineName()
                    + " has no map_integration stage, so it builds no map");
  start();
}

Mapper::~Mapper() = default;

void
Mapper::addStage(const StageSpec& spec, const StageInfo& info)
{
  stages_.push_back(
    stages::createStage(spec.type, spec.params, config_.name, spec.line, spec.column));
  writes_map_.push_back(contains(info.produces, StageData::MAP));
  takes_stereo_ = takes_stereo_ || contains(info.needs, StageData::STEREO_IMAGES);
  estimates_poses_ = estimates_poses_ || contains(info.produces, StageData::POSES);
  needs_poses_ = needs_poses_ || contains(info.needs, StageData::POSES);
}

std::string
Mapper::pipelineName() const
{
  return config_.name.empty() ? std::string("the mapper's pipeline")
                              : "the pipeline of " + config_.name;
}

void
Mapper::start()
{
  stage_reports_.clear();
  for (const StageSpec& spec : config_.stages) {
    StageReport sr;
    sr.type = spec.type;
    stage_reports_.push_back(sr);
  }
  state_ = PipelineState();
  trajectory_.clear();
  for (auto& stage : stages_)
    stage->start(state_);
  started_ = true;
}

void
Mapper::requireInput(bool stereo, const char* call) const
{
  if (takes_stereo_ != stereo)
    throw Exception(std::string("Mapper::") + call + ": " + pipelineName() + " takes "
                    + inputName(takes_stereo_) + ", not " + inputName(stereo));
}

FrameStats
Mapper::integrateStereo(const cv::Mat& left,
                        const cv::Mat& right,
                        const StereoCalibration& calibration,
                        const Eigen::Isometry3d& world_T_camera)
{
  return integrateStereoPair(left, right, calibration, &world_T_camera);
}

FrameStats
Mapper::integrateStereo(const cv::Mat& left,
                        const cv::Mat& right,
                        const StereoCalibration& calibration)
{
  return integrateStereoPair(left, right, calibration, nullptr);
}

FrameStats
Mapper::integrateStereoPair(const cv::Mat& left,
                            const cv::Mat& right,
                            const StereoCalibration& calibration,
                            const Eigen::Isometry3d* world_T_camera)
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  requireInput(true, "integrateStereo");
  const auto size = [](const cv::Mat& image) {
    return std::to_string(image.cols) + "x" + std::to_string(image.rows) + " px";
  };
  if (left.empty() || right.empty())
    throw Exception(std::string("Mapper::integrateStereo: the ")
                    + (left.empty() ? "left" : "right") + " image is empty");
  if (left.type() != CV_8UC1 || right.type() != CV_8UC1)
    throw Exception("Mapper::integrateStereo: the images must be 8-bit grey "
                    "(CV_8UC1, numpy uint8 of shape (H, W))");
  if (left.size() != right.size())
    throw Exception("Mapper::integrateStereo: the right image's size " + size(right)
                    + " differs from the left image's " + size(left));
  if (calibration.width > 0 && calibration.height > 0
      && (left.cols != calibration.width || left.rows != calibration.height))
    throw Exception("Mapper::integrateStereo: the images' size " + size(left)
                    + " differs from the calibration's "
                    + std::to_string(calibration.width) + "x"
                    + std::to_string(calibration.height) + " px");
  // The calibration files of some inputs (Karlsruhe's) give no image size: the
  // principal point then tells images of another camera.
  if ((calibration.width <= 0 || calibration.height <= 0)
      && !(calibration.cx_px >= 0.0 && calibration.cx_px < left.cols
           && calibration.cy_px >= 0.0 && calibration.cy_px < left.rows))
    throw Exception("Mapper::integrateStereo: the calibration's principal point ("
                    + std::to_string(calibration.cx_px) + ", "
                    + std::to_string(calibration.cy_px) + ") px lies outside the "
                    + size(left) + " images");
  // The stages that track features or estimate motion compare frame with frame.
  if (frames_ > 0 && left.size() != image_size_)
    throw Exception("Mapper::integrateStereo: the images' size " + size(left)
                    + " differs from the earlier frames' "
                    + std::to_string(image_size_.width) + "x"
                    + std::to_string(image_size_.height) + " px");
  try {
    calibration.validate("the calibration");
  } catch (const IOError& e) {
    throw Exception(std::string("Mapper::integrateStereo: ") + e.what());
  }
  if (frames_ == 0) {
    const std::string off_centre = calibration.principalPointWarning(
      left.cols, left.rows, "Mapper::integrateStereo");
    if (!off_centre.empty())
      PCL_WARN("[planar_grid::Mapper] %s\n", off_centre.c_str());
    // Swapped or doubled images would be mapped frame after frame into next to nothing.
    try {
      checkStereoPairOrder(left, right, "the left image", "the right image",
                           "pass the images the other way round");
    } catch (const IOError& e) {
      throw Exception(std::string("Mapper::integrateStereo: ") + e.what());
    }
  }
  image_size_ = left.size();
  Frame frame;
  // The stages read the images and never write them: no copy.
  frame.left = left;
  frame.right = right;
  frame.calibration = calibration;
  return integrate(frame, world_T_camera);
}

FrameStats
Mapper::integrateCloud(const PointCloud& cloud, const Eigen::Isometry3d& world_T_sensor)
{
  Frame::Cloud::Ptr working(new Frame::Cloud);
  // As a PCD file with bare x, y, z is read (intensity 0).
  pcl::copyPointCloud(cloud, *working);
  return integrateCloud(*working, world_T_sensor);
}

FrameStats
Mapper::integrateCloud(const Frame::Cloud& cloud,
                       const Eigen::Isometry3d& world_T_sensor)
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  requireInput(false, "integrateCloud");
  if (cloud.empty())
    throw Exception("Mapper::integrateCloud: the cloud is empty");
  Frame frame;
  frame.cloud.reset(new Frame::Cloud(cloud));
  // The points are in the sensor frame; the pose is world_T_sensor.
  frame.cloud->sensor_origin_ = Eigen::Vector4f(0, 0, 0, 1);
  frame.cloud->sensor_orientation_ = Eigen::Quaternionf::Identity();
  return integrate(frame, &world_T_sensor);
}

FrameStats
Mapper::integrateDepth(const cv::Mat& depth,
                       const PinholeView& camera,
                       const Eigen::Isometry3d& world_T_camera)
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  requireInput(false, "integrateDepth");
  if (depth.empty())
    throw Exception("Mapper::integrateDepth: the depth image is empty");
  if (depth.type() != CV_16UC1 && depth.type() != CV_32FC1)
    throw Exception("Mapper::integrateDepth: the depth image must be CV_16UC1 "
                    "(millimeters) or CV_32FC1 (meters), not type "
                    + std::to_string(depth.type()));
  if (depth.cols != camera.width_px || depth.rows != camera.height_px)
    throw Exception("Mapper::integrateDepth: the depth image is "
                    + std::to_string(depth.cols) + " x " + std::to_string(depth.rows)
                    + " px, the camera " + std::to_string(camera.width_px) + " x "
                    + std::to_string(camera.height_px) + " px");
  const auto positive = [](double v) {
    return std::isfinite(v) && v > 0.0;
  };
  if (!positive(camera.fx_px) || !positive(camera.fy_px) || !std::isfinite(camera.cx_px)
      || !std::isfinite(camera.cy_px))
    throw Exception("Mapper::integrateDepth: the camera's focal lengths must be "
                    "positive and its principal point finite (px)");

  // The organized cloud of the image, pixel (u, v) at index v * width + u.
  Frame frame;
  frame.cloud.reset(new Frame::Cloud(static_cast<std::uint32_t>(depth.cols),
                                     static_cast<std::uint32_t>(depth.rows)));
  frame.cloud->is_dense = false;
  const float fx = static_cast<float>(camera.fx_px);
  const float fy = static_cast<float>(camera.fy_px);
  const float cx = static_cast<float>(camera.cx_px);
  const float cy = static_cast<float>(camera.cy_px);
  const float nan = std::numeric_limits<float>::quiet_NaN();
  bool any_valid = false;
  for (int v = 0; v < depth.rows; ++v) {
    for (int u = 0; u < depth.cols; ++u) {
      const float z = depth.type() == CV_16UC1
                        ? 0.001f * static_cast<float>(depth.at<std::uint16_t>(v, u))
                        : depth.at<float>(v, u);
      pcl::PointXYZI& p = frame.cloud->at(u, v);
      p.intensity = 0.0f;
      if (!(z > 0.0f) || !std::isfinite(z)) {
        p.x = p.y = p.z = nan;
        continue;
      }
      p.x = (static_cast<float>(u) - cx) * z / fx;
      p.y = (static_cast<float>(v) - cy) * z / fy;
      p.z = z;
      any_valid = true;
    }
  }
  if (!any_valid)
    throw Exception("Mapper::integrateDepth: the depth image has no valid pixel");
  frame.cloud->sensor_origin_ = Eigen::Vector4f(0, 0, 0, 1);
  frame.cloud->sensor_orientation_ = Eigen::Quaternionf::Identity();
  frame.depth_camera = camera;
  return integrate(frame, &world_T_camera);
}

FrameStats
Mapper::integrate(Frame& frame, const Eigen::Isometry3d* world_T_camera)
{
  const auto start = std::chrono::steady_clock::now();
  if (world_T_camera && estimates_poses_)
    throw Exception("Mapper: " + pipelineName()
                    + " estimates the poses (visual_odometry stage), which would "
                      "replace the pose given; call without world_T_camera");
  if (!world_T_camera && needs_poses_ && !estimates_poses_)
    throw Exception("Mapper: no pose given, and " + pipelineName()
                    + " has no visual_odometry stage to estimate it: pass "
                      "world_T_camera");
  frame.has_pose = world_T_camera != nullptr;
  if (world_T_camera)
    frame.world_T_camera = *world_T_camera;
  const std::size_t sequence_number = frames_.load();
  frame.sequence_number = sequence_number;
  frame.file_index = static_cast<int>(sequence_number);
  frame.name = "#" + std::to_string(sequence_number);

  const std::vector<StageReport> before = stage_reports_;
  StageProgress progress;
  runStages(frame, progress, StageCallback());

  FrameStats stats;
  stats.sequence_number = frame.sequence_number;
  const std::vector<StageReport>& after = stage_reports_;
  for (std::size_t s = 0; s < after.size(); ++s) {
    const StageReport& a = after[s];
    const StageReport& b = before[s];
    FrameStageStats st;
    st.type = a.type;
    st.ms = a.total_ms - b.total_ms;
    st.cpu_ms = a.cpu_ms - b.cpu_ms;
    st.points_in = a.points_in - b.points_in;
    st.points_out = a.points_out - b.points_out;
    for (const auto& [name, value] : a.counters)
      st.counters.emplace_back(name, value - counterValue(b.counters, name));
    stats.stages.push_back(std::move(st));
  }
  stats.planes = frame.planes.size();
  stats.cuboids = frame.cuboids.size();
  stats.world_T_camera = frame.world_T_camera;
  // Only this thread changes the map, and its queries are safe beside the readers'.
  stats.map_cells = state_.map->getSurfaceLayer().getCellCount();
  stats.lock_wait_ms = lock_wait_ms_;
  stats.exclusive_ms = exclusive_ms_;
  stats.total_ms = msSince(start);
  return stats;
}

void
Mapper::runStages(Frame& frame, StageProgress& progress, const StageCallback& callback)
{
  lock_wait_ms_ = 0.0;
  exclusive_ms_ = 0.0;
  // Readers are locked out from the first stage that changes the map to the first
  // stage after it that does not (or the end of the frame); every stage runs on this
  // thread, right after this callback.
  const stages::StageCallback lock_map = [this, &callback](std::size_t s, Frame& f) {
    if (writes_map_[s] && !write_lock_.owns_lock()) {
      const auto t = std::chrono::steady_clock::now();
      write_lock_.lock();
      locked_at_ = std::chrono::steady_clock::now();
      lock_wait_ms_ +=
        std::chrono::duration<double, std::milli>(locked_at_ - t).count();
    } else if (!writes_map_[s] && write_lock_.owns_lock()) {
      exclusive_ms_ += msSince(locked_at_);
      write_lock_.unlock();
    }
    if (callback)
      callback(s, f);
  };
  const std::size_t first = progress.stages.size();
  progress.stages.reserve(stages_.size());
  try {
    for (std::size_t s = first; s < stages_.size(); ++s)
      stages::runStage(*stages_[s], s, config_.stages[s].type, lock_map, frame, state_,
                       frame.sequence_number, progress);
  } catch (...) {
    if (write_lock_.owns_lock())
      write_lock_.unlock();
    throw;
  }
  if (write_lock_.owns_lock()) {
    exclusive_ms_ += msSince(locked_at_);
    write_lock_.unlock();
  }
  for (std::size_t s = 0; s < progress.stages.size(); ++s)
    stage_reports_[s].add(progress.stages[s]);
  // After the stages: visual_odometry sets the pose of frames given none.
  if (frame.has_pose)
    trajectory_.push_back(frame.world_T_camera);
  ++frames_;
}

std::size_t
Mapper::getFrameLocalStageCount() const
{
  std::size_t front = 0;
  while (front < stages_.size() && stages_[front]->isFrameLocal())
    ++front;
  return front;
}

void
Mapper::prepareFrame(Frame& frame,
                     std::size_t stage_end,
                     StageProgress& progress,
                     const StageCallback& callback)
{
  if (stage_end > getFrameLocalStageCount())
    throw Exception("Mapper::prepareFrame: stage " + std::to_string(stage_end - 1)
                    + " is past the " + std::to_string(getFrameLocalStageCount())
                    + " leading frame-local stages of " + pipelineName());
  // Those stages touch nothing but their frame: the state they are given is never
  // read, and it is not the one integrateFrame() changes on the other thread.
  for (std::size_t s = progress.stages.size(); s < stage_end; ++s)
    stages::runStage(*stages_[s], s, config_.stages[s].type, callback, frame,
                     unused_state_, frame.sequence_number, progress);
}

void
Mapper::integrateFrame(Frame& frame,
                       StageProgress& progress,
                       const StageCallback& callback)
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  if (!started_)
    throw Exception("Mapper::integrateFrame: the stages of " + pipelineName()
                    + " have not started; call reset() before the first frame");
  runStages(frame, progress, callback);
}

std::vector<double>
Mapper::finish()
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  std::vector<double> ms(stages_.size(), 0.0);
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    const auto t = std::chrono::steady_clock::now();
    stages_[s]->finish(state_);
    ms[s] = msSince(t);
  }
  return ms;
}

std::vector<std::vector<std::uint8_t>>
Mapper::saveStageStates() const
{
  std::vector<std::vector<std::uint8_t>> states(stages_.size());
  for (std::size_t s = 0; s < stages_.size(); ++s)
    stages_[s]->saveState(states[s]);
  return states;
}

void
Mapper::resume(PipelineState state,
               Trajectory trajectory,
               const std::vector<std::vector<std::uint8_t>>& stage_states,
               std::size_t frames)
{
  if (stage_states.size() != stages_.size())
    throw Exception("Mapper::resume: " + std::to_string(stage_states.size())
                    + " stage states for the " + std::to_string(stages_.size())
                    + " stages of " + pipelineName());
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  const std::unique_lock<WriterPreferringSharedMutex> lock(map_mutex_);
  state_ = std::move(state);
  trajectory_ = std::move(trajectory);
  for (std::size_t s = 0; s < stages_.size(); ++s)
    stages_[s]->loadState(stage_states[s].data(), stage_states[s].size());
  frames_ = frames;
}

Mapper::MapReader
Mapper::readMap() const
{
  return MapReader(map_mutex_, state_.map);
}

void
Mapper::save(const std::string& path) const
{
  readMap()->save(path);
}

void
Mapper::reset()
{
  const std::lock_guard<std::mutex> frame_lock(frame_mutex_);
  const std::unique_lock<WriterPreferringSharedMutex> lock(map_mutex_);
  start();
  frames_ = 0;
}

} // namespace planar_grid
