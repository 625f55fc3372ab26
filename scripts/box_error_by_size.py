# SPDX-License-Identifier: BSD-3-Clause
"""The share of a map's non-planar boxes (Fig. 7) lying off the truth, by box size.

    PYTHONPATH=build/python /usr/bin/python3 scripts/box_error_by_size.py \
        MAP.pgmap TRUTH.pcd

MAP.pgmap and TRUTH.pcd are what `planar_grid_eval --save-maps` writes
(pg_DATASET_Rm.pgmap, truth_DATASET.pcd). Each non-planar cuboid the map reports is
sampled at the centres of its voxels (the map's resolution r), as the evaluation samples
PG's error; a sample with no truth point within r is erroneous. Prints, for the boxes of
1, 2, 3-8 and more than 8 voxels, their count, samples and erroneous share.

With --by-evidence every occupied cell (probability >= 0.5, as the evaluation counts
them; a planar cell sampled over its face) is counted, each class split into the cells
without feature evidence (probability exactly 0.5, the prior) and those with it, and
the share of all samples that are erroneous (the map's own error) is printed last. A map saved
before skip_isolated_non_planar (surface section version 6) reports every box."""
import argparse
import os
import sys
from collections import defaultdict

import numpy as np

import planar_grid as pg

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from plane_precision_control import read_pcd_xyz  # noqa: E402


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", help="a .pgmap file")
    parser.add_argument("truth", help="its truth or reference points, a .pcd file")
    parser.add_argument("--by-evidence", action="store_true",
                        help="split each class by feature evidence (probability 0.5 or "
                        "not), planar cells included")
    args = parser.parse_args()
    grid = pg.PlanarGridMap.load(args.map)
    r = grid.resolution_m
    truth = read_pcd_xyz(args.truth)
    cells = defaultdict(list)
    for i, key in enumerate(map(tuple, np.floor(truth / r).astype(np.int64))):
        cells[key].append(i)

    def near_truth(p):
        k = np.floor(p / r).astype(np.int64)
        for dx in (-1, 0, 1):
            for dy in (-1, 0, 1):
                for dz in (-1, 0, 1):
                    idx = cells.get((k[0] + dx, k[1] + dy, k[2] + dz))
                    if idx and (np.linalg.norm(truth[idx] - p, axis=1) <= r).any():
                        return True
        return False

    c = grid.cuboids
    extents = np.asarray(c.extents_m)
    planar = np.asarray(c.is_planar, bool)
    centres = np.asarray(c.centres)
    rotations = np.asarray(c.rotations).reshape(-1, 3, 3)
    probabilities = np.asarray(c.probabilities)
    classes = defaultdict(lambda: [0, 0, 0])
    if args.by_evidence:
        chosen = np.flatnonzero(probabilities >= 0.5)
    else:
        chosen = np.flatnonzero(~planar)
    for i in chosen:
        n = np.maximum(1, np.round(extents[i] / r).astype(int))
        if planar[i]:
            n[2] = 1  # a planar cell is sampled over its face
        axes = [(np.arange(k) + 0.5) / k - 0.5 for k in n]
        local = np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3) * extents[i]
        samples = centres[i] + local @ rotations[i].T
        erroneous = sum(0 if near_truth(p) else 1 for p in samples)
        voxels = int(np.prod(n))
        name = ("planar cells" if planar[i] else
                "boxes of   1 voxels" if voxels == 1 else "boxes of   2 voxels"
                if voxels == 2 else "boxes of 3-8 voxels" if voxels <= 8
                else "boxes of  >8 voxels")
        if args.by_evidence:
            name += ", no evidence" if probabilities[i] == 0.5 else ", evidence"
        classes[name][0] += 1
        classes[name][1] += len(samples)
        classes[name][2] += erroneous
    print(f"{args.map}: {len(planar)} cuboids, {int(planar.sum())} planar, r = {r} m")
    order = ["boxes of   1", "boxes of   2", "boxes of 3-8", "boxes of  >8", "planar"]
    for name in sorted(classes, key=lambda n: ([n.startswith(o) for o in order].index(True), n)):
        cells_in, samples, erroneous = classes[name]
        print(f"  {name}: {cells_in:6d} cells, {samples:7d} samples, "
              f"{erroneous / samples:.3f} erroneous")
    if args.by_evidence:
        samples = sum(v[1] for v in classes.values())
        erroneous = sum(v[2] for v in classes.values())
        print(f"  all occupied cells: {samples} samples, {erroneous / samples:.3f} erroneous")
    return 0


if __name__ == "__main__":
    sys.exit(main())
