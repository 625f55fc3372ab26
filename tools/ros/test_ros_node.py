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
stop the node with an error naming it.

--stereo-launch FILE starts planar_grid_stereo.launch with roslaunch (its configuration,
--stereo-config, has a visual_odometry stage) on a bag of the frames' images and
CameraInfos alone, and checks the poses the node estimated on /tf and ~odometry (one per
frame, the image's stamp) against planar_grid_pipeline's on the same bag, their RTE
against the sequence's ground truth (planar_grid_trajectory_check) and the two maps.

Every process is stopped at the end, also on failure.
"""
import argparse
import json
import os
import re
import signal
import socket
import statistics
import struct
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


def stop_all(player, processes, master):
    """Stops rosbag play, then each (process, name) of processes, this process's rospy
    node if it started one, and the rosmaster last (the nodes unregister from it on
    their way out)."""
    stop(player, "rosbag play")
    for process, name in processes:
        stop(process, name)
    if "rospy" in sys.modules:
        sys.modules["rospy"].signal_shutdown("test done")
    stop(master, "rosmaster")


def wait_until(condition, timeout_s, what):
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if condition():
            return
        time.sleep(0.1)
    raise AssertionError(f"timed out after {timeout_s} s waiting for "
                         f"{what() if callable(what) else what}")


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
        stop_all(player, [(node, "planar_grid_ros_node")], master)
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


# octomap_server's parameters the node takes (docs/ROS.md), one test each: what the
# variant node gets, and values the node must reject, with a part of its error.
PARAMETERS = {
    "frame_id": ({"frame_id": "map_test"},
                 [({"frame_id": "map_test", "fixed_frame": "odom"},
                   "both name the map's frame and differ"),
                  ({"frame_id": 3}, "~frame_id must be a string")]),
    "resolution": ({"resolution": 0.2},
                   [({"resolution": 0.0}, "~resolution must be in [0.001, 10] m"),
                    ({"resolution": "fine"}, "~resolution must be a number")]),
    "max_range": ({"sensor_model/max_range": 5},
                  [({"sensor_model/max_range": -1.0},
                    "~sensor_model/max_range must be in (0, 1000] m")]),
    "height_band": ({"pointcloud_min_z": 2.5, "pointcloud_max_z": 4.0},
                    [({"pointcloud_min_z": 2.0, "pointcloud_max_z": 1.0},
                      "below ~pointcloud_max_z"),
                     ({"pointcloud_max_z": 5000.0},
                      "~pointcloud_max_z must be in [-1000, 1000] m")]),
    "latch": ({"latch": False}, [({"latch": "maybe"}, "~latch must be true or false")]),
    "octomap_period": ({"octomap_period": 0.0},
                       [({"octomap_period": -1.0}, "~octomap_period >= 0")]),
}


def param_arg(name, value):
    """A private parameter on the node's command line (_name:=value, read as YAML)."""
    if isinstance(value, bool):
        value = "true" if value else "false"
    return f"_{name}:={value}"


class NodeRun:
    """A planar_grid_ros_node under \a name with private parameters, its log, and the
    test's subscriptions to its frame statistics, 2D map and binary OctoMap. Every frame
    is kept (~max_queued_frames 0) and waits up to 2 s for its pose (~tf_timeout), so a
    busy machine delays frames but fails none."""

    def __init__(self, args, env, work, config, name, params):
        import rospy
        from nav_msgs.msg import OccupancyGrid
        from std_msgs.msg import String
        self.name = name
        self.folder = os.path.join(work, name)
        self.log_path = os.path.join(work, f"{name}.log")
        self.stats = []
        self.grids = []
        with open(self.log_path, "w") as log:
            self.process = subprocess.Popen(
                [args.node, f"__name:={name}", f"_config:={config}", "_max_queued_frames:=0",
                 "_tf_timeout:=2.0", f"_output_folder:={self.folder}"]
                + [param_arg(k, v) for k, v in params.items()],
                env=env, stdout=log, stderr=subprocess.STDOUT)
        self.subscribers = [
            rospy.Subscriber(f"/{name}/frame_stats", String,
                             lambda m: self.stats.append(json.loads(m.data))),
            rospy.Subscriber(f"/{name}/map_2d", OccupancyGrid, self.grids.append),
        ]
        self.octomap = RawTopic(f"/{name}/octomap_binary")
        self.subscribers.append(self.octomap.subscriber)

    def log(self):
        with open(self.log_path) as f:
            return f.read()

    def mapped(self):
        return self.stats[-1]["mapped"] if self.stats else 0

    def last_stats(self):
        """The frame counts of the last frame statistics, for a failure message."""
        if not self.stats:
            return f"{self.name}: no frame statistics"
        last = self.stats[-1]
        return f"{self.name}: " + ", ".join(f"{key} {last.get(key)}" for key in
                                            ("received", "mapped", "failed", "dropped"))

    def last_grid(self, stamp, timeout_s=30):
        """The 2D map of the frame stamped \a stamp (the last), once it came."""
        wait_until(lambda: self.grids and abs(self.grids[-1].header.stamp.to_sec() - stamp)
                   < 1e-6, timeout_s, f"{self.name}'s 2D map of the last frame")
        return self.grids[-1]


def expect_rejected(args, env, config, params, expected):
    """The node started with \a params exits with status 1 and \a expected in its
    error, within 30 s."""
    result = subprocess.run([args.node, "__name:=planar_grid_rejected", f"_config:={config}"]
                            + [param_arg(k, v) for k, v in params.items()], env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True,
                            timeout=30)
    assert result.returncode == 1 and expected in result.stdout, (
        f"with {params} the node exited {result.returncode}; expected '{expected}' in: "
        f"{result.stdout}")
    print(f"rejected {params}: ...{expected}...")


def count_messages(seconds, topics):
    """--count-messages: a subscriber that comes late, in its own process: prints the
    messages each topic gave within \a seconds as JSON."""
    import rospy
    rospy.init_node("planar_grid_late_subscriber", anonymous=True, disable_signals=True)
    counts = {t: 0 for t in topics}

    def keep(topic):
        def count(_):
            counts[topic] += 1
        return count

    subscribers = [rospy.Subscriber(t, rospy.AnyMsg, keep(t)) for t in topics]
    time.sleep(seconds)
    for subscriber in subscribers:
        subscriber.unregister()
    print(json.dumps(counts))
    rospy.signal_shutdown("counted")


def late_subscriber_counts(env, topics, seconds=3.0):
    result = subprocess.run([sys.executable, os.path.abspath(__file__), "--count-messages",
                             str(seconds)] + topics, env=env, stdout=subprocess.PIPE,
                            text=True, timeout=60, check=True)
    return json.loads(result.stdout.strip().splitlines()[-1])


def parameter_test(args):
    """One of octomap_server's parameters (--parameter): a node with it set and a node
    without it map the same bag; checks what it changes, that the start-up line prints
    it, and that bad values stop the node with an error naming the parameter."""
    name = args.parameter
    variant_params, rejected = PARAMETERS[name]
    # For frame_id, the poses come from map_test, which the configuration does not name.
    parent_frame = "map_test" if name == "frame_id" else "world"
    work, bag, config, env, port = prepare(args, f"planar_grid_ros_{name}_", args.frames,
                                           parent_frame)
    import rosbag
    import rospy
    with rosbag.Bag(bag) as recorded:
        last_stamp = max(m.header.stamp.to_sec() for _, m, _ in
                         recorded.read_messages(topics=["/stereo/left/image_rect"]))
    master = player = None
    nodes = []
    try:
        master = start_master(env, port)
        for params, expected in rejected:
            expect_rejected(args, env, config, params, expected)
        rospy.init_node("planar_grid_test", anonymous=True, disable_signals=True)
        nodes = [NodeRun(args, env, work, config, "planar_grid_default", {}),
                 NodeRun(args, env, work, config, "planar_grid_variant", variant_params)]
        default, variant = nodes
        wait_until(lambda: all(s.get_num_connections() > 0 for n in nodes
                               for s in n.subscribers), 60,
                   "the test's subscriptions to the nodes' topics")
        player = subprocess.Popen(["rosbag", "play", "--quiet", "-d", "2", bag], env=env,
                                  stdout=subprocess.DEVNULL)
        player.wait(timeout=120)
        assert player.returncode == 0, f"rosbag play exited {player.returncode}"
        wait_until(lambda: variant.mapped() == args.frames, 120,
                   f"the variant node to map {args.frames} frames")
        variant_grid = variant.last_grid(last_stamp)
        variant_octomap = wait_for_octomaps(args, work, [variant.octomap], last_stamp)
        # The start-up line with the effective values, read once the node has ended
        # (its stdout, a file here, is flushed then).
        printed = []
        if name == "frame_id":
            # The default node looks for world -> camera, which the bag does not have.
            wait_until(lambda: default.log().count("planar_grid_ros_node: frame ")
                       >= args.frames, 60,
                f"the default node to fail {args.frames} frames")
            assert not default.stats, "the default node mapped frames without world"
            assert variant_grid.header.frame_id == "map_test", variant_grid.header
            assert variant_octomap["binary"]["frame_id"] == "map_test", variant_octomap
            printed.append("frame_id map_test (~frame_id)")
            print(f"~frame_id map_test: {args.frames} frames mapped in map_test, the 2D "
                  f"map and the OctoMap in map_test; without it all {args.frames} failed "
                  f"(no TF from the configuration's world)")
        else:
            wait_until(lambda: default.mapped() == args.frames, 120,
                       f"the default node to map {args.frames} frames")
            default_grid = default.last_grid(last_stamp)
            default_octomap = wait_for_octomaps(args, work, [default.octomap], last_stamp)
            d, v = default_octomap["binary"], variant_octomap["binary"]
            if name == "resolution":
                assert abs(v["resolution"] - 0.2) < 1e-9 and abs(d["resolution"] - 0.1) < 1e-9
                assert abs(variant_grid.info.resolution - 0.2) < 1e-6, variant_grid.info
                assert abs(default_grid.info.resolution - 0.1) < 1e-6, default_grid.info
                assert v["leaf_nodes"] < d["leaf_nodes"], (v, d)
                printed.append("resolution 0.2 m (~resolution)")
                print(f"~resolution 0.2: the OctoMap's tree at 0.2 m with {v['leaf_nodes']} "
                      f"leaves (0.1 m and {d['leaf_nodes']} without), the 2D map's cells "
                      f"0.2 m")
            elif name == "max_range":
                assert v["free_voxels"] < d["free_voxels"], (v, d)
                printed.append("sensor_model/max_range 5 m (~sensor_model/max_range)")
                print(f"~sensor_model/max_range 5: {v['free_voxels']} free voxels in the "
                      f"OctoMap ({d['free_voxels']} with the configuration's 25 m)")
            elif name == "height_band":
                def occupied(grid):
                    return sum(1 for c in grid.data if c == 100)
                assert occupied(variant_grid) != occupied(default_grid), (
                    occupied(variant_grid), occupied(default_grid))
                printed.append("pointcloud_min_z 2.5 m, pointcloud_max_z 4 m")
                print(f"~pointcloud_min_z 2.5, ~pointcloud_max_z 4: {occupied(variant_grid)} "
                      f"occupied cells in the 2D map ({occupied(default_grid)} in the "
                      f"configuration's 0.3-2.0 m band)")
            elif name == "latch":
                assert variant.octomap.count > 0 and variant.grids, "the variant published"
                topics = [f"/{n.name}/{t}" for n in nodes for t in ("octomap_binary",
                                                                     "map_2d")]
                late = late_subscriber_counts(env, topics)
                for t in ("octomap_binary", "map_2d"):
                    assert late[f"/planar_grid_default/{t}"] == 1, late
                    assert late[f"/planar_grid_variant/{t}"] == 0, late
                printed.append("latch false")
                print(f"~latch false: a subscriber that comes after the last frame gets "
                      f"nothing in 3 s ({late}); latched (the default) the last message")
            elif name == "octomap_period":
                assert variant.octomap.count > default.octomap.count, (
                    variant.octomap.count, default.octomap.count)
                print(f"~octomap_period 0: {variant.octomap.count} OctoMaps for "
                      f"{args.frames} frames ({default.octomap.count} with the default "
                      f"2 s)")
    finally:
        stop_all(player, [(node.process, node.name) for node in nodes], master)
    for node in nodes:
        assert node.process.returncode == 0, f"{node.name} exited {node.process.returncode}"
    effective = [line for line in variant.log().splitlines()
                 if "planar_grid_ros_node: frame_id" in line]
    assert effective, f"no start-up line of the parameters in {variant.log_path}"
    for text in printed:
        assert text in effective[0], f"'{text}' not in the start-up line {effective[0]}"
    print("the variant printed:",
          re.sub(r"\x1b\[[0-9;]*m", "", effective[0]).split("planar_grid_ros_node: ")[-1])
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


def dynamic_reconfigure_test(args):
    """dynamic_reconfigure (--dynamic-reconfigure): a node (planar_grid_live) whose
    parameters change while it maps, beside a node started with the 2D band it gets
    (planar_grid_band). The server reports the values the node runs with; after the
    first half of the frames publish_every 1000 and octomap_period 3600 stop its cuboid
    markers and OctoMaps for the second half (the other node publishes the last frame's
    OctoMap); a band upside down is refused; the band of the other node makes the live
    node publish, without a new frame, the other node's 2D map cell for cell."""
    work, bag, config, env, port = prepare(args, "planar_grid_ros_reconfigure_",
                                           args.frames)
    import rosbag
    import rospy
    from dynamic_reconfigure.client import Client
    with rosbag.Bag(bag) as recorded:
        stamps = sorted(m.header.stamp.to_sec() for _, m, _ in
                        recorded.read_messages(topics=["/stereo/left/image_rect"]))
        start = recorded.get_start_time()
    half = args.frames // 2
    # rosbag play's offsets (s from the bag's start): the first half, then the rest.
    split_s = (stamps[half - 1] + stamps[half]) / 2 - start
    band = {"pointcloud_min_z": 2.5, "pointcloud_max_z": 4.0}
    master = player = None
    nodes = []
    try:
        master = start_master(env, port)
        rospy.init_node("planar_grid_test", anonymous=True, disable_signals=True)
        nodes = [NodeRun(args, env, work, config, "planar_grid_live", {}),
                 NodeRun(args, env, work, config, "planar_grid_band", band)]
        live, fixed = nodes
        cuboids = RawTopic("/planar_grid_live/cuboids")
        wait_until(lambda: cuboids.subscriber.get_num_connections() > 0
                   and all(s.get_num_connections() > 0 for n in nodes
                           for s in n.subscribers), 60,
                   "the test's subscriptions to the nodes' topics")
        client = Client("/planar_grid_live", timeout=30)
        started = client.get_configuration(timeout=30)
        expected = {"pointcloud_min_z": 0.3, "pointcloud_max_z": 2.0, "publish_every": 1,
                    "map_2d_period": 2.0, "octomap_period": 2.0, "tf_timeout": 2.0}
        for name, value in expected.items():
            assert abs(started[name] - value) < 1e-9, (name, started[name], value)
        print(f"the server reports the values the node runs with: {expected}")

        def play(*window):
            # -d 2: the nodes connect to each new player's topics before its first
            # message, which would otherwise be lost on a busy machine.
            player = subprocess.Popen(["rosbag", "play", "--quiet", "-d", "2", *window, bag],
                                      env=env, stdout=subprocess.DEVNULL)
            player.wait(timeout=120)
            assert player.returncode == 0, f"rosbag play exited {player.returncode}"

        play("-u", f"{split_s:.3f}")
        wait_until(lambda: live.mapped() == half and fixed.mapped() == half, 120,
                   lambda: f"both nodes to map the first {half} frames "
                   f"(last statistics: {live.last_stats()}, {fixed.last_stats()})")
        wait_until(lambda: cuboids.count >= half and live.octomap.count > 0, 30,
                   "the live node's markers and OctoMaps of the first half")
        answer = client.update_configuration({"publish_every": 1000, "octomap_period": 3600})
        assert answer["publish_every"] == 1000 and answer["octomap_period"] == 3600, answer
        time.sleep(2.0)  # an OctoMap under way when the answer came is out by now
        before = (cuboids.count, live.octomap.count)
        play("-s", f"{split_s:.3f}")
        wait_until(lambda: live.mapped() == args.frames and fixed.mapped() == args.frames,
                   120, lambda: f"both nodes to map all {args.frames} frames "
                   f"(last statistics: {live.last_stats()}, {fixed.last_stats()})")
        wait_for_octomaps(args, work, [fixed.octomap], stamps[-1])
        time.sleep(3.0)
        after = (cuboids.count, live.octomap.count)
        assert after == before, (
            f"publish_every 1000 and octomap_period 3600: markers and OctoMaps went from "
            f"{before} to {after} in the second half")
        print(f"publish_every 1000, octomap_period 3600 after frame {half}: no markers and "
              f"no OctoMap for frames {half + 1}-{args.frames} (markers {before[0]}, "
              f"OctoMaps {before[1]}, from the first half); the node started with the "
              f"defaults published the last frame's OctoMap")

        answer = client.update_configuration({"pointcloud_min_z": 3.0, "pointcloud_max_z": 1.0})
        assert (answer["pointcloud_min_z"], answer["pointcloud_max_z"]) == (0.3, 2.0), answer
        grids = len(live.grids)
        answer = client.update_configuration(band)
        assert all(answer[k] == v for k, v in band.items()), answer
        wait_until(lambda: len(live.grids) > grids, 30,
                   "the live node's 2D map in its new band")
        fixed_grid = fixed.last_grid(stamps[-1])

        def occupied(grid):
            return sum(1 for c in grid.data if c == 100)

        def layout(grid):
            return (grid.info.resolution, grid.info.width, grid.info.height,
                    grid.info.origin)

        # The same cells (map_load_time is the stamp of each node's last published frame).
        assert (layout(live.grids[-1]) == layout(fixed_grid)
                and live.grids[-1].data == fixed_grid.data), (
            f"the live node's 2D map in 2.5-4 m: {occupied(live.grids[-1])} occupied cells, "
            f"the node started with the band {occupied(fixed_grid)}")
        print(f"a band upside down (3 over 1 m) refused; pointcloud_min_z 2.5, "
              f"pointcloud_max_z 4 while it runs: a new 2D map at once, without a new "
              f"frame, equal to the one of the node started with them "
              f"({occupied(fixed_grid)} occupied cells; {occupied(live.grids[grids - 1])} "
              f"in 0.3-2 m)")
    finally:
        stop_all(player, [(node.process, node.name) for node in nodes], master)
    for node in nodes:
        assert node.process.returncode == 0, f"{node.name} exited {node.process.returncode}"
    log = live.log()
    assert "the band stays 0.3 to 2 m" in log, log
    assert "dynamic_reconfigure: publish_every 1000, octomap_period 3600 s" in log, log
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


def transforms_of(raw):
    """The transforms of a serialized tf2_msgs/TFMessage (rospy.AnyMsg's bytes; Debian
    packages no Python tf2_msgs): (parent, child, stamp in s, (x, y, z), (qx, qy, qz,
    qw)) each."""
    offset = 0

    def take(fmt):
        nonlocal offset
        values = struct.unpack_from(fmt, raw, offset)
        offset += struct.calcsize(fmt)
        return values

    def string():
        nonlocal offset
        (length,) = take("<I")
        text = raw[offset:offset + length].decode()
        offset += length
        return text

    (count,) = take("<I")
    transforms = []
    for _ in range(count):
        _seq, secs, nsecs = take("<III")
        parent = string()
        child = string()
        translation = take("<3d")
        rotation = take("<4d")
        transforms.append((parent, child, secs + nsecs * 1e-9, translation, rotation))
    return transforms


def write_tum(path, poses):
    """Poses (stamp s, (x, y, z), (qx, qy, qz, qw)) as a TUM trajectory file, every
    double in full (repr)."""
    with open(path, "w") as f:
        for stamp, t, q in poses:
            f.write(" ".join(repr(float(v)) for v in (stamp, *t, *q)) + "\n")


def package_folder(args, work):
    """A ROS package folder as `cmake --install` lays out share/planar_grid (package.xml,
    the launch and RViz files, the stereo configuration and a link to the node), for
    roslaunch to find with ROS_PACKAGE_PATH: the folder given to ROS_PACKAGE_PATH."""
    here = os.path.dirname(os.path.abspath(__file__))
    share = os.path.join(work, "share")
    package = os.path.join(share, "planar_grid")
    os.makedirs(package)
    for source in (os.path.join(here, "package.xml"), args.stereo_launch,
                   os.path.join(here, "planar_grid.rviz"), args.stereo_config,
                   os.path.abspath(args.node)):
        os.symlink(os.path.abspath(source),
                   os.path.join(package, os.path.basename(source)))
    return share


def stereo_odometry_test(args):
    """A stereo camera alone (--stereo-launch): roslaunch starts planar_grid_stereo.launch
    with its configuration, rosbag plays the frames' images and CameraInfos (no /tf),
    and the node's poses come from its visual odometry. Checks that every frame is
    mapped and posed once on /tf and once on ~odometry with the image's stamp, that
    planar_grid_pipeline with the same configuration on the same bag makes the same map
    and poses, and that the node's trajectory has the pipeline's RTE against the
    sequence's ground truth (planar_grid_trajectory_check, docs/ODOMETRY.md's metric)."""
    work = tempfile.mkdtemp(prefix="planar_grid_ros_stereo_")
    bag = os.path.join(work, "stereo.bag")
    subprocess.run([args.write_bag, "--config", args.config, "--frames", str(args.frames),
                    "--rate", str(args.bag_rate), "--no-tf", "--output", bag], check=True,
                   timeout=120)
    with open(args.config) as f:
        source = yaml.safe_load(f)
    ground_truth = os.path.join(os.path.dirname(os.path.abspath(args.config)),
                                source["input"]["poses"]["file"])
    with open(args.stereo_config) as f:
        stereo_config = yaml.safe_load(f)
    bag_topics = [stereo_config["input"][k] for k in ("left_image", "right_image",
                                                      "left_camera_info",
                                                      "right_camera_info")]
    import rosbag
    with rosbag.Bag(bag) as recorded:
        topics = sorted(recorded.get_type_and_topic_info().topics)
        image_stamps = [m.header.stamp.to_sec() for _, m, _ in
                        recorded.read_messages(topics=[bag_topics[0]])]
    assert topics == sorted(bag_topics), f"the bag holds {topics}, not only {bag_topics}"
    share = package_folder(args, work)
    port = free_port()
    env = dict(os.environ, ROS_MASTER_URI=f"http://127.0.0.1:{port}", ROS_IP="127.0.0.1",
               ROS_HOME=os.path.join(work, "ros_home"),
               ROS_LOG_DIR=os.path.join(work, "log"), ROS_PACKAGE_PATH=share)
    os.environ.update(env)
    import rospy
    from nav_msgs.msg import Odometry
    from std_msgs.msg import String
    from std_srvs.srv import Trigger

    node_folder = os.path.join(work, "node")
    launch_log = os.path.join(work, "roslaunch.log")
    master = launch = player = None
    try:
        master = start_master(env, port)
        # The camera's topics are not the configuration's: the launch file's arguments
        # remap them.
        camera_topics = {k: t.replace("/stereo/", "/camera/") for k, t in
                         zip(("left_image", "right_image", "left_camera_info",
                              "right_camera_info"), bag_topics)}
        with open(launch_log, "w") as log:
            # roslaunch without --wait: it takes the running master (rosmaster --core
            # sets no /run_id, for which --wait would poll without end).
            launch = subprocess.Popen(
                ["roslaunch", "planar_grid", os.path.basename(args.stereo_launch),
                 "rviz:=false", "max_queued_frames:=0", f"output_folder:={node_folder}"]
                + [f"{k}:={t}" for k, t in camera_topics.items()],
                env=env, stdout=log, stderr=subprocess.STDOUT)
        rospy.init_node("planar_grid_test", anonymous=True, disable_signals=True)
        stats, odometry, tf = [], [], []
        subscribers = [
            rospy.Subscriber("/planar_grid/frame_stats", String,
                             lambda m: stats.append(json.loads(m.data))),
            rospy.Subscriber("/planar_grid/odometry", Odometry, odometry.append),
            rospy.Subscriber("/tf", rospy.AnyMsg,
                             lambda m: tf.extend(transforms_of(bytes(m._buff)))),
        ]
        rospy.wait_for_service("/planar_grid/save_map", timeout=60)
        wait_until(lambda: all(s.get_num_connections() > 0 for s in subscribers), 30,
                   "the test's subscriptions to the node's frame_stats, odometry and /tf")
        player = subprocess.Popen(["rosbag", "play", "--quiet", "-d", "2", "-r",
                                   str(args.rate), bag]
                                  + [f"{t}:={camera_topics[k]}" for k, t in
                                     zip(camera_topics, bag_topics)],
                                  env=env, stdout=subprocess.DEVNULL)
        player.wait(timeout=120)
        assert player.returncode == 0, f"rosbag play exited {player.returncode}"
        wait_until(lambda: stats and stats[-1]["mapped"] + stats[-1]["failed"]
                   + stats[-1]["dropped"] >= args.frames, 180,
                   f"the node to map {args.frames} frames")
        final = stats[-1]
        assert final["failed"] == 0 and final["dropped"] == 0, final
        assert final["mapped"] == args.frames and final["unpaired"] == 0, final
        wait_until(lambda: len(odometry) >= args.frames, 30,
                   f"{args.frames} messages on ~odometry")
        response = rospy.ServiceProxy("/planar_grid/save_map", Trigger)()
        assert response.success, response.message
        print("save_map:", response.message)
        time.sleep(1.0)  # nothing more may come on /tf or ~odometry
    finally:
        stop_all(player, [(launch, "roslaunch")], master)
    with open(launch_log) as f:
        launched = f.read()
    assert launch.returncode == 0, f"roslaunch exited {launch.returncode}: {launch_log}"
    assert "process has died" not in launched, f"the node died: {launch_log}"
    assert "from the pipeline's visual_odometry stage" in launched, launched
    assert f"mapping the pair {camera_topics['left_image']}" in launched, launched

    # One pose per mapped frame on each topic, with the frames' image stamps in order.
    camera = [t for t in tf if t[1] == "camera"]
    assert all(t[0] == "world" for t in camera), {t[0] for t in camera}
    assert len(camera) == args.frames, f"{len(camera)} poses on /tf for {args.frames} frames"
    assert len(odometry) == args.frames, (
        f"{len(odometry)} poses on ~odometry for {args.frames} frames")
    for k, (t, o) in enumerate(zip(camera, odometry)):
        assert abs(t[2] - image_stamps[k]) < 1e-6, (k, t[2], image_stamps[k])
        assert o.header.stamp.to_sec() == t[2], (k, o.header.stamp.to_sec(), t[2])
        assert o.header.frame_id == "world" and o.child_frame_id == "camera", o.header
        p, q = o.pose.pose.position, o.pose.pose.orientation
        assert (p.x, p.y, p.z) == t[3] and (q.x, q.y, q.z, q.w) == t[4], (k, o.pose, t)
    assert all("odometry_flagged" in s and "odometry_inliers" in s for s in stats), stats[0]
    flagged = sum(1 for s in stats if s["odometry_flagged"])
    speeds = sorted(o.twist.twist.linear.z for o in odometry[1:])
    assert odometry[0].twist.twist.linear.z == 0.0 and speeds[len(speeds) // 2] > 0.0
    print(f"{args.frames} frames mapped ({final['keyframes']} keyframes); /tf and "
          f"~odometry each carried {args.frames} poses world -> camera, one per frame "
          f"with its image's stamp; median forward speed {speeds[len(speeds) // 2]:.2f} m/s; "
          f"{flagged} frames flagged by the odometry, median inliers "
          f"{statistics.median(s['odometry_inliers'] for s in stats):.0f}")
    node_tf = os.path.join(work, "node_tf.txt")
    node_odometry = os.path.join(work, "node_odometry.txt")
    write_tum(node_tf, [(t[2], t[3], t[4]) for t in camera])
    write_tum(node_odometry, [
        (o.header.stamp.to_sec(),
         (o.pose.pose.position.x, o.pose.pose.position.y, o.pose.pose.position.z),
         (o.pose.pose.orientation.x, o.pose.pose.orientation.y,
          o.pose.pose.orientation.z, o.pose.pose.orientation.w)) for o in odometry])

    # planar_grid_pipeline with the same configuration on the same bag.
    stereo_config["input"]["file"] = bag
    stereo_config["output"] = {"folder": os.path.join(work, "pipeline"),
                               "trajectory": "trajectory.txt", "report": "report.json",
                               "map": "map.pgmap"}
    pipeline_config = os.path.join(work, "pipeline.yaml")
    with open(pipeline_config, "w") as f:
        yaml.safe_dump(stereo_config, f, sort_keys=False)
    subprocess.run([args.pipeline, "--config", pipeline_config, "--no-snapshot"],
                   check=True, timeout=600, stdout=subprocess.DEVNULL)
    pipeline_trajectory = os.path.join(work, "pipeline", "trajectory.txt")
    result = subprocess.run([args.trajectory_check, "--ground-truth", ground_truth,
                             "--kitti", f"pipeline={pipeline_trajectory}",
                             "--tum", f"node_tf={node_tf}",
                             "--tum", f"node_odometry={node_odometry}"],
                            check=True, timeout=120, stdout=subprocess.PIPE, text=True)
    errors = json.loads(result.stdout)
    pipeline = errors["pipeline"]
    for name in ("node_tf", "node_odometry"):
        node = errors[name]
        difference = abs(node["rte_percent"] - pipeline["rte_percent"])
        assert difference <= 0.001 * pipeline["rte_percent"], (
            f"{name}: RTE {node['rte_percent']:.4f} %, planar_grid_pipeline's "
            f"{pipeline['rte_percent']:.4f} %: more than 0.1 % apart")
        print(f"{name}: RTE {node['rte_percent']:.4f} % (planar_grid_pipeline "
              f"{pipeline['rte_percent']:.4f} %, {difference:.2e} points apart), ATE "
              f"{node['ate_m']:.4f} m ({pipeline['ate_m']:.4f}); path "
              f"{node['path_length_m']:.2f} m (ground truth "
              f"{node['path_length_ground_truth_m']:.2f} m); poses at most "
              f"{node['max_position_difference_m']:.2e} m and "
              f"{node['max_rotation_difference_rad']:.2e} rad from the pipeline's")
    with open(os.path.join(node_folder, "map.pgmap"), "rb") as f:
        node_map = f.read()
    with open(os.path.join(work, "pipeline", "map.pgmap"), "rb") as f:
        pipeline_map = f.read()
    assert len(node_map) > 1000 and node_map == pipeline_map, (
        f"the node's map.pgmap ({len(node_map)} bytes) differs from planar_grid_pipeline's "
        f"({len(pipeline_map)} bytes); both in {work}")
    print("the node's map.pgmap equals planar_grid_pipeline's, byte for byte")
    if not args.keep:
        subprocess.run(["rm", "-rf", work], check=False)
    print("1 passed, 0 failed")


def main():
    if len(sys.argv) > 2 and sys.argv[1] == "--count-messages":
        # A late subscriber for --parameter latch: --count-messages SECONDS TOPIC...
        count_messages(float(sys.argv[2]), sys.argv[3:])
        return
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
    parser.add_argument("--bag-rate", type=float, default=9.4,
                        help="--stereo-launch: the camera's frame rate in the bag, Hz "
                        "(frame k stamped k / rate after the first)")
    parser.add_argument("--cpu", type=int, default=-1,
                        help="pin the node to this CPU (taskset -c); -1: not pinned")
    parser.add_argument("--stop-while-waiting-for-tf", action="store_true",
                        help="instead: play the pairs without /tf to the node with a "
                        "~tf_timeout of a day, send SIGINT, and check that it exits at "
                        "once with status 0")
    parser.add_argument("--parameter", choices=sorted(PARAMETERS),
                        help="instead: a node with this octomap_server parameter set "
                        "beside one without it, on --frames frames (docs/ROS.md)")
    parser.add_argument("--stereo-launch",
                        help="instead: roslaunch this launch file (planar_grid_stereo.launch) "
                        "with its configuration, --stereo-config, on a bag of --config's "
                        "images and CameraInfos without /tf, and check the visual "
                        "odometry's poses against planar_grid_pipeline's and the ground "
                        "truth")
    parser.add_argument("--stereo-config",
                        help="the launch file's default configuration (its topics; "
                        "planar_grid_pipeline runs it on the bag)")
    parser.add_argument("--trajectory-check",
                        help="planar_grid_trajectory_check (default: beside --node)")
    parser.add_argument("--dynamic-reconfigure", action="store_true",
                        help="instead: change the node's parameters while it maps, "
                        "through its dynamic_reconfigure server")
    parser.add_argument("--keep", action="store_true",
                        help="keep the work folder (bag, configuration, maps)")
    args = parser.parse_args()
    if args.octomap_check is None:
        args.octomap_check = os.path.join(os.path.dirname(args.node),
                                          "planar_grid_octomap_check")
    if args.trajectory_check is None:
        args.trajectory_check = os.path.join(os.path.dirname(args.node),
                                             "planar_grid_trajectory_check")
    if args.stop_while_waiting_for_tf:
        stop_while_waiting_for_tf(args)
        return
    if args.stereo_launch:
        stereo_odometry_test(args)
        return
    if args.dynamic_reconfigure:
        dynamic_reconfigure_test(args)
        return
    if args.parameter:
        parameter_test(args)
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
        stop_all(player, [(node, "planar_grid_ros_node")], master)
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
