# SPDX-License-Identifier: BSD-3-Clause
"""The planar area of a map covered twice by parallel planes a little apart: one wall
mapped as a stack of planes.

    PYTHONPATH=build/python /usr/bin/python3 scripts/stacked_planes.py MAP.pgmap \
        [--angle-rad 0.1] [--min-gap-m 0.05] [--max-gap-m 0.6]

A planar cuboid is stacked when its face centre lies over a planar cuboid of another
plane (inside it along that cuboid's two face axes) whose normal is within --angle-rad
of its own, between --min-gap-m and --max-gap-m from that cuboid's mid-plane along its
normal (nearer is the same surface, farther a distinct one). Prints the planar face
area, the stacked area (m^2) and the stacked cuboids; with --pairs, the plane pairs."""
import argparse
import sys

import numpy as np

import planar_grid as pg
from planar_grid.analysis import stacked_planar_cuboids


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", help="a .pgmap file")
    parser.add_argument("--angle-rad", type=float, default=0.1)
    parser.add_argument("--min-gap-m", type=float, default=0.05)
    parser.add_argument("--max-gap-m", type=float, default=0.6)
    parser.add_argument("--pairs", action="store_true", help="list the plane pairs")
    args = parser.parse_args()
    try:
        m = pg.PlanarGridMap.load(args.map)
    except (OSError, pg.Error) as e:
        sys.exit(f"stacked_planes.py: {e}")
    area, is_stacked, over, ids = stacked_planar_cuboids(m, args.angle_rad, args.min_gap_m,
                                          args.max_gap_m)
    print(f"planar area {area.sum():.1f} m^2, stacked {area[is_stacked].sum():.1f} m^2 "
          f"({int(is_stacked.sum())} of {len(area)} planar cuboids)")
    if args.pairs:
        pairs = {}
        for k in np.flatnonzero(is_stacked):
            key = (int(ids[k]), int(over[k]))
            pairs[key] = pairs.get(key, 0.0) + area[k]
        for (a, b), a_m2 in sorted(pairs.items(), key=lambda x: -x[1]):
            print(f"  plane {a} over plane {b}: {a_m2:.1f} m^2")


if __name__ == "__main__":
    main()
