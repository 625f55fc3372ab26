# SPDX-License-Identifier: BSD-3-Clause
# Runs PROGRAM with ARGS; passes when it exits 0, its output matches EXPECT and, when
# FILE is given, FILE exists and is not empty.
if(FILE)
  file(REMOVE "${FILE}")
endif()
execute_process(COMMAND ${PROGRAM} ${ARGS}
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "expected exit 0, got ${rc}\n${out}${err}")
endif()
if(NOT "${out}${err}" MATCHES "${EXPECT}")
  message(FATAL_ERROR "the output does not match '${EXPECT}':\n${out}${err}")
endif()
if(FILE)
  file(SIZE "${FILE}" size)
  if(NOT size GREATER 0)
    message(FATAL_ERROR "${FILE} is empty")
  endif()
endif()
message(STATUS "${out}")
