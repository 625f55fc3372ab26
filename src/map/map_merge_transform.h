// SPDX-License-Identifier: BSD-3-Clause
// The transform of a map merge (this_T_other): its checks, shared by the layers'
// merge() (private to the map module).
#pragma once

#include <planar_grid/core/exceptions.h>

#include <Eigen/Geometry>

#include <iomanip>
#include <sstream>
#include <string>

namespace planar_grid {
namespace map_merge {

/** \brief Throws planar_grid::Exception, naming \a who, unless \a t is finite with
 * a rotation part (orthonormal within 1e-6, determinant +1) and a last row 0 0 0 1. */
inline void
checkRigid(const Eigen::Isometry3d& t, const std::string& who)
{
  const Eigen::Matrix3d rotation = t.linear();
  const bool rigid = t.matrix().allFinite()
                     && (rotation.transpose() * rotation - Eigen::Matrix3d::Identity())
                            .cwiseAbs()
                            .maxCoeff()
                          <= 1e-6
                     && rotation.determinant() > 0.0
                     && t.matrix().row(3) == Eigen::RowVector4d(0.0, 0.0, 0.0, 1.0);
  if (!rigid)
    throw Exception(who + ": this_T_other must be a finite rigid transform (rotation "
                    + "and translation in meters)");
}

/** \brief True when \a t is exactly the identity (nothing to resample). */
inline bool
isIdentity(const Eigen::Isometry3d& t)
{
  return t.matrix() == Eigen::Matrix4d::Identity();
}

/** \brief "<name> differ (<a> and <b> <unit>)" when \a a != \a b, else "". */
template <typename T>
std::string
difference(const char* name, const T& a, const T& b, const char* unit)
{
  if (a == b)
    return "";
  std::ostringstream text;
  text << std::setprecision(10) << name << " differ (" << a << " and " << b
       << (unit[0] != '\0' ? " " : "") << unit << ")";
  return text.str();
}

} // namespace map_merge
} // namespace planar_grid
