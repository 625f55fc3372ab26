// SPDX-License-Identifier: BSD-3-Clause
// libFuzzer target: planar_grid::loadStereoCalibration() on arbitrary bytes. The first
// byte picks the format (karlsruhe, kitti, ros_camera_info, euroc, by its value mod 4);
// the rest is written to a temporary file, given as both the left and the right file
// of the pair formats. The contract (calibration_io.h): a model whose calibration
// passes validate() or a planar_grid::Exception (IOError) naming the file; anything
// else is a finding.

#include <planar_grid/core/exceptions.h>
#include <planar_grid/stereo/calibration_io.h>

#include <cstddef>
#include <cstdint>

#include "fuzz_input_file.h"

extern "C" int
LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size)
{
  if (size == 0)
    return 0;
  static const planar_grid::fuzz::FuzzInputFile file("calibration");
  const planar_grid::CalibrationFormat formats[] = {
    planar_grid::CalibrationFormat::KARLSRUHE, planar_grid::CalibrationFormat::KITTI,
    planar_grid::CalibrationFormat::ROS_CAMERA_INFO,
    planar_grid::CalibrationFormat::EUROC};
  const std::string& path = file.write(data + 1, size - 1);
  try {
    (void)planar_grid::loadStereoCalibration(formats[data[0] % 4], path, path);
  } catch (const planar_grid::Exception&) {
  }
  return 0;
}
