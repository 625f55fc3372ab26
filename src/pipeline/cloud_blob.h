// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <planar_grid/pipeline/frame.h>

#include <pcl/PCLPointCloud2.h>

namespace planar_grid {

/** \brief Converts a PCL blob (a PCD file's or a PointCloud2 message's) to the working
 * cloud type with the fields it has, so that PCL does not warn once per missing field:
 * an intensity field is kept, colour becomes the grey intensity
 * (pcl::PointXYZRGBtoXYZI), bare x/y/z get intensity 0. The blob's x/y/z are checked by
 * the caller. An empty blob gives an empty cloud. */
void intensityCloudFromBlob(const pcl::PCLPointCloud2& blob, Frame::Cloud& cloud);

} // namespace planar_grid
