#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Fails when a tracked C++ file is not formatted with the project's .clang-format
# (PCL's layout, so that the code reads like the library it extends).
set -euo pipefail
cd "$(dirname "$0")/.."
command -v clang-format >/dev/null || { echo "check_format: clang-format not installed" >&2; exit 1; }
# Two clang-format processes at a time, each over a batch of files; a file that is not
# formatted is printed by name.
mapfile -t bad < <(git ls-files -z '*.h' '*.hpp' '*.cpp' | xargs -0 -P "${JOBS:-2}" -n 32 \
  sh -c 'for f; do clang-format --dry-run -Werror "$f" >/dev/null 2>&1 || echo "$f"; done' sh \
  | sort)
if [ ${#bad[@]} -gt 0 ]; then
  echo "check_format: not formatted with .clang-format (run clang-format -i):" >&2
  printf '  %s\n' "${bad[@]}" >&2
  exit 1
fi
