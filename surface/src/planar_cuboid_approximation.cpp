// SPDX-License-Identifier: BSD-3-Clause
#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/point_types.h>
#include <planar_grid/surface/impl/planar_cuboid_approximation.hpp>

#include <pcl/point_types.h>

// One explicit instantiation per point type of the CMake list PLANAR_GRID_POINT_TYPES.
PLANAR_GRID_INSTANTIATE(PlanarCuboidApproximation, PLANAR_GRID_POINT_TYPES)
#endif // PCL_NO_PRECOMPILE
