# Runs a command and checks its exit code and output; used by CTest for CLI behaviour (exit codes, error
# messages) that a GoogleTest inside the process cannot see.
# cmake -DCMD="prog;arg1;arg2" -DEXPECT_CODE=2 -DEXPECT_REGEX="..." [-DENV="A=1;B=2"] -P expect_run.cmake
if(ENV)
  set(prefix ${CMAKE_COMMAND} -E env ${ENV})
endif()
execute_process(COMMAND ${prefix} ${CMD} RESULT_VARIABLE code OUTPUT_VARIABLE out ERROR_VARIABLE err)
set(all "${out}${err}")
if(NOT "${code}" STREQUAL "${EXPECT_CODE}")
  message(FATAL_ERROR "exit code ${code}, expected ${EXPECT_CODE}\n--- output ---\n${all}")
endif()
if(EXPECT_REGEX AND NOT all MATCHES "${EXPECT_REGEX}")
  message(FATAL_ERROR "output does not match '${EXPECT_REGEX}'\n--- output ---\n${all}")
endif()
message(STATUS "ok: exit ${code}")
