// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of the mapping error: the checks of its arguments and the
// sample counts of a cuboid.
#pragma once

#include <planar_grid/core/exceptions.h>

#include <cmath>
#include <cstdint>
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

/** \brief Samples per axis of a cuboid's extent: max(1, ceil(extent / resolution -
 * 1e-3)), the 1e-3 absorbing float extents such as 0.3f = 0.30000001 m that are meant
 * as whole cells; 0 for a non-finite or negative extent; 1000000001 above 1e9. */
inline std::int64_t
samplesAlong(float extent_m, double resolution_m)
{
  if (!std::isfinite(extent_m) || extent_m < 0.0f)
    return 0;
  const double n = std::ceil(static_cast<double>(extent_m) / resolution_m - 1e-3);
  return n < 1.0 ? 1
                 : (n > 1e9 ? std::int64_t{1000000001} : static_cast<std::int64_t>(n));
}

/** \brief The offset from a cuboid's centre along one axis of sample \a i of the \a n
 * that samplesAlong() gives an \a extent_m: the centre of the i-th of n equal
 * sub-intervals, meters. */
inline double
sampleOffset(std::int64_t i, std::int64_t n, double extent_m)
{
  return ((static_cast<double>(i) + 0.5) / static_cast<double>(n) - 0.5) * extent_m;
}

} // namespace detail
} // namespace planar_grid
