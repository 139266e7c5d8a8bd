cmake_policy(SET CMP0007 NEW)
# cmake -DROOT=path -P check_layers.cmake: fails if the core's layers are crossed (doc/architecture.md)
# or a source file grows past 600 lines.
#   common, camera, rig, frontend  (no mvis layer above them)
#   inertial   may include common, rig
#   factors    may include common, camera, rig, frontend, inertial, factors
#   estimator  may include all of the above
set(layers
  "inertial|estimator|factors|sim|ros"
  "factors|estimator|sim|ros")
set(dirs inertial factors)
set(failures "")
foreach(i RANGE 1)
  list(GET dirs ${i} dir)
  list(GET layers ${i} forbidden)
  file(GLOB_RECURSE files ${ROOT}/include/mvis/${dir}/*.h ${ROOT}/src/core/${dir}/*.h
       ${ROOT}/src/core/${dir}/*.cpp)
  if(NOT files)
    list(APPEND failures "no files in the ${dir} layer (wrong ROOT?)")
  endif()
  foreach(f ${files})
    file(STRINGS ${f} includes REGEX "^#include \"mvis/(${forbidden})/")
    # A layer may include itself: inertial files include mvis/inertial/.
    list(FILTER includes EXCLUDE REGEX "mvis/${dir}/")
    if(includes)
      list(APPEND failures "${f}: ${dir}/ must not include ${includes}")
    endif()
  endforeach()
endforeach()
file(GLOB_RECURSE sources ${ROOT}/include/*.h ${ROOT}/src/*.h ${ROOT}/src/*.cpp ${ROOT}/test/*.h
     ${ROOT}/test/*.cpp ${ROOT}/scripts/*.py)
foreach(f ${sources})
  file(STRINGS ${f} lines)
  list(LENGTH lines n)
  if(n GREATER 600)
    list(APPEND failures "${f}: ${n} lines (at most 600)")
  endif()
endforeach()
if(failures)
  string(REPLACE ";" "\n" text "${failures}")
  message(FATAL_ERROR "${text}")
endif()
list(LENGTH sources count)
message(STATUS "layers respected; ${count} source files, none over 600 lines")
