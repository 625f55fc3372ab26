// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/map/plane_association.h>

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>

namespace planar_grid {

namespace {

/** \brief Largest plane offset accepted by fitPlane(), meters (corrupt data guard). */
constexpr float MAX_OFFSET_M = 1e7f;

} // namespace

Eigen::Matrix3d
PlaneMoments::sumSq() const
{
  Eigen::Matrix3d s;
  s << sum_sq_upper[0], sum_sq_upper[1], sum_sq_upper[2], sum_sq_upper[1],
    sum_sq_upper[3], sum_sq_upper[4], sum_sq_upper[2], sum_sq_upper[4], sum_sq_upper[5];
  return s;
}

void
PlaneMoments::setSumSq(const Eigen::Matrix3d& s)
{
  const Eigen::Matrix3d sym = 0.5 * (s + s.transpose());
  sum_sq_upper = {sym(0, 0), sym(0, 1), sym(0, 2), sym(1, 1), sym(1, 2), sym(2, 2)};
}

void
PlaneMoments::addFace(const PlanarCuboid& c, double min_weight)
{
  const double w = c.width_m, h = c.height_m;
  const double area = w * h + min_weight;
  const Eigen::Vector3d centre = c.faceCentre().cast<double>();
  if (weight == 0.0)
    anchor = centre;
  const Eigen::Vector3d rel = centre - anchor;
  const Eigen::Vector3d hx = c.horizontal_axis.cast<double>();
  const Eigen::Vector3d vy = c.verticalAxis().cast<double>();
  weight += area;
  sum += area * rel;
  Eigen::Matrix3d sum_sq = sumSq();
  sum_sq += area
            * (rel * rel.transpose() + (w * w / 12.0) * hx * hx.transpose()
               + (h * h / 12.0) * vy * vy.transpose());
  setSumSq(sum_sq);
}

void
PlaneMoments::add(const PlaneMoments& other)
{
  if (other.weight == 0.0)
    return;
  if (weight == 0.0) {
    *this = other;
    return;
  }
  const Eigen::Vector3d delta = other.anchor - anchor;
  Eigen::Matrix3d sum_sq = sumSq();
  const Eigen::Matrix3d other_sum_sq = other.sumSq();
  sum_sq += other_sum_sq + other.sum * delta.transpose() + delta * other.sum.transpose()
            + other.weight * delta * delta.transpose();
  sum += other.sum + other.weight * delta;
  weight += other.weight;
  setSumSq(sum_sq);
}

double
PlaneMoments::meanSquaredDistance(const Eigen::Vector3d& n, double d) const
{
  if (!(weight > 0.0))
    return 0.0;
  const double c = n.dot(anchor) + d;
  const double e =
    n.dot((sumSq() / weight) * n) + 2.0 * c * n.dot(sum / weight) + c * c;
  return std::max(0.0, e);
}

bool
PlaneMoments::operator==(const PlaneMoments& o) const
{
  return anchor == o.anchor && weight == o.weight && sum == o.sum
         && sum_sq_upper == o.sum_sq_upper;
}

bool
fitPlane(const PlaneMoments& m,
         const Eigen::Vector3f& current_normal,
         double cos_max_angle,
         Eigen::Vector3d& normal,
         double& d)
{
  if (!(m.weight > 0.0) || !std::isfinite(m.weight))
    return false;
  const Eigen::Vector3d mean = m.sum / m.weight;
  const Eigen::Matrix3d covariance = m.sumSq() / m.weight - mean * mean.transpose();
  if (!mean.allFinite() || !covariance.allFinite())
    return false;
  Eigen::Vector3d n = current_normal.cast<double>().normalized();
  const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(covariance);
  if (solver.info() == Eigen::Success) {
    const Eigen::Vector3d ev = solver.eigenvalues(); // ascending
    if (ev(1) > 0.0 && ev(1) >= 4.0 * std::max(0.0, ev(0))) {
      Eigen::Vector3d e = solver.eigenvectors().col(0).normalized();
      if (e.dot(n) < 0.0)
        e = -e;
      if (e.allFinite() && e.dot(n) >= cos_max_angle)
        n = e;
    }
  }
  const double offset = -n.dot(m.anchor + mean);
  if (!n.allFinite() || !std::isfinite(offset) || std::abs(offset) > MAX_OFFSET_M)
    return false;
  normal = n;
  d = offset;
  return true;
}

PlaneAssociation::PlaneAssociation(const PlaneAssociationCriteria& criteria) :
    criteria_(criteria), cos_angle_(std::cos(criteria.eps_angle_rad))
{}

bool
PlaneAssociation::match(const PlaneObservation& registered,
                        const PlaneObservation& observed,
                        double& distance) const
{
  const Eigen::Vector3f na = registered.model_coefficients.head<3>();
  Eigen::Vector3f nb = observed.model_coefficients.head<3>();
  float db = observed.model_coefficients[3];
  if (criteria_.orientation == PlaneOrientation::EITHER && na.dot(nb) < 0.0f) {
    nb = -nb;
    db = -db;
  }
  if (criteria_.distance == PlaneDistance::OFFSET) {
    // The coefficients are floats: the bounds are compared in float.
    if (!(na.dot(nb) >= static_cast<float>(cos_angle_)))
      return false;
    const float offset = std::abs(registered.model_coefficients[3] - db);
    if (!(offset <= static_cast<float>(criteria_.distance_threshold_m)))
      return false;
    distance = offset;
    return true;
  }
  // EVIDENCE_RMS: one plane explains both evidence sets.
  const PlaneMoments* a = registered.evidence;
  const PlaneMoments* b = observed.evidence;
  if (a == nullptr || b == nullptr || !(na.dot(nb) >= cos_angle_) || !(a->weight > 0.0)
      || !(b->weight > 0.0))
    return false;
  PlaneMoments joint = *a;
  joint.add(*b);
  Eigen::Vector3d n;
  double d = 0.0;
  if (!fitPlane(joint, na, cos_angle_, n, d)
      || !(n.dot(nb.cast<double>()) >= cos_angle_))
    return false;
  const double limit = criteria_.distance_threshold_m * criteria_.distance_threshold_m;
  const double ea = a->meanSquaredDistance(n, d);
  const double eb = b->meanSquaredDistance(n, d);
  if (!(ea <= limit) || !(eb <= limit))
    return false;
  distance = std::sqrt(eb);
  return true;
}

Eigen::Vector4f
averageModelCoefficients(const Eigen::Vector4f& registered,
                         float registered_weight,
                         Eigen::Vector4f observed,
                         float observed_weight)
{
  if (registered.head<3>().dot(observed.head<3>()) < 0.0f)
    observed = -observed;
  Eigen::Vector4f m = (registered_weight * registered + observed_weight * observed)
                      / std::max(registered_weight + observed_weight, 1.0f);
  m /= m.head<3>().norm();
  return m;
}

} // namespace planar_grid
