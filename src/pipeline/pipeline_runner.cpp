// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/pipeline/pipeline_runner.h>

#include <pcl/common/time.h>

#include <nlohmann/json.hpp>

#include <chrono>
#include <iomanip>
#include <sstream>

#include "stages.h"

namespace planar_grid {

PipelineRunner::PipelineRunner(const PipelineConfig& config) : config_(config)
{
  for (const auto& sc : config_.stages) {
    const StageInfo* info = findStage(sc.type);
    if (!info)
      throw ConfigError(config_.source_file, sc.line, sc.column,
                        "unknown stage type '" + sc.type
                          + "'; known types: " + knownStageTypes());
    try {
      stages_.push_back(info->create(sc.params));
    } catch (const ConfigError&) {
      throw;
    } catch (const Exception& e) {
      // A combination of parameters the stage rejects (e.g. SGBM constraints).
      throw ConfigError(config_.source_file, sc.line, sc.column,
                        "stage '" + sc.type + "': " + e.what());
    }
  }
  source_ = createFrameSource(config_.input);
  begin_ = 0;
  end_ = source_->size();
}

PipelineRunner::~PipelineRunner() = default;

std::size_t
PipelineRunner::frameCount() const
{
  return source_->size();
}

void
PipelineRunner::setFrameRange(std::size_t begin, std::size_t end)
{
  if (begin >= end)
    throw Exception("the frame range " + std::to_string(begin) + ":"
                    + std::to_string(end) + " is empty");
  if (end > source_->size())
    throw Exception("the frame range " + std::to_string(begin) + ":"
                    + std::to_string(end) + " goes past the input's "
                    + std::to_string(source_->size()) + " frames");
  begin_ = begin;
  end_ = end;
}

RunReport
PipelineRunner::run()
{
  using Clock = std::chrono::steady_clock;
  const auto start = Clock::now();
  const auto ms_since = [](Clock::time_point t) {
    return std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  };

  RunReport report;
  report.config_file = config_.source_file;
  report.input_description = source_->describe();
  report.first_frame = begin_;
  for (const auto& sc : config_.stages) {
    StageReport sr;
    sr.type = sc.type;
    report.stages.push_back(sr);
  }
  state_ = PipelineState();
  trajectory_.clear();
  for (auto& stage : stages_)
    stage->start(state_);

  const std::size_t total = end_ - begin_;
  std::vector<std::pair<std::string, double>> counter_values;
  for (std::size_t i = begin_; i < end_; ++i) {
    Frame frame;
    const auto load_start = Clock::now();
    source_->load(i, frame);
    frame.sequence_number = i;
    report.load_ms += ms_since(load_start);

    for (std::size_t s = 0; s < stages_.size(); ++s) {
      StageReport& sr = report.stages[s];
      const bool counts = stages_[s]->countsCloudPoints();
      if (counts && frame.cloud)
        sr.points_in += stages::countValidPoints(*frame.cloud);
      const auto t = Clock::now();
      try {
        stages_[s]->process(frame, state_);
      } catch (const Exception& e) {
        throw Exception("frame " + frame.name + " (" + std::to_string(i) + "), stage '"
                        + sr.type + "': " + e.what());
      }
      const double ms = ms_since(t);
      sr.total_ms += ms;
      sr.max_ms = std::max(sr.max_ms, ms);
      ++sr.frames;
      if (counts && frame.cloud)
        sr.points_out += stages::countValidPoints(*frame.cloud);
      counter_values.clear();
      stages_[s]->counters(frame, counter_values);
      for (const auto& [name, value] : counter_values)
        sr.addCounter(name, value);
    }
    // After the stages: visual_odometry sets the pose of frames whose input has none.
    if (frame.has_pose)
      trajectory_.push_back(frame.world_T_camera);
    ++report.frames;
    if (progress_)
      progress_(i - begin_ + 1, total, ms_since(start) / 1000.0);
  }
  for (std::size_t s = 0; s < stages_.size(); ++s) {
    const auto t = Clock::now();
    stages_[s]->finish(state_);
    report.stages[s].total_ms += ms_since(t);
  }
  report.world_cloud_points = state_.world_cloud ? state_.world_cloud->size() : 0;
  report.planes = state_.plane_models.size();
  if (state_.map) {
    const PlanarGridMap& map = *state_.map;
    const auto& space = map.getSpaceLayer();
    const auto& surface = map.getSurfaceLayer();
    std::size_t planar = 0;
    for (const auto& c : surface.getCuboids()) // rebuilds the cuboids if stale
      planar += c.is_planar;
    const MapMemory memory = map.getMemory(); // after the rebuild
    report.map_summary = {
      {"resolution_m", map.getResolution()},
      {"cuboids", static_cast<double>(surface.getCuboids().size())},
      {"planar_cuboids", static_cast<double>(planar)},
      {"planes", static_cast<double>(surface.getPlanes().size())},
      {"plane_cells", static_cast<double>(surface.getCellCount())},
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
  report.seconds = ms_since(start) / 1000.0;
  return report;
}

void
StageReport::addCounter(const std::string& name, double value)
{
  for (auto& [key, sum] : counters)
    if (key == name) {
      sum += value;
      return;
    }
  counters.emplace_back(name, value);
}

std::string
RunReport::toJson() const
{
  nlohmann::ordered_json j;
  j["config_file"] = config_file;
  j["input"] = input_description;
  j["first_frame"] = first_frame;
  j["frames"] = frames;
  j["seconds"] = seconds;
  j["frames_per_second"] = framesPerSecond();
  j["load_ms_per_frame"] = frames ? load_ms / static_cast<double>(frames) : 0.0;
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
    e["points_in"] = s.points_in;
    e["points_out"] = s.points_out;
    for (const auto& [name, value] : s.counters) {
      e[name] = value;
      e[name + "_per_frame"] = s.frames ? value / static_cast<double>(s.frames) : 0.0;
    }
    js.push_back(e);
  }
  if (!map_summary.empty()) {
    auto& jm = j["map"] = nlohmann::ordered_json::object();
    for (const auto& [name, value] : map_summary)
      jm[name] = value;
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
  if (!map_summary.empty()) {
    out << "map:";
    for (const auto& [name, value] : map_summary)
      out << " " << name << " " << std::setprecision(name == "resolution_m" ? 2 : 0)
          << value;
    out << "\n";
  }
  return out.str();
}

} // namespace planar_grid
