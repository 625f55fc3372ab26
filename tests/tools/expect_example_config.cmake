# SPDX-License-Identifier: BSD-3-Clause
# Fails when config/example.yaml does not hold, verbatim, the stage list that
# `planar_grid_pipeline --print-default-pipeline` prints from the stage tables.
# -DPROGRAM=the tool -DEXAMPLE=config/example.yaml -DSOURCE_DIR=the source tree
execute_process(COMMAND ${PROGRAM} --print-default-pipeline
  OUTPUT_VARIABLE generated RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${PROGRAM} --print-default-pipeline exited with ${status}")
endif()
file(READ ${EXAMPLE} example)
string(FIND "${example}" "${generated}" at)
if(at EQUAL -1)
  message(FATAL_ERROR "${EXAMPLE}: its stage list differs from what "
    "`planar_grid_pipeline --print-default-pipeline` prints from the stage tables; "
    "regenerate it with: bash ${SOURCE_DIR}/scripts/update_example_config.sh ${PROGRAM}")
endif()
