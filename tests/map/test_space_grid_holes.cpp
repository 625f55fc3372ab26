// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid::integrateDepthImage() where the depth image has no measurement: a
// pixel without a disparity (a textureless patch, an occlusion) gives no information,
// so no voxel whose whole footprint lies on such pixels may come out free, however
// near or far it is, and the measured surroundings still clear their space.
#include <planar_grid/map/explicit_space_grid.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <limits>
#include <random>
#include <vector>

namespace {

using planar_grid::DepthImage;
using planar_grid::ExplicitSpaceGrid;
using planar_grid::SpaceState;

/** \brief A 240 x 180 view (f = 180 px) of a wall 6 m ahead with an unmeasured
 * rectangle [u0, u1) x [v0, v1) (NaN) and, with \a scatter, 20 % of the other pixels
 * unmeasured at random. */
DepthImage
renderWallWithHole(int u0, int v0, int u1, int v1, bool scatter)
{
  DepthImage image;
  image.width = 240;
  image.height = 180;
  image.fx = image.fy = 180.0f;
  image.cx = 119.5f;
  image.cy = 89.5f;
  image.depth_m.assign(static_cast<std::size_t>(image.width * image.height), 6.0f);
  std::mt19937 rng(5u);
  std::uniform_real_distribution<float> unit(0.0f, 1.0f);
  for (int v = 0; v < image.height; ++v)
    for (int u = 0; u < image.width; ++u) {
      const bool in_hole = u >= u0 && u < u1 && v >= v0 && v < v1;
      if (in_hole || (scatter && unit(rng) < 0.2f))
        image.depth_m[static_cast<std::size_t>(v * image.width + u)] =
          std::numeric_limits<float>::quiet_NaN();
    }
  return image;
}

/** \brief A general camera pose, so that voxels and pixels do not line up. */
Eigen::Isometry3d
cameraPose()
{
  Eigen::Isometry3d T = Eigen::Isometry3d::Identity();
  T.linear() = Eigen::AngleAxisd(0.4, Eigen::Vector3d(0.3, 1.0, -0.2).normalized())
                 .toRotationMatrix();
  T.translation() = Eigen::Vector3d(-0.7, 0.25, 1.9);
  return T;
}

/** \brief What the oracle finds for the free voxels of a grid. */
struct FreeCheck {
  std::size_t free{0};            // free voxels in the grid
  std::size_t without_measure{0}; // ... with no measured pixel near their footprint
  std::size_t behind_surface{0};  // ... behind every measured depth near it
};

/** \brief Every free voxel's centre projected into \a image: the pixels within 3 r + 2
 * of it (r = the footprint radius f res sqrt(3) / 2 / z at its cube's nearest depth,
 * and the min-depth cells that bound the footprint reach at most 2 r + 1 further) must
 * hold a measurement, and the voxel must lie in front of the nearest one. Voxels within
 * a cube diagonal of the camera plane are not checked. */
FreeCheck
checkFreeVoxels(const ExplicitSpaceGrid& grid,
                const DepthImage& image,
                const Eigen::Isometry3d& world_T_camera,
                double resolution_m)
{
  FreeCheck check;
  const Eigen::Isometry3f camera_T_world = world_T_camera.inverse().cast<float>();
  grid.forEachVoxelIn(SpaceState::FREE, [&](const ExplicitSpaceGrid::VoxelKey& key) {
    ++check.free;
    const Eigen::Vector3f pc = camera_T_world * grid.toCentre(key);
    const double z = pc.z();
    const double u = image.fx * pc.x() / z + image.cx,
                 v = image.fy * pc.y() / z + image.cy;
    // The voxel's 4^3 cube reads its footprints at the radius of its nearest corner,
    // up to a cube diagonal nearer; a cube across the camera plane reads the whole
    // image.
    const double z_cube = z - 4.0 * resolution_m * std::sqrt(3.0);
    if (z_cube < 0.05)
      return;
    const int r = static_cast<int>(
      std::ceil(image.fx * resolution_m * std::sqrt(3.0) / 2.0 / z_cube));
    const int reach = 3 * r + 2;
    const int cu = static_cast<int>(std::floor(u + 0.5)),
              cv = static_cast<int>(std::floor(v + 0.5));
    double nearest = std::numeric_limits<double>::infinity();
    for (int wv = std::max(cv - reach, 0); wv <= std::min(cv + reach, image.height - 1);
         ++wv)
      for (int wu = std::max(cu - reach, 0);
           wu <= std::min(cu + reach, image.width - 1); ++wu) {
        const float d = image.at(wu, wv);
        if (std::isfinite(d) && d > 0.0f)
          nearest = std::min(nearest, static_cast<double>(d));
      }
    if (!std::isfinite(nearest))
      ++check.without_measure;
    else if (z >= nearest)
      ++check.behind_surface;
  });
  return check;
}

} // namespace

TEST(ExplicitSpaceGridHoles, NoVoxelIsFreeWhereNothingWasMeasured)
{
  // A 100 x 80 px hole: at 6 m a 0.8 m block spans 24 px, so blocks straddle its edge
  // and the cubes and voxels inside them are decided one by one.
  const DepthImage image = renderWallWithHole(70, 50, 170, 130, false);
  const Eigen::Isometry3d T = cameraPose();
  for (const double resolution_m : {0.1, 0.05}) {
    ExplicitSpaceGrid::Params params;
    params.resolution_m = resolution_m;
    params.max_range_m = 20.0;
    ExplicitSpaceGrid grid(params);
    grid.integrateDepthImage(image, T);
    const FreeCheck check = checkFreeVoxels(grid, image, T, resolution_m);
    EXPECT_GT(check.free, resolution_m < 0.1 ? 400000u : 50000u);
    EXPECT_EQ(check.without_measure, 0u) << "resolution " << resolution_m;
    EXPECT_EQ(check.behind_surface, 0u) << "resolution " << resolution_m;
    // Inside the hole's cone, away from its edges, nothing is observed: neither in
    // front of the wall's depth nor behind it.
    const auto state = [&](double xn, double yn, double z) {
      return grid.getState(
        (T * Eigen::Vector3d(xn * z, yn * z, z)).cast<float>().eval());
    };
    for (const double z : {1.5, 3.0, 5.0, 8.0, 12.0, 18.0})
      EXPECT_EQ(state(0.0, 0.0, z), SpaceState::UNKNOWN) << "z " << z;
    // Beside the hole the wall clears its space and holds its surface.
    const double xn_side = (20.0 - image.cx) / image.fx;
    EXPECT_EQ(state(xn_side, 0.0, 3.0), SpaceState::FREE);
    EXPECT_EQ(state(xn_side, 0.0, 6.0 + 0.3 * resolution_m), SpaceState::OCCUPIED);
    EXPECT_EQ(state(xn_side, 0.0, 8.0), SpaceState::UNKNOWN);
  }
}

TEST(ExplicitSpaceGridHoles, ScatteredHolesStillClearSpaceAndTheHoleStaysUnknown)
{
  // One pixel in five missing everywhere: every voxel footprint still holds
  // measurements outside the hole (free in front of the wall), none inside it.
  const DepthImage image = renderWallWithHole(70, 50, 170, 130, true);
  const Eigen::Isometry3d T = cameraPose();
  for (const auto prior : {SpaceState::UNKNOWN, SpaceState::FREE}) {
    ExplicitSpaceGrid::Params params;
    params.resolution_m = 0.1;
    params.max_range_m = 20.0;
    params.prior = prior;
    ExplicitSpaceGrid grid(params);
    grid.integrateDepthImage(image, T);
    const FreeCheck check = checkFreeVoxels(grid, image, T, 0.1);
    EXPECT_GT(check.free, 50000u);
    EXPECT_EQ(check.without_measure, 0u);
    EXPECT_EQ(check.behind_surface, 0u);
    const Eigen::Vector3f centre =
      (T * Eigen::Vector3d(0.0, 0.0, 8.0)).cast<float>().eval();
    EXPECT_EQ(grid.getState(centre), prior);
  }
}
