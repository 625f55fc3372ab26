# SPDX-License-Identifier: BSD-3-Clause
# Fails when docs/STAGES.md is not, verbatim, what `planar_grid_pipeline
# --stage-reference` prints from the stage tables.
# -DPROGRAM=the tool -DPAGE=docs/STAGES.md
execute_process(COMMAND ${PROGRAM} --stage-reference
  OUTPUT_VARIABLE generated RESULT_VARIABLE status)
if(NOT status EQUAL 0)
  message(FATAL_ERROR "${PROGRAM} --stage-reference exited with ${status}")
endif()
file(READ ${PAGE} page)
if(NOT page STREQUAL generated)
  message(FATAL_ERROR "${PAGE} differs from what `planar_grid_pipeline --stage-reference` "
    "prints from the stage tables; regenerate it with: "
    "${PROGRAM} --stage-reference > ${PAGE}")
endif()
