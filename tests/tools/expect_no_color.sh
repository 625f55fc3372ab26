#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# Runs a tool on a pseudo-terminal (script(1)), where PCL's messages are coloured, once
# as is and once with NO_COLOR=1: the first output must hold an ANSI escape sequence (so
# that this check can see colour at all), the second none.
#   expect_no_color.sh PROGRAM [ARGS...]
set -u
command -v script >/dev/null || { echo "script(1) is not installed"; exit 1; }
printf -v command '%q ' "$@"
esc=$(printf '\033[')
coloured=$(script -qec "$command" /dev/null 2>&1)
plain=$(NO_COLOR=1 script -qec "$command" /dev/null 2>&1)
if [[ "$coloured" != *"$esc"* ]]; then
  echo "no colour on a terminal without NO_COLOR:"; printf '%s\n' "$coloured"; exit 1
fi
if [[ "$plain" == *"$esc"* ]]; then
  echo "colour with NO_COLOR=1:"; printf '%s\n' "$plain" | cat -v; exit 1
fi
[ -n "$plain" ] || { echo "no output with NO_COLOR=1"; exit 1; }
echo "coloured without NO_COLOR, plain with it"
