# SPDX-License-Identifier: Apache-2.0
# Injected with -DCMAKE_PROJECT_INCLUDE when skynav_msgs is built against the
# ROS 2 wheels from PyPI. Those wheels were built in a manylinux container and
# their exported *__rosidl_generator_py targets still list include directories
# under /opt/python/... that exist only there, which fails CMake's generate
# step. Once the top-level directory is processed, drop those entries from
# every imported target. A regular ROS 2 install never reads this file.
function(skynav_strip_wheel_include_dirs)
  get_property(targets DIRECTORY "${CMAKE_SOURCE_DIR}" PROPERTY IMPORTED_TARGETS)
  foreach(target IN LISTS targets)
    get_target_property(dirs ${target} INTERFACE_INCLUDE_DIRECTORIES)
    if(dirs)
      list(FILTER dirs EXCLUDE REGEX "^/opt/python/")
      set_target_properties(${target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${dirs}")
    endif()
  endforeach()
endfunction()
cmake_language(DEFER DIRECTORY "${CMAKE_SOURCE_DIR}" CALL skynav_strip_wheel_include_dirs)
