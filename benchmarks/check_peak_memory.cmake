# Peak memory of `bloomref run` at 7680x4320 must stay within 3.5 full-size float RGBA images
# (the peak-memory target, docs/performance.md), under the plan given (-DPLAN=adaptive, the default, or full). Run by ctest
# (label benchmark): cmake -DBLOOMREF=... -DOUT=... -DPLAN=... -P this.
if(NOT PLAN)
  set(PLAN adaptive)
endif()
execute_process(COMMAND ${BLOOMREF} run --size 7680x4320 --plan ${PLAN} -o ${OUT}/peak-${PLAN}.exr
                        --json ${OUT}/peak-${PLAN}.json -q
                RESULT_VARIABLE rc)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "bloomref run failed (${rc})")
endif()
file(READ ${OUT}/peak-${PLAN}.json json)
string(JSON peak GET ${json} peak_rss_bytes)
math(EXPR image "7680 * 4320 * 16")
math(EXPR limit "${image} * 7 / 2")
math(EXPR tenths "${peak} * 10 / ${image}")
message(STATUS "${PLAN} plan: peak RSS ${peak} bytes = ${tenths}/10 full-size images (limit 35/10)")
if(peak GREATER limit)
  message(FATAL_ERROR "peak RSS ${peak} exceeds 3.5 images (${limit} bytes)")
endif()
