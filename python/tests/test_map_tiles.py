# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.save_tiles() / load_tiles() through the Python module: a wall across
four tiles saved and loaded back whole, by box and by radius, and the errors."""

import numpy as np
import pytest

import planar_grid as pg
from conftest import plane_patch

S = pg.SpaceState


def wall_map():
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


def probes():
    return np.random.default_rng(1).uniform([-0.5, -1.5, -1.5], [4.0, 1.5, 1.5],
                                            size=(20000, 3))


def test_all_tiles_give_back_the_map(tmp_path):
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
    np.testing.assert_array_equal(loaded.get_state(probes()), m.get_state(probes()))
    assert len(loaded.planes) == len(m.planes) == 1
    np.testing.assert_allclose(loaded.planes, m.planes, atol=1e-5)
    # the method forms
    same = pg.PlanarGridMap.load_tiles(tmp_path, [-np.inf] * 3, [np.inf] * 3)
    np.testing.assert_array_equal(same.get_state(probes()), m.get_state(probes()))


def test_a_region_holds_the_map_inside_it(tmp_path):
    m = wall_map()
    m.save_tiles(tmp_path, 0.5)
    part = pg.load_tiles(tmp_path, [2.5, 0.1, -2.0], [3.5, 0.4, 2.0])
    inside = probes()
    inside = inside[(inside[:, 0] >= 2.5) & (inside[:, 0] <= 3.5)
                    & (inside[:, 1] >= 0.1) & (inside[:, 1] <= 0.4)]
    assert len(inside) > 100
    np.testing.assert_array_equal(part.get_state(inside), m.get_state(inside))
    # the wall at y = -0.8 is in a tile that was not loaded
    assert m.get_state([[3.0, -0.8, 0.0]])[0] == S.OCCUPIED
    assert part.get_state([[3.0, -0.8, 0.0]])[0] == S.UNKNOWN
    disc = pg.load_tiles(tmp_path, [3.0, 0.25, 0.0], 0.2)
    assert disc.get_state([[3.0, 0.25, 0.0]])[0] == S.OCCUPIED
    assert len(disc.planes) == 1


def test_bad_sets_are_refused(tmp_path):
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
