// SPDX-License-Identifier: BSD-3-Clause
// The surface layer's mesh export (PLY, VTK).
#include <planar_grid/core/atomic_file.h>
#include <planar_grid/core/exceptions.h>
#include <planar_grid/map/surface_layer.h>

#include <pcl/PolygonMesh.h>
#include <pcl/conversions.h>
#include <pcl/io/ply_io.h>
#include <pcl/io/vtk_io.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <string>

namespace planar_grid {

void
SurfaceLayer::exportMesh(const std::string& path) const
{
  const auto dot = path.find_last_of('.');
  std::string ext = dot == std::string::npos ? "" : path.substr(dot);
  std::transform(ext.begin(), ext.end(), ext.begin(),
                 [](unsigned char ch) { return static_cast<char>(std::tolower(ch)); });
  if (ext != ".ply" && ext != ".vtk")
    throw IOError(path + ": unknown mesh extension (expected .ply or .vtk)");
  const PlanarCuboids& cuboids = getCuboids();
  pcl::PointCloud<pcl::PointXYZRGB> vertices;
  vertices.reserve(cuboids.size() * 8);
  pcl::PolygonMesh mesh;
  mesh.polygons.reserve(cuboids.size() * 12);
  // corners(): face 0-3 (front), back 4-7; outward-facing triangles
  static const int TRIANGLES[12][3] = {{0, 1, 2}, {0, 2, 3}, {4, 6, 5}, {4, 7, 6},
                                       {0, 4, 5}, {0, 5, 1}, {1, 5, 6}, {1, 6, 2},
                                       {2, 6, 7}, {2, 7, 3}, {3, 7, 4}, {3, 4, 0}};
  for (const PlanarCuboid& c : cuboids) {
    const auto base = static_cast<pcl::index_t>(vertices.size());
    const float p = std::max(0.0f, std::min(1.0f, c.probability));
    const auto red = static_cast<std::uint8_t>(std::lround(255.0f * p));
    const auto blue = static_cast<std::uint8_t>(255 - red);
    for (const auto& corner : c.corners()) {
      pcl::PointXYZRGB v;
      v.getVector3fMap() = corner;
      v.r = red;
      v.g = c.is_planar ? 96 : 160;
      v.b = blue;
      vertices.push_back(v);
    }
    for (const auto& t : TRIANGLES) {
      pcl::Vertices poly;
      poly.vertices = {base + t[0], base + t[1], base + t[2]};
      mesh.polygons.push_back(std::move(poly));
    }
  }
  pcl::toPCLPointCloud2(vertices, mesh.cloud);
  const bool ply = ext == ".ply";
  writeFileAtomically(path, [&mesh, ply](const std::string& tmp) {
    return (ply ? pcl::io::savePLYFileBinary(tmp, mesh)
                : pcl::io::saveVTKFile(tmp, mesh))
           == 0;
  });
}

} // namespace planar_grid
