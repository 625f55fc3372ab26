// SPDX-License-Identifier: BSD-3-Clause
// SceneRenderer: the camera and its presets, text and trajectory overlays, PNG
// snapshots and the interactive window.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/scene_renderer.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/common/io.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>

#include <Eigen/Geometry>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkCellData.h>
#include <vtkInteractorStyleTrackballCamera.h>
#include <vtkMath.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderWindowInteractor.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkTextActor.h>
#include <vtkTextProperty.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <tuple>
#include <unordered_set>
#include <utility>

#include "render_window_png.h"
#include "scene_renderer_impl.h"

namespace planar_grid {

namespace {

using detail::isFinite;

/** \brief Height of one text line, as a fraction of the window height. */
constexpr double TEXT_LINE_STEP = 0.05;

/** \brief Margin around the framed bounds of a camera preset (1 = tight). */
constexpr double FRAME_MARGIN = 1.05;

/** \brief Elevation of CameraPreset::OBLIQUE above the horizontal, radians (45 deg). */
constexpr double OBLIQUE_ELEVATION_RAD = 0.7853981633974483;

} // namespace

void
SceneRenderer::Impl::applyCamera(int width_px, int height_px)
{
  vtkCamera* cam = renderer->GetActiveCamera();
  if (has_explicit_camera) {
    cam->SetPosition(camera.position.data());
    cam->SetFocalPoint(camera.focal_point.data());
    cam->SetViewUp(camera.view_up.data());
    cam->SetViewAngle(camera.view_angle_deg);
    cam->OrthogonalizeViewUp();
    renderer->ResetCameraClippingRange();
    return;
  }

  double bounds[6];
  renderer->ComputeVisiblePropBounds(bounds);
  if (!instanced_bounds.isEmpty()) {
    const bool initialized = vtkMath::AreBoundsInitialized(bounds);
    for (int axis = 0; axis < 3; ++axis) {
      const double lo = instanced_bounds.min()[axis], hi = instanced_bounds.max()[axis];
      bounds[2 * axis] = initialized ? std::min(bounds[2 * axis], lo) : lo;
      bounds[2 * axis + 1] = initialized ? std::max(bounds[2 * axis + 1], hi) : hi;
    }
  }
  if (!vtkMath::AreBoundsInitialized(bounds)) {
    // Nothing to frame: a unit box at the origin keeps the camera well defined.
    bounds[0] = bounds[2] = bounds[4] = -0.5;
    bounds[1] = bounds[3] = bounds[5] = 0.5;
  }
  const Eigen::Vector3d lo(bounds[0], bounds[2], bounds[4]);
  const Eigen::Vector3d hi(bounds[1], bounds[3], bounds[5]);
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  const double aspect = static_cast<double>(width_px) / static_cast<double>(height_px);
  const double tan_half_v = std::tan(0.5 * camera.view_angle_deg * M_PI / 180.0);
  const double tan_half_h = tan_half_v * aspect;

  Eigen::Vector3d direction; // from the focal point towards the camera, unit
  Eigen::Vector3d view_up;   // unit, orthogonal to direction
  if (preset == CameraPreset::TOP) {
    direction = Eigen::Vector3d::UnitZ();
    view_up = Eigen::Vector3d::UnitY();
  } else {
    // Above and behind (-y) the centre, looking forwards (+y) and down.
    const double c = std::cos(OBLIQUE_ELEVATION_RAD),
                 s = std::sin(OBLIQUE_ELEVATION_RAD);
    direction = Eigen::Vector3d(0.0, -c, s);
    view_up = Eigen::Vector3d(0.0, s, c);
  }
  const Eigen::Vector3d right = view_up.cross(direction);
  // The smallest distance from the centre at which all 8 corners of the bounds are
  // inside both fields of view: a corner at depth q.d towards the camera and offsets
  // q.r, q.u needs distance >= q.d + |q.r| / tan_half_h and >= q.d + |q.u| /
  // tan_half_v.
  double distance = 0.0;
  for (int corner = 0; corner < 8; ++corner) {
    const Eigen::Vector3d p((corner & 1) != 0 ? hi.x() : lo.x(),
                            (corner & 2) != 0 ? hi.y() : lo.y(),
                            (corner & 4) != 0 ? hi.z() : lo.z());
    const Eigen::Vector3d q = p - centre;
    const double depth = q.dot(direction);
    distance = std::max(distance, depth + std::abs(q.dot(right)) / tan_half_h);
    distance = std::max(distance, depth + std::abs(q.dot(view_up)) / tan_half_v);
  }
  distance = std::max(FRAME_MARGIN * distance, 1e-3);
  const Eigen::Vector3d position = centre + distance * direction;
  cam->SetFocalPoint(centre.data());
  cam->SetPosition(position.data());
  cam->SetViewUp(view_up.data());
  cam->SetViewAngle(camera.view_angle_deg);
  cam->OrthogonalizeViewUp();
  renderer->ResetCameraClippingRange(bounds);
}

vtkSmartPointer<vtkRenderWindow>
SceneRenderer::Impl::makeWindow(int width_px, int height_px, bool offscreen)
{
  auto window = vtkSmartPointer<vtkRenderWindow>::New();
  window->SetOffScreenRendering(offscreen ? 1 : 0);
  // No multisampling: snapshots show exactly the colours that were set.
  window->SetMultiSamples(0);
  window->SetSize(width_px, height_px);
  window->SetWindowName("planar_grid_viewer");
  window->AddRenderer(renderer);
  applyCamera(width_px, height_px);
  return window;
}

void
SceneRenderer::Impl::releaseWindow(vtkRenderWindow* window)
{
  window->RemoveRenderer(renderer);
  window->Finalize();
}

SceneRenderer::SceneRenderer() : impl_(std::make_unique<Impl>())
{
  impl_->renderer->SetBackground(0.0, 0.0, 0.0);
}

SceneRenderer::~SceneRenderer() = default;

void
SceneRenderer::addTrajectory(const std::vector<Eigen::Vector3d>& positions,
                             const Eigen::Vector3d& rgb,
                             double line_width_px)
{
  if (!(line_width_px > 0.0))
    throw Exception(
      "[planar_grid::SceneRenderer::addTrajectory] line width must be > 0 "
      "px, got "
      + std::to_string(line_width_px));
  vtkNew<vtkPoints> points;
  points->SetDataTypeToDouble();
  points->Allocate(static_cast<vtkIdType>(positions.size()));
  for (const auto& p : positions)
    if (isFinite(p))
      points->InsertNextPoint(p.data());
  const vtkIdType n = points->GetNumberOfPoints();
  if (n < 2) {
    PCL_WARN("[planar_grid::SceneRenderer::addTrajectory] Fewer than 2 finite "
             "positions (%zu given); nothing added.\n",
             positions.size());
    return;
  }
  vtkNew<vtkCellArray> lines;
  lines->AllocateExact(1, n);
  lines->InsertNextCell(n);
  for (vtkIdType k = 0; k < n; ++k)
    lines->InsertCellPoint(k);
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->SetLines(lines);

  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(poly);
  mapper->ScalarVisibilityOff();
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb.x(), rgb.y(), rgb.z());
  actor->GetProperty()->SetLineWidth(static_cast<float>(line_width_px));
  actor->GetProperty()->LightingOff();
  impl_->renderer->AddActor(actor);
}

void
SceneRenderer::addText(const std::string& text, const Eigen::Vector3d& rgb)
{
  vtkNew<vtkTextActor> actor;
  actor->SetInput(text.c_str());
  actor->GetPositionCoordinate()->SetCoordinateSystemToNormalizedViewport();
  actor->SetPosition(0.01, 0.98 - TEXT_LINE_STEP * impl_->text_lines);
  vtkTextProperty* property = actor->GetTextProperty();
  property->SetFontSize(18);
  property->SetColor(rgb.x(), rgb.y(), rgb.z());
  property->SetVerticalJustificationToTop();
  property->SetJustificationToLeft();
  ++impl_->text_lines;
  impl_->renderer->AddActor2D(actor);
}

void
SceneRenderer::setBackground(const Eigen::Vector3d& rgb)
{
  impl_->renderer->SetBackground(rgb.x(), rgb.y(), rgb.z());
}

void
SceneRenderer::setCamera(const CameraParameters& camera)
{
  if (!isFinite(camera.position) || !isFinite(camera.focal_point)
      || !isFinite(camera.view_up))
    throw Exception("[planar_grid::SceneRenderer::setCamera] camera vectors must be "
                    "finite");
  const Eigen::Vector3d direction = camera.focal_point - camera.position;
  if (direction.norm() <= 0.0)
    throw Exception("[planar_grid::SceneRenderer::setCamera] position and focal point "
                    "must differ");
  if (camera.view_up.cross(direction).norm()
      <= 1e-9 * direction.norm() * camera.view_up.norm())
    throw Exception("[planar_grid::SceneRenderer::setCamera] view_up must be non-zero "
                    "and not parallel to the viewing direction");
  if (!(camera.view_angle_deg > 0.0 && camera.view_angle_deg < 180.0))
    throw Exception("[planar_grid::SceneRenderer::setCamera] view angle must be in (0, "
                    "180) degrees, got "
                    + std::to_string(camera.view_angle_deg));
  impl_->camera = camera;
  impl_->has_explicit_camera = true;
}

void
SceneRenderer::setCamera(CameraPreset preset)
{
  impl_->preset = preset;
  impl_->has_explicit_camera = false;
}

void
SceneRenderer::saveSnapshot(const std::string& path, int width_px, int height_px)
{
  if (width_px <= 0 || height_px <= 0)
    throw Exception("[planar_grid::SceneRenderer::saveSnapshot] image size must be "
                    "positive, got "
                    + std::to_string(width_px) + "x" + std::to_string(height_px));
  if (!hasDisplay())
    throw Exception(
      "cannot save " + path
      + ": no X display: VTK 9.1 from Debian renders offscreen only "
        "through an X server; install xvfb (apt-get install xvfb) and run "
        "under `xvfb-run -a <command>`");
  vtkSmartPointer<vtkRenderWindow> window =
    impl_->makeWindow(width_px, height_px, true);
  try {
    detail::saveRenderWindowPng(window, path);
  } catch (...) {
    impl_->releaseWindow(window);
    throw;
  }
  impl_->releaseWindow(window);
}

void
SceneRenderer::show(int width_px, int height_px)
{
  if (width_px <= 0 || height_px <= 0)
    throw Exception("[planar_grid::SceneRenderer::show] window size must be positive, "
                    "got "
                    + std::to_string(width_px) + "x" + std::to_string(height_px));
  if (!hasDisplay())
    throw Exception("cannot open the viewer window: no X display (DISPLAY is unset or "
                    "does not answer); the interactive viewer needs a screen, "
                    "snapshots can be rendered under `xvfb-run -a <command>`");
  vtkSmartPointer<vtkRenderWindow> window =
    impl_->makeWindow(width_px, height_px, false);
  vtkNew<vtkRenderWindowInteractor> interactor;
  vtkNew<vtkInteractorStyleTrackballCamera> style;
  interactor->SetRenderWindow(window);
  interactor->SetInteractorStyle(style);
  interactor->Initialize();
  window->Render();
  interactor->Start(); // returns when the window is closed (or on 'q')
  interactor->SetRenderWindow(nullptr);
  impl_->releaseWindow(window);
}

} // namespace planar_grid
