# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.distributed: the first 40 Karlsruhe frames mapped in 4 segments on a Dask
cluster of 2 worker processes (loopback only) and merged, against one run of the same
frames (states, planar cuboids, one plane per facade); a worker killed while it maps a
segment; a segment on bad input; the command planar_grid_batch's exit statuses. Every
cluster is stopped by the test that starts it."""
import fcntl
import json
import os
import pathlib
import signal
import subprocess
import threading
import time
from typing import Any, Dict, Iterator, List, Optional, Tuple

import distributed
import numpy as np
import numpy.typing as npt
import psutil
import pytest

import planar_grid as pg
import planar_grid.distributed as pgd

FRAMES = 40

# The batch fixture: map_segments' report, its progress lines and the output folder.
Batch = Tuple[Dict[str, Any], List[str], pathlib.Path]


@pytest.fixture(scope="module")
def config(request: pytest.FixtureRequest) -> str:
    source = pathlib.Path(os.environ.get("PLANAR_GRID_SOURCE_DIR",
                                         pathlib.Path(__file__).resolve().parents[2]))
    path = source / "config" / "karlsruhe.yaml"
    data = pathlib.Path(os.environ.get("PLANAR_GRID_DATA_DIR", source / ".." / "shared" / "data"))
    if not (data / "karlsruhe_2010_03_09_drive_0023").is_dir():
        pytest.fail(f"the Karlsruhe data are missing in {data} (PLANAR_GRID_DATA_DIR)")
    return str(path)


@pytest.fixture(scope="module")
def absolute_config_text(config: str) -> str:
    """karlsruhe.yaml with its data paths absolute, for copies in a temporary folder."""
    text = pathlib.Path(config).read_text(encoding="utf-8")
    data = os.path.realpath(os.path.join(os.path.dirname(config), "..", "..", "shared",
                                         "data"))
    if "PLANAR_GRID_DATA_DIR" in os.environ:
        data = os.path.realpath(os.environ["PLANAR_GRID_DATA_DIR"])
    return text.replace("../../shared/data", data)


@pytest.fixture(scope="module")
def one_run(config: str) -> pg.PlanarGridMap:
    """The map of one sequential run of frames 0-39."""
    m: pg.PlanarGridMap = pg.run_pipeline(config, frames=(0, FRAMES), write_outputs=False).map
    return m


@pytest.fixture(scope="module")
def probes(one_run: pg.PlanarGridMap) -> npt.NDArray[np.float64]:
    """20,000 random points in the box of the main job's map that the one run observed
    (free or occupied), as scripts/measure_batch.py draws them; fixed seed."""
    return pgd.sample_observed_points(one_run, 20_000, [0.0, -52.8, -7.2],
                                      [106.4, 18.4, 8.0])


@pytest.fixture(scope="module")
def batch(config: str, tmp_path_factory: pytest.TempPathFactory) -> Batch:
    """The 4-segment job on map_segments' own local cluster of 2 worker processes."""
    out = tmp_path_factory.mktemp("batch")
    lines: List[str] = []
    report = pgd.map_segments(config, frames=(0, FRAMES), num_segments=4, n_workers=2,
                              output_dir=out, progress=lines.append)
    return report, lines, out


@pytest.fixture(scope="module")
def cluster() -> Iterator[distributed.LocalCluster]:
    """A local cluster of 2 single-threaded worker processes on 127.0.0.1, no
    dashboard, for the jobs given a scheduler address."""
    # Dask's LocalCluster is not annotated: its calls are untyped (no-untyped-call).
    c = distributed.LocalCluster(  # type: ignore[no-untyped-call]
        n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
        dashboard_address=None, silence_logs=50)
    yield c
    c.close()  # type: ignore[no-untyped-call]  # Dask's, not annotated


def planar_count(m: pg.PlanarGridMap) -> int:
    return int(np.count_nonzero(m.cuboids.is_planar))


def test_four_segments_agree_with_one_run(batch: Batch, one_run: pg.PlanarGridMap,
                                          probes: npt.NDArray[np.float64]) -> None:
    report, lines, out = batch
    merged = pg.PlanarGridMap.load(report["map"])
    # getState on the points the one run observed: 4 segments join as the halves of the
    # whole drive do (docs/MAP.md: 99.82 %); a segment's first frames see less of what
    # the frames before it confirmed, so a little below that.
    agree = np.mean(merged.get_state(probes) == one_run.get_state(probes))
    assert agree >= 0.99, agree
    # the segments' observation spans are ordered, so the newer segment's voxels win
    # where two saw the same space, as in the one run: its space layer, voxel for voxel
    assert merged.voxel_counts == one_run.voxel_counts
    ratio = planar_count(merged) / planar_count(one_run)
    assert 0.9 <= ratio <= 1.1, (planar_count(merged), planar_count(one_run))
    # the report: 4 segments covering 0-39 in order, 3 merges (2 + the root), ints
    assert report["schema_version"] == pgd.BATCH_REPORT_SCHEMA_VERSION
    assert [s["frames"] for s in report["segments"]] == [[0, 10], [10, 20], [20, 30],
                                                          [30, 40]]
    assert len(report["merges"]) == 3 and report["frames"] == FRAMES
    assert report["merges"][-1]["map"] == str(out / "map.pgmap")
    assert report["planar_cuboids"] == planar_count(merged)
    assert report["cluster"] == dict(scheduler="local", local=True, workers=2)
    for s in report["segments"]:
        assert isinstance(s["planes"], int) and isinstance(s["cells"], int)
        assert os.path.isfile(s["map"]) and os.path.isfile(s["pipeline_report"])
    with open(out / "batch_report.json", encoding="utf-8") as f:
        assert json.load(f) == report
    # one line per task after the job's line
    assert len(lines) == 1 + 4 + 3 and lines[-1].startswith("[7/7] merge 2.0")
    # the local cluster is stopped: no worker or nanny process is left (multiprocessing's
    # resource tracker stays for the life of the interpreter)
    left = [p.cmdline() for p in psutil.Process().children(recursive=True)
            if "multiprocessing.resource_tracker" not in " ".join(p.cmdline())]
    assert left == []


def test_the_facades_are_one_plane_each_after_the_merge(batch: Batch,
                                                       one_run: pg.PlanarGridMap) -> None:
    # A facade seen by several segments joins as one plane in the merge (association,
    # converged planes, absorbed rectangles, as in integration), not a stack of parallel
    # vertical planes a few decimetres apart (pgd.parallel_plane_stacks): the merged map
    # has none, as the one run of the same frames has none.
    merged = pg.PlanarGridMap.load(batch[0]["map"])
    assert pgd.parallel_plane_stacks(one_run) == []
    assert pgd.parallel_plane_stacks(merged) == []
    # the segments hold facades more than once: the merge joined vertical planes
    segments = [pg.PlanarGridMap.load(s["map"]) for s in batch[0]["segments"]]
    vertical = [int(np.count_nonzero(np.abs(s.planes[:, 2]) <= 0.3)) for s in segments]
    assert sum(vertical) > int(np.count_nonzero(np.abs(merged.planes[:, 2]) <= 0.3))


def test_killed_worker_task_runs_again_with_the_same_map(
        config: str, batch: Batch, cluster: distributed.LocalCluster, tmp_path: pathlib.Path,
        probes: npt.NDArray[np.float64]) -> None:
    expected = pg.PlanarGridMap.load(batch[0]["map"])
    # Dask's Client is not annotated (no-untyped-call).
    with distributed.Client(  # type: ignore[no-untyped-call]
            cluster.scheduler_address, set_as_default=False) as client:
        pids = client.run(os.getpid)
        result: Dict[str, Dict[str, Any]] = {}
        failure: List[BaseException] = []

        def job() -> None:
            try:
                result["report"] = pgd.map_segments(
                    config, frames=(0, FRAMES), num_segments=4,
                    scheduler_address=cluster.scheduler_address, output_dir=tmp_path,
                    progress=False)
            except BaseException as e:  # handed to the test's thread
                failure.append(e)

        thread = threading.Thread(target=job)
        thread.start()
        # The tasks a worker executes now (the scheduler's processing() lists those
        # queued on it too); nested, so that it is pickled by value for the workers.
        def executing(dask_worker: distributed.Worker) -> List[str]:
            return [str(ts.key) for ts in dask_worker.state.executing]

        # A segment task seen executing, its worker killed 0.5 s later if the task is
        # still executing there then (a 10-frame segment runs for 1.5 s or more).
        victim: Optional[Tuple[str, str]] = None
        deadline = time.monotonic() + 60
        while victim is None and time.monotonic() < deadline and thread.is_alive():
            segment_keys = {w: [k for k in keys if k.startswith("segment-")]
                            for w, keys in client.run(executing).items() if w in pids}
            seen = {w: keys[0] for w, keys in segment_keys.items() if keys}
            time.sleep(0.5)
            if seen:
                now = client.run(executing)
                for worker, key in seen.items():
                    if key in now.get(worker, []):
                        killed_at = time.time()
                        os.kill(pids[worker], signal.SIGKILL)
                        victim = (worker, key)
                        break
        assert victim is not None, "no segment task was seen executing"
        thread.join(timeout=180)
        assert not thread.is_alive(), "the job did not finish after the kill"
    assert not failure, failure
    report = result["report"]
    index = int(victim[1].split("-")[1])
    # the killed task ran again from its start, in another process
    assert report["segments"][index]["worker"]["pid"] != pids[victim[0]]
    assert report["segments"][index]["start_time"] > killed_at
    merged = pg.PlanarGridMap.load(report["map"])
    assert np.array_equal(np.asarray(merged.get_state(probes)),
                          np.asarray(expected.get_state(probes)))
    for key in ("planes", "planar_cuboids", "non_planar_cuboids", "cells"):
        assert report[key] == batch[0][key], key


def test_bad_input_names_it_and_keeps_the_maps_done(config: str, absolute_config_text: str,
                                                    cluster: distributed.LocalCluster,
                                                    tmp_path: pathlib.Path) -> None:
    missing = tmp_path / "no_such_calib.txt"
    bad = tmp_path / "bad_calibration.yaml"
    text = absolute_config_text
    start = text.index("file:", text.index("calibration:"))
    end = text.index("\n", start)
    bad.write_text(text[:start] + f"file: {missing}" + text[end:], encoding="utf-8")
    # the bad segment last: the two good ones take both workers first
    with pytest.raises(pgd.BatchError) as error:
        pgd.map_segments([config, bad],
                         segments=[(config, 0, 10), (config, 10, 20), (bad, 0, 10)],
                         scheduler_address=cluster.scheduler_address,
                         output_dir=tmp_path / "out", progress=False)
    message = str(error.value)
    assert str(bad) in message and "frames 0:10" in message, message
    assert "no_such_calib.txt" in message, message
    assert isinstance(error.value.cause, pg.IOError)
    assert error.value.segment == pgd.Segment(str(bad), 0, 10)
    assert pgd.exit_status(error.value) == pgd.EXIT_INPUT
    done = sorted((tmp_path / "out" / "segments").glob("*/map.pgmap"))
    assert done, "no segment map was kept"
    for path in done:
        assert "bad_calibration" not in str(path)
        assert pg.PlanarGridMap.load(str(path)).cell_count > 0
    assert not (tmp_path / "out" / "map.pgmap").exists()


def test_frame_range_past_the_end_is_named(config: str, cluster: distributed.LocalCluster,
                                           tmp_path: pathlib.Path) -> None:
    with pytest.raises(pgd.BatchError) as error:
        pgd.map_segments(config, segments=[(0, 5), (200, 210)],
                         scheduler_address=cluster.scheduler_address,
                         output_dir=tmp_path, progress=False)
    message = str(error.value)
    assert f"{config} frames 200:210" in message and "112 frames" in message, message
    # the same range split by the client is refused before any task
    with pytest.raises(ValueError, match="outside the 112 frames"):
        pgd.map_segments(config, frames=(100, 120),
                         scheduler_address=cluster.scheduler_address,
                         output_dir=tmp_path, progress=False)


def test_one_segment_is_the_map(config: str, cluster: distributed.LocalCluster,
                                tmp_path: pathlib.Path) -> None:
    report = pgd.map_segments(config, frames=(0, 4), num_segments=1,
                              scheduler_address=cluster.scheduler_address,
                              output_dir=tmp_path, progress=False)
    assert report["merges"] == [] and len(report["segments"]) == 1
    with open(tmp_path / "map.pgmap", "rb") as merged, \
            open(report["segments"][0]["map"], "rb") as segment:
        assert merged.read() == segment.read()
    assert not [p for p in tmp_path.rglob("*.tmp")]
    with pytest.raises(ValueError, match="not both"):
        pgd.map_segments(config, frames=(0, 4), segments=[(0, 4)], output_dir=tmp_path,
                         scheduler_address=cluster.scheduler_address)


def test_split_and_tree() -> None:
    assert pgd.split_frames(0, 10, 4) == [(0, 2), (2, 5), (5, 7), (7, 10)]
    assert pgd.split_frames(5, 8, 3) == [(5, 6), (6, 7), (7, 8)]
    with pytest.raises(ValueError):
        pgd.split_frames(0, 3, 4)
    with pytest.raises(ValueError):
        pgd.split_frames(0, 3, 0)
    assert pgd._merge_tree(1) == []
    assert pgd._merge_tree(4) == [[(0, 1), (2, 3)], [(0, 1)]]
    assert pgd._merge_tree(5) == [[(0, 1), (2, 3), (4,)], [(0, 1), (2,)], [(0, 1)]]


def batch_tool() -> str:
    build = os.environ.get("PLANAR_GRID_BUILD_DIR")
    if build is None:
        pytest.fail("PLANAR_GRID_BUILD_DIR is not set (CTest sets it)")
    return os.path.join(build, "tools", "planar_grid_batch")


def run_tool(*args: str, cwd: pathlib.Path) -> "subprocess.CompletedProcess[str]":
    env = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}
    return subprocess.run([batch_tool(), *args], capture_output=True, text=True,
                          cwd=cwd, env=env, timeout=120)


def test_command_exit_statuses(config: str, tmp_path: pathlib.Path) -> None:
    # the build folder's command finds the build folder's package by itself
    version = run_tool("--version", cwd=tmp_path)
    assert version.returncode == 0 and version.stdout.strip() == \
        f"planar_grid_batch {pg.__version__}", version
    usage = run_tool("--config", config, "--segments", "0", cwd=tmp_path)
    assert usage.returncode == pgd.EXIT_USAGE and "--segments" in usage.stderr, usage
    frames = run_tool("--config", config, "--frames", "9:3", cwd=tmp_path)
    assert frames.returncode == pgd.EXIT_USAGE and "9:3" in frames.stderr, frames
    missing = run_tool("--config", str(tmp_path / "none.yaml"), cwd=tmp_path)
    assert missing.returncode == pgd.EXIT_INPUT and "none.yaml" in missing.stderr, missing
    unwritable = run_tool("--config", config, "--output", "/dev/null/batch", cwd=tmp_path)
    assert unwritable.returncode == pgd.EXIT_OUTPUT and "/dev/null" in unwritable.stderr, \
        unwritable
    bad = tmp_path / "bad.yaml"
    bad.write_text("input:\n  type: no_such_input\n", encoding="utf-8")
    config_error = run_tool("--config", str(bad), "--workers", "1", "--output",
                            str(tmp_path / "out"), cwd=tmp_path)
    assert config_error.returncode == pgd.EXIT_CONFIG, config_error
    assert "bad.yaml" in config_error.stderr, config_error.stderr


def test_a_second_job_into_the_folder_is_refused(config: str, tmp_path: pathlib.Path) -> None:
    # Another run holds the folder's lock (the pipeline's lock file, flock(2)): the job
    # is refused before its first task, naming the holder, and the command exits 5.
    out = tmp_path / "job"
    out.mkdir()
    holder = os.open(out / pgd.LOCK_NAME, os.O_RDWR | os.O_CREAT, 0o644)
    try:
        fcntl.flock(holder, fcntl.LOCK_EX)
        os.write(holder, b"4242\n")
        with pytest.raises(OSError, match=r"in use by another run \(process 4242 holds"):
            pgd.map_segments(config, frames=(0, 2), num_segments=1, n_workers=1,
                             output_dir=out, progress=False)
        assert not (out / "segments").exists()
        refused = run_tool("--config", config, "--frames", "0:2", "--segments", "1",
                           "--workers", "1", "--output", str(out), cwd=tmp_path)
        assert refused.returncode == pgd.EXIT_OUTPUT, refused
        assert "in use by another run (process 4242" in refused.stderr, refused.stderr
    finally:
        os.close(holder)
    # A link in the lock file's place is not followed: its target keeps its bytes.
    (out / pgd.LOCK_NAME).unlink()
    precious = tmp_path / "precious.txt"
    precious.write_text("keep me", encoding="utf-8")
    os.symlink(precious, out / pgd.LOCK_NAME)
    with pytest.raises(OSError, match="is a symbolic link"):
        pgd.map_segments(config, frames=(0, 2), num_segments=1, n_workers=1,
                         output_dir=out, progress=False)
    assert precious.read_text(encoding="utf-8") == "keep me"


def test_a_configuration_given_twice_is_refused(config: str, tmp_path: pathlib.Path) -> None:
    # One recording twice in one world frame would count each observation twice.
    for again in (config, os.path.join(os.path.dirname(config), ".",
                                       os.path.basename(config))):
        with pytest.raises(ValueError, match="is given twice"):
            pgd.map_segments([config, again], num_segments=1, n_workers=1,
                             output_dir=tmp_path / "twice", progress=False)
    assert not (tmp_path / "twice").exists()
