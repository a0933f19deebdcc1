# Regenerates the bundled textures into OUT and compares them byte for byte with scenes/textures.
execute_process(COMMAND ${PYTHON} ${SOURCE}/scenes/gen_textures.py ${OUT} RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "gen_textures.py failed")
endif()
foreach(name wall.png painting.png floor.png sky.pfm)
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT}/${name} ${SOURCE}/scenes/textures/${name}
                  RESULT_VARIABLE diff)
  if(NOT diff EQUAL 0)
    message(FATAL_ERROR "scenes/textures/${name} differs from what gen_textures.py writes")
  endif()
endforeach()
