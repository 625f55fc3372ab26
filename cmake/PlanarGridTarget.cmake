# SPDX-License-Identifier: BSD-3-Clause
# Helpers shared by every target (S3, S4): warnings and sanitizers per target, nothing global.

function(planar_grid_set_warnings target)
  target_compile_options(${target} PRIVATE -Wall -Wextra -Wpedantic)
  if(PLANAR_GRID_SANITIZE)
    target_compile_options(${target} PRIVATE -fsanitize=address,undefined -fno-omit-frame-pointer)
    target_link_options(${target} PRIVATE -fsanitize=address,undefined)
  endif()
endfunction()

# planar_grid_add_library(<module> SOURCES ... DEPENDS ...): the library planar_grid_<module>
# with include/ as its public include directory.
function(planar_grid_add_library module)
  cmake_parse_arguments(ARG "" "" "SOURCES;DEPENDS;PRIVATE_DEPENDS" ${ARGN})
  set(target planar_grid_${module})
  add_library(${target} ${ARG_SOURCES})
  target_include_directories(${target} PUBLIC
    $<BUILD_INTERFACE:${CMAKE_CURRENT_SOURCE_DIR}/include>
    $<INSTALL_INTERFACE:include>)
  target_link_libraries(${target} PUBLIC ${ARG_DEPENDS} PRIVATE ${ARG_PRIVATE_DEPENDS})
  planar_grid_set_warnings(${target})
endfunction()
