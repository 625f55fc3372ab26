// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>
#include <planar_grid/core/writer_preferring_shared_mutex.h>
#include <planar_grid/map/planar_grid_map.h>
#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/mapper_config.h>
#include <planar_grid/pipeline/stage.h>
#include <planar_grid/pipeline/stage_report.h>

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Geometry>
#include <opencv2/core/mat.hpp>

#include <atomic>
#include <chrono>
#include <cstdint>
#include <functional>
#include <memory>
#include <mutex>
#include <shared_mutex>
#include <string>
#include <utility>
#include <vector>

namespace planar_grid {

/** \brief A frame's way through a mapper's stages so far (Mapper::prepareFrame(),
 * Mapper::integrateFrame()): what each stage it went through did, from the first stage
 * on, and the count of the valid points the last one left, which the next stage starts
 * from. Start each frame with an empty one. \ingroup pipeline */
struct StageProgress {
  /** \brief The count of the valid points of the cloud a stage left behind. The next
   * stage starts from the same cloud, unchanged, so its count of the points in is this
   * one. */
  struct CloudCount {
    /** \brief The cloud counted (nullptr: none). */
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

  /** \brief One entry per stage the frame went through, in order: the next stage to
   * run is stages.size(). */
  std::vector<FrameStageStats> stages;
  /** \brief The valid points of the cloud the last stage left. */
  CloudCount last_count;
};

/** \brief What the pipeline did to one frame of a Mapper. \ingroup pipeline */
struct FrameStats {
  /** \brief The frame's position in the mapper's run (0-based). */
  std::size_t sequence_number{0};
  /** \brief Wall time of the whole call (checks, stages, waiting for readers),
   * milliseconds. */
  double total_ms{0.0};
  /** \brief Wall time the call waited for readers of the map (Mapper::readMap(),
   * Mapper::save()) to finish before the map changed, milliseconds. */
  double lock_wait_ms{0.0};
  /** \brief Wall time during which readers were locked out of the map (the stages
   * that change it), milliseconds. */
  double exclusive_ms{0.0};
  /** \brief One entry per stage, in pipeline order. */
  std::vector<FrameStageStats> stages;
  /** \brief Planes found in the frame (after ground removal). */
  std::size_t planes{0};
  /** \brief Cells (cuboids) of the frame. */
  std::size_t cuboids{0};
  /** \brief Cells of the map's surface layer after the frame:
   * SurfaceLayer::getCellCount(), each plane's observed raster cells and the
   * non-planar cells. Counting them builds nothing; the map's cuboids, which merge
   * the raster cells into rectangles, come from
   * getMap()->getSurfaceLayer().getCuboidCount() when they are wanted (it rebuilds
   * the covers of the planes the frames changed). */
  std::size_t map_cells{0};
  /** \brief The frame's pose world_T_camera (meters), the caller's or the visual
   * odometry's. */
  Eigen::Isometry3d world_T_camera{Eigen::Isometry3d::Identity()};

  EIGEN_MAKE_ALIGNED_OPERATOR_NEW
};

/** \brief Builds a map frame by frame from the caller's data: each call runs one
 * frame through the mapper's stages and returns that frame's statistics. The stages
 * and their parameters are a MapperConfig; built from a pipeline configuration
 * (loadMapperConfig()), the same frames give the same map, byte for byte, as a
 * planar_grid_pipeline run of that configuration over them: that run's PipelineRunner
 * drives a Mapper of the same stages through the engine calls below (prepareFrame(),
 * integrateFrame()), on which the live calls run too.
 *
 * The mapper owns its stages, the state they carry from frame to frame, the map and
 * the map's lock; it reads no file. It takes stereo pairs when a stage reads stereo
 * images (stereo_disparity, feature_matching), else point clouds and depth images.
 * Each frame carries its pose world_T_camera (meters, z-up world, camera x right, y
 * down, z forward), or none when the visual_odometry stage estimates it. One stage
 * must make the map (map_integration). A frame whose stage throws may leave part of
 * its work in the map and the stages' state, as a failed run of planar_grid_pipeline
 * does; reset() starts over.
 *
 * Thread safety: the integrate calls and reset() may come from any thread; they run
 * one at a time, each whole, in the order they take the mapper's frame lock (a second
 * thread's call waits for the first's frame). Any number of other threads may read the
 * map at the same time through readMap() and save(): they hold a shared lock while
 * they read, and each frame holds it exclusively only while its map_integration stage
 * changes the map, so every reader sees the map as it was after some whole frame. The
 * lock prefers the frame (WriterPreferringSharedMutex): once the frame waits, new
 * readers wait behind it, so the frame waits at most for the reads under way
 * (FrameStats::lock_wait_ms), and a reader at most for one map_integration stage
 * (FrameStats::exclusive_ms; docs/LIVE.md has both measured). A thread holding a
 * MapReader must not take a second one nor integrate. Nothing is copied: a copy per
 * frame, the alternative, would cost more than the frame (docs/LIVE.md).
 * \ingroup pipeline */
class Mapper {
public:
  /** \brief Shared pointer to a mapper. */
  using Ptr = std::shared_ptr<Mapper>;
  /** \brief Shared pointer to a const mapper. */
  using ConstPtr = std::shared_ptr<const Mapper>;
  /** \brief The point cloud type of integrateCloud(). */
  using PointCloud = pcl::PointCloud<pcl::PointXYZ>;
  /** \brief Called right before a stage processes a frame (prepareFrame(),
   * integrateFrame()): the stage's index and the frame as the stages before it left
   * it. */
  using StageCallback = std::function<void(std::size_t, Frame&)>;

  /** \brief What the constructor checks of the stages beyond their types and
   * parameters. */
  enum class StageChecks {
    /** Every stage's needs (StageInfo::needs) come from the caller's frames (stereo
     * pairs or clouds, with poses) or an earlier stage, and a stage makes the map
     * (map_integration); the parameters a stage leaves out take its table's defaults,
     * and a key its table lacks is an error. The stages start at once. For the live
     * calls (integrateStereo(), integrateCloud(), integrateDepth()). */
    LIVE,
    /** None: the frames come from a pipeline's input, whose loader
     * (loadPipelineConfig()) checked the stages' needs against it and filled in their
     * parameters; a pipeline without a map (a front end) is accepted. The stages start
     * at the first reset(). For integrateFrame(), as PipelineRunner drives it. */
    PIPELINE
  };

  /** \brief The map, read under a shared lock held until this object is destroyed:
   * the map cannot change while it lives. Keep it no longer than the read, and do not
   * integrate a frame on a thread that holds one (the frame would wait for it). */
  class MapReader {
  public:
    /** \brief The map. */
    const PlanarGridMap& operator*() const { return *map_; }
    /** \brief The map. */
    const PlanarGridMap* operator->() const { return map_; }

  private:
    friend class Mapper;
    /** \brief Locks, then reads the map pointer (reset() replaces the map). */
    MapReader(WriterPreferringSharedMutex& mutex,
              const std::shared_ptr<PlanarGridMap>& map) :
        lock_(mutex),
        map_(map.get())
    {}
    /** \brief The shared lock on the map. */
    std::shared_lock<WriterPreferringSharedMutex> lock_;
    /** \brief The map. */
    const PlanarGridMap* map_;
  };

  /** \brief Builds the stages of \a config and starts with an empty map.
   * \param[in] config the stages, in run order (e.g. loadMapperConfig() of a pipeline
   * file, or written in code)
   * \throws planar_grid::ConfigError, naming the stage (and config.name, line and
   * column when given), for an unknown stage type, a key its table lacks, parameters
   * the stage rejects, or a stage that needs data (StageInfo::needs) that neither the
   * frames nor an earlier stage give; planar_grid::Exception when no stage makes the
   * map (map_integration) */
  explicit Mapper(const MapperConfig& config);

  /** \brief Builds the stages of \a config with the checks \a checks.
   * \param[in] config the stages, in run order
   * \param[in] checks StageChecks::LIVE as the other constructor; StageChecks::PIPELINE
   * for the stages of a pipeline configuration (toMapperConfig()), whose frames come
   * through integrateFrame()
   * \throws planar_grid::ConfigError, naming the stage, for an unknown stage type or
   * parameters the stage rejects, and with StageChecks::LIVE as the other constructor
   * \throws planar_grid::Exception with StageChecks::LIVE when no stage makes the map
   */
  Mapper(const MapperConfig& config, StageChecks checks);

  Mapper(const Mapper&) = delete;
  Mapper& operator=(const Mapper&) = delete;
  /** \brief Ends the run; no MapReader may outlive the mapper. */
  ~Mapper();

  /** \brief Maps a rectified stereo pair seen from \a world_T_camera.
   * \param[in] left rectified left image, 8-bit grey (CV_8UC1), calibration.width x
   * calibration.height px when the calibration gives a size
   * \param[in] right rectified right image, the left one's size and type
   * \param[in] calibration the rectified pair's focal length (px), principal point
   * (px) and baseline (m)
   * \param[in] world_T_camera the left camera's pose, meters
   * \return the frame's statistics
   * \throws planar_grid::Exception for an empty image, images of different size or
   * type, not the calibration's size (or, when it gives none, with the principal point
   * outside them) or not the earlier frames' size, an invalid calibration, a pipeline
   * that reads point clouds or estimates its own poses (visual_odometry), or a stage
   * that fails on the frame (the message names the frame and stage) */
  FrameStats integrateStereo(const cv::Mat& left,
                             const cv::Mat& right,
                             const StereoCalibration& calibration,
                             const Eigen::Isometry3d& world_T_camera);

  /** \brief As the other integrateStereo(), with the pose from the pipeline's
   * visual_odometry stage.
   * \throws planar_grid::Exception as the other, and when the pipeline has no
   * visual_odometry stage (pass the pose) */
  FrameStats integrateStereo(const cv::Mat& left,
                             const cv::Mat& right,
                             const StereoCalibration& calibration);

  /** \brief Maps a point cloud seen from \a world_T_sensor.
   * \param[in] cloud points in the sensor frame, meters (NaN points are invalid;
   * organized clouds keep their width and height); intensity 0
   * \param[in] world_T_sensor the sensor's pose, meters
   * \return the frame's statistics
   * \throws planar_grid::Exception for an empty cloud, a pipeline that reads stereo
   * pairs, or a stage that fails on the frame */
  FrameStats integrateCloud(const PointCloud& cloud,
                            const Eigen::Isometry3d& world_T_sensor);

  /** \brief As the other integrateCloud(), for a cloud with an intensity field (the
   * pipeline's working cloud type, Frame::Cloud). */
  FrameStats integrateCloud(const Frame::Cloud& cloud,
                            const Eigen::Isometry3d& world_T_sensor);

  /** \brief Maps a depth image seen from \a world_T_camera, as its organized point
   * cloud through integrateCloud(), with the camera's own pinhole model for the free
   * space (map_integration's `auto` and `pinhole` sensor models).
   * \param[in] depth the depth along the optical axis per pixel: CV_16UC1 in
   * millimeters or CV_32FC1 in meters (REP 118, as ROS depth cameras publish it); 0,
   * NaN and infinity are invalid pixels
   * \param[in] camera the depth camera: width and height (px, the image's size),
   * focal lengths (px, > 0) and principal point (px)
   * \param[in] world_T_camera the camera's pose (x right, y down, z forward), meters
   * \return the frame's statistics
   * \throws planar_grid::Exception for an empty image, another pixel type, a size
   * other than the camera's, focal lengths that are not positive and finite, a
   * pipeline that reads stereo pairs, or a stage that fails on the frame */
  FrameStats integrateDepth(const cv::Mat& depth,
                            const PinholeView& camera,
                            const Eigen::Isometry3d& world_T_camera);

  /** \brief The map under a shared lock (see the class brief): safe from any thread,
   * also while a frame is being integrated. */
  [[nodiscard]] MapReader readMap() const;

  /** \brief The map itself, without a lock: read it only from the thread that
   * integrates, between its calls (the map changes during them); other threads read
   * through readMap(). The map stays alive while the pointer does, also after
   * reset(), which starts a new one. */
  [[nodiscard]] std::shared_ptr<const PlanarGridMap> getMap() const
  {
    return state_.map;
  }

  /** \brief Writes the map file (.pgmap, PlanarGridMap::save()) under a shared lock;
   * safe from any thread.
   * \throws planar_grid::IOError when it cannot be written */
  void save(const std::string& path) const;

  /** \brief Empties the map and restarts the run (the odometry and every stage's
   * state too); waits for a frame under way on another thread and for the readers
   * under way. */
  void reset();

  /** \brief Frames integrated since construction or reset(). */
  [[nodiscard]] std::size_t getFrameCount() const { return frames_.load(); }

  /** \brief The poses of the integrated frames (world_T_camera), in order. Read it from
   * the thread that integrates. */
  const Trajectory& getTrajectory() const { return trajectory_; }

  /** \brief Per stage, in run order, its sums over the frames integrated since
   * construction or reset() (times, points, counters), as a planar_grid_pipeline run
   * reports them. Read it from the thread that integrates. */
  const std::vector<StageReport>& getStageReports() const { return stage_reports_; }

  /** \brief The stages the mapper was built from. */
  const MapperConfig& getConfig() const { return config_; }

  /** \brief Whether the mapper takes stereo pairs (integrateStereo()), rather than
   * point clouds and depth images (integrateCloud(), integrateDepth()). */
  bool takesStereo() const { return takes_stereo_; }

  /** \name The engine beneath a batch run (PipelineRunner)
   * A frame the caller has loaded (a Frame, with its pose or none) runs through the
   * stages in two parts: prepareFrame() runs the leading frame-local stages, which
   * touch only their frame, and may do so on another thread, a frame or two ahead;
   * integrateFrame() runs the rest, which carry state across frames and change the map.
   * The checks and the frame numbering of the live calls are the caller's: the frame
   * keeps its name, its position (Frame::sequence_number) and its pose. */
  ///@{

  /** \brief Number of stages. */
  [[nodiscard]] std::size_t getStageCount() const { return stages_.size(); }

  /** \brief Stage \a s, in run order (e.g. to ask Stage::supportsCheckpoint()).
   * \param[in] s the stage's index, < getStageCount() */
  [[nodiscard]] const Stage& getStage(std::size_t s) const { return *stages_.at(s); }

  /** \brief Number of leading stages that are frame-local (Stage::isFrameLocal(): in
   * the main job stereo_disparity and feature_matching): they read and write only the
   * frame and their own members, so prepareFrame() may run them on another thread
   * while integrateFrame() runs earlier frames through the stages after them. */
  [[nodiscard]] std::size_t getFrameLocalStageCount() const;

  /** \brief Runs stages progress.stages.size() to \a stage_end - 1 on \a frame,
   * without the map or the state carried across frames, and appends what each did to
   * \a progress. Safe on another thread while integrateFrame() runs other frames
   * through the stages from \a stage_end on; one prepareFrame() at a time, the frames
   * in their order.
   * \param[in,out] frame a loaded frame; its name and sequence_number are named in
   * errors
   * \param[in] stage_end one past the last stage to run, <= getFrameLocalStageCount()
   * \param[in,out] progress the frame's way through the stages so far (empty for a new
   * frame)
   * \param[in] callback called right before each stage (none when empty)
   * \throws planar_grid::Exception naming the frame and stage when a stage fails, or
   * when \a stage_end is past the frame-local stages */
  void prepareFrame(Frame& frame,
                    std::size_t stage_end,
                    StageProgress& progress,
                    const StageCallback& callback);

  /** \brief Runs the stages from progress.stages.size() to the end on \a frame, as
   * the live calls do (the map's lock, the sums of getStageReports()), then appends its
   * pose to the trajectory (when Frame::has_pose, which visual_odometry sets) and
   * counts the frame. The frame carries its pose: Frame::has_pose and
   * Frame::world_T_camera (meters), or none when a stage estimates it. Nothing is
   * checked of the frame or its pose, and its name and sequence_number stay as they
   * are. \param[in,out] frame a loaded frame, after prepareFrame() of the same \a
   * progress or none \param[in,out] progress the frame's way through the stages so far;
   * on return one entry per stage \param[in] callback called right before each stage
   * (none when empty), on this thread \throws planar_grid::Exception naming the frame
   * and stage when a stage fails, or before the stages have started
   * (StageChecks::PIPELINE: call reset() first) */
  void
  integrateFrame(Frame& frame, StageProgress& progress, const StageCallback& callback);

  /** \brief Ends the run: calls every stage's Stage::finish() (e.g. to complete the
   * state carried across frames), in order.
   * \return each stage's wall time in it, milliseconds, in stage order */
  std::vector<double> finish();

  /** \brief Each stage's state carried across frames (Stage::saveState()), in stage
   * order, for a checkpoint. Read it from the thread that integrates, between frames.
   */
  [[nodiscard]] std::vector<std::vector<std::uint8_t>> saveStageStates() const;

  /** \brief Continues a run from a checkpoint, after reset(): the state carried across
   * frames (the map among it), the trajectory, each stage's state (saveStageStates()
   * of the same stages) and the number of frames run. getStageReports() counts from
   * here.
   * \param[in] state the state the checkpoint's run had
   * \param[in] trajectory its poses
   * \param[in] stage_states one per stage, in order
   * \param[in] frames the frames it ran
   * \throws planar_grid::Exception when the number of stage states differs from
   * getStageCount(), or a stage rejects its state */
  void resume(PipelineState state,
              Trajectory trajectory,
              const std::vector<std::vector<std::uint8_t>>& stage_states,
              std::size_t frames);

  /** \brief The state the stages carry across frames (the map, the accumulated clouds
   * and planes). Read it from the thread that integrates, between frames. */
  [[nodiscard]] const PipelineState& getState() const { return state_; }

  ///@}

private:
  /** \brief Checks a stereo pair and runs it through the stages; no pose: the
   * odometry's. */
  FrameStats integrateStereoPair(const cv::Mat& left,
                                 const cv::Mat& right,
                                 const StereoCalibration& calibration,
                                 const Eigen::Isometry3d* world_T_camera);

  /** \brief Runs \a frame through the stages with \a world_T_camera (none: the
   * odometry's); the common end of the integrate calls. */
  FrameStats integrate(Frame& frame, const Eigen::Isometry3d* world_T_camera);

  /** \brief Runs \a frame through the stages from progress.stages.size() on, holding
   * readers out of the map while a stage changes it, adds them to the sums and counts
   * the frame; the frame lock is the caller's. */
  void runStages(Frame& frame, StageProgress& progress, const StageCallback& callback);

  /** \brief Throws unless the mapper takes stereo pairs (\a stereo) or clouds. */
  void requireInput(bool stereo, const char* call) const;

  /** \brief Builds the stage of \a spec (of registry entry \a info, its parameters
   * complete) at the end of the stages and records what it reads and writes. */
  void addStage(const StageSpec& spec, const StageInfo& info);

  /** \brief Clears the map, the state, the trajectory and the sums, and starts every
   * stage. */
  void start();

  /** \brief "the pipeline", and the configuration's name when it has one. */
  std::string pipelineName() const;

  /** \brief The stages the mapper was built from. */
  MapperConfig config_;
  /** \brief The stages, in run order. */
  std::vector<std::unique_ptr<Stage>> stages_;
  /** \brief What the stages carry across frames, the map among it. */
  PipelineState state_;
  /** \brief The poses of the integrated frames. */
  Trajectory trajectory_;
  /** \brief Per stage, its sums over the integrated frames. */
  std::vector<StageReport> stage_reports_;
  /** \brief Whether a stage reads stereo images: the mapper takes stereo pairs. */
  bool takes_stereo_{false};
  /** \brief The state given to the stages prepareFrame() runs, which never read it. */
  PipelineState unused_state_;
  /** \brief Per stage: whether it changes the map (readers are locked out). */
  std::vector<bool> writes_map_;
  /** \brief Whether a stage estimates the poses (visual_odometry). */
  bool estimates_poses_{false};
  /** \brief Whether a stage needs the poses. */
  bool needs_poses_{false};
  /** \brief Whether the stages have started (the constructor, or reset() with
   * StageChecks::PIPELINE). */
  bool started_{false};
  /** \brief Frames integrated since the start of the run. */
  std::atomic<std::size_t> frames_{0};
  /** \brief Held through each integrate call and reset(): one frame at a time. */
  std::mutex frame_mutex_;
  /** \brief The stereo images' size (integrateStereo()). */
  cv::Size image_size_;
  /** \brief Guards the map: shared for readers, exclusive while a stage changes it. */
  mutable WriterPreferringSharedMutex map_mutex_;
  /** \brief The exclusive lock of the frame under way (owned between the stages that
   * change the map). */
  std::unique_lock<WriterPreferringSharedMutex> write_lock_{map_mutex_,
                                                            std::defer_lock};
  /** \brief Wall time the frame under way waited for readers, milliseconds. */
  double lock_wait_ms_{0.0};
  /** \brief Wall time the frame under way held readers out, milliseconds. */
  double exclusive_ms_{0.0};
  /** \brief When the frame under way took the exclusive lock. */
  std::chrono::steady_clock::time_point locked_at_;
};

} // namespace planar_grid
