// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/stereo/calibration_io.h>

#include <array>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief Where an input's camera poses come from (input.poses.format); every reader
 * gives them in the z-up world (docs/INPUTS.md). \ingroup pipeline */
enum class PoseFormat {
  /** "none": no poses. */
  NONE,
  /** "odometry": estimated by the visual_odometry stage (stereo input). */
  ODOMETRY,
  /** "karlsruhe_insdata": the Karlsruhe sequences' GPS/INS file (stereo input). */
  KARLSRUHE_INSDATA,
  /** "kitti": world_T_camera per frame in KITTI's world, the first camera's optical
   * frame; converted to the z-up world. */
  KITTI,
  /** "euroc_groundtruth": EuRoC gt_body_poses.txt, world_T_body by image index, with
   * the euroc calibration's T_BS and rectification (stereo input). */
  EUROC_GROUNDTRUTH,
  /** "viewpoint": each PCD file's VIEWPOINT (PCD input). */
  VIEWPOINT,
  /** "registration": frame-to-frame GICP of the PCD files (PCD input). */
  REGISTRATION,
  /** "tf": along a /tf chain of a ROS bag (ros_bag input). */
  TF,
};

/** \brief Where frames come from. \ingroup pipeline */
struct InputConfig {
  /** \brief The kind of input. */
  enum class Type {
    /** Rectified (or raw, with a calibration that rectifies) stereo image pairs. */
    STEREO_SEQUENCE,
    /** PCD files, each with its VIEWPOINT as the sensor pose. */
    PCD_FILES
  };
  /** \brief The kind of input. */
  Type type{Type::STEREO_SEQUENCE};

  /** \brief Left image paths with one printf-style index field (%d or %0Nd),
   * resolved against the config file's folder. */
  std::string left_images;
  /** \brief Right image paths, as left_images. */
  std::string right_images;
  /** \brief Index of the first frame in the file names. */
  int first_index{0};
  /** \brief Number of frames; 0 = every index until the first missing left image. */
  int frame_count{0};

  /** \brief Calibration format (stereo input). */
  CalibrationFormat calibration_format{CalibrationFormat::KARLSRUHE};
  /** \brief Calibration file (the left camera's for ros_camera_info and euroc). */
  std::string calibration_file;
  /** \brief The right camera's calibration file (ros_camera_info and euroc only). */
  std::string calibration_right_file;

  /** \brief Where the poses come from: for stereo input NONE, ODOMETRY,
   * KARLSRUHE_INSDATA, KITTI or EUROC_GROUNDTRUTH (world_T_camera = world_T_body *
   * body_T_left * rectified_R_left^T); for PCD input VIEWPOINT (the default there: see
   * docs/INPUTS.md), REGISTRATION, KITTI or NONE; for a ROS bag TF, ODOMETRY (stereo)
   * or NONE. */
  PoseFormat poses_format{PoseFormat::NONE};
  /** \brief Poses file ("" for none and viewpoint). */
  std::string poses_file;
  /** \brief karlsruhe_insdata only: the camera's height above the road, metres (the
   * world origin is put on the road below the first pose, so the ground is at z = 0).
   */
  double camera_height_m{0.0};
  /** \brief karlsruhe_insdata only: the camera's downward pitch from level, radians
   * (positive = looking down); the insdata poses are level along the track. */
  double camera_pitch_rad{0.0};

  /** \brief PCD input: files or glob patterns, resolved against the config's folder and
   * sorted by name within each pattern. */
  std::vector<std::string> pcd_files;

  /** \brief PCD input: the up direction in the first file's sensor frame
   * (input.sensor_up, non-zero, need not be unit), used where no pose fixes "up"
   * (registration, or one file with PCL's default VIEWPOINT) instead of estimating it
   * from the floor. */
  std::array<double, 3> sensor_up{{0.0, 0.0, 0.0}};
  /** \brief True when input.sensor_up was given. */
  bool has_sensor_up{false};

  /** \brief registration only: voxel edge the clouds are registered at, metres
   * (input.poses.leaf_size_m). */
  double registration_leaf_size_m{0.05};
  /** \brief registration only: the coarse GICP pass's correspondence distance, metres
   * (input.poses.max_correspondence_distance_m). */
  double registration_max_correspondence_distance_m{0.5};
  /** \brief registration only: also try an FPFH feature guess
   * (input.poses.feature_initial_guess). */
  bool registration_feature_initial_guess{true};
  /** \brief registration only: a pair whose point-to-plane residual exceeds this is
   * flagged with a warning, metres (input.poses.max_residual_m). */
  double registration_max_residual_m{0.05};

  /** \brief Passes over the frames (input.repeat.count, >= 1): the input is run this
   * many times in a row, e.g. to test a long run. */
  int repeat_count{1};
  /** \brief Added to the poses' positions once per pass after the first, meters
   * (input.repeat.offset_m; zero: each pass revisits the same place). */
  std::array<double, 3> repeat_offset_m{{0.0, 0.0, 0.0}};

  /** \brief A ROS 1 bag as the input (input.type ros_bag, docs/INPUTS.md): its frames
   * are stereo pairs (type STEREO_SEQUENCE) or point clouds (type PCD_FILES), read
   * with Debian's rosbag_storage. Empty file: the input is not a bag. */
  struct RosBag {
    /** \brief The bag file, resolved against the config file's folder. */
    std::string file;
    /** \brief Stereo: the rectified left sensor_msgs/Image topic. */
    std::string left_image_topic;
    /** \brief Stereo: the rectified right sensor_msgs/Image topic. */
    std::string right_image_topic;
    /** \brief Stereo: the left sensor_msgs/CameraInfo topic; its projection matrix P
     * gives f, cx and cy. */
    std::string left_info_topic;
    /** \brief Stereo: the right sensor_msgs/CameraInfo topic; B = -P_right[0][3] /
     * P_right[0][0]. */
    std::string right_info_topic;
    /** \brief Stereo: a left and a right image pair up when their header stamps
     * differ by at most this, seconds (0: equal stamps). */
    double pair_tolerance_s{0.0};
    /** \brief Clouds: the sensor_msgs/PointCloud2 topic. */
    std::string cloud_topic;
    /** \brief Poses (input.poses.format tf): the tf2_msgs/TFMessage topic of moving
     * transforms; the frames' pose is parent_frame_T_child_frame through the chain of
     * transforms. */
    std::string tf_topic{"/tf"};
    /** \brief Poses: the tf2_msgs/TFMessage topic of static transforms. */
    std::string tf_static_topic{"/tf_static"};
    /** \brief Poses: the world frame (z up). */
    std::string parent_frame;
    /** \brief Poses: the camera's (or sensor's) frame. */
    std::string child_frame;
    /** \brief Poses: how far a frame's stamp may lie outside a transform's samples,
     * seconds (between samples the transform is interpolated). */
    double tf_tolerance_s{0.05};
  };
  /** \brief The ROS bag input (file empty for the other inputs). */
  RosBag ros_bag;
};

/** \brief True when this build reads ROS 1 bags (input.type ros_bag: Debian's
 * rosbag_storage was found at configure time and PLANAR_GRID_WITH_ROS_BAG is on);
 * otherwise a ros_bag input is a planar_grid::ConfigError. */
bool rosBagSupported();

} // namespace planar_grid
