# SPDX-License-Identifier: BSD-3-Clause
"""Measures planar_grid.distributed on a recording: the job split into segments on a
local Dask cluster against one run of the same frames, the merge cost as the map grows,
and the per-task costs the throughput projection of docs/SCALE.md starts from.

    PYTHONPATH=build/python nice -n 10 /usr/bin/python3 scripts/measure_batch.py \
        --config config/karlsruhe.yaml --segments 4 --workers 2 --output /tmp/batch_measure

Steps (each prints its figures; all of them go to OUTPUT/measure_batch.json):
  1. one run of the frames (run_pipeline, the frame overlap on the second core), timed;
  2. the batch job (map_segments: N segments, W worker processes, the local cluster's
     start and stop included), timed; the merged map against the one run: getState
     agreement on --probes random points the one run observed (free or occupied; drawn
     as scripts/measure_map_merge.py draws them), planes, planar and non-planar cuboids,
     the space layer's voxels (occupied beyond the turn, x > 70 m and y < -10 m, apart)
     and the stacks of parallel vertical planes (parallel_plane_stacks); the same
     segment maps merged again in the same tree with their observation spans removed
     (the symmetric voxel rule, occupied wins, of maps without an order), the same
     figures;
  3. the batch job again with --fine-segments segments: every merge task's load, merge
     and save seconds against the planes and cells of its result (merging 2, 4, 8, ...
     segment maps), and each segment task's seconds against its frames;
  4. the map grown by copies of the one run's map moved by whole voxels along x
     (1, 2, 4, 8 copies: a longer drive through new space), each doubling merged, timed
     (saving, and loading as the median of 3);
  5. the batch job again on a local cluster of its own, a worker killed (SIGKILL) 3 s
     into the first segment task seen running: the job's wall time, and its map against
     step 2's (getState on the same probes, counts);
  6. the projection of docs/SCALE.md from these figures (the model is in project());
  7. the merge by region against the tree (tile_merge_run()): the batch job with
     merge="tree" and with merge="tiles" (--tile-size meters), alternately, --repeats
     times each: wall times, the largest single merge task of each (its result's cells
     and seconds), and the tile merge's map (load_tiles of every tile) against the
     tree's map and against the tree's map saved as tiles and loaded: getState on
     --probes points the tree's map observed, voxel counts and the occupied voxels
     (by centre), planes, planar and non-planar cuboids; and against the segment maps
     merged whole without the planes' tidying (as the tile merge), saved as tiles and
     loaded: getState and counts. Its figures also
     go to OUTPUT/measure_tile_merge.json; --tile-merge-only runs this step alone:

    PYTHONPATH=build/python nice -n 10 /usr/bin/python3 scripts/measure_batch.py \
        --config config/karlsruhe.yaml --segments 4 --workers 2 --tile-size 20 \
        --tile-merge-only --output /tmp/tile_merge_measure
"""
import argparse
import json
import math
import os
import signal
import threading
import time

import distributed

import numpy as np

import planar_grid as pg
import planar_grid.distributed as pgd

S = pg.SpaceState


# The box of the main job's map, world frame, meters.
BOX_MIN, BOX_MAX = [0.0, -52.8, -7.2], [106.4, 18.4, 8.0]


# Beyond the drive's turn, world frame, meters: x > 70 and y < -10.
TURN_X, TURN_Y = 70.0, -10.0


def space_figures(m):
    """The space layer's voxel counts (free, occupied, unknown), the occupied voxels
    beyond the turn, and the map's stacks of parallel vertical planes."""
    occupied = m.voxel_centres("occupied")
    beyond = (occupied[:, 0] > TURN_X) & (occupied[:, 1] < TURN_Y)
    return dict(voxels={k: int(v) for k, v in m.voxel_counts.items()},
                occupied_beyond_turn=int(np.count_nonzero(beyond)),
                plane_stacks=[list(p) for p in pgd.parallel_plane_stacks(m)])


def compare(single, merged, probes):
    s1, s2 = single.get_state(probes), merged.get_state(probes)
    out = dict(probes=len(probes), agreement=float(np.mean(s1 == s2)))
    for state in (S.FREE, S.OCCUPIED):
        sel = s1 == state
        out[f"agreement_{state.name.lower()}"] = float(np.mean(s2[sel] == state))
        out[f"probes_{state.name.lower()}"] = int(sel.sum())
    return out


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--config", default="config/karlsruhe.yaml")
    parser.add_argument("--frames", type=int, nargs=2, default=None, metavar=("A", "B"))
    parser.add_argument("--segments", type=int, default=4)
    parser.add_argument("--fine-segments", type=int, default=16)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--probes", type=int, default=100_000)
    parser.add_argument("--copies", type=int, default=8)
    parser.add_argument("--output", default="/tmp/batch_measure")
    parser.add_argument("--tile-size", type=float, default=20.0, metavar="M",
                        help="tile edge of step 7's merge by region, meters")
    parser.add_argument("--repeats", type=int, default=2,
                        help="runs of each job in step 7")
    parser.add_argument("--tile-merge-only", action="store_true",
                        help="run step 7 alone")
    parser.add_argument("--project-tiles", nargs=2, metavar=("BATCH_JSON", "TILE_JSON"),
                        help="print step 8 alone from the figures of an earlier run "
                             "(measure_batch.json, measure_tile_merge.json)")
    args = parser.parse_args()
    if args.project_tiles:
        with open(args.project_tiles[0], encoding="utf-8") as f:
            projection = json.load(f)["projection"]
        with open(args.project_tiles[1], encoding="utf-8") as f:
            tile_merge = json.load(f)
        project_tiles(projection, tile_merge)
        return
    os.makedirs(args.output, exist_ok=True)
    figures = dict(config=os.path.abspath(args.config), segments=args.segments,
                   workers=args.workers)
    frames = tuple(args.frames) if args.frames else None
    if args.tile_merge_only:
        tile_merge_run(args, frames)
        return

    # 1. one run
    t = time.perf_counter()
    result = pg.run_pipeline(args.config, frames=frames, write_outputs=False)
    single_s = time.perf_counter() - t
    single = result.map
    single_path = os.path.join(args.output, "single_map.pgmap")
    single.save(single_path)
    figures["single"] = dict(wall_time_s=single_s, frames=int(result.frames),
                             **pgd.map_counts(single), **space_figures(single))
    print(f"one run: {result.frames} frames in {single_s:.1f} s: {figures['single']}")

    # 2. the batch job
    t = time.perf_counter()
    report = pgd.map_segments(args.config, frames=frames, num_segments=args.segments,
                              n_workers=args.workers,
                              output_dir=os.path.join(args.output, "batch"))
    batch_s = time.perf_counter() - t
    merged = pg.PlanarGridMap.load(report["map"])
    tasks = report["segments"] + report["merges"]
    probes = pgd.sample_observed_points(single, args.probes, BOX_MIN, BOX_MAX)
    figures["batch"] = dict(wall_time_s=batch_s, **pgd.map_counts(merged),
                            **space_figures(merged), **compare(single, merged, probes),
                            segment_s=[s["wall_time_s"] for s in report["segments"]],
                            merge_s=[m["wall_time_s"] for m in report["merges"]],
                            tasks_span_s=(max(r["end_time"] for r in tasks)
                                          - min(r["start_time"] for r in tasks)))
    b, s1 = figures["batch"], figures["single"]
    print(f"batch: {args.segments} segments on {args.workers} workers in {batch_s:.1f} s; "
          f"getState agreement {b['agreement']*100:.2f} % of {b['probes']} probes "
          f"(free {b['agreement_free']*100:.2f} %, occupied "
          f"{b['agreement_occupied']*100:.2f} %); planar cuboids {b['planar_cuboids']} / "
          f"{s1['planar_cuboids']} = {b['planar_cuboids']/s1['planar_cuboids']:.3f}; "
          f"planes {b['planes']} / {s1['planes']}; non-planar {b['non_planar_cuboids']} / "
          f"{s1['non_planar_cuboids']}")
    print(f"occupied voxels {b['voxels']['occupied']} / {s1['voxels']['occupied']} (beyond "
          f"the turn {b['occupied_beyond_turn']} / {s1['occupied_beyond_turn']}); free "
          f"voxels {b['voxels']['free']} / {s1['voxels']['free']}; stacks of parallel "
          f"vertical planes {len(b['plane_stacks'])} / {len(s1['plane_stacks'])}")

    # 2b. the same segment maps without their order: the symmetric voxel rule
    unordered = [pg.PlanarGridMap.load(seg["map"]) for seg in report["segments"]]
    for m in unordered:
        m.observation_span = None
    while len(unordered) > 1:  # map_segments' tree: neighbours first
        for a, b in zip(unordered[::2], unordered[1::2]):
            a.merge(b, np.eye(4))
        unordered = unordered[::2]
    unordered[0].save(os.path.join(args.output, "unordered_map.pgmap"))
    figures["batch_unordered"] = dict(**pgd.map_counts(unordered[0]),
                                      **space_figures(unordered[0]),
                                      **compare(single, unordered[0], probes))
    u = figures["batch_unordered"]
    print(f"the segments merged without their order (occupied wins): occupied voxels "
          f"{u['voxels']['occupied']} (beyond the turn {u['occupied_beyond_turn']}); "
          f"getState agreement {u['agreement']*100:.2f} % (free "
          f"{u['agreement_free']*100:.2f} %, occupied {u['agreement_occupied']*100:.2f} %)")

    # 3. finer segments: the merge tree's levels and the per-segment cost
    fine = pgd.map_segments(args.config, frames=frames, num_segments=args.fine_segments,
                            n_workers=args.workers,
                            output_dir=os.path.join(args.output, "fine"), progress=False)
    figures["fine"] = dict(
        segments=[dict(frames=s["frames"][1] - s["frames"][0], wall_time_s=s["wall_time_s"],
                       cells=s["cells"]) for s in fine["segments"]],
        merges=[dict(inputs=len(m["inputs"]), load_s=m["load_s"], merge_s=m["merge_s"],
                     save_s=m["save_s"], planes=m["planes"], cells=m["cells"],
                     memory_bytes=m["memory_bytes"], map_file_bytes=os.path.getsize(m["map"]))
                for m in fine["merges"]],
        wall_time_s=fine["wall_time_s"])
    for s in figures["fine"]["segments"][:3]:
        print(f"segment task: {s['frames']} frames {s['wall_time_s']:.2f} s")
    print("merge tasks (result planes / cells: load, merge, save seconds):")
    for m in figures["fine"]["merges"]:
        print(f"  {m['planes']} planes / {m['cells']} cells ({m['map_file_bytes']/1e6:.1f} MB "
              f"file): load {m['load_s']:.3f}, merge {m['merge_s']:.3f}, save {m['save_s']:.3f}")

    # 4. the map grown by shifted copies: merge cost against map size
    growth = []
    loads = []
    for _ in range(3):
        t = time.perf_counter()
        grown = pg.PlanarGridMap.load(single_path)
        loads.append(time.perf_counter() - t)
    figures["single"]["load_s"] = float(np.median(loads))
    span = 200.0  # m along x per copy: new space, no overlap with the copies before
    copies = 1
    while copies < args.copies:
        other = pg.PlanarGridMap.load(single_path)
        for k in range(1, copies):  # the other half: the same number of copies, shifted
            shifted = pg.PlanarGridMap.load(single_path)
            move = np.eye(4)
            move[0, 3] = k * span
            other.merge(shifted, move)
        move = np.eye(4)
        move[0, 3] = copies * span
        before = pgd.map_counts(grown)
        t = time.perf_counter()
        grown.merge(other, move)
        merge_s = time.perf_counter() - t
        path = os.path.join(args.output, "grown.pgmap")
        t = time.perf_counter()
        grown.save(path)
        save_s = time.perf_counter() - t
        loads = []
        for _ in range(3):
            t = time.perf_counter()
            pg.PlanarGridMap.load(path)
            loads.append(time.perf_counter() - t)
        load_s = float(np.median(loads))
        copies *= 2
        after = pgd.map_counts(grown)
        growth.append(dict(copies=copies, merge_s=merge_s, save_s=save_s, load_s=load_s,
                           file_bytes=os.path.getsize(path), before=before, **after))
        print(f"{copies} copies: merge of two {copies // 2}-copy maps {merge_s:.3f} s, "
              f"save {save_s:.3f} s, load {load_s:.3f} s; {after['planes']} planes, "
              f"{after['cells']} cells, {os.path.getsize(path)/1e6:.1f} MB file, "
              f"{after['memory_bytes']/1e6:.0f} MB in memory")
    figures["growth"] = growth

    # 5. a worker killed mid-task
    figures["kill"] = kill_run(args, frames, report, probes)
    k = figures["kill"]
    print(f"worker killed {k['killed_after_s']:.1f} s into {k['task']}: the job took "
          f"{k['wall_time_s']:.1f} s (against {batch_s:.1f} s); the task ran again in "
          f"pid {k['rerun_pid']} (killed: {k['killed_pid']}); getState equal to the "
          f"un-killed job's on {k['same_state']*100:.2f} % of the probes, counts equal: "
          f"{k['same_counts']}")

    # 6. the projection
    figures["projection"] = project(figures)

    # 7. the merge by region
    figures["tile_merge"] = tile_merge_run(args, frames)
    # 8. its projection
    figures["tile_projection"] = project_tiles(figures["projection"], figures["tile_merge"])
    with open(os.path.join(args.output, "measure_batch.json"), "w", encoding="utf-8") as f:
        json.dump(figures, f, indent=1)
    print(f"figures: {os.path.join(args.output, 'measure_batch.json')}")


def tile_merge_run(args, frames):
    """Step 7: the tree merge against the merge by region, on the same segments."""
    runs = dict(tree=[], tiles=[])
    reports = {}
    for repeat in range(args.repeats):
        for merge in ("tree", "tiles"):
            out = os.path.join(args.output, f"{merge}_{repeat}")
            t = time.perf_counter()
            report = pgd.map_segments(
                args.config, frames=frames, num_segments=args.segments,
                n_workers=args.workers, output_dir=out, merge=merge,
                tile_size_m=args.tile_size if merge == "tiles" else None,
                progress=False)
            wall = time.perf_counter() - t
            merges = report["merges"] if merge == "tree" else report["tile_merges"]
            largest = max(merges, key=lambda r: r["cells"])
            slowest = max(merges, key=lambda r: r["wall_time_s"])
            run = dict(wall_time_s=wall, merge_tasks=len(merges),
                       largest_merge=dict(cells=largest["cells"],
                                          wall_time_s=largest["wall_time_s"]),
                       slowest_merge=dict(cells=slowest["cells"],
                                          wall_time_s=slowest["wall_time_s"]),
                       merge_cells_total=int(sum(r["cells"] for r in merges)),
                       segment_s=[r["wall_time_s"] for r in report["segments"]])
            if merge == "tiles":
                run["tiles"] = report["tiles"]["tiles"]
                run["tiles_from_several_segments"] = sum(
                    len(r["inputs"]) > 1 for r in report["tile_merges"])
                run["segment_save_tiles_s"] = [r["save_tiles_s"]
                                               for r in report["segments"]]
                run["tile_tasks"] = [dict(key=r["key"], inputs=len(r["inputs"]),
                                          cells=r["cells"], merge_s=r["merge_s"],
                                          wall_time_s=r["wall_time_s"])
                                     for r in report["tile_merges"]]
            runs[merge].append(run)
            reports[merge] = report
            print(f"{merge} merge, run {repeat + 1}: {wall:.1f} s, {len(merges)} merge "
                  f"tasks, largest {largest['cells']} cells in "
                  f"{largest['wall_time_s']:.3f} s, slowest {slowest['wall_time_s']:.3f} s "
                  f"({slowest['cells']} cells)")

    everywhere = (np.full(3, -np.inf), np.full(3, np.inf))
    tree = pg.PlanarGridMap.load(reports["tree"]["map"])
    tree_tiles_folder = os.path.join(args.output, "tree_map_tiles")
    pg.save_tiles(tree, tree_tiles_folder, args.tile_size)
    tree_tiles = pg.load_tiles(tree_tiles_folder, *everywhere)
    merged = pg.load_tiles(reports["tiles"]["tiles"]["folder"], *everywhere)
    # The segment maps merged whole in frame order without the planes' tidying after
    # each merge (which the tile merge skips), saved as tiles and loaded.
    segment_maps = [pg.PlanarGridMap.load(r["map"]) for r in reports["tiles"]["segments"]]
    params = dict(segment_maps[0].params)
    params.update(planes_absorb_overlapping=False, planes_replace_non_planar=False)
    untidy = pg.PlanarGridMap(**params)
    for m in segment_maps:
        untidy.merge(m, np.eye(4))
    untidy_folder = os.path.join(args.output, "untidy_map_tiles")
    pg.save_tiles(untidy, untidy_folder, args.tile_size)
    untidy_tiles = pg.load_tiles(untidy_folder, *everywhere)
    probes = pgd.sample_observed_points(tree, args.probes, BOX_MIN, BOX_MAX)
    states = dict(tree=tree.get_state(probes), tree_tiles=tree_tiles.get_state(probes),
                  tiles=merged.get_state(probes),
                  untidy_tiles=untidy_tiles.get_state(probes))
    figures = dict(
        tile_size_m=args.tile_size, runs=runs, probes=len(probes),
        agreement_tiles_vs_tree=float(np.mean(states["tiles"] == states["tree"])),
        agreement_tiles_vs_tree_tiles=float(np.mean(states["tiles"]
                                                    == states["tree_tiles"])),
        agreement_tree_tiles_vs_tree=float(np.mean(states["tree_tiles"]
                                                   == states["tree"])),
        agreement_tiles_vs_untidy_tiles=float(np.mean(states["tiles"]
                                                      == states["untidy_tiles"])),
        same_voxel_counts=merged.voxel_counts == tree.voxel_counts,
        same_occupied_voxels=bool(np.array_equal(
            np.unique(merged.voxel_centres("occupied"), axis=0),
            np.unique(tree.voxel_centres("occupied"), axis=0))),
        voxels={k: int(v) for k, v in merged.voxel_counts.items()},
        tree=pgd.map_counts(tree), tree_tiles=pgd.map_counts(tree_tiles),
        tiles=pgd.map_counts(merged), untidy_tiles=pgd.map_counts(untidy_tiles))
    differ = states["tiles"] != states["tree_tiles"]
    figures["disagreements"] = {
        f"{S(a).name.lower()}_vs_{S(b).name.lower()}": int(np.count_nonzero(
            differ & (states["tiles"] == a) & (states["tree_tiles"] == b)))
        for a in (S.FREE, S.OCCUPIED, S.UNKNOWN) for b in (S.FREE, S.OCCUPIED, S.UNKNOWN)
        if a != b}
    f = figures
    print(f"tiles vs tree: getState {f['agreement_tiles_vs_tree']*100:.3f} % of "
          f"{f['probes']} probes (vs the tree's map saved as tiles and loaded "
          f"{f['agreement_tiles_vs_tree_tiles']*100:.3f} %; that against the tree's map "
          f"{f['agreement_tree_tiles_vs_tree']*100:.3f} %); same voxel counts "
          f"{f['same_voxel_counts']}, same occupied voxels {f['same_occupied_voxels']}; "
          f"planar cuboids {f['tiles']['planar_cuboids']} / tree "
          f"{f['tree']['planar_cuboids']} / tree as tiles {f['tree_tiles']['planar_cuboids']}"
          f"; non-planar {f['tiles']['non_planar_cuboids']} / "
          f"{f['tree']['non_planar_cuboids']}; planes {f['tiles']['planes']} / "
          f"{f['tree']['planes']}; disagreements {f['disagreements']}")
    print(f"tiles vs the segments merged whole without the tidying, as tiles: getState "
          f"{f['agreement_tiles_vs_untidy_tiles']*100:.3f} %; counts {f['tiles']} / "
          f"{f['untidy_tiles']}")
    path = os.path.join(args.output, "measure_tile_merge.json")
    with open(path, "w", encoding="utf-8") as out:
        json.dump(figures, out, indent=1)
    print(f"figures: {path}")
    return figures


def kill_run(args, frames, expected, probes):
    """The batch job on a local cluster of its own, one worker process killed 3 s into
    the first segment task seen running."""
    cluster = distributed.LocalCluster(n_workers=args.workers, threads_per_worker=1,
                                       processes=True, host="127.0.0.1",
                                       dashboard_address=None, silence_logs=50)
    try:
        with distributed.Client(cluster.scheduler_address, set_as_default=False) as client:
            pids = client.run(os.getpid)
            out = {}

            def job():
                t = time.perf_counter()
                out["report"] = pgd.map_segments(
                    args.config, frames=frames, num_segments=args.segments,
                    scheduler_address=cluster.scheduler_address,
                    output_dir=os.path.join(args.output, "killed"), progress=False)
                out["wall_time_s"] = time.perf_counter() - t

            thread = threading.Thread(target=job)
            start = time.perf_counter()
            thread.start()
            # the tasks a worker executes now (the scheduler's processing() lists those
            # queued on it too)
            def executing(dask_worker):
                return [str(ts.key) for ts in dask_worker.state.executing]

            victim = None
            while victim is None and thread.is_alive():
                for worker, keys in client.run(executing).items():
                    running = [k for k in keys if k.startswith("segment-")]
                    if running and worker in pids:
                        victim = (worker, running[0])
                        break
                time.sleep(0.05)
            time.sleep(3.0)
            killed_after = time.perf_counter() - start
            os.kill(pids[victim[0]], signal.SIGKILL)
            thread.join()
    finally:
        cluster.close()
    report = out["report"]
    merged = pg.PlanarGridMap.load(report["map"])
    reference = pg.PlanarGridMap.load(expected["map"])
    index = int(victim[1].split("-")[1])
    keys = ("planes", "planar_cuboids", "non_planar_cuboids", "cells")
    return dict(task=f"segment {index + 1}", killed_pid=pids[victim[0]],
                killed_after_s=killed_after,
                rerun_pid=report["segments"][index]["worker"]["pid"],
                wall_time_s=out["wall_time_s"],
                same_state=float(np.mean(merged.get_state(probes)
                                         == reference.get_state(probes))),
                same_counts=all(report[k] == expected[k] for k in keys))


def project(figures, frames_per_worker=1120, workers=(10, 100, 1000)):
    """Throughput of a batch on W workers, on paper, from the measured costs.

    Model: W workers, one segment of frames_per_worker frames each (weak scaling: the
    job grows with the cluster), every segment through new space. A segment task costs
    t_seg = frames_per_worker * t_frame (t_frame: least squares over the measured
    segment tasks; their fixed cost fitted ~0). The merges form a binary tree of
    ceil(log2 W) levels that runs after the segments; a level's merges run in parallel,
    so each level costs one merge task of its result's size, the root's the whole map.
    A merge task of a result of C cells costs k * C (loading both inputs, merging,
    saving; k: the median per cell of the grown maps' merges of step 4). Cells grow
    with the frames (c_frame: the one run's cells per frame). t_start: the local
    cluster's start and stop as measured (the job's wall time less its tasks' critical
    path). Not modelled: the shared filesystem's bandwidth, the scheduler's per-task
    overhead (milliseconds), stragglers and re-runs."""
    segs = figures["fine"]["segments"] + [
        dict(frames=f, wall_time_s=t) for f, t in
        zip([28] * len(figures["batch"]["segment_s"]), figures["batch"]["segment_s"])]
    f = np.array([s["frames"] for s in segs], float)
    t = np.array([s["wall_time_s"] for s in segs])
    t_frame, t_fixed = np.polyfit(f, t, 1)
    # a merge task of the i-th doubling loads two maps of the (i-1)-th size
    input_loads = [figures["single"]["load_s"]] + [g["load_s"] for g in figures["growth"]]
    k = float(np.median([(2 * load + g["merge_s"] + g["save_s"]) / g["cells"]
                         for load, g in zip(input_loads, figures["growth"])]))
    single = figures["single"]
    c_frame = single["cells"] / single["frames"]
    bytes_per_cell = single["memory_bytes"] / single["cells"]
    t_start = figures["batch"]["wall_time_s"] - figures["batch"]["tasks_span_s"]
    rows = []
    print(f"projection: t_frame {t_frame:.3f} s (fixed {t_fixed:.2f} s), merge {k*1e6:.1f} "
          f"us/cell, {c_frame:.0f} cells/frame, {bytes_per_cell:.0f} B/cell, t_start "
          f"{t_start:.1f} s; {frames_per_worker} frames per worker")
    for w in workers:
        levels = math.ceil(math.log2(w))
        total = w * frames_per_worker
        merge_path = sum(k * min(2 ** level, w) * frames_per_worker * c_frame
                         for level in range(1, levels + 1))
        seg = frames_per_worker * t_frame
        wall = t_start + seg + merge_path
        rows.append(dict(workers=w, frames=total, segment_s=seg, merge_levels=levels,
                         merge_path_s=merge_path, wall_time_s=wall,
                         frames_per_s=total / wall, ideal_frames_per_s=w / t_frame,
                         root_cells=total * c_frame,
                         root_memory_gb=total * c_frame * bytes_per_cell / 1e9))
        r = rows[-1]
        print(f"  {w} workers: {total} frames, segments {seg:.0f} s + {levels} merge levels "
              f"{merge_path:.0f} s = {wall:.0f} s: {r['frames_per_s']:.0f} frames/s "
              f"(ideal {r['ideal_frames_per_s']:.0f}); root map {r['root_cells']/1e6:.0f} M "
              f"cells, {r['root_memory_gb']:.1f} GB")
    return dict(t_frame_s=t_frame, t_fixed_s=t_fixed, merge_s_per_cell=k,
                cells_per_frame=c_frame, bytes_per_cell=bytes_per_cell, t_start_s=t_start,
                frames_per_worker=frames_per_worker, rows=rows)


def project_tiles(projection, tile_merge, segment_frames=28, seconds_per_task=1e-3,
                  grouped_tiles_per_task=16):
    """Throughput of the merge by region on W workers, on paper (step 8), beside the
    tree's projection (same workers, frames per worker, t_frame, cells per frame and
    t_start).

    Model: as project(), every segment through new space. A segment task costs
    frames_per_worker * (t_frame + s_frame), s_frame being save_tiles' measured seconds
    per segment frame (median over step 7's tile runs; segment_frames frames each).
    The tile tasks then merge each cell once: W * frames_per_worker * c_frame cells at
    k_tile seconds per cell (all tile tasks' seconds over all their cells, step 7),
    spread over the W workers. The scheduler hands out the tile tasks one at a time:
    tiles_per_frame * W * frames_per_worker tasks (tiles_per_frame: step 7's tiles over
    its frames) at seconds_per_task each, an assumed figure (Dask's documented per-task
    overhead is of the order of a millisecond), not measured here; with
    grouped_tiles_per_task keys per task (map_segments' tiles_per_task) they are that
    many times fewer, as long as they still outnumber the workers. Not modelled: the
    shared filesystem, stragglers, drives that revisit a tile (its task merges more
    maps)."""
    tiles_runs = tile_merge["runs"]["tiles"]
    s_frame = float(np.median([t for run in tiles_runs
                               for t in run["segment_save_tiles_s"]])) / segment_frames
    tasks = [task for run in tiles_runs for task in run["tile_tasks"]]
    k_tile = sum(task["wall_time_s"] for task in tasks) / max(
        1, sum(task["cells"] for task in tasks))
    frames = segment_frames * len(tiles_runs[0]["segment_s"])
    tiles_per_frame = tiles_runs[0]["tiles"] / frames
    t_frame, c_frame = projection["t_frame_s"], projection["cells_per_frame"]
    t_start, f_w = projection["t_start_s"], projection["frames_per_worker"]
    print(f"tile projection: save_tiles {s_frame*1e3:.1f} ms/frame, tile merge "
          f"{k_tile*1e6:.1f} us/cell, {tiles_per_frame:.3f} tiles/frame, "
          f"{seconds_per_task*1e3:.1f} ms/task (assumed)")
    rows = []
    for tree_row in projection["rows"]:
        w = tree_row["workers"]
        total = w * f_w
        seg = f_w * (t_frame + s_frame)
        merge = f_w * c_frame * k_tile
        tile_tasks = tiles_per_frame * total
        scheduler = tile_tasks * seconds_per_task
        wall = t_start + seg + merge + scheduler
        grouped_tasks = max(tile_tasks / grouped_tiles_per_task, min(tile_tasks, w))
        grouped_wall = t_start + seg + merge + grouped_tasks * seconds_per_task
        rows.append(dict(workers=w, frames=total, segment_s=seg, merge_s=merge,
                         tile_tasks=tile_tasks, scheduler_s=scheduler, wall_time_s=wall,
                         frames_per_s=total / wall, tree_frames_per_s=tree_row["frames_per_s"],
                         grouped_tasks=grouped_tasks, grouped_wall_time_s=grouped_wall,
                         grouped_frames_per_s=total / grouped_wall,
                         ideal_frames_per_s=w / t_frame))
        print(f"  {w} workers: segments {seg:.0f} s + tile merges {merge:.1f} s + "
              f"scheduler {scheduler:.0f} s ({tile_tasks:.0f} tile tasks) = {wall:.0f} s: "
              f"{total / wall:.0f} frames/s; {grouped_tiles_per_task} tiles per task: "
              f"{grouped_tasks:.0f} tasks, {total / grouped_wall:.0f} frames/s (tree "
              f"{tree_row['frames_per_s']:.0f}, ideal {w / t_frame:.0f})")
    return dict(save_tiles_s_per_frame=s_frame, tile_merge_s_per_cell=k_tile,
                tiles_per_frame=tiles_per_frame, seconds_per_task=seconds_per_task,
                grouped_tiles_per_task=grouped_tiles_per_task, rows=rows)


if __name__ == "__main__":
    main()
