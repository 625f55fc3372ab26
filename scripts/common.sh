# SPDX-License-Identifier: BSD-3-Clause
# Sourced by the build scripts.
#   phase NAME command [args...]   runs a named phase and prints its wall time when it
#                                  ends; on exit (success or failure) the outermost script
#                                  that sourced this file prints every phase with the total.
#   configure_build DIR [cmake args...]
#                                  configures a build folder with Ninja when it is installed
#                                  (a folder configured before keeps its generator).

if [ -z "${PLANAR_GRID_PHASES_OWNER:-}" ]; then
  export PLANAR_GRID_PHASES_OWNER=$$
  PLANAR_GRID_PHASES_START=$SECONDS
  PLANAR_GRID_PHASE_NAMES=()
  PLANAR_GRID_PHASE_SECONDS=()
  PLANAR_GRID_PHASE_CURRENT=""
  PLANAR_GRID_PHASE_CURRENT_START=0

  planar_grid_phase_table() {
    local status=$?
    [ "${PLANAR_GRID_PHASES_OWNER}" = "$$" ] || return "$status"
    [ ${#PLANAR_GRID_PHASE_NAMES[@]} -gt 0 ] || [ -n "$PLANAR_GRID_PHASE_CURRENT" ] \
      || return "$status"
    echo
    echo "phase                     wall time"
    local i
    for i in "${!PLANAR_GRID_PHASE_NAMES[@]}"; do
      printf '%-24s %6d s  (%d min %02d s)\n' "${PLANAR_GRID_PHASE_NAMES[$i]}" \
        "${PLANAR_GRID_PHASE_SECONDS[$i]}" $((PLANAR_GRID_PHASE_SECONDS[i] / 60)) \
        $((PLANAR_GRID_PHASE_SECONDS[i] % 60))
    done
    if [ -n "$PLANAR_GRID_PHASE_CURRENT" ]; then
      printf '%-24s %6d s  FAILED\n' "$PLANAR_GRID_PHASE_CURRENT" \
        $((SECONDS - PLANAR_GRID_PHASE_CURRENT_START))
    fi
    local total=$((SECONDS - PLANAR_GRID_PHASES_START))
    printf '%-24s %6d s  (%d min %02d s)\n' "total" "$total" $((total / 60)) $((total % 60))
    return "$status"
  }
  trap planar_grid_phase_table EXIT
fi

phase() {
  local name=$1
  shift
  PLANAR_GRID_PHASE_CURRENT=$name
  PLANAR_GRID_PHASE_CURRENT_START=$SECONDS
  echo "==> $name"
  "$@"
  local elapsed=$((SECONDS - PLANAR_GRID_PHASE_CURRENT_START))
  PLANAR_GRID_PHASE_NAMES+=("$name")
  PLANAR_GRID_PHASE_SECONDS+=("$elapsed")
  PLANAR_GRID_PHASE_CURRENT=""
  echo "==> $name: $elapsed s"
}

configure_build() {
  local dir=$1
  shift
  local generator=()
  if [ ! -f "$dir/CMakeCache.txt" ] && command -v ninja >/dev/null; then
    generator=(-G Ninja)
  fi
  mkdir -p "$dir"
  cmake "${generator[@]}" -S . -B "$dir" "$@" >"$dir/configure.log"
}
