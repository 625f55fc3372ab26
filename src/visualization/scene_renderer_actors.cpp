// SPDX-License-Identifier: BSD-3-Clause
// The data a SceneRenderer draws: point clouds with their colour ramps, cuboids,
// polygon meshes and a planar grid map (instanced voxel boxes).
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
#include <vtkCubeSource.h>
#include <vtkFloatArray.h>
#include <vtkGlyph3DMapper.h>
#include <vtkIdTypeArray.h>
#include <vtkNew.h>
#include <vtkPointData.h>
#include <vtkPoints.h>
#include <vtkPolyData.h>
#include <vtkPolyDataMapper.h>
#include <vtkProperty.h>
#include <vtkRenderWindow.h>
#include <vtkRenderer.h>
#include <vtkSmartPointer.h>
#include <vtkUnsignedCharArray.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <tuple>
#include <unordered_set>
#include <utility>

#include "scene_renderer_impl.h"

namespace planar_grid {

namespace {

using detail::isFinite;

/** \brief Fraction of the sorted values cut at each end of a colour ramp, so that a few
 * outliers do not squeeze the colours of everything else into one end of the map. */
constexpr double RAMP_TAIL = 0.02;

/** \brief The part of the Turbo map used for HEIGHT: its near-black ends would vanish
 * on the default black background. Low is blue (75, 74, 200), high red (155, 15, 0). */
constexpr double TURBO_LOW = 0.08;
constexpr double TURBO_HIGH = 0.95;

/** \brief Share of a cuboid's colour lit regardless of the light's direction (ambient);
 * the rest is diffuse. */
constexpr double CUBOID_AMBIENT = 0.4;

/** \brief Axis-aligned boxes, one colour, drawn as instances of one unit cube (VTK's
 * glyph mapper): about 30 bytes a box in VTK and the GPU buffers where a box of
 * polygons takes about 400, so that a street map's hundreds of thousands of occupied
 * voxel runs render in little memory. The actor does not report bounds (the glyph
 * mapper's are padded by the largest box around every centre); the exact bounds are
 * returned for the camera to frame instead. \param[in] centres box centres, m
 * \param[in] sizes edge lengths along x, y, z, m (one per centre) \return the boxes'
 * bounds, m (empty when there are none) */
Eigen::AlignedBox3d
addInstancedBoxes(vtkRenderer* renderer,
                  const std::vector<Eigen::Vector3f>& centres,
                  const std::vector<Eigen::Vector3f>& sizes,
                  const Eigen::Vector3d& rgb,
                  double opacity)
{
  Eigen::AlignedBox3d bounds;
  if (centres.empty())
    return bounds;
  const auto n = static_cast<vtkIdType>(centres.size());
  vtkNew<vtkPoints> points;
  points->SetDataTypeToFloat();
  points->SetNumberOfPoints(n);
  vtkNew<vtkFloatArray> scale;
  scale->SetName("size");
  scale->SetNumberOfComponents(3);
  scale->SetNumberOfTuples(n);
  for (vtkIdType k = 0; k < n; ++k) {
    const Eigen::Vector3f& c = centres[static_cast<std::size_t>(k)];
    const Eigen::Vector3f& e = sizes[static_cast<std::size_t>(k)];
    points->SetPoint(k, c.x(), c.y(), c.z());
    scale->SetTypedTuple(k, e.data());
    bounds.extend((c - 0.5f * e).cast<double>());
    bounds.extend((c + 0.5f * e).cast<double>());
  }
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->GetPointData()->AddArray(scale);
  vtkNew<vtkCubeSource> cube; // unit cube about the origin
  vtkNew<vtkGlyph3DMapper> mapper;
  mapper->SetInputData(poly);
  mapper->SetSourceConnection(cube->GetOutputPort());
  mapper->SetScaleArray("size");
  mapper->SetScaleModeToScaleByVectorComponents();
  mapper->ScalingOn();
  mapper->OrientOff();
  mapper->ScalarVisibilityOff();
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetColor(rgb.x(), rgb.y(), rgb.z());
  actor->GetProperty()->SetOpacity(opacity);
  // Closed boxes with outward faces: a back face is never seen, and culling it before
  // rasterisation halves the triangles the software renderer bins.
  actor->GetProperty()->BackfaceCullingOn();
  actor->GetProperty()->SetAmbient(CUBOID_AMBIENT);
  actor->GetProperty()->SetDiffuse(1.0 - CUBOID_AMBIENT);
  actor->UseBoundsOff();
  renderer->AddActor(actor);
  return bounds;
}

/** \brief A colour component in [0, 1] as a byte. */
unsigned char
toByte(double value)
{
  return static_cast<unsigned char>(std::lround(std::clamp(value, 0.0, 1.0) * 255.0));
}

/** \brief The Turbo colour map (A. Mikhailov, Google, 2019; Apache-2.0) through R. Du's
 * published polynomial fit, for t in [0, 1]: dark blue, cyan, green, yellow, red. */
std::array<unsigned char, 3>
turbo(double t)
{
  t = std::clamp(t, 0.0, 1.0);
  const double t2 = t * t, t3 = t2 * t, t4 = t2 * t2, t5 = t4 * t;
  const double r = 0.13572138 + 4.61539260 * t - 42.66032258 * t2 + 132.13108234 * t3
                   - 152.94239396 * t4 + 59.28637943 * t5;
  const double g = 0.09140261 + 2.19418839 * t + 4.84296658 * t2 - 14.18503333 * t3
                   + 4.27729857 * t4 + 2.82956604 * t5;
  const double b = 0.10667330 + 12.64194608 * t - 60.58204836 * t2 + 110.36276771 * t3
                   - 89.90310912 * t4 + 27.34824973 * t5;
  return {toByte(r), toByte(g), toByte(b)};
}

/** \brief The RAMP_TAIL and 1 - RAMP_TAIL quantiles of \a values (reordered in place).
 * \return {low, high}; equal when all values are (nearly) equal */
std::pair<float, float>
robustRange(std::vector<float>& values)
{
  const std::size_t n = values.size();
  const auto lo_index =
    static_cast<std::size_t>(RAMP_TAIL * static_cast<double>(n - 1));
  const auto hi_index =
    static_cast<std::size_t>((1.0 - RAMP_TAIL) * static_cast<double>(n - 1));
  std::nth_element(values.begin(),
                   values.begin() + static_cast<std::ptrdiff_t>(lo_index),
                   values.end());
  const float lo = values[lo_index];
  std::nth_element(values.begin() + static_cast<std::ptrdiff_t>(lo_index),
                   values.begin() + static_cast<std::ptrdiff_t>(hi_index),
                   values.end());
  const float hi = values[hi_index];
  return {lo, hi};
}

/** \brief Position of \a value in [lo, hi] as a fraction in [0, 1]; 0.5 when the range
 * is empty. */
double
rampFraction(float value, float lo, float hi)
{
  if (!(hi > lo))
    return 0.5;
  return std::clamp(static_cast<double>(value - lo) / static_cast<double>(hi - lo), 0.0,
                    1.0);
}

/** \brief A distinct colour per integer label: 12 hues a golden-ratio step apart, at
 * two saturation/value levels so neighbouring labels differ strongly. */
std::array<unsigned char, 3>
labelColor(float label)
{
  const long id = std::lround(label);
  const double hue = std::fmod(0.618033988749895 * static_cast<double>(id % 12), 1.0);
  const double s = (id / 12) % 2 == 0 ? 0.85 : 0.55;
  const double v = (id / 12) % 2 == 0 ? 0.95 : 0.75;
  // HSV to RGB.
  const double h6 = hue * 6.0;
  const int sector = static_cast<int>(h6) % 6;
  const double f = h6 - std::floor(h6);
  const double p = v * (1.0 - s), q = v * (1.0 - s * f), t = v * (1.0 - s * (1.0 - f));
  double r = v, g = t, b = p;
  switch (sector) {
    case 1:
      r = q;
      g = v;
      b = p;
      break;
    case 2:
      r = p;
      g = v;
      b = t;
      break;
    case 3:
      r = p;
      g = q;
      b = v;
      break;
    case 4:
      r = t;
      g = p;
      b = v;
      break;
    case 5:
      r = v;
      g = p;
      b = q;
      break;
    default:
      break;
  }
  return {toByte(r), toByte(g), toByte(b)};
}

} // namespace

void
SceneRenderer::addPointCloud(const pcl::PointCloud<pcl::PointXYZI>& cloud,
                             ColorMode mode,
                             double point_size_px,
                             const Eigen::Vector3d& rgb)
{
  if (!(point_size_px > 0.0))
    throw Exception(
      "[planar_grid::SceneRenderer::addPointCloud] point size must be > 0 "
      "px, got "
      + std::to_string(point_size_px));
  std::size_t n_finite = 0;
  for (const auto& p : cloud.points)
    if (pcl::isFinite(p))
      ++n_finite;
  if (n_finite == 0) {
    PCL_WARN("[planar_grid::SceneRenderer::addPointCloud] The cloud has no finite "
             "points (%zu points in all); nothing added.\n",
             cloud.size());
    return;
  }
  const auto n = static_cast<vtkIdType>(n_finite);

  // Coordinates, written straight into VTK's float array.
  vtkNew<vtkFloatArray> coords;
  coords->SetNumberOfComponents(3);
  coords->SetNumberOfTuples(n);
  float* xyz = coords->WritePointer(0, 3 * n);
  // One vertex cell per point, given as offsets + connectivity (no per-cell inserts).
  vtkNew<vtkIdTypeArray> offsets;
  offsets->SetNumberOfValues(n + 1);
  vtkIdType* offset = offsets->WritePointer(0, n + 1);
  vtkNew<vtkIdTypeArray> connectivity;
  connectivity->SetNumberOfValues(n);
  vtkIdType* ids = connectivity->WritePointer(0, n);

  // Values for the colour ramp (z or intensity), only for the modes that need one.
  std::vector<float> ramp_values;
  if (mode != ColorMode::SOLID)
    ramp_values.reserve(n_finite);

  vtkIdType i = 0;
  for (const auto& p : cloud.points) {
    if (!pcl::isFinite(p))
      continue;
    xyz[3 * i] = p.x;
    xyz[3 * i + 1] = p.y;
    xyz[3 * i + 2] = p.z;
    offset[i] = i;
    ids[i] = i;
    if (mode == ColorMode::HEIGHT)
      ramp_values.push_back(p.z);
    else if (mode == ColorMode::INTENSITY || mode == ColorMode::LABEL)
      ramp_values.push_back(p.intensity);
    ++i;
  }
  offset[n] = n;

  vtkNew<vtkPoints> points;
  points->SetData(coords);
  vtkNew<vtkCellArray> vertices;
  vertices->SetData(offsets, connectivity);
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->SetVerts(vertices);

  vtkNew<vtkPolyDataMapper> mapper;
  vtkNew<vtkActor> actor;
  if (mode == ColorMode::SOLID) {
    mapper->ScalarVisibilityOff();
    actor->GetProperty()->SetColor(rgb.x(), rgb.y(), rgb.z());
  } else {
    std::vector<float> sorted = ramp_values; // robustRange reorders its input
    const auto [lo, hi] = robustRange(sorted);
    sorted.clear();
    sorted.shrink_to_fit();
    vtkNew<vtkUnsignedCharArray> colors;
    colors->SetName("colors");
    colors->SetNumberOfComponents(3);
    colors->SetNumberOfTuples(n);
    unsigned char* c = colors->WritePointer(0, 3 * n);
    for (vtkIdType k = 0; k < n; ++k) {
      const double t = rampFraction(ramp_values[static_cast<std::size_t>(k)], lo, hi);
      if (mode == ColorMode::LABEL) {
        const auto color = labelColor(ramp_values[static_cast<std::size_t>(k)]);
        c[3 * k] = color[0];
        c[3 * k + 1] = color[1];
        c[3 * k + 2] = color[2];
      } else if (mode == ColorMode::HEIGHT) {
        const auto color = turbo(TURBO_LOW + (TURBO_HIGH - TURBO_LOW) * t);
        c[3 * k] = color[0];
        c[3 * k + 1] = color[1];
        c[3 * k + 2] = color[2];
      } else {
        // Grey from 0.2 (darkest, still visible on black) to 1.0; a constant intensity
        // (e.g. a cloud without that field) renders at 0.6.
        const unsigned char grey = toByte(0.2 + 0.8 * t);
        c[3 * k] = c[3 * k + 1] = c[3 * k + 2] = grey;
      }
    }
    poly->GetPointData()->SetScalars(colors);
    mapper->ScalarVisibilityOn();
    mapper->SetColorModeToDirectScalars();
    mapper->SetScalarModeToUsePointData();
  }
  mapper->SetInputData(poly);
  actor->SetMapper(mapper);
  actor->GetProperty()->SetPointSize(static_cast<float>(point_size_px));
  // Points carry no normals: draw their colours as given.
  actor->GetProperty()->LightingOff();
  impl_->renderer->AddActor(actor);
}

void
SceneRenderer::addCuboids(const PlanarCuboids& cuboids,
                          bool wireframe,
                          double opacity,
                          const Eigen::Vector3d& non_planar_rgb)
{
  addCuboids(cuboids, CuboidColorMode::PLANE, wireframe, opacity, non_planar_rgb);
}

void
SceneRenderer::addCuboids(const PlanarCuboids& cuboids,
                          CuboidColorMode mode,
                          bool wireframe,
                          double opacity,
                          const Eigen::Vector3d& rgb)
{
  if (!(opacity > 0.0 && opacity <= 1.0))
    throw Exception(
      "[planar_grid::SceneRenderer::addCuboids] opacity must be in (0, 1], "
      "got "
      + std::to_string(opacity));
  if (cuboids.empty())
    return;
  const auto n = static_cast<vtkIdType>(cuboids.size());
  vtkNew<vtkPoints> points;
  points->SetDataTypeToFloat();
  points->SetNumberOfPoints(8 * n);
  vtkNew<vtkCellArray> quads;
  quads->AllocateExact(6 * n, 24 * n);
  vtkNew<vtkUnsignedCharArray> colors;
  colors->SetNumberOfComponents(3);
  colors->SetNumberOfTuples(6 * n);
  unsigned char* c = colors->WritePointer(0, 18 * n);
  const std::array<unsigned char, 3> fixed{toByte(rgb.x()), toByte(rgb.y()),
                                           toByte(rgb.z())};
  // Corner order of PlanarCuboid::corners(): face 0-3, back 4-7 (same winding).
  static constexpr vtkIdType FACES[6][4] = {{0, 1, 2, 3}, {4, 7, 6, 5}, {0, 4, 5, 1},
                                            {1, 5, 6, 2}, {2, 6, 7, 3}, {3, 7, 4, 0}};
  for (vtkIdType k = 0; k < n; ++k) {
    const PlanarCuboid& cuboid = cuboids[static_cast<std::size_t>(k)];
    const auto corners = cuboid.corners();
    for (vtkIdType j = 0; j < 8; ++j) {
      const Eigen::Vector3f& q = corners[static_cast<std::size_t>(j)];
      points->SetPoint(8 * k + j, q.x(), q.y(), q.z());
    }
    std::array<unsigned char, 3> color = fixed;
    if (mode == CuboidColorMode::PLANE && cuboid.plane_id >= 0)
      color = labelColor(static_cast<float>(cuboid.plane_id));
    else if (mode == CuboidColorMode::OCCUPANCY)
      color = turbo(static_cast<double>(cuboid.probability));
    for (const auto& face : FACES) {
      const vtkIdType ids[4] = {8 * k + face[0], 8 * k + face[1], 8 * k + face[2],
                                8 * k + face[3]};
      quads->InsertNextCell(4, ids);
      c[0] = color[0];
      c[1] = color[1];
      c[2] = color[2];
      c += 3;
    }
  }
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  poly->SetPolys(quads);
  poly->GetCellData()->SetScalars(colors);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(poly);
  mapper->ScalarVisibilityOn();
  mapper->SetColorModeToDirectScalars();
  mapper->SetScalarModeToUseCellData();
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetOpacity(opacity);
  if (opacity < 1.0)
    actor->GetProperty()->BackfaceCullingOn();
  if (wireframe) {
    actor->GetProperty()->SetRepresentationToWireframe();
    actor->GetProperty()->LightingOff();
  } else {
    // Part of the colour does not depend on the light: a face seen at a grazing angle
    // (a facade seen along the street) keeps its colour instead of turning black. A
    // face looked at straight on is as bright as with diffuse light alone.
    actor->GetProperty()->SetAmbient(CUBOID_AMBIENT);
    actor->GetProperty()->SetDiffuse(1.0 - CUBOID_AMBIENT);
  }
  impl_->renderer->AddActor(actor);
}

std::size_t
SceneRenderer::addPolygonMesh(const pcl::PolygonMesh& mesh, double opacity)
{
  if (!(opacity > 0.0 && opacity <= 1.0))
    throw Exception("[planar_grid::SceneRenderer::addPolygonMesh] opacity must be in "
                    "(0, 1], got "
                    + std::to_string(opacity));
  if (pcl::getFieldIndex(mesh.cloud, "x") < 0 || pcl::getFieldIndex(mesh.cloud, "y") < 0
      || pcl::getFieldIndex(mesh.cloud, "z") < 0)
    throw Exception("[planar_grid::SceneRenderer::addPolygonMesh] the mesh's vertices "
                    "have no x, y, z fields");
  const bool has_rgb = pcl::getFieldIndex(mesh.cloud, "rgb") >= 0
                       || pcl::getFieldIndex(mesh.cloud, "rgba") >= 0;
  pcl::PointCloud<pcl::PointXYZRGB> vertices;
  if (has_rgb) {
    pcl::fromPCLPointCloud2(mesh.cloud, vertices);
  } else {
    pcl::PointCloud<pcl::PointXYZ> xyz;
    pcl::fromPCLPointCloud2(mesh.cloud, xyz);
    pcl::copyPointCloud(xyz, vertices);
  }
  const auto n = static_cast<vtkIdType>(vertices.size());
  if (n == 0)
    return 0;
  vtkNew<vtkPoints> points;
  points->SetDataTypeToFloat();
  points->SetNumberOfPoints(n);
  std::vector<float> heights;
  heights.reserve(vertices.size());
  for (vtkIdType k = 0; k < n; ++k) {
    const auto& p = vertices[static_cast<std::size_t>(k)];
    points->SetPoint(k, p.x, p.y, p.z);
    if (std::isfinite(p.z))
      heights.push_back(p.z);
  }
  vtkNew<vtkUnsignedCharArray> colors;
  colors->SetNumberOfComponents(3);
  colors->SetNumberOfTuples(n);
  unsigned char* c = colors->WritePointer(0, 3 * n);
  float lo = 0.0f, hi = 0.0f;
  if (!heights.empty())
    std::tie(lo, hi) = robustRange(heights);
  for (vtkIdType k = 0; k < n; ++k) {
    const auto& p = vertices[static_cast<std::size_t>(k)];
    std::array<unsigned char, 3> color{p.r, p.g, p.b};
    if (!has_rgb)
      color = turbo(TURBO_LOW + (TURBO_HIGH - TURBO_LOW) * rampFraction(p.z, lo, hi));
    c[3 * k] = color[0];
    c[3 * k + 1] = color[1];
    c[3 * k + 2] = color[2];
  }
  vtkNew<vtkCellArray> cells;
  std::size_t faces = 0;
  std::vector<vtkIdType> ids;
  for (const auto& polygon : mesh.polygons) {
    ids.clear();
    bool finite = true;
    for (const auto index : polygon.vertices) {
      if (index < 0 || index >= n)
        throw Exception("[planar_grid::SceneRenderer::addPolygonMesh] a polygon "
                        "refers to vertex "
                        + std::to_string(index) + " of " + std::to_string(n));
      finite = finite && pcl::isFinite(vertices[static_cast<std::size_t>(index)]);
      ids.push_back(static_cast<vtkIdType>(index));
    }
    if (!finite || ids.size() < 3)
      continue;
    cells->InsertNextCell(static_cast<vtkIdType>(ids.size()), ids.data());
    ++faces;
  }
  vtkNew<vtkPolyData> poly;
  poly->SetPoints(points);
  if (mesh.polygons.empty()) {
    for (vtkIdType k = 0; k < n; ++k)
      if (pcl::isFinite(vertices[static_cast<std::size_t>(k)]))
        cells->InsertNextCell(1, &k);
    poly->SetVerts(cells);
  } else {
    poly->SetPolys(cells);
  }
  poly->GetPointData()->SetScalars(colors);
  vtkNew<vtkPolyDataMapper> mapper;
  mapper->SetInputData(poly);
  mapper->ScalarVisibilityOn();
  mapper->SetColorModeToDirectScalars();
  mapper->SetScalarModeToUsePointData();
  vtkNew<vtkActor> actor;
  actor->SetMapper(mapper);
  actor->GetProperty()->SetOpacity(opacity);
  if (mesh.polygons.empty()) {
    actor->GetProperty()->SetPointSize(2.0f);
    actor->GetProperty()->LightingOff();
  } else {
    actor->GetProperty()->SetAmbient(CUBOID_AMBIENT);
    actor->GetProperty()->SetDiffuse(1.0 - CUBOID_AMBIENT);
  }
  impl_->renderer->AddActor(actor);
  return faces;
}

MapRenderSummary
SceneRenderer::addMap(const PlanarGridMap& map,
                      CuboidColorMode cuboid_color,
                      double unknown_opacity,
                      std::size_t max_voxel_boxes)
{
  if (!(unknown_opacity >= 0.0 && unknown_opacity <= 1.0))
    throw Exception("[planar_grid::SceneRenderer::addMap] unknown_opacity must be in "
                    "[0, 1], got "
                    + std::to_string(unknown_opacity));
  MapRenderSummary summary;
  const auto& surface = map.getSurfaceLayer();
  const auto& space = map.getSpaceLayer();
  addCuboids(surface.getCuboids(), cuboid_color);
  summary.cuboids = surface.getCuboidCount();

  // Occupied voxels that no cuboid covers, as small dark boxes; unknown space gathered
  // into coarse boxes of 8 voxels (one per 8^3 region holding any unknown voxel).
  const auto res = static_cast<float>(map.getResolution());
  const float coarse = 8.0f * res;
  std::vector<Eigen::Vector3f> unknown_centres;
  std::unordered_set<std::int64_t> unknown_regions;
  std::vector<ExplicitSpaceGrid::VoxelKey> occupied_keys;
  space.forEachVoxel([&](const ExplicitSpaceGrid::VoxelKey& key, SpaceState state) {
    if (state == SpaceState::OCCUPIED) {
      if (occupied_keys.size() >= max_voxel_boxes)
        return;
      if (!surface.findCuboid(space.toCentre(key)))
        occupied_keys.push_back(key);
    } else if (state == SpaceState::UNKNOWN && unknown_opacity > 0.0) {
      const Eigen::Vector3i region(key.x() >> 3, key.y() >> 3, key.z() >> 3);
      const std::int64_t id =
        ((static_cast<std::int64_t>(region.x()) & 0x1FFFFF) << 42)
        | ((static_cast<std::int64_t>(region.y()) & 0x1FFFFF) << 21)
        | (static_cast<std::int64_t>(region.z()) & 0x1FFFFF);
      if (unknown_regions.insert(id).second && unknown_centres.size() < max_voxel_boxes)
        unknown_centres.push_back(
          (region.cast<float>() + Eigen::Vector3f::Constant(0.5f)) * coarse);
    }
  });
  // The occupied voxels drawn as few boxes: runs along x, then equal runs in
  // consecutive rows of y joined, then equal rectangles in consecutive layers of z (the
  // same volume, a fraction of the boxes: a street map holds a million voxels, and the
  // software renderer's memory grows with the boxes drawn).
  struct Run {
    int x0, x1, y0, y1, z0, z1;
  };
  std::sort(occupied_keys.begin(), occupied_keys.end(),
            [](const auto& a, const auto& b) {
              return std::make_tuple(a.z(), a.y(), a.x())
                     < std::make_tuple(b.z(), b.y(), b.x());
            });
  std::vector<Run> runs;
  for (const auto& k : occupied_keys) {
    if (!runs.empty() && runs.back().z0 == k.z() && runs.back().y0 == k.y()
        && runs.back().x1 + 1 == k.x())
      runs.back().x1 = k.x();
    else
      runs.push_back(Run{k.x(), k.x(), k.y(), k.y(), k.z(), k.z()});
  }
  summary.occupied_voxel_boxes = occupied_keys.size();
  std::vector<ExplicitSpaceGrid::VoxelKey>().swap(occupied_keys);
  std::sort(runs.begin(), runs.end(), [](const Run& a, const Run& b) {
    return std::make_tuple(a.z0, a.x0, a.x1, a.y0)
           < std::make_tuple(b.z0, b.x0, b.x1, b.y0);
  });
  std::vector<Run> rects;
  for (const Run& r : runs) {
    if (!rects.empty() && rects.back().z0 == r.z0 && rects.back().x0 == r.x0
        && rects.back().x1 == r.x1 && rects.back().y1 + 1 == r.y0)
      rects.back().y1 = r.y0;
    else
      rects.push_back(r);
  }
  std::vector<Run>().swap(runs);
  std::sort(rects.begin(), rects.end(), [](const Run& a, const Run& b) {
    return std::make_tuple(a.x0, a.x1, a.y0, a.y1, a.z0)
           < std::make_tuple(b.x0, b.x1, b.y0, b.y1, b.z0);
  });
  std::vector<Run> boxes;
  for (const Run& r : rects) {
    if (!boxes.empty() && boxes.back().x0 == r.x0 && boxes.back().x1 == r.x1
        && boxes.back().y0 == r.y0 && boxes.back().y1 == r.y1
        && boxes.back().z1 + 1 == r.z0)
      boxes.back().z1 = r.z0;
    else
      boxes.push_back(r);
  }
  std::vector<Run>().swap(rects);
  std::vector<Eigen::Vector3f> occupied_centres, occupied_sizes;
  occupied_centres.reserve(boxes.size());
  occupied_sizes.reserve(boxes.size());
  for (const Run& r : boxes) {
    occupied_centres.emplace_back(
      Eigen::Vector3f(0.5f * static_cast<float>(r.x0 + r.x1 + 1),
                      0.5f * static_cast<float>(r.y0 + r.y1 + 1),
                      0.5f * static_cast<float>(r.z0 + r.z1 + 1))
      * res);
    occupied_sizes.emplace_back(static_cast<float>(r.x1 - r.x0 + 1) * res,
                                static_cast<float>(r.y1 - r.y0 + 1) * res,
                                static_cast<float>(r.z1 - r.z0 + 1) * res);
  }
  summary.unknown_boxes = unknown_centres.size();
  impl_->instanced_bounds.extend(
    addInstancedBoxes(impl_->renderer, occupied_centres, occupied_sizes,
                      Eigen::Vector3d(0.3, 0.3, 0.3), 1.0));
  if (!unknown_centres.empty())
    impl_->instanced_bounds.extend(
      addInstancedBoxes(impl_->renderer, unknown_centres,
                        std::vector<Eigen::Vector3f>(unknown_centres.size(),
                                                     Eigen::Vector3f::Constant(coarse)),
                        Eigen::Vector3d(0.55, 0.35, 0.75), unknown_opacity));
  return summary;
}

} // namespace planar_grid
