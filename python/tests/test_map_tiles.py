# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.save_tiles() / load_tiles() through the Python module: a wall across
four tiles saved and loaded back whole, by box and by radius, and the errors; two maps'
tile sets merged tile by tile (merge_tile_sets, and in steps) against the maps merged
whole."""

import pathlib
from typing import Dict, List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import planar_grid as pg
from conftest import plane_patch

S = pg.SpaceState


def wall_map() -> pg.PlanarGridMap:
    """A map of the wall x = 3 (normal -x) over y in [-1, 1], z in [-1, 1]: its planar
    cuboids (features of probability 0.9) and its ray-cast scan from the origin."""
    points = plane_patch([-1.0, 0.0, 0.0], 3.0, 2.0, 0.05)
    m = pg.PlanarGridMap(resolution_m=0.1)
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                          min_inliers=100).segment(points)
    cuboids = pg.PlanarCuboidApproximation().approximate(points, planes)
    m.integrate_surface(cuboids, planes.model_coefficients, points[::7],
                        np.full(len(points[::7]), 0.9))
    m.integrate_point_cloud(points, sensor_origin=[0.0, 0.0, 0.0])
    return m


def probes() -> npt.NDArray[np.float64]:
    return np.random.default_rng(1).uniform([-0.5, -1.5, -1.5], [4.0, 1.5, 1.5],
                                            size=(20000, 3))


def test_all_tiles_give_back_the_map(tmp_path: pathlib.Path) -> None:
    m = wall_map()
    # 0.5 m tiles: the wall at x = 3 (its voxels over y in [-1, 1.1)) crosses the
    # borders y = -0.5, 0, 0.5 and 1: five tiles of x in [3, 3.5)
    index = pg.save_tiles(m, tmp_path, 0.5)
    assert index["tile_size_m"] == 0.5 and index["resolution_m"] == 0.1
    wall_tiles = [t for t in index["tiles"] if t["key"][0] == 6]
    assert len(wall_tiles) == 5
    read = pg.read_tile_index(tmp_path)
    assert [t["file"] for t in read["tiles"]] == [t["file"] for t in index["tiles"]]
    loaded = pg.load_tiles(tmp_path, [-np.inf] * 3, [np.inf] * 3)
    np.testing.assert_array_equal(np.asarray(loaded.get_state(probes())),
                                  np.asarray(m.get_state(probes())))
    assert len(loaded.planes) == len(m.planes) == 1
    np.testing.assert_allclose(loaded.planes, m.planes, atol=1e-5)
    # the method forms
    same = pg.PlanarGridMap.load_tiles(tmp_path, [-np.inf] * 3, [np.inf] * 3)
    np.testing.assert_array_equal(np.asarray(same.get_state(probes())),
                                  np.asarray(m.get_state(probes())))


def test_a_region_holds_the_map_inside_it(tmp_path: pathlib.Path) -> None:
    m = wall_map()
    m.save_tiles(tmp_path, 0.5)
    part = pg.load_tiles(tmp_path, [2.5, 0.1, -2.0], [3.5, 0.4, 2.0])
    inside = probes()
    inside = inside[(inside[:, 0] >= 2.5) & (inside[:, 0] <= 3.5)
                    & (inside[:, 1] >= 0.1) & (inside[:, 1] <= 0.4)]
    assert len(inside) > 100
    np.testing.assert_array_equal(np.asarray(part.get_state(inside)),
                                  np.asarray(m.get_state(inside)))
    # the wall at y = -0.8 is in a tile that was not loaded
    assert np.asarray(m.get_state([[3.0, -0.8, 0.0]]))[0] == S.OCCUPIED
    assert np.asarray(part.get_state([[3.0, -0.8, 0.0]]))[0] == S.UNKNOWN
    disc = pg.load_tiles(tmp_path, [3.0, 0.25, 0.0], 0.2)
    assert np.asarray(disc.get_state([[3.0, 0.25, 0.0]]))[0] == S.OCCUPIED
    assert len(disc.planes) == 1


def test_bad_sets_are_refused(tmp_path: pathlib.Path) -> None:
    with pytest.raises(pg.IOError, match="index.pgtiles: missing"):
        pg.load_tiles(tmp_path, [0, 0, 0], 1.0)
    m = wall_map()
    m.save_tiles(tmp_path, 0.5)
    text = (tmp_path / "index.pgtiles").read_text()
    (tmp_path / "index.pgtiles").write_text(text.replace("version 1", "version 9"))
    with pytest.raises(pg.IOError, match="index.pgtiles:2: unknown version 9"):
        pg.load_tiles(tmp_path, [0, 0, 0], 10.0)
    with pytest.raises(pg.Error, match="tile_size_m"):
        m.save_tiles(tmp_path / "other", 0.25)
    with pytest.raises(ValueError):
        pg.load_tiles(tmp_path, [0, 0], [1, 1, 1])


def halves() -> List[pg.PlanarGridMap]:
    """The wall map's two overlapping halves (y < 0.3 and y >= -0.3), each mapped on
    its own, with the observation spans of two parts of one drive (frames 0-4, then
    5-9)."""
    points = plane_patch([-1.0, 0.0, 0.0], 3.0, 2.0, 0.05)
    out = []
    for part, span in ((points[:, 1] < 0.3, (0.0, 4.0)),
                       (points[:, 1] >= -0.3, (5.0, 9.0))):
        m = pg.PlanarGridMap(resolution_m=0.1)
        p = np.ascontiguousarray(points[part])
        planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                              min_inliers=100).segment(p)
        cuboids = pg.PlanarCuboidApproximation().approximate(p, planes)
        m.integrate_surface(cuboids, planes.model_coefficients, p[::7],
                            np.full(len(p[::7]), 0.9))
        m.integrate_point_cloud(p, sensor_origin=[0.0, 0.0, 0.0])
        m.observation_span = span
        out.append(m)
    return out


def test_tile_sets_merge_tile_by_tile(tmp_path: pathlib.Path) -> None:
    a, b = halves()
    folders = [tmp_path / "a", tmp_path / "b"]
    a.save_tiles(folders[0], 0.5)
    b.save_tiles(folders[1], 0.5)
    index = pg.merge_tile_sets(folders, tmp_path / "out")
    # the oracle: the halves merged whole, saved as tiles and loaded
    whole = pg.PlanarGridMap(resolution_m=0.1)
    whole.merge(a, np.eye(4))
    whole.merge(b, np.eye(4))
    whole.save_tiles(tmp_path / "whole", 0.5)
    oracle = pg.load_tiles(tmp_path / "whole", [-np.inf] * 3, [np.inf] * 3)
    merged = pg.load_tiles(tmp_path / "out", [-np.inf] * 3, [np.inf] * 3)
    np.testing.assert_array_equal(np.asarray(merged.get_state(probes())),
                                  np.asarray(oracle.get_state(probes())))
    assert merged.voxel_counts == oracle.voxel_counts
    assert len(merged.planes) == len(oracle.planes) == 1
    assert index["generation"] == 1
    assert [t["key"] for t in index["tiles"]] == \
        [t["key"] for t in pg.read_tile_index(tmp_path / "whole")["tiles"]]

    # the same in steps: the base, one tile per key (only the sets holding it), the
    # index; the tiles of the finished set are the same files
    prepared = pg.prepare_tile_merge(folders, tmp_path / "steps")
    assert prepared["tiles"] == [] and prepared["generation"] == 1
    holders: Dict[Tuple[int, ...], List[pathlib.Path]] = {}
    for f in folders:
        for t in pg.read_tile_index(f)["tiles"]:
            holders.setdefault(tuple(t["key"]), []).append(f)
    assert max(len(h) for h in holders.values()) == 2  # the overlap's tiles
    tiles = [pg.merge_tile(holders[key], list(key), tmp_path / "steps", 1)
             for key in holders]  # a key is any sequence of two ints
    prepared["tiles"] = tiles
    written = pg.write_tile_index(tmp_path / "steps", prepared)
    assert [(t["key"], t["file_bytes"]) for t in written["tiles"]] == \
        [(t["key"], t["file_bytes"]) for t in index["tiles"]]
    assert (tmp_path / "steps" / "index.pgtiles").read_text() == \
        (tmp_path / "out" / "index.pgtiles").read_text()


def test_tile_merge_errors_name_the_folder(tmp_path: pathlib.Path) -> None:
    a, _ = halves()
    a.save_tiles(tmp_path / "a", 0.5)
    a.save_tiles(tmp_path / "coarse", 1.0)
    with pytest.raises(pg.Error, match=f"{tmp_path / 'coarse'}.*tile_size_m 1"):
        pg.merge_tile_sets([tmp_path / "a", tmp_path / "coarse"], tmp_path / "out")
    with pytest.raises(pg.Error, match="no tile folder holds tile 99 99"):
        pg.merge_tile([tmp_path / "a"], (99, 99), tmp_path / "out", 1)
    with pytest.raises(pg.IOError, match="index.pgtiles: missing"):
        pg.merge_tile_sets([tmp_path / "none"], tmp_path / "out")
    index = pg.read_tile_index(tmp_path / "a")
    index["tiles"][0]["file_bytes"] += 1
    with pytest.raises(pg.IOError, match="the index to be written says"):
        pg.write_tile_index(tmp_path / "a", index)
    with pytest.raises(ValueError):
        pg.merge_tile([tmp_path / "a"], (1, 2, 3), tmp_path / "out", 1)
