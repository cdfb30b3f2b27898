# Memory-size regression check: compares the numbers in ACTUAL (a summary.json) with the committed
# baselines in BASELINE (tests/baselines/*.json: {"checks": {"key": {"value": v, "tolerance": t}}}, t a
# relative tolerance). A value above value * (1 + t) fails and says which key grew and by how much;
# a value far below (< value * (1 - 2t)) only warns, so an improvement is noticed and the baseline can be
# lowered in a deliberate commit.
file(READ ${BASELINE} base)
file(READ ${ACTUAL} actual)
string(JSON n LENGTH "${base}" checks)
math(EXPR last "${n} - 1")
set(failures "")
foreach(i RANGE ${last})
  string(JSON key MEMBER "${base}" checks ${i})
  string(JSON want GET "${base}" checks ${key} value)
  string(JSON tol GET "${base}" checks ${key} tolerance)
  string(JSON got ERROR_VARIABLE err GET "${actual}" ${key})
  if(err)
    list(APPEND failures "${key}: missing from ${ACTUAL}")
    continue()
  endif()
  # CMake has no floating-point arithmetic: awk compares.
  execute_process(COMMAND awk "BEGIN { w=${want}; g=${got}; t=${tol}; d=(g-w)/w*100; \
                                      if (g > w*(1+t)) print \"FAIL \" d; else if (g < w*(1-2*t)) print \"LOW \" d; else print \"OK \" d }"
                  OUTPUT_VARIABLE verdict OUTPUT_STRIP_TRAILING_WHITESPACE)
  string(REPLACE " " ";" verdict "${verdict}")
  list(GET verdict 0 state)
  list(GET verdict 1 pct)
  if(state STREQUAL "FAIL")
    list(APPEND failures "${key}: ${got} vs baseline ${want} (+${pct} %, tolerance ${tol})")
  elseif(state STREQUAL "LOW")
    message(WARNING "${key}: ${got} is ${pct} % below the baseline ${want}: lower tests/baselines in a deliberate commit")
  else()
    message(STATUS "${key}: ${got} (baseline ${want}, ${pct} %)")
  endif()
endforeach()
if(failures)
  string(REPLACE ";" "\n  " msg "${failures}")
  message(FATAL_ERROR "memory regression against ${BASELINE}:\n  ${msg}\n(if the growth is intended, update the baseline in its own commit)")
endif()
