# SPDX-License-Identifier: BSD-3-Clause
# planar_grid_eval: SG, OG, RA and PG on the same frames, CSV and plots.
add_executable(planar_grid_eval_tool planar_grid_eval.cpp)
set_target_properties(planar_grid_eval_tool PROPERTIES OUTPUT_NAME planar_grid_eval)
target_link_libraries(planar_grid_eval_tool PRIVATE planar_grid_eval planar_grid_eval_config
                      pcl_common)
if(PLANAR_GRID_BUILD_VIEWER)
  target_link_libraries(planar_grid_eval_tool PRIVATE planar_grid_visualization)
  target_compile_definitions(planar_grid_eval_tool PRIVATE PLANAR_GRID_WITH_VIEWER=1)
endif()
planar_grid_set_warnings(planar_grid_eval_tool)
