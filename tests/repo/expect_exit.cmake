# Runs COMMAND (a list) with extra environment ENV (NAME=VALUE list) and passes if it exits with
# code CODE and its output (stdout and stderr) matches REGEX.
execute_process(COMMAND ${CMAKE_COMMAND} -E env ${ENV} ${COMMAND}
                RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT code STREQUAL "${CODE}")
  message(FATAL_ERROR "expected exit code ${CODE}, got '${code}'\nstdout: ${out}\nstderr: ${err}")
endif()
if(NOT "${out}${err}" MATCHES "${REGEX}")
  message(FATAL_ERROR "the output does not match '${REGEX}':\n${out}${err}")
endif()
message(STATUS "ok (exit ${code})")
