// SPDX-License-Identifier: BSD-3-Clause
#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/surface/impl/planar_cuboid_approximation.hpp>

#include <pcl/impl/instantiate.hpp>
#include <pcl/point_types.h>

// S6: the point types of PLANAR_GRID_POINT_TYPES (top-level CMakeLists.txt).
template class planar_grid::PlanarCuboidApproximation<pcl::PointXYZ>;
template class planar_grid::PlanarCuboidApproximation<pcl::PointXYZI>;
template class planar_grid::PlanarCuboidApproximation<pcl::PointXYZRGB>;
#endif // PCL_NO_PRECOMPILE
