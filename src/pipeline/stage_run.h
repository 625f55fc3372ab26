// SPDX-License-Identifier: BSD-3-Clause
// Running one stage on one frame and building the stages, as PipelineRunner and Mapper
// both do (internal to the pipeline module).
#pragma once

#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/param_table.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/stage_report.h>

#include <cstddef>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {
namespace stages {

/** \brief Called right before a stage processes a frame: the stage's index and the
 * frame as the stages before it left it. */
using StageCallback = std::function<void(std::size_t, Frame&)>;

/** \brief What one stage did to one frame, recorded where it ran and added to the
 * report on the main thread in frame order. */
struct StageSample {
  /** \brief Wall time, milliseconds. */
  double ms{0.0};
  /** \brief CPU time of the thread that ran it, milliseconds. */
  double cpu_ms{0.0};
  /** \brief Valid points in. */
  std::uint64_t points_in{0};
  /** \brief Valid points out. */
  std::uint64_t points_out{0};
  /** \brief The stage's named figures on the frame. */
  std::vector<std::pair<std::string, double>> counters;
};

/** \brief The valid points of the cloud a stage left behind. The next stage starts
 * from the same cloud, unchanged (nothing runs between two stages of a frame), so its
 * count of the points in is this one. */
struct CloudCount {
  /** \brief The cloud counted. */
  const Frame::Cloud* cloud{nullptr};
  /** \brief Its points' storage when counted. */
  const void* data{nullptr};
  /** \brief Its size when counted. */
  std::size_t size{0};
  /** \brief Its valid points. */
  std::uint64_t valid{0};

  /** \brief Whether \a c is the cloud counted, unchanged. */
  bool counts(const Frame::Cloud& c) const
  {
    return &c == cloud && c.points.data() == data && c.size() == size;
  }
};

/** \brief CPU time of the calling thread, milliseconds. */
double threadCpuMs();

/** \brief Runs stage \a s (\a stage, of type \a type) on \a frame, after \a callback
 * when it is set, and records its time, points and counters; failures name the frame,
 * its position \a i and the stage. */
StageSample runStage(Stage& stage,
                     std::size_t s,
                     const std::string& type,
                     const StageCallback& callback,
                     Frame& frame,
                     PipelineState& state,
                     std::size_t i,
                     CloudCount& last_count);

/** \brief Adds \a sample to the stage's sums \a sr. */
void addSample(StageReport& sr, const StageSample& sample);

/** \brief Builds a stage of type \a type from its parameters.
 * \throws planar_grid::ConfigError at \a source, \a line, \a column for an unknown
 * type or parameters the stage rejects */
std::unique_ptr<Stage> createStage(const std::string& type,
                                   const ParamValues& params,
                                   const std::string& source,
                                   int line,
                                   int column);

} // namespace stages
} // namespace planar_grid
