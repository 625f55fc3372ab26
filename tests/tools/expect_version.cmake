# SPDX-License-Identifier: BSD-3-Clause
# Runs PROGRAM --version; passes when it exits 0 and prints exactly "NAME VERSION" on
# one line of standard output, nothing on standard error.
execute_process(COMMAND ${PROGRAM} --version
  RESULT_VARIABLE rc OUTPUT_VARIABLE out ERROR_VARIABLE err)
if(NOT rc EQUAL 0)
  message(FATAL_ERROR "expected exit 0, got ${rc}\n${out}${err}")
endif()
if(NOT "${out}" STREQUAL "${NAME} ${VERSION}\n")
  message(FATAL_ERROR "expected '${NAME} ${VERSION}', got '${out}'")
endif()
if(NOT "${err}" STREQUAL "")
  message(FATAL_ERROR "unexpected output on standard error: ${err}")
endif()
message(STATUS "${out}")
