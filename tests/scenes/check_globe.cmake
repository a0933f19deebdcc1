# Regenerates scenes/globe.xml, globe.obj and textures/globe.png into OUT and compares them byte for
# byte with the committed ones.
execute_process(COMMAND ${PYTHON} ${SOURCE}/scenes/gen_globe.py ${OUT} RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "gen_globe.py failed")
endif()
foreach(name globe.xml globe.obj textures/globe.png)
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT}/${name} ${SOURCE}/scenes/${name}
                  RESULT_VARIABLE diff)
  if(NOT diff EQUAL 0)
    message(FATAL_ERROR "scenes/${name} differs from what gen_globe.py writes")
  endif()
endforeach()
