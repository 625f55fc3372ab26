// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string>

namespace planar_grid {

/** \brief Checks that \a path names an existing regular file (or a link to one) before
 * a reader opens it.
 * \throws planar_grid::IOError naming the file: "no such file", "a folder, not a
 * file" or "not a regular file (a device, pipe or socket)" \ingroup core */
void checkRegularFile(const std::string& path);

/** \brief Checks that \a path names an existing, non-empty regular file before a reader
 * opens it, and returns its size in bytes.
 * \param[in] path the file
 * \param[in] kind what the file should be, for the message ("a PCD file", "an
 * OctoMap file", ...)
 * \throws planar_grid::IOError naming the file: as checkRegularFile(), its
 * size unreadable, or "not <kind>: the file is empty (0 bytes)"
 * \ingroup core */
std::uintmax_t checkInputFile(const std::string& path, const std::string& kind);

} // namespace planar_grid
