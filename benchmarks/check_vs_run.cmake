# bloomref check against bloomref run on one frame (issue 37, part 5): a frame with every stage
# captured (bloomref's own CPU stages, dumped), judged by check, beside run --plan full of the
# same frame, in one script run; prints both times, their ratio and check's peak memory, and
# warns where the issue's targets are not met (check within 3x of run at 1920x1080; check's
# peak under 1.5 GB at 3840x2160). Run by ctest (label benchmark):
#   cmake -DBLOOMREF=... -DOUT=... -DSIZE=1920x1080 -P this
if(NOT SIZE)
  set(SIZE 1920x1080)
endif()
set(dir ${OUT}/check-vs-run-${SIZE})
file(REMOVE_RECURSE ${dir})
file(MAKE_DIRECTORY ${dir})
function(bloomref)
  execute_process(COMMAND ${BLOOMREF} ${ARGN} RESULT_VARIABLE rc WORKING_DIRECTORY ${dir})
  if(NOT rc EQUAL 0)
    message(FATAL_ERROR "bloomref ${ARGN} failed (${rc})")
  endif()
endfunction()
bloomref(scenes demo --size ${SIZE} -o scene.exr)
bloomref(run scene.exr --plan full --dump-stages stages -q)
bloomref(run scene.exr --plan full -o out.exr --json run.json -q)
bloomref(check scene.exr --stages stages --json check.json -q)
file(READ ${dir}/run.json run)
file(READ ${dir}/check.json check)
string(JSON run_ms GET ${run} timings_ms total)
string(JSON load_ms GET ${check} items 0 timings_ms load)
string(JSON oracle_ms GET ${check} items 0 timings_ms oracle)
string(JSON judge_ms GET ${check} items 0 timings_ms judge)
string(JSON peak GET ${check} peak_rss_bytes)
string(JSON verdict GET ${check} verdict)
foreach(v run_ms load_ms oracle_ms judge_ms)  # whole milliseconds: math() is integer only
  string(REGEX REPLACE "\\..*" "" ${v} "${${v}}")
endforeach()
math(EXPR check_ms "${load_ms} + ${oracle_ms} + ${judge_ms}" OUTPUT_FORMAT DECIMAL)
math(EXPR ratio10 "${check_ms} * 10 / ${run_ms}")
math(EXPR peak_mb "${peak} / 1000000")
message(STATUS "${SIZE}: run --plan full ${run_ms} ms; check of 15 stages ${check_ms} ms "
               "(load ${load_ms}, oracle ${oracle_ms}, judge ${judge_ms}) = ${ratio10}/10 x run; "
               "check peak RSS ${peak_mb} MB; verdict ${verdict}")
if(NOT verdict STREQUAL "PASS")
  message(FATAL_ERROR "bloomref's own stages did not pass check")
endif()
if(SIZE STREQUAL "1920x1080" AND ratio10 GREATER 30)
  message(WARNING "check takes ${ratio10}/10 x run --plan full (the issue's target: at most 3x)")
endif()
if(SIZE STREQUAL "3840x2160" AND peak GREATER 1500000000)
  message(WARNING "check's peak RSS ${peak_mb} MB (the issue's target: under 1500 MB)")
endif()
