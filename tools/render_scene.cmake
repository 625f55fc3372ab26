# SPDX-License-Identifier: BSD-3-Clause
# planar_grid_render_scene: the synthetic stereo sequence with known surfaces
# (SyntheticStereoScene, docs/SYNTHETIC_SCENE.md). Included by tools/CMakeLists.txt.
if(TARGET planar_grid_visualization)
  add_executable(planar_grid_render_scene ${CMAKE_CURRENT_LIST_DIR}/planar_grid_render_scene.cpp)
  target_link_libraries(planar_grid_render_scene PRIVATE planar_grid_visualization pcl_common)
  planar_grid_set_warnings(planar_grid_render_scene)
endif()
