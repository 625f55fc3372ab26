// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/exceptions.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>
#include <planar_grid/surface/rectangle_merge.h>

#include <pcl/PolygonMesh.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/point_types.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>

namespace planar_grid {

template <typename PointT>
Eigen::Vector3f
PlanarCuboidApproximation<PointT>::getHorizontalReference() const
{
  const float up_norm = up_axis_.norm();
  if (!up_axis_.allFinite() || !(up_norm > 0.0f))
    return Eigen::Vector3f::Zero();
  const Eigen::Vector3f up = up_axis_ / up_norm;
  Eigen::Vector3f best = Eigen::Vector3f::Zero();
  float best_norm = -1.0f;
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3f axis = Eigen::Vector3f::Unit(k);
    const Eigen::Vector3f projected = axis - up * up.dot(axis);
    // "longest" with a margin so that ties keep the earlier axis deterministically
    if (projected.norm() > best_norm + 1e-6f) {
      best = projected;
      best_norm = projected.norm();
    }
  }
  return best / best_norm;
}

template <typename PointT>
const char*
PlanarCuboidApproximation<PointT>::checkParameters() const
{
  namespace ranges = planar_cuboid_approximation_ranges;
  // One message per check, the range ones written from their range once (static: the
  // returned pointer stays valid).
  static const std::array<std::string, 9> messages{
    paramRangeMessage("min_cell_size", ranges::MIN_CELL_SIZE, "m"),
    paramRangeMessage("density_threshold", ranges::DENSITY_THRESHOLD),
    paramRangeMessage("non_planar_density_threshold",
                      ranges::NON_PLANAR_DENSITY_THRESHOLD),
    paramRangeMessage("min_width", ranges::MIN_WIDTH, "m"),
    paramRangeMessage("min_height", ranges::MIN_HEIGHT, "m"),
    paramRangeMessage("thickness", ranges::THICKNESS, "m"),
    paramRangeMessage("min_points_per_cell", ranges::MIN_POINTS_PER_CELL),
    "up_axis must be finite and non-zero",
    "sensor_origin must be finite"};
  const std::array<bool, 9> valid{
    ranges::MIN_CELL_SIZE.contains(params_.min_cell_size_m),
    ranges::DENSITY_THRESHOLD.contains(params_.density_threshold),
    ranges::NON_PLANAR_DENSITY_THRESHOLD.contains(params_.non_planar_density_threshold),
    ranges::MIN_WIDTH.contains(params_.min_width_m),
    ranges::MIN_HEIGHT.contains(params_.min_height_m),
    ranges::THICKNESS.contains(params_.thickness_m),
    ranges::MIN_POINTS_PER_CELL.contains(params_.min_points_per_cell),
    up_axis_.allFinite() && up_axis_.norm() > 0.0f,
    getSensorOrigin().allFinite()};
  for (std::size_t i = 0; i < valid.size(); ++i)
    if (!valid[i])
      return messages[i].c_str();
  return nullptr;
}

template <typename PointT>
bool
PlanarCuboidApproximation<PointT>::initCompute()
{
  if (!pcl::PCLBase<PointT>::initCompute()) {
    PCL_ERROR("[planar_grid::%s::approximate] No input cloud given.\n",
              getClassName().c_str());
    return false;
  }
  const char* bad = checkParameters();
  if (bad != nullptr) {
    PCL_ERROR("[planar_grid::%s::approximate] Invalid parameter: %s.\n",
              getClassName().c_str(), bad);
    pcl::PCLBase<PointT>::deinitCompute();
    return false;
  }
  if (input_->empty() || indices_->empty()) {
    PCL_WARN("[planar_grid::%s::approximate] Empty input cloud.\n",
             getClassName().c_str());
    pcl::PCLBase<PointT>::deinitCompute();
    return false;
  }
  return true;
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::approximate(PlanarCuboids& cuboids)
{
  cuboids.clear();
  if (!initCompute())
    return;
  applyApproximation(cuboids);
  this->deinitCompute();
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::setPlanes(
  const std::vector<pcl::ModelCoefficients>& model_coefficients,
  const std::vector<pcl::PointIndices>& inliers)
{
  if (model_coefficients.size() != inliers.size())
    throw Exception("[planar_grid::" + getClassName() + "::setPlanes] "
                    + std::to_string(model_coefficients.size())
                    + " model_coefficients but " + std::to_string(inliers.size())
                    + " inlier lists; they must be parallel (one of each per plane)");
  PlanarSegments planes(model_coefficients.size());
  for (std::size_t i = 0; i < planes.size(); ++i) {
    planes[i].model_coefficients = model_coefficients[i];
    planes[i].inliers = inliers[i];
  }
  planes_ = std::move(planes);
}

namespace detail {

/** \brief Appends the box of \a cuboid to a triangle mesh: its 8 corners (in
 * PlanarCuboid::corners() order: the face, counter-clockwise seen from the front,
 * then the back) and 12 triangles, counter-clockwise seen from outside. */
inline void
appendCuboidMesh(const PlanarCuboid& cuboid,
                 pcl::PointCloud<pcl::PointXYZ>& vertices,
                 std::vector<pcl::Vertices>& polygons)
{
  const auto first = static_cast<pcl::index_t>(vertices.size());
  for (const Eigen::Vector3f& corner : cuboid.corners())
    vertices.push_back(pcl::PointXYZ(corner.x(), corner.y(), corner.z()));
  const auto triangle = [&polygons, first](pcl::index_t a, pcl::index_t b,
                                           pcl::index_t c) {
    pcl::Vertices polygon;
    polygon.vertices = {first + a, first + b, first + c};
    polygons.push_back(std::move(polygon));
  };
  // The face (0, 1, 2, 3) turns counter-clockwise about the normal, the back (4 to 7)
  // the other way round; each side joins a face edge (a, b) to its back edge.
  triangle(0, 1, 2);
  triangle(0, 2, 3);
  triangle(4, 6, 5);
  triangle(4, 7, 6);
  for (pcl::index_t a = 0; a < 4; ++a) {
    const pcl::index_t b = (a + 1) % 4;
    triangle(a, a + 4, b + 4);
    triangle(a, b + 4, b);
  }
}

} // namespace detail

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::reconstruct(pcl::PolygonMesh& mesh)
{
  PlanarCuboids cuboids;
  approximate(cuboids);
  pcl::PointCloud<pcl::PointXYZ> vertices;
  if (input_)
    vertices.header = input_->header;
  vertices.reserve(8 * cuboids.size());
  mesh.polygons.clear();
  mesh.polygons.reserve(12 * cuboids.size());
  for (const PlanarCuboid& cuboid : cuboids)
    detail::appendCuboidMesh(cuboid, vertices, mesh.polygons);
  vertices.width = static_cast<std::uint32_t>(vertices.size());
  vertices.height = vertices.empty() ? 0 : 1;
  vertices.is_dense = true;
  pcl::toPCLPointCloud2(vertices, mesh.cloud);
  mesh.header = vertices.header;
}

template <typename PointT>
double
PlanarCuboidApproximation<PointT>::setUpRaster(float u_min,
                                               float u_max,
                                               float v_min,
                                               float v_max)
{
  double cell = params_.min_cell_size_m;
  double nu = std::floor((static_cast<double>(u_max) - u_min) / cell) + 1.0;
  double nv = std::floor((static_cast<double>(v_max) - v_min) / cell) + 1.0;
  while (nu * nv > static_cast<double>(MAX_RASTER_CELLS)) {
    cell *= 2.0;
    nu = std::floor((static_cast<double>(u_max) - u_min) / cell) + 1.0;
    nv = std::floor((static_cast<double>(v_max) - v_min) / cell) + 1.0;
  }
  if (cell != params_.min_cell_size_m)
    PCL_WARN("[planar_grid::%s::approximate] A cluster spans %g x %g m; its raster "
             "cell is coarsened to %g m.\n",
             getClassName().c_str(), static_cast<double>(u_max - u_min),
             static_cast<double>(v_max - v_min), cell);
  nu_ = static_cast<int>(nu);
  nv_ = static_cast<int>(nv);
  u_origin_ = u_min;
  v_origin_ = v_min;
  occupied_.assign(static_cast<std::size_t>(nu_) * static_cast<std::size_t>(nv_), 0);
  return cell;
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::splitUnits(double cell_m)
{
  const std::size_t stride = static_cast<std::size_t>(nu_) + 1;
  integral_.assign(stride * (static_cast<std::size_t>(nv_) + 1), 0);
  for (int v = 0; v < nv_; ++v) {
    std::uint32_t row_sum = 0;
    const std::uint8_t* occ = occupied_.data() + static_cast<std::size_t>(v) * nu_;
    std::uint32_t* above = integral_.data() + static_cast<std::size_t>(v) * stride;
    std::uint32_t* here = above + stride;
    for (int u = 0; u < nu_; ++u) {
      row_sum += occ[u];
      here[u + 1] = above[u + 1] + row_sum;
    }
  }
  const auto occupiedIn = [&](int u0, int v0, int u1, int v1) {
    return integral_[static_cast<std::size_t>(v1) * stride + u1]
           - integral_[static_cast<std::size_t>(v0) * stride + u1]
           - integral_[static_cast<std::size_t>(v1) * stride + u0]
           + integral_[static_cast<std::size_t>(v0) * stride + u0];
  };

  units_.clear();
  int root = 1;
  while (root < std::max(nu_, nv_))
    root *= 2;
  std::vector<Unit> stack;
  stack.reserve(64);
  stack.push_back(Unit{0, 0, root});
  while (!stack.empty()) {
    const Unit unit = stack.back();
    stack.pop_back();
    if (unit.u0 >= nu_ || unit.v0 >= nv_)
      continue;
    const int u1 = std::min(unit.u0 + unit.side, nu_);
    const int v1 = std::min(unit.v0 + unit.side, nv_);
    const std::uint32_t occupied = occupiedIn(unit.u0, unit.v0, u1, v1);
    if (occupied == 0)
      continue; // empty parts are dropped
    // Fig. 8, lines 7-8: D = S_PO / S_PA, W and H of the (square) unit
    const double area = static_cast<double>(unit.side) * unit.side;
    const double density = static_cast<double>(occupied) / area;
    const double size_m = unit.side * cell_m;
    const bool split = density < params_.density_threshold
                       && size_m > params_.min_width_m + 1e-9
                       && size_m > params_.min_height_m + 1e-9 && unit.side > 1;
    if (!split) {
      units_.push_back(unit);
      continue;
    }
    const int half = unit.side / 2;
    stack.push_back(Unit{unit.u0, unit.v0, half});
    stack.push_back(Unit{unit.u0 + half, unit.v0, half});
    stack.push_back(Unit{unit.u0, unit.v0 + half, half});
    stack.push_back(Unit{unit.u0 + half, unit.v0 + half, half});
  }
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::applyApproximation(PlanarCuboids& cuboids)
{
  const PointCloud& cloud = *input_;
  const std::size_t n = cloud.size();
  const Eigen::Vector3f origin = getSensorOrigin();

  state_.assign(n, 0);
  std::size_t available = 0;
  for (const auto index : *indices_) {
    if (index < 0 || static_cast<std::size_t>(index) >= n || state_[index] != 0)
      continue;
    if (pcl::isFinite(cloud[index])) {
      state_[index] = 1;
      ++available;
    }
  }
  if (available == 0) {
    PCL_WARN("[planar_grid::%s::approximate] No finite point in the input.\n",
             getClassName().c_str());
    return;
  }
  remainder_.clear();
  remainder_.reserve(available);

  for (std::size_t i = 0; i < planes_.size(); ++i) {
    const auto& c = planes_[i].model_coefficients.values;
    if (c.size() != 4 || !std::isfinite(c[0]) || !std::isfinite(c[1])
        || !std::isfinite(c[2]) || !std::isfinite(c[3])) {
      PCL_WARN("[planar_grid::%s::approximate] Plane %zu: model_coefficients are "
               "not 4 finite values; skipped.\n",
               getClassName().c_str(), i);
      continue;
    }
    Eigen::Vector3f normal(c[0], c[1], c[2]);
    const float norm = normal.norm();
    if (!(norm > 1e-6f)) {
      PCL_WARN("[planar_grid::%s::approximate] Plane %zu: zero normal; skipped.\n",
               getClassName().c_str(), i);
      continue;
    }
    normal /= norm;
    float d = c[3] / norm;
    if (normal.dot(origin) + d < 0.0f) { // face the sensor (front = positive side)
      normal = -normal;
      d = -d;
    }
    plane_points_.clear();
    for (const auto index : planes_[i].inliers.indices) {
      if (index < 0 || static_cast<std::size_t>(index) >= n || state_[index] != 1)
        continue;
      state_[index] = 2;
      plane_points_.push_back(index);
    }
    if (plane_points_.empty()) {
      PCL_WARN("[planar_grid::%s::approximate] Plane %zu: no usable inliers; "
               "skipped.\n",
               getClassName().c_str(), i);
      continue;
    }
    approximatePlane(static_cast<int>(i), normal, d, cuboids);
  }

  for (const auto index : *indices_) {
    if (index >= 0 && static_cast<std::size_t>(index) < n && state_[index] == 1) {
      state_[index] = 3;
      remainder_.push_back(index);
    }
  }
  approximateRemainder(cuboids);
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::approximatePlane(int plane_id,
                                                    const Eigen::Vector3f& normal,
                                                    float d,
                                                    PlanarCuboids& cuboids)
{
  const PointCloud& cloud = *input_;
  const Eigen::Vector3f up = up_axis_.normalized();
  // Horizontal axis: the plane's direction perpendicular to the up axis; for a
  // (near-)horizontal plane, the horizontal reference e1 projected onto the plane.
  Eigen::Vector3f horizontal = up.cross(normal);
  if (horizontal.norm() < 1e-3f) {
    const Eigen::Vector3f e1 = getHorizontalReference();
    horizontal = e1 - normal * normal.dot(e1);
  }
  horizontal.normalize();
  const Eigen::Vector3f vertical = normal.cross(horizontal);

  const std::size_t m = plane_points_.size();
  coords_.resize(m);
  float u_min = std::numeric_limits<float>::max(), u_max = -u_min;
  float v_min = u_min, v_max = -u_min;
  for (std::size_t k = 0; k < m; ++k) {
    const Eigen::Vector3f p = cloud[plane_points_[k]].getVector3fMap();
    const Eigen::Vector3f q(horizontal.dot(p), vertical.dot(p), normal.dot(p) + d);
    coords_[k] = q;
    u_min = std::min(u_min, q.x());
    u_max = std::max(u_max, q.x());
    v_min = std::min(v_min, q.y());
    v_max = std::max(v_max, q.y());
  }
  const double cell = setUpRaster(u_min, u_max, v_min, v_max);
  const float inv_cell = static_cast<float>(1.0 / cell);
  cell_of_point_.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    const int iu = std::min(
      nu_ - 1, std::max(0, static_cast<int>((coords_[k].x() - u_origin_) * inv_cell)));
    const int iv = std::min(
      nv_ - 1, std::max(0, static_cast<int>((coords_[k].y() - v_origin_) * inv_cell)));
    const int cell_index = iv * nu_ + iu;
    cell_of_point_[k] = cell_index;
    occupied_[cell_index] = 1;
  }
  splitUnits(cell);

  // Covered raster cells (-2) = union of the kept units.
  label_.assign(occupied_.size(), -1);
  for (const Unit& unit : units_) {
    const int u1 = std::min(unit.u0 + unit.side, nu_);
    const int v1 = std::min(unit.v0 + unit.side, nv_);
    for (int v = unit.v0; v < v1; ++v)
      std::fill(label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + unit.u0,
                label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + u1, -2);
  }

  // Merge (Fig. 6(b)): horizontal runs per raster row (equal heights), then runs with
  // equal u-extent in consecutive rows (equal widths) grow into one rectangle; each
  // covered cell is labelled with its rectangle.
  covered_keys_.clear();
  for (int v = 0; v < nv_; ++v)
    for (int u = 0; u < nu_; ++u)
      if (label_[static_cast<std::size_t>(v) * nu_ + u] == -2)
        covered_keys_.push_back(rasterCellKey(u, v));
  covered_classes_.assign(covered_keys_.size(), 0);
  const std::vector<RasterRectangle> rects =
    mergeRasterRectangles(covered_keys_, covered_classes_, RectangleMergeRule::PAPER);
  for (std::size_t r = 0; r < rects.size(); ++r)
    for (int v = rects[r].j0; v < rects[r].j1; ++v)
      std::fill(label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + rects[r].i0,
                label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + rects[r].i1,
                static_cast<int>(r));

  // Per rectangle: inlier count and (u, v, w) extent.
  struct Extent {
    std::size_t count{0};
    Eigen::Vector3f lo{Eigen::Vector3f::Constant(std::numeric_limits<float>::max())};
    Eigen::Vector3f hi{Eigen::Vector3f::Constant(-std::numeric_limits<float>::max())};
  };
  std::vector<Extent> extents(rects.size());
  for (std::size_t k = 0; k < m; ++k) {
    Extent& e = extents[label_[cell_of_point_[k]]];
    ++e.count;
    e.lo = e.lo.cwiseMin(coords_[k]);
    e.hi = e.hi.cwiseMax(coords_[k]);
  }
  const float cell_f = static_cast<float>(cell);
  const float thickness = static_cast<float>(params_.thickness_m);
  for (std::size_t r = 0; r < rects.size(); ++r) {
    const Extent& e = extents[r];
    if (e.count < static_cast<std::size_t>(params_.min_points_per_cell))
      continue;
    // Tighten to the inliers; keep at least one raster cell, inside the rectangle.
    const auto tighten = [cell_f](float lo, float hi, float r_lo, float r_hi) {
      if (hi - lo >= cell_f)
        return std::make_pair(lo, hi);
      const float mid = 0.5f * (lo + hi);
      float a = mid - 0.5f * cell_f;
      a = std::max(r_lo, std::min(a, r_hi - cell_f));
      return std::make_pair(std::min(a, lo), std::max(a + cell_f, hi));
    };
    const auto u = tighten(e.lo.x(), e.hi.x(), u_origin_ + rects[r].i0 * cell_f,
                           u_origin_ + rects[r].i1 * cell_f);
    const auto v = tighten(e.lo.y(), e.hi.y(), v_origin_ + rects[r].j0 * cell_f,
                           v_origin_ + rects[r].j1 * cell_f);
    // Fig. 6(c): face at the front-most inlier, extruded to the back.
    const float front = e.hi.z();
    const float back = std::min(e.lo.z(), front - thickness);
    PlanarCuboid cuboid;
    cuboid.normal = normal;
    cuboid.horizontal_axis = horizontal;
    cuboid.width_m = u.second - u.first;
    cuboid.height_m = v.second - v.first;
    cuboid.thickness_m = front - back;
    cuboid.centre = horizontal * (0.5f * (u.first + u.second))
                    + vertical * (0.5f * (v.first + v.second))
                    + normal * (0.5f * (front + back) - d);
    cuboid.plane_id = plane_id;
    cuboid.point_count = e.count;
    cuboid.is_planar = true;
    cuboids.push_back(cuboid);
  }
  // Inliers of dropped rectangles join the non-planar remainder.
  for (std::size_t k = 0; k < m; ++k)
    if (extents[label_[cell_of_point_[k]]].count
        < static_cast<std::size_t>(params_.min_points_per_cell)) {
      state_[plane_points_[k]] = 3;
      remainder_.push_back(plane_points_[k]);
    }
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::approximateRemainder(PlanarCuboids& cuboids)
{
  const std::size_t m = remainder_.size();
  if (m == 0)
    return;
  const PointCloud& cloud = *input_;
  const Eigen::Vector3f up = up_axis_.normalized();
  const Eigen::Vector3f e1 = getHorizontalReference();
  const Eigen::Vector3f e2 = up.cross(e1);

  coords_.resize(m);
  float a_min = std::numeric_limits<float>::max(), a_max = -a_min;
  float b_min = a_min, b_max = -a_min;
  for (std::size_t k = 0; k < m; ++k) {
    const Eigen::Vector3f p = cloud[remainder_[k]].getVector3fMap();
    const Eigen::Vector3f q(e1.dot(p), up.dot(p), e2.dot(p));
    coords_[k] = q;
    a_min = std::min(a_min, q.x());
    a_max = std::max(a_max, q.x());
    b_min = std::min(b_min, q.y());
    b_max = std::max(b_max, q.y());
  }
  const double cell = setUpRaster(a_min, a_max, b_min, b_max);
  const float inv_cell = static_cast<float>(1.0 / cell);
  cell_of_point_.resize(m);
  for (std::size_t k = 0; k < m; ++k) {
    const int ia = std::min(
      nu_ - 1, std::max(0, static_cast<int>((coords_[k].x() - u_origin_) * inv_cell)));
    const int ib = std::min(
      nv_ - 1, std::max(0, static_cast<int>((coords_[k].y() - v_origin_) * inv_cell)));
    const int cell_index = ib * nu_ + ia;
    cell_of_point_[k] = cell_index;
    occupied_[cell_index] = 1;
  }
  splitUnits(cell); // Fig. 7(a): split about the centre; never merged

  label_.assign(occupied_.size(), -1);
  for (std::size_t i = 0; i < units_.size(); ++i) {
    const Unit& unit = units_[i];
    const int u1 = std::min(unit.u0 + unit.side, nu_);
    const int v1 = std::min(unit.v0 + unit.side, nv_);
    for (int v = unit.v0; v < v1; ++v)
      std::fill(label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + unit.u0,
                label_.begin() + static_cast<std::ptrdiff_t>(v) * nu_ + u1,
                static_cast<int>(i));
  }
  // Counting sort of the points by unit.
  std::vector<std::size_t> offset(units_.size() + 1, 0);
  for (std::size_t k = 0; k < m; ++k)
    ++offset[label_[cell_of_point_[k]] + 1];
  for (std::size_t i = 0; i < units_.size(); ++i)
    offset[i + 1] += offset[i];
  std::vector<std::size_t> order(m);
  {
    std::vector<std::size_t> next(offset.begin(), offset.end() - 1);
    for (std::size_t k = 0; k < m; ++k)
      order[next[label_[cell_of_point_[k]]]++] = k;
  }

  const float cell_f = static_cast<float>(cell);
  for (std::size_t i = 0; i < units_.size(); ++i) {
    const auto first = order.begin() + static_cast<std::ptrdiff_t>(offset[i]);
    const auto last = order.begin() + static_cast<std::ptrdiff_t>(offset[i + 1]);
    std::sort(first, last, [this](std::size_t x, std::size_t y) {
      return coords_[x].z() < coords_[y].z();
    });
    // Cut along the depth e2 at gaps wider than one raster cell; each part with
    // enough points is then split in 3D until its boxes are supported.
    for (auto begin = first; begin != last;) {
      auto end = begin + 1;
      while (end != last && coords_[*end].z() - coords_[*(end - 1)].z() <= cell_f)
        ++end;
      const auto count = static_cast<std::size_t>(end - begin);
      if (count >= static_cast<std::size_t>(params_.min_points_per_cell))
        splitNonPlanarPart(begin, end, cell_f, cuboids);
      begin = end;
    }
  }
}

template <typename PointT>
void
PlanarCuboidApproximation<PointT>::splitNonPlanarPart(
  std::vector<std::size_t>::iterator first,
  std::vector<std::size_t>::iterator last,
  float cell,
  PlanarCuboids& cuboids)
{
  const Eigen::Vector3f up = up_axis_.normalized();
  const Eigen::Vector3f e1 = getHorizontalReference();
  const Eigen::Vector3f e2 = up.cross(e1);
  const float thickness = static_cast<float>(params_.thickness_m);
  const double box_density = params_.non_planar_density_threshold > 0.0
                               ? params_.non_planar_density_threshold
                               : params_.density_threshold;
  Eigen::Vector3f lo = coords_[*first];
  for (auto it = first; it != last; ++it)
    lo = lo.cwiseMin(coords_[*it]);
  // Voxel of each point on a lattice of edge `cell` anchored at the part's minimum.
  const auto voxelOf = [&](std::size_t k) {
    const Eigen::Vector3f q = (coords_[k] - lo) / cell;
    return Eigen::Vector3i(static_cast<int>(q.x()), static_cast<int>(q.y()),
                           static_cast<int>(q.z()));
  };
  struct Box {
    Eigen::Vector3i lo, hi;    // voxel range [lo, hi)
    std::ptrdiff_t begin, end; // range in `part`
  };
  std::vector<std::size_t> part(first, last);
  std::vector<Eigen::Vector3i, Eigen::aligned_allocator<Eigen::Vector3i>> voxel(
    part.size());
  Eigen::Vector3i extent = Eigen::Vector3i::Ones();
  for (std::size_t k = 0; k < part.size(); ++k) {
    voxel[k] = voxelOf(part[k]);
    extent = extent.cwiseMax(voxel[k] + Eigen::Vector3i::Ones());
  }
  std::vector<std::uint64_t> keys;
  const auto occupiedVoxels = [&](const Box& box) {
    keys.clear();
    for (auto k = box.begin; k < box.end; ++k) {
      const Eigen::Vector3i& v = voxel[static_cast<std::size_t>(k)];
      keys.push_back((static_cast<std::uint64_t>(v.x()) << 42)
                     | (static_cast<std::uint64_t>(v.y()) << 21)
                     | static_cast<std::uint64_t>(v.z()));
    }
    std::sort(keys.begin(), keys.end());
    return static_cast<std::size_t>(std::unique(keys.begin(), keys.end())
                                    - keys.begin());
  };
  // Order the part's points and voxels together so that a box is a contiguous range.
  std::vector<std::size_t> perm(part.size());
  std::vector<Box> stack{
    Box{Eigen::Vector3i::Zero(), extent, 0, static_cast<std::ptrdiff_t>(part.size())}};
  while (!stack.empty()) {
    const Box box = stack.back();
    stack.pop_back();
    const Eigen::Vector3i size = box.hi - box.lo;
    const double volume = static_cast<double>(size.x()) * size.y() * size.z();
    const double density = static_cast<double>(occupiedVoxels(box)) / volume;
    if (density >= box_density || volume <= 1.0) {
      Eigen::Vector3f b_lo = coords_[part[static_cast<std::size_t>(box.begin)]];
      Eigen::Vector3f b_hi = b_lo;
      for (auto k = box.begin; k < box.end; ++k) {
        b_lo = b_lo.cwiseMin(coords_[part[static_cast<std::size_t>(k)]]);
        b_hi = b_hi.cwiseMax(coords_[part[static_cast<std::size_t>(k)]]);
      }
      const auto widen = [](float& a, float& b, float min_size) {
        if (b - a < min_size) {
          const float mid = 0.5f * (a + b);
          a = mid - 0.5f * min_size;
          b = mid + 0.5f * min_size;
        }
      };
      widen(b_lo.x(), b_hi.x(), cell);
      widen(b_lo.y(), b_hi.y(), cell);
      widen(b_lo.z(), b_hi.z(), thickness);
      PlanarCuboid cuboid;
      cuboid.normal = -e2;
      cuboid.horizontal_axis = e1; // vertical = -e2 x e1 = up
      cuboid.width_m = b_hi.x() - b_lo.x();
      cuboid.height_m = b_hi.y() - b_lo.y();
      cuboid.thickness_m = b_hi.z() - b_lo.z();
      const Eigen::Vector3f mid = 0.5f * (b_lo + b_hi);
      cuboid.centre = e1 * mid.x() + up * mid.y() + e2 * mid.z();
      cuboid.plane_id = -1;
      cuboid.point_count = static_cast<std::size_t>(box.end - box.begin);
      cuboid.is_planar = false;
      cuboids.push_back(cuboid);
      continue;
    }
    // Split every axis longer than one voxel at its middle (an octree step).
    const Eigen::Vector3i mid = box.lo + (size.array() / 2).max(1).matrix();
    const auto child = [&](std::size_t k) {
      const Eigen::Vector3i& v = voxel[k];
      return (size.x() > 1 && v.x() >= mid.x() ? 1 : 0)
             | (size.y() > 1 && v.y() >= mid.y() ? 2 : 0)
             | (size.z() > 1 && v.z() >= mid.z() ? 4 : 0);
    };
    std::array<std::ptrdiff_t, 9> bucket{};
    for (auto k = box.begin; k < box.end; ++k)
      ++bucket[static_cast<std::size_t>(child(static_cast<std::size_t>(k))) + 1];
    for (std::size_t c = 0; c < 8; ++c)
      bucket[c + 1] += bucket[c];
    std::array<std::ptrdiff_t, 8> next{};
    for (std::size_t c = 0; c < 8; ++c)
      next[c] = box.begin + bucket[c];
    for (auto k = box.begin; k < box.end; ++k)
      perm[static_cast<std::size_t>(
        next[static_cast<std::size_t>(child(static_cast<std::size_t>(k)))]++)] =
        static_cast<std::size_t>(k);
    {
      std::vector<std::size_t> moved_part(
        static_cast<std::size_t>(box.end - box.begin));
      std::vector<Eigen::Vector3i, Eigen::aligned_allocator<Eigen::Vector3i>>
        moved_voxel(moved_part.size());
      for (auto k = box.begin; k < box.end; ++k) {
        const std::size_t from = perm[static_cast<std::size_t>(k)];
        moved_part[static_cast<std::size_t>(k - box.begin)] = part[from];
        moved_voxel[static_cast<std::size_t>(k - box.begin)] = voxel[from];
      }
      std::copy(moved_part.begin(), moved_part.end(), part.begin() + box.begin);
      std::copy(moved_voxel.begin(), moved_voxel.end(), voxel.begin() + box.begin);
    }
    for (int c = 0; c < 8; ++c) {
      const std::ptrdiff_t b = box.begin + bucket[static_cast<std::size_t>(c)];
      const std::ptrdiff_t e = box.begin + bucket[static_cast<std::size_t>(c) + 1];
      if (b == e)
        continue;
      Box sub;
      sub.begin = b;
      sub.end = e;
      for (int axis = 0; axis < 3; ++axis) {
        if (size[axis] <= 1) {
          sub.lo[axis] = box.lo[axis];
          sub.hi[axis] = box.hi[axis];
        } else if ((c >> axis) & 1) {
          sub.lo[axis] = mid[axis];
          sub.hi[axis] = box.hi[axis];
        } else {
          sub.lo[axis] = box.lo[axis];
          sub.hi[axis] = mid[axis];
        }
      }
      stack.push_back(sub);
    }
  }
}

} // namespace planar_grid

#define PLANAR_GRID_INSTANTIATE_PlanarCuboidApproximation(T) \
  template class planar_grid::PlanarCuboidApproximation<T>;
