# SPDX-License-Identifier: BSD-3-Clause
"""Splits a map into tiles (planar_grid.save_tiles) and loads them back, all of them
and a disc around a pose of the drive (planar_grid.load_tiles), and compares what is
loaded with the map: tiles, bytes, times, getState agreement.

    build/tools/planar_grid_pipeline --config config/karlsruhe.yaml --no-snapshot \
        --output /tmp/tiles_mj
    PYTHONPATH=build/python /usr/bin/python3 scripts/measure_map_tiles.py \
        /tmp/tiles_mj/map.pgmap /tmp/tiles_mj/trajectory.txt /tmp/tiles_out

The pose is the middle frame's camera position of trajectory.txt (camera frame of the
first frame: x right, y down, z forward), turned into the map's world frame (x forward,
y left, z up). The probes are 200,000 points drawn uniformly in the map's bounds (all
of the loaded disc's cylinder for the region), seeded, and, for the whole map, the
centres of every occupied voxel, of 1,000,000 free voxels and of every cuboid."""
import os
import shutil
import sys
import time

import numpy as np

import planar_grid as pg


def folder_bytes(folder):
    return sum(os.path.getsize(os.path.join(folder, f)) for f in os.listdir(folder))


def agreement(a, b, points):
    sa, sb = a.get_state(points), b.get_state(points)
    observed = (sa != pg.SpaceState.UNKNOWN) | (sb != pg.SpaceState.UNKNOWN)
    same = sa == sb
    return (100.0 * np.mean(same), 100.0 * np.mean(same[observed]),
            int(np.count_nonzero(observed)))


def cuboid_rows(m):
    c = m.cuboids
    rows = np.column_stack([c.is_planar, c.centres, c.normals, c.horizontal_axes,
                            c.extents_m, c.probabilities])
    return rows[np.lexsort(np.round(rows, 3).T[::-1])]


def same_cuboids(a, b):
    ra, rb = cuboid_rows(a), cuboid_rows(b)
    return ra.shape == rb.shape and bool(np.allclose(ra, rb, atol=1e-4))


def plane_difference(a, b):
    pa, pb = np.asarray(a.planes), np.asarray(b.planes)
    if len(pa) != len(pb):
        return float("inf")
    return float(max(np.abs(pb - p).max(axis=1).min() for p in pa))


def summary(m):
    c = m.cuboids
    return dict(planes=len(m.planes), cuboids=len(c.is_planar),
                planar=int(np.count_nonzero(c.is_planar)), voxels=m.voxel_counts)


def main(map_path, trajectory_path, out_root):
    t = time.perf_counter()
    whole = pg.PlanarGridMap.load(map_path)
    print(f"map {map_path}: {os.path.getsize(map_path):,} bytes, loaded in "
          f"{1e3 * (time.perf_counter() - t):.0f} ms, {summary(whole)}")
    poses = np.loadtxt(trajectory_path).reshape(-1, 3, 4)
    cam = poses[len(poses) // 2][:, 3]
    position = np.array([cam[2], -cam[0], -cam[1]])
    print(f"pose {len(poses) // 2}: world position {np.round(position, 2)}")

    rng = np.random.default_rng(7)
    c = whole.cuboids
    lo = np.array([0.0, -52.8, -7.2])
    hi = np.array([106.4, 18.4, 8.0])
    everywhere = rng.uniform(lo, hi, size=(200_000, 3))
    radius = 30.0
    r = radius * np.sqrt(rng.uniform(0, 1, 200_000))
    a = rng.uniform(0, 2 * np.pi, 200_000)
    disc = np.column_stack([position[0] + r * np.cos(a), position[1] + r * np.sin(a),
                            rng.uniform(lo[2], hi[2], 200_000)])
    occupied = whole.voxel_centres(pg.SpaceState.OCCUPIED)
    free = whole.voxel_centres(pg.SpaceState.FREE)
    free = free[rng.choice(len(free), size=min(1_000_000, len(free)), replace=False)]
    dense = np.vstack([occupied, free, c.centres])
    in_disc = np.linalg.norm(dense[:, :2] - position[:2], axis=1) <= radius
    del c

    for size in (20.0, 50.0):
        folder = os.path.join(out_root, f"tiles_{int(size)}m")
        shutil.rmtree(folder, ignore_errors=True)
        t = time.perf_counter()
        index = pg.save_tiles(whole, folder, size)
        save_ms = 1e3 * (time.perf_counter() - t)
        total = folder_bytes(folder)
        print(f"\n{size:g} m tiles: {len(index['tiles'])} tiles, {total:,} bytes in the "
              f"folder ({100.0 * total / os.path.getsize(map_path):.1f} % of the file), "
              f"saved in {save_ms:.0f} ms")
        t = time.perf_counter()
        loaded = pg.load_tiles(folder, [-np.inf] * 3, [np.inf] * 3)
        print(f"  all tiles loaded in {1e3 * (time.perf_counter() - t):.0f} ms: "
              f"{summary(loaded)}; equal to the map: {loaded == whole}")
        print("  getState agreement, everywhere: %.4f %% (observed %.4f %% of %d)"
              % agreement(whole, loaded, everywhere))
        print("  getState agreement at the voxel and cuboid centres: %.4f %% of %d"
              % (agreement(whole, loaded, dense)[0], len(dense)))
        print(f"  same cuboids up to order: {same_cuboids(whole, loaded)}; planes: "
              f"largest coefficient difference {plane_difference(whole, loaded):.2e}")
        for margin in (0.0, 10.0):
            t = time.perf_counter()
            part = pg.load_tiles(folder, position, radius, margin_m=margin)
            ms = 1e3 * (time.perf_counter() - t)
            print(f"  {radius:g} m disc, margin {margin:g} m: loaded in {ms:.0f} ms, "
                  f"{summary(part)['cuboids']} cuboids, "
                  f"{part.memory['total_bytes']:,} bytes in memory; agreement in the "
                  "disc %.4f %% (observed %.4f %% of %d)" % agreement(whole, part, disc)
                  + ", at the voxel and cuboid centres in the disc %.4f %% of %d"
                  % (agreement(whole, part, dense[in_disc])[0], int(in_disc.sum())))


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(__doc__)
    main(*sys.argv[1:])
