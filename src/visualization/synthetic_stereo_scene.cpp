// SPDX-License-Identifier: BSD-3-Clause
// SyntheticStereoScene: the corridor and room geometry, the camera path, the rendered
// stereo frames (VTK, offscreen) and the truth queries.
#include <planar_grid/core/exceptions.h>
#include <planar_grid/visualization/scene_renderer.h>
#include <planar_grid/visualization/synthetic_stereo_scene.h>

#include <pcl/console/print.h>

#include <opencv2/core.hpp>
#include <vtkActor.h>
#include <vtkCamera.h>
#include <vtkCellArray.h>
#include <vtkFloatArray.h>
#include <vtkImageData.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkTexture.h>
#include <vtkUnsignedCharArray.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <limits>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

#include "synthetic_stereo_scene_impl.h"

namespace planar_grid {

namespace {

using detail::makeTexture;
using detail::mix;

using Polygon = std::vector<Eigen::Vector3d, Eigen::aligned_allocator<Eigen::Vector3d>>;

/** \brief Corridor: width (y), height (z) and length (x), metres. */
constexpr double CORRIDOR_WIDTH_M = 2.5;
constexpr double CORRIDOR_HEIGHT_M = 2.6;
constexpr double CORRIDOR_LENGTH_M = 20.0;
/** \brief Room: length (x), width (y) and height (z), metres. */
constexpr double ROOM_LENGTH_M = 8.0;
constexpr double ROOM_WIDTH_M = 6.0;
constexpr double ROOM_HEIGHT_M = 3.0;
/** \brief Slope of the room's ramp, radians (15 degrees). */
constexpr double RAMP_SLOPE_RAD = 15.0 * M_PI / 180.0;
/** \brief Where the camera path starts along the scene's x, metres. */
constexpr double CORRIDOR_PATH_START_M = 1.0;
constexpr double ROOM_PATH_START_M = 0.8;
/** \brief The path must end this far before the far wall's foot, metres. */
constexpr double PATH_END_MARGIN_M = 3.0;
/** \brief Largest |wall_lean_rad| (30 degrees). */
constexpr double MAX_LEAN_RAD = M_PI / 6.0;
/** \brief Clipping range of the rendering camera, metres. The depth buffer's
 * resolution at depth z is about z^2 / NEAR_CLIP_M * 2^-24 (2.4e-4 m at 20 m). */
constexpr double NEAR_CLIP_M = 0.1;
constexpr double FAR_CLIP_M = 100.0;
/** \brief Most points samplePoints() makes. */
constexpr double MAX_SAMPLE_POINTS = 2e8;
/** \brief Largest texture side, texels (OpenGL's limit is at least 8192 on Mesa). */
constexpr int MAX_TEXTURE_SIDE = 8192;

/** \brief Angle between a unit normal and the nearest coordinate axis, radians. */
double
tiltFromAxes(const Eigen::Vector3d& normal)
{
  return std::acos(std::min(1.0, normal.cwiseAbs().maxCoeff()));
}

/** \brief Distance from \a p to the segment [a, b]. */
double
distanceToSegment(const Eigen::Vector3d& p,
                  const Eigen::Vector3d& a,
                  const Eigen::Vector3d& b)
{
  const Eigen::Vector3d ab = b - a;
  const double length2 = ab.squaredNorm();
  const double t =
    length2 > 0.0 ? std::clamp((p - a).dot(ab) / length2, 0.0, 1.0) : 0.0;
  return (p - (a + t * ab)).norm();
}

/** \brief True when \a p (on the plane) lies inside the convex polygon, counter-
 * clockwise about \a normal, with a tolerance of \a eps metres. */
bool
insidePolygon(const Eigen::Vector3d& p,
              const Polygon& polygon,
              const Eigen::Vector3d& normal,
              double eps)
{
  const std::size_t n = polygon.size();
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3d& a = polygon[k];
    const Eigen::Vector3d& b = polygon[(k + 1) % n];
    const Eigen::Vector3d edge = (b - a).normalized();
    // Signed distance of p to the edge's line, positive inside.
    if (normal.cross(edge).dot(p - a) < -eps)
      return false;
  }
  return true;
}

} // namespace

SyntheticSceneKind
syntheticSceneKindFromString(const std::string& name)
{
  if (name == "corridor")
    return SyntheticSceneKind::CORRIDOR;
  if (name == "room")
    return SyntheticSceneKind::ROOM;
  throw Exception("unknown synthetic scene '" + name
                  + "'; known scenes: corridor, room");
}

std::string
toString(SyntheticSceneKind kind)
{
  return kind == SyntheticSceneKind::CORRIDOR ? "corridor" : "room";
}

struct SyntheticStereoScene::Impl {
  /** \brief The offscreen window, made at the first render and kept (the textures stay
   * on the GPU between frames). */
  vtkSmartPointer<vtkRenderWindow> window;
  /** \brief One textured actor per plane. */
  vtkNew<vtkRenderer> renderer;

  ~Impl()
  {
    if (window) {
      window->RemoveRenderer(renderer);
      window->Finalize();
    }
  }
};

SyntheticStereoScene::SyntheticStereoScene() : SyntheticStereoScene(Params()) {}

SyntheticStereoScene::SyntheticStereoScene(const Params& params) :
    params_(params), impl_(std::make_unique<Impl>())
{
  const auto check = [](bool ok, const std::string& what) {
    if (!ok)
      throw Exception("[planar_grid::SyntheticStereoScene] " + what);
  };
  check(std::isfinite(params.scene_yaw_rad), "scene_yaw_rad must be finite");
  check(std::abs(params.wall_lean_rad) <= MAX_LEAN_RAD,
        "wall_lean_rad must be in [-pi/6, pi/6] (30 degrees), got "
          + std::to_string(params.wall_lean_rad));
  check(params.frame_count >= 1,
        "frame_count must be >= 1, got " + std::to_string(params.frame_count));
  check(params.step_m >= 0.0 && std::isfinite(params.step_m),
        "step_m must be >= 0 m, got " + std::to_string(params.step_m));
  check(params.camera_height_m >= 0.3 && params.camera_height_m <= 2.3,
        "camera_height_m must be in [0.3, 2.3] m, got "
          + std::to_string(params.camera_height_m));
  check(params.width_px >= 16 && params.width_px <= 8192 && params.height_px >= 16
          && params.height_px <= 8192,
        "the image size must be in [16, 8192] px, got "
          + std::to_string(params.width_px) + "x" + std::to_string(params.height_px));
  check(params.focal_length_px > 0.0 && std::isfinite(params.focal_length_px),
        "focal_length_px must be > 0");
  check(params.baseline_m > 0.0 && std::isfinite(params.baseline_m),
        "baseline_m must be > 0");
  check(params.texel_m >= 0.002 && params.texel_m <= 0.1,
        "texel_m must be in [0.002, 0.1] m, got " + std::to_string(params.texel_m));

  const bool corridor = params.kind == SyntheticSceneKind::CORRIDOR;
  path_start_x_m_ = corridor ? CORRIDOR_PATH_START_M : ROOM_PATH_START_M;
  const double far_wall_x = corridor ? CORRIDOR_LENGTH_M : ROOM_LENGTH_M;
  const double path_end_x = path_start_x_m_ + (params.frame_count - 1) * params.step_m;
  check(path_end_x <= far_wall_x - PATH_END_MARGIN_M,
        "the camera path leaves the " + toString(params.kind)
          + ": it ends at x = " + std::to_string(path_end_x) + " m, but must end by "
          + std::to_string(far_wall_x - PATH_END_MARGIN_M)
          + " m (3 m before the far wall); use fewer frames or a shorter step");

  calibration_.focal_length_px = params.focal_length_px;
  calibration_.cx_px = 0.5 * (params.width_px - 1);
  calibration_.cy_px = 0.5 * (params.height_px - 1);
  calibration_.baseline_m = params.baseline_m;
  calibration_.width = params.width_px;
  calibration_.height = params.height_px;

  world_T_scene_ = Eigen::Isometry3d(
    Eigen::AngleAxisd(params.scene_yaw_rad, Eigen::Vector3d::UnitZ()));
  if (corridor)
    buildCorridor();
  else
    buildRoom();
}

SyntheticStereoScene::~SyntheticStereoScene() = default;

void
SyntheticStereoScene::addPlane(const std::string& name,
                               const Polygon& corners,
                               const Eigen::Vector3d& free_side)
{
  Polygon scene = corners;
  Eigen::Vector3d normal =
    (scene[1] - scene[0]).cross(scene[2] - scene[0]).normalized();
  if (normal.dot(free_side - scene[0]) < 0.0) {
    normal = -normal;
    std::reverse(scene.begin(), scene.end());
  }
  for (const auto& c : scene)
    if (std::abs(normal.dot(c - scene[0])) > 1e-9)
      throw Exception("[planar_grid::SyntheticStereoScene] plane '" + name
                      + "' is not planar");

  SyntheticPlane plane;
  plane.name = name;
  const Eigen::Vector3d n = world_T_scene_.linear() * normal;
  for (const auto& c : scene)
    plane.polygon.push_back(world_T_scene_ * c);
  plane.model_coefficients << n, -n.dot(plane.polygon.front());
  // -0 + 0 = +0: no "-0" in scene.json.
  plane.model_coefficients.array() += 0.0;
  for (auto& c : plane.polygon)
    c.array() += 0.0;
  plane.tilt_rad = tiltFromAxes(n);
  plane.texture_seed = mix(params_.seed ^ mix(0x7E57ULL + planes_.size()));

  // Texture axes: u horizontal (up x n) and v = n x u (up the wall) for walls; for
  // near-horizontal planes u is the scene's x. Both turn with the scene, so the
  // texture on a surface does not depend on the yaw.
  TextureFrame frame;
  frame.origin = plane.polygon.front();
  const Eigen::Vector3d up = Eigen::Vector3d::UnitZ();
  if (std::abs(n.z()) < 0.9)
    frame.u_axis = up.cross(n).normalized();
  else {
    const Eigen::Vector3d x = world_T_scene_.linear() * Eigen::Vector3d::UnitX();
    frame.u_axis = (x - x.dot(n) * n).normalized();
  }
  frame.v_axis = n.cross(frame.u_axis);
  frame.u_min = frame.v_min = std::numeric_limits<double>::infinity();
  frame.u_max = frame.v_max = -std::numeric_limits<double>::infinity();
  for (const auto& c : plane.polygon) {
    const double u = (c - frame.origin).dot(frame.u_axis);
    const double v = (c - frame.origin).dot(frame.v_axis);
    frame.u_min = std::min(frame.u_min, u);
    frame.u_max = std::max(frame.u_max, u);
    frame.v_min = std::min(frame.v_min, v);
    frame.v_max = std::max(frame.v_max, v);
  }
  planes_.push_back(std::move(plane));
  texture_frames_.push_back(frame);
}

void
SyntheticStereoScene::addBox(const std::string& name,
                             const Eigen::Vector3d& lo,
                             const Eigen::Vector3d& hi,
                             const std::string& faces)
{
  const Eigen::Vector3d centre = 0.5 * (lo + hi);
  for (const char face : faces) {
    const int axis = std::tolower(face) - 'x';
    const bool high = std::isupper(face) != 0;
    const int a = (axis + 1) % 3, b = (axis + 2) % 3;
    const double at = high ? hi[axis] : lo[axis];
    Polygon corners(4);
    const double ua[4] = {lo[a], hi[a], hi[a], lo[a]};
    const double ub[4] = {lo[b], lo[b], hi[b], hi[b]};
    for (int k = 0; k < 4; ++k) {
      corners[static_cast<std::size_t>(k)][axis] = at;
      corners[static_cast<std::size_t>(k)][a] = ua[k];
      corners[static_cast<std::size_t>(k)][b] = ub[k];
    }
    // Outward: a point beyond the face, away from the box centre.
    Eigen::Vector3d outside = centre;
    outside[axis] = at + (high ? 1.0 : -1.0);
    // The face at low x looks towards the camera (it walks along +x); low y is on
    // its right.
    static const char* const NAMES[3][2] = {
      {"front", "back"}, {"right", "left"}, {"bottom", "top"}};
    addPlane(name + "_" + NAMES[axis][high ? 1 : 0], corners, outside);
  }
}

void
SyntheticStereoScene::buildCorridor()
{
  const double w = 0.5 * CORRIDOR_WIDTH_M, h = CORRIDOR_HEIGHT_M, l = CORRIDOR_LENGTH_M;
  // The left wall (+y) turns about its foot: its top is at y = w + lean.
  const double lean = h * std::tan(params_.wall_lean_rad);
  const Eigen::Vector3d inside(0.5 * l, 0.0, 0.5 * h);
  using V = Eigen::Vector3d;
  addPlane("floor", {V(0, -w, 0), V(l, -w, 0), V(l, w, 0), V(0, w, 0)}, inside);
  addPlane("ceiling", {V(0, -w, h), V(l, -w, h), V(l, w + lean, h), V(0, w + lean, h)},
           inside);
  addPlane("right_wall", {V(0, -w, 0), V(l, -w, 0), V(l, -w, h), V(0, -w, h)}, inside);
  addPlane("left_wall", {V(0, w, 0), V(l, w, 0), V(l, w + lean, h), V(0, w + lean, h)},
           inside);
  addPlane("far_wall", {V(l, -w, 0), V(l, w, 0), V(l, w + lean, h), V(l, -w, h)},
           inside);
  addPlane("near_wall", {V(0, -w, 0), V(0, w, 0), V(0, w + lean, h), V(0, -w, h)},
           inside);
  // Pillars and a box against the right wall (no face against the wall or ceiling),
  // a free-standing box on the left, clear of the left wall for any lean.
  addBox("pillar1", V(5.0, -w, 0), V(5.4, -w + 0.3, h), "xXY");
  addBox("box1", V(9.0, -w, 0), V(10.0, -w + 0.6, 0.9), "xXYZ");
  addBox("box2", V(12.0, 0.2, 0), V(12.6, 0.6, 1.0), "xXyYZ");
  addBox("pillar2", V(15.0, -w, 0), V(15.4, -w + 0.3, h), "xXY");
}

void
SyntheticStereoScene::buildRoom()
{
  const double w = 0.5 * ROOM_WIDTH_M, h = ROOM_HEIGHT_M, l = ROOM_LENGTH_M;
  // The far wall (x = l) turns about its foot: its top is at x = l + lean.
  const double lean = h * std::tan(params_.wall_lean_rad);
  const Eigen::Vector3d inside(0.5 * l, 0.0, 0.5 * h);
  using V = Eigen::Vector3d;
  addPlane("floor", {V(0, -w, 0), V(l, -w, 0), V(l, w, 0), V(0, w, 0)}, inside);
  addPlane("ceiling", {V(0, -w, h), V(l + lean, -w, h), V(l + lean, w, h), V(0, w, h)},
           inside);
  addPlane("near_wall", {V(0, -w, 0), V(0, w, 0), V(0, w, h), V(0, -w, h)}, inside);
  addPlane("far_wall", {V(l, -w, 0), V(l, w, 0), V(l + lean, w, h), V(l + lean, -w, h)},
           inside);
  addPlane("left_wall", {V(0, w, 0), V(l, w, 0), V(l + lean, w, h), V(0, w, h)},
           inside);
  addPlane("right_wall", {V(0, -w, 0), V(l, -w, 0), V(l + lean, -w, h), V(0, -w, h)},
           inside);
  // The ramp rises along +x at RAMP_SLOPE_RAD from (3.0, y, 0) to (5.2, y, rise).
  const double x0 = 3.0, x1 = 5.2, y0 = 0.8, y1 = 2.2;
  const double rise = (x1 - x0) * std::tan(RAMP_SLOPE_RAD);
  addPlane("ramp_top", {V(x0, y0, 0), V(x1, y0, rise), V(x1, y1, rise), V(x0, y1, 0)},
           V(0.5 * (x0 + x1), 0.5 * (y0 + y1), h));
  addPlane("ramp_right", {V(x0, y0, 0), V(x1, y0, 0), V(x1, y0, rise)},
           V(x1, y0 - 1.0, 0.1));
  addPlane("ramp_left", {V(x0, y1, 0), V(x1, y1, 0), V(x1, y1, rise)},
           V(x1, y1 + 1.0, 0.1));
  addPlane("ramp_back", {V(x1, y0, 0), V(x1, y1, 0), V(x1, y1, rise), V(x1, y0, rise)},
           V(x1 + 1.0, 0.5 * (y0 + y1), 0.1));
  addBox("table", V(5.4, -2.2, 0), V(6.6, -1.4, 0.75), "xXyYZ");
}

Eigen::Isometry3d
SyntheticStereoScene::getCameraPose(std::size_t frame) const
{
  if (frame >= getFrameCount())
    throw Exception("[planar_grid::SyntheticStereoScene::getCameraPose] frame "
                    + std::to_string(frame) + " out of range ("
                    + std::to_string(getFrameCount()) + " frames)");
  // Level camera looking along the scene's +x: camera x = scene -y (right), camera
  // y = scene -z (down), camera z = scene +x (forward).
  Eigen::Matrix3d scene_R_camera;
  scene_R_camera.col(0) = -Eigen::Vector3d::UnitY();
  scene_R_camera.col(1) = -Eigen::Vector3d::UnitZ();
  scene_R_camera.col(2) = Eigen::Vector3d::UnitX();
  Eigen::Isometry3d scene_T_camera = Eigen::Isometry3d::Identity();
  scene_T_camera.linear() = scene_R_camera;
  scene_T_camera.translation() =
    Eigen::Vector3d(path_start_x_m_ + static_cast<double>(frame) * params_.step_m, 0.0,
                    params_.camera_height_m);
  Eigen::Isometry3d world_T_camera = world_T_scene_ * scene_T_camera;
  // -0 + 0 = +0: no "-0" in the poses file.
  world_T_camera.matrix().array() += 0.0;
  return world_T_camera;
}

void
SyntheticStereoScene::render(std::size_t frame,
                             cv::Mat& left,
                             cv::Mat& right,
                             cv::Mat* depth_m)
{
  const Eigen::Isometry3d world_T_left = getCameraPose(frame);
  if (!hasDisplay())
    throw Exception(
      "[planar_grid::SyntheticStereoScene::render] no X display: VTK 9.1 "
      "from Debian renders offscreen only through an X server; install "
      "xvfb (apt-get install xvfb) and run under `xvfb-run -a <command>`");
  const int width = params_.width_px, height = params_.height_px;
  Impl& impl = *impl_;
  if (!impl.window) {
    // Textured polygons without lighting: the colour is the texture's grey value
    // (ambient 1, diffuse 0, specular 0), identical from both cameras.
    impl.renderer->SetBackground(0.0, 0.0, 0.0);
    impl.renderer->SetAutomaticLightCreation(false);
    for (std::size_t k = 0; k < planes_.size(); ++k) {
      const SyntheticPlane& plane = planes_[k];
      const TextureFrame& tf = texture_frames_[k];
      vtkNew<vtkPoints> points;
      points->SetDataTypeToDouble();
      vtkNew<vtkFloatArray> tcoords;
      tcoords->SetNumberOfComponents(2);
      tcoords->SetName("tcoords");
      vtkNew<vtkCellArray> cells;
      cells->InsertNextCell(static_cast<vtkIdType>(plane.polygon.size()));
      for (const auto& c : plane.polygon) {
        const vtkIdType id = points->InsertNextPoint(c.data());
        cells->InsertCellPoint(id);
        const double u = (c - tf.origin).dot(tf.u_axis);
        const double v = (c - tf.origin).dot(tf.v_axis);
        tcoords->InsertNextTuple2((u - tf.u_min) / (tf.u_max - tf.u_min),
                                  (v - tf.v_min) / (tf.v_max - tf.v_min));
      }
      vtkNew<vtkPolyData> poly;
      poly->SetPoints(points);
      poly->SetPolys(cells);
      poly->GetPointData()->SetTCoords(tcoords);

      // About texel_m per texel (metric texture coordinates).
      const double width_m = tf.u_max - tf.u_min, height_m = tf.v_max - tf.v_min;
      const int nu = std::clamp(static_cast<int>(std::ceil(width_m / params_.texel_m)),
                                1, MAX_TEXTURE_SIDE);
      const int nv = std::clamp(static_cast<int>(std::ceil(height_m / params_.texel_m)),
                                1, MAX_TEXTURE_SIDE);
      const std::vector<unsigned char> texels =
        makeTexture(plane.texture_seed, nu, nv, width_m, height_m);
      vtkNew<vtkImageData> image;
      image->SetDimensions(nu, nv, 1);
      image->AllocateScalars(VTK_UNSIGNED_CHAR, 1);
      std::copy(texels.begin(), texels.end(),
                static_cast<unsigned char*>(image->GetScalarPointer()));
      vtkNew<vtkTexture> texture;
      texture->SetInputData(image);
      texture->InterpolateOn();
      texture->MipmapOn();
      texture->RepeatOff();
      texture->EdgeClampOn();

      vtkNew<vtkPolyDataMapper> mapper;
      mapper->SetInputData(poly);
      mapper->ScalarVisibilityOff();
      vtkNew<vtkActor> actor;
      actor->SetMapper(mapper);
      actor->SetTexture(texture);
      vtkProperty* property = actor->GetProperty();
      property->SetColor(1.0, 1.0, 1.0);
      property->SetAmbient(1.0);
      property->SetDiffuse(0.0);
      property->SetSpecular(0.0);
      property->LightingOff();
      impl.renderer->AddActor(actor);
    }
    impl.window = vtkSmartPointer<vtkRenderWindow>::New();
    impl.window->SetOffScreenRendering(1);
    impl.window->SetMultiSamples(0);
    impl.window->SetSize(width, height);
    impl.window->SetWindowName("planar_grid_synthetic_stereo_scene");
    impl.window->AddRenderer(impl.renderer);
  }

  vtkCamera* camera = impl.renderer->GetActiveCamera();
  // Vertical view angle from f and the image height: the optical axis goes through the
  // window centre, i.e. pixel (width - 1) / 2, (height - 1) / 2.
  const double view_angle_deg =
    2.0 * std::atan(0.5 * height / params_.focal_length_px) * 180.0 / M_PI;
  const auto view = [&](const Eigen::Isometry3d& world_T_camera, cv::Mat& grey,
                        cv::Mat* depth) {
    const Eigen::Vector3d position = world_T_camera.translation();
    const Eigen::Vector3d forward = world_T_camera.linear().col(2);
    const Eigen::Vector3d up = -world_T_camera.linear().col(1);
    const Eigen::Vector3d focal = position + forward;
    camera->SetPosition(position.data());
    camera->SetFocalPoint(focal.data());
    camera->SetViewUp(up.data());
    camera->SetViewAngle(view_angle_deg);
    camera->SetClippingRange(NEAR_CLIP_M, FAR_CLIP_M);
    impl.window->Render();

    vtkNew<vtkUnsignedCharArray> rgb;
    impl.window->GetPixelData(0, 0, width - 1, height - 1, 0, rgb, 0);
    grey.create(height, width, CV_8UC1);
    const unsigned char* p = rgb->GetPointer(0);
    // OpenGL's rows start at the bottom; image row 0 is the top.
    for (int row = 0; row < height; ++row) {
      unsigned char* out = grey.ptr<unsigned char>(height - 1 - row);
      const unsigned char* in = p + 3 * static_cast<std::size_t>(row) * width;
      for (int col = 0; col < width; ++col)
        out[col] = in[3 * col];
    }
    if (depth != nullptr) {
      std::vector<float> z(static_cast<std::size_t>(width) * height);
      impl.window->GetZbufferData(0, 0, width - 1, height - 1, z.data());
      double range[2];
      camera->GetClippingRange(range);
      const double n = range[0], f = range[1];
      depth->create(height, width, CV_32FC1);
      for (int row = 0; row < height; ++row) {
        float* out = depth->ptr<float>(height - 1 - row);
        const float* in = z.data() + static_cast<std::size_t>(row) * width;
        for (int col = 0; col < width; ++col) {
          const double zb = in[col];
          if (zb >= 1.0) {
            out[col] = 0.0f;
            continue;
          }
          // Window depth [0, 1] -> NDC [-1, 1] -> eye-space distance along the axis.
          const double ndc = 2.0 * zb - 1.0;
          out[col] = static_cast<float>(2.0 * n * f / ((f + n) - ndc * (f - n)));
        }
      }
    }
  };
  view(world_T_left, left, depth_m);
  view(world_T_left * Eigen::Translation3d(params_.baseline_m, 0.0, 0.0), right,
       nullptr);
}

void
SyntheticStereoScene::samplePoints(double spacing_m,
                                   pcl::PointCloud<pcl::PointXYZ>& cloud) const
{
  if (!(spacing_m > 0.0) || !std::isfinite(spacing_m))
    throw Exception(
      "[planar_grid::SyntheticStereoScene::samplePoints] spacing_m must be "
      "> 0 m, got "
      + std::to_string(spacing_m));
  double expected = 0.0;
  for (const auto& tf : texture_frames_)
    expected += ((tf.u_max - tf.u_min) / spacing_m + 1.0)
                * ((tf.v_max - tf.v_min) / spacing_m + 1.0);
  if (expected > MAX_SAMPLE_POINTS)
    throw Exception("[planar_grid::SyntheticStereoScene::samplePoints] spacing_m = "
                    + std::to_string(spacing_m) + " m would give about "
                    + std::to_string(expected) + " points (at most 2e8)");
  cloud.clear();
  cloud.reserve(static_cast<std::size_t>(expected));
  for (std::size_t k = 0; k < planes_.size(); ++k) {
    const SyntheticPlane& plane = planes_[k];
    const TextureFrame& tf = texture_frames_[k];
    const Eigen::Vector3d normal = plane.model_coefficients.head<3>();
    const auto nu =
      static_cast<long>(std::floor((tf.u_max - tf.u_min) / spacing_m + 1e-9));
    const auto nv =
      static_cast<long>(std::floor((tf.v_max - tf.v_min) / spacing_m + 1e-9));
    for (long j = 0; j <= nv; ++j)
      for (long i = 0; i <= nu; ++i) {
        const Eigen::Vector3d p =
          tf.origin + (tf.u_min + static_cast<double>(i) * spacing_m) * tf.u_axis
          + (tf.v_min + static_cast<double>(j) * spacing_m) * tf.v_axis;
        if (insidePolygon(p, plane.polygon, normal, 1e-9))
          cloud.push_back(pcl::PointXYZ(static_cast<float>(p.x()),
                                        static_cast<float>(p.y()),
                                        static_cast<float>(p.z())));
      }
  }
  cloud.width = static_cast<std::uint32_t>(cloud.size());
  cloud.height = 1;
  cloud.is_dense = true;
}

double
SyntheticStereoScene::distanceToSurface(const Eigen::Vector3d& point) const
{
  if (!point.allFinite())
    return std::numeric_limits<double>::infinity();
  double best = std::numeric_limits<double>::infinity();
  for (const auto& plane : planes_) {
    const Eigen::Vector3d normal = plane.model_coefficients.head<3>();
    const double signed_distance = normal.dot(point) + plane.model_coefficients[3];
    const Eigen::Vector3d projected = point - signed_distance * normal;
    double distance;
    if (insidePolygon(projected, plane.polygon, normal, 0.0))
      distance = std::abs(signed_distance);
    else {
      // Outside: the nearest point is on the boundary.
      distance = std::numeric_limits<double>::infinity();
      const std::size_t n = plane.polygon.size();
      for (std::size_t e = 0; e < n; ++e)
        distance = std::min(distance, distanceToSegment(point, plane.polygon[e],
                                                        plane.polygon[(e + 1) % n]));
    }
    best = std::min(best, distance);
  }
  return best;
}

} // namespace planar_grid
