// SPDX-License-Identifier: BSD-3-Clause
// The argument check of the castRay() queries. Private to src/map.
#pragma once

#include <planar_grid/core/exceptions.h>

#include <Eigen/Core>

#include <string>

namespace planar_grid {

/** \brief Throws planar_grid::Exception, naming \a caller, unless \a origin is finite,
 * \a direction finite and non-zero, and \a max_range_m >= 0 (infinity allowed). */
inline void
checkCastRay(const Eigen::Vector3f& origin,
             const Eigen::Vector3f& direction,
             double max_range_m,
             const char* caller)
{
  if (!origin.allFinite())
    throw Exception(std::string(caller) + ": the origin is not finite");
  if (!direction.allFinite() || !(direction.norm() > 0.0f))
    throw Exception(std::string(caller)
                    + ": the direction must be finite and non-zero");
  if (!(max_range_m >= 0.0))
    throw Exception(std::string(caller)
                    + ": max_range_m must be >= 0 (infinity allowed), not "
                    + std::to_string(max_range_m));
}

} // namespace planar_grid
