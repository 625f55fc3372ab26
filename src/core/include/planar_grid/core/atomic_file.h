// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <functional>
#include <string>

namespace planar_grid {

/** \brief Writes \a path so that it is never seen half-written: \a write is called
 * with a temporary path in the same folder, and the file is renamed over \a path only
 * when the write succeeded. A write fails when \a write returns false or creates no
 * file, and also when it returns true but a write(2) inside it failed with a full disk
 * (ENOSPC, EDQUOT), an I/O error or the file size limit (EFBIG, or a file as long as
 * RLIMIT_FSIZE): several library writers (PCL's PLY, OctoMap) do not check their
 * streams. On failure the temporary file is removed, an existing \a path is left as it
 * was, and planar_grid::IOError names the file and the cause ("No space left on device
 * (the disk of <folder> is full)", "File too large (over the process's file size
 * limit ...)", "Permission denied", ...).
 * \param[in] path the final file
 * \param[in] write writes the whole content to the path it is given; returns success
 * \throws planar_grid::IOError as above, also for a std::runtime_error thrown by \a
 * write (a library's writer; its message is kept); any other exception of \a write is
 * passed on after the temporary file is removed
 * \ingroup core */
void writeFileAtomically(const std::string& path,
                         const std::function<bool(const std::string&)>& write);

/** \brief writeFileAtomically() for text content. */
void writeTextFileAtomically(const std::string& path, const std::string& content);

/** \brief The cause of a failed write, for an error message: strerror(\a error_number)
 * with the likely reason (a full disk, the file size limit); when \a error_number is
 * 0 (the writer gave no errno), what the file system of \a folder and the process's
 * limits suggest.
 * \param[in] error_number the errno of the failed call, or 0
 * \param[in] folder the folder written into
 * \ingroup core */
std::string describeWriteError(int error_number, const std::string& folder);

} // namespace planar_grid
