// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/frame_source.h>
#include <planar_grid/pipeline/mapper.h>
#include <planar_grid/pipeline/memory_estimate.h>
#include <planar_grid/pipeline/pipeline_config.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/stage_report.h>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief What a run did. \ingroup pipeline */
struct RunReport {
  /** \brief The configuration file of the run. */
  std::string config_file;
  /** \brief One line on the input (kind, folder, frame count). */
  std::string input_description;
  /** \brief First frame of the run (0-based position in the input). */
  std::size_t first_frame{0};
  /** \brief Frames run. */
  std::size_t frames{0};
  /** \brief Wall time of the whole run including loading, seconds. */
  double seconds{0.0};
  /** \brief Time spent loading (and rectifying) frames, milliseconds. */
  double load_ms{0.0};
  /** \brief Leading frame-local stages that ran up to two frames ahead on the second
   * thread at the end of the run (their number is balanced by the measured times; 0
   * when frames do not overlap). */
  std::size_t read_ahead_stages{0};
  /** \brief Frames this process ran through run() (a resumed run counts only the
   * frames after the checkpoint): the divisor of the four CPU and wait figures below.
   */
  std::size_t timed_frames{0};
  /** \brief CPU time of the thread that loads each frame and runs the read-ahead
   * stages on it (CLOCK_THREAD_CPUTIME_ID), summed over timed_frames, milliseconds.
   * Work that a stage hands to other threads (OpenCV's parallel loops) is not in it;
   * it is in process_cpu_ms. */
  double read_ahead_cpu_ms{0.0};
  /** \brief CPU time of the thread that runs the other stages (the caller's thread),
   * summed over timed_frames, milliseconds; the same caveat as read_ahead_cpu_ms. */
  double mapping_cpu_ms{0.0};
  /** \brief Wall time the mapping thread waited for the next frame from the read-ahead
   * thread, summed over timed_frames, milliseconds (0 when frames do not overlap). */
  double mapping_wait_ms{0.0};
  /** \brief CPU time of the whole process (every thread, getrusage) while the frames
   * ran, milliseconds. */
  double process_cpu_ms{0.0};
  /** \brief One report per stage, in run order. */
  std::vector<StageReport> stages;
  /** \brief Points in the accumulated world cloud at the end. */
  std::size_t world_cloud_points{0};
  /** \brief Run-wide planes after association across frames (accumulate stage). */
  std::size_t planes{0};
  /** \brief Figures of the map at the end (map_integration stage): cell counts and
   * memory in bytes, by name; empty without a map. */
  std::vector<std::pair<std::string, double>> map_summary;
  /** \brief What the OctoMap export (output.map_octomap) wrote, by name: nodes,
   * leaf_nodes, occupied_leaves, free_leaves, occupied_voxels, free_voxels,
   * skipped_voxels (OctoMapExportSummary), as liboctomap counts the file's tree; the
   * .bt holds the cuboids' voxels over the space layer's, so its counts differ from
   * map_summary's. Filled by writeRunOutputs(); empty without that output. */
  std::vector<std::pair<std::string, double>> map_octomap_summary;
  /** \brief Peak resident memory of the process at the end of the run (getrusage
   * ru_maxrss), bytes. */
  std::uint64_t peak_rss_bytes{0};
  /** \brief Resident memory (/proc/self/statm) after frames of the run: (frame
   * position, bytes), about 20 samples over the run, to show whether memory grows with
   * the frames or with the map. */
  std::vector<std::pair<std::size_t, std::uint64_t>> rss_samples;
  /** \brief Frame position the run resumed at from a checkpoint (0: not resumed). */
  std::size_t resumed_at_frame{0};
  /** \brief Checkpoints written during the run (including before a resume). */
  std::size_t checkpoints_written{0};
  /** \brief Wall time spent writing checkpoints in this process, milliseconds. */
  double checkpoint_ms{0.0};
  /** \brief Output files written, by kind (cloud, trajectory, snapshot, report). */
  std::vector<std::pair<std::string, std::string>> outputs;

  /** \brief Returns frames per second of wall time (0 when no time was measured). */
  double framesPerSecond() const
  {
    return seconds > 0.0 ? static_cast<double>(frames) / seconds : 0.0;
  }

  /** \brief Version of the report.json layout toJson() writes ("schema_version"):
   * raised when a field is renamed, removed or changes type or unit. */
  static constexpr int REPORT_SCHEMA_VERSION = 1;

  /** \brief The report as JSON text (the report.json schema, docs/OUTPUTS.md): counts
   * as integers, times, rates and metres as floats. */
  std::string toJson() const;

  /** \brief The per-stage timing table for the terminal. */
  std::string timingTable() const;
};

/** \brief Runs a configured pipeline over a range of frames: run() reads them from
 * the configured input; start(), processFrame() and finish() take frames the caller
 * supplies (one input feeding several pipelines, as planar_grid_eval feeds one front
 * end's frames to the mapping stages at each cell size).
 *
 * The runner is the frame source, the read-ahead thread, the checkpoints and the
 * report around a Mapper, which owns the stages, the state they carry across frames
 * and the map: each frame runs through the mapper's stages (Mapper::prepareFrame() for
 * the stages that run ahead, Mapper::integrateFrame() for the rest), as the live calls
 * of the tool's library, the ROS node and Python do. \ingroup pipeline */
class PipelineRunner {
public:
  /** \brief Called after each frame: frames done, frames in total, seconds elapsed. */
  using ProgressCallback = std::function<void(std::size_t, std::size_t, double)>;
  /** \brief Called after the stages have processed a frame: its position in the
   * input, the frame as the last stage left it, and each stage's time on it in
   * milliseconds (in stage order). */
  using FrameCallback =
    std::function<void(std::size_t, Frame&, const std::vector<double>&)>;
  /** \brief Called right before a stage processes a frame: the stage's index and the
   * frame as the stages before it left it. */
  using StageCallback = std::function<void(std::size_t, Frame&)>;

  /** \brief Where the frames come from. */
  enum class FrameSupply {
    /** The configured input, opened by the constructor and read by run(). */
    INPUT,
    /** The caller, through start(), processFrame() and finish(); the input is not
     * opened (run(), frameCount() and setFrameRange() throw). */
    CALLER
  };

  /** \brief Builds the stages and, for FrameSupply::INPUT, opens the input.
   * \param[in] config the pipeline
   * \param[in] supply where the frames come from
   * \throws planar_grid::ConfigError, planar_grid::IOError */
  explicit PipelineRunner(const PipelineConfig& config,
                          FrameSupply supply = FrameSupply::INPUT);
  ~PipelineRunner();

  /** \brief Number of frames in the input.
   * \throws planar_grid::Exception without an input (FrameSupply::CALLER) */
  std::size_t frameCount() const;

  /** \brief Every file the run reads: the input's (FrameSource::files()) and the
   * configuration file it was loaded from (when that is a file).
   * \throws planar_grid::Exception without an input (FrameSupply::CALLER) */
  std::vector<InputFile> inputFiles() const;

  /** \brief Restricts the run to frames begin, begin + step, ... before end (0-based
   * positions).
   * \param[in] begin first frame position
   * \param[in] end one past the last frame position
   * \param[in] step frames from one processed frame to the next, >= 1; checkpoints
   * (setCheckpoint(), resumeFrom()) need 1
   * \throws planar_grid::Exception when the range is empty or outside the input, or
   * the step is 0 */
  void setFrameRange(std::size_t begin, std::size_t end, std::size_t step = 1);

  /** \brief Sets the function called after each frame (none by default).
   * \param[in] callback receives frames done, frames in total, seconds elapsed */
  void setProgressCallback(ProgressCallback callback)
  {
    progress_ = std::move(callback);
  }

  /** \brief Sets a flag that stops run() between two frames once it is true (none by
   * default), e.g. set by a SIGINT handler (an atomic store is async-signal-safe).
   * run() then finishes the frame under way, writes a checkpoint of it when
   * checkpoints are set (setCheckpoint(); a later run resumes from it), and throws
   * planar_grid::Interrupted naming that frame; it returns no report and writes no
   * output. A flag set after the last frame has no effect.
   * \param[in] stop the flag, read with load(); it must outlive run() (nullptr: none)
   */
  void setStopFlag(const std::atomic<bool>* stop) { stop_ = stop; }

  /** \brief Sets the function called after the stages have processed each frame, on
   * the calling thread, in frame order, before the progress callback (none by
   * default). It may read the frame, keep a copy or feed it to other pipelines; what
   * it changes in the frame is not seen by this pipeline's stages.
   * \param[in] callback receives the frame's position, the frame and each stage's
   * milliseconds on it */
  void setFrameCallback(FrameCallback callback)
  {
    frame_callback_ = std::move(callback);
  }

  /** \brief Sets the function called right before each stage processes a frame
   * (none by default), e.g. to give another map the cloud a stage receives. It runs on
   * the thread that runs the stage: the second thread for the stages that run ahead
   * (setFrameOverlap()), the calling thread for the others. Its time is not counted
   * in the stage's.
   * \param[in] callback receives the stage's index and the frame */
  void setStageCallback(StageCallback callback)
  {
    stage_callback_ = std::move(callback);
  }

  /** \brief Runs the leading frame-local stages (Stage::isFrameLocal(): in the main
   * job stereo_disparity and feature_matching) and the loading of frames t + 1 and
   * t + 2, one after the other, on a second thread while the other stages map frame t
   * (on by default). The stages see
   * the same frames in the same order, so the map, clouds, trajectory and report
   * figures are identical to a sequential run; only the wall time differs. A pipeline
   * whose first stage keeps state across frames runs sequentially either way.
   * \param[in] overlap false runs every frame start to end on the calling thread */
  void setFrameOverlap(bool overlap) { overlap_ = overlap; }

  /** \brief Number of leading stages that may run ahead on the second thread (0 when
   * the overlap is off or the first stage is not frame-local). The run starts with all
   * of them ahead and moves the last ones to the calling thread while that shortens
   * the longer thread's mean frame time (RunReport::read_ahead_stages). */
  std::size_t frameLocalPrefix() const;

  /** \brief Writes a checkpoint to \a path every \a every_n_frames frames of the run
   * (and after its last frame): the whole state carried across frames (the map, the
   * accumulated clouds and planes, the stages' state such as the feature tracks, the
   * trajectory and the report so far) in one file, replaced atomically (temporary file,
   * rename), so that a process killed at any time leaves the previous checkpoint
   * intact. 0 frames: no checkpoints.
   * \throws planar_grid::ConfigError when a stage cannot be checkpointed
   * (Stage::supportsCheckpoint()) */
  void setCheckpoint(const std::string& path, std::size_t every_n_frames);

  /** \brief Continues the run from a checkpoint written by a run of the same stages,
   * parameters and input: run() restores the state and starts at the frame after the
   * checkpoint, and gives the same map as an uninterrupted run. Call before run(),
   * after setFrameRange(): the range must start where the checkpoint's run started (the
   * map holds its frames from there); its end may differ (a longer run continues).
   * \param[in] path the checkpoint file
   * \return the frame position the run continues at
   * \throws planar_grid::IOError for a missing, corrupt or foreign checkpoint (other
   * stages, parameters or input), one whose run started at another frame, or one at or
   * past the end of the range, naming the file */
  std::size_t resumeFrom(const std::string& path);

  /** \brief Bounds the memory of a run of the frame range (estimateRunMemory()): the
   * input's camera, and the poses of the range when the input gives them before the
   * run. Reads no frame.
   * \throws planar_grid::Exception without an input (FrameSupply::CALLER) */
  MemoryEstimate estimateMemory() const;

  /** \brief Sets the limit run() holds estimateMemory() to before the first frame (a
   * planar_grid::ConfigError at the cell size's key when the estimate exceeds it).
   * Default: machineMemoryLimit(), read when the runner is built.
   * \param[in] limit the limit; bytes 0: no check */
  void setMemoryLimit(const MemoryLimit& limit) { memory_limit_ = limit; }

  /** \brief The limit run() checks (setMemoryLimit()). */
  const MemoryLimit& getMemoryLimit() const { return memory_limit_; }

  /** \brief Runs every frame of the range through every stage: start(), the frames,
   * finish(). Before the first frame, a run whose memory estimate exceeds the limit
   * (setMemoryLimit()) is refused with a planar_grid::ConfigError.
   * \throws planar_grid::Exception naming the frame and stage on failure, or without
   * an input (FrameSupply::CALLER) */
  RunReport run();

  /** \brief Starts a run of frames the caller supplies: clears the state and the
   * trajectory and starts every stage. */
  void start();

  /** \brief Runs every stage on \a frame, on the calling thread, then the frame
   * callback (a frame of a run begun by start()).
   * \param[in,out] frame a loaded frame; its sequence_number is its position, named in
   * errors
   * \throws planar_grid::Exception naming the frame and stage on failure */
  void processFrame(Frame& frame);

  /** \brief Finishes every stage and reports the frames processed since start().
   * \return the report (per-stage times and counts, the map's summary) */
  RunReport finish();

  /** \brief The report of the frames processed since start() so far: per-stage sums,
   * without the figures finish() adds (the map summary, the run's wall time). */
  const RunReport& report() const { return report_; }

  /** \brief The shared state (accumulated world cloud) after run(). */
  const PipelineState& state() const { return mapper_->getState(); }

  /** \brief The poses of the frames that ran (world_T_camera), in order. */
  const Trajectory& trajectory() const { return mapper_->getTrajectory(); }

  /** \brief The mapper that runs the stages: the runner hands it each frame of the
   * run (Mapper::prepareFrame() ahead, Mapper::integrateFrame()). Its map is the run's
   * (state().map). */
  const Mapper& mapper() const { return *mapper_; }

private:
  struct ResumeData;
  /** \brief A small file the run read at its start, as a checkpoint records it: what
   * it is, its path, its size in bytes and the 64-bit FNV-1a hash of its bytes, so
   * that a resume finds a file that changed since. */
  struct InputStamp {
    std::string what;
    std::string path;
    std::uint64_t size{0};
    std::uint64_t hash{0};
  };
  /** \brief The stamps of the configuration file, the calibration and the poses
   * file of \a config (the images and clouds are read frame by frame and are too
   * large to read twice). */
  static std::vector<InputStamp> stampInputFiles(const PipelineConfig& config);

  /** \brief The stages, their parameters and the input, as text: a checkpoint is only
   * resumed by the pipeline that wrote it. */
  std::string fingerprint() const;
  /** \brief Writes the checkpoint after frame position \a next_frame - 1. */
  void writeCheckpoint(std::size_t next_frame, const RunReport& report) const;
  /** \brief The input, or an Exception naming \a what needs it. */
  FrameSource& input(const std::string& what) const;

  PipelineConfig config_;
  std::unique_ptr<FrameSource> source_;
  /** \brief The stages, the state they carry across frames and the map. */
  std::unique_ptr<Mapper> mapper_;
  std::size_t begin_{0};
  std::size_t end_{0};
  std::size_t step_{1};
  ProgressCallback progress_;
  FrameCallback frame_callback_;
  StageCallback stage_callback_;
  /** \brief The report of the run under way (start() to finish()). */
  RunReport report_;
  /** \brief When the run began, and the seconds of the run a checkpoint continues. */
  std::chrono::steady_clock::time_point run_start_;
  double previous_seconds_{0.0};
  std::string checkpoint_path_;
  std::size_t checkpoint_every_{0};
  /** \brief The input files' stamps when the checkpoints were set up, before the
   * first frame; every checkpoint records them. */
  std::vector<InputStamp> input_stamps_;
  /** \brief The stamps of the frame files (FrameSource::frameFiles()) of the frames
   * before frame_stamps_until_, taken when a checkpoint is written (the files are
   * read again then, from the page cache) and recorded by every later one. */
  mutable std::vector<InputStamp> frame_stamps_;
  mutable std::size_t frame_stamps_until_{0};
  std::unique_ptr<ResumeData> resume_;
  bool overlap_{true};
  /** \brief setStopFlag()'s flag, or nullptr. */
  const std::atomic<bool>* stop_{nullptr};
  /** \brief The limit run() checks the memory estimate against. */
  MemoryLimit memory_limit_{machineMemoryLimit()};
};

} // namespace planar_grid
