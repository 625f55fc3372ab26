// SPDX-License-Identifier: BSD-3-Clause
// The tile index's first line and version, shared by its writer and its reader.
#pragma once

namespace planar_grid {
namespace map_tiles_detail {

/** \brief The first line of a tile index. */
constexpr const char* INDEX_MAGIC = "# Planar grid map tiles";
/** \brief The index format's version. */
constexpr int INDEX_VERSION = 1;

} // namespace map_tiles_detail
} // namespace planar_grid
