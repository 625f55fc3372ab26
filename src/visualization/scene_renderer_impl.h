// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of SceneRenderer: its private state and a finiteness test.
#pragma once

#include <planar_grid/visualization/scene_renderer.h>

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <vtkNew.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>

namespace planar_grid {
namespace detail {

/** \brief True when all three components are finite. */
inline bool
isFinite(const Eigen::Vector3d& v)
{
  return v.allFinite();
}

} // namespace detail

struct SceneRenderer::Impl {
  /** \brief Holds every actor and the camera; moved between render windows. */
  vtkNew<vtkRenderer> renderer;
  /** \brief The explicit camera, when one was set. */
  CameraParameters camera;
  /** \brief True when setCamera(const CameraParameters&) was called last. */
  bool has_explicit_camera{false};
  /** \brief The preset applied at render time when no explicit camera is set. */
  CameraPreset preset{CameraPreset::TOP};
  /** \brief Number of text lines added so far (they stack downwards). */
  int text_lines{0};
  /** \brief Bounds of the actors that do not report their own (instanced boxes), m. */
  Eigen::AlignedBox3d instanced_bounds;

  /** \brief Places the camera for a \a width_px x \a height_px image. */
  void applyCamera(int width_px, int height_px);

  /** \brief A render window of the given size holding the renderer. */
  vtkSmartPointer<vtkRenderWindow>
  makeWindow(int width_px, int height_px, bool offscreen);

  /** \brief Detaches the renderer from \a window and releases the window's resources.
   */
  void releaseWindow(vtkRenderWindow* window);
};

} // namespace planar_grid
