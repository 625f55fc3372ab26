#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Replaces the stage list of config/example.yaml with what
# `planar_grid_pipeline --print-default-pipeline` prints from the stage tables (every
# stage, every parameter at its default, documented). The test
# StageRegistry.ExampleConfigHoldsTheGeneratedStageList fails until this is run after
# a change to a stage's table.
#
# Usage: bash scripts/update_example_config.sh [PATH/TO/planar_grid_pipeline]
#        (default: build/tools/planar_grid_pipeline)
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
tool=${1:-$root/build/tools/planar_grid_pipeline}
file=$root/config/example.yaml
generated=$(mktemp)
trap 'rm -f "$generated" "$file.new"' EXIT
"$tool" --print-default-pipeline >"$generated"
first=$(head -n 1 "$generated")
last=$(tail -n 1 "$generated")
if ! grep -qxF -- "$first" "$file"; then
  echo "$file: no generated stage list (a line '$first')" >&2
  exit 1
fi
# The lines from the section's first line to its last one are replaced.
awk -v first="$first" -v last="$last" -v generated="$generated" '
  !done && $0 == first {
    while ((getline line < generated) > 0) print line
    inside = 1
    next
  }
  inside { if ($0 == last) { inside = 0; done = 1 }; next }
  { print }' "$file" >"$file.new"
mv "$file.new" "$file"
echo "updated $file"
