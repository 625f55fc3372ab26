// SPDX-License-Identifier: BSD-3-Clause
// The helpers of SACMultiPlaneSegmentation: the PCA plane fit, the plane model that
// keeps PCL quiet, the struct-of-arrays point store and the non-template plane tests
// and RANSAC compiled into the library. Included by sac_multi_plane_segmentation.hpp.
#pragma once

#include <pcl/common/centroid.h>
#include <pcl/common/eigen.h>
#include <pcl/common/point_tests.h>
#include <pcl/console/print.h>
#include <pcl/point_cloud.h>
#include <pcl/sample_consensus/ransac.h>
#include <pcl/sample_consensus/sac_model_plane.h>
#include <pcl/types.h>

#include <Eigen/Core>
#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <functional>
#include <limits>
#include <random>
#include <vector>

namespace planar_grid {

namespace detail {

/** \brief Flips [a, b, c, d] so that the origin lies on the positive side
 * (a o_x + b o_y + c o_z + d >= 0). */
inline void
orientTowards(Eigen::Vector4f& plane, const Eigen::Vector3f& origin)
{
  if (plane.head<3>().dot(origin) + plane[3] < 0.0f)
    plane = -plane;
}

/** \brief Whether \a plane is terrain that the normal and cluster tests spare: its
 * unit normal within acos(\a cos_tilt) of the unit \a up (either sign) and
 * \a origin (the sensor) more than max(0, \a min_height) above it along the plane's
 * upward normal. */
inline bool
isTerrainPlane(const Eigen::Vector4f& plane,
               const Eigen::Vector3f& up,
               const Eigen::Vector3f& origin,
               float cos_tilt,
               float min_height)
{
  const float c = plane.head<3>().dot(up);
  const float height =
    (c >= 0.0f ? 1.0f : -1.0f) * (plane.head<3>().dot(origin) + plane[3]);
  return std::abs(c) > cos_tilt && height > std::max(0.0f, min_height);
}

/** \brief Depth below a terrain plane beyond which a point of the frame counts as
 * lying under it (DensePoints::isTerrain()), meters: a road's noise and a kerb's step
 * stay within it. */
constexpr float TERRAIN_BELOW_MARGIN = 0.3f;

/** \brief Cell edge of a terrain plane's footprint in DensePoints::isTerrain(),
 * meters. */
constexpr float TERRAIN_BELOW_CELL = 0.3f;

/** \brief Most footprint cells of a frame (DensePoints::setTerrainFrame()). */
constexpr std::size_t MAX_FOOTPRINT_CELLS = std::size_t{1} << 22;

/** \brief Least-squares plane (PCA) of the indexed points: the eigenvector of the
 * smallest eigenvalue of the covariance; false when fewer than 3 points. */
template <typename PointT>
bool
fitPlanePCA(const pcl::PointCloud<PointT>& cloud,
            const pcl::Indices& indices,
            Eigen::Vector4f& plane,
            Eigen::Vector4f& centroid)
{
  if (indices.size() < 3)
    return false;
  Eigen::Matrix3f covariance;
  if (pcl::computeMeanAndCovarianceMatrix(cloud, indices, covariance, centroid) < 3)
    return false;
  float eigen_value = 0.0f;
  Eigen::Vector3f eigen_vector;
  pcl::eigen33(covariance, eigen_value, eigen_vector);
  if (!eigen_vector.allFinite() || !(eigen_vector.norm() > 0.0f))
    return false;
  eigen_vector.normalize();
  plane.head<3>() = eigen_vector;
  plane[3] = -eigen_vector.dot(centroid.head<3>());
  return true;
}

/** \brief True when the indexed points span a plane: the middle eigenvalue of their
 * covariance is > 1e-6 of the largest (false for coincident or colinear points). */
template <typename PointT>
bool
spansPlane(const pcl::PointCloud<PointT>& cloud, const pcl::Indices& indices)
{
  if (indices.size() < 3)
    return false;
  Eigen::Matrix3f covariance;
  Eigen::Vector4f centroid;
  pcl::computeMeanAndCovarianceMatrix(cloud, indices, covariance, centroid);
  const Eigen::Vector3f eigen_values =
    Eigen::SelfAdjointEigenSolver<Eigen::Matrix3f>(covariance, Eigen::EigenvaluesOnly)
      .eigenvalues();
  return eigen_values[1] > 1e-6f * eigen_values[2];
}

/** \brief pcl::SampleConsensusModelPlane that rejects a degenerate minimal sample
 * (coincident or colinear points: |(p1 - p0) x (p2 - p0)| below Eigen's float
 * dummy_precision, PCL's own test) with PCL_DEBUG instead of PCL_ERROR. PCL's model
 * prints an error for every such draw, and the sample consensus simply draws again, so
 * stereo features with duplicated positions (one SIFT keypoint, two orientations)
 * flooded the console; here the rejection is the expected, silent path.
 *
 * Its countWithinDistance() gives PCL's count (the same arithmetic: |n . (x, y, z, 1)|
 * < threshold, summed as Eigen sums the 4-vector's products) over a struct-of-arrays
 * copy of the indexed points. With setEarlyExit(true) it stops counting as soon as
 * the count cannot exceed the largest count it has returned (it then returns a count
 * no larger than that): pcl::RandomSampleConsensus keeps a hypothesis only when its
 * count exceeds the best so far, so it chooses exactly what full counts would choose,
 * while most hypotheses, which lose, are counted over part of the points only. */
template <typename PointT>
class QuietPlaneModel : public pcl::SampleConsensusModelPlane<PointT> {
public:
  QuietPlaneModel(const typename pcl::PointCloud<PointT>::ConstPtr& cloud,
                  const pcl::Indices& indices) :
      pcl::SampleConsensusModelPlane<PointT>(cloud, indices, false)
  {
    x_.reserve(indices.size());
    y_.reserve(indices.size());
    z_.reserve(indices.size());
    for (const auto i : indices) {
      x_.push_back((*cloud)[i].x);
      y_.push_back((*cloud)[i].y);
      z_.push_back((*cloud)[i].z);
    }
  }

  /** \brief Whether counts may stop early (only for an estimator that compares each
   * count with the best so far and keeps the larger, as RANSAC does). */
  void setEarlyExit(bool early_exit) { early_exit_ = early_exit; }

  std::size_t countWithinDistance(const Eigen::VectorXf& model_coefficients,
                                  const double threshold) const override
  {
    if (!this->isModelValid(model_coefficients) || x_.size() != this->indices_->size())
      return pcl::SampleConsensusModelPlane<PointT>::countWithinDistance(
        model_coefficients, threshold);
    constexpr std::size_t BLOCK = 64;
    const float a = model_coefficients[0], b = model_coefficients[1],
                c = model_coefficients[2], d = model_coefficients[3];
    const std::size_t n = x_.size();
    const float* px = x_.data();
    const float* py = y_.data();
    const float* pz = z_.data();
    std::size_t count = 0;
    for (std::size_t begin = 0; begin < n; begin += BLOCK) {
      const std::size_t end = std::min(n, begin + BLOCK);
      std::uint32_t block_count = 0;
      for (std::size_t k = begin; k < end; ++k) {
        const float dist = (a * px[k] + c * pz[k]) + (b * py[k] + d);
        block_count += static_cast<double>(std::abs(dist)) < threshold ? 1u : 0u;
      }
      count += block_count;
      if (early_exit_ && count + (n - end) <= best_count_)
        return count;
    }
    best_count_ = std::max(best_count_, count);
    return count;
  }

protected:
  bool isSampleGood(const pcl::Indices& samples) const override
  {
    if (samples.size() != 3)
      return false;
    const auto& cloud = *this->input_;
    const Eigen::Vector3f p0 = cloud[samples[0]].getVector3fMap();
    const Eigen::Vector3f p1 = cloud[samples[1]].getVector3fMap();
    const Eigen::Vector3f p2 = cloud[samples[2]].getVector3fMap();
    if ((p1 - p0).cross(p2 - p0).stableNorm()
        < Eigen::NumTraits<float>::dummy_precision()) {
      PCL_DEBUG("[planar_grid::SACMultiPlaneSegmentation] Rejected a degenerate "
                "(coincident or colinear) sample.\n");
      return false;
    }
    return true;
  }

private:
  /** \brief The indexed points' coordinates, meters. */
  std::vector<float> x_, y_, z_;
  /** \brief Whether counts may stop early. */
  bool early_exit_{false};
  /** \brief The largest count returned so far. */
  mutable std::size_t best_count_{0};
};

/** \brief Struct-of-arrays store of the unassigned finite input points, so that the
 * eq. 11 pass over ~10^5 points is one branch-free, vectorisable loop per plane. */
struct DensePoints {
  std::vector<float> x, y, z;
  /** Per-point eq. 11 threshold (range-dependent); empty: the fixed d_T. */
  std::vector<float> threshold;
  /** Along-sight depth noise: each point's depth error (eq. 4), unit line of sight
   * and the bounds of its threshold (d_T below, the inlier-only cap above); empty:
   * the threshold does not depend on the plane. */
  std::vector<float> depth_error, ray_x, ray_y, ray_z, floor, cap;
  /** Per-point unit surface normals (NaN where unknown: too few neighbours to tell);
   * empty: no normal test. */
  std::vector<float> nx, ny, nz;
  /** Normals on request (setNormalFunction()): the normal of an input index, set
   * into nx, ny, nz the first time the normal test examines the point; normal_known
   * says which are. Empty: nx, ny, nz hold every point's normal. */
  std::function<Eigen::Vector3f(pcl::index_t)> normal_of;
  std::vector<std::uint8_t> normal_known;
  /** Cosine of the largest angle between a point's normal and an inlier's plane
   * normal (either side); used when the normals are present. */
  float min_normal_cos{0.0f};
  /** Whether selectInliers() applies the normal test (the normals present). */
  bool use_normals{false};
  /** The normal test spares terrain: a plane whose unit normal lies within
   * acos(terrain_cos) of terrain_up (either sign) with terrain_origin more than
   * terrain_min_height above it. terrain_cos > 1: nothing is spared. */
  Eigen::Vector3f terrain_up{Eigen::Vector3f::UnitZ()};
  Eigen::Vector3f terrain_origin{Eigen::Vector3f::Zero()};
  float terrain_cos{2.0f};
  float terrain_min_height{0.0f};
  /** Largest ratio of the frame's points lying more than TERRAIN_BELOW_MARGIN below
   * a level plane, under its selected points' footprint, to those points (the frame
   * holds a floor under it: a table, a shelf, a slab in mid-air that cuts the walls);
   * 1: no test. */
  float terrain_max_below_ratio{1.0f};
  /** The frame's primary points as collected, before any plane took its inliers
   * (what lies below a plane), and the index of each one's footprint cell. */
  std::vector<float> frame_x, frame_y, frame_z;
  std::vector<std::uint32_t> frame_cell;

  /** \brief Keeps the primary points as the frame for isTerrain() and lays its grid
   * of footprint cells (TERRAIN_BELOW_CELL squares across terrain_up, coarser when
   * the points span more than MAX_FOOTPRINT_CELLS of them) over every point. Call
   * after collecting the points and setting terrain_up. */
  void setTerrainFrame()
  {
    frame_x.assign(x.begin(), x.begin() + static_cast<std::ptrdiff_t>(primary));
    frame_y.assign(y.begin(), y.begin() + static_cast<std::ptrdiff_t>(primary));
    frame_z.assign(z.begin(), z.begin() + static_cast<std::ptrdiff_t>(primary));
    cell_e1_ = terrain_up.unitOrthogonal();
    cell_e2_ = terrain_up.cross(cell_e1_);
    float u_min = std::numeric_limits<float>::max(), v_min = u_min;
    float u_max = std::numeric_limits<float>::lowest(), v_max = u_max;
    for (std::size_t k = 0; k < size(); ++k) {
      const Eigen::Vector3f p(x[k], y[k], z[k]);
      u_min = std::min(u_min, cell_e1_.dot(p));
      u_max = std::max(u_max, cell_e1_.dot(p));
      v_min = std::min(v_min, cell_e2_.dot(p));
      v_max = std::max(v_max, cell_e2_.dot(p));
    }
    cell_u0_ = u_min;
    cell_v0_ = v_min;
    cell_size_ = TERRAIN_BELOW_CELL;
    const auto cellsAlong = [&](float extent) {
      return static_cast<std::size_t>(std::max(0.0f, extent) / cell_size_) + 1;
    };
    while (cellsAlong(u_max - u_min) * cellsAlong(v_max - v_min) > MAX_FOOTPRINT_CELLS)
      cell_size_ *= 2.0f;
    cells_u_ = cellsAlong(u_max - u_min);
    cells_v_ = cellsAlong(v_max - v_min);
    footprint_.assign(cells_u_ * cells_v_, 0);
    frame_cell.resize(primary);
    for (std::size_t k = 0; k < primary; ++k)
      frame_cell[k] = cellOf(x[k], y[k], z[k]);
    terrain_cache_valid_ = false;
  }

  /** \brief Whether \a plane is terrain: level and far enough below terrain_origin
   * (isTerrainPlane()), and, with the selected points (mask) as its footprint of
   * cells (setTerrainFrame()), at most terrain_max_below_ratio frame points per
   * selected point more than TERRAIN_BELOW_MARGIN below it inside that footprint. The
   * answer for the last plane asked is kept: asked again (the normal agreement and
   * the cluster test of the same plane), it is the same. */
  bool isTerrain(const Eigen::Vector4f& plane)
  {
    if (!isTerrainPlane(plane, terrain_up, terrain_origin, terrain_cos,
                        terrain_min_height))
      return false;
    if (terrain_max_below_ratio >= 1.0f || frame_x.empty())
      return true;
    if (terrain_cache_valid_ && plane == terrain_cache_plane_)
      return terrain_cache_;
    // The normal oriented up: a point below the plane has a negative distance.
    const float s = plane.head<3>().dot(terrain_up) >= 0.0f ? 1.0f : -1.0f;
    const float a = s * plane[0], b = s * plane[1], c = s * plane[2];
    const float d = s * plane[3] + TERRAIN_BELOW_MARGIN;
    const std::size_t n = frame_x.size();
    std::size_t below_anywhere = 0;
    for (std::size_t k = 0; k < n; ++k)
      below_anywhere += (a * frame_x[k] + b * frame_y[k] + c * frame_z[k] + d < 0.0f);
    std::size_t selected = 0;
    for (const auto m : mask)
      selected += m;
    const float bound = terrain_max_below_ratio * static_cast<float>(selected);
    bool terrain = static_cast<float>(below_anywhere) <= bound;
    if (!terrain) {
      // Only the points under the plane's own footprint count.
      for (std::size_t k = 0; k < mask.size(); ++k)
        if (mask[k])
          footprint_[cellOf(x[k], y[k], z[k])] = 1;
      std::size_t below = 0;
      for (std::size_t k = 0; k < n; ++k)
        below += (a * frame_x[k] + b * frame_y[k] + c * frame_z[k] + d < 0.0f)
                 && footprint_[frame_cell[k]];
      std::fill(footprint_.begin(), footprint_.end(), std::uint8_t{0});
      terrain = static_cast<float>(below) <= bound;
    }
    terrain_cache_plane_ = plane;
    terrain_cache_ = terrain;
    terrain_cache_valid_ = true;
    return terrain;
  }

  /** \brief Whether the normal test applies to \a plane (the normals present and
   * the plane no terrain). */
  bool testsNormals(const Eigen::Vector4f& plane)
  {
    return use_normals && !isTerrain(plane);
  }
  pcl::Indices index;
  std::vector<std::uint8_t> mask;
  /** The first primary points may make planes; the rest are inlier-only (they stay
   * behind the primary ones, the removals being stable). */
  std::size_t primary{0};

  std::size_t size() const { return index.size(); }

  /** \brief Eq. 11 with the per-point thresholds (the fixed \a t when there are
   * none): mask[k] = 1 iff |a x + b y + c z + d| <= threshold[k]; returns the count. */
  std::size_t selectInliers(const Eigen::Vector4f& plane, float t)
  {
    std::size_t count = 0;
    if (threshold.empty()) {
      count = select(plane, t);
    } else {
      setPlaneThresholds(plane);
      const std::size_t n = size();
      mask.resize(n);
      for (std::size_t k = 0; k < n; ++k) {
        const float dist =
          std::abs(plane[0] * x[k] + plane[1] * y[k] + plane[2] * z[k] + plane[3]);
        const std::uint8_t in = dist <= threshold[k] ? 1 : 0;
        mask[k] = in;
        count += in;
      }
    }
    if (testsNormals(plane))
      count -= deselectOffNormal(plane);
    return count;
  }

  /** \brief Eq. 11 alone (selectInliers() without the normal test), whatever
   * use_normals says. \return the number of points selected */
  std::size_t selectInliersByDistance(const Eigen::Vector4f& plane, float t)
  {
    const bool tested = use_normals;
    use_normals = false;
    const std::size_t count = selectInliers(plane, t);
    use_normals = tested;
    return count;
  }

  /** \brief Sets the unit normal of point \a k from \a v (any length), NaN when \a v
   * is not finite or zero. */
  void setNormal(std::size_t k, const Eigen::Vector3f& v)
  {
    const float length = v.norm();
    const bool valid = v.allFinite() && length > 0.0f;
    nx[k] = valid ? v.x() / length : std::numeric_limits<float>::quiet_NaN();
    ny[k] = valid ? v.y() / length : std::numeric_limits<float>::quiet_NaN();
    nz[k] = valid ? v.z() / length : std::numeric_limits<float>::quiet_NaN();
  }

  /** \brief With normals on request, asks normal_of for the selected points whose
   * normal is not known yet. */
  void requestSelectedNormals()
  {
    if (!normal_of)
      return;
    for (std::size_t k = 0; k < size(); ++k)
      if (mask[k] && !normal_known[k]) {
        setNormal(k, normal_of(index[k]));
        normal_known[k] = 1;
      }
  }

  /** \brief The number of selected points without a normal (NaN). */
  std::size_t countSelectedWithoutNormal()
  {
    requestSelectedNormals();
    std::size_t count = 0;
    for (std::size_t k = 0; k < size(); ++k)
      count += mask[k] && !std::isfinite(nx[k]) ? 1 : 0;
    return count;
  }

  /** \brief The normal test: deselects (mask 0) the selected points whose surface
   * normal makes more than acos(min_normal_cos) with \a plane's normal (either side);
   * with \a keep_off_normal, those that agree and those without a normal instead
   * (the mask keeps the points that disagree). A point without a normal (NaN: too few
   * neighbours to tell) is no evidence either way and stays an inlier by distance.
   * \return the number deselected */
  std::size_t deselectOffNormal(const Eigen::Vector4f& plane,
                                bool keep_off_normal = false)
  {
    requestSelectedNormals();
    std::size_t removed = 0;
    const float a = plane[0], b = plane[1], c = plane[2];
    for (std::size_t k = 0; k < size(); ++k) {
      if (!mask[k])
        continue;
      const float dot = std::abs(a * nx[k] + b * ny[k] + c * nz[k]);
      // NaN compares false: a point without a normal is kept by the test and
      // deselected by its inverse.
      const bool disagrees = dot < min_normal_cos;
      if (disagrees != keep_off_normal) {
        mask[k] = 0;
        ++removed;
      }
    }
    return removed;
  }

  /** \brief With along-sight depth noise, threshold[k] = min(cap, max(d_T, depth
   * error |n . u|)) for \a plane's normal n and the point's line of sight u; else
   * nothing. */
  void setPlaneThresholds(const Eigen::Vector4f& plane)
  {
    for (std::size_t k = 0; k < depth_error.size(); ++k) {
      const float along =
        std::abs(plane[0] * ray_x[k] + plane[1] * ray_y[k] + plane[2] * ray_z[k]);
      threshold[k] = std::min(cap[k], std::max(floor[k], depth_error[k] * along));
    }
  }

  /** \brief mask[k] = 1 iff |a x + b y + c z + d| <= t (eq. 11, unit normal); returns
   * the number of such points. */
  std::size_t select(const Eigen::Vector4f& plane, float t)
  {
    const float a = plane[0], b = plane[1], c = plane[2], d = plane[3];
    const std::size_t n = size();
    mask.resize(n);
    const float* px = x.data();
    const float* py = y.data();
    const float* pz = z.data();
    std::uint8_t* m = mask.data();
    std::size_t count = 0;
    for (std::size_t k = 0; k < n; ++k) {
      const float dist = std::abs(a * px[k] + b * py[k] + c * pz[k] + d);
      const std::uint8_t in = dist <= t ? 1 : 0;
      m[k] = in;
      count += in;
    }
    return count;
  }

  /** \brief The input indices of the selected points (mask == 1), in store order. */
  void selected(pcl::Indices& out) const
  {
    out.clear();
    for (std::size_t k = 0; k < size(); ++k)
      if (mask[k])
        out.push_back(index[k]);
  }

  /** \brief Removes the points whose mask is \a value, mask included (stable, in
   * place); the other points keep their mask. */
  void removeMarked(std::uint8_t value)
  {
    removeIf([this, value](std::size_t k) { return mask[k] == value; });
  }

  /** \brief Removes the selected points (stable, in place); the others keep their
   * mask (0). */
  void removeSelected()
  {
    removeIf([this](std::size_t k) { return mask[k] != 0; });
  }

  /** \brief Removes the points k for which \a remove(k) is true, from every field
   * (stable, in place). */
  template <typename Remove> void removeIf(Remove remove)
  {
    std::size_t w = 0;
    std::size_t removed_primary = 0;
    for (std::size_t k = 0; k < size(); ++k) {
      if (remove(k)) {
        removed_primary += k < primary ? 1 : 0;
        continue;
      }
      x[w] = x[k];
      y[w] = y[k];
      z[w] = z[k];
      if (!threshold.empty())
        threshold[w] = threshold[k];
      if (!depth_error.empty()) {
        depth_error[w] = depth_error[k];
        ray_x[w] = ray_x[k];
        ray_y[w] = ray_y[k];
        ray_z[w] = ray_z[k];
        floor[w] = floor[k];
        cap[w] = cap[k];
      }
      if (!nx.empty()) {
        nx[w] = nx[k];
        ny[w] = ny[k];
        nz[w] = nz[k];
      }
      if (!normal_known.empty())
        normal_known[w] = normal_known[k];
      index[w] = index[k];
      mask[w] = mask[k];
      ++w;
    }
    if (!nx.empty())
      for (auto* v : {&nx, &ny, &nz})
        v->resize(w);
    if (!normal_known.empty())
      normal_known.resize(w);
    x.resize(w);
    y.resize(w);
    z.resize(w);
    if (!threshold.empty())
      threshold.resize(w);
    if (!depth_error.empty())
      for (auto* v : {&depth_error, &ray_x, &ray_y, &ray_z, &floor, &cap})
        v->resize(w);
    index.resize(w);
    mask.resize(w);
    primary -= removed_primary;
  }

private:
  /** \brief Index of the footprint cell of a point (clamped into the grid). */
  std::uint32_t cellOf(float px, float py, float pz) const
  {
    const Eigen::Vector3f p(px, py, pz);
    const auto along = [&](float w, float w0, std::size_t cells) {
      const float i = std::floor((w - w0) / cell_size_);
      return static_cast<std::size_t>(
        std::min(std::max(i, 0.0f), static_cast<float>(cells - 1)));
    };
    return static_cast<std::uint32_t>(along(cell_e1_.dot(p), cell_u0_, cells_u_)
                                        * cells_v_
                                      + along(cell_e2_.dot(p), cell_v0_, cells_v_));
  }

  Eigen::Vector3f cell_e1_{Eigen::Vector3f::UnitX()},
    cell_e2_{Eigen::Vector3f::UnitY()};
  float cell_u0_{0.0f}, cell_v0_{0.0f}, cell_size_{TERRAIN_BELOW_CELL};
  std::size_t cells_u_{1}, cells_v_{1};
  std::vector<std::uint8_t> footprint_;
  Eigen::Vector4f terrain_cache_plane_{Eigen::Vector4f::Zero()};
  bool terrain_cache_{false};
  bool terrain_cache_valid_{false};
};

/** \brief Surface normals of struct-of-arrays points from a grid of moments: the
 * points are binned in cubic cells of edge `cell`; each point's normal is the
 * eigenvector of the smallest eigenvalue of the covariance of the points in the 3 x 3
 * x 3 block of cells around its own (a cube of edge 3 `cell`), as
 * pcl::NormalEstimation computes it over a k-d tree neighbourhood, at a fixed cost of
 * 27 look-ups per occupied cell. A block with fewer than `min_points` points, or
 * whose points do not span a surface (the middle eigenvalue below 1/16 of the
 * largest: a line), gives NaN. Not oriented (the sign is arbitrary).
 * \param[in] x, y, z n coordinates each, meters
 * \param[out] nx, ny, nz n components each */
void estimateGridNormals(const std::vector<float>& x,
                         const std::vector<float>& y,
                         const std::vector<float>& z,
                         float cell,
                         std::size_t min_points,
                         std::vector<float>& nx,
                         std::vector<float>& ny,
                         std::vector<float>& nz);

// The plane tests and the SoA RANSAC below are not templates: they are compiled once,
// in the library (src/sac_multi_plane_segmentation.cpp), not in every user of this
// file.

/** \brief The visibility test of one plane. A point of `all` conflicts with the plane
 * when it lies off the plane by more than `margin` + its own eq. 11 threshold (`t`
 * where `all` has none) and the line of sight from `origin` through it meets the plane
 * in a cell of the inliers' footprint (PlaneFootprint, cells of edge `cell`): behind
 * the plane, the point was seen through the surface; in front of it, it hides the
 * surface that the inlier was seen on. An opaque surface seen from `origin` has next
 * to no conflicts (an object in front of a wall hides cells that then hold no
 * inlier), while a slab through a volume of scattered points (a tree's canopy) has
 * about as many as inliers or more. A cell is transparent when, over it and its 8
 * neighbours, the conflicts outnumber `max_ratio` x the inliers; the inliers of
 * transparent cells are taken out of the plane (their mask set to 0).
 * \param[in] plane unit normal, oriented so that origin lies on the positive side
 * \return the number of inliers taken out */
std::size_t removeVisibilityConflicts(DensePoints& store,
                                      const DensePoints& all,
                                      float t,
                                      const Eigen::Vector4f& plane,
                                      const Eigen::Vector3f& origin,
                                      float margin,
                                      float cell,
                                      double max_ratio);

/** \brief The sensor plane test of one plane: when the plane passes closer than
 * `min_distance` to `origin` (|n . origin + d| < min_distance, n the unit normal),
 * its selected points (mask 1) are taken out of `store` altogether: stereo smears
 * every object along the lines of sight, and a plane that contains them takes the
 * smear for a surface; its points would only give the same plane again.
 * \return the number of points taken out (0 when the plane passes the test) */
std::size_t removeSensorPlane(DensePoints& store,
                              const Eigen::Vector4f& plane,
                              const Eigen::Vector3f& origin,
                              float min_distance);

/** \brief The shell test of one plane. A surface's points lie within its eq. 11
 * threshold t, up to stereo noise; a plane that cuts through a thicker structure (a
 * slab through a tree's canopy, a horizontal stripe across a facade or a car) has
 * points beyond the threshold on both sides as well, about as many per unit of
 * thickness as within it. A point of `all` is in the shell when it lies between t and
 * t + max(t, `width`) off the plane (t: its own eq. 11 threshold, `t` where `all` has
 * none) and its orthogonal projection falls in a cell of the inliers' footprint
 * (PlaneFootprint, cells of edge `cell`); front and back are counted apart. Where,
 * over a cell and its 8 neighbours, twice the smaller of the two counts exceeds
 * `max_ratio` x the inliers, the cell's inliers are taken out of the plane (their mask
 * set to 0). What stands on a surface or in front of it lies on one side only and does
 * not count. For a uniform volume or a perpendicular surface the ratio is about
 * max(t, width) / t (1 for the shell t..2t); for Gaussian noise of standard deviation
 * t (the noise reaching the threshold) it is 0.40.
 * \param[in] plane unit normal
 * \param[in] width smallest shell width, meters (e.g. the voxel edge of a voxelised
 * cloud, whose surface points lie in layers one voxel apart)
 * \return the number of inliers taken out */
std::size_t removeShellCells(DensePoints& store,
                             const DensePoints& all,
                             float t,
                             const Eigen::Vector4f& plane,
                             float width,
                             float cell,
                             double max_ratio);

/** \brief The cluster test of one plane: the selected points of `store` (mask 1) of
 * every connected cluster of the plane's footprint (PlaneFootprint, cells of edge
 * `cell`; cells up to two apart are connected) holding fewer than `min_size` of them
 * are taken out of the plane (mask 0). A plane through separate objects (two tree
 * trunks, a pole and a facade) or slicing a cluttered volume (car bodies, a shop
 * window) falls apart into small clusters; a surface is one large cluster.
 * \return the number of points taken out */
std::size_t removeSmallClusters(DensePoints& store,
                                const Eigen::Vector4f& plane,
                                float cell,
                                std::size_t min_size);

/** \brief Number of points (SoA) with |a x + b y + c z + d| <= t, counting in blocks
 * and stopping as soon as the count cannot exceed `to_beat` (then the partial count,
 * <= to_beat, is returned). With to_beat = 0 every point is counted, so the result is
 * exact whenever it is > to_beat: a RANSAC that keeps a hypothesis only when its count
 * is > the best so far chooses exactly what a full count would choose. Compiled in
 * the library (src/sac_multi_plane_segmentation.cpp) for the baseline instruction set
 * and for AVX2, chosen at load time by the CPU; both evaluate the same expression
 * (no fused multiply-add), so they count the same points.
 * \param[in] px, py, pz n coordinates each, meters
 * \param[in] plane [a, b, c, d], unit normal
 * \param[in] t distance threshold, meters */
std::size_t countWithinDistance(const float* px,
                                const float* py,
                                const float* pz,
                                std::size_t n,
                                const Eigen::Vector4f& plane,
                                float t,
                                std::size_t to_beat);

/** \brief Plain RANSAC for a plane on struct-of-arrays points, drawing minimal samples
 * with `rng`: the hypothesis with the most points within t wins; the iteration count
 * adapts as in pcl::RandomSampleConsensus (k = log(1 - p) / log(1 - w^3), capped at
 * max_iterations). Used for the local dense refinement, where PCL's
 * SampleConsensusModelPlane over an AoS index list cost most of the run time.
 * \return the inlier count of `plane` (unit normal), 0 when no valid sample was found
 */
std::size_t ransacPlane(const std::vector<float>& x,
                        const std::vector<float>& y,
                        const std::vector<float>& z,
                        float t,
                        int max_iterations,
                        double probability,
                        std::mt19937& rng,
                        Eigen::Vector4f& plane);

/** \brief Local optimisation of a plane (the LO step of LO-RANSAC, Chum, Matas and
 * Kittler, DAGM 2003): `iterations` minimal samples drawn with `rng` from the points
 * within t of the starting plane, each counted over the first n points (SoA, early
 * exit; the others take no part); a
 * sample plane with more points within t replaces the plane. Only a strictly better
 * count is accepted, so the count never decreases.
 * \return the exact number of points within t of the returned `plane` */
std::size_t optimizePlane(const std::vector<float>& x,
                          const std::vector<float>& y,
                          const std::vector<float>& z,
                          std::size_t n,
                          float t,
                          int iterations,
                          std::mt19937& rng,
                          Eigen::Vector4f& plane);

} // namespace detail

} // namespace planar_grid
