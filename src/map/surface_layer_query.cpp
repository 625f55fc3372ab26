// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's queries: the spatial hash over its cuboids, findCuboid() and
// castRay().
#include <planar_grid/map/surface_layer.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <utility>

#include "surface_layer_impl.h"

namespace planar_grid {

using namespace surface_layer_detail;

namespace {

/** \brief Ray / oriented box slab test; \a dir unit. Returns the entry distance (0
 * when the origin is inside), or a negative value when missed. */
float
rayBoxEntry(const PlanarCuboid& box,
            const Eigen::Vector3f& origin,
            const Eigen::Vector3f& dir,
            float max_t)
{
  const Eigen::Vector3f axes[3] = {box.horizontal_axis, box.verticalAxis(), box.normal};
  const float half[3] = {0.5f * box.width_m, 0.5f * box.height_m,
                         0.5f * box.thickness_m};
  const Eigen::Vector3f rel = origin - box.centre;
  float t0 = 0.0f, t1 = max_t;
  for (int k = 0; k < 3; ++k) {
    const float o = rel.dot(axes[k]);
    const float d = dir.dot(axes[k]);
    if (std::abs(d) < 1e-12f) {
      if (std::abs(o) > half[k])
        return -1.0f;
      continue;
    }
    float a = (-half[k] - o) / d;
    float b = (half[k] - o) / d;
    if (a > b)
      std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
    if (t0 > t1)
      return -1.0f;
  }
  return t0;
}

} // namespace

/** \brief Builds the spatial hash over all cuboids; caller holds the mutex. */
void
SurfaceLayer::Impl::ensureIndex(const Params& params)
{
  Impl& impl = *this;
  if (impl.index.valid)
    return;
  impl.index.cuboids.clear();
  buildCuboids(params, impl.index.cuboids);
  impl.index.bins.clear();
  impl.index.large.clear();
  impl.index.bounds_min = Eigen::Vector3f::Constant(std::numeric_limits<float>::max());
  impl.index.bounds_max = -impl.index.bounds_min;
  for (const auto& cuboid : impl.index.cuboids) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(cuboid, lo, hi);
    impl.index.bounds_min =
      impl.index.bounds_min.cwiseMin((lo.array() - 1e-4f).matrix());
    impl.index.bounds_max =
      impl.index.bounds_max.cwiseMax((hi.array() + 1e-4f).matrix());
  }
  // Bins of 4 cells; never more than 1e5 bins across the map's extent (a ray walks at
  // most ~3e5 bins), whatever the data.
  const float span = impl.index.cuboids.empty()
                       ? 0.0f
                       : (impl.index.bounds_max - impl.index.bounds_min).maxCoeff();
  impl.index.bin_m =
    std::max(static_cast<float>(4.0 * params.resolution_m), span * 1e-5f);
  const float inv = 1.0f / impl.index.bin_m;
  for (std::size_t c = 0; c < impl.index.cuboids.size(); ++c) {
    Eigen::Vector3f lo, hi;
    cuboidBounds(impl.index.cuboids[c], lo, hi);
    lo.array() -= 1e-4f;
    hi.array() += 1e-4f;
    const Eigen::Vector3d a = (lo * inv).cast<double>().array().floor();
    const Eigen::Vector3d b = (hi * inv).cast<double>().array().floor();
    const Eigen::Vector3d span = b - a + Eigen::Vector3d::Ones();
    if (!(span.prod() <= MAX_BINS_PER_CUBOID)) {
      impl.index.large.push_back(static_cast<std::uint32_t>(c));
      continue;
    }
    for (auto x = static_cast<std::int64_t>(a.x());
         x <= static_cast<std::int64_t>(b.x()); ++x)
      for (auto y = static_cast<std::int64_t>(a.y());
           y <= static_cast<std::int64_t>(b.y()); ++y)
        for (auto z = static_cast<std::int64_t>(a.z());
             z <= static_cast<std::int64_t>(b.z()); ++z)
          impl.index.bins[binKey(x, y, z)].push_back(static_cast<std::uint32_t>(c));
  }
  impl.index.valid = true;
}

const PlanarCuboid*
SurfaceLayer::findCuboid(const Eigen::Vector3f& point) const
{
  if (!point.allFinite())
    return nullptr;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& impl = *impl_;
  impl.ensureIndex(params_);
  const float inv = 1.0f / impl.index.bin_m;
  const std::uint32_t* best = nullptr;
  const auto consider = [&](const std::uint32_t& c) {
    if ((best == nullptr || c < *best) && impl.index.cuboids[c].contains(point))
      best = &c;
  };
  if ((point.array() >= impl.index.bounds_min.array()).all()
      && (point.array() <= impl.index.bounds_max.array()).all()) {
    const auto it = impl.index.bins.find(
      binKey(static_cast<std::int64_t>(std::floor(point.x() * inv)),
             static_cast<std::int64_t>(std::floor(point.y() * inv)),
             static_cast<std::int64_t>(std::floor(point.z() * inv))));
    if (it != impl.index.bins.end())
      for (const auto& c : it->second)
        consider(c);
  }
  for (const auto& c : impl.index.large)
    consider(c);
  return best == nullptr ? nullptr : &impl.index.cuboids[*best];
}

bool
SurfaceLayer::castRay(const Eigen::Vector3f& origin,
                      const Eigen::Vector3f& direction,
                      double max_range_m,
                      float& distance_m,
                      std::size_t& index) const
{
  const float len = direction.norm();
  if (!origin.allFinite() || !direction.allFinite() || !(len > 0.0f)
      || !(max_range_m >= 0.0))
    return false;
  const Eigen::Vector3f dir = direction / len;
  std::lock_guard<std::mutex> lock(impl_->mutex);
  Impl& impl = *impl_;
  impl.ensureIndex(params_);
  if (impl.index.cuboids.empty())
    return false;
  const float max_t = static_cast<float>(std::min(max_range_m, 1e9));
  const float thres = static_cast<float>(params_.occupancy_thres);
  float best_t = std::numeric_limits<float>::infinity();
  std::size_t best_index = 0;
  const auto test = [&](std::uint32_t c) {
    const PlanarCuboid& box = impl.index.cuboids[c];
    if (!(box.probability >= thres))
      return;
    const float t = rayBoxEntry(box, origin, dir, max_t);
    if (t >= 0.0f && (t < best_t || (t == best_t && c < best_index))) {
      best_t = t;
      best_index = c;
    }
  };
  for (const auto c : impl.index.large)
    test(c);
  // Clip the ray to the bounds of the index, then walk the bins (3D DDA).
  float t0 = 0.0f, t1 = max_t;
  for (int k = 0; k < 3; ++k) {
    if (std::abs(dir[k]) < 1e-12f) {
      if (origin[k] < impl.index.bounds_min[k] || origin[k] > impl.index.bounds_max[k])
        t1 = -1.0f;
      continue;
    }
    float a = (impl.index.bounds_min[k] - origin[k]) / dir[k];
    float b = (impl.index.bounds_max[k] - origin[k]) / dir[k];
    if (a > b)
      std::swap(a, b);
    t0 = std::max(t0, a);
    t1 = std::min(t1, b);
  }
  if (t0 <= t1) {
    const float bin = impl.index.bin_m;
    const Eigen::Vector3f start = origin + dir * t0;
    std::int64_t cell[3], step[3];
    float t_next[3], t_delta[3];
    for (int k = 0; k < 3; ++k) {
      cell[k] = static_cast<std::int64_t>(std::floor(start[k] / bin));
      if (dir[k] > 0.0f) {
        step[k] = 1;
        t_delta[k] = bin / dir[k];
        t_next[k] = t0 + ((static_cast<float>(cell[k] + 1) * bin) - start[k]) / dir[k];
      } else if (dir[k] < 0.0f) {
        step[k] = -1;
        t_delta[k] = -bin / dir[k];
        t_next[k] = t0 + ((static_cast<float>(cell[k]) * bin) - start[k]) / dir[k];
      } else {
        step[k] = 0;
        t_delta[k] = std::numeric_limits<float>::infinity();
        t_next[k] = std::numeric_limits<float>::infinity();
      }
    }
    // at most the bins along the clipped segment (+ slack), never unbounded
    const double max_steps = 3.0 * (t1 - t0) / bin + 8.0;
    for (double s = 0; s < max_steps; ++s) {
      const auto it = impl.index.bins.find(binKey(cell[0], cell[1], cell[2]));
      if (it != impl.index.bins.end())
        for (const auto c : it->second)
          test(c);
      int k = 0;
      if (t_next[1] < t_next[k])
        k = 1;
      if (t_next[2] < t_next[k])
        k = 2;
      const float t_exit = t_next[k];
      // a hit entering before this bin's exit cannot be beaten by later bins
      if (best_t <= t_exit || t_exit > t1)
        break;
      cell[k] += step[k];
      t_next[k] += t_delta[k];
    }
  }
  if (!(best_t <= max_t))
    return false;
  distance_m = best_t;
  index = best_index;
  return true;
}

} // namespace planar_grid
