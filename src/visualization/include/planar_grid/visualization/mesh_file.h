// SPDX-License-Identifier: BSD-3-Clause
#pragma once

#include <pcl/PolygonMesh.h>

#include <string>

namespace planar_grid {

/** \brief Checks that \a path is a PLY file that PCL's reader can take safely, before
 * pcl::io::loadPLYFile() sees it: a non-empty regular file whose first line is "ply",
 * with a "format ascii 1.0", "format binary_little_endian 1.0" or
 * "format binary_big_endian 1.0" line, "element <name> <count>" and
 * "property <type> <name>" / "property list <count type> <type> <name>" lines of known
 * types, an "end_header" line within the first 64 KiB, a "vertex" element with x, y and
 * z properties, and at least the data bytes the header declares (binary: count x the
 * element's fixed bytes, lists counted with no entries; ASCII: two bytes per value), so
 * that a header announcing billions of vertices is refused before anything is
 * allocated.
 * \param[in] path the file
 * \throws planar_grid::IOError naming the file and the cause ("the file is empty (0
 * bytes)", "not a PLY file: ...", "truncated: ...")
 * \ingroup visualization */
void checkPLYFile(const std::string& path);

/** \brief Reads a PLY mesh (checkPLYFile(), then pcl::io::loadPLYFile()) and checks
 * that every polygon has at least three vertices, each an index into the vertices.
 * A PLY file without faces gives a mesh without polygons (its vertices only).
 * \param[in] path the file
 * \return the mesh: vertices in mesh.cloud (x, y, z and any other properties),
 * polygons as vertex indices
 * \throws planar_grid::IOError naming the file and the cause
 * \ingroup visualization */
pcl::PolygonMesh loadPLYMesh(const std::string& path);

} // namespace planar_grid
