// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_runner.h>
#include <planar_grid/version.h>

#include <pcl/common/time.h>

#include <nlohmann/json.hpp>
#include <sys/resource.h>
#include <time.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <condition_variable>
#include <deque>
#include <filesystem>
#include <fstream>
#include <functional>
#include <future>
#include <iomanip>
#include <memory>
#include <mutex>
#include <sstream>
#include <thread>

#include "resume_data.h"

namespace planar_grid {

namespace {

/** \a value for report.json: an integer when \a is_count and \a value is a whole number
 * a double holds exactly (every count is), else a float. */
nlohmann::ordered_json
reportNumber(double value, bool is_count)
{
  if (is_count && std::isfinite(value) && value == std::floor(value)
      && std::fabs(value) <= 9007199254740992.0) // 2^53
    return static_cast<std::int64_t>(value);
  return value;
}

/** Whether the figure \a name (a Stage::counters name or a map summary name) is a count
 * (features, inliers, cells, bytes, ...); the others are measures: lengths in metres
 * (names ending in "_m") and the KL filter's probability and motion likelihood. */
bool
isCountName(const std::string& name)
{
  const bool metres = name.size() >= 2 && name.compare(name.size() - 2, 2, "_m") == 0;
  return !metres && name != "mean_probability" && name != "motion_likelihood";
}

/** Resident memory of the process now (/proc/self/statm), bytes; 0 when unknown. */
std::uint64_t
residentMemoryBytes()
{
  std::ifstream statm("/proc/self/statm");
  std::uint64_t size = 0, resident = 0;
  if (!(statm >> size >> resident))
    return 0;
  return resident * static_cast<std::uint64_t>(::sysconf(_SC_PAGESIZE));
}

/** Peak resident memory of the process (getrusage ru_maxrss, KiB on Linux), bytes. */
std::uint64_t
peakResidentMemoryBytes()
{
  struct rusage usage {};
  if (::getrusage(RUSAGE_SELF, &usage) != 0)
    return 0;
  return static_cast<std::uint64_t>(usage.ru_maxrss) * 1024u;
}

/** CPU time of the whole process (user and system, every thread), milliseconds. */
double
processCpuMs()
{
  struct rusage usage {};
  if (::getrusage(RUSAGE_SELF, &usage) != 0)
    return 0.0;
  const auto ms = [](const timeval& t) {
    return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_usec) * 1e-3;
  };
  return ms(usage.ru_utime) + ms(usage.ru_stime);
}

/** A loaded frame after the leading frame-local stages. */
struct PreparedFrame {
  Frame frame;
  /** What the stages did to it so far. */
  StageProgress progress;
  double load_ms{0.0};
  /** CPU time of the thread that loaded the frame and ran those stages. */
  double cpu_ms{0.0};
};

/** Adds frame \a i's stage samples to \a report and calls \a callback with each
 * stage's milliseconds (the mapper has added the frame's pose to its trajectory). */
void
endFrame(RunReport& report,
         const PipelineRunner::FrameCallback& callback,
         std::size_t i,
         Frame& frame,
         const std::vector<FrameStageStats>& samples)
{
  for (std::size_t s = 0; s < samples.size(); ++s)
    report.stages[s].add(samples[s]);
  ++report.frames;
  if (callback) {
    std::vector<double> ms(samples.size());
    for (std::size_t s = 0; s < samples.size(); ++s)
      ms[s] = samples[s].ms;
    callback(i, frame, ms);
  }
}

double
msSince(std::chrono::steady_clock::time_point t)
{
  return std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - t)
    .count();
}

/** One thread that runs the submitted tasks in order, one at a time; the destructor
 * runs the tasks still queued, then joins. */
class SerialWorker {
public:
  using Result = std::unique_ptr<PreparedFrame>;

  SerialWorker() : thread_([this]() { loop(); }) {}
  SerialWorker(const SerialWorker&) = delete;
  SerialWorker& operator=(const SerialWorker&) = delete;
  ~SerialWorker()
  {
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      stopping_ = true;
    }
    wake_.notify_one();
    thread_.join();
  }

  /** Queues \a task; its result (or exception) arrives through the future. */
  std::future<Result> submit(std::function<Result()> task)
  {
    std::packaged_task<Result()> packaged(std::move(task));
    std::future<Result> result = packaged.get_future();
    {
      const std::lock_guard<std::mutex> lock(mutex_);
      tasks_.push_back(std::move(packaged));
    }
    wake_.notify_one();
    return result;
  }

private:
  void loop()
  {
    for (;;) {
      std::packaged_task<Result()> task;
      {
        std::unique_lock<std::mutex> lock(mutex_);
        wake_.wait(lock, [this]() { return stopping_ || !tasks_.empty(); });
        if (tasks_.empty())
          return;
        task = std::move(tasks_.front());
        tasks_.pop_front();
      }
      task();
    }
  }

  std::mutex mutex_;
  std::condition_variable wake_;
  std::deque<std::packaged_task<Result()>> tasks_;
  bool stopping_{false};
  std::thread thread_; // last: started once the members above exist
};

/** The number of leading stages to run ahead from now on: \a ahead, or one fewer when
 * moving the last of them to the mapping thread shortens the longer of the two
 * threads' mean frame times by more than a millisecond (after a few frames, so that
 * start-up costs do not decide). */
std::size_t
balancedReadAhead(const RunReport& report, std::size_t ahead)
{
  constexpr std::size_t MIN_FRAMES = 8;
  constexpr double MIN_GAIN_MS = 1.0;
  if (ahead <= 1 || report.frames < MIN_FRAMES)
    return ahead;
  const auto mean = [&report](std::size_t s) {
    const StageReport& sr = report.stages[s];
    return sr.frames ? sr.total_ms / static_cast<double>(sr.frames) : 0.0;
  };
  double front = report.load_ms / static_cast<double>(report.frames), back = 0.0;
  for (std::size_t s = 0; s < report.stages.size(); ++s)
    (s < ahead ? front : back) += mean(s);
  const double moved = mean(ahead - 1);
  return std::max(front - moved, back + moved) + MIN_GAIN_MS < std::max(front, back)
           ? ahead - 1
           : ahead;
}

} // namespace

PipelineRunner::PipelineRunner(const PipelineConfig& config, FrameSupply supply) :
    config_(config), mapper_(std::make_unique<Mapper>(toMapperConfig(config_),
                                                      Mapper::StageChecks::PIPELINE))
{
  if (supply == FrameSupply::INPUT) {
    source_ = createFrameSource(config_.input);
    end_ = source_->size();
  }
}

PipelineRunner::~PipelineRunner() = default;

FrameSource&
PipelineRunner::input(const std::string& what) const
{
  if (!source_)
    throw Exception("PipelineRunner::" + what
                    + " needs the input, and this runner takes the caller's frames");
  return *source_;
}

std::size_t
PipelineRunner::frameCount() const
{
  return input("frameCount()").size();
}

std::vector<InputFile>
PipelineRunner::inputFiles() const
{
  std::vector<InputFile> files = input("inputFiles()").files();
  std::error_code ec;
  // A configuration parsed from text names its source without being a file.
  if (std::filesystem::is_regular_file(config_.source_file, ec))
    files.insert(files.begin(),
                 InputFile{config_.source_file, "the configuration file"});
  return files;
}

void
PipelineRunner::setFrameRange(std::size_t begin, std::size_t end, std::size_t step)
{
  const std::size_t size = input("setFrameRange()").size();
  if (begin >= end)
    throw Exception("the frame range " + std::to_string(begin) + ":"
                    + std::to_string(end) + " is empty");
  if (end > size)
    throw Exception("the frame range " + std::to_string(begin) + ":"
                    + std::to_string(end) + " goes past the input's "
                    + std::to_string(size) + " frames");
  if (step == 0)
    throw Exception("the frame step must be at least 1");
  if (resume_ && begin != begin_)
    throw Exception(
      "the frame range " + std::to_string(begin) + ":" + std::to_string(end)
      + " does not start where the checkpoint's run " + "started (frame position "
      + std::to_string(begin_) + "); set the range before resumeFrom()");
  begin_ = begin;
  end_ = end;
  step_ = step;
}

void
PipelineRunner::start()
{
  run_start_ = std::chrono::steady_clock::now();
  previous_seconds_ = 0.0;
  report_ = RunReport();
  report_.config_file = config_.source_file;
  report_.input_description =
    source_ ? source_->describe() : std::string("frames supplied by the caller");
  report_.first_frame = begin_;
  for (const auto& sc : config_.stages) {
    StageReport sr;
    sr.type = sc.type;
    report_.stages.push_back(sr);
  }
  mapper_->reset();
}

void
PipelineRunner::processFrame(Frame& frame)
{
  StageProgress progress;
  mapper_->integrateFrame(frame, progress, stage_callback_);
  endFrame(report_, frame_callback_, frame.sequence_number, frame, progress.stages);
}

MemoryEstimate
PipelineRunner::estimateMemory() const
{
  const FrameSource& source = input("estimateMemory()");
  StereoCalibration calibration;
  PinholeView view;
  const bool has_camera = source.camera(calibration);
  if (has_camera) {
    view.width_px = calibration.width;
    view.height_px = calibration.height;
    view.fx_px = view.fy_px = calibration.focal_length_px;
    view.cx_px = calibration.cx_px;
    view.cy_px = calibration.cy_px;
  }
  Trajectory poses;
  std::size_t frames = 0;
  for (std::size_t i = begin_; i < end_; i += step_) {
    ++frames;
    if (i < source.poses().size())
      poses.push_back(source.poses()[i]);
  }
  if (poses.size() != frames) // poses made during the run (odometry, registration)
    poses.clear();
  return estimateRunMemory(config_, has_camera ? &view : nullptr, poses, frames);
}

RunReport
PipelineRunner::run()
{
  using Clock = std::chrono::steady_clock;
  FrameSource& source = input("run()");
  if (step_ != 1 && (checkpoint_every_ > 0 || resume_))
    throw Exception("checkpoints need every frame of the range (frame step 1, not "
                    + std::to_string(step_) + ")");
  if (memory_limit_.bytes > 0)
    checkMemoryEstimate(estimateMemory(), memory_limit_);
  start();

  std::size_t first = begin_;
  frame_stamps_.clear();
  frame_stamps_until_ = 0;
  if (resume_) {
    // A resumed run: the state and the report as they were after the checkpoint's
    // frame.
    ResumeData& resume = *resume_;
    report_.frames = resume.report.frames;
    report_.load_ms = resume.report.load_ms;
    report_.stages = std::move(resume.report.stages);
    report_.rss_samples = std::move(resume.report.rss_samples);
    report_.checkpoints_written = resume.report.checkpoints_written;
    previous_seconds_ = resume.report.seconds;
    mapper_->resume(std::move(resume.state), std::move(resume.trajectory),
                    resume.stage_states, resume.report.frames);
    first = resume.next_frame;
    report_.resumed_at_frame = first;
    if (!resume.frame_stamps.empty()) {
      frame_stamps_ = std::move(resume.frame_stamps);
      frame_stamps_until_ = first;
    }
    resume_.reset();
  }

  const std::size_t total = (end_ - begin_ + step_ - 1) / step_;
  const std::size_t rss_every = std::max<std::size_t>(total / 20, 1);
  // Frames i + 1 and i + 2 are loaded and go through the leading frame-local stages on
  // a second thread while frame i goes through the rest here. Those stages touch
  // nothing but their frame (no PipelineState: the empty state below is never read),
  // and each runs its frames in order, one frame at a time, so the results equal a
  // sequential run's. How many of them run ahead is balanced by their measured times:
  // it starts at all of them and only shrinks, so a stage that frame i runs here (s >=
  // its count) is never one that a later frame runs on the other thread at the same
  // time.
  std::size_t ahead = frameLocalPrefix();
  // One prepare() runs at a time: each waits for the previous.
  const auto prepare = [this, &source](std::size_t i, std::size_t n) {
    auto prepared = std::make_unique<PreparedFrame>();
    const double cpu_start = threadCpuMs();
    const auto load_start = Clock::now();
    source.load(i, prepared->frame);
    prepared->frame.sequence_number = i;
    prepared->load_ms = msSince(load_start);
    mapper_->prepareFrame(prepared->frame, n, prepared->progress, stage_callback_);
    prepared->cpu_ms = threadCpuMs() - cpu_start;
    return prepared;
  };
  // Up to READ_AHEAD_FRAMES frames are prepared ahead, one after the other on one
  // worker thread, so that the read-ahead stages still see one frame at a time, in
  // order. Two frames let the worker run on while the frame it prepared waits for the
  // mapping thread, which evens out frames of unequal cost (e.g. stereo_disparity's
  // every_n_frames). One thread for all frames keeps to one more malloc arena than a
  // sequential run (a thread per frame in flight would hold one each).
  constexpr std::size_t READ_AHEAD_FRAMES = 2;
  std::unique_ptr<SerialWorker> worker;
  const auto launch = [&prepare, &worker](std::size_t i, std::size_t n) {
    if (n == 0)
      return std::async(std::launch::deferred, prepare, i, n);
    if (!worker)
      worker = std::make_unique<SerialWorker>();
    return worker->submit([&prepare, i, n]() { return prepare(i, n); });
  };
  const double process_cpu_start = processCpuMs();
  // The frames launched and not yet mapped, in order, and whether each runs on the
  // other thread.
  std::deque<std::pair<std::future<std::unique_ptr<PreparedFrame>>, bool>> launched;
  std::size_t next_launch = first;
  const auto launchMore = [&]() {
    while (next_launch < end_ && launched.size() < READ_AHEAD_FRAMES) {
      launched.emplace_back(launch(next_launch, ahead), ahead > 0);
      next_launch += step_;
    }
  };
  launchMore();
  for (std::size_t i = first; i < end_; i += step_) {
    const auto wait_start = Clock::now();
    const std::unique_ptr<PreparedFrame> prepared = launched.front().first.get();
    if (launched.front().second)
      report_.mapping_wait_ms += msSince(wait_start);
    launched.pop_front();
    const double mapping_cpu_start = threadCpuMs();
    const bool last = i + step_ >= end_;
    launchMore();
    Frame& frame = prepared->frame;
    report_.load_ms += prepared->load_ms;
    mapper_->integrateFrame(frame, prepared->progress, stage_callback_);
    endFrame(report_, frame_callback_, i, frame, prepared->progress.stages);
    ++report_.timed_frames;
    report_.read_ahead_cpu_ms += prepared->cpu_ms;
    report_.mapping_cpu_ms += threadCpuMs() - mapping_cpu_start;
    report_.process_cpu_ms = processCpuMs() - process_cpu_start;
    ahead = balancedReadAhead(report_, ahead);
    report_.read_ahead_stages = ahead;
    const std::size_t done = (i - begin_) / step_ + 1;
    if (done % rss_every == 0 || last)
      report_.rss_samples.emplace_back(i, residentMemoryBytes());
    const bool stop = !last && stop_ != nullptr && stop_->load();
    if (checkpoint_every_ > 0 && (done % checkpoint_every_ == 0 || last || stop)) {
      const auto t = Clock::now();
      ++report_.checkpoints_written;
      report_.seconds = previous_seconds_ + msSince(run_start_) / 1000.0;
      writeCheckpoint(i + 1, report_);
      report_.checkpoint_ms += msSince(t);
    }
    if (progress_)
      progress_(done, total, msSince(run_start_) / 1000.0);
    if (stop)
      throw Interrupted(
        "stopped on request after frame " + std::to_string(i) + " ("
        + std::to_string(done) + " of " + std::to_string(total) + " frames)"
        + (checkpoint_every_ > 0 ? "; the checkpoint " + checkpoint_path_
                                     + " holds it (resume from it to continue)"
                                 : ""));
  }
  return finish();
}

RunReport
PipelineRunner::finish()
{
  const std::vector<double> finish_ms = mapper_->finish();
  for (std::size_t s = 0; s < finish_ms.size(); ++s)
    report_.stages[s].total_ms += finish_ms[s];
  const PipelineState& state = mapper_->getState();
  report_.world_cloud_points = state.world_cloud ? state.world_cloud->size() : 0;
  report_.planes = state.planes->size();
  if (state.map) {
    const PlanarGridMap& map = *state.map;
    const auto& space = map.getSpaceLayer();
    const auto& surface = map.getSurfaceLayer();
    const PlanarCuboids cuboids = surface.getCuboids();
    std::size_t planar = 0;
    for (const auto& c : cuboids)
      planar += c.is_planar;
    const MapMemory memory = map.getMemory();
    report_.map_summary = {
      {"resolution_m", map.getResolution()},
      {"cuboids", static_cast<double>(cuboids.size())},
      {"planar_cuboids", static_cast<double>(planar)},
      {"planes", static_cast<double>(surface.getPlaneCount())},
      {"plane_cells", static_cast<double>(surface.getCellCount())},
      {"raster_cells", static_cast<double>(surface.getRasterCellCount())},
      {"free_voxels", static_cast<double>(space.getVoxelCount(SpaceState::FREE))},
      {"occupied_voxels",
       static_cast<double>(space.getVoxelCount(SpaceState::OCCUPIED))},
      {"unknown_voxels", static_cast<double>(space.getVoxelCount(SpaceState::UNKNOWN))},
      {"space_blocks", static_cast<double>(space.getBlockCount())},
      {"surface_bytes", static_cast<double>(memory.surface_bytes)},
      {"space_bytes", static_cast<double>(memory.space_bytes)},
      {"total_bytes", static_cast<double>(memory.total_bytes)},
    };
  }
  report_.peak_rss_bytes = peakResidentMemoryBytes();
  report_.seconds = previous_seconds_ + msSince(run_start_) / 1000.0;
  return report_;
}

std::size_t
PipelineRunner::frameLocalPrefix() const
{
  return overlap_ ? mapper_->getFrameLocalStageCount() : 0;
}

std::string
RunReport::toJson() const
{
  nlohmann::ordered_json j;
  j["schema_version"] = REPORT_SCHEMA_VERSION;
  j["planar_grid_version"] = PLANAR_GRID_VERSION_STRING;
  j["config_file"] = config_file;
  j["input"] = input_description;
  j["first_frame"] = first_frame;
  j["frames"] = frames;
  j["seconds"] = seconds;
  j["frames_per_second"] = framesPerSecond();
  j["load_ms_per_frame"] = frames ? load_ms / static_cast<double>(frames) : 0.0;
  j["read_ahead_stages"] = read_ahead_stages;
  const auto per_timed_frame = [this](double ms) {
    return timed_frames ? ms / static_cast<double>(timed_frames) : 0.0;
  };
  auto& jt = j["threads"] = nlohmann::ordered_json::object();
  jt["frames"] = timed_frames;
  jt["read_ahead_cpu_ms_per_frame"] = per_timed_frame(read_ahead_cpu_ms);
  jt["mapping_cpu_ms_per_frame"] = per_timed_frame(mapping_cpu_ms);
  jt["mapping_wait_ms_per_frame"] = per_timed_frame(mapping_wait_ms);
  jt["process_cpu_ms_per_frame"] = per_timed_frame(process_cpu_ms);
  j["world_cloud_points"] = world_cloud_points;
  j["planes"] = planes;
  auto& js = j["stages"] = nlohmann::ordered_json::array();
  for (const auto& s : stages) {
    nlohmann::ordered_json e;
    e["type"] = s.type;
    e["frames"] = s.frames;
    e["ms_per_frame"] = s.meanMs();
    e["max_ms"] = s.max_ms;
    e["total_ms"] = s.total_ms;
    e["cpu_ms_per_frame"] =
      s.cpu_frames ? s.cpu_ms / static_cast<double>(s.cpu_frames) : 0.0;
    e["points_in"] = s.points_in;
    e["points_out"] = s.points_out;
    for (const auto& [name, value] : s.counters) {
      e[name] = reportNumber(value, isCountName(name));
      e[name + "_per_frame"] = s.frames ? value / static_cast<double>(s.frames) : 0.0;
    }
    js.push_back(e);
  }
  auto& jmem = j["memory"] = nlohmann::ordered_json::object();
  jmem["peak_rss_bytes"] = peak_rss_bytes;
  auto& jsamples = jmem["rss_bytes_after_frame"] = nlohmann::ordered_json::array();
  for (const auto& [frame, bytes] : rss_samples)
    jsamples.push_back(nlohmann::ordered_json::array({frame, bytes}));
  if (resumed_at_frame > 0)
    j["resumed_at_frame"] = resumed_at_frame;
  j["checkpoints_written"] = checkpoints_written;
  j["checkpoint_ms"] = checkpoint_ms;
  if (!map_summary.empty()) {
    auto& jm = j["map"] = nlohmann::ordered_json::object();
    for (const auto& [name, value] : map_summary)
      jm[name] = reportNumber(value, isCountName(name));
  }
  if (!map_octomap_summary.empty()) {
    auto& jm = j["map_octomap"] = nlohmann::ordered_json::object();
    for (const auto& [name, value] : map_octomap_summary)
      jm[name] = reportNumber(value, true);
  }
  auto& jo = j["outputs"] = nlohmann::ordered_json::object();
  for (const auto& [kind, path] : outputs)
    jo[kind] = path;
  return j.dump(2) + "\n";
}

std::string
RunReport::timingTable() const
{
  std::ostringstream out;
  out << std::fixed;
  out << std::left << std::setw(30) << "stage" << std::right << std::setw(12)
      << "ms/frame" << std::setw(10) << "max ms" << std::setw(14) << "pts in/frame"
      << std::setw(15) << "pts out/frame" << std::setw(10) << "removed"
      << "\n";
  const auto per_frame = [](std::uint64_t v, std::size_t n) {
    return n ? static_cast<double>(v) / static_cast<double>(n) : 0.0;
  };
  out << std::left << std::setw(30) << "(load + rectify)" << std::right << std::setw(12)
      << std::setprecision(1) << (frames ? load_ms / static_cast<double>(frames) : 0.0)
      << "\n";
  double sum = 0.0;
  for (const auto& s : stages) {
    sum += s.meanMs();
    out << std::left << std::setw(30) << s.type << std::right << std::setw(12)
        << std::setprecision(1) << s.meanMs() << std::setw(10) << s.max_ms;
    if (s.points_in > 0 || s.points_out > 0) {
      const double removed =
        s.points_in
          ? 100.0
              * (1.0
                 - static_cast<double>(s.points_out) / static_cast<double>(s.points_in))
          : 0.0;
      out << std::setw(14) << std::setprecision(0) << per_frame(s.points_in, s.frames)
          << std::setw(15) << per_frame(s.points_out, s.frames) << std::setw(9)
          << std::setprecision(1) << removed << "%";
    } else
      out << std::setw(39) << "";
    // The stage's own figures, per frame (e.g. "480 features", "5.2 planes"); rare
    // events (below one per frame, e.g. flagged frames) as a total too, so that 2 in
    // 112 frames does not read as 0.0.
    for (const auto& [name, value] : s.counters) {
      const double mean = s.frames ? value / static_cast<double>(s.frames) : 0.0;
      out << "  " << std::setprecision(1) << mean << " " << name;
      if (mean < 1.0 && value > 0.0)
        out << " (" << std::setprecision(0) << value << " in all)";
    }
    out << "\n";
  }
  out << std::left << std::setw(30) << "total (stages)" << std::right << std::setw(12)
      << std::setprecision(1) << sum << "\n";
  out << frames << " frames in " << std::setprecision(1) << seconds << " s ("
      << std::setprecision(2) << framesPerSecond() << " frames/s); world cloud "
      << world_cloud_points << " points, " << planes << " run-wide planes\n";
  if (timed_frames > 0) {
    const double n = static_cast<double>(timed_frames);
    out << "CPU ms/frame: read-ahead thread " << std::setprecision(1)
        << read_ahead_cpu_ms / n << ", mapping thread " << mapping_cpu_ms / n
        << " (waited " << mapping_wait_ms / n << " ms/frame), process "
        << process_cpu_ms / n << "\n";
  }
  if (resumed_at_frame > 0)
    out << "resumed from a checkpoint at frame position " << resumed_at_frame << "\n";
  if (checkpoints_written > 0)
    out << checkpoints_written << " checkpoints written (" << std::setprecision(1)
        << checkpoint_ms << " ms in all)\n";
  out << "peak resident memory " << std::setprecision(1)
      << static_cast<double>(peak_rss_bytes) / (1024.0 * 1024.0) << " MiB\n";
  if (!map_summary.empty()) {
    out << "map:";
    for (const auto& [name, value] : map_summary)
      out << " " << name << " " << std::setprecision(name == "resolution_m" ? 2 : 0)
          << value;
    out << "\n";
  }
  if (!map_octomap_summary.empty()) {
    out << "map_octomap:";
    for (const auto& [name, value] : map_octomap_summary)
      out << " " << name << " " << std::setprecision(0) << value;
    out << "\n";
  }
  return out.str();
}

} // namespace planar_grid
