// SPDX-License-Identifier: BSD-3-Clause
#include "stage_run.h"

#include <planar_grid/core/exceptions.h>

#include <time.h>

#include <algorithm>
#include <chrono>
#include <utility>

#include "stages.h"

namespace planar_grid {

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

void
StageReport::add(const FrameStageStats& sample)
{
  total_ms += sample.ms;
  max_ms = std::max(max_ms, sample.ms);
  ++frames;
  cpu_ms += sample.cpu_ms;
  ++cpu_frames;
  points_in += sample.points_in;
  points_out += sample.points_out;
  for (const auto& [name, value] : sample.counters)
    addCounter(name, value);
}

double
threadCpuMs()
{
  timespec t{};
  if (::clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t) != 0)
    return 0.0;
  return static_cast<double>(t.tv_sec) * 1e3 + static_cast<double>(t.tv_nsec) * 1e-6;
}

namespace stages {

void
runStage(Stage& stage,
         std::size_t s,
         const std::string& type,
         const StageCallback& callback,
         Frame& frame,
         PipelineState& state,
         std::size_t i,
         StageProgress& progress)
{
  using Clock = std::chrono::steady_clock;
  if (callback)
    callback(s, frame);
  CloudCount& last_count = progress.last_count;
  FrameStageStats sample;
  sample.type = type;
  const bool counts = stage.countsCloudPoints();
  if (counts && frame.cloud)
    sample.points_in = last_count.counts(*frame.cloud) ? last_count.valid
                                                       : countValidPoints(*frame.cloud);
  const double cpu_start = threadCpuMs();
  const auto t = Clock::now();
  try {
    stage.process(frame, state);
  } catch (const Exception& e) {
    throw Exception("frame " + frame.name + " (" + std::to_string(i) + "), stage '"
                    + type + "': " + e.what());
  }
  sample.ms = std::chrono::duration<double, std::milli>(Clock::now() - t).count();
  sample.cpu_ms = threadCpuMs() - cpu_start;
  if (counts && frame.cloud) {
    sample.points_out = countValidPoints(*frame.cloud);
    last_count = {frame.cloud.get(), frame.cloud->points.data(), frame.cloud->size(),
                  sample.points_out};
  } else
    last_count = {};
  stage.counters(frame, sample.counters);
  progress.stages.push_back(std::move(sample));
}

std::unique_ptr<Stage>
createStage(const std::string& type,
            const ParamValues& params,
            const std::string& source,
            int line,
            int column)
{
  const StageInfo* info = findStage(type);
  if (!info)
    throw ConfigError(source, line, column,
                      "unknown stage type '" + type
                        + "'; known types: " + knownStageTypes());
  try {
    return info->create(params);
  } catch (const ConfigError&) {
    throw;
  } catch (const Exception& e) {
    // A combination of parameters the stage rejects (e.g. SGBM constraints).
    throw ConfigError(source, line, column, "stage '" + type + "': " + e.what());
  }
}

} // namespace stages
} // namespace planar_grid
