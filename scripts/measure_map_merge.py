# SPDX-License-Identifier: BSD-3-Clause
"""Times PlanarGridMap.merge() on maps of the Karlsruhe drive mapped in parts by the
pipeline tool, and compares the merged map with the map of the whole range.

    build/tools/planar_grid_pipeline --config config/karlsruhe.yaml --no-snapshot \
        --frames 0:56 --output /tmp/k_0_56
    (the same with 56:112 and with all frames, --output /tmp/k_all)
    PYTHONPATH=build/python /usr/bin/python3 scripts/measure_map_merge.py \
        /tmp/k_0_56/map.pgmap /tmp/k_56_112/map.pgmap /tmp/k_all/map.pgmap

The probes are drawn in the box that holds the main job's map and kept where the
whole-range map has observed space."""
import sys
import time

import numpy as np

import planar_grid as pg
import planar_grid.distributed as pgd

S = pg.SpaceState


def counts(m):
    c = m.cuboids
    planar = int(np.count_nonzero(c.is_planar))
    v = m.voxel_counts
    return dict(planes=len(m.planes), planar_cuboids=planar,
                non_planar=len(c.is_planar) - planar, cells=m.cell_count,
                voxels=v["free"] + v["occupied"] + v["unknown"],
                mem_mb=m.memory["total_bytes"] / 1e6)


def measure(first, second, full=None, repeats=3, probes=100_000):
    load = time.perf_counter()
    a = pg.PlanarGridMap.load(first)
    b = pg.PlanarGridMap.load(second)
    load = time.perf_counter() - load
    ca, cb = counts(a), counts(b)
    times = []
    for _ in range(repeats):
        m = pg.PlanarGridMap.load(first)
        t = time.perf_counter()
        m.merge(b, np.eye(4))
        times.append(time.perf_counter() - t)
    # the other direction, for the symmetry
    ba = pg.PlanarGridMap.load(second)
    t = time.perf_counter()
    ba.merge(a, np.eye(4))
    t_ba = time.perf_counter() - t
    cm = counts(m)
    print(f"A {first}: {ca}")
    print(f"B {second}: {cb}")
    print(f"merged A<-B: {cm}")
    print(f"load both {load*1e3:.0f} ms; merge A<-B {np.median(times)*1e3:.0f} ms "
          f"(median of {repeats}: {', '.join(f'{x*1e3:.0f}' for x in times)}); "
          f"B<-A {t_ba*1e3:.0f} ms")
    if full is not None:
        f = pg.PlanarGridMap.load(full)
        cf = counts(f)
        print(f"full {full}: {cf}")
        p = pgd.sample_observed_points(f, probes, [0.0, -52.8, -7.2], [106.4, 18.4, 8.0])
        sf, sm, sba = f.get_state(p), m.get_state(p), ba.get_state(p)
        agree = np.mean(sf == sm)
        print(f"getState agreement merged vs full on {len(p)} random points observed by "
              f"the full run: {agree*100:.2f} %")
        for s_full in (S.FREE, S.OCCUPIED):
            sel = sf == s_full
            print(f"  full {s_full.name}: {sel.sum()} probes, merged agrees on "
                  f"{np.mean(sm[sel] == s_full)*100:.2f} %, merged says "
                  + ", ".join(f"{s.name} {np.sum(sm[sel] == s)}" for s in S))
        print(f"A<-B vs B<-A agreement on the same probes: {np.mean(sm == sba)*100:.3f} %; "
              f"planes {len(m.planes)} / {len(ba.planes)}")
        print(f"planar cuboid count ratio merged/full: "
              f"{cm['planar_cuboids']}/{cf['planar_cuboids']} = "
              f"{cm['planar_cuboids']/cf['planar_cuboids']:.3f}; planes merged/full "
              f"{cm['planes']}/{cf['planes']}; non-planar merged/full "
              f"{cm['non_planar']}/{cf['non_planar']}")


if __name__ == "__main__":
    measure(*sys.argv[1:3], full=sys.argv[3] if len(sys.argv) > 3 else None)
