# Regenerates scenes/gallery-lights.xml into OUT and compares it byte for byte with the committed one.
execute_process(COMMAND ${PYTHON} ${SOURCE}/scenes/gen_gallery.py ${OUT} RESULT_VARIABLE code)
if(NOT code EQUAL 0)
  message(FATAL_ERROR "gen_gallery.py failed")
endif()
execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files ${OUT}/gallery-lights.xml
                        ${SOURCE}/scenes/gallery-lights.xml RESULT_VARIABLE diff)
if(NOT diff EQUAL 0)
  message(FATAL_ERROR "scenes/gallery-lights.xml differs from what gen_gallery.py writes")
endif()
