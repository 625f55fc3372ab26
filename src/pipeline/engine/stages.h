// SPDX-License-Identifier: BSD-3-Clause
// Internal: the factories of the built-in stages, one file per concern.
#pragma once

#include <planar_grid/pipeline/stage.h>

#include <cstdint>
#include <string>
#include <vector>

namespace planar_grid {

enum class FeatureType;

namespace stages {

// stereo_stages.cpp
StageInfo stereoDisparityInfo();
StageInfo featureMatchingInfo();

// cloud_feature_stages.cpp
StageInfo cloudFeaturesInfo();

// odometry_stages.cpp
StageInfo visualOdometryInfo();

// filter_stages.cpp
StageInfo depthErrorFilterInfo();
StageInfo voxelGridInfo();
StageInfo statisticalOutlierRemovalInfo();

// segmentation_stages.cpp
StageInfo multiPlaneSegmentationInfo();
StageInfo groundRemovalInfo();

// surface_stages.cpp
StageInfo planarCuboidApproximationInfo();

// range_adaptive_stages.cpp
StageInfo rangeAdaptiveCellsInfo();

// occupancy_stages.cpp
StageInfo klOccupancyFilterInfo();

// map_stages.cpp
StageInfo mapIntegrationInfo();

// world_stages.cpp
StageInfo transformToWorldInfo();
StageInfo accumulateInfo();

/** Valid (finite) points of a cloud. */
std::size_t countValidPoints(const pcl::PointCloud<pcl::PointXYZI>& cloud);

/** The up axis of the frame's cloud: world +z, or -y of the camera frame. */
Eigen::Vector3f upAxis(const Frame& frame);

/** The sensor origin in the frame of the cloud (metres). */
Eigen::Vector3f sensorOrigin(const Frame& frame);

/** The transform from the frame of the cloud to the camera frame: identity before
 * transform_to_world, the inverse of the frame's pose after it. */
Eigen::Affine3f cameraTCloud(const Frame& frame);

/** Removes the points of the frame's cloud where \a remove is non-zero (one entry per
 * point): an organized cloud keeps its image structure (the points become NaN, indices
 * stay valid); any other cloud is compacted and the planes' inliers are renumbered
 * (removed inliers are dropped). Returns the number of points removed. */
std::size_t removePoints(Frame& frame, const std::vector<std::uint8_t>& remove);

/** True when the frame's cloud has a valid point. Otherwise the frame has nothing left
 * for the point stages (all-dark images, every point filtered out): the first stage of
 * the frame that finds this warns, naming the frame and itself, and records it in
 * Frame::no_points_stage; the stage then passes the empty frame on, which adds nothing
 * to the map. */
bool hasPoints(Frame& frame, const char* stage_type);

} // namespace stages
} // namespace planar_grid
