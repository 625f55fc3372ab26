# SPDX-License-Identifier: BSD-3-Clause
"""The tasks of a merge by region (``map_segments(merge="tiles")``, planar_grid_batch
``--merge tiles``), and the helpers every task of planar_grid.distributed shares: a
folder written under a temporary name and renamed, and the worker that ran a task.

Module-level functions: the workers import them by name. planar_grid.distributed
submits them and re-exports them."""
from __future__ import annotations

import os
import shutil
import time
import uuid
from typing import Any, Dict, List, Sequence, Tuple

import planar_grid as pg
from planar_grid.analysis import map_counts


def _replace_folder(tmp: str, final: str) -> None:
    """Moves the finished folder tmp to final, replacing a final of an earlier attempt
    (the same task run again after its worker died, or an earlier job) in two renames."""
    try:
        os.rename(tmp, final)
        return
    except OSError:
        if not os.path.isdir(final):
            raise
    old = f"{final}.old-{uuid.uuid4().hex}"
    os.rename(final, old)
    os.rename(tmp, final)
    shutil.rmtree(old, ignore_errors=True)


def _worker_identity() -> Dict[str, Any]:
    """Where a task ran: host name and process id."""
    return dict(host=os.uname().nodename, pid=os.getpid())



def save_tiles_task(merged: Dict[str, Any], folder: str,
                    tile_size_m: float) -> Dict[str, Any]:
    """Task: saves the map of ``merged`` as tiles of tile_size_m meters (save_tiles) in
    ``folder``, written under a temporary name and renamed."""
    start = time.perf_counter()
    m = pg.PlanarGridMap.load(merged["map"])
    parent = os.path.dirname(folder)
    tmp = os.path.join(parent, f".{os.path.basename(folder)}.{uuid.uuid4().hex}.tmp")
    try:
        index = pg.save_tiles(m, tmp, tile_size_m)
        _replace_folder(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return dict(kind="tiles", folder=folder, tile_size_m=float(tile_size_m),
                tiles=int(len(index["tiles"])),
                wall_time_s=round(time.perf_counter() - start, 3),
                worker=_worker_identity())


def prepare_tile_merge_task(segments: Sequence[Dict[str, Any]],
                            folder: str) -> Dict[str, Any]:
    """Task: the first step of a merge by region (prepare_tile_merge): checks that the
    segments' tile sets (their reports' ``tiles``) agree and writes the merged set's
    base map into ``folder``.

    Returns
    -------
    dict
        The task report, with ``index``: the merged set's index without tiles (its
        ``generation`` names the tile files).
    """
    start = time.perf_counter()
    pg.set_verbosity("error")
    index = pg.prepare_tile_merge([r["tiles"] for r in segments], folder)
    return dict(kind="tile-prepare", folder=folder, index=index,
                wall_time_s=round(time.perf_counter() - start, 3),
                worker=_worker_identity())


def merge_tile_task(folders: Sequence[str], key: Sequence[int],
                    prepared: Dict[str, Any], folder: str) -> Dict[str, Any]:
    """Task: merges tile ``key`` of the tile sets ``folders`` (in order, earliest
    frames first) into one tile file of ``folder`` (merge_tile), named for the
    generation of ``prepared`` (prepare_tile_merge_task's report).

    Returns
    -------
    dict
        The task report: key, inputs, the tile as the index lists it (bounds as lists),
        the merged tile's counts, ``merge_s`` (loading the tiles, merging, saving) and
        wall time in seconds.
    """
    start = time.perf_counter()
    start_time = time.time()
    pg.set_verbosity("error")
    tile = pg.merge_tile(list(folders), (int(key[0]), int(key[1])), folder,
                         prepared["index"]["generation"])
    merge_s = time.perf_counter() - start
    counts = map_counts(pg.PlanarGridMap.load(os.path.join(folder, tile["file"])))
    tile = dict(key=[int(k) for k in tile["key"]], file=tile["file"],
                file_bytes=int(tile["file_bytes"]),
                bounds_min=[float(v) for v in tile["bounds_min"]],
                bounds_max=[float(v) for v in tile["bounds_max"]])
    return dict(kind="tile", key=tile["key"], inputs=list(folders), tile=tile, **counts,
                merge_s=round(merge_s, 4),
                wall_time_s=round(time.perf_counter() - start, 3),
                start_time=start_time, end_time=time.time(),
                worker=_worker_identity())


def merge_tiles_task(groups: Sequence[Tuple[Sequence[str], Sequence[int]]],
                     prepared: Dict[str, Any], folder: str) -> Dict[str, Any]:
    """Task: merge_tile_task for several tile keys, one after another: each of
    ``groups`` is (the tile sets holding the key, in frame order; the key). Fewer,
    longer tasks for the scheduler to hand out when a job has many tiles.

    Returns
    -------
    dict
        kind "tile_group", ``reports`` (merge_tile_task's report for each key, in the
        order of ``groups``), wall time in seconds and the worker.
    """
    start = time.perf_counter()
    reports = [merge_tile_task(folders, key, prepared, folder) for folders, key in groups]
    return dict(kind="tile_group", reports=reports,
                wall_time_s=round(time.perf_counter() - start, 3),
                worker=_worker_identity())


def write_tile_index_task(prepared: Dict[str, Any], tiles: Sequence[Dict[str, Any]],
                          folder: str, tile_size_m: float) -> Dict[str, Any]:
    """Task: the last step of a merge by region: writes the index of ``folder``
    (write_tile_index) naming the base of ``prepared`` and the tiles of the
    merge_tile_task reports ``tiles`` (or merge_tiles_task's groups of them); until
    then the folder reads as its previous set.

    Returns
    -------
    dict
        The task report: the folder, tile_size_m, the number of tiles, the generation
        and wall time in seconds.
    """
    start = time.perf_counter()
    index = dict(prepared["index"])
    index["tiles"] = [r["tile"] for r in _flat_reports(tiles)]
    written = pg.write_tile_index(folder, index)
    return dict(kind="tiles", folder=folder, tile_size_m=float(tile_size_m),
                tiles=int(len(written["tiles"])),
                generation=int(written["generation"]),
                wall_time_s=round(time.perf_counter() - start, 3),
                worker=_worker_identity())


def _flat_reports(items: Sequence[Dict[str, Any]]) -> List[Dict[str, Any]]:
    """Tile task reports, merge_tiles_task's groups opened up."""
    return [r for item in items
            for r in (item["reports"] if item.get("kind") == "tile_group" else [item])]
