// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of the mapping error: the checks of its arguments.
#pragma once

#include <planar_grid/core/exceptions.h>

#include <cmath>
#include <string>

namespace planar_grid {
namespace detail {

/** \brief Throws unless \a tolerance_m >= 0 (meters). */
inline void
checkTolerance(double tolerance_m)
{
  if (!(tolerance_m >= 0.0))
    throw Exception("mapping error: tolerance_m must be >= 0 meters, got "
                    + std::to_string(tolerance_m));
}

/** \brief Throws unless \a resolution_m is finite and > 0 (meters). */
inline void
checkResolution(double resolution_m)
{
  if (!(resolution_m > 0.0) || !std::isfinite(resolution_m))
    throw Exception("mapping error: resolution_m must be > 0 meters, got "
                    + std::to_string(resolution_m));
}

} // namespace detail
} // namespace planar_grid
