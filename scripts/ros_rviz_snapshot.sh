#!/usr/bin/env bash
# SPDX-License-Identifier: BSD-3-Clause
# RViz's view of planar_grid_ros_node mapping the Karlsruhe sequence live (docs/ROS.md):
# writes the frames to a bag, starts Xvfb, rosmaster (loopback), the node (every frame
# queued), RViz with tools/ros/planar_grid.rviz, plays the bag at 1x, waits for the last
# frame and saves a screenshot of the 3D view. Needs a Release build with the node
# (build/) and Debian's rviz, imagemagick and x11-apps (not installed by install_deps.sh).
#   bash scripts/ros_rviz_snapshot.sh [FRAMES (112)] [OUT (docs/images/ros_rviz_karlsruhe.png)]
set -euo pipefail
cd "$(dirname "$0")/.."
FRAMES=${1:-112}
OUT=${2:-docs/images/ros_rviz_karlsruhe.png}
BUILD_DIR=${BUILD_DIR:-build}
for tool in rviz xwd convert Xvfb rosmaster rosbag; do
  command -v "$tool" >/dev/null || { echo "ros_rviz_snapshot: $tool is not installed" >&2; exit 1; }
done
work=$(mktemp -d "${TMPDIR:-/tmp}/planar_grid_rviz.XXXXXX")
pids=()
cleanup() {
  for pid in "${pids[@]}"; do kill -INT "$pid" 2>/dev/null || true; done
  sleep 1
  for pid in "${pids[@]}"; do kill -KILL "$pid" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
"$BUILD_DIR/tools/ros/planar_grid_write_stereo_bag" --config config/karlsruhe.yaml \
  --frames "$FRAMES" --output "$work/karlsruhe.bag"
/usr/bin/python3 -c "import sys; sys.path.insert(0, 'tools/ros'); import test_ros_node as t; \
t.write_config('config/karlsruhe.yaml', '$work/karlsruhe.bag', '$work/pipeline', '$work/ros.yaml')"
port=$(/usr/bin/python3 -c "import sys; sys.path.insert(0, 'tools/ros'); import test_ros_node as t; print(t.free_port())")
export ROS_MASTER_URI=http://127.0.0.1:$port ROS_IP=127.0.0.1 ROS_HOME=$work/ros_home
display=:$((90 + RANDOM % 100))
Xvfb "$display" -screen 0 1280x860x24 >/dev/null 2>&1 & pids+=($!)
rosmaster --core -p "$port" >/dev/null 2>&1 & pids+=($!)
sleep 3
"$BUILD_DIR/tools/ros/planar_grid_ros_node" __name:=planar_grid "_config:=$work/ros.yaml" \
  _max_queued_frames:=0 >"$work/node.log" 2>&1 & pids+=($!)
DISPLAY=$display rviz -d tools/ros/planar_grid.rviz >"$work/rviz.log" 2>&1 & pids+=($!)
sleep 8
rosbag play --quiet -d 2 "$work/karlsruhe.bag" >/dev/null
# Every frame queued: the node maps the last one well after the bag ends.
/usr/bin/python3 - "$FRAMES" <<'PY'
import json, sys, time
import rospy
from std_msgs.msg import String
frames = int(sys.argv[1])
rospy.init_node("rviz_snapshot", anonymous=True, disable_signals=True)
deadline = time.monotonic() + 180
while time.monotonic() < deadline:
    stats = json.loads(rospy.wait_for_message("/planar_grid/frame_stats", String, 30).data)
    if stats["mapped"] + stats["dropped"] + stats["failed"] >= frames:
        break
PY
# RViz (software GL under Xvfb) takes a few seconds to draw thousands of markers.
sleep 20
DISPLAY=$display xwd -root | convert xwd:- -crop 900x768+364+62 +repage "$OUT"
echo "ros_rviz_snapshot: wrote $OUT"
