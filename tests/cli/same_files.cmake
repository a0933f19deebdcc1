# Runs COMMAND (a list) twice, writing OUTPUTS (file names in DIR; the command names them through
# the placeholder {DIR}) a little over a second apart, and passes if each output is the same file
# byte for byte both times: nothing in them depends on the time of writing.
foreach(round 1 2)
  file(REMOVE_RECURSE "${DIR}/${round}")
  file(MAKE_DIRECTORY "${DIR}/${round}")
  string(REPLACE "{DIR}" "${DIR}/${round}" command "${COMMAND}")
  execute_process(COMMAND ${command} RESULT_VARIABLE code OUTPUT_QUIET ERROR_VARIABLE err)
  if(NOT code EQUAL 0)
    message(FATAL_ERROR "round ${round}: exit ${code}\n${err}")
  endif()
  if(round EQUAL 1)
    execute_process(COMMAND ${CMAKE_COMMAND} -E sleep 1.2) # past the header clocks' second
  endif()
endforeach()
foreach(output IN LISTS OUTPUTS)
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files "${DIR}/1/${output}" "${DIR}/2/${output}"
                  RESULT_VARIABLE differ)
  if(differ)
    message(FATAL_ERROR "${output} differs between two runs")
  endif()
endforeach()
message(STATUS "ok: ${OUTPUTS} the same byte for byte")
