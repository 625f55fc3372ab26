// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>
#include <planar_grid/map/planar_grid_map.h>

#include <pcl/PolygonMesh.h>
#include <pcl/point_cloud.h>
#include <pcl/point_types.h>

#include <Eigen/Core>

#include <memory>
#include <string>
#include <vector>

namespace planar_grid {

/** \brief How a cloud is coloured. \ingroup visualization */
enum class ColorMode {
  /** By world z (height) with the Turbo colour map (blue low, green, yellow, red high;
   * its near-black ends left out) over the cloud's 2nd..98th percentile of z, so that
   * a few outliers do not wash it out. */
  HEIGHT,
  /** By the intensity field, grey from dark (2nd percentile) to white (98th
   * percentile); a constant intensity renders mid grey. */
  INTENSITY,
  /** One fixed colour. */
  SOLID,
  /** By the integer value of the intensity field taken as a label (e.g. a plane id):
   * one of 12 distinct colours per label (golden-ratio hue steps). */
  LABEL
};

/** \brief A VTK camera: where it is, what it looks at, which way is up (world frame,
 * metres) and the vertical view angle (degrees). \ingroup visualization */
struct CameraParameters {
  /** \brief Camera centre, metres. */
  Eigen::Vector3d position{0.0, 0.0, 10.0};
  /** \brief The point looked at, metres; must differ from position. */
  Eigen::Vector3d focal_point{0.0, 0.0, 0.0};
  /** \brief Up direction in the image; not parallel to the viewing direction. */
  Eigen::Vector3d view_up{0.0, 1.0, 0.0};
  /** \brief Vertical field of view, degrees, in (0, 180). */
  double view_angle_deg{30.0};
};

/** \brief Camera presets framing everything added so far. \ingroup visualization */
enum class CameraPreset {
  /** Looking straight down -z (a map view), x to the right, y up in the image. */
  TOP,
  /** From above and behind (-y) the scene's centre at 45 degrees elevation, looking
   * along +y, z up in the image. */
  OBLIQUE
};

/** \brief How addCuboids() colours the cells. \ingroup visualization */
enum class CuboidColorMode {
  /** \brief One colour per plane_id (the LABEL palette); non-planar cells grey. */
  PLANE,
  /** \brief By the cell's occupancy probability (Turbo ramp over [0, 1]). */
  OCCUPANCY,
  /** \brief One given colour. */
  SOLID
};

/** \brief What SceneRenderer::addMap() drew. \ingroup visualization */
struct MapRenderSummary {
  /** \brief Cuboids of the surface layer. */
  std::size_t cuboids{0};
  /** \brief Occupied voxels not covered by a cuboid. */
  std::size_t occupied_voxel_boxes{0};
  /** \brief Coarse boxes of unknown space. */
  std::size_t unknown_boxes{0};
};

/** \brief Renders data (clouds, trajectories) with VTK, interactively or offscreen to
 * PNG. It takes data, never algorithms, so that drawing
 * cannot change a result. Only this target links VTK. Debian's
 * VTK 9.1 needs an X server even offscreen: call ensureDisplay() first. Without any
 * camera call, the scene is framed with CameraPreset::TOP; the background is black. An
 * empty scene renders as background only. \ingroup visualization */
class SceneRenderer {
public:
  /** \brief An empty scene; opens no window (no display is needed until rendering). */
  SceneRenderer();
  /** \brief Releases the VTK objects. */
  ~SceneRenderer();
  SceneRenderer(const SceneRenderer&) = delete;
  SceneRenderer& operator=(const SceneRenderer&) = delete;

  /** \brief Adds a cloud; NaN points are skipped. Copies the data once into VTK arrays
   * (no per-point allocation), so clouds of millions of points are fine.
   * \param[in] cloud points in the world frame, metres
   * \param[in] mode colouring
   * \param[in] point_size_px rendered point size, px, > 0
   * \param[in] rgb colour for ColorMode::SOLID, components in [0, 1]
   * \note A cloud without finite points adds nothing and prints a PCL_WARN.
   * \throws planar_grid::Exception when point_size_px <= 0 */
  void addPointCloud(const pcl::PointCloud<pcl::PointXYZI>& cloud,
                     ColorMode mode = ColorMode::HEIGHT,
                     double point_size_px = 2.0,
                     const Eigen::Vector3d& rgb = Eigen::Vector3d(1.0, 1.0, 1.0));

  /** \brief Adds cuboids (PlanarCuboid, paper Figs. 6-7) as oriented boxes, all in one
   * VTK actor (six quads each).
   * Planar cells take one colour per plane_id (the ColorMode::LABEL palette),
   * non-planar cells (plane_id < 0) \a non_planar_rgb. \param[in] cuboids the cells,
   * world frame, metres \param[in] wireframe draw the edges only \param[in] opacity in
   * (0, 1] \param[in] non_planar_rgb colour of the non-planar cells, components in [0,
   * 1] \throws planar_grid::Exception when opacity is outside (0, 1] */
  void
  addCuboids(const PlanarCuboids& cuboids,
             bool wireframe = false,
             double opacity = 1.0,
             const Eigen::Vector3d& non_planar_rgb = Eigen::Vector3d(0.6, 0.6, 0.6));

  /** \brief Adds cuboids as oriented boxes, coloured by \a mode: PLANE as the
   * overload above (non-planar cells \a rgb), OCCUPANCY by probability on the Turbo
   * ramp (0 dark blue, 0.5 green, 1 red), SOLID all \a rgb. A translucent actor
   * (opacity < 1) culls back faces. \param[in] cuboids the cells, world frame, metres
   * \param[in] mode colouring \param[in] wireframe draw the edges only
   * \param[in] opacity in (0, 1] \param[in] rgb colour, components in [0, 1]
   * \throws planar_grid::Exception when opacity is outside (0, 1] */
  void addCuboids(const PlanarCuboids& cuboids,
                  CuboidColorMode mode,
                  bool wireframe = false,
                  double opacity = 1.0,
                  const Eigen::Vector3d& rgb = Eigen::Vector3d(0.6, 0.6, 0.6));

  /** \brief Adds a PlanarGridMap: the surface layer's cuboids coloured by
   * \a cuboid_color (by default by occupancy, Turbo ramp), the occupied voxels of the
   * space layer that no cuboid covers as dark grey boxes (runs along x and equal runs
   * of consecutive rows joined: the same volume in a fraction of the polygons), and the
   * unknown space as translucent violet boxes of 8 voxels' edge (one per 8^3-voxel
   * region holding an unknown voxel). Free space is not drawn. \param[in] map the map
   * \param[in] cuboid_color the cuboids' colouring (PLANE: one colour per plane,
   * non-planar grey; SOLID: grey)
   * \param[in] unknown_opacity opacity of the unknown boxes, in [0, 1] (0: not drawn)
   * \param[in] max_voxel_boxes most occupied-voxel and unknown boxes drawn (each)
   * \return what was drawn \throws planar_grid::Exception when unknown_opacity is
   * outside [0, 1] */
  MapRenderSummary addMap(const PlanarGridMap& map,
                          CuboidColorMode cuboid_color = CuboidColorMode::OCCUPANCY,
                          double unknown_opacity = 0.15,
                          std::size_t max_voxel_boxes = 2000000);

  /** \brief Adds a polygon mesh (e.g. a PLY file read with loadPLYMesh()) as one
   * actor: its faces coloured per vertex by the mesh's rgb fields when it has them
   * (PLY red / green / blue), else by height (the ColorMode::HEIGHT ramp). A mesh
   * without polygons draws its vertices as points. Faces with a non-finite vertex are
   * skipped. \param[in] mesh vertices in mesh.cloud (x, y, z in metres, optional rgb
   * or rgba), polygons as indices into them \param[in] opacity in (0, 1] \return the
   * number of faces drawn \throws planar_grid::Exception when opacity is outside (0,
   * 1], the cloud has no x, y, z or a polygon refers to a missing vertex */
  std::size_t addPolygonMesh(const pcl::PolygonMesh& mesh, double opacity = 1.0);

  /** \brief Adds a polyline through camera positions (world frame, metres).
   * \param[in] positions the positions in order
   * \param[in] rgb line colour, components in [0, 1]
   * \param[in] line_width_px line width, px, > 0
   * \note Non-finite positions are skipped; with fewer than 2 left nothing is added
   *       and a PCL_WARN is printed.
   * \throws planar_grid::Exception when line_width_px <= 0 */
  void addTrajectory(const std::vector<Eigen::Vector3d>& positions,
                     const Eigen::Vector3d& rgb = Eigen::Vector3d(1.0, 0.2, 0.2),
                     double line_width_px = 3.0);

  /** \brief Adds a text label in the top-left corner; further labels stack below it.
   * \param[in] text the label
   * \param[in] rgb text colour, components in [0, 1] (white by default; use a dark
   * colour on a light background) */
  void addText(const std::string& text,
               const Eigen::Vector3d& rgb = Eigen::Vector3d(1.0, 1.0, 1.0));

  /** \brief Sets the background colour (default black).
   * \param[in] rgb components in [0, 1] */
  void setBackground(const Eigen::Vector3d& rgb);

  /** \brief Uses an explicit camera (replaces any preset).
   * \param[in] camera the camera
   * \throws planar_grid::Exception when a vector is not finite, position equals
   *         focal_point, view_up is zero or parallel to the viewing direction, or the
   *         view angle is outside (0, 180) degrees */
  void setCamera(const CameraParameters& camera);

  /** \brief Frames everything in the scene from a preset direction (replaces any
   * explicit camera); the framing is computed at render time, for the image size.
   * \param[in] preset the direction */
  void setCamera(CameraPreset preset);

  /** \brief Renders offscreen and writes a PNG (vtkWindowToImageFilter + vtkPNGWriter,
   * as pcl::visualization::PCLVisualizer::saveScreenshot), atomically.
   * \param[in] path the PNG file
   * \param[in] width_px image width, px, > 0
   * \param[in] height_px image height, px, > 0
   * \throws planar_grid::Exception when there is no display (see ensureDisplay()) or
   *         the size is not positive; planar_grid::IOError when the file cannot be
   *         written (its folder is missing, ...), leaving no file behind */
  void saveSnapshot(const std::string& path, int width_px = 1600, int height_px = 1000);

  /** \brief Opens an interactive window (trackball camera: left drag rotates, wheel
   * zooms, 'q' quits) and returns when it is closed.
   * \param[in] width_px window width, px, > 0
   * \param[in] height_px window height, px, > 0
   * \throws planar_grid::Exception when there is no display or the size is not
   *         positive */
  void show(int width_px = 1280, int height_px = 800);

private:
  /** \brief The VTK objects (VTK stays out of this header, so that code including it
   * needs no VTK headers). */
  struct Impl;
  /** \brief The implementation. */
  std::unique_ptr<Impl> impl_;
};

/** \brief True when an X display can be opened (DISPLAY is set and answers).
 * \return whether VTK can render (on screen or offscreen)
 * \note The first successful check keeps its X connection open until the process
 *       exits, so that the X server (e.g. Xvfb) cannot reset between this check and
 *       VTK's own connection (VTK aborts when it cannot connect).
 * \ingroup visualization */
bool hasDisplay();

/** \brief Makes sure VTK can render: returns when a display is available; otherwise
 * starts `Xvfb -displayfd` as a child of this process, sets DISPLAY to the display it
 * picked and returns; otherwise throws planar_grid::Exception saying to install xvfb
 * and run the command under `xvfb-run -a`. Never lets VTK abort the process for lack
 * of a display. The program is not re-executed under a wrapper: its exit code is its
 * own, and the kernel stops the server when the program ends, however it ends
 * (PR_SET_PDEATHSIG), so that no Xvfb outlives it. Call it from the main thread (the
 * server gets SIGTERM when the thread that started it ends).
 * \param[in] argc the argument count, as given to main (unused; kept for callers)
 * \param[in] argv the program's arguments, as given to main (unused)
 * \throws planar_grid::Exception when no display can be provided
 * \ingroup visualization */
void ensureDisplay(int argc, char** argv);

} // namespace planar_grid
