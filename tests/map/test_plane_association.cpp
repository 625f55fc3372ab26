// SPDX-License-Identifier: BSD-3-Clause
#include <planar_grid/map/plane_association.h>

#include <gtest/gtest.h>

#include <cmath>
#include <random>
#include <vector>

namespace {

using planar_grid::PlaneAssociation;
using planar_grid::PlaneAssociationCriteria;
using planar_grid::PlaneDistance;
using planar_grid::PlaneMoments;
using planar_grid::PlaneObservation;
using planar_grid::PlaneOrientation;

/** A wall: unit normal \a n (horizontal), the plane n . x + d = 0. */
struct Wall {
  Eigen::Vector3f n;
  float d;
  Eigen::Vector3f u; // horizontal in-plane axis
  Eigen::Vector3f v; // vertical in-plane axis (n x u)

  Wall(const Eigen::Vector3f& normal, float offset) : n(normal.normalized()), d(offset)
  {
    u = Eigen::Vector3f::UnitZ().cross(n).normalized();
    v = n.cross(u);
  }
  Eigen::Vector4f coefficients() const { return {n.x(), n.y(), n.z(), d}; }
  /** The point at in-plane coordinates (a, b), meters, moved \a off along n. */
  Eigen::Vector3f at(float a, float b, float off = 0.0f) const
  {
    return -d * n + a * u + b * v + off * n;
  }
};

/** The evidence of \a cells faces of 0.2 x 0.2 m on \a wall in a 2 m x 2 m patch at
 * (a0, b0), each moved along the normal by Gaussian noise of \a sigma meters. */
PlaneMoments
faces(const Wall& wall, float a0, float b0, float sigma, std::mt19937& rng)
{
  std::normal_distribution<float> noise(0.0f, sigma);
  PlaneMoments m;
  for (int i = 0; i < 10; ++i)
    for (int j = 0; j < 10; ++j) {
      planar_grid::PlanarCuboid c;
      c.normal = wall.n;
      c.horizontal_axis = wall.u;
      c.width_m = 0.2f;
      c.height_m = 0.2f;
      c.thickness_m = 0.1f;
      c.centre = wall.at(a0 + 0.2f * i + 0.1f, b0 + 0.2f * j + 0.1f,
                         sigma > 0.0f ? noise(rng) : 0.0f)
                 - wall.n * 0.05f;
      m.addFace(c, 1e-8);
    }
  return m;
}

PlaneAssociationCriteria
evidenceCriteria()
{
  PlaneAssociationCriteria criteria; // the surface layer's: 0.1 rad, 0.15 m
  criteria.orientation = PlaneOrientation::SAME;
  criteria.distance = PlaneDistance::EVIDENCE_RMS;
  return criteria;
}

PlaneAssociationCriteria
offsetCriteria()
{
  PlaneAssociationCriteria criteria; // the accumulate stage's: 0.1 rad, 0.2 m
  criteria.eps_angle_rad = 0.1;
  criteria.distance_threshold_m = 0.2;
  criteria.orientation = PlaneOrientation::EITHER;
  criteria.distance = PlaneDistance::OFFSET;
  return criteria;
}

} // namespace

// Oracle: the exact moments of face rectangles give the mean squared distance of the
// faces' area to a plane; compared with a dense sampling of the faces (40 x 40 points
// per face) for a plane tilted against them.
TEST(PlaneMoments, MeanSquaredDistanceMatchesSampledFaces)
{
  const Wall wall(Eigen::Vector3f(1.0f, 0.2f, 0.0f), -3.0f);
  std::mt19937 rng(1);
  std::normal_distribution<float> noise(0.0f, 0.05f);
  PlaneMoments m;
  std::vector<Eigen::Vector3d> samples;
  for (int f = 0; f < 6; ++f) {
    planar_grid::PlanarCuboid c;
    c.normal = wall.n;
    c.horizontal_axis = wall.u;
    c.width_m = 0.3f + 0.1f * static_cast<float>(f);
    c.height_m = 0.5f;
    c.thickness_m = 0.1f;
    c.centre = wall.at(0.7f * f, 0.3f * f, noise(rng)) - wall.n * 0.05f;
    m.addFace(c, 0.0);
    for (int s = 0; s < 40; ++s)
      for (int t = 0; t < 40; ++t)
        samples.push_back((c.faceCentre()
                           + c.horizontal_axis * (c.width_m * ((s + 0.5f) / 40 - 0.5f))
                           + c.verticalAxis() * (c.height_m * ((t + 0.5f) / 40 - 0.5f)))
                            .cast<double>());
  }
  const Eigen::Vector3d n = Eigen::Vector3d(0.9, 0.3, 0.1).normalized();
  const double d = 2.5;
  // the area-weighted mean over the faces: each face's samples weighted by its area
  double sum = 0.0, weight = 0.0;
  for (int f = 0; f < 6; ++f) {
    const double area = (0.3 + 0.1 * f) * 0.5;
    for (int k = 0; k < 1600; ++k) {
      const double e = n.dot(samples[static_cast<std::size_t>(f * 1600 + k)]) + d;
      sum += area / 1600.0 * e * e;
    }
    weight += area;
  }
  // midpoint sampling of a linear function squared: error below 1e-3 relative
  EXPECT_NEAR(m.meanSquaredDistance(n, d), sum / weight, 1e-3 * sum / weight);
}

// A plane fitted to noisy faces (5 cm) of a 2 x 2 m patch converges to the truth, and
// the fit keeps the current normal when the evidence is a line (one row of faces).
TEST(PlaneMoments, FitPlaneRecoversTheWall)
{
  const Wall wall(Eigen::Vector3f(0.3f, -1.0f, 0.0f), 4.0f);
  std::mt19937 rng(2);
  const PlaneMoments m = faces(wall, -1.0f, 0.0f, 0.05f, rng);
  Eigen::Vector3d n;
  double d = 0.0;
  const Eigen::Vector3f start =
    (wall.n + Eigen::Vector3f(0.05f, 0.0f, 0.03f)).normalized();
  ASSERT_TRUE(planar_grid::fitPlane(m, start, std::cos(0.1), n, d));
  EXPECT_GT(n.dot(wall.n.cast<double>()), std::cos(0.02));
  EXPECT_NEAR(d, wall.d, 0.02);
  EXPECT_FALSE(planar_grid::fitPlane(PlaneMoments(), start, std::cos(0.1), n, d));
}

// The surface layer's criteria (0.1 rad, 0.15 m): the same wall seen again with 3 cm
// noise joins; a parallel wall 0.35 m away (the joint plane lies halfway, 0.175 m
// from each), a wall turned by 0.2 rad, and the back of the wall (opposite normal) do
// not; without evidence nothing matches.
TEST(PlaneAssociation, EvidenceCriteriaJoinTheSameSurfaceOnly)
{
  const Wall wall(Eigen::Vector3f(1.0f, 0.0f, 0.0f), -5.0f);
  std::mt19937 rng(3);
  const PlaneMoments registered = faces(wall, 0.0f, 0.0f, 0.03f, rng);
  const PlaneAssociation association(evidenceCriteria());
  const PlaneObservation map_plane{wall.coefficients(), &registered};
  double distance = -1.0;

  // the same surface, the next 2 m along the wall, with noise
  const PlaneMoments same = faces(wall, 1.8f, 0.0f, 0.03f, rng);
  EXPECT_TRUE(association.match(map_plane, {wall.coefficients(), &same}, distance));
  EXPECT_LT(distance, 0.06);

  const Wall parallel(wall.n, wall.d - 0.35f);
  const PlaneMoments behind = faces(parallel, 0.0f, 0.0f, 0.03f, rng);
  EXPECT_FALSE(
    association.match(map_plane, {parallel.coefficients(), &behind}, distance));

  const Wall turned(Eigen::AngleAxisf(0.2f, Eigen::Vector3f::UnitZ()) * wall.n, wall.d);
  const PlaneMoments turned_faces = faces(turned, 0.0f, 0.0f, 0.0f, rng);
  EXPECT_FALSE(
    association.match(map_plane, {turned.coefficients(), &turned_faces}, distance));

  Wall back = wall;
  back.n = -wall.n;
  back.d = -wall.d;
  EXPECT_FALSE(association.match(map_plane, {back.coefficients(), &same}, distance));

  EXPECT_FALSE(association.match(map_plane, {wall.coefficients(), nullptr}, distance));
  const PlaneMoments empty;
  EXPECT_FALSE(association.match(map_plane, {wall.coefficients(), &empty}, distance));
}

// The accumulate stage's criteria: coefficients within 0.1 rad and 0.2 m in either
// orientation (a noisy view joins, flipped or not; a parallel plane 0.3 m away and a
// plane turned by 0.15 rad do not); findBest() takes the nearest offset, the lowest
// index on a tie.
TEST(PlaneAssociation, OffsetCriteriaAndFindBest)
{
  const PlaneAssociation association(offsetCriteria());
  const Eigen::Vector4f wall(1.0f, 0.0f, 0.0f, -5.0f);
  double distance = -1.0;
  // noise: normal turned by 0.05 rad, offset 0.1 m
  const Eigen::Vector3f n =
    Eigen::AngleAxisf(0.05f, Eigen::Vector3f::UnitZ()) * Eigen::Vector3f::UnitX();
  const Eigen::Vector4f noisy(n.x(), n.y(), n.z(), -5.1f);
  EXPECT_TRUE(association.match({wall}, {noisy}, distance));
  EXPECT_NEAR(distance, 0.1, 1e-5);
  EXPECT_TRUE(association.match({wall}, {-noisy}, distance)); // flipped
  EXPECT_NEAR(distance, 0.1, 1e-5);
  EXPECT_FALSE(association.match({wall}, {Eigen::Vector4f(1, 0, 0, -5.3f)}, distance));
  const Eigen::Vector3f turned =
    Eigen::AngleAxisf(0.15f, Eigen::Vector3f::UnitZ()) * Eigen::Vector3f::UnitX();
  EXPECT_FALSE(association.match(
    {wall}, {Eigen::Vector4f(turned.x(), turned.y(), turned.z(), -5.0f)}, distance));

  PlaneAssociationCriteria same = offsetCriteria();
  same.orientation = PlaneOrientation::SAME;
  EXPECT_FALSE(PlaneAssociation(same).match({wall}, {-noisy}, distance));

  const std::vector<Eigen::Vector4f> registered = {
    Eigen::Vector4f(0, 0, 1, 0), Eigen::Vector4f(1, 0, 0, -5.15f),
    Eigen::Vector4f(1, 0, 0, -5.05f), Eigen::Vector4f(1, 0, 0, -4.95f)};
  const auto get = [&registered](std::size_t k) {
    return PlaneObservation{registered[k]};
  };
  // -5.05 and -4.95 are both 0.05 m away: the lower index wins
  EXPECT_EQ(association.findBest(registered.size(), get, {wall}), 2);
  EXPECT_EQ(
    association.findBest(registered.size(), get, {Eigen::Vector4f(1, 0, 0, -5.14f)}),
    1);
  EXPECT_EQ(association.findBest(registered.size(), get, {Eigen::Vector4f(0, 1, 0, 0)}),
            -1);
  EXPECT_EQ(association.findBest(0, get, {wall}), -1);
}

// The inlier-weighted mean: weights 3 and 1, the observation flipped first.
TEST(PlaneAssociation, AverageModelCoefficients)
{
  const Eigen::Vector4f a(1.0f, 0.0f, 0.0f, -5.0f);
  const Eigen::Vector4f b(-1.0f, 0.0f, 0.0f, 5.4f); // the same plane, flipped, 0.4 m
  const Eigen::Vector4f m = planar_grid::averageModelCoefficients(a, 3.0f, b, 1.0f);
  EXPECT_NEAR(m[0], 1.0f, 1e-6f);
  EXPECT_NEAR(m[3], -5.1f, 1e-5f);
  // a turned normal is renormalised
  const Eigen::Vector4f c(0.0f, 1.0f, 0.0f, -5.0f);
  const Eigen::Vector4f e = planar_grid::averageModelCoefficients(a, 1.0f, c, 1.0f);
  EXPECT_NEAR(e.head<3>().norm(), 1.0f, 1e-6f);
  EXPECT_NEAR(e[0], e[1], 1e-6f);
  EXPECT_NEAR(e[3], -5.0f / std::sqrt(0.5f), 1e-4f);
}
