# Runs COMMAND (a list) under Oclgrind, an OpenCL 1.2 simulator that checks every memory access,
# on its device (TANDEM_DEVICE=oclgrind), and passes if the command exits 0 and Oclgrind reported
# nothing: no invalid or unaligned access and no data race (its --log file LOG stays empty), and no
# API error or fatal error (printed on stderr).
#
#   cmake -DOCLGRIND=oclgrind -DCOMMAND="tandem;render;..." -DLOG=file.log [-DENV="NAME=VALUE;..."]
#         -P run.cmake
#
# Oclgrind's checks used: --data-races (between work items, and within a work-group),
# --uniform-writes (also races where every writer stores the same value) and --check-api (bad
# OpenCL calls). Not used: --uninitialized, which in Oclgrind 21.10 stops with a fatal error at
# LLVM 14's `freeze` instruction (in render_pass) and then reports every value computed after it.
#
# Images and gradients are not compared with PoCL's: they differ by a few ulps in some pixels
# (bench/RESULTS.md, "Oclgrind against PoCL"), as OpenCL lets each implementation round sin, cos,
# acos and the like differently.
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
message(STATUS "ok: nothing reported by Oclgrind")
