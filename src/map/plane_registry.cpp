// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/plane_registry.h>

#include <cmath>
#include <string>
#include <utility>

namespace planar_grid {

namespace {

/** \brief \a params, after a check of each against its range.
 * \throws planar_grid::Exception naming the first parameter out of its range */
const PlaneRegistryParams&
checkedParams(const PlaneRegistryParams& params)
{
  namespace ranges = plane_registry_ranges;
  const auto check = [](const ParamRange& range, double value, const char* name,
                        const char* unit) {
    if (!range.contains(value))
      throw Exception("PlaneRegistry: " + paramRangeMessage(name, range, unit));
  };
  check(ranges::EPS_ANGLE, params.eps_angle_rad, "eps_angle_rad", "rad");
  check(ranges::DISTANCE_THRESHOLD, params.distance_threshold_m, "distance_threshold_m",
        "m");
  check(ranges::LEAF_SIZE, params.leaf_size_m, "leaf_size_m", "m");
  return params;
}

/** \brief The association of the run-wide planes: normals within eps_angle_rad in
 * either orientation (a plane's normal may come either way from a frame's fit), offsets
 * d within distance_threshold_m. */
PlaneAssociationCriteria
associationCriteria(const PlaneRegistryParams& params)
{
  PlaneAssociationCriteria criteria;
  criteria.eps_angle_rad = params.eps_angle_rad;
  criteria.distance_threshold_m = params.distance_threshold_m;
  criteria.orientation = PlaneOrientation::EITHER;
  criteria.distance = PlaneDistance::OFFSET;
  return criteria;
}

} // namespace

PlaneRegistry::PlaneRegistry() : PlaneRegistry(Params()) {}

PlaneRegistry::PlaneRegistry(const Params& params) :
    params_(checkedParams(params)), association_(associationCriteria(params))
{}

void
PlaneRegistry::setParams(const Params& params)
{
  const bool new_leaf_size = checkedParams(params).leaf_size_m != params_.leaf_size_m;
  params_ = params;
  association_ = PlaneAssociation(associationCriteria(params));
  if (new_leaf_size)
    resetLeaves(); // the voxels of the last downsample() were of the old size
}

int
PlaneRegistry::associate(const Eigen::Vector4f& model_coefficients,
                         std::size_t inlier_count)
{
  if (!model_coefficients.allFinite()
      || !(model_coefficients.head<3>().squaredNorm() > 0.0f)) {
    PCL_WARN("[planar_grid::PlaneRegistry::associate] Plane coefficients [%g, %g, %g, "
             "%g] without a finite normal.\n",
             model_coefficients[0], model_coefficients[1], model_coefficients[2],
             model_coefficients[3]);
    return -1;
  }
  const std::ptrdiff_t found = association_.findBest(
    model_coefficients_.size(),
    [this](std::size_t k) { return PlaneObservation{model_coefficients_[k]}; },
    PlaneObservation{model_coefficients});
  if (found < 0) {
    model_coefficients_.push_back(model_coefficients);
    inlier_counts_.push_back(inlier_count);
    return static_cast<int>(model_coefficients_.size() - 1);
  }
  const auto best = static_cast<std::size_t>(found);
  model_coefficients_[best] = averageModelCoefficients(
    model_coefficients_[best], static_cast<float>(inlier_counts_[best]),
    model_coefficients, static_cast<float>(inlier_count));
  inlier_counts_[best] += inlier_count;
  return static_cast<int>(best);
}

void
PlaneRegistry::cropToWindow(const Eigen::Vector3d& sensor_origin,
                            double window_half_size_m)
{
  cropToWindowXY(inlier_cloud_, sensor_origin, window_half_size_m);
  resetLeaves(); // the points moved: the voxels' indices no longer hold
}

std::size_t
PlaneRegistry::LeafHash::operator()(const Leaf& l) const
{
  return static_cast<std::size_t>(
    (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.x)) * 73856093U)
    ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.y)) * 19349669U)
    ^ (static_cast<std::uint64_t>(static_cast<std::uint32_t>(l.z)) * 83492791U));
}

void
PlaneRegistry::resetLeaves()
{
  leaves_.clear();
  sampled_points_ = 0;
}

void
PlaneRegistry::downsample()
{
  if (params_.leaf_size_m <= 0.0)
    return;
  // single precision, as pcl::UniformSampling computes the voxels and the distances
  const auto leaf = static_cast<float>(params_.leaf_size_m);
  const float inverse = 1.0f / leaf;
  auto& cloud = inlier_cloud_;
  if (sampled_points_ > cloud.size())
    resetLeaves();
  std::size_t kept = sampled_points_;
  for (std::size_t i = sampled_points_; i < cloud.size(); ++i) {
    const pcl::PointXYZL p = cloud[i];
    if (!std::isfinite(p.x) || !std::isfinite(p.y) || !std::isfinite(p.z))
      continue;
    const Eigen::Array3f scaled = p.getArray3fMap() * inverse;
    if (!(scaled.abs() < 2.0e9f).all())
      continue; // beyond the voxel indices (1e7 m at a 5 mm leaf)
    const Eigen::Array3f cell = scaled.floor();
    const Leaf key{static_cast<std::int32_t>(cell.x()),
                   static_cast<std::int32_t>(cell.y()),
                   static_cast<std::int32_t>(cell.z())};
    const auto [it, added] = leaves_.emplace(key, static_cast<std::uint32_t>(kept));
    if (added) {
      cloud[kept++] = p;
      continue;
    }
    Eigen::Vector4f centre = Eigen::Vector4f::Zero();
    centre.head<3>() = ((cell + 0.5f) * leaf).matrix();
    pcl::PointXYZL& held = cloud[it->second];
    if ((p.getVector4fMap() - centre).squaredNorm()
        < (held.getVector4fMap() - centre).squaredNorm())
      held = p;
  }
  cloud.resize(kept);
  cloud.is_dense = true;
  sampled_points_ = kept;
}

void
PlaneRegistry::setPlanes(PlaneModels model_coefficients,
                         std::vector<std::size_t> inlier_counts,
                         PointCloud inlier_cloud)
{
  if (model_coefficients.size() != inlier_counts.size())
    throw Exception("PlaneRegistry::setPlanes: "
                    + std::to_string(model_coefficients.size()) + " planes but "
                    + std::to_string(inlier_counts.size()) + " inlier counts");
  for (const auto& m : model_coefficients)
    if (!m.allFinite())
      throw Exception("PlaneRegistry::setPlanes: non-finite plane coefficients");
  for (const auto& p : inlier_cloud.points)
    if (p.label >= model_coefficients.size())
      throw Exception("PlaneRegistry::setPlanes: a point labelled "
                      + std::to_string(p.label) + " among "
                      + std::to_string(model_coefficients.size()) + " planes");
  model_coefficients_ = std::move(model_coefficients);
  inlier_counts_ = std::move(inlier_counts);
  inlier_cloud_ = std::move(inlier_cloud);
  resetLeaves();
}

void
PlaneRegistry::clear()
{
  model_coefficients_.clear();
  inlier_counts_.clear();
  inlier_cloud_.clear();
  resetLeaves();
}

} // namespace planar_grid
