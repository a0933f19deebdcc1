# Runs COMMAND (a list) with extra environment ENV (NAME=VALUE list) and passes if it exits with a
# code in 1..127 (an error, not a crash or signal), prints exactly one line on stderr, and that
# line matches REGEX.
set(env_args)
foreach(kv IN LISTS ENV)
  list(APPEND env_args "${kv}")
endforeach()
execute_process(COMMAND ${CMAKE_COMMAND} -E env ${env_args} ${COMMAND}
                RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
string(STRIP "${err}" err_stripped)
string(REGEX MATCHALL "\n" newlines "${err_stripped}")
list(LENGTH newlines extra_lines)
if(NOT code MATCHES "^[0-9]+$" OR code EQUAL 0 OR code GREATER 127)
  message(FATAL_ERROR "expected an error exit code, got '${code}'\nstderr: ${err}")
endif()
if(NOT extra_lines EQUAL 0)
  message(FATAL_ERROR "expected one line on stderr, got:\n${err}")
endif()
if(NOT err_stripped MATCHES "${REGEX}")
  message(FATAL_ERROR "stderr does not match '${REGEX}':\n${err}")
endif()
message(STATUS "ok (exit ${code}): ${err_stripped}")
