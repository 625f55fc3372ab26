# SPDX-License-Identifier: BSD-3-Clause
"""Batch mapping on a Dask cluster: a recording (or several) mapped in frame segments,
one Dask task per segment, and the segment maps merged pairwise in a tree of merge tasks
into one map, or, with merge="tiles", merged by region: each segment saves its map as
tiles and one task per tile key merges that tile over the segments that hold it.

    import planar_grid.distributed as pgd
    report = pgd.map_segments("config/karlsruhe.yaml", num_segments=4, n_workers=2,
                              output_dir="/tmp/batch")
    # /tmp/batch/map.pgmap, /tmp/batch/batch_report.json, /tmp/batch/segments/...

The segment maps share one world frame when the poses do (GPS/INS poses such as
Karlsruhe's, or recordings registered beforehand), so they are merged with the identity
transform (PlanarGridMap.merge). Every task writes its output under its own name in
output_dir, atomically (a temporary name, then a rename), and is a pure function of its
inputs: a task that runs twice (a worker that died mid-task, its task run again
elsewhere) leaves the same file. The files are exchanged through output_dir, so on a
cluster of several machines output_dir must be on a filesystem every worker and the
client see at the same path, and so must the configurations and their inputs.

The command planar_grid_batch runs main(); docs/SCALE.md has the measured figures.
"""
from __future__ import annotations

import dataclasses
import errno
import fcntl
import json
import os
import shutil
import sys
import time
import uuid
from typing import Any, Callable, Dict, List, Optional, Sequence, Tuple, Union

import numpy as np

import planar_grid as pg
from planar_grid.analysis import (map_counts, parallel_plane_stacks,  # noqa: F401
                                 sample_observed_points)
from planar_grid.distributed_tiles import (  # noqa: F401 (tasks the workers import)
    _flat_reports, _replace_folder, _worker_identity, merge_tile_task, merge_tiles_task,
    prepare_tile_merge_task, save_tiles_task, write_tile_index_task)

#: Version of the batch report's layout (batch_report.json); raised when a field changes
#: meaning or is removed.
BATCH_REPORT_SCHEMA_VERSION = 1

#: Exit statuses of planar_grid_batch, the classes of planar_grid_pipeline's.
EXIT_FAILURE = 1
EXIT_USAGE = 2
EXIT_CONFIG = 3
EXIT_INPUT = 4
EXIT_OUTPUT = 5

PathLike = Union[str, "os.PathLike[str]"]


@dataclasses.dataclass(frozen=True)
class Segment:
    """One task of a batch: frame positions begin .. end - 1 (0-based, end excluded) of
    the recording a configuration file describes.

    Attributes
    ----------
    config : str
        The configuration file (an absolute path).
    begin, end : int
        The frame range, as run_pipeline(frames=(begin, end)).
    """

    config: str
    begin: int
    end: int

    def describe(self) -> str:
        """The segment as the messages name it: 'config frames begin:end'."""
        return f"{self.config} frames {self.begin}:{self.end}"


class BatchError(RuntimeError):
    """A batch task failed. The message names the task's input (the configuration and
    frame range of a segment, or the maps of a merge) and the cause; ``cause`` is the
    task's own exception (e.g. planar_grid.IOError for a missing input file) and
    ``segment`` the Segment, or None for a merge or tile task. The maps of the tasks
    that had finished stay in output_dir."""

    def __init__(self, message: str, cause: BaseException,
                 segment: Optional[Segment] = None):
        super().__init__(message)
        self.cause = cause
        self.segment = segment


# --------------------------------------------------------------------------- the tasks
# Module-level functions: the workers import them by name (planar_grid.distributed).


def count_frames_task(config: str) -> int:
    """Task: frames in the input of ``config`` (planar_grid.input_frame_count)."""
    return int(pg.input_frame_count(config))


def map_segment_task(segment: Segment, folder: str,
                     tile_size_m: Optional[float] = None) -> Dict[str, Any]:
    """Task: runs the pipeline on one segment and writes ``folder/map.pgmap`` and
    ``folder/report.json`` (the pipeline's report), and with tile_size_m the map as
    tiles in ``folder/tiles`` (save_tiles), all or none.

    Parameters
    ----------
    segment : Segment
        The configuration and frame range.
    folder : str
        The segment's own output folder (replaced as a whole when the task ends).
    tile_size_m : float, optional
        Also save the map as tiles of this many meters. Default: no tiles.

    Returns
    -------
    dict
        The task report: the segment, the map's path and counts, the pipeline report's
        path, wall time in seconds, start and end (Unix time, seconds), and the host and
        process that ran it; with tile_size_m also ``tiles`` (the tile folder),
        ``tile_keys`` (the keys [i, j] of its tiles) and ``save_tiles_s``.

    Raises
    ------
    planar_grid.ConfigError, planar_grid.IOError, planar_grid.Error
        As run_pipeline() raises them (bad configuration, missing input, a frame range
        outside the input).
    ValueError
        When the configuration has no map_integration stage (no map to merge).
    """
    start = time.perf_counter()
    start_time = time.time()
    pg.set_verbosity("error")
    # Every frame on the worker's one thread: a worker is one core of the cluster (the
    # result is the same as with the frame overlap on a second thread).
    result = pg.run_pipeline(segment.config, frames=(segment.begin, segment.end),
                             write_outputs=False, sequential=True)
    if result.map is None:
        raise ValueError(f"{segment.config} has no map_integration stage: the segment "
                         "makes no map to merge")
    parent = os.path.dirname(folder)
    tmp = os.path.join(parent, f".{os.path.basename(folder)}.{uuid.uuid4().hex}.tmp")
    os.makedirs(tmp)
    tiles: Dict[str, Any] = {}
    try:
        result.map.save(os.path.join(tmp, "map.pgmap"))
        with open(os.path.join(tmp, "report.json"), "w", encoding="utf-8") as f:
            json.dump(result.report, f, indent=1)
        if tile_size_m is not None:
            t = time.perf_counter()
            index = pg.save_tiles(result.map, os.path.join(tmp, "tiles"), tile_size_m)
            tiles = dict(tiles=os.path.join(folder, "tiles"),
                         tile_keys=[[int(k) for k in tile["key"]]
                                    for tile in index["tiles"]],
                         save_tiles_s=round(time.perf_counter() - t, 4))
        _replace_folder(tmp, folder)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    report = dict(kind="segment", config=segment.config,
                  frames=[int(segment.begin), int(segment.end)],
                  map=os.path.join(folder, "map.pgmap"),
                  pipeline_report=os.path.join(folder, "report.json"),
                  **map_counts(result.map),
                  frames_run=int(result.frames), **tiles,
                  wall_time_s=round(time.perf_counter() - start, 3),
                  start_time=start_time, end_time=time.time(),
                  worker=_worker_identity())
    return report


def merge_maps_task(inputs: Sequence[Dict[str, Any]], path: str) -> Dict[str, Any]:
    """Task: merges the maps of ``inputs`` (task reports with a ``map`` path), in order,
    into the first with the identity transform, and writes the result to ``path``
    atomically.

    Returns
    -------
    dict
        The task report: the input maps, the output, the counts of the merged map, and
        the seconds spent loading, merging and saving.
    """
    start = time.perf_counter()
    start_time = time.time()
    pg.set_verbosity("error")
    maps = [r["map"] for r in inputs]
    t = time.perf_counter()
    merged = pg.PlanarGridMap.load(maps[0])
    others = [pg.PlanarGridMap.load(p) for p in maps[1:]]
    load_s = time.perf_counter() - t
    t = time.perf_counter()
    for other in others:
        merged.merge(other, np.eye(4))
    merge_s = time.perf_counter() - t
    t = time.perf_counter()
    tmp = f"{path}.{uuid.uuid4().hex}.tmp"
    try:
        merged.save(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise
    save_s = time.perf_counter() - t
    return dict(kind="merge", inputs=maps, map=path, **map_counts(merged),
                load_s=round(load_s, 4), merge_s=round(merge_s, 4),
                save_s=round(save_s, 4),
                wall_time_s=round(time.perf_counter() - start, 3),
                start_time=start_time, end_time=time.time(),
                worker=_worker_identity())


# ------------------------------------------------------------------------- the client


def split_frames(begin: int, end: int, num_segments: int) -> List[Tuple[int, int]]:
    """Splits frames begin .. end - 1 into num_segments contiguous ranges whose sizes
    differ by at most one frame.

    Raises
    ------
    ValueError
        When num_segments < 1 or the range has fewer frames than num_segments.
    """
    frames = end - begin
    if num_segments < 1:
        raise ValueError(f"num_segments must be >= 1, not {num_segments}")
    if frames < num_segments:
        raise ValueError(f"frames {begin}:{end} ({max(frames, 0)} frames) cannot be split "
                         f"into {num_segments} segments")
    bounds = [begin + (frames * i) // num_segments for i in range(num_segments + 1)]
    return list(zip(bounds[:-1], bounds[1:]))


def _merge_tree(count: int) -> List[List[Tuple[int, ...]]]:
    """The levels of a pairwise merge tree over count leaves: each level lists, for each
    node, the indices of the previous level's nodes it merges (a pair, or a single node
    carried up when the level has an odd count)."""
    levels = []
    width = count
    while width > 1:
        level = [tuple(range(i, min(i + 2, width))) for i in range(0, width, 2)]
        levels.append(level)
        width = len(level)
    return levels


def _as_segments(configs: List[str], segments: Optional[Sequence[Any]]
                 ) -> Optional[List[Segment]]:
    """Checks the explicit segments: Segment, (config, begin, end) or, with one
    configuration, (begin, end)."""
    if segments is None:
        return None
    out = []
    for s in segments:
        if isinstance(s, Segment):
            seg = Segment(os.path.abspath(s.config), int(s.begin), int(s.end))
        elif len(s) == 3:
            seg = Segment(os.path.abspath(os.fspath(s[0])), int(s[1]), int(s[2]))
        elif len(s) == 2:
            if len(configs) != 1:
                raise ValueError("a (begin, end) segment needs exactly one configuration; "
                                 "with several, give (config, begin, end)")
            seg = Segment(configs[0], int(s[0]), int(s[1]))
        else:
            raise ValueError(f"a segment is (begin, end) or (config, begin, end), not {s!r}")
        if seg.begin < 0 or seg.end <= seg.begin:
            raise ValueError(f"segment {seg.describe()}: the frame range is empty or "
                             "negative")
        out.append(seg)
    if not out:
        raise ValueError("segments is empty")
    return out


def _failure(future, what: str, segment: Optional[Segment]) -> BatchError:
    cause = future.exception()
    text = str(cause) or type(cause).__name__
    return BatchError(f"{what} failed: {type(cause).__name__}: {text}", cause, segment)


def map_segments(config: Union[PathLike, Sequence[PathLike]], *,
                 segments: Optional[Sequence[Any]] = None,
                 num_segments: int = 4,
                 frames: Optional[Tuple[Optional[int], Optional[int]]] = None,
                 output_dir: PathLike = "output/batch",
                 scheduler_address: Optional[str] = None,
                 n_workers: int = 2,
                 tile_size_m: Optional[float] = None,
                 merge: str = "tree",
                 tiles_per_task: int = 1,
                 progress: Union[bool, Callable[[str], None]] = True,
                 ) -> Dict[str, Any]:
    """Maps recordings in frame segments on a Dask cluster and merges the segment maps.

    Each segment is one Dask task that runs the pipeline on its frames
    (run_pipeline(frames=...), every frame on the worker's one thread) and writes
    ``output_dir/segments/<NNN>_<config>_<begin>-<end>/map.pgmap`` with the pipeline's
    ``report.json``. The segment maps are then merged pairwise, neighbours in frame
    order first, by merge tasks (``output_dir/merges/level<L>_<N>.pgmap``), the root
    writing ``output_dir/map.pgmap``; ``tile_size_m`` also writes it as tiles
    (``output_dir/tiles``). With ``merge="tiles"`` the maps are merged by region
    instead, and no task holds the whole map: each segment task also saves its map as
    tiles of tile_size_m (``<segment folder>/tiles``), one task per tile key merges
    that key over the segments that hold it, in frame order (merge_tile), into
    ``output_dir/tiles``, and a last task writes that set's index; the merged map is
    that tile set (load_tiles), and no ``output_dir/map.pgmap`` is written. The task
    reports are collected into ``output_dir/batch_report.json`` (returned as a dict).

    Parameters
    ----------
    config : str or os.PathLike, or a sequence of them
        The configuration file(s) (schema: config/example.yaml), each with a
        map_integration stage. Several files are several recordings, each split into
        num_segments; all must give poses in one world frame (the maps are merged with
        the identity transform).
    segments : sequence, optional
        The segments to run instead of splitting: each (begin, end) (one configuration
        only), (config, begin, end) or a Segment; frame positions are 0-based, end
        excluded. A range outside the input fails its task (BatchError).
    num_segments : int, optional
        Segments per recording when ``segments`` is not given (default 4), >= 1; the
        frames are split into contiguous ranges whose sizes differ by at most one.
    frames : tuple of (int or None, int or None), optional
        (begin, end): split only these frame positions of each recording (as
        run_pipeline's frames; not with ``segments``). Default: every frame. A range
        outside the input is a ValueError.
    output_dir : str or os.PathLike, optional
        The job's folder (created; default ``output/batch``). On a cluster of several
        machines, a filesystem every worker sees at the same path.
    scheduler_address : str, optional
        A running Dask scheduler ("tcp://host:8786") to run the job on. Default: a
        ``distributed.LocalCluster`` of n_workers processes on 127.0.0.1 (one thread
        each, no dashboard), started for the job and stopped after it.
    n_workers : int, optional
        Worker processes of the local cluster (default 2), >= 1; ignored with
        scheduler_address.
    tile_size_m : float, optional
        Also save the merged map as tiles of this many meters (save_tiles): a whole
        number of voxels, in (0, 1e5]. Default: no tiles. Required with
        ``merge="tiles"``, where it is the size of the tiles merged.
    merge : str, optional
        "tree" (default): the segment maps merged pairwise in a tree of merge tasks;
        "tiles": merged tile by tile (see above). Both give the same voxels; the tile
        merge skips the planes' tidying after each merge (docs/SCALE.md has the
        figures).
    tiles_per_task : int, optional
        With ``merge="tiles"``: tile keys merged by one task, one after another
        (default 1), >= 1; neighbouring keys (in (i, j) order) share a task. More keys
        per task mean fewer tasks for the scheduler to hand out on a large job; the
        tiles written are the same.
    progress : bool or callable, optional
        True (default): a line per finished task on stdout; a callable receives each
        line instead; False: silent.

    Returns
    -------
    dict
        The batch report (as written to batch_report.json): ``schema_version``, the
        configurations, ``merge`` ("tree" or "tiles"), ``segments`` and ``merges``
        (the task reports, in job order: config, frames, map path, planes,
        planar_cuboids, non_planar_cuboids, cells, memory_bytes, wall_time_s, worker),
        ``tile_merges`` (with merge="tiles": one report per tile task, key, inputs,
        tile, the merged tile's counts, merge_s, wall_time_s; else empty), ``map``
        (the merged map's path; None with merge="tiles") with its counts (None with
        merge="tiles"), ``tiles`` (the tile set's folder, tile count, generation; or
        None), the cluster and the job's wall time in seconds.

    Raises
    ------
    ValueError
        For invalid arguments (num_segments, n_workers, tile_size_m, merge, frames
        outside the input or given with segments, an empty or malformed segment
        list).
    BatchError
        When a task fails: the message names its input (configuration and frame range)
        and the cause (``.cause``: e.g. planar_grid.ConfigError, planar_grid.IOError);
        the remaining tasks are cancelled and the segment maps already written stay in
        output_dir.
    OSError
        When output_dir cannot be created, or another run (a batch job or
        planar_grid_pipeline) holds it: the job takes the folder's lock
        (``output_dir/.planar_grid_lock``, flock(2), never through a symbolic link)
        before its first task, and the message names the holder's process id.
    """
    import distributed  # noqa: F401 (without Dask, fail before touching the folder)

    job_start = time.perf_counter()
    configs = [os.path.abspath(os.fspath(c)) for c in
               ([config] if isinstance(config, (str, os.PathLike)) else list(config))]
    if not configs:
        raise ValueError("no configuration given")
    seen: Dict[str, str] = {}
    for c in configs:
        real = os.path.realpath(c)
        if real in seen:
            raise ValueError(f"the configuration {c} is given twice (also as "
                             f"{seen[real]}): a recording merged with itself counts its "
                             "observations twice")
        seen[real] = c
    if n_workers < 1:
        raise ValueError(f"n_workers must be >= 1, not {n_workers}")
    if num_segments < 1:
        raise ValueError(f"num_segments must be >= 1, not {num_segments}")
    if tile_size_m is not None and not tile_size_m > 0:
        raise ValueError(f"tile_size_m must be > 0 meters, not {tile_size_m}")
    if merge not in ("tree", "tiles"):
        raise ValueError(f"merge must be 'tree' or 'tiles', not {merge!r}")
    if merge == "tiles" and tile_size_m is None:
        raise ValueError("merge='tiles' needs tile_size_m (the size of the tiles merged)")
    if isinstance(tiles_per_task, bool) or not isinstance(tiles_per_task, int) \
            or tiles_per_task < 1:
        raise ValueError(
            f"tiles_per_task must be a whole number >= 1, not {tiles_per_task!r}")
    if segments is not None and frames is not None:
        raise ValueError("give either segments or frames, not both")
    explicit = _as_segments(configs, segments)
    output_dir = os.path.abspath(os.fspath(output_dir))
    os.makedirs(output_dir, exist_ok=True)
    lock = _lock_output_folder(output_dir)
    try:
        return _map_segments_locked(configs, explicit, num_segments, frames, output_dir,
                                    scheduler_address, n_workers, tile_size_m, merge,
                                    tiles_per_task, progress, job_start)
    finally:
        # Closing the descriptor releases the lock; the file stays (as the pipeline's).
        os.close(lock)


LOCK_NAME = ".planar_grid_lock"
"""The output folder's lock file, the one planar_grid_pipeline takes (flock(2))."""


def _lock_output_folder(output_dir: str) -> int:
    """Takes the output folder's lock, as planar_grid_pipeline does: an exclusive
    flock(2) on OUTPUT/.planar_grid_lock, not followed through a symbolic link, holding
    this process's id; the kernel releases it when the process ends. Returns the
    descriptor. Raises OSError naming the folder and the holder's process id when
    another run (a batch job or the pipeline) holds it."""
    path = os.path.join(output_dir, LOCK_NAME)
    try:
        fd = os.open(path, os.O_RDWR | os.O_CREAT | os.O_CLOEXEC | os.O_NOFOLLOW, 0o644)
    except OSError as e:
        if e.errno == errno.ELOOP:
            raise OSError(e.errno, f"{path}: is a symbolic link; the lock file is not "
                                   "followed through links (remove it)") from None
        raise OSError(e.errno, f"{output_dir}: cannot write into the output folder "
                               f"(creating {LOCK_NAME}): {e.strerror}") from None
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except OSError as e:
        holder = os.pread(fd, 31, 0).decode("ascii", "replace").strip()
        os.close(fd)
        if e.errno in (errno.EWOULDBLOCK, errno.EAGAIN):
            who = f"process {holder}" if holder else "process id unknown"
            raise OSError(errno.EBUSY, f"{output_dir}: the output folder is in use by "
                                       f"another run ({who} holds {path}); wait for it "
                                       "to finish or choose another output folder") \
                from None
        raise OSError(e.errno, f"{path}: cannot lock the output folder: {e.strerror}") \
            from None
    os.ftruncate(fd, 0)
    os.pwrite(fd, f"{os.getpid()}\n".encode("ascii"), 0)
    return fd


def _map_segments_locked(configs: List[str], explicit: Optional[List[Segment]],
                         num_segments: int,
                         frames: Optional[Tuple[Optional[int], Optional[int]]],
                         output_dir: str, scheduler_address: Optional[str],
                         n_workers: int, tile_size_m: Optional[float], merge: str,
                         tiles_per_task: int,
                         progress: Union[bool, Callable[[str], None]],
                         job_start: float) -> Dict[str, Any]:
    """map_segments() with the output folder locked."""
    import distributed  # only map_segments() needs Dask
    for sub in ("segments", "merges"):
        os.makedirs(os.path.join(output_dir, sub), exist_ok=True)

    say: Callable[[str], None]
    if progress is True:
        say = _print_line
    elif callable(progress):
        say = progress
    else:
        say = _ignore_line

    cluster = None
    if scheduler_address is None:
        cluster = distributed.LocalCluster(
            n_workers=n_workers, threads_per_worker=1, processes=True, host="127.0.0.1",
            dashboard_address=None, worker_dashboard_address=None, silence_logs=40)
        address = cluster.scheduler_address
    else:
        address = scheduler_address
    job = uuid.uuid4().hex[:8]
    try:
        with distributed.Client(address, set_as_default=False) as client:
            report = _run_job(client, distributed, job, configs, explicit, num_segments,
                              frames, output_dir, tile_size_m, merge, tiles_per_task,
                              say)
            report["cluster"] = dict(
                scheduler=address if cluster is None else "local",
                local=cluster is not None,
                workers=int(len(client.scheduler_info()["workers"])))
    finally:
        if cluster is not None:
            cluster.close()
    report["wall_time_s"] = round(time.perf_counter() - job_start, 3)
    _write_json(os.path.join(output_dir, "batch_report.json"), report)
    return report


def _print_line(line: str) -> None:
    print(line, flush=True)


def _ignore_line(line: str) -> None:
    pass


def _write_json(path: str, data: Dict[str, Any]) -> None:
    tmp = f"{path}.{uuid.uuid4().hex}.tmp"
    with open(tmp, "w", encoding="utf-8") as f:
        json.dump(data, f, indent=1)
        f.write("\n")
    os.replace(tmp, path)


def _run_job(client, distributed, job: str, configs: List[str],
             explicit: Optional[List[Segment]], num_segments: int,
             frames: Optional[Tuple[Optional[int], Optional[int]]], output_dir: str,
             tile_size_m: Optional[float], merge: str, tiles_per_task: int,
             say: Callable[[str], None]) -> Dict[str, Any]:
    """Submits the tasks, reports each as it finishes and collects the reports."""
    segment_list = explicit
    if segment_list is None:
        # The frame counts come from the workers, which read the inputs.
        counts = {}
        futures = {client.submit(count_frames_task, c, key=f"count-frames-{i}-{job}"): c
                   for i, c in enumerate(configs)}
        for future in distributed.as_completed(list(futures), loop=client.loop):
            if future.status != "finished":
                raise _failure(future, f"opening the input of {futures[future]}", None)
            counts[futures[future]] = int(future.result())
        segment_list = []
        for c in configs:
            begin, end = 0, counts[c]
            if frames is not None:
                begin = 0 if frames[0] is None else int(frames[0])
                end = counts[c] if frames[1] is None else int(frames[1])
                if not 0 <= begin < end <= counts[c]:
                    raise ValueError(f"frames {begin}:{end} are outside the "
                                     f"{counts[c]} frames of {c}")
            segment_list += [Segment(c, b, e) for b, e in split_frames(begin, end,
                                                                       num_segments)]

    total = len(segment_list)
    by_tile = merge == "tiles"
    tree = [] if by_tile else _merge_tree(total)
    tasks = total + sum(len(level) for level in tree) + (tile_size_m is not None)
    say(f"planar_grid_batch: {total} segments of {len(configs)} recording(s), "
        + (f"merged by {tile_size_m:g} m tile" if by_tile else
           f"{sum(len(level) for level in tree)} merges")
        + f", on {len(client.scheduler_info()['workers'])} workers")

    # key -> (the task's input as messages name it, its Segment or None)
    described: Dict[str, Tuple[str, Optional[Segment]]] = {}
    label: Dict[str, str] = {}
    level_futures = []
    for i, seg in enumerate(segment_list):
        stem = os.path.splitext(os.path.basename(seg.config))[0]
        folder = os.path.join(output_dir, "segments",
                              f"{i:03d}_{stem}_{seg.begin}-{seg.end}")
        f = client.submit(map_segment_task, seg, folder,
                          tile_size_m if by_tile else None, key=f"segment-{i:03d}-{job}")
        label[f.key] = f"segment {i + 1}/{total}"
        described[f.key] = (f"{label[f.key]} ({seg.describe()})", seg)
        level_futures.append(f)
    segment_futures = list(level_futures)
    if by_tile:
        assert tile_size_m is not None
        return _run_tile_merge(client, distributed, job, configs, segment_futures,
                               described, output_dir, tile_size_m, tiles_per_task, say)
    merge_futures = []
    for depth, level in enumerate(tree, start=1):
        nxt = []
        for j, node in enumerate(level):
            children = [level_futures[k] for k in node]
            if len(children) == 1:  # an odd node out: carried up unmerged
                nxt.append(children[0])
                continue
            path = (os.path.join(output_dir, "map.pgmap") if depth == len(tree) else
                    os.path.join(output_dir, "merges", f"level{depth}_{j:03d}.pgmap"))
            f = client.submit(merge_maps_task, children, path,
                              key=f"merge-{depth}-{j:03d}-{job}")
            label[f.key] = f"merge {depth}.{j}"
            described[f.key] = (f"{label[f.key]} ("
                                + " + ".join(label[c.key] for c in children) + ")", None)
            merge_futures.append(f)
            nxt.append(f)
        level_futures = nxt
    root_future = level_futures[0]
    all_futures = segment_futures + merge_futures
    tiles_future = None
    if tile_size_m is not None:
        tiles_future = client.submit(save_tiles_task, root_future,
                                     os.path.join(output_dir, "tiles"), tile_size_m,
                                     key=f"tiles-{job}")
        described[tiles_future.key] = ("tiles of the merged map", None)
        all_futures.append(tiles_future)

    _collect(client, distributed, all_futures, described, say, 0, tasks)

    segment_reports = [f.result() for f in segment_futures]
    merge_reports = [f.result() for f in merge_futures]
    if not merge_futures:
        # One segment: its map is the job's map.
        final_path = os.path.join(output_dir, "map.pgmap")
        tmp = f"{final_path}.{uuid.uuid4().hex}.tmp"
        shutil.copyfile(segment_reports[0]["map"], tmp)
        os.replace(tmp, final_path)
    _remove_leftovers(output_dir)
    final = root_future.result()
    return dict(
        schema_version=BATCH_REPORT_SCHEMA_VERSION,
        configs=configs,
        output_dir=output_dir,
        merge="tree",
        map=os.path.join(output_dir, "map.pgmap"),
        **{k: final[k] for k in ("planes", "planar_cuboids", "non_planar_cuboids",
                                 "cells", "memory_bytes")},
        frames=int(sum(r["frames_run"] for r in segment_reports)),
        segments=segment_reports,
        merges=merge_reports,
        tile_merges=[],
        tiles=tiles_future.result() if tiles_future is not None else None)


def _collect(client, distributed, futures: List[Any],
             described: Dict[str, Tuple[str, Optional[Segment]]],
             say: Callable[[str], None], done: int, tasks: int) -> int:
    """Waits for the futures, a progress line for each as it finishes ("[done/tasks]");
    the first that fails cancels them all and raises its BatchError. Returns done plus
    the futures' count."""
    try:
        for future in distributed.as_completed(futures, loop=client.loop):
            what, failed = described[future.key]
            if future.status != "finished":
                raise _failure(future, what, failed)
            r = future.result()
            done += 1
            say(f"[{done}/{tasks}] {what}: {r['wall_time_s']:.1f} s"
                + (f", {r['planes']} planes, {r['planar_cuboids']} planar cuboids, "
                   f"{r['cells']} cells" if "planes" in r else "")
                + f" (pid {r['worker']['pid']} on {r['worker']['host']})")
    except BaseException:
        client.cancel(futures)
        raise
    return done


def _remove_leftovers(output_dir: str) -> None:
    """Removes what attempts killed while they wrote left behind (the attempts that ran
    again wrote their own)."""
    for folder in (os.path.join(output_dir, "segments"),
                   os.path.join(output_dir, "merges"), output_dir):
        for name in os.listdir(folder):
            if name.endswith(".tmp") and (folder != output_dir
                                          or name.startswith("map.pgmap.")):
                path = os.path.join(folder, name)
                if os.path.isdir(path):
                    shutil.rmtree(path, ignore_errors=True)
                else:
                    os.remove(path)


def _run_tile_merge(client, distributed, job: str, configs: List[str],
                    segment_futures: List[Any],
                    described: Dict[str, Tuple[str, Optional[Segment]]],
                    output_dir: str, tile_size_m: float, tiles_per_task: int,
                    say: Callable[[str], None]) -> Dict[str, Any]:
    """The merge by region: once the segments have saved their tiles, one task writes
    the merged set's base, one task per tile key (or per tiles_per_task neighbouring
    keys) merges that key over the segments holding it (in segment order, which is
    frame order within a recording), and one task writes the index."""
    done = _collect(client, distributed, segment_futures, described, say, 0,
                    len(segment_futures))
    segment_reports = [f.result() for f in segment_futures]
    folder = os.path.join(output_dir, "tiles")
    holders: Dict[Tuple[int, int], List[str]] = {}
    for r in segment_reports:
        for key in r["tile_keys"]:
            holders.setdefault((key[0], key[1]), []).append(r["tiles"])
    keys = sorted(holders)
    groups = [keys[i:i + tiles_per_task] for i in range(0, len(keys), tiles_per_task)]
    tasks = done + len(groups) + 2
    say(f"planar_grid_batch: {len(keys)} tiles to merge, "
        f"{sum(len(h) > 1 for h in holders.values())} of them held by several segments")
    prepared = client.submit(prepare_tile_merge_task, segment_reports, folder,
                             key=f"tile-prepare-{job}")
    described[prepared.key] = ("tile merge: the base map", None)
    tile_futures = []
    for group in groups:
        if len(group) == 1:
            key = group[0]
            f = client.submit(merge_tile_task, holders[key], list(key), prepared, folder,
                              key=f"tile-{key[0]}_{key[1]}-{job}")
            n = len(holders[key])
            described[f.key] = (
                f"tile {key[0]} {key[1]} ({n} segment{'s' if n > 1 else ''})", None)
        else:
            first, last = group[0], group[-1]
            f = client.submit(merge_tiles_task,
                              [(holders[key], list(key)) for key in group], prepared,
                              folder,
                              key=f"tiles-{first[0]}_{first[1]}-{last[0]}_{last[1]}-{job}")
            described[f.key] = (f"tiles {first[0]} {first[1]} .. {last[0]} {last[1]} "
                                f"({len(group)} tiles)", None)
        tile_futures.append(f)
    index_future = client.submit(write_tile_index_task, prepared, tile_futures, folder,
                                 tile_size_m, key=f"tile-index-{job}")
    described[index_future.key] = ("tile merge: the index", None)
    _collect(client, distributed, [prepared] + tile_futures + [index_future], described,
             say, done, tasks)
    _remove_leftovers(output_dir)
    return dict(
        schema_version=BATCH_REPORT_SCHEMA_VERSION,
        configs=configs,
        output_dir=output_dir,
        merge="tiles",
        map=None,
        **{k: None for k in ("planes", "planar_cuboids", "non_planar_cuboids", "cells",
                             "memory_bytes")},
        frames=int(sum(r["frames_run"] for r in segment_reports)),
        segments=segment_reports,
        merges=[],
        tile_merges=_flat_reports([f.result() for f in tile_futures]),
        tiles=index_future.result())


# ------------------------------------------------------------------------ the command


def exit_status(error: BaseException) -> int:
    """The exit status of planar_grid_batch for an error, by its class as
    planar_grid_pipeline classes them: 3 configuration, 4 input, 5 output, 2 usage,
    1 anything else."""
    cause = error.cause if isinstance(error, BatchError) else error
    if isinstance(cause, pg.ConfigError):
        return EXIT_CONFIG
    if isinstance(cause, pg.IOError):
        return EXIT_INPUT
    if isinstance(cause, OSError):
        return EXIT_OUTPUT
    if isinstance(error, ValueError):
        return EXIT_USAGE
    return EXIT_FAILURE


def main(argv: Optional[Sequence[str]] = None) -> int:
    """planar_grid_batch: the command-line entry point of map_segments()
    (planar_grid.batch_cli.main; its docstring gives the exit statuses)."""
    from planar_grid.batch_cli import main as _main
    return _main(argv)
