// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief How a cloud is coloured. \ingroup visualization */
enum class ColorMode {
  /** By world z (height), with a perceptual colour map over the cloud's z range. */
  HEIGHT,
  /** By the intensity field (grey). */
  INTENSITY,
  /** One fixed colour. */
  SOLID
};

/** \brief A VTK camera: where it is, what it looks at, which way is up (world frame,
  * metres) and the vertical view angle (degrees). \ingroup visualization */
struct CameraParameters {
  Eigen::Vector3d position{0.0, 0.0, 10.0};
  Eigen::Vector3d focal_point{0.0, 0.0, 0.0};
  Eigen::Vector3d view_up{0.0, 1.0, 0.0};
  double view_angle_deg{30.0};
};

/** \brief Camera presets framing everything added so far. \ingroup visualization */
enum class CameraPreset {
  /** Looking straight down -z (a map view), x to the right. */
  TOP,
  /** From above and behind the scene's centre at 45 degrees. */
  OBLIQUE
};

/** \brief Renders data (clouds, trajectories) with VTK, interactively or offscreen to PNG.
  * It takes data, never algorithms (S34). Only this target links VTK.
  * Debian's VTK 9.1 needs an X server even offscreen: call ensureDisplay() first.
  * \ingroup visualization */
class SceneRenderer {
public:
  SceneRenderer();
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer&
  operator=(const SceneRenderer&) = delete;

  /** \brief Adds a cloud; NaN points are skipped.
    * \param[in] cloud points in the world frame, metres
    * \param[in] mode colouring
    * \param[in] point_size_px rendered point size, px
    * \param[in] rgb colour for ColorMode::SOLID, components in [0, 1] */
  void
  addPointCloud(const pcl::PointCloud<pcl::PointXYZI>& cloud,
                ColorMode mode = ColorMode::HEIGHT,
                double point_size_px = 2.0,
                const Eigen::Vector3d& rgb = Eigen::Vector3d(1.0, 1.0, 1.0));

  /** \brief Adds a polyline through camera positions (world frame, metres).
    * \param[in] positions the positions in order
    * \param[in] rgb line colour, components in [0, 1]
    * \param[in] line_width_px line width, px */
  void
  addTrajectory(const std::vector<Eigen::Vector3d>& positions,
                const Eigen::Vector3d& rgb = Eigen::Vector3d(1.0, 0.2, 0.2),
                double line_width_px = 3.0);

  /** \brief Adds a text label in the top-left corner. */
  void
  addText(const std::string& text);

  /** \brief Sets the background colour, components in [0, 1]. */
  void
  setBackground(const Eigen::Vector3d& rgb);

  /** \brief Uses an explicit camera. */
  void
  setCamera(const CameraParameters& camera);

  /** \brief Frames everything added so far from a preset direction. */
  void
  setCamera(CameraPreset preset);

  /** \brief Renders offscreen and writes a PNG (vtkWindowToImageFilter + vtkPNGWriter,
    * as pcl::visualization::PCLVisualizer::saveScreenshot), atomically.
    * \param[in] path the PNG file
    * \param[in] width_px image width, px
    * \param[in] height_px image height, px
    * \throws planar_grid::Exception when there is no display (see ensureDisplay()) or the
    *         file cannot be written */
  void
  saveSnapshot(const std::string& path, int width_px = 1600, int height_px = 1000);

  /** \brief Opens an interactive window and returns when it is closed.
    * \throws planar_grid::Exception when there is no display */
  void
  show(int width_px = 1280, int height_px = 800);

private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

/** \brief True when an X display can be opened (DISPLAY is set and answers).
  * \ingroup visualization */
bool
hasDisplay();

/** \brief Makes sure VTK can render: returns when a display is available; otherwise, when
  * `xvfb-run` is on the PATH, re-executes the current program under `xvfb-run -a` with the
  * same arguments (it does not return then); otherwise throws planar_grid::Exception
  * saying to install xvfb and run the command under `xvfb-run -a`. Never lets VTK abort
  * the process for lack of a display.
  * \param[in] argc, argv the program's arguments, as given to main */
void
ensureDisplay(int argc, char** argv);

} // namespace planar_grid
