// SPDX-License-Identifier: BSD-3-Clause
// Shared by the sources of the map comparison: which stages run once per frame.
#pragma once

#include <planar_grid/pipeline/stage.h>

#include <string>

namespace planar_grid {
namespace detail {

/** Whether the stage registry declares \a type a front-end stage, which does not
 * depend on the cell size and so runs once per frame for all sizes. */
inline bool
isFrontEnd(const std::string& type)
{
  const StageInfo* info = findStage(type);
  return info && info->role == StageRole::FRONT_END;
}

} // namespace detail
} // namespace planar_grid
