// SPDX-License-Identifier: BSD-3-Clause
// PlanarGrid's fast filters for a point type of the user's own, as PCL users do with
// PCL's filters: PCL_NO_PRECOMPILE before the first include makes the headers bring the
// template bodies (impl/*.hpp), so any registered point type can be filtered.
// planar_grid::FastVoxelGrid gives pcl::VoxelGrid's output and
// planar_grid::FastStatisticalOutlierRemoval pcl::StatisticalOutlierRemoval's, faster.
//   custom_point_filters cloud.pcd   (e.g. ../shared/data/pcl_clouds/office1.pcd)
#define PCL_NO_PRECOMPILE
#include <planar_grid/filters/fast_statistical_outlier_removal.h>
#include <planar_grid/filters/fast_voxel_grid.h>

#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>
#include <pcl/register_point_struct.h>

#include <cstdlib>
#include <iostream>

namespace example {
/** A scanner's point: x, y, z (meters) and a return confidence in [0, 1]. */
struct EIGEN_ALIGN16 PointXYZConfidence {
  PCL_ADD_POINT4D;
  float confidence;
  PCL_MAKE_ALIGNED_OPERATOR_NEW
};
} // namespace example

// clang-format off
POINT_CLOUD_REGISTER_POINT_STRUCT(example::PointXYZConfidence,
                                  (float, x, x)(float, y, y)(float, z, z)
                                  (float, confidence, confidence))
// clang-format on

int
main(int argc, char** argv)
{
  if (argc != 2) {
    std::cerr << "usage: " << argv[0] << " cloud.pcd\n";
    return EXIT_FAILURE;
  }
  pcl::PointCloud<pcl::PointXYZ> scan;
  if (pcl::io::loadPCDFile(argv[1], scan) < 0)
    return EXIT_FAILURE;

  using Point = example::PointXYZConfidence;
  pcl::PointCloud<Point>::Ptr cloud(new pcl::PointCloud<Point>);
  for (const auto& p : scan) {
    Point q;
    q.x = p.x;
    q.y = p.y;
    q.z = p.z;
    q.confidence = 1.0f;
    cloud->push_back(q);
  }
  cloud->is_dense = false; // the scan's invalid returns are NaN

  // 5 cm voxels (centroids, the confidence averaged too), then the points whose mean
  // distance to their 20 nearest neighbours is more than 2 standard deviations above
  // the mean removed.
  pcl::PointCloud<Point>::Ptr voxels(new pcl::PointCloud<Point>);
  planar_grid::FastVoxelGrid<Point> grid;
  grid.setInputCloud(cloud);
  grid.setLeafSize(0.05f, 0.05f, 0.05f);
  grid.filter(*voxels);

  pcl::PointCloud<Point> kept;
  planar_grid::FastStatisticalOutlierRemoval<Point> outliers;
  outliers.setInputCloud(voxels);
  outliers.setMeanK(20);
  outliers.setStddevMulThresh(2.0);
  outliers.filter(kept);

  std::cout << scan.size() << " points, " << voxels->size() << " voxels of 5 cm, "
            << kept.size() << " kept after the outlier removal\n";
  return kept.empty() ? EXIT_FAILURE : EXIT_SUCCESS;
}
