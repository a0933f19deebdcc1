# Regenerates the media scenes and plume.vol into OUT and compares each byte for byte with the
# committed one.
execute_process(COMMAND ${PYTHON} ${SOURCE}/scenes/gen_media.py ${OUT} RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "gen_media.py failed")
endif()
foreach(file media-cube.xml media-plume.xml plume.vol)
  execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT}/${file} ${SOURCE}/scenes/${file}
                  RESULT_VARIABLE diff)
  if(NOT diff EQUAL 0)
    message(FATAL_ERROR "scenes/${file} differs from what gen_media.py writes")
  endif()
endforeach()
