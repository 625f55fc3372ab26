// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <string>

namespace planar_grid {

/** \brief Checks that \a path is a PCD file PCL can read safely, before it is handed to
 * pcl::io::loadPCDFile(): PCL's reader accepts a header without any PCD keyword (an
 * empty file, a text file, another format) and then reads past the end of the file,
 * and it trusts the compressed sizes. The file must be a non-empty regular file whose
 * first line that is not a comment is a PCD keyword (VERSION or FIELDS), whose header
 * pcl::PCDReader::readHeader() reads, with at least one field of a known type, and
 * whose data hold what the header declares: width * height points of the fields' bytes
 * for binary data; for binary-compressed data the two sizes after the header, the
 * compressed bytes within the file and the uncompressed size equal to the points'
 * bytes.
 * \param[in] path the file
 * \throws planar_grid::IOError naming the file and the cause ("the file is empty (0
 * bytes)", "not a PCD file: ...", "is a planar grid map (.pgmap) file", "truncated:
 * ...", "the compressed data ...")
 * \ingroup visualization */
void checkPCDFile(const std::string& path);

} // namespace planar_grid
