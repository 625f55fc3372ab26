// SPDX-License-Identifier: BSD-3-Clause
// Segments the planes of a PCD scan with planar_grid::SACMultiPlaneSegmentation, used
// the way pcl::SACSegmentation is.
//   segment_planes cloud.pcd      (e.g. ../shared/data/pcl_clouds/office1.pcd)
#include <planar_grid/segmentation/sac_multi_plane_segmentation.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cstdlib>
#include <iostream>
#include <vector>

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

  planar_grid::SACMultiPlaneSegmentation<pcl::PointXYZ> seg;
  seg.setInputCloud(cloud);
  seg.setDistanceThreshold(0.02);           // meters
  seg.setUpAxis(Eigen::Vector3f(0, -1, 0)); // camera frame: y points down
  std::vector<pcl::ModelCoefficients> model_coefficients;
  std::vector<pcl::PointIndices> inliers;
  seg.segment(model_coefficients, inliers);

  for (std::size_t i = 0; i < model_coefficients.size(); ++i) {
    const auto& c = model_coefficients[i].values;
    std::cout << "plane " << i << ": " << inliers[i].indices.size()
              << " inliers, [a b c d] = [" << c[0] << ' ' << c[1] << ' ' << c[2] << ' '
              << c[3] << "]\n";
  }
  return model_coefficients.empty() ? EXIT_FAILURE : EXIT_SUCCESS;
}
