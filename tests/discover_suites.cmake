# SPDX-License-Identifier: BSD-3-Clause
# Run after a test executable is built (cmake -P): lists its GoogleTest cases and writes
# OUTPUT, a CTest file with one test per suite (--gtest_filter=Suite.*). Each test is a
# process, and a process that loads PCL, VTK and OpenCV spends about a second in the
# dynamic loader before its first case (more under the sanitizers), so one process per
# suite rather than per case. The number of cases of each suite is written beside it.
#   -DEXECUTABLE=<file> -DOUTPUT=<file> -DWORKING_DIRECTORY=<dir>
#   [-DEMULATOR=<program|arg|...>] [-DSERIAL=ON] [-DLONG_SUITES=<suite|suite|...>]
# LONG_SUITES get a high COST: ctest -j starts them first when it has no timings of its own
# yet (a fresh build folder), so that no long suite starts last and runs alone.
cmake_policy(SET CMP0057 NEW)
string(REPLACE "|" ";" emulator "${EMULATOR}")
string(REPLACE "|" ";" long_suites "${LONG_SUITES}")
execute_process(
  COMMAND ${emulator} "${EXECUTABLE}" --gtest_list_tests
  WORKING_DIRECTORY "${WORKING_DIRECTORY}"
  OUTPUT_VARIABLE listing
  ERROR_VARIABLE errors
  RESULT_VARIABLE result
  TIMEOUT 120)
if(NOT result EQUAL 0)
  message(FATAL_ERROR "${EXECUTABLE} --gtest_list_tests failed (${result}):\n${listing}\n${errors}")
endif()

string(REPLACE ";" "\\;" listing "${listing}")
string(REPLACE "\n" ";" lines "${listing}")
set(suites "")
set(suite "")
foreach(line IN LISTS lines)
  if(line MATCHES "^([^ #][^ ]*)\\.( .*)?$")
    set(suite "${CMAKE_MATCH_1}")
    list(APPEND suites "${suite}")
    set(cases_${suite} 0)
  elseif(line MATCHES "^  [^ ]" AND NOT suite STREQUAL "")
    math(EXPR cases_${suite} "${cases_${suite}} + 1")
  endif()
endforeach()
if(NOT suites)
  message(FATAL_ERROR "${EXECUTABLE} lists no GoogleTest case")
endif()

set(content "# Generated from ${EXECUTABLE} --gtest_list_tests\n")
foreach(suite IN LISTS suites)
  set(command "")
  foreach(word IN LISTS emulator)
    string(APPEND command " [==[${word}]==]")
  endforeach()
  string(APPEND content
    "add_test([==[${suite}]==]${command} [==[${EXECUTABLE}]==] [==[--gtest_filter=${suite}.*]==])\n"
    "set_tests_properties([==[${suite}]==] PROPERTIES WORKING_DIRECTORY [==[${WORKING_DIRECTORY}]==]"
    " LABELS gtest")
  if(SERIAL)
    string(APPEND content " RUN_SERIAL TRUE")
  endif()
  if(suite IN_LIST long_suites)
    string(APPEND content " COST 1000")
  endif()
  string(APPEND content ")\n# gtest_cases ${cases_${suite}}\n")
endforeach()
file(WRITE "${OUTPUT}" "${content}")
