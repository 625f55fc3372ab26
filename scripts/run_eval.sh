#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# The paper's evaluation (Sec. IV-B, Figs. 12-14): builds planar_grid_eval and
# planar_grid_render_scene, renders the synthetic stereo scenes, links the Aloe pair and
# writes the poses the real indoor pairs lack (output/eval/prep; the data stays in
# ../shared/data), then runs the indoor, tilt, outdoor, outdoor_live, range_adaptive
# and euroc evaluations (outdoor: Karlsruhe and the KITTI snippet with its ground-truth
# poses; outdoor_live: the same roads, every frame, dense stereo on keyframes;
# range_adaptive: the same two roads with the points beyond eq. 4's bound mapped at
# coarser cells; euroc: the 100 EuRoC V1_01 Vicon room keyframes with their Vicon
# poses). Results in
# output/eval/{indoor,tilt,outdoor,outdoor_live,range_adaptive,euroc}/{eval.csv,eval.md,*.png};
# docs/EVALUATION.md and docs/BENCHMARKS.md quote them. About 45-55 minutes on 2 cores
# (outdoor alone: about 1-2 minutes, outdoor_live about 3, range_adaptive about 9,
# euroc about 1.5).
#
#   bash scripts/run_eval.sh             # all six
#   bash scripts/run_eval.sh outdoor     # only the named ones (indoor, tilt, outdoor,
#                                        # outdoor_live, range_adaptive, euroc)
set -euo pipefail
cd "$(dirname "$0")/.."
# The evaluations to run, checked before anything is built.
EVALS=("$@")
if [ ${#EVALS[@]} -eq 0 ]; then
  EVALS=(indoor tilt outdoor outdoor_live range_adaptive euroc)
fi
for eval in "${EVALS[@]}"; do
  case "$eval" in
    indoor | tilt | outdoor | outdoor_live | range_adaptive | euroc) ;;
    *)
      echo "run_eval.sh: unknown evaluation '$eval' (indoor, tilt, outdoor," \
        "outdoor_live, range_adaptive, euroc)" >&2
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
# EuRoC keyframes: the Vicon poses of the rectified left camera in EuRoC's world (z up,
# the floor near z = 0; TUM lines "t tx ty tz qx qy qz qw") as KITTI rows. The KITTI
# reader takes its world for a level camera's optical frame (x right, y down, z
# forward), so each world_T_camera is written as B world_T_camera with B the fixed
# rotation from EuRoC's world to such a frame (x = -y_w, y = -z_w, z = x_w); the reader
# turns it back into EuRoC's world. The data's own poses.txt has frame 0's camera,
# which looks 21.7 degrees down, as its world: the floor would be tilted by as much.
awk '!/^#/ && NF == 8 {
  tx = $2; ty = $3; tz = $4; x = $5; y = $6; z = $7; w = $8
  n = sqrt(x * x + y * y + z * z + w * w); x /= n; y /= n; z /= n; w /= n
  r00 = 1 - 2 * (y * y + z * z); r01 = 2 * (x * y - z * w); r02 = 2 * (x * z + y * w)
  r10 = 2 * (x * y + z * w); r11 = 1 - 2 * (x * x + z * z); r12 = 2 * (y * z - x * w)
  r20 = 2 * (x * z - y * w); r21 = 2 * (y * z + x * w); r22 = 1 - 2 * (x * x + y * y)
  printf "%.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f %.9f\n",
    -r10, -r11, -r12, -ty, -r20, -r21, -r22, -tz, r00, r01, r02, tx
}' "$DATA/euroc_v1_01_keyframes/poses_left_rect_world_tum.txt" \
  > "$OUT/prep/euroc_keyframes_poses.txt"

for eval in "${EVALS[@]}"; do
  build/tools/planar_grid_eval --config "config/eval_$eval.yaml"
done
