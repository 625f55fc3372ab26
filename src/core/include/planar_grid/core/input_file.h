// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <cstdint>
#include <string>

namespace planar_grid {

/** \brief Checks that \a path names an existing regular file (or a link to one) before
 * a reader opens it.
 * \param[in] path the file
 * \param[in] what what the file is, for the messages ("left image"); empty: "file"
 * \throws planar_grid::IOError naming the file: "no such file", "a folder, not a
 * file" or "not a regular file (a device, pipe or socket)" (with \a what: "<what> not
 * found", "the <what> is a folder, not a file", "the <what> is not a regular file
 * ...") \ingroup core */
void checkRegularFile(const std::string& path, const std::string& what = std::string());

/** \brief Checks that \a path names an existing, non-empty regular file before a reader
 * opens it, and returns its size in bytes.
 * \param[in] path the file
 * \param[in] kind what the file should be, for the message ("a PCD file", "an
 * OctoMap file", ...)
 * \throws planar_grid::IOError naming the file: as checkRegularFile(), its
 * size unreadable, or "not <kind>: the file is empty (0 bytes)"
 * \ingroup core */
std::uintmax_t checkInputFile(const std::string& path, const std::string& kind);

/** \brief True when \a text ends with \a suffix (a file name's extension: ".ply").
 * \ingroup core */
inline bool
endsWith(const std::string& text, const std::string& suffix)
{
  return text.size() >= suffix.size()
         && text.compare(text.size() - suffix.size(), suffix.size(), suffix) == 0;
}

} // namespace planar_grid
