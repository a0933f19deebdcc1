# Runs COMMAND (a list) under Oclgrind, an OpenCL 1.2 simulator that checks every memory access,
# on its device (TANDEM_DEVICE=oclgrind), and passes if the command exits 0 and Oclgrind reported
# nothing: no invalid or unaligned access and no data race (its --log file LOG stays empty), and no
# API error or fatal error (printed on stderr).
#
#   cmake -DOCLGRIND=oclgrind -DCOMMAND="tandem;render;..." -DLOG=file.log [-DENV="NAME=VALUE;..."]
#         [-DEXPECT=regex] [-DSAME_AS="tandem;render;..." -DIMGCMP=tandem-imgcmp
#         [-DIMAGES="a.exr;b.exr"] [-DDIRS="a;b"]] -P run.cmake
#
# With EXPECT, the command's output (stdout and stderr) must also match that regular expression.
#
# With SAME_AS, the same work on the default device (PoCL) must give the same bits: its standard
# output, line for line, apart from the values of times ("...seconds": values, "in 0.12 s (3.4 M
# samples/s)"), of the "reproducible" flag (Oclgrind does not claim correctly rounded division and
# sqrt, although its host arithmetic rounds them correctly) and the names of the outputs (IMAGES,
# DIRS), which differ between the two runs: every count (the guards' dropped samples among them)
# and value is compared. The images IMAGES (Oclgrind's, then PoCL's) must store the same words
# (IMGCMP, tandem-imgcmp: NaN payloads and the sign of zero count). The output folders DIRS
# (Oclgrind's, then PoCL's; `tandem optimize --out`) must hold the same files: every image the same
# words (IMGCMP), metrics.csv the same rows but for its "seconds" column (wall-clock time), every
# other file the same bytes (params.json: the final parameters, each float written in full), and
# checkpoint.bin and checkpoint.prev.bin too but for their wall-clock fields (their "clock" section): the parameters, the optimizer's moments, the
# control variate's state, the reservoirs and the metrics at full precision (metrics.csv holds 9
# digits) are the same bits.
#
# Oclgrind's checks used: --data-races (between work items, and within a work-group),
# --uniform-writes (also races where every writer stores the same value) and --check-api (bad
# OpenCL calls). Not used: --uninitialized, which in Oclgrind 21.10 stops with a fatal error at
# LLVM 14's `freeze` instruction (in render_pass) and then reports every value computed after it.
#
file(REMOVE "${LOG}")
# no output of an earlier run may stand in for this one's
foreach(output IN LISTS IMAGES DIRS)
  file(REMOVE_RECURSE "${output}")
endforeach()
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

# What may differ between the devices: the values of times and of the "reproducible" flag, and
# the names of the outputs (`names`: those of the run whose output `var` holds).
function(normalize var names)
  set(text "${${var}}")
  string(REGEX REPLACE "\"([a-z_]*seconds|samples_per_second)\": [-+0-9.eE]+" "\"\\1\": (time)"
         text "${text}")
  string(REGEX REPLACE "in [-+0-9.eE]+ s \\([-+0-9.eE]+ M samples/s\\)" "in (time)" text "${text}")
  string(REGEX REPLACE " iterations in [-+0-9.eE]+ s" " iterations in (time)" text "${text}")
  string(REGEX REPLACE "\"reproducible\": (true|false)" "\"reproducible\": (device)" text "${text}")
  foreach(name IN LISTS names)
    string(REPLACE "${name}" "(output)" text "${text}")
  endforeach()
  set(${var} "${text}" PARENT_SCOPE)
endfunction()

# Whether the images of each pair in `pairs` (A;B;A2;B2...) store the same words (tandem-imgcmp).
function(require_same_images pairs)
  execute_process(COMMAND "${IMGCMP}" ${pairs} RESULT_VARIABLE icode OUTPUT_VARIABLE iout
                  ERROR_VARIABLE ierr)
  if(NOT icode STREQUAL "0")
    message(FATAL_ERROR "Oclgrind's image differs from the default device's: ${iout}${ierr}")
  endif()
endfunction()

# metrics.csv without its "seconds" column, one row a list element.
function(metrics_rows file var)
  file(STRINGS "${file}" lines)
  list(GET lines 0 header)
  string(REPLACE "," ";" columns "${header}")
  list(FIND columns "seconds" at)
  if(at LESS 0)
    message(FATAL_ERROR "${file}: no 'seconds' column in '${header}'")
  endif()
  set(rows "")
  foreach(line IN LISTS lines)
    string(REPLACE "," ";" cells "${line}")
    list(REMOVE_AT cells ${at})
    string(REPLACE ";" "," line "${cells}")
    list(APPEND rows "${line}")
  endforeach()
  set(${var} "${rows}" PARENT_SCOPE)
endfunction()

# A checkpoint (core/inverse/checkpoint.h) as `tandem checkpoint` describes it once it has verified
# every section's checksum: the size and XXH3 digest of each section, and the run's inputs. Without
# the line naming the file and the "clock" section, which holds every wall-clock field: equal
# descriptions are the same parameters, optimizer moments, control-variate state, reservoirs and
# metrics at full precision, bit for bit.
function(checkpoint_without_times file var)
  list(GET SAME_AS 0 tandem)
  execute_process(COMMAND "${tandem}" checkpoint "${file}" RESULT_VARIABLE code
                  OUTPUT_VARIABLE out ERROR_VARIABLE err)
  if(NOT code STREQUAL "0")
    message(FATAL_ERROR "${file}: ${err}")
  endif()
  string(REGEX REPLACE "^[^\n]*\n" "" out "${out}")
  string(REGEX REPLACE "  section clock [^\n]*\n" "" out "${out}")
  set(${var} "${out}" PARENT_SCOPE)
endfunction()

# Whether the output folders `a` and `b` hold the same files (see the top of this file), those of
# their subfolders too (views/K/ of a run with several views).
function(require_same_folder a b)
  file(GLOB_RECURSE names_a LIST_DIRECTORIES false RELATIVE "${a}" "${a}/*")
  file(GLOB_RECURSE names_b LIST_DIRECTORIES false RELATIVE "${b}" "${b}/*")
  if(NOT names_a STREQUAL names_b)
    message(FATAL_ERROR "Oclgrind's and the default device's outputs differ in files:\n"
                        "${a}: ${names_a}\n${b}: ${names_b}")
  endif()
  set(compared 0)
  set(images "")
  foreach(name IN LISTS names_a)
    if(name STREQUAL ".tandem.lock")
      # the lock file (core/io/folder_lock.h): empty once its run ended
      file(SIZE "${a}/${name}" size_a)
      file(SIZE "${b}/${name}" size_b)
      if(NOT size_a EQUAL 0 OR NOT size_b EQUAL 0)
        message(FATAL_ERROR "${a} or ${b}: the lock file of a finished run is not empty")
      endif()
    elseif(name MATCHES "^checkpoint(\\.prev)?\\.bin$")
      checkpoint_without_times("${a}/${name}" hex_a)
      checkpoint_without_times("${b}/${name}" hex_b)
      if(NOT hex_a STREQUAL hex_b)
        message(FATAL_ERROR "Oclgrind's checkpoint differs from the default device's (wall-clock "
                            "times aside): ${a}, ${b}")
      endif()
    elseif(name MATCHES "\\.exr$")
      list(APPEND images "${a}/${name}" "${b}/${name}")
    elseif(name STREQUAL "metrics.csv")
      metrics_rows("${a}/${name}" rows_a)
      metrics_rows("${b}/${name}" rows_b)
      if(NOT rows_a STREQUAL rows_b)
        message(FATAL_ERROR "Oclgrind's metrics differ from the default device's (seconds "
                            "aside):\n--- Oclgrind\n${rows_a}\n--- default device\n${rows_b}")
      endif()
    else()
      execute_process(COMMAND ${CMAKE_COMMAND} -E compare_files "${a}/${name}" "${b}/${name}"
                      RESULT_VARIABLE fcode)
      if(NOT fcode STREQUAL "0")
        message(FATAL_ERROR "Oclgrind's ${name} differs from the default device's (${a}, ${b})")
      endif()
    endif()
    math(EXPR compared "${compared} + 1")
  endforeach()
  if(images)
    require_same_images("${images}")
  endif()
  message(STATUS "ok: ${compared} outputs the same")
endfunction()

if(DEFINED SAME_AS)
  execute_process(COMMAND ${SAME_AS} RESULT_VARIABLE pcode OUTPUT_VARIABLE pout ERROR_VARIABLE perr)
  if(NOT pcode STREQUAL "0")
    message(FATAL_ERROR "the same work on the default device failed: ${perr}")
  endif()
  set(names_o "")
  set(names_p "")
  foreach(pair IMAGES DIRS)
    if(${pair})
      list(GET ${pair} 0 name)
      list(APPEND names_o "${name}")
      list(GET ${pair} 1 name)
      list(APPEND names_p "${name}")
    endif()
  endforeach()
  normalize(out "${names_o}")
  normalize(pout "${names_p}")
  if(NOT out STREQUAL pout)
    message(FATAL_ERROR "Oclgrind and the default device differ:\n--- Oclgrind\n${out}\n--- default device\n${pout}")
  endif()
  if(IMAGES)
    require_same_images("${IMAGES}")
  endif()
  if(DIRS)
    list(GET DIRS 0 a)
    list(GET DIRS 1 b)
    require_same_folder("${a}" "${b}")
  endif()
  message(STATUS "ok: the same bits as on the default device")
endif()
