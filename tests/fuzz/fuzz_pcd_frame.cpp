// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: a PCD frame as the pipeline, the viewer and the pose reader take
// it: planar_grid::checkPCDFile() on arbitrary bytes and, for a file it passes, PCL's
// reader and the conversion to points. The contract (pcd_file_check.h): the check
// throws a planar_grid::Exception (IOError) naming the file, or PCL reads the file
// without a crash, a sanitizer report or an allocation beyond the file's size; anything
// else is a finding (of the check: it lets through a file PCL mishandles).

#include <planar_grid/core/exceptions.h>
#include <planar_grid/core/pcd_file_check.h>

#include <pcl/PCLPointCloud2.h>
#include <pcl/console/print.h>
#include <pcl/conversions.h>
#include <pcl/io/pcd_io.h>
#include <pcl/point_types.h>

#include <cstddef>
#include <cstdint>

#include "fuzz_input_file.h"

// PCL's reader reports every malformed header line on the console: silenced, so that
// the fuzzer's time goes to the inputs.
extern "C" int
LLVMFuzzerInitialize(int* /*argc*/, char*** /*argv*/)
{
  pcl::console::setVerbosityLevel(pcl::console::L_ALWAYS);
  return 0;
}

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  static const planar_grid::fuzz::FuzzInputFile file("frame.pcd");
  const std::string& path = file.write(data, size);
  try {
    const planar_grid::PCDFileInfo info = planar_grid::checkPCDFile(path);
    pcl::PCLPointCloud2 blob;
    if (pcl::io::loadPCDFile(path, blob) == 0 && info.points > 0) {
      planar_grid::checkPointCloudBlob(blob, path);
      pcl::PointCloud<pcl::PointXYZ> cloud;
      pcl::fromPCLPointCloud2(blob, cloud);
    }
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
