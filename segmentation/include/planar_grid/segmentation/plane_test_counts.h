// SPDX-License-Identifier: BSD-3-Clause
// What the plane tests of one SACMultiPlaneSegmentation::segment() call took out.
#pragma once

#include <cstddef>

namespace planar_grid {

/** \brief The counts of one SACMultiPlaneSegmentation::segment() call's plane tests:
 * for each test, the planes it dropped and the inliers it took out (of the planes it
 * kept or dropped). A default-constructed value is all zeros.
 * \ingroup segmentation */
struct PlaneTestCounts {
  /** \brief Planes dropped in the cluster test. */
  std::size_t cluster_rejected{0};
  /** \brief Inliers the cluster test took out. */
  std::size_t cluster_removed{0};
  /** \brief Planes dropped in the sensor plane test. */
  std::size_t sensor_plane_rejected{0};
  /** \brief Inliers the sensor plane test took out. */
  std::size_t sensor_plane_removed{0};
  /** \brief Planes dropped in the shell test. */
  std::size_t shell_rejected{0};
  /** \brief Inliers the shell test took out. */
  std::size_t shell_removed{0};
  /** \brief Planes dropped in the visibility test. */
  std::size_t visibility_rejected{0};
  /** \brief Inliers the visibility test took out. */
  std::size_t visibility_removed{0};
  /** \brief Hypotheses dropped because their support scattered in normal. */
  std::size_t normal_rejected{0};
  /** \brief Distance inliers of kept planes that the normal test took out. */
  std::size_t normal_removed{0};
};

} // namespace planar_grid
