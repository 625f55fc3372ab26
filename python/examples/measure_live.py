# SPDX-License-Identifier: BSD-3-Clause
"""Measures planar_grid.Mapper on a configuration's frames: each frame's latency, how long
a reader thread waits for the map while frames are integrated, and what a copy of the
map (the alternative: publishing a snapshot after every frame) would cost.

    PYTHONPATH=build/python python3 python/examples/measure_live.py config/karlsruhe.yaml 112

The reader queries the state at 10000 points in the mapped area (a planner's check) in
a loop, under the mapper's shared lock, for as long as frames are integrated."""

import statistics
import sys
import threading
import time
from typing import Any, Dict, Iterable, List

import numpy as np

import planar_grid as pg


def summary(name: str, values: Iterable[float]) -> None:
    values = sorted(values)
    p95 = values[min(len(values) - 1, int(0.95 * len(values)))]
    print(f"{name}: mean {statistics.fmean(values):.2f} ms, median "
          f"{statistics.median(values):.2f}, p95 {p95:.2f}, max {values[-1]:.2f} "
          f"({len(values)} samples)")


def main(config: str, frame_count: int) -> None:
    frames = pg.InputFrames(config)
    mapper = pg.Mapper(config)
    points = np.random.default_rng(0).uniform([-5, -30, -1], [95, 30, 4], (10000, 3))
    waits: List[float] = []
    holds: List[float] = []
    done = threading.Event()

    def read() -> None:
        while not done.is_set():
            t0 = time.perf_counter()
            with mapper.read_map() as m:
                t1 = time.perf_counter()
                m.get_state(points)
            waits.append((t1 - t0) * 1e3)
            holds.append((time.perf_counter() - t1) * 1e3)

    reader = threading.Thread(target=read)
    reader.start()
    stats: List[Dict[str, Any]] = []
    for i in range(min(frame_count, len(frames))):
        f = frames[i]
        stats.append(mapper.integrate_stereo(f["left"], f["right"], f["calibration"],
                                             f["world_T_camera"]))
    done.set()
    reader.join()
    summary("integrate_stereo() per frame", [s["total_ms"] for s in stats])
    summary("readers locked out per frame (map_integration)",
            [s["exclusive_ms"] for s in stats])
    summary("frame waited for readers", [s["lock_wait_ms"] for s in stats])
    summary("reader waited for the lock", waits)
    summary("reader held the lock (get_state at 10000 points)", holds)
    copies: List[float] = []
    with mapper.read_map() as m:
        for _ in range(5):
            t0 = time.perf_counter()
            pg.PlanarGridMap.__new__(pg.PlanarGridMap).__setstate__(m.__getstate__())
            copies.append((time.perf_counter() - t0) * 1e3)
        print(f"final map: {len(m.cuboids)} cuboids, {len(m.__getstate__())} bytes")
    summary("a copy of the final map (serialize + deserialize)", copies)


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit(f"usage: {sys.argv[0]} config.yaml frame_count")
    main(sys.argv[1], int(sys.argv[2]))
