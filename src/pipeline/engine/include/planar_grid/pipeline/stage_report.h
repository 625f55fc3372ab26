// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstddef>
#include <cstdint>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {

/** \brief What one stage did to one frame (Mapper::integrateStereo(),
 * Mapper::integrateCloud(), Mapper::integrateFrame()). \ingroup pipeline */
struct FrameStageStats {
  /** \brief Stage type. */
  std::string type;
  /** \brief Wall time of the stage on the frame, milliseconds. */
  double ms{0.0};
  /** \brief CPU time of the thread that ran the stage on the frame
   * (CLOCK_THREAD_CPUTIME_ID), milliseconds; work the stage hands to other threads is
   * not in it. */
  double cpu_ms{0.0};
  /** \brief Valid points entering the stage (stages that work on the cloud; else 0). */
  std::uint64_t points_in{0};
  /** \brief Valid points leaving the stage. */
  std::uint64_t points_out{0};
  /** \brief The stage's named figures on this frame (Stage::counters), e.g.
   * feature_matching: "features", multi_plane_segmentation: "planes". */
  std::vector<std::pair<std::string, double>> counters;
};

/** \brief Per-stage timing and point counts of a run. \ingroup pipeline */
struct StageReport {
  /** \brief Stage type. */
  std::string type;
  /** \brief Frames the stage ran on. */
  std::size_t frames{0};
  /** \brief Wall time in the stage, summed over frames, milliseconds. */
  double total_ms{0.0};
  /** \brief Wall time of the stage's slowest frame, milliseconds. */
  double max_ms{0.0};
  /** \brief CPU time of the thread that ran the stage (CLOCK_THREAD_CPUTIME_ID: not
   * the worker threads a stage starts, e.g. OpenCV's), summed over cpu_frames,
   * milliseconds. Unlike the wall time it barely depends on what else the machine
   * runs. */
  double cpu_ms{0.0};
  /** \brief Frames in cpu_ms: those this process ran (a resumed run's checkpoint
   * keeps only the wall times). */
  std::size_t cpu_frames{0};
  /** \brief Valid points entering the stage, summed over frames (for stages that work
   * on the cloud). */
  std::uint64_t points_in{0};
  /** \brief Valid points leaving the stage, summed over frames. */
  std::uint64_t points_out{0};
  /** \brief The stage's named figures (Stage::counters), summed over frames, in the
   * order the stage first reported them (e.g. feature_matching: "features"). */
  std::vector<std::pair<std::string, double>> counters;

  /** \brief Adds \a value to the counter \a name. */
  void addCounter(const std::string& name, double value);

  /** \brief Adds what the stage did to one frame, \a sample, to the sums. */
  void add(const FrameStageStats& sample);

  /** \brief Returns the mean wall time per frame, milliseconds (0 without frames). */
  double meanMs() const
  {
    return frames ? total_ms / static_cast<double>(frames) : 0.0;
  }
};

/** \brief CPU time of the calling thread (CLOCK_THREAD_CPUTIME_ID), milliseconds: the
 * clock of FrameStageStats::cpu_ms and StageReport::cpu_ms. \ingroup pipeline */
double threadCpuMs();

} // namespace planar_grid
