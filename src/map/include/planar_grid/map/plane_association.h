// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/core/planar_cuboid.h>

#include <Eigen/Core>

#include <array>
#include <cstddef>
#include <cstdint>
#include <limits>

namespace planar_grid {

/** \brief Area moments of the evidence of a plane (the faces of the planar cuboids
 * seen on it), in double about an anchor point so that planes far from the world
 * origin keep their precision: weight = sum of the face areas (m^2), sum = sum of
 * area (centre - anchor), sum_sq = sum of area ((centre - anchor)(centre - anchor)^T
 * + width^2 / 12 h h^T + height^2 / 12 v v^T), the exact first and second moments of
 * the face rectangles (h, v their horizontal and vertical axes). sum_sq is symmetric;
 * its upper triangle is stored (xx, xy, xz, yy, yz, zz). \ingroup map */
struct PlaneMoments {
  /** The first face's centre, world frame, meters. */
  Eigen::Vector3d anchor{Eigen::Vector3d::Zero()};
  /** Sum of the face areas, m^2 (0: no evidence). */
  double weight{0.0};
  /** Area-weighted sum of the face centres relative to the anchor, m^3. */
  Eigen::Vector3d sum{Eigen::Vector3d::Zero()};
  /** Upper triangle of the second moments about the anchor, m^4. */
  std::array<double, 6> sum_sq_upper{};

  /** \brief The second moments as a symmetric matrix, m^4. */
  Eigen::Matrix3d sumSq() const;

  /** \brief Stores \a s made exactly symmetric (rounding in the products of the
   * updates is not), so that the 6 stored values restore it bit for bit. */
  void setSumSq(const Eigen::Matrix3d& s);

  /** \brief Adds the face of \a c with weight its area plus \a min_weight (m^2; so
   * that a face of zero area still counts as a point). The first face sets the
   * anchor. */
  void addFace(const PlanarCuboid& c, double min_weight);

  /** \brief Adds \a other (its moments moved to this anchor). */
  void add(const PlaneMoments& other);

  /** \brief Weighted mean squared distance of the evidence to the plane
   * n . x + d = 0 (\a n unit, \a d meters), square meters (0 without evidence). */
  double meanSquaredDistance(const Eigen::Vector3d& n, double d) const;

  /** \brief True when every member is equal. */
  bool operator==(const PlaneMoments& o) const;
};

/** \brief Least-squares plane of the evidence \a m: the normal is the eigenvector of
 * the smallest eigenvalue of the covariance, oriented like \a current_normal, used
 * when the evidence spans a plane (middle eigenvalue >= 4 x the smallest, > 0) and
 * within the angle whose cosine is \a cos_max_angle of \a current_normal (else
 * \a current_normal is kept); d puts the plane through the centroid.
 * \param[in] m the evidence
 * \param[in] current_normal the plane's normal so far (any length > 0)
 * \param[in] cos_max_angle cosine of the largest change of the normal
 * \param[out] normal unit normal
 * \param[out] d offset, meters (|d| <= 1e7)
 * \return false (outputs untouched) without evidence or for non-finite results
 * \ingroup map */
bool fitPlane(const PlaneMoments& m,
              const Eigen::Vector3f& current_normal,
              double cos_max_angle,
              Eigen::Vector3d& normal,
              double& d);

/** \brief Which normals may belong to one surface. \ingroup map */
enum class PlaneOrientation : std::uint8_t {
  /** Only normals pointing the same way (toward the sensors that saw the plane): the
   * two faces of a wall stay two planes. */
  SAME = 0,
  /** Either orientation: an observed plane is flipped to the registered one's side. */
  EITHER = 1
};

/** \brief How far an observed plane is from a registered one. \ingroup map */
enum class PlaneDistance : std::uint8_t {
  /** |d_registered - d_observed| of the coefficients (the observed plane oriented
   * like the registered one), meters. */
  OFFSET = 0,
  /** Where the faces are: the least-squares plane of both evidence sets together
   * (fitPlane(), from the registered normal) must lie within the angle of each
   * normal, and the root mean square distance of each set to it within the
   * threshold; the distance is the observed set's, meters. Needs the evidence of both
   * planes. */
  EVIDENCE_RMS = 1
};

/** \brief When an observed plane is the same physical surface as a registered plane
 * (the association of the planes of many frames into one set of planes). Defaults:
 * the surface layer's. \ingroup map */
struct PlaneAssociationCriteria {
  /** Largest angle between the normals, radians; in [0, pi/2]. */
  double eps_angle_rad{0.1};
  /** Largest distance (PlaneDistance), meters; >= 0. */
  double distance_threshold_m{0.15};
  /** Which normals may match. */
  PlaneOrientation orientation{PlaneOrientation::SAME};
  /** How the distance is measured. */
  PlaneDistance distance{PlaneDistance::EVIDENCE_RMS};
};

/** \brief A plane as the association sees it: its coefficients [a, b, c, d] (unit
 * normal, d in meters) and, for PlaneDistance::EVIDENCE_RMS, its evidence.
 * \ingroup map */
struct PlaneObservation {
  /** [a, b, c, d], unit normal, d in meters. */
  Eigen::Vector4f model_coefficients{Eigen::Vector4f::Zero()};
  /** The plane's evidence (not owned); nullptr when the criteria do not need it. */
  const PlaneMoments* evidence{nullptr};
};

/** \brief Association of observed planes with registered ones (one surface, one
 * plane), by PlaneAssociationCriteria: the test of one pair (match()) and the search
 * for the best registered plane (findBest()). The callers keep their planes; this
 * class holds the criteria only. \ingroup map */
class PlaneAssociation {
public:
  /** \brief Keeps \a criteria (not validated: the callers validate their
   * parameters). */
  explicit PlaneAssociation(const PlaneAssociationCriteria& criteria);

  /** \brief The criteria. */
  const PlaneAssociationCriteria& getCriteria() const { return criteria_; }

  /** \brief Whether \a observed is the same surface as \a registered.
   * \param[in] registered a registered plane (with EVIDENCE_RMS, its normal is the
   * start of the joint fit)
   * \param[in] observed the observed plane
   * \param[out] distance its distance by the criteria, meters (set on a match)
   * \return true on a match; false also when EVIDENCE_RMS lacks an evidence or it has
   * no weight */
  bool match(const PlaneObservation& registered,
             const PlaneObservation& observed,
             double& distance) const;

  /** \brief The registered plane that \a observed matches at the smallest distance
   * (the lowest index on a tie).
   * \param[in] count number of registered planes
   * \param[in] registered callable: registered(k), k in [0, count), returns the
   * PlaneObservation of plane k
   * \param[in] observed the observed plane
   * \return the index, or -1 when none matches */
  template <typename Registered>
  std::ptrdiff_t findBest(std::size_t count,
                          const Registered& registered,
                          const PlaneObservation& observed) const
  {
    std::ptrdiff_t best = -1;
    double best_distance = std::numeric_limits<double>::infinity();
    for (std::size_t k = 0; k < count; ++k) {
      double distance = 0.0;
      if (match(registered(k), observed, distance) && distance < best_distance) {
        best = static_cast<std::ptrdiff_t>(k);
        best_distance = distance;
      }
    }
    return best;
  }

private:
  /** \brief The criteria. */
  PlaneAssociationCriteria criteria_;
  /** \brief cos(eps_angle_rad). */
  double cos_angle_;
};

/** \brief The weighted mean of two planes' coefficients, renormalised to a unit
 * normal: (w_r registered + w_o observed) / max(w_r + w_o, 1), \a observed flipped to
 * the side of \a registered first (the update of a registered plane by an observation
 * whose weights are, for example, inlier counts).
 * \param[in] registered [a, b, c, d], unit normal, d in meters
 * \param[in] registered_weight its weight (>= 0)
 * \param[in] observed [a, b, c, d], unit normal, d in meters
 * \param[in] observed_weight its weight (>= 0)
 * \ingroup map */
Eigen::Vector4f averageModelCoefficients(const Eigen::Vector4f& registered,
                                         float registered_weight,
                                         Eigen::Vector4f observed,
                                         float observed_weight);

} // namespace planar_grid
