#!/usr/bin/env python3
"""Per-frame cost against the map's size: a long run made of copies of one sequence.

Maps the frames of CONFIG's input LOOPS times with planar_grid.Mapper (one frame per
call, as a robot would), each copy moved by SHIFT (meters, world x,y,z) from the one
before, so that the map keeps growing. Prints, per block of BLOCK frames, the mean wall
time per frame (milliseconds) of the whole frame, of map_integration and of accumulate
(whose downsampling runs every few frames), and the map's cuboid count at the block's
end. A stage whose work follows
what the frame sees keeps its time flat while the map grows.

    PYTHONPATH=build/python python3 scripts/long_street.py config/karlsruhe.yaml \\
        --loops 4 --shift 400,0,0

The default shift puts the copies of the Karlsruhe street side by side; its own
start-to-end vector (76.15,-26.89,0.51) chains them into one street.
"""
import argparse
import json
import statistics
import sys

import numpy as np

import planar_grid as pg


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("config", help="pipeline configuration (stereo input with poses)")
    parser.add_argument("--loops", type=int, default=4, help="copies of the sequence")
    parser.add_argument("--shift", default="400,0,0",
                        help="x,y,z meters between consecutive copies")
    parser.add_argument("--block", type=int, default=56, help="frames per printed row")
    parser.add_argument("--json", help="also write every frame's figures here")
    args = parser.parse_args()
    shift = np.array([float(v) for v in args.shift.split(",")])
    if shift.shape != (3,) or args.loops < 1 or args.block < 1:
        sys.exit("long_street: --shift takes x,y,z; --loops and --block are >= 1")

    frames = pg.InputFrames(args.config)
    mapper = pg.Mapper(args.config)
    rows = []
    for loop in range(args.loops):
        for i in range(len(frames)):
            frame = frames[i]
            if frame["world_T_camera"] is None:
                sys.exit("long_street: the input gives no poses")
            pose = np.array(frame["world_T_camera"], dtype=float)
            pose[:3, 3] += shift * loop
            stats = mapper.integrate_stereo(frame["left"], frame["right"],
                                            frame["calibration"], pose)
            stage_ms = {s["type"]: s["ms"] for s in stats["stages"]}
            row = {"frame": len(rows), "total_ms": stats["total_ms"],
                   "map_integration_ms": stage_ms.get("map_integration", 0.0),
                   "accumulate_ms": stage_ms.get("accumulate", 0.0),
                   "map_cells": stats["map_cells"]}
            if (len(rows) + 1) % args.block == 0:
                # The cuboids merge the cells into rectangles: counted at the block's
                # end, outside the frames' times.
                with mapper.read_map() as m:
                    row["map_cuboids"] = len(m.cuboids)
            rows.append(row)
    print("| frames | frame ms | map_integration ms | accumulate ms | map cuboids |")
    print("|---|---|---|---|---|")
    for first in range(0, len(rows), args.block):
        block = rows[first:first + args.block]
        mean = lambda key: statistics.fmean(r[key] for r in block)
        print(f"| {first}-{first + len(block) - 1} | {mean('total_ms'):.0f} "
              f"| {mean('map_integration_ms'):.1f} | {mean('accumulate_ms'):.1f} "
              f"| {block[-1].get('map_cuboids', block[-1]['map_cells']):,} |")
    if args.json:
        with open(args.json, "w") as f:
            json.dump(rows, f)


if __name__ == "__main__":
    main()
