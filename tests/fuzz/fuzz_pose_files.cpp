// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: the pose readers on arbitrary bytes. The first byte picks the
// reader (loadKittiPoses, loadKarlsruheInsData, loadEurocBodyPoses, loadPCDViewpoint,
// by its value mod 4); the rest is written to a temporary file. The contract
// (trajectory_io.h): poses, or a planar_grid::Exception (IOError) naming the file;
// anything else is a finding.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/odometry/trajectory_io.h>

#include <pcl/console/print.h>

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
  if (size == 0)
    return 0;
  static const planar_grid::fuzz::FuzzInputFile file("poses");
  const std::string& path = file.write(data + 1, size - 1);
  try {
    switch (data[0] % 4) {
      case 0:
        (void)planar_grid::loadKittiPoses(path);
        break;
      case 1:
        (void)planar_grid::loadKarlsruheInsData(path);
        break;
      case 2:
        (void)planar_grid::loadEurocBodyPoses(path);
        break;
      default:
        (void)planar_grid::loadPCDViewpoint(path);
        break;
    }
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
