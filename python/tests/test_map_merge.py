# SPDX-License-Identifier: BSD-3-Clause
"""PlanarGridMap.merge() through the Python module: two maps of one wall join as one
plane, the voxel rules (by rank, and the newer map's by observation span), symmetry, the
4x4 transform and the errors."""

import pickle
from typing import Sequence

import numpy as np
import numpy.typing as npt
import pytest

import planar_grid as pg
from conftest import plane_patch

S = pg.SpaceState


def rigid(yaw_rad: float, translation_m: Sequence[float]) -> npt.NDArray[np.float64]:
    """A (4, 4) rigid transform: a turn about z and a translation, meters."""
    c, s = np.cos(yaw_rad), np.sin(yaw_rad)
    t = np.eye(4)
    t[:3, :3] = [[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]]
    t[:3, 3] = translation_m
    return t


def moved(points: npt.NDArray[np.float64],
          transform: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    result: npt.NDArray[np.float64] = points @ transform[:3, :3].T + transform[:3, 3]
    return result


def wall_map(y_shift_m: float, x_m: float = 3.0,
             transform: npt.NDArray[np.float64] = np.eye(4),
             extra_wall: bool = False) -> pg.PlanarGridMap:
    """A map of the wall x = x_m (normal -x) over y in [-1, 1] + y_shift_m, z in
    [-1, 1], mapped in the frame `transform` (its points moved by it): its planar
    cuboids (features of probability 0.9) and its ray-cast scan from the origin. With
    extra_wall, a second wall y = 4 (normal -y) too."""
    patches = [plane_patch([-1.0, 0.0, 0.0], x_m, 2.0, 0.05) + [0.0, y_shift_m, 0.0]]
    if extra_wall:
        patches.append(plane_patch([0.0, -1.0, 0.0], 4.0, 2.0, 0.05) + [3.0, 0.0, 0.0])
    m = pg.PlanarGridMap(resolution_m=0.1)
    for patch in patches:
        points = moved(patch, transform)
        planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                              min_inliers=100).segment(points)
        cuboids = pg.PlanarCuboidApproximation().approximate(points, planes)
        features = points[::7]
        m.integrate_surface(cuboids, planes.model_coefficients, features,
                            np.full(len(features), 0.9))
        m.integrate_point_cloud(points, sensor_origin=transform[:3, 3])
    return m


def copy_of(m: pg.PlanarGridMap) -> pg.PlanarGridMap:
    copy: pg.PlanarGridMap = pickle.loads(pickle.dumps(m))
    return copy


def probes() -> npt.NDArray[np.float64]:
    return np.random.default_rng(1).uniform([-0.5, -2.5, -1.5], [4.5, 5.0, 1.5],
                                            size=(20000, 3))


def test_a_wall_in_both_maps_becomes_one_plane() -> None:
    a = wall_map(0.0)
    b = wall_map(1.5, x_m=3.005, extra_wall=True)
    assert len(a.planes) == 1 and len(b.planes) == 2
    a.merge(b, np.eye(4))
    planes = a.planes
    assert planes.shape == (2, 4)
    # the wall x = 3 (a) and x = 3.005 (b) is one plane, the least-squares plane of
    # both maps' faces: between them, within 5 mm of each; the other wall is its own
    to_a = planes[0, :3] @ [3.0, 0.0, 0.0] + planes[0, 3]
    to_b = planes[0, :3] @ [3.005, 1.5, 0.0] + planes[0, 3]
    assert to_a * to_b < 0 and abs(to_a) < 5e-3 and abs(to_b) < 5e-3
    np.testing.assert_allclose(planes[0, :3], [-1.0, 0.0, 0.0], atol=5e-3)
    np.testing.assert_allclose(planes[1], [0.0, -1.0, 0.0, 4.0], atol=1e-3)
    # the wall's cuboids cover both stretches, y in [-1, 2.5]
    states = np.asarray(a.get_state([[3.05, -0.95, 0.0], [3.05, 2.45, 0.0]]))
    np.testing.assert_array_equal(states, [S.OCCUPIED, S.OCCUPIED])


def test_voxels_merge_by_rank_and_the_order_does_not_matter() -> None:
    a = pg.PlanarGridMap(resolution_m=0.1)
    b = pg.PlanarGridMap(resolution_m=0.1)
    p_occ_free, p_free_unknown, p_free_never = [0.05, 0.05, 0.05], [1.05, 0.05, 0.05], [
        2.05, 0.05, 0.05]
    a.set_state([p_occ_free, p_free_unknown], "occupied")
    a.set_state([p_free_unknown], "free")
    b.set_state([p_occ_free], "free")
    b.set_state([p_free_never], "free")
    ab, ba = copy_of(a), copy_of(b)
    ab.merge(b, np.eye(4))
    ba.merge(a, np.eye(4))
    # occupied > free > unknown (never observed here: the unknown prior)
    np.testing.assert_array_equal(
        np.asarray(ab.get_state([p_occ_free, p_free_unknown, p_free_never])),
        [S.OCCUPIED, S.FREE, S.FREE])
    assert ab == ba
    # maps of surfaces too: the same states and planes either way
    a, b = wall_map(0.0), wall_map(1.5, x_m=3.005, extra_wall=True)
    ab, ba = copy_of(a), copy_of(b)
    ab.merge(b, np.eye(4))
    ba.merge(a, np.eye(4))
    np.testing.assert_array_equal(np.asarray(ab.get_state(probes())),
                                  np.asarray(ba.get_state(probes())))
    assert len(ab.planes) == len(ba.planes) == 2


def test_the_newer_map_wins_where_the_spans_are_ordered() -> None:
    older = pg.PlanarGridMap(resolution_m=0.1)
    newer = pg.PlanarGridMap(resolution_m=0.1)
    assert older.observation_span is None
    older.note_observation_order(3)
    older.note_observation_order(1)
    newer.observation_span = (4.0, 6.0)
    assert older.observation_span == (1.0, 3.0)
    p_occ_free, p_free_occ, p_occ_unknown = [0.05, 0.05, 0.05], [1.05, 0.05, 0.05], [
        2.05, 0.05, 0.05]
    older.set_state([p_occ_free, p_occ_unknown], "occupied")
    older.set_state([p_free_occ], "free")
    newer.set_state([p_occ_free], "free")
    newer.set_state([p_free_occ], "occupied")
    newer.set_state([p_occ_unknown], "unknown")
    on, no = copy_of(older), copy_of(newer)
    on.merge(newer, np.eye(4))
    no.merge(older, np.eye(4))
    # the newer observation wins; occlusion does not erase an observed state
    for m in (on, no):
        np.testing.assert_array_equal(
            np.asarray(m.get_state([p_occ_free, p_free_occ, p_occ_unknown])),
            [S.FREE, S.OCCUPIED, S.OCCUPIED])
        assert m.observation_span == (1.0, 6.0)
    assert on == no
    # spans that overlap: no newer map, occupied wins
    newer.observation_span = (2.0, 6.0)
    ranked = copy_of(older)
    ranked.merge(newer, np.eye(4))
    np.testing.assert_array_equal(np.asarray(ranked.get_state([p_occ_free, p_free_occ])),
                                  [S.OCCUPIED, S.OCCUPIED])
    with pytest.raises(ValueError):
        newer.observation_span = (6.0, 2.0)
    with pytest.raises(pg.Error):
        newer.note_observation_order(float("nan"))
    newer.observation_span = None
    assert copy_of(newer).observation_span is None


def test_merging_an_empty_map_changes_nothing() -> None:
    m = wall_map(0.0)
    before = copy_of(m)
    m.merge(pg.PlanarGridMap(resolution_m=0.1), np.eye(4))
    assert m == before


def test_the_transform_moves_the_other_map_into_this_frame() -> None:
    # b mapped in a frame turned 0.4 rad and shifted: merged with this_T_other (the
    # inverse of that frame's pose), it lands where b mapped in this frame lands
    other_T_world = rigid(0.4, [1.23, -0.45, 0.31])
    this_T_other = np.linalg.inv(other_T_world)
    reference = wall_map(0.0)
    reference.merge(wall_map(1.5, extra_wall=True), np.eye(4))
    merged = wall_map(0.0)
    merged.merge(wall_map(1.5, extra_wall=True, transform=other_T_world),
                 this_T_other.astype(np.float32))  # a float32 matrix is accepted
    np.testing.assert_allclose(merged.planes, reference.planes, atol=2e-3)
    agree = np.mean(merged.get_state(probes()) == reference.get_state(probes()))
    assert agree > 0.98
    wrong = wall_map(0.0)
    wrong.merge(wall_map(1.5, extra_wall=True, transform=other_T_world), np.eye(4))
    assert np.mean(wrong.get_state(probes()) == reference.get_state(probes())) < agree


def test_merge_errors() -> None:
    m = wall_map(0.0)
    before = copy_of(m)
    with pytest.raises(pg.Error, match="resolution_m"):
        m.merge(pg.PlanarGridMap(resolution_m=0.2), np.eye(4))
    with pytest.raises(pg.Error, match="thickness_m"):
        m.merge(pg.PlanarGridMap(resolution_m=0.1, thickness_m=0.3), np.eye(4))
    with pytest.raises(pg.Error, match="itself"):
        m.merge(m, np.eye(4))
    with pytest.raises(ValueError, match=r"\(4, 4\)"):
        m.merge(pg.PlanarGridMap(resolution_m=0.1), np.eye(3))
    with pytest.raises(ValueError, match="rigid"):
        m.merge(pg.PlanarGridMap(resolution_m=0.1), 2.0 * np.eye(4))
    assert m == before
