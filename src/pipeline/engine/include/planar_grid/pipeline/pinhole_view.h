// SPDX-License-Identifier: BSD-3-Clause
#pragma once

namespace planar_grid {

/** \brief A pinhole camera: image size and intrinsics (camera frame x right, y down, z
 * forward). \ingroup pipeline */
struct PinholeView {
  /** \brief Image width, pixels (> 0). */
  int width_px{0};
  /** \brief Image height, pixels (> 0). */
  int height_px{0};
  /** \brief Horizontal focal length, pixels (> 0). */
  double fx_px{0.0};
  /** \brief Vertical focal length, pixels (> 0). */
  double fy_px{0.0};
  /** \brief Principal point column, pixels. */
  double cx_px{0.0};
  /** \brief Principal point row, pixels. */
  double cy_px{0.0};
};

} // namespace planar_grid
