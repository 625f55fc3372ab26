// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
PLANAR_GRID_INSTANTIATE(SACMultiPlaneSegmentation, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE

// The RANSAC's inner loop: on x86-64 with GNU ifunc, an AVX2 clone (8 floats a step
// instead of SSE2's 4) beside the baseline one, chosen by the loader. AVX2 alone does
// not enable FMA, so both clones round a x + b y + c z + d alike.
#if defined(__x86_64__) && defined(__GNUC__) && defined(__ELF__) \
  && !defined(__INTEL_COMPILER)
#define PLANAR_GRID_TARGET_CLONES __attribute__((target_clones("avx2", "default")))
#else
#define PLANAR_GRID_TARGET_CLONES
#endif

namespace planar_grid {
namespace detail {

PLANAR_GRID_TARGET_CLONES std::size_t
countWithinDistance(const float* px,
                    const float* py,
                    const float* pz,
                    std::size_t n,
                    const Eigen::Vector4f& plane,
                    float t,
                    std::size_t to_beat)
{
  constexpr std::size_t BLOCK = 256;
  const float a = plane[0], b = plane[1], c = plane[2], d = plane[3];
  std::size_t count = 0;
  for (std::size_t begin = 0; begin < n; begin += BLOCK) {
    const std::size_t end = std::min(n, begin + BLOCK);
    std::uint32_t block_count = 0;
    for (std::size_t k = begin; k < end; ++k)
      block_count += std::abs(a * px[k] + b * py[k] + c * pz[k] + d) <= t ? 1u : 0u;
    count += block_count;
    if (to_beat > 0 && count + (n - end) <= to_beat)
      return count;
  }
  return count;
}

/** \brief Open-addressing map from a packed 64-bit cell key to a cell number
 * (linear probing, at most half full): the footprint look-ups of the visibility test,
 * one per input point and plane, without std::unordered_map's node per entry. */
class CellIndex {
public:
  static constexpr std::uint32_t NONE = std::numeric_limits<std::uint32_t>::max();

  /** \brief An empty map for up to \a max_size keys. */
  explicit CellIndex(std::size_t max_size)
  {
    std::size_t capacity = 16;
    while (capacity < 2 * max_size)
      capacity *= 2;
    keys_.resize(capacity);
    values_.assign(capacity, NONE);
    mask_ = capacity - 1;
  }

  /** \brief The number of \a key, NONE when absent. */
  std::uint32_t find(std::uint64_t key) const
  {
    for (std::size_t slot = hash(key);; slot = (slot + 1) & mask_) {
      if (values_[slot] == NONE || keys_[slot] == key)
        return values_[slot];
    }
  }

  /** \brief The number of \a key, which gets \a value when absent; \a inserted tells
   * which. */
  std::uint32_t emplace(std::uint64_t key, std::uint32_t value, bool& inserted)
  {
    std::size_t slot = hash(key);
    while (values_[slot] != NONE && keys_[slot] != key)
      slot = (slot + 1) & mask_;
    inserted = values_[slot] == NONE;
    if (inserted) {
      keys_[slot] = key;
      values_[slot] = value;
    }
    return values_[slot];
  }

private:
  std::size_t hash(std::uint64_t key) const
  {
    key ^= key >> 31;
    key *= 0x9E3779B97F4A7C15ULL;
    return static_cast<std::size_t>(key ^ (key >> 29)) & mask_;
  }

  std::vector<std::uint64_t> keys_;
  std::vector<std::uint32_t> values_;
  std::size_t mask_{0};
};

/** \brief The footprint of one plane's inliers (the points of a store whose mask is
 * 1): the square cells of edge `cell`, in the plane's own 2D frame, that hold the
 * orthogonal projection of an inlier. Each cell counts its inliers and the evidence a
 * test adds against it, on the plane's front (the normal's side) and back;
 * removeCells() takes the inliers out of the cells where, over the cell and its 8
 * neighbours, the evidence outnumbers a ratio x the inliers. Used by the visibility
 * and the shell tests. */
class PlaneFootprint {
public:
  /** \brief The footprint of the selected points of \a store for \a plane (unit
   * normal) with cells of edge \a cell, in meters. */
  PlaneFootprint(const DensePoints& store, const Eigen::Vector4f& plane, float cell) :
      cell_(cell), index_of_(countSelected(store))
  {
    const Eigen::Vector3f normal = plane.head<3>();
    // An orthonormal frame (u, v) of the plane.
    const Eigen::Vector3f helper =
      std::abs(normal.x()) < 0.9f ? Eigen::Vector3f::UnitX() : Eigen::Vector3f::UnitY();
    u_ = normal.cross(helper).normalized();
    v_ = normal.cross(u_);
    cell_of_inlier_.resize(store.size());
    for (std::size_t k = 0; k < store.size(); ++k) {
      if (!store.mask[k])
        continue;
      const Eigen::Vector2i c =
        cellOf(Eigen::Vector3f(store.x[k], store.y[k], store.z[k]));
      bool inserted = false;
      const std::uint32_t n = index_of_.emplace(
        key(c.x(), c.y()), static_cast<std::uint32_t>(cells_.size()), inserted);
      if (inserted)
        cells_.push_back({c.x(), c.y()});
      ++cells_[n].inliers;
      cell_of_inlier_[k] = n;
    }
  }

  /** \brief The number of the footprint cell holding the orthogonal projection of \a p
   * onto the plane, CellIndex::NONE when that cell holds no inlier. */
  std::uint32_t cellAt(const Eigen::Vector3f& p) const
  {
    const Eigen::Vector2i c = cellOf(p);
    return index_of_.find(key(c.x(), c.y()));
  }

  /** \brief Adds one piece of evidence against cell \a n (a number from cellAt()),
   * from the plane's back (\a back true) or front. */
  void addEvidence(std::uint32_t n, bool back)
  {
    ++(back ? cells_[n].back_evidence : cells_[n].front_evidence);
  }

  /** \brief Takes out of \a store (mask set to 0) the inliers of every cluster of
   * footprint cells holding fewer than \a min_size inliers. A cluster is a connected
   * set of cells, two cells being connected when they are at most two cells apart
   * along each axis (a gap of one empty cell is bridged).
   * \return the number of inliers taken out */
  std::size_t removeSmallClusters(DensePoints& store, std::size_t min_size) const
  {
    constexpr std::uint32_t UNSET = CellIndex::NONE;
    std::vector<std::uint32_t> cluster(cells_.size(), UNSET);
    std::vector<std::size_t> cluster_size;
    std::vector<std::uint32_t> stack;
    for (std::size_t c = 0; c < cells_.size(); ++c) {
      if (cluster[c] != UNSET)
        continue;
      const auto id = static_cast<std::uint32_t>(cluster_size.size());
      cluster_size.push_back(0);
      cluster[c] = id;
      stack.assign(1, static_cast<std::uint32_t>(c));
      while (!stack.empty()) {
        const std::uint32_t n = stack.back();
        stack.pop_back();
        cluster_size[id] += cells_[n].inliers;
        for (int di = -2; di <= 2; ++di)
          for (int dj = -2; dj <= 2; ++dj) {
            const std::uint32_t m =
              index_of_.find(key(cells_[n].i + di, cells_[n].j + dj));
            if (m != CellIndex::NONE && cluster[m] == UNSET) {
              cluster[m] = id;
              stack.push_back(m);
            }
          }
      }
    }
    std::size_t removed = 0;
    for (std::size_t k = 0; k < store.size(); ++k)
      if (store.mask[k] && cluster_size[cluster[cell_of_inlier_[k]]] < min_size) {
        store.mask[k] = 0;
        ++removed;
      }
    return removed;
  }

  /** \brief Takes the inliers of every cell whose 3 x 3 neighbourhood holds more than
   * \a max_ratio x its inliers of evidence out of \a store (their mask set to 0).
   * The evidence is the front's plus the back's, or, when \a two_sided, twice the
   * smaller of the two (evidence on one side only then counts for nothing).
   * \return the number of inliers taken out */
  std::size_t removeCells(DensePoints& store, double max_ratio, bool two_sided) const
  {
    std::vector<std::uint8_t> rejected(cells_.size(), 0);
    bool any = false;
    for (std::size_t c = 0; c < cells_.size(); ++c) {
      std::size_t inliers = 0, front = 0, back = 0;
      for (int di = -1; di <= 1; ++di)
        for (int dj = -1; dj <= 1; ++dj) {
          const std::uint32_t n =
            index_of_.find(key(cells_[c].i + di, cells_[c].j + dj));
          if (n == CellIndex::NONE)
            continue;
          inliers += cells_[n].inliers;
          front += cells_[n].front_evidence;
          back += cells_[n].back_evidence;
        }
      const std::size_t evidence = two_sided ? 2 * std::min(front, back) : front + back;
      rejected[c] =
        static_cast<double>(evidence) > max_ratio * static_cast<double>(inliers) ? 1
                                                                                 : 0;
      any = any || rejected[c];
    }
    if (!any)
      return 0;
    std::size_t removed = 0;
    for (std::size_t k = 0; k < store.size(); ++k)
      if (store.mask[k] && rejected[cell_of_inlier_[k]]) {
        store.mask[k] = 0;
        ++removed;
      }
    return removed;
  }

private:
  struct Cell {
    int i, j;
    std::size_t inliers{0}, front_evidence{0}, back_evidence{0};
  };

  static std::size_t countSelected(const DensePoints& store)
  {
    std::size_t count = 0;
    for (std::size_t k = 0; k < store.size(); ++k)
      count += store.mask[k] ? 1 : 0;
    return count;
  }

  static std::uint64_t key(int i, int j)
  {
    return (static_cast<std::uint64_t>(static_cast<std::uint32_t>(i)) << 32)
           | static_cast<std::uint32_t>(j);
  }

  Eigen::Vector2i cellOf(const Eigen::Vector3f& p) const
  {
    return Eigen::Vector2i(static_cast<int>(std::floor(u_.dot(p) / cell_)),
                           static_cast<int>(std::floor(v_.dot(p) / cell_)));
  }

  float cell_;
  Eigen::Vector3f u_, v_;
  std::vector<Cell> cells_;
  CellIndex index_of_;
  std::vector<std::uint32_t> cell_of_inlier_;
};

/** \brief Mask value of a point that the sensor plane test takes out of the store. */
constexpr std::uint8_t SENSOR_PLANE = 2;

std::size_t
removeVisibilityConflicts(DensePoints& store,
                          const DensePoints& all,
                          float t,
                          const Eigen::Vector4f& plane,
                          const Eigen::Vector3f& origin,
                          float margin,
                          float cell,
                          double max_ratio)
{
  const Eigen::Vector3f normal = plane.head<3>();
  const float origin_distance = normal.dot(origin) + plane[3];
  if (!(origin_distance > 0.0f))
    return 0;
  PlaneFootprint footprint(store, plane, cell);
  bool any = false;
  for (std::size_t k = 0; k < all.size(); ++k) {
    const Eigen::Vector3f q(all.x[k], all.y[k], all.z[k]);
    const float s = normal.dot(q) + plane[3];
    const float off = margin + (all.threshold.empty() ? t : all.threshold[k]);
    // Off the plane, and not beside or behind the origin (whose line of sight through
    // q never meets the plane).
    if (!(std::abs(s) > off) || !(s < origin_distance))
      continue;
    // Where the line of sight from the origin through q meets the plane: before q
    // (lambda < 1) when q is behind it, beyond q when q is in front.
    const float lambda = origin_distance / (origin_distance - s);
    const std::uint32_t n = footprint.cellAt(origin + lambda * (q - origin));
    if (n != CellIndex::NONE) {
      footprint.addEvidence(n, s < 0.0f);
      any = true;
    }
  }
  return any ? footprint.removeCells(store, max_ratio, false) : 0;
}

std::size_t
removeSensorPlane(DensePoints& store,
                  const Eigen::Vector4f& plane,
                  const Eigen::Vector3f& origin,
                  float min_distance)
{
  if (!(std::abs(plane.head<3>().dot(origin) + plane[3]) < min_distance))
    return 0;
  std::size_t removed = 0;
  for (std::size_t k = 0; k < store.size(); ++k)
    if (store.mask[k]) {
      store.mask[k] = SENSOR_PLANE;
      ++removed;
    }
  store.removeMarked(SENSOR_PLANE);
  return removed;
}

std::size_t
removeShellCells(DensePoints& store,
                 const DensePoints& all,
                 float t,
                 const Eigen::Vector4f& plane,
                 float width,
                 float cell,
                 double max_ratio)
{
  PlaneFootprint footprint(store, plane, cell);
  const Eigen::Vector3f normal = plane.head<3>();
  bool any = false;
  for (std::size_t k = 0; k < all.size(); ++k) {
    const Eigen::Vector3f q(all.x[k], all.y[k], all.z[k]);
    const float s = normal.dot(q) + plane[3];
    const float t_k = all.threshold.empty() ? t : all.threshold[k];
    if (!(std::abs(s) > t_k) || !(std::abs(s) <= t_k + std::max(t_k, width)))
      continue;
    const std::uint32_t n = footprint.cellAt(q);
    if (n != CellIndex::NONE) {
      footprint.addEvidence(n, s < 0.0f);
      any = true;
    }
  }
  return any ? footprint.removeCells(store, max_ratio, true) : 0;
}

std::size_t
removeSmallClusters(DensePoints& store,
                    const Eigen::Vector4f& plane,
                    float cell,
                    std::size_t min_size)
{
  const PlaneFootprint footprint(store, plane, cell);
  return footprint.removeSmallClusters(store, min_size);
}

std::size_t
ransacPlane(const std::vector<float>& x,
            const std::vector<float>& y,
            const std::vector<float>& z,
            float t,
            int max_iterations,
            double probability,
            std::mt19937& rng,
            Eigen::Vector4f& plane)
{
  const std::size_t n = x.size();
  if (n < 3)
    return 0;
  std::uniform_int_distribution<std::size_t> pick(0, n - 1);
  const double log_probability = std::log(1.0 - probability);
  double k = max_iterations;
  std::size_t best = 0;
  int skipped = 0;
  const int max_skip = 10 * max_iterations;
  for (int iteration = 0; iteration < k && iteration < max_iterations;) {
    const std::size_t i0 = pick(rng), i1 = pick(rng), i2 = pick(rng);
    const Eigen::Vector3f p0(x[i0], y[i0], z[i0]);
    const Eigen::Vector3f normal = (Eigen::Vector3f(x[i1], y[i1], z[i1]) - p0)
                                     .cross(Eigen::Vector3f(x[i2], y[i2], z[i2]) - p0);
    const float norm = normal.norm();
    if (i0 == i1 || i0 == i2 || i1 == i2 || !(norm > 1e-12f)) {
      if (++skipped > max_skip)
        break;
      continue;
    }
    ++iteration;
    Eigen::Vector4f candidate;
    candidate.head<3>() = normal / norm;
    candidate[3] = -candidate.head<3>().dot(p0);
    const std::size_t count =
      countWithinDistance(x.data(), y.data(), z.data(), n, candidate, t, best);
    if (count <= best)
      continue;
    best = count;
    plane = candidate;
    const double w = static_cast<double>(best) / static_cast<double>(n);
    const double p_no_outliers =
      std::max(std::numeric_limits<double>::epsilon(),
               std::min(1.0 - w * w * w, 1.0 - std::numeric_limits<double>::epsilon()));
    k = log_probability / std::log(p_no_outliers);
  }
  return best;
}

std::size_t
optimizePlane(const std::vector<float>& x,
              const std::vector<float>& y,
              const std::vector<float>& z,
              std::size_t n,
              float t,
              int iterations,
              std::mt19937& rng,
              Eigen::Vector4f& plane)
{
  n = std::min(n, x.size());
  std::vector<std::size_t> inliers;
  for (std::size_t k = 0; k < n; ++k)
    if (std::abs(plane[0] * x[k] + plane[1] * y[k] + plane[2] * z[k] + plane[3]) <= t)
      inliers.push_back(k);
  std::size_t best = inliers.size();
  if (best < 3)
    return best;
  std::uniform_int_distribution<std::size_t> pick(0, inliers.size() - 1);
  for (int iteration = 0; iteration < iterations; ++iteration) {
    const std::size_t i0 = inliers[pick(rng)], i1 = inliers[pick(rng)],
                      i2 = inliers[pick(rng)];
    const Eigen::Vector3f p0(x[i0], y[i0], z[i0]);
    const Eigen::Vector3f normal = (Eigen::Vector3f(x[i1], y[i1], z[i1]) - p0)
                                     .cross(Eigen::Vector3f(x[i2], y[i2], z[i2]) - p0);
    const float norm = normal.norm();
    if (!(norm > 1e-12f))
      continue;
    Eigen::Vector4f candidate;
    candidate.head<3>() = normal / norm;
    candidate[3] = -candidate.head<3>().dot(p0);
    const std::size_t count =
      countWithinDistance(x.data(), y.data(), z.data(), n, candidate, t, best);
    if (count > best) {
      best = count;
      plane = candidate;
    }
  }
  return best;
}

void
estimateGridNormals(const std::vector<float>& x,
                    const std::vector<float>& y,
                    const std::vector<float>& z,
                    float cell,
                    std::size_t min_points,
                    std::vector<float>& nx,
                    std::vector<float>& ny,
                    std::vector<float>& nz)
{
  const std::size_t n = x.size();
  const float nan = std::numeric_limits<float>::quiet_NaN();
  nx.assign(n, nan);
  ny.assign(n, nan);
  nz.assign(n, nan);
  if (n == 0 || !(cell > 0.0f))
    return;
  // 21 bits per axis: +-2^20 cells around the first point.
  constexpr std::int64_t BIAS = std::int64_t(1) << 20;
  const Eigen::Vector3d reference(x[0], y[0], z[0]);
  const double inv_cell = 1.0 / static_cast<double>(cell);
  const auto cellOf = [&](std::size_t k) {
    return Eigen::Vector3i(
      static_cast<int>(std::floor((x[k] - reference.x()) * inv_cell)),
      static_cast<int>(std::floor((y[k] - reference.y()) * inv_cell)),
      static_cast<int>(std::floor((z[k] - reference.z()) * inv_cell)));
  };
  const auto pack = [&](const Eigen::Vector3i& c) {
    return (static_cast<std::uint64_t>(c.x() + BIAS) << 42)
           | (static_cast<std::uint64_t>(c.y() + BIAS) << 21)
           | static_cast<std::uint64_t>(c.z() + BIAS);
  };
  const auto inRange = [&](const Eigen::Vector3i& c) {
    return c.cwiseAbs().maxCoeff() < BIAS - 1;
  };
  // The raw moments of each occupied cell, relative to the first point (double: the
  // world coordinates can be hundreds of meters).
  struct Moments {
    double count{0.0};
    Eigen::Vector3d sum{Eigen::Vector3d::Zero()};
    Eigen::Matrix3d outer{Eigen::Matrix3d::Zero()};
  };
  CellIndex index_of(n);
  std::vector<Moments> moments;
  std::vector<Eigen::Vector3i> cells;
  std::vector<std::uint32_t> cell_of_point(n, CellIndex::NONE);
  for (std::size_t k = 0; k < n; ++k) {
    const Eigen::Vector3i c = cellOf(k);
    if (!inRange(c))
      continue;
    bool inserted = false;
    const std::uint32_t id =
      index_of.emplace(pack(c), static_cast<std::uint32_t>(moments.size()), inserted);
    if (inserted) {
      moments.emplace_back();
      cells.push_back(c);
    }
    const Eigen::Vector3d p = Eigen::Vector3d(x[k], y[k], z[k]) - reference;
    Moments& m = moments[id];
    m.count += 1.0;
    m.sum += p;
    m.outer.selfadjointView<Eigen::Upper>().rankUpdate(p);
    cell_of_point[k] = id;
  }
  // The normal of each occupied cell from its 3 x 3 x 3 block.
  std::vector<Eigen::Vector3f, Eigen::aligned_allocator<Eigen::Vector3f>> normal(
    cells.size(), Eigen::Vector3f::Constant(nan));
  for (std::size_t id = 0; id < cells.size(); ++id) {
    Moments block;
    for (int dx = -1; dx <= 1; ++dx)
      for (int dy = -1; dy <= 1; ++dy)
        for (int dz = -1; dz <= 1; ++dz) {
          const std::uint32_t j =
            index_of.find(pack(cells[id] + Eigen::Vector3i(dx, dy, dz)));
          if (j == CellIndex::NONE)
            continue;
          block.count += moments[j].count;
          block.sum += moments[j].sum;
          block.outer += moments[j].outer;
        }
    if (block.count < static_cast<double>(std::max<std::size_t>(3, min_points)))
      continue;
    const Eigen::Vector3d mean = block.sum / block.count;
    Eigen::Matrix3d covariance = block.outer / block.count - mean * mean.transpose();
    covariance = covariance.selfadjointView<Eigen::Upper>();
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver;
    solver.computeDirect(covariance);
    const Eigen::Vector3d values = solver.eigenvalues(); // ascending
    if (!(values[2] > 0.0) || values[1] < values[2] / 16.0)
      continue;
    normal[id] = solver.eigenvectors().col(0).normalized().cast<float>();
  }
  for (std::size_t k = 0; k < n; ++k)
    if (cell_of_point[k] != CellIndex::NONE) {
      const Eigen::Vector3f& v = normal[cell_of_point[k]];
      nx[k] = v.x();
      ny[k] = v.y();
      nz[k] = v.z();
    }
}

} // namespace detail
} // namespace planar_grid
