// SPDX-License-Identifier: BSD-3-Clause
#ifndef PCL_NO_PRECOMPILE
#include <planar_grid/segmentation/impl/sac_multi_plane_segmentation.hpp>

#include <pcl/impl/instantiate.hpp>
#include <pcl/point_types.h>

// S6: the point types of PLANAR_GRID_POINT_TYPES (top-level CMakeLists.txt).
template class planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ>;
template class planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZI>;
template class planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZRGB>;
#endif // PCL_NO_PRECOMPILE
