#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""The ROS node against a real ROS master (CTest RosNode.*, docs/ROS.md).

Writes the first frames of a stereo configuration to a bag (images, CameraInfo, poses on
/tf), starts rosmaster on a free loopback port, planar_grid_ros_node with every frame
queued, and `rosbag play` of the bag at 1x (or --rate); checks that every frame is mapped
and each output topic published, saves the map through the node's service, runs
planar_grid_pipeline on the same bag with the same configuration, and compares the two
map.pgmap files byte for byte and the keyframes each made dense (stereo_disparity's
frame_selection). The last octomap_msgs/Octomap messages of ~octomap_binary and
~octomap_full (md5sum and definition upstream's) are rebuilt with liboctomap
(planar_grid_octomap_check) and counted against the node's map.bt, its ~save_map answer
and planar_grid_pipeline's report.json. Prints the latency from a pair's arrival to its
markers (median, 95th percentile), of every frame and of the keyframes.

--parameter NAME runs the node with one of octomap_server's parameters set beside a node
without it on the same bag and checks what the parameter changes, and that bad values
stop the node with an error naming it. Every process is stopped at the end, also on
failure.
"""
import argparse
import json
import os
import re
import signal
import socket
import statistics
import subprocess
import sys
import tempfile
import time

import yaml


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def stop(process, name):
    if process is None or process.poll() is not None:
        return
    process.send_signal(signal.SIGINT)
    try:
        process.wait(timeout=15)
    except subprocess.TimeoutExpired:
        print(f"{name} did not stop on SIGINT within 15 s: killed", file=sys.stderr)
        process.kill()
        process.wait(timeout=15)


def wait_until(condition, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out after {timeout_s} s waiting for {what}")


# octomap_msgs/Octomap's md5sum upstream (octomap_msgs 0.3's generated Octomap.h, and
# what rosbag info shows for recorded octomap topics): the node's must be the same for
# MoveIt and octomap_rviz_plugins to subscribe.
OCTOMAP_MD5SUM = "9a45536b45c5e409cd49f04bb2d9999f"
OCTOMAP_MSG_FILE = os.path.join(os.path.dirname(os.path.abspath(__file__)), "msg",
                                "octomap_msgs", "Octomap.msg")
# The tree counts that liboctomap gives a .bt file, in planar_grid_octomap_check's and
# report.json's names.
TREE_COUNTS = ("nodes", "leaf_nodes", "occupied_leaves", "free_leaves", "occupied_voxels",
               "free_voxels")


class RawTopic:
    """A subscription that keeps the serialized bytes of the last message, its
    connection header and the number received (rospy has no octomap_msgs module)."""

    def __init__(self, topic):
        import rospy
        self.topic = topic
        self.count = 0
        self.last = None
        self.connection_header = None
        self.subscriber = rospy.Subscriber(topic, rospy.AnyMsg, self._keep)

    def _keep(self, msg):
        self.last = bytes(msg._buff)
        self.connection_header = msg._connection_header
        self.count += 1


def check_octomaps(args, work, binary, full=None, bt=None, occupancy_thres=0.5):
    """planar_grid_octomap_check on serialized messages and a .bt file: its JSON."""
    command = [args.octomap_check, "--occupancy-thres", str(occupancy_thres)]
    for name, data in (("binary", binary), ("full", full)):
        if data is not None:
            path = os.path.join(work, f"octomap_{name}.msg")
            with open(path, "wb") as f:
                f.write(data)
            command += [f"--{name}-msg", path]
    if bt is not None:
        command += ["--bt", bt]
    result = subprocess.run(command, check=True, timeout=120, stdout=subprocess.PIPE,
                            text=True)
    return json.loads(result.stdout)


def wait_for_octomaps(args, work, topics, stamp, timeout_s=60, **kwargs):
    """Waits until the last message of each raw OctoMap topic (binary, full) carries
    \a stamp (the last mapped frame's): planar_grid_octomap_check's JSON of them."""
    deadline = time.monotonic() + timeout_s
    checked = None
    while time.monotonic() < deadline:
        if all(t.last is not None for t in topics):
            checked = check_octomaps(args, work, topics[0].last,
                                     topics[1].last if len(topics) > 1 else None, **kwargs)
            kinds = ["binary", "full"][:len(topics)]
            if all(abs(checked[k]["stamp"] - stamp) < 1e-6 for k in kinds):
                return checked
        time.sleep(0.5)
    raise AssertionError(f"timed out after {timeout_s} s waiting for the OctoMaps of the "
                         f"frame stamped {stamp:.3f} (last: {checked})")


def occupancy_thres_of(config_path):
    """map_integration's occupancy_thres in the configuration (its default 0.5)."""
    with open(config_path) as f:
        config = yaml.safe_load(f)
    for stage in config.get("pipeline", []):
        if stage.get("type") == "map_integration":
            return float((stage.get("params") or {}).get("occupancy_thres", 0.5))
    return 0.5


def assert_upstream_octomap_type(topic):
    """The topic's connection carries upstream's octomap_msgs/Octomap: its type, its
    md5sum and its definition (the .msg file, then std_msgs/Header's)."""
    header = topic.connection_header
    assert header["type"] == "octomap_msgs/Octomap", f"{topic.topic}: {header['type']}"
    assert header["md5sum"] == OCTOMAP_MD5SUM, (
        f"{topic.topic}: md5sum {header['md5sum']}, upstream's {OCTOMAP_MD5SUM}")
    with open(OCTOMAP_MSG_FILE) as f:
        text = f.read()
    definition = header["message_definition"]
    assert definition.startswith(text) and "\nMSG: std_msgs/Header\n" in definition, (
        f"{topic.topic}: the definition differs from {OCTOMAP_MSG_FILE}: {definition!r}")


def assert_octomaps_equal_bt(checked, frame_id, resolution):
    """The binary message's tree is the .bt file's (counts and data section, byte for
    byte), the full message's tree in maximum likelihood too, both in frame_id at the
    resolution (meters)."""
    bt = checked["bt"]
    for kind in ("binary", "full"):
        msg = checked[kind]
        assert msg["frame_id"] == frame_id, f"~octomap_{kind}: frame {msg['frame_id']}"
        assert msg["id"] == "OcTree" and msg["binary"] == (kind == "binary"), msg
        assert abs(msg["resolution"] - resolution) < 1e-9, msg
    for name in TREE_COUNTS:
        assert checked["binary"][name] == bt[name], (
            f"~octomap_binary's tree has {name} {checked['binary'][name]}, map.bt "
            f"{bt[name]}")
        assert checked["full_max_likelihood"][name] == bt[name], (
            f"~octomap_full's tree in maximum likelihood has {name} "
            f"{checked['full_max_likelihood'][name]}, map.bt {bt[name]}")
    assert checked["binary_data_equals_bt"], "~octomap_binary's data differ from map.bt's"
    assert checked["full"]["leaf_nodes"] >= checked["binary"]["leaf_nodes"] > 0


def saved_octomap_counts(message):
    """The map.bt counts in ~save_map's answer."""
    found = re.search(r"map\.bt: (\d+) nodes, (\d+) leaves, (\d+) occupied, (\d+) free",
                      message)
    assert found, f"no map.bt counts in ~save_map's answer: {message}"
    return dict(zip(("nodes", "leaf_nodes", "occupied_leaves", "free_leaves"),
                    map(int, found.groups())))


def write_config(source_config, bag, output_folder, path):
    with open(source_config) as f:
        config = yaml.safe_load(f)
    config["input"] = {
        "type": "ros_bag",
        "file": bag,
        "left_image": "/stereo/left/image_rect",
        "right_image": "/stereo/right/image_rect",
        "left_camera_info": "/stereo/left/camera_info",
        "right_camera_info": "/stereo/right/camera_info",
        "poses": {"format": "tf", "parent_frame": "world", "child_frame": "camera"},
    }
    config["output"] = {"folder": output_folder, "map": "map.pgmap", "report": "report.json"}
    with open(path, "w") as f:
        yaml.safe_dump(config, f, sort_keys=False)


def prepare(args, prefix, frames, parent_frame="world"):
    """A work folder with a bag of the configuration's first frames (their poses on /tf
    as parent_frame -> camera), the node's YAML for it (poses from world to camera),
    and the environment of a ROS master on a free loopback port (also set in this
    process, for rospy): (work, bag, config, env, port)."""
    work = tempfile.mkdtemp(prefix=prefix)
    bag = os.path.join(work, "pairs.bag")
    subprocess.run([args.write_bag, "--config", args.config, "--frames", str(frames),
                    "--output", bag, "--parent-frame", parent_frame], check=True,
                   timeout=120)
    config = os.path.join(work, "ros.yaml")
    write_config(args.config, bag, os.path.join(work, "pipeline"), config)
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1",
               ROS_HOME=os.path.join(work, "ros_home"), ROS_LOG_DIR=os.path.join(work, "log"))
    os.environ.update(env)
    return work, bag, config, env, port


def start_master(env, port):
    """rosmaster --core on the port, once it answers."""
    import rosgraph
    master = subprocess.Popen(["rosmaster", "--core", "-p", str(port)], env=env,
                              stdout=subprocess.DEVNULL, stderr=subprocess.STDOUT)
    wait_until(lambda: rosgraph.Master("/planar_grid_test").is_online(), 30,
               f"rosmaster on 127.0.0.1:{port}")
    return master


def stop_while_waiting_for_tf(args):
    """The node waits for a pose that never comes (no /tf, ~tf_timeout 86400 s); SIGINT
    must still stop it within seconds, with status 0."""
    work, bag, config, env, port = prepare(args, "planar_grid_ros_stop_", 3)
    import rospy
    from std_msgs.msg import String

    master = node = player = None
    try:
        master = start_master(env, port)
        node = subprocess.Popen([args.node, "__name:=planar_grid", f"_config:={config}",
                                 "_tf_timeout:=86400"], env=env)
        rospy.init_node("planar_grid_test", anonymous=True, disable_signals=True)
        stats = []
        subscriber = rospy.Subscriber("/planar_grid/frame_stats", String, stats.append)
        wait_until(lambda: subscriber.get_num_connections() > 0, 30,
                   "the subscription to the node's frame_stats")
        player = subprocess.Popen(
            ["rosbag", "play", "--quiet", bag, "--topics", "/stereo/left/image_rect",
             "/stereo/right/image_rect", "/stereo/left/camera_info",
             "/stereo/right/camera_info"], env=env, stdout=subprocess.DEVNULL)
        player.wait(timeout=60)
        time.sleep(1.0)  # the node now waits for the first pair's pose
        assert node.poll() is None, f"the node exited early ({node.returncode})"
        assert not stats, "a frame was mapped without its pose"
        started = time.monotonic()
        node.send_signal(signal.SIGINT)
        node.wait(timeout=10)
        stopped_s = time.monotonic() - started
        assert node.returncode == 0, f"the node exited {node.returncode} on SIGINT"
        print(f"the node stopped {stopped_s:.2f} s after SIGINT while waiting for TF")
    finally:
        stop(player, "rosbag play")
        stop(node, "planar_grid_ros_node")
        rospy.signal_shutdown("test done") if "rospy" in sys.modules else None
        stop(master, "rosmaster")
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


def main():
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--node", required=True)
    parser.add_argument("--pipeline", required=True)
    parser.add_argument("--write-bag", required=True)
    parser.add_argument("--octomap-check",
                        help="planar_grid_octomap_check (default: beside --node)")
    parser.add_argument("--config", required=True)
    parser.add_argument("--frames", type=int, default=30)
    parser.add_argument("--max-queued-frames", type=int, default=0,
                        help="the node's ~max_queued_frames; above 0 frames may be "
                        "dropped, and only the latency is measured (no map comparison)")
    parser.add_argument("--rate", type=float, default=1.0,
                        help="rosbag play's rate (1: the recording's pace)")
    parser.add_argument("--cpu", type=int, default=-1,
                        help="pin the node to this CPU (taskset -c); -1: not pinned")
    parser.add_argument("--stop-while-waiting-for-tf", action="store_true",
                        help="instead: play the pairs without /tf to the node with a "
                        "~tf_timeout of a day, send SIGINT, and check that it exits at "
                        "once with status 0")
    parser.add_argument("--keep", action="store_true",
                        help="keep the work folder (bag, configuration, maps)")
    args = parser.parse_args()
    if args.octomap_check is None:
        args.octomap_check = os.path.join(os.path.dirname(args.node),
                                          "planar_grid_octomap_check")
    if args.stop_while_waiting_for_tf:
        stop_while_waiting_for_tf(args)
        return
    measure_only = args.max_queued_frames > 0

    work, bag, config, env, port = prepare(args, "planar_grid_ros_", args.frames)
    import rospy
    from nav_msgs.msg import OccupancyGrid
    from sensor_msgs.msg import PointCloud2
    from std_msgs.msg import String
    from std_srvs.srv import Trigger
    from visualization_msgs.msg import MarkerArray

    master = node = player = None
    try:
        master = start_master(env, port)
        node_folder = os.path.join(work, "node")
        pin = ["taskset", "-c", str(args.cpu)] if args.cpu >= 0 else []
        node = subprocess.Popen(pin + [args.node, "__name:=planar_grid", f"_config:={config}",
                                 f"_max_queued_frames:={args.max_queued_frames}",
                                 f"_output_folder:={node_folder}"],
                                env=env)
        rospy.init_node("planar_grid_test", anonymous=True, disable_signals=True)
        received = {"cuboids": [], "occupied_cells": [], "map_2d": [], "frame_stats": []}

        def keep(name):
            return lambda msg: received[name].append(msg)

        # Measuring, the map topics are taken as raw bytes: rospy's deserialization of
        # thousands of markers would take the CPU from the node on a 2-core machine.
        def message_type(t):
            return rospy.AnyMsg if measure_only else t

        subscribers = [
            rospy.Subscriber("/planar_grid/cuboids", message_type(MarkerArray), keep("cuboids")),
            rospy.Subscriber("/planar_grid/occupied_cells", message_type(PointCloud2),
                             keep("occupied_cells")),
            rospy.Subscriber("/planar_grid/map_2d", message_type(OccupancyGrid), keep("map_2d")),
            rospy.Subscriber("/planar_grid/frame_stats", String, keep("frame_stats")),
        ]
        # The OctoMaps, as MoveIt and octomap_rviz_plugins take them (not when
        # measuring the latency).
        octomaps = [] if measure_only else [RawTopic("/planar_grid/octomap_binary"),
                                            RawTopic("/planar_grid/octomap_full")]
        subscribers += [t.subscriber for t in octomaps]
        rospy.wait_for_service("/planar_grid/save_map", timeout=60)
        wait_until(lambda: all(s.get_num_connections() > 0 for s in subscribers), 30,
                   "the test's subscriptions to the node's topics")

        started = time.monotonic()
        player = subprocess.Popen(["rosbag", "play", "--quiet", "-d", "2", "-r",
                                   str(args.rate), bag], env=env, stdout=subprocess.DEVNULL)
        player.wait(timeout=120)
        assert player.returncode == 0, f"rosbag play exited {player.returncode}"
        played_s = time.monotonic() - started - 2.0

        def last_stats():
            return json.loads(received["frame_stats"][-1].data) if received["frame_stats"] else {}

        wait_until(lambda: last_stats().get("mapped", 0) + last_stats().get("failed", 0)
                   + last_stats().get("dropped", 0) >= args.frames, 180,
                   f"the node to map {args.frames} frames")
        stats = [json.loads(m.data) for m in received["frame_stats"]]
        final = stats[-1]
        assert final["failed"] == 0, f"{final['failed']} frames failed: {final}"
        if not measure_only:
            assert final["dropped"] == 0, f"{final['dropped']} frames dropped: {final}"
            assert final["mapped"] == args.frames, final
            assert final["unpaired"] == 0, f"{final['unpaired']} left images unpaired"
            assert len(stats) == args.frames, f"{len(stats)} frame_stats for {args.frames} frames"
        for name, messages in received.items():
            assert messages, f"nothing published on /planar_grid/{name}"
        if not measure_only:
            # Each topic has its own connection: the last frame's markers may come after
            # its statistics.
            def cubes():
                markers = received["cuboids"][-1].markers
                return [m for m in markers if m.action == m.ADD]

            wait_until(lambda: len(cubes()) == final["map_cuboids"], 30,
                       f"the last frame's {final['map_cuboids']} cuboid markers "
                       f"(last message: {len(cubes())})")
            assert received["occupied_cells"][-1].width > 0
            grid = received["map_2d"][-1]
            assert grid.info.width * grid.info.height == len(grid.data) > 0
            assert any(v == 100 for v in grid.data) and any(v == 0 for v in grid.data)
        response = rospy.ServiceProxy("/planar_grid/save_map", Trigger)()
        assert response.success, response.message
        print("save_map:", response.message)
        if not measure_only:
            # The map no longer changes: the OctoMaps of the last frame are map.bt's tree.
            stamp = received["cuboids"][-1].markers[0].header.stamp.to_sec()
            octomap = wait_for_octomaps(args, work, octomaps, stamp,
                                        bt=os.path.join(node_folder, "map.bt"),
                                        occupancy_thres=occupancy_thres_of(config))
            for topic in octomaps:
                assert_upstream_octomap_type(topic)
            assert_octomaps_equal_bt(octomap, "world", 0.1)
            saved = saved_octomap_counts(response.message)
            assert saved == {k: octomap["bt"][k] for k in saved}, (saved, octomap["bt"])
            print(f"~octomap_binary ({octomaps[0].count} messages) and ~octomap_full "
                  f"({octomaps[1].count}): upstream's md5sum {OCTOMAP_MD5SUM}; the last "
                  f"rebuilt with liboctomap: {octomap['binary']['nodes']} nodes, "
                  f"{octomap['binary']['leaf_nodes']} leaves "
                  f"({octomap['binary']['occupied_leaves']} occupied), "
                  f"{octomap['binary']['data_bytes']} bytes / "
                  f"{octomap['full']['leaf_nodes']} leaves, "
                  f"{octomap['full']['data_bytes']} bytes: map.bt's tree; both "
                  f"published in {final['last_octomap_ms']:.1f} ms")

        def summary(values):
            values = sorted(values)
            if not values:
                return "none"
            p95 = values[min(len(values) - 1, int(round(0.95 * (len(values) - 1))))]
            return (f"median {statistics.median(values):.1f} ms, p95 {p95:.1f} ms, "
                    f"max {values[-1]:.1f} ms")

        keyframe_stats = [s for s in stats if s.get("keyframe", True)]
        print(f"{args.frames} frames played in {played_s:.1f} s at rate {args.rate}; mapped "
              f"{final['mapped']} ({final['keyframes']} keyframes), dropped "
              f"{final['dropped']}, unpaired {final['unpaired']}; arrival -> markers latency: "
              f"{summary(s['latency_ms'] for s in stats)}; of the keyframes: "
              f"{summary(s['latency_ms'] for s in keyframe_stats)}; mapping {statistics.mean(s['total_ms'] for s in stats):.1f}"
              f" ms a frame, publishing {statistics.mean(s['publish_ms'] for s in stats):.1f} ms"
              f" (markers {statistics.mean(s['cuboids_ms'] for s in stats):.1f}); the publisher"
              f" thread's last occupied cells {final['last_occupied_cells_ms']:.1f} ms, 2D map"
              f" {final['last_map_2d_ms']:.1f} ms;"
              f" final map {final['map_cuboids']} cuboids")
    finally:
        stop(player, "rosbag play")
        stop(node, "planar_grid_ros_node")
        rospy.signal_shutdown("test done") if "rospy" in sys.modules else None
        stop(master, "rosmaster")
    assert node.returncode == 0, f"planar_grid_ros_node exited {node.returncode}"
    if measure_only:
        if not args.keep:
            subprocess.run(["rm", "-rf", work], check=False)
        return

    subprocess.run([args.pipeline, "--config", config, "--no-snapshot"], check=True,
                   timeout=600, stdout=subprocess.DEVNULL)
    with open(os.path.join(work, "node", "map.pgmap"), "rb") as f:
        node_map = f.read()
    with open(os.path.join(work, "pipeline", "map.pgmap"), "rb") as f:
        pipeline_map = f.read()
    assert len(node_map) > 1000
    assert node_map == pipeline_map, (
        f"the node's map.pgmap ({len(node_map)} bytes) differs from planar_grid_pipeline's "
        f"({len(pipeline_map)} bytes); both in {work}")
    print("the node's map.pgmap equals planar_grid_pipeline's, byte for byte")
    with open(os.path.join(work, "pipeline", "report.json")) as f:
        report = json.load(f)
    stereo = [s for s in report["stages"] if s["type"] == "stereo_disparity"]
    pipeline_keyframes = int(stereo[0]["dense_frames"]) if stereo else args.frames
    assert final["keyframes"] == pipeline_keyframes, (
        f"the node made {final['keyframes']} frames dense, planar_grid_pipeline "
        f"{pipeline_keyframes}")
    assert sum(1 for s in stats if s["keyframe"]) == pipeline_keyframes
    print(f"both made the same {pipeline_keyframes} of {args.frames} frames dense")
    for name in TREE_COUNTS:
        assert report["map_octomap"][name] == octomap["binary"][name], (
            f"report.json's map_octomap {name} {report['map_octomap'][name]}, the node's "
            f"~octomap_binary {octomap['binary'][name]}")
    print("the OctoMap messages' counts equal report.json's map_octomap")
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


if __name__ == "__main__":
    main()
