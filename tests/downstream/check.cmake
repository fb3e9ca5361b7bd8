# ctest driver: install lgvi from BUILD_DIR into a scratch prefix, configure and
# build tests/downstream against it with find_package(lgvi), and run it.
file(REMOVE_RECURSE ${WORK_DIR})
execute_process(COMMAND ${CMAKE_COMMAND} --install ${BUILD_DIR} --prefix ${WORK_DIR}/prefix
                RESULT_VARIABLE rc OUTPUT_QUIET)
if(rc)
  message(FATAL_ERROR "cmake --install failed: ${rc}")
endif()
# The licence and the notices come with every install.
foreach(doc LICENSE THIRD-PARTY-NOTICES.md CITATION.cff)
  if(NOT EXISTS ${WORK_DIR}/prefix/share/doc/lgvi/${doc})
    message(FATAL_ERROR "cmake --install did not install share/doc/lgvi/${doc}")
  endif()
endforeach()
# The command-line tool, and (when the build has it) the Python package, in the prefix too.
execute_process(COMMAND ${WORK_DIR}/prefix/bin/lgvi --version RESULT_VARIABLE rc OUTPUT_VARIABLE out)
if(rc OR NOT out MATCHES "^lgvi [0-9]")
  message(FATAL_ERROR "the installed bin/lgvi --version failed (${rc}): ${out}")
endif()
if(PYTHON AND PYTHON_SITE)
  execute_process(COMMAND ${CMAKE_COMMAND} -E env PYTHONPATH=${WORK_DIR}/prefix/${PYTHON_SITE}
                          ${PYTHON} -c "import lgvi, lgvi._core; print(lgvi._core.__file__)"
                  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(rc OR NOT out MATCHES "^${WORK_DIR}/prefix/")
    message(FATAL_ERROR "the installed Python package does not import from the prefix (${rc}): ${out}${err}")
  endif()
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -S ${SOURCE_DIR} -B ${WORK_DIR}/build -DCMAKE_BUILD_TYPE=Release
                        -DCMAKE_PREFIX_PATH=${WORK_DIR}/prefix
                RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc)
  message(FATAL_ERROR "configuring the downstream project failed:\n${out}\n${err}")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} --build ${WORK_DIR}/build RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc)
  message(FATAL_ERROR "building the downstream project failed:\n${out}\n${err}")
endif()
execute_process(COMMAND ${WORK_DIR}/build/downstream RESULT_VARIABLE rc OUTPUT_VARIABLE out)
message("${out}")
if(rc)
  message(FATAL_ERROR "the downstream program failed: ${rc}")
endif()
# The gyrostat example: 300 steps of Manchester & Peck's free gyrostat; its last row's inertial angular
# momentum is the first's to round-off (the step carries it by a rotation: 1e-13 relative, measured ~1e-15).
execute_process(COMMAND ${WORK_DIR}/build/gyrostat 0.1 30 RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc)
  message(FATAL_ERROR "the gyrostat example failed: ${rc}\n${err}")
endif()
string(REGEX MATCHALL "[^\n]+" rows "${out}")
list(GET rows 1 first)
list(GET rows -1 last)
string(REPLACE "," ";" first "${first}")
string(REPLACE "," ";" last "${last}")
foreach(i 8 9 10)
  list(GET first ${i} a)
  list(GET last ${i} b)
  # |b - a| <= 1e-13 (|L| is about 1.6 here): CMake has no floating point, so the scripting is in Python.
  list(APPEND pairs "${a},${b}")
endforeach()
execute_process(COMMAND ${PYTHON} -c "import sys; d = [abs(float(b) - float(a)) for a, b in (p.split(',') for p in sys.argv[1:])]; sys.exit(0 if max(d) < 1e-13 else 1)" ${pairs}
                RESULT_VARIABLE rc)
if(rc)
  message(FATAL_ERROR "the gyrostat example did not keep its angular momentum: first ${first}, last ${last}")
endif()
message("gyrostat example: 300 steps, inertial angular momentum kept to 1e-13")
