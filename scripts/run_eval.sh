#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The paper's evaluation (Sec. IV-B, Figs. 12-14): builds planar_grid_eval and
# planar_grid_render_scene, renders the synthetic stereo scenes, links the Aloe pair and
# writes the poses the real indoor pairs lack (output/eval/prep; the data stays in
# ../shared/data), then runs the indoor, tilt, outdoor and range_adaptive evaluations
# (outdoor: Karlsruhe and the KITTI snippet with its ground-truth poses; range_adaptive:
# the same two roads with the points beyond eq. 4's bound mapped at coarser cells).
# Results in output/eval/{indoor,tilt,outdoor,range_adaptive}/{eval.csv,eval.md,*.png};
# docs/EVALUATION.md quotes them. About 30-40 minutes on 2 cores (outdoor alone: about
# 1-2 minutes, range_adaptive about 9).
#
#   bash scripts/run_eval.sh             # all four
#   bash scripts/run_eval.sh outdoor     # only the named ones (indoor, tilt, outdoor,
#                                        # range_adaptive)
set -euo pipefail
cd "$(dirname "$0")/.."
# The evaluations to run, checked before anything is built.
EVALS=("$@")
if [ ${#EVALS[@]} -eq 0 ]; then
  EVALS=(indoor tilt outdoor range_adaptive)
fi
for eval in "${EVALS[@]}"; do
  case "$eval" in
    indoor | tilt | outdoor | range_adaptive) ;;
    *)
      echo "run_eval.sh: unknown evaluation '$eval' (indoor, tilt, outdoor," \
        "range_adaptive)" >&2
      exit 1
      ;;
  esac
done
bash scripts/install_deps.sh
cmake -S . -B build -DCMAKE_BUILD_TYPE=Release > /dev/null
cmake --build build -j2 --target planar_grid_eval_tool planar_grid_render_scene
DATA=$(cd ../shared/data && pwd)
OUT=output/eval
mkdir -p "$OUT/synthetic" "$OUT/prep/aloe/left" "$OUT/prep/aloe/right"

# Synthetic scenes with exact surfaces (docs/SYNTHETIC_SCENE.md), for indoor and tilt
# only (the outdoor datasets read ../shared/data alone).
if [[ " ${EVALS[*]} " == *" indoor "* || " ${EVALS[*]} " == *" tilt "* ]]; then
  for yaw in 0 15 30 45; do
    build/tools/planar_grid_render_scene --scene corridor --frames 20 --yaw-deg "$yaw" \
      --output "$OUT/synthetic/corridor_yaw$yaw"
  done
  build/tools/planar_grid_render_scene --scene room --frames 20 --lean-deg 15 \
    --output "$OUT/synthetic/room_lean15"
fi

# Aloe: the pair as frame 0, a calibration (f = 3740 px, B = 0.16 m, centre), identity pose.
ln -sf "$DATA/middlebury_aloe/aloeL.jpg" "$OUT/prep/aloe/left/0.jpg"
ln -sf "$DATA/middlebury_aloe/aloeR.jpg" "$OUT/prep/aloe/right/0.jpg"
cat > "$OUT/prep/aloe/calib.txt" <<CALIB
calib_time: derived for planar_grid_eval (Middlebury 2006 focal length and baseline)
P1_roi: 3740 0 640.5 0 0 3740 554.5 0 0 0 1 0
P2_roi: 3740 0 640.5 -598.4 0 3740 554.5 0 0 0 1 0
CALIB
# KITTI files hold poses in KITTI's world, the first camera's optical frame (x right,
# y down, z forward); the reader turns them to the z-up world (docs/INPUTS.md).
# Aloe: the world is the camera frame itself (z-up world_T_camera = identity).
echo "0 -1 0 0 0 0 -1 0 1 0 0 0" > "$OUT/prep/aloe/poses.txt"
# rtabmap pair 50: a level camera 1.2 m above the floor (z-up world: camera z along +x,
# 1.2 m up); the KITTI file needs a line per index up to 50.
for _ in $(seq 0 50); do echo "1 0 0 0 0 1 0 -1.2 0 0 1 0"; done > "$OUT/prep/rtabmap_poses.txt"

for eval in "${EVALS[@]}"; do
  build/tools/planar_grid_eval --config "config/eval_$eval.yaml"
done
