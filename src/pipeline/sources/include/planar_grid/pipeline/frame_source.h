// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/odometry/trajectory_io.h>
#include <planar_grid/pipeline/frame.h>
#include <planar_grid/pipeline/input_config.h>

#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief A file a run reads, and what it is to the run in the configuration's words
 * ("the poses file (input.poses.file)"), for messages. \ingroup pipeline */
struct InputFile {
  /** \brief The file's path, as the configuration resolved it. */
  std::string path;
  /** \brief What the file is to the run. */
  std::string what;
};

/** \brief Produces the frames of an input, by position. \ingroup pipeline */
class FrameSource {
public:
  virtual ~FrameSource() = default;

  /** \brief Number of frames. */
  virtual std::size_t size() const = 0;

  /** \brief Loads frame \a i (0-based) into \a frame (images or cloud, calibration,
   * pose). \throws planar_grid::IOError naming the file when it is missing, unreadable,
   * or of the wrong size */
  virtual void load(std::size_t i, Frame& frame) const = 0;

  /** \brief A short description for the console ("112 stereo pairs from ..."). */
  virtual std::string describe() const = 0;

  /** \brief The poses of all frames (empty when the input has none). */
  virtual const Trajectory& poses() const = 0;

  /** \brief The camera of stereo frames, as the frames will have it (the rectified
   * calibration, its width and height the images' size), known before the first frame
   * is processed.
   * \param[out] calibration the camera
   * \return false for point clouds, or when the image size is not known yet */
  virtual bool camera(StereoCalibration& calibration) const
  {
    (void)calibration;
    return false;
  }

  /** \brief Every file the input reads: each frame's images or cloud, the
   * calibration, the poses file, the ROS bag (the configuration file is not the
   * input's). */
  virtual std::vector<InputFile> files() const = 0;

  /** \brief The files frame \a i (0-based) reads: its images or its cloud (none for
   * a ROS bag's frames, which live in the bag). A checkpoint records their size and
   * hash, so that a resume finds a frame file that changed since. */
  virtual std::vector<InputFile> frameFiles(std::size_t i) const
  {
    (void)i;
    return {};
  }
};

/** \brief The frame source of an input configuration: checks that the files exist, that
 * the calibration loads and that there are as many poses as frames (a shorter pose file
 * is an error) before any frame is processed. Every pose is in the z-up world
 * (docs/INPUTS.md): KITTI poses and PCD VIEWPOINTs are converted from their own
 * conventions; PCD files whose VIEWPOINTs fix no pose are levelled on their floor
 * (planar_grid::estimateFloorPlane()) or by input.sensor_up, and with
 * input.poses.format registration they are first registered frame to frame
 * (planar_grid::registerCloud(), which reads every file once here).
 * \throws planar_grid::IOError, also for several PCD files whose VIEWPOINTs are all the
 * same under format viewpoint (their motion is unknown); planar_grid::ConfigError */
std::unique_ptr<FrameSource> createFrameSource(const InputConfig& input);

} // namespace planar_grid
