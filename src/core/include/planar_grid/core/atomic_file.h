// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <functional>
#include <string>

namespace planar_grid {

/** \brief Writes \a path so that it is never seen half-written: \a write is called
 * with a temporary path in the same folder, and the file is renamed over \a path only
 * when \a write returns true. On failure the temporary file is removed, an existing
 * \a path is left as it was, and planar_grid::IOError names the file.
 * \param[in] path the final file
 * \param[in] write writes the whole content to the path it is given; returns success
 * \ingroup core */
void writeFileAtomically(const std::string& path,
                         const std::function<bool(const std::string&)>& write);

/** \brief writeFileAtomically() for text content. */
void writeTextFileAtomically(const std::string& path, const std::string& content);

} // namespace planar_grid
