# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.analysis: the stack measures against a map of two parallel walls whose
overlap is known."""
import numpy as np
import numpy.typing as npt
import pytest

import planar_grid as pg
from planar_grid.analysis import (map_counts, parallel_plane_stacks,
                                  stacked_planar_cuboids)


def wall(x_m: float, y_min_m: float, y_max_m: float,
         spacing_m: float = 0.05) -> npt.NDArray[np.float64]:
    """Points of the wall x = x_m, y in [y_min_m, y_max_m], z in [0, 2] m."""
    y, z = np.meshgrid(np.arange(y_min_m, y_max_m + 1e-9, spacing_m),
                       np.arange(0.0, 2.0 + 1e-9, spacing_m))
    return np.column_stack([np.full(y.size, x_m), y.ravel(), z.ravel()])


def walls_map(gap_m: float, y_min_m: float, y_max_m: float) -> pg.PlanarGridMap:
    """Wall A at x = 3, y in [0, 4]; wall B at x = 3 - gap_m (nearer the sensor at the
    origin), y in [y_min_m, y_max_m]. A plane merge distance of 0.05 m and
    absorb_distance_m 0 keep B a plane of its own."""
    m = pg.PlanarGridMap(resolution_m=0.1, plane_merge_distance_m=0.05,
                         absorb_distance_m=0.0)
    for points in (wall(3.0, 0.0, 4.0), wall(3.0 - gap_m, y_min_m, y_max_m)):
        planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                              min_inliers=100).segment(points)
        cuboids = pg.PlanarCuboidApproximation().approximate(points, planes)
        m.integrate_surface(cuboids, planes.model_coefficients, points[::7],
                            np.full(len(points[::7]), 0.9))
    return m


def test_a_wall_in_front_of_a_wider_one_is_a_stack() -> None:
    # B (2 m x 2 m) lies before the middle of A (4 m x 2 m): every cuboid of B lies over
    # A, and A's, whose centres are at y = 2, over B.
    m = walls_map(0.3, 1.0, 3.0)
    assert len(m.planes) == 2
    area, stacked, over, ids = stacked_planar_cuboids(m)
    assert area.sum() == pytest.approx(12.0, rel=0.05)
    assert stacked.all()
    assert set(ids) == {0, 1} and np.all(over != ids) and set(over) == {0, 1}
    assert parallel_plane_stacks(m) == [(0, 1)]
    counts = map_counts(m)
    assert counts["planes"] == 2 and counts["planar_cuboids"] == len(area)


def test_walls_side_by_side_or_far_apart_are_no_stack() -> None:
    # Beside A, not before it: parallel, 0.3 m apart, no overlap.
    m = walls_map(0.3, 4.5, 6.5)
    area, stacked, _, _ = stacked_planar_cuboids(m)
    assert area.sum() == pytest.approx(12.0, rel=0.05) and not stacked.any()
    assert parallel_plane_stacks(m) == []
    # Before A but 0.8 m away: a distinct surface, unless the gap allowed is larger.
    m = walls_map(0.8, 1.0, 3.0)
    _, stacked, _, _ = stacked_planar_cuboids(m, max_gap_m=0.6)
    assert not stacked.any()
    assert parallel_plane_stacks(m, max_offset_m=0.5) == []
    _, stacked, _, _ = stacked_planar_cuboids(m, max_gap_m=1.0)
    assert stacked.all()
