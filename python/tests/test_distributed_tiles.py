# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.distributed with merge="tiles": Karlsruhe frames 0-59 mapped in 3
segments on a Dask cluster of 2 worker processes (loopback only), each segment's map
saved as 20 m tiles and merged tile by tile, against the same segments merged in the
tree (getState on probes, voxels, planar cuboids). Every cluster is stopped by the test
that starts it; CTest bounds the file's time."""
import os
import pathlib
from typing import Any, Dict, List, Tuple

import numpy as np
import psutil
import pytest

import planar_grid as pg
import planar_grid.distributed as pgd

FRAMES = 60
SEGMENTS = 3
TILE_M = 20.0
EVERYWHERE = (np.full(3, -np.inf), np.full(3, np.inf))

# A job of the jobs fixture: map_segments' report, its progress lines and the output folder.
Job = Tuple[Dict[str, Any], List[str], pathlib.Path]


@pytest.fixture(scope="module")
def config() -> str:
    source = pathlib.Path(os.environ.get("PLANAR_GRID_SOURCE_DIR",
                                         pathlib.Path(__file__).resolve().parents[2]))
    data = pathlib.Path(os.environ.get("PLANAR_GRID_DATA_DIR",
                                       source / ".." / "shared" / "data"))
    if not (data / "karlsruhe_2010_03_09_drive_0023").is_dir():
        pytest.fail(f"the Karlsruhe data are missing in {data} (PLANAR_GRID_DATA_DIR)")
    return str(source / "config" / "karlsruhe.yaml")


@pytest.fixture(scope="module")
def jobs(config: str, tmp_path_factory: pytest.TempPathFactory) -> Dict[str, Job]:
    """The same 3 segments merged in the tree (its map also saved as 20 m tiles), by
    tile, and by tile with 4 tile keys per task, each job on map_segments' own local
    cluster of 2 worker processes."""
    out: Dict[str, Job] = {}
    for name, merge, per_task in (("tree", "tree", 1), ("tiles", "tiles", 1),
                                  ("grouped", "tiles", 4)):
        folder = tmp_path_factory.mktemp(name)
        lines: List[str] = []
        report = pgd.map_segments(config, frames=(0, FRAMES), num_segments=SEGMENTS,
                                  n_workers=2, output_dir=folder, tile_size_m=TILE_M,
                                  merge=merge, tiles_per_task=per_task,
                                  progress=lines.append)
        out[name] = (report, lines, folder)
    return out


def planar_count(m: pg.PlanarGridMap) -> int:
    return int(np.count_nonzero(m.cuboids.is_planar))


def test_the_tile_merge_equals_the_tree_merge(jobs: Dict[str, Job]) -> None:
    tree_report, _, _ = jobs["tree"]
    report, lines, folder = jobs["tiles"]
    tree = pg.PlanarGridMap.load(tree_report["map"])
    tree_tiles = pg.load_tiles(tree_report["tiles"]["folder"], *EVERYWHERE)
    merged = pg.load_tiles(report["tiles"]["folder"], *EVERYWHERE)
    # The space layer, voxel for voxel: every tile merges its segments in frame order,
    # so the newest segment's observation of a voxel wins, as in the tree.
    assert merged.voxel_counts == tree.voxel_counts
    # getState on 20,000 random points the tree's map observed, against the tree's map
    # saved as tiles and loaded. The tile merge skips the planes' tidying after each
    # merge (absorbing parallel rectangles, removing non-planar cells on planes), as
    # load_tiles does, so a cuboid the tree's tidying moved or removed may answer a
    # probe. Stated tolerance 99.9 % (measured: all 20,000 agree).
    probes = pgd.sample_observed_points(tree, 20_000, [0.0, -52.8, -7.2],
                                        [106.4, 18.4, 8.0])
    agree = np.mean(merged.get_state(probes) == tree_tiles.get_state(probes))
    assert agree >= 0.999, agree
    # Planar cuboids within 10 % of the tree's (measured: 174 against 165, +5.5 %): the
    # rectangles the tree's tidying absorbed into a parallel plane stay, and the covers
    # of planes that met in some tiles only differ near those tiles' borders; a few
    # cuboids weigh more now that the segmentation's normal test leaves fewer planar
    # ones (399 against 386 without it).
    ratio = planar_count(merged) / planar_count(tree_tiles)
    assert 0.90 <= ratio <= 1.10, (planar_count(merged), planar_count(tree_tiles))
    assert len(merged.planes) >= 1


def test_the_report_lists_the_tile_tasks(jobs: Dict[str, Job]) -> None:
    report, lines, folder = jobs["tiles"]
    assert report["merge"] == "tiles" and report["map"] is None
    assert report["merges"] == [] and report["frames"] == FRAMES
    assert not os.path.exists(folder / "map.pgmap")
    index = pg.read_tile_index(folder / "tiles")
    keys = sorted(tuple(t["key"]) for t in index["tiles"])
    # one task per key any segment holds, over exactly the segments holding it
    held: Dict[Tuple[int, ...], List[str]] = {}
    for s in report["segments"]:
        assert os.path.isfile(os.path.join(s["tiles"], "index.pgtiles"))
        for key in s["tile_keys"]:
            held.setdefault(tuple(key), []).append(s["tiles"])
    assert sorted(held) == keys
    assert sorted(tuple(t["key"]) for t in report["tile_merges"]) == keys
    for t in report["tile_merges"]:
        assert t["inputs"] == held[tuple(t["key"])]
        assert isinstance(t["cells"], int) and t["merge_s"] > 0
    assert any(len(t["inputs"]) > 1 for t in report["tile_merges"])
    assert report["tiles"]["tiles"] == len(keys)
    assert report["tiles"]["generation"] == index["generation"]
    # a line per segment, the plan, a line per tile task, the base and the index
    assert len(lines) == 1 + SEGMENTS + 1 + len(keys) + 2
    assert lines[-1].startswith(f"[{SEGMENTS + len(keys) + 2}/{SEGMENTS + len(keys) + 2}]")
    assert not [p for p in folder.rglob("*.tmp")]
    # the local clusters are stopped: no worker or nanny process is left
    left = [p.cmdline() for p in psutil.Process().children(recursive=True)
            if "multiprocessing.resource_tracker" not in " ".join(p.cmdline())]
    assert left == []


def test_tiles_grouped_into_tasks_are_the_same_files(jobs: Dict[str, Job]) -> None:
    report, _, folder = jobs["tiles"]
    grouped, lines, grouped_folder = jobs["grouped"]
    index = pg.read_tile_index(folder / "tiles")
    grouped_index = pg.read_tile_index(grouped_folder / "tiles")
    assert [t["key"] for t in grouped_index["tiles"]] == [t["key"] for t in index["tiles"]]
    for tile, other in zip(index["tiles"], grouped_index["tiles"]):
        assert tile["file"] == other["file"]
        assert (folder / "tiles" / tile["file"]).read_bytes() == \
            (grouped_folder / "tiles" / other["file"]).read_bytes()
    # one report per tile, as without grouping; a line per task: ceil(keys / 4) of them
    keys = len(index["tiles"])
    assert sorted(t["key"] for t in grouped["tile_merges"]) == \
        sorted(t["key"] for t in report["tile_merges"])
    tasks = SEGMENTS + -(-keys // 4) + 2
    assert len(lines) == 1 + SEGMENTS + 1 + -(-keys // 4) + 2
    assert lines[-1].startswith(f"[{tasks}/{tasks}]")


def test_tiles_need_a_tile_size(config: str, tmp_path: pathlib.Path) -> None:
    with pytest.raises(ValueError, match="tile_size_m"):
        pgd.map_segments(config, merge="tiles", output_dir=tmp_path, progress=False)
    with pytest.raises(ValueError, match="merge"):
        pgd.map_segments(config, merge="octree", output_dir=tmp_path, progress=False)
    assert pgd.main(["--config", config, "--merge", "tiles", "--output",
                     str(tmp_path)]) == pgd.EXIT_USAGE
    bad: Any  # 1.5 is no int: refused values on purpose, which the function checks
    for bad in (0, 1.5, True):
        with pytest.raises(ValueError, match="tiles_per_task"):
            pgd.map_segments(config, merge="tiles", tile_size_m=TILE_M,
                             tiles_per_task=bad, output_dir=tmp_path, progress=False)
