# Runs COMMAND (a list) under Oclgrind, an OpenCL 1.2 simulator that checks every memory access,
# on its device (TANDEM_DEVICE=oclgrind), and passes if the command exits 0 and Oclgrind reported
# nothing: no invalid or unaligned access and no data race (its --log file LOG stays empty), and no
# API error or fatal error (printed on stderr).
#
#   cmake -DOCLGRIND=oclgrind -DCOMMAND="tandem;render;..." -DLOG=file.log [-DENV="NAME=VALUE;..."]
#         [-DEXPECT=regex] [-DSAME_AS="tandem;render;..." [-DIMAGES="a.exr;b.exr"]] -P run.cmake
#
# With EXPECT, the command's output (stdout and stderr) must also match that regular expression.
#
# With SAME_AS, the same work on the default device (PoCL) must give the same bits: the images
# IMAGES (Oclgrind's, then PoCL's) pixel for pixel (idiff -fail 0), and the standard output line
# for line apart from timings and the "reproducible" flag (Oclgrind does not claim correctly
# rounded division and sqrt, although its host arithmetic rounds them correctly).
#
# Oclgrind's checks used: --data-races (between work items, and within a work-group),
# --uniform-writes (also races where every writer stores the same value) and --check-api (bad
# OpenCL calls). Not used: --uninitialized, which in Oclgrind 21.10 stops with a fatal error at
# LLVM 14's `freeze` instruction (in render_pass) and then reports every value computed after it.
#
file(REMOVE "${LOG}")
execute_process(COMMAND ${CMAKE_COMMAND} -E env TANDEM_DEVICE=oclgrind ${ENV}
                        "${OCLGRIND}" --data-races --uniform-writes --check-api --log "${LOG}" ${COMMAND}
                RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(report "")
if(EXISTS "${LOG}")
  file(READ "${LOG}" report)
endif()
if(NOT code STREQUAL "0")
  message(FATAL_ERROR "exit code '${code}'\nstdout: ${out}\nstderr: ${err}\nOclgrind: ${report}")
endif()
if(NOT report STREQUAL "")
  string(SUBSTRING "${report}" 0 6000 head)
  message(FATAL_ERROR "Oclgrind reported (full log: ${LOG}):\n${head}")
endif()
if(err MATCHES "OCLGRIND|Oclgrind - OpenCL runtime error")
  message(FATAL_ERROR "Oclgrind reported on stderr:\n${err}")
endif()
if(DEFINED EXPECT AND NOT "${out}${err}" MATCHES "${EXPECT}")
  message(FATAL_ERROR "the output does not match '${EXPECT}':\nstdout: ${out}\nstderr: ${err}")
endif()
message(STATUS "ok: nothing reported by Oclgrind")

if(DEFINED SAME_AS)
  execute_process(COMMAND ${SAME_AS} RESULT_VARIABLE pcode OUTPUT_VARIABLE pout ERROR_VARIABLE perr)
  if(NOT pcode STREQUAL "0")
    message(FATAL_ERROR "the same work on the default device failed: ${perr}")
  endif()
  # what may differ: times, and whether the device claims reproducible arithmetic
  foreach(var out pout)
    string(REGEX REPLACE "[^\n]*(seconds|reproducible|samples/s|out_grad)[^\n]*\n" "" ${var} "${${var}}")
  endforeach()
  if(NOT out STREQUAL pout)
    message(FATAL_ERROR "Oclgrind and the default device differ:\n--- Oclgrind\n${out}\n--- default device\n${pout}")
  endif()
  if(IMAGES)
    execute_process(COMMAND idiff -fail 0 -warn 0 ${IMAGES} RESULT_VARIABLE icode OUTPUT_VARIABLE iout)
    if(NOT icode STREQUAL "0")
      message(FATAL_ERROR "Oclgrind's image differs from the default device's:\n${iout}")
    endif()
  endif()
  message(STATUS "ok: the same bits as on the default device")
endif()
