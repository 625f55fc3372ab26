// SPDX-License-Identifier: BSD-3-Clause
// Keeps the occupied features of a sparse feature cloud with
// planar_grid::KLDivergenceOccupancyFilter, a pcl::FilterIndices (paper eqs. 4-10):
// each filter() call on a new input is one frame; a track seen again is updated by the
// Kullback-Leibler rule.
//   filter_features cloud.pcd      (an organized camera-frame scan, e.g.
//                                   ../shared/data/pcl_clouds/office1.pcd)
#include <planar_grid/filters/kl_divergence_occupancy_filter.h>

#include <pcl/common/point_tests.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cstdint>
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
  pcl::PointCloud<pcl::PointXYZ> scan;
  if (pcl::io::loadPCDFile(argv[1], scan) < 0)
    return EXIT_FAILURE;

  // A sparse feature cloud, as stereo key points are: every 400th finite point of the
  // scan, its track id being its index in the scan.
  pcl::PointCloud<pcl::PointXYZ>::Ptr features(new pcl::PointCloud<pcl::PointXYZ>);
  std::vector<std::int64_t> track_ids;
  for (std::size_t i = 0; i < scan.size(); i += 400) {
    if (pcl::isFinite(scan[i])) {
      features->push_back(scan[i]);
      track_ids.push_back(static_cast<std::int64_t>(i));
    }
  }

  planar_grid::KLDivergenceOccupancyFilter<pcl::PointXYZ> occupancy;
  occupancy.setStereoParameters(525.0,
                                0.075);     // Kinect: f in pixels, baseline in meters
  for (int frame = 0; frame < 2; ++frame) { // the static scene observed twice
    occupancy.setInputCloud(features);
    occupancy.setTrackIds(track_ids);
    pcl::Indices occupied;
    occupancy.filter(occupied);
    std::cout << "frame " << frame << ": " << occupied.size() << " of "
              << features->size() << " features occupied, " << occupancy.getTrackCount()
              << " tracks\n";
  }
  return features->empty() ? EXIT_FAILURE : EXIT_SUCCESS;
}
