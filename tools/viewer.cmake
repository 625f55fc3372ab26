# SPDX-License-Identifier: BSD-3-Clause
# planar_grid_viewer, the interactive and offscreen viewer (one .cpp per tool, built only
# with VTK): included from tools/CMakeLists.txt.
if(TARGET planar_grid_visualization)
  add_executable(planar_grid_viewer ${CMAKE_CURRENT_LIST_DIR}/planar_grid_viewer.cpp)
  # planar_grid_odometry reads the --trajectory (KITTI poses).
  target_link_libraries(planar_grid_viewer PRIVATE planar_grid_visualization
                        planar_grid_odometry pcl_io pcl_common)
  planar_grid_set_warnings(planar_grid_viewer)
endif()
