// SPDX-License-Identifier: BSD-3-Clause
// ExplicitSpaceGrid's private part: the storage of the map and the working memory of
// integration, side by side so that a view's scratch is never mistaken for the map's
// content. Private to src/map.
#pragma once

#include <planar_grid/map/explicit_space_grid.h>

#include "explicit_space_grid_integration.h"
#include "explicit_space_grid_storage.h"

namespace planar_grid {

struct ExplicitSpaceGrid::Impl {
  /** \brief The map's content: super-blocks, their directory and the edit buffer. */
  explicit_space::BlockStorage storage;
  /** \brief Scratch of integrateDepthImage(), kept between views. */
  explicit_space::IntegrationWorkspace workspace;
};

} // namespace planar_grid
