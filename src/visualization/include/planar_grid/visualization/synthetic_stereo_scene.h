// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/stereo_calibration.h>

#include <pcl/memory.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <Eigen/StdVector>
#include <opencv2/core/mat.hpp>

#include <cstddef>
#include <cstdint>
#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief The two synthetic scenes. \ingroup visualization */
enum class SyntheticSceneKind {
  /** A corridor 2.5 m wide, 2.6 m high and 20 m long along the scene's +x: floor,
   * ceiling, two side walls (the left one, at +y, is the leaning wall), a wall at each
   * end, two pillars and a box against the right wall and a free-standing box on the
   * left. The camera walks along the centre line towards the far end. */
  CORRIDOR,
  /** A room 8 m (x) by 6 m (y) by 3 m: floor, ceiling, four walls (the far one, at
   * x = 8 m, is the leaning wall), a ramp rising along +x on the left and a table-like
   * box on the right. The camera walks along +x from near the back wall. */
  ROOM
};

/** \brief Parses "corridor" or "room"; throws planar_grid::Exception otherwise.
 * \ingroup visualization */
SyntheticSceneKind syntheticSceneKindFromString(const std::string& name);

/** \brief "corridor" or "room". \ingroup visualization */
std::string toString(SyntheticSceneKind kind);

/** \brief One true surface of a synthetic scene: a convex planar polygon.
 * \ingroup visualization */
struct SyntheticPlane {
  /** \brief What it is ("floor", "left_wall", "box1_top", ...), unique in a scene. */
  std::string name;
  /** \brief [a, b, c, d], world frame: unit normal (a, b, c) pointing into the free
   * space the camera moves in (out of a box), and d such that a x + b y + c z + d = 0
   * on the plane, in metres. */
  Eigen::Vector4d model_coefficients{Eigen::Vector4d::UnitZ()};
  /** \brief Angle between the normal and the nearest world axis (+-x, +-y, +-z),
   * radians, in [0, 0.9553]: 0 for a surface an axis-aligned cuboid fits exactly. With
   * the scene's yaw, a wall's tilt is the yaw folded into [0, pi/4]. */
  double tilt_rad{0.0};
  /** \brief The corners in the world frame, metres, counter-clockwise seen from the
   * normal's side (convex, on the plane). */
  std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>> polygon;
  /** \brief Seed of the plane's procedural texture. */
  std::uint64_t texture_seed{0};
};

/** \brief A synthetic stereo sequence with exactly known surfaces, for ground truth:
 * a corridor or a room of textured planar polygons rendered with VTK
 * offscreen into rectified left/right grey images with a Karlsruhe-like calibration,
 * along a known straight camera path.
 *
 * Frames: the world frame has z up and the floor at z = 0 (the pipeline's
 * convention). The scene is built in a scene frame (corridor axis along +x) and turned
 * by Params::scene_yaw_rad about world z; the camera path turns with it, so the images
 * do not depend on the yaw while every wall is at a known angle to the map axes. The
 * camera frame is x right, y down, z forward; poses are world_T_camera of the left
 * camera, which looks level along the scene's +x at Params::camera_height_m, moving
 * Params::step_m per frame. The right camera is baseline_m along the left camera's +x.
 *
 * Images: each surface carries its own procedural grey texture (multi-octave value
 * noise plus random blobs and strokes, about one texel per centimetre, texture
 * coordinates in metres on the plane), rendered without lighting (ambient 1, diffuse
 * 0, specular 0) with interpolation and mipmaps, so both views see the same
 * intensities and OpenCV SGBM and SIFT match well. The principal point is the image
 * centre, cx = (width - 1) / 2, cy = (height - 1) / 2 (pixel centres at integers, as
 * OpenCV counts), which is where VTK puts the optical axis.
 *
 * Rendering needs an X display (Debian's VTK 9.1; see ensureDisplay()); the geometry
 * (planes, poses, samplePoints(), distanceToSurface()) does not. Not thread-safe: one
 * VTK window per object. \ingroup visualization */
class SyntheticStereoScene {
public:
  /** \brief Scene and camera parameters with their defaults (the Karlsruhe
   * calibration: 1344 x 372 px, f = 645.24 px, B = 0.5707 m) and valid ranges. */
  struct Params {
    /** \brief Which scene. */
    SyntheticSceneKind kind{SyntheticSceneKind::CORRIDOR};
    /** \brief Rotation of the whole scene and of the camera path about world z,
     * radians, finite. */
    double scene_yaw_rad{0.0};
    /** \brief Lean of the leaning wall from vertical, radians, in [-pi/6, pi/6]: it
     * turns about its bottom edge, positive leans its top away from the camera path
     * (the corridor's left wall, the room's far wall). */
    double wall_lean_rad{0.0};
    /** \brief Number of frames, >= 1; the camera path must end at least 3 m before
     * the far wall (see the constructor). */
    int frame_count{20};
    /** \brief Camera motion per frame along the scene's +x, metres, >= 0. */
    double step_m{0.15};
    /** \brief Height of the camera above the floor, metres, in [0.3, 2.3]. */
    double camera_height_m{1.2};
    /** \brief Image width, px, in [16, 8192]. */
    int width_px{1344};
    /** \brief Image height, px, in [16, 8192]. */
    int height_px{372};
    /** \brief Focal length of both rectified cameras, px, > 0. */
    double focal_length_px{645.24};
    /** \brief Distance between the two optical centres, metres, > 0. */
    double baseline_m{0.5707};
    /** \brief Texel size of the procedural textures, metres, in [0.002, 0.1]. */
    double texel_m{0.01};
    /** \brief Seed of the textures: the same seed renders the same images. */
    std::uint64_t seed{1};
  };

  /** \brief Builds the scene's geometry (the textures are made at the first render).
   * \param[in] params the parameters
   * \throws planar_grid::Exception when a parameter is outside its range or the
   *         camera path leaves the scene (it must end at least 3 m before the far
   *         wall: start 1 m (corridor) or 0.8 m (room) from the near wall, plus
   *         (frame_count - 1) step_m) */
  explicit SyntheticStereoScene(const Params& params);
  /** \brief The default corridor. (Two constructors rather than a default argument:
   * GCC rejects `= Params()` for a nested struct with member initialisers.) */
  SyntheticStereoScene();
  /** \brief Releases the VTK window, if one was opened. */
  ~SyntheticStereoScene();
  SyntheticStereoScene(const SyntheticStereoScene&) = delete;
  SyntheticStereoScene& operator=(const SyntheticStereoScene&) = delete;

  /** \brief Returns the parameters. */
  const Params& getParams() const { return params_; }

  /** \brief Returns the rectified calibration of the pair: f, cx = (width - 1) / 2,
   * cy = (height - 1) / 2, baseline and image size. */
  const StereoCalibration& getCalibration() const { return calibration_; }

  /** \brief Returns the number of frames (Params::frame_count). */
  std::size_t getFrameCount() const
  {
    return static_cast<std::size_t>(params_.frame_count);
  }

  /** \brief Returns world_T_camera of the left camera at \a frame.
   * \throws planar_grid::Exception when frame >= getFrameCount() */
  Eigen::Isometry3d getCameraPose(std::size_t frame) const;

  /** \brief Returns the true surfaces, world frame. */
  const std::vector<SyntheticPlane>& getPlanes() const { return planes_; }

  /** \brief Renders the left and right rectified views of \a frame offscreen.
   * \param[in] frame the frame, < getFrameCount()
   * \param[out] left the left image, CV_8UC1, height_px x width_px
   * \param[out] right the right image, CV_8UC1, same size
   * \param[out] depth_m if not null: the left view's z depth (along the optical axis)
   *             from the z-buffer, CV_32FC1, metres, 0 where nothing was drawn; the
   *             true disparity is f B / z
   * \throws planar_grid::Exception when the frame is out of range or there is no X
   *         display (see ensureDisplay()) */
  void
  render(std::size_t frame, cv::Mat& left, cv::Mat& right, cv::Mat* depth_m = nullptr);

  /** \brief Samples every true surface on a square grid in its plane (the polygon's
   * texture axes), world frame; for the mapping-error ground truth.
   * \param[in] spacing_m grid spacing, metres, > 0
   * \param[out] cloud the points (replaced), unorganized, dense
   * \throws planar_grid::Exception when spacing_m is not positive or would give more
   *         than 200 million points */
  void samplePoints(double spacing_m, pcl::PointCloud<pcl::PointXYZ>& cloud) const;

  /** \brief Exact Euclidean distance from \a point to the nearest true surface (point
   * to convex polygon, not to the infinite plane).
   * \param[in] point world frame, metres
   * \return the distance, metres (+inf for a non-finite point) */
  [[nodiscard]] double distanceToSurface(const Eigen::Vector3d& point) const;

  /** \brief Writes the whole sequence to \a folder (created if missing): left/%06d.png
   * and right/%06d.png (every frame rendered), calib.txt in the Karlsruhe format
   * (P1_roi / P2_roi rows), poses.txt (KITTI: world_T_camera, 3x4 per line),
   * truth.pcd (samplePoints() at 0.02 m, binary), scene.json (planes with
   * model_coefficients, tilt, polygon; yaw, lean, calibration, path) and pipeline.yaml
   * (a pipeline for this sequence modelled on config/karlsruhe.yaml, writing to
   * `<folder>/output`). Each file is written atomically.
   * \param[in] folder the output folder
   * \throws planar_grid::IOError when a file cannot be written;
   *         planar_grid::Exception when there is no X display */
  void writeSequence(const std::string& folder);

  /** \brief The pipeline configuration writeSequence() saves as pipeline.yaml: input
   * stereo_sequence with left/%06d.png, right/%06d.png, `calibration: {format:
   * karlsruhe}`, `poses: {format: kitti, file: poses.txt}`, the stages of
   * config/karlsruhe.yaml with indoor ranges, output to \a output_folder.
   * \param[in] output_folder the output.folder value
   * \return the YAML text */
  std::string pipelineYaml(const std::string& output_folder) const;

  PCL_MAKE_ALIGNED_OPERATOR_NEW

private:
  /** \brief Adds a plane from its corners in the scene frame (any winding) and a point
   * on its free side (\a free_side), which fixes the normal's sign. */
  void addPlane(const std::string& name,
                const std::vector<Eigen::Vector3d,
                                  Eigen::aligned_allocator<Eigen::Vector3d>>& corners,
                const Eigen::Vector3d& free_side);
  /** \brief Adds the faces of the box [lo, hi] (scene frame) named in \a faces, a
   * string of letters: x/X = face at lo.x()/hi.x(), y/Y, z/Z likewise. */
  void addBox(const std::string& name,
              const Eigen::Vector3d& lo,
              const Eigen::Vector3d& hi,
              const std::string& faces);
  /** \brief Builds the corridor's planes (scene frame, then turned by the yaw). */
  void buildCorridor();
  /** \brief Builds the room's planes. */
  void buildRoom();

  /** \brief The parameters. */
  Params params_;
  /** \brief The rectified calibration. */
  StereoCalibration calibration_;
  /** \brief world_T_scene: the yaw about world z. */
  Eigen::Isometry3d world_T_scene_{Eigen::Isometry3d::Identity()};
  /** \brief Where the camera path starts along the scene's x, metres. */
  double path_start_x_m_{0.0};
  /** \brief The true surfaces, world frame. */
  std::vector<SyntheticPlane> planes_;
  /** \brief Texture frame of each plane in the world frame: origin, u and v axes (unit,
   * in-plane, u x v = normal) and the (u, v) extent of the polygon, metres. */
  struct TextureFrame {
    Eigen::Vector3d origin;
    Eigen::Vector3d u_axis;
    Eigen::Vector3d v_axis;
    double u_min, u_max, v_min, v_max;
  };
  /** \brief One TextureFrame per plane. */
  std::vector<TextureFrame> texture_frames_;
  /** \brief The VTK objects, made at the first render (VTK stays out of this header,
   * so that code including it needs no VTK headers). */
  struct Impl;
  /** \brief The implementation. */
  std::unique_ptr<Impl> impl_;
};

} // namespace planar_grid
