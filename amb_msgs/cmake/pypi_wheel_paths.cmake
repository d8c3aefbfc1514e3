# Rewrite the wheel build machine's Python paths in imported targets (ROS 2 from PyPI wheels).
#
# The ros-jazzy-* wheels are built by cibuildwheel in a manylinux image whose interpreter lives
# under /opt/python/cpXY-cpXY; their exported CMake targets name that interpreter's include
# directory and NumPy's include directory. On any other machine those paths do not exist and the
# CMake generate step fails. amb_msgs_fix_wheel_paths() replaces them, in every imported target
# of this directory, with the paths of the interpreter found by find_package(Python3). On a full
# ROS 2 install no target names /opt/python and nothing changes.

find_package(Python3 REQUIRED COMPONENTS Interpreter Development NumPy)

function(amb_msgs_fix_wheel_paths)
  get_property(_targets DIRECTORY PROPERTY IMPORTED_TARGETS)
  foreach(_target IN LISTS _targets)
    get_target_property(_dirs ${_target} INTERFACE_INCLUDE_DIRECTORIES)
    if(NOT _dirs OR NOT _dirs MATCHES "/opt/python/")
      continue()
    endif()
    set(_fixed "")
    foreach(_dir IN LISTS _dirs)
      if(_dir MATCHES "^/opt/python/[^/]+/include/python")
        list(APPEND _fixed ${Python3_INCLUDE_DIRS})
      elseif(_dir MATCHES "^/opt/python/.*/numpy/.*include$")
        list(APPEND _fixed ${Python3_NumPy_INCLUDE_DIRS})
      else()
        list(APPEND _fixed "${_dir}")
      endif()
    endforeach()
    list(REMOVE_DUPLICATES _fixed)
    set_target_properties(${_target} PROPERTIES INTERFACE_INCLUDE_DIRECTORIES "${_fixed}")
    message(STATUS "amb_msgs: rewrote wheel build paths of ${_target}")
  endforeach()
endfunction()
