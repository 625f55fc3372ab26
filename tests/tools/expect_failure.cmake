# SPDX-License-Identifier: BSD-3-Clause
# Runs PROGRAM with ARGS; passes when it exits non-zero (with STATUS, when given) and its
# output matches EXPECT (and, when FORBID is given, does not match FORBID).
execute_process(COMMAND ${PROGRAM} ${ARGS}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(rc EQUAL 0)
  message(FATAL_ERROR "expected a non-zero exit, got 0\n${out}${err}")
endif()
if(DEFINED STATUS AND NOT rc EQUAL STATUS)
  message(FATAL_ERROR "expected exit ${STATUS}, got ${rc}\n${out}${err}")
endif()
if(NOT "${out}${err}" MATCHES "${EXPECT}")
  message(FATAL_ERROR "exit ${rc}, but the output does not match '${EXPECT}':\n${out}${err}")
endif()
if(DEFINED FORBID AND "${out}${err}" MATCHES "${FORBID}")
  message(FATAL_ERROR "exit ${rc}, but the output matches '${FORBID}':\n${out}${err}")
endif()
message(STATUS "exit ${rc}: ${err}")
