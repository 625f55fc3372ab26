// SPDX-License-Identifier: BSD-3-Clause
// Segments the planes of a PCD scan, then approximates the scan by plane-aligned
// cuboids with planar_grid::PlanarCuboidApproximation (paper Sec. III-F, Figs. 6-8).
//   approximate_cuboids cloud.pcd      (e.g. ../shared/data/pcl_clouds/office1.pcd)
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>
#include <planar_grid/surface/planar_cuboid_approximation.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cstdlib>
#include <iostream>

int
main(int argc, char** argv)
{
  if (argc != 2) {
    std::cerr << "usage: " << argv[0] << " cloud.pcd\n";
    return EXIT_FAILURE;
  }
  pcl::PointCloud<pcl::PointXYZ>::Ptr cloud(new pcl::PointCloud<pcl::PointXYZ>);
  if (pcl::io::loadPCDFile(argv[1], *cloud) < 0)
    return EXIT_FAILURE;
  const Eigen::Vector3f up(0, -1, 0); // camera frame: y points down

  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ> seg;
  seg.setInputCloud(cloud);
  seg.setDistanceThreshold(0.02); // meters
  seg.setUpAxis(up);
  planar_grid::PlanarSegments planes;
  seg.segment(planes);

  planar_grid::PlanarCuboidApproximation<pcl::PointXYZ> approximation;
  approximation.setInputCloud(cloud);
  approximation.setPlanes(planes);
  approximation.setUpAxis(up);
  approximation.setMinCellSize(0.05); // meters
  planar_grid::PlanarCuboids cuboids;
  approximation.approximate(cuboids);

  std::size_t planar = 0;
  double planar_area_m2 = 0.0;
  for (const auto& cuboid : cuboids) {
    if (cuboid.is_planar) {
      ++planar;
      planar_area_m2 += cuboid.faceArea();
    }
  }
  std::cout << planes.size() << " planes, " << cuboids.size() << " cuboids: " << planar
            << " planar (face area " << planar_area_m2 << " m^2), "
            << cuboids.size() - planar << " non-planar\n";
  return planar == 0 ? EXIT_FAILURE : EXIT_SUCCESS;
}
