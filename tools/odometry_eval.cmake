# SPDX-License-Identifier: BSD-3-Clause
# planar_grid_odometry_eval: stereo visual odometry (paper eq. 8) against the Karlsruhe
# INS positions and the EuRoC ground-truth poses (docs/ODOMETRY.md). Included by
# tools/CMakeLists.txt.
add_executable(planar_grid_odometry_eval planar_grid_odometry_eval.cpp)
target_link_libraries(planar_grid_odometry_eval PRIVATE
  planar_grid_odometry planar_grid_stereo planar_grid_calibration_io planar_grid_core pcl_common
  nlohmann_json::nlohmann_json ${OpenCV_LIBS})
planar_grid_set_warnings(planar_grid_odometry_eval)
