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
