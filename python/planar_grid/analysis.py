# SPDX-License-Identifier: BSD-3-Clause
"""Measures of a map for reports and comparisons, with numpy only (no Dask): its counts,
random probe points in its observed space, and two measures of one surface held as
several parallel planes.

    import planar_grid as pg
    from planar_grid.analysis import stacked_planar_cuboids
    area, stacked, _, _ = stacked_planar_cuboids(pg.PlanarGridMap.load("map.pgmap"))
    print(area[stacked].sum(), "of", area.sum(), "m^2 stacked")

planar_grid.distributed uses them in its batch reports; scripts/stacked_planes.py and
scripts/measure_batch.py print them.
"""
from __future__ import annotations

from typing import Dict, List, Sequence, Tuple

import numpy as np

import planar_grid as pg


def map_counts(m: "pg.PlanarGridMap") -> Dict[str, int]:
    """Counts of a map, as the batch reports give them (plain ints): planes,
    planar_cuboids, non_planar_cuboids, cells, memory_bytes."""
    planar = int(np.count_nonzero(m.cuboids.is_planar))
    return dict(planes=int(len(m.planes)), planar_cuboids=planar,
                non_planar_cuboids=int(len(m.cuboids.is_planar)) - planar,
                cells=int(m.cell_count),
                memory_bytes=int(m.memory["total_bytes"]))


def sample_observed_points(m: "pg.PlanarGridMap", count: int, box_min: Sequence[float],
                           box_max: Sequence[float], seed: int = 0) -> np.ndarray:
    """Random points where a map has observed space, to compare another map with it by
    getState (a batch's merged map against one run of the same frames).

    Parameters
    ----------
    m : PlanarGridMap
        The map whose observed space (free or occupied) the points are drawn from.
    count : int
        How many points.
    box_min, box_max : sequence of 3 floats
        The box the points are drawn in, uniformly, world frame, meters.
    seed : int
        numpy.random.default_rng's seed: the same points for the same map and box.

    Returns
    -------
    numpy.ndarray, shape (count, 3), float64, meters. Loops for ever when the box holds
    no observed space.
    """
    rng = np.random.default_rng(seed)
    lo, hi = np.asarray(box_min, dtype=float), np.asarray(box_max, dtype=float)
    kept, n = [], 0
    while n < count:
        candidates = rng.uniform(lo, hi, size=(400_000, 3))
        keep = candidates[m.get_state(candidates) != pg.SpaceState.UNKNOWN]
        kept.append(keep)
        n += len(keep)
    return np.concatenate(kept)[:count]


def parallel_plane_stacks(m: "pg.PlanarGridMap", max_offset_m: float = 0.5,
                          max_normal_z: float = 0.3) -> List[Tuple[int, int]]:
    """Stacks of parallel vertical planes in a map: one facade held as several planes
    a few centimetres apart, which a merge that joins planes by the association of
    integration does not leave (the batch test and scripts/measure_batch.py check the
    merged map with it).

    A pair of planes is a stack when both are vertical (|normal z| <= max_normal_z),
    their normals are within the map's plane_merge_angle_rad of each other (either
    sign), they are less than max_offset_m apart where they are (the mean distance of
    one plane's cuboid face corners to the other plane, the smaller of the two ways),
    and their extents overlap, in height and along the first plane's horizontal in-plane
    direction (their cuboids' face corners).

    Parameters
    ----------
    m : PlanarGridMap
        The map.
    max_offset_m : float
        Planes farther apart than this, meters, are separate surfaces.
    max_normal_z : float
        The largest |z| of a vertical plane's unit normal (0.3: within 17.5 degrees).

    Returns
    -------
    list of (int, int)
        The pairs (i, j), i < j, of indices into m.planes; empty when every facade is
        one plane.
    """
    planes, cuboids = m.planes, m.cuboids
    ids = cuboids.plane_ids
    faces = cuboids.corners[:, :4]
    cos_max = np.cos(m.params["plane_merge_angle_rad"])
    vertical = [k for k in range(len(planes))
                if abs(planes[k, 2]) <= max_normal_z and np.any(ids == k)]

    def overlap(a: np.ndarray, b: np.ndarray) -> bool:
        return min(a.max(), b.max()) > max(a.min(), b.min())

    stacks = []
    for n, i in enumerate(vertical):
        pi = faces[ids == i].reshape(-1, 3)
        along = np.cross([0.0, 0.0, 1.0], planes[i, :3])
        along /= np.linalg.norm(along)
        for j in vertical[n + 1:]:
            if abs(planes[i, :3] @ planes[j, :3]) < cos_max:
                continue
            pj = faces[ids == j].reshape(-1, 3)
            offset = min(np.mean(np.abs(pj @ planes[i, :3] + planes[i, 3])),
                         np.mean(np.abs(pi @ planes[j, :3] + planes[j, 3])))
            if offset < max_offset_m and overlap(pi @ along, pj @ along) \
                    and overlap(pi[:, 2], pj[:, 2]):
                stacks.append((i, j))
    return stacks


def stacked_planar_cuboids(m: "pg.PlanarGridMap", angle_rad: float = 0.1,
                           min_gap_m: float = 0.05, max_gap_m: float = 0.6
                           ) -> Tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The planar area a map covers twice: one wall held as a stack of parallel planes.

    A planar cuboid is stacked when its centre lies over a planar cuboid of another
    plane (inside it along that cuboid's two face axes) whose normal is within
    angle_rad of its own (either sign), between min_gap_m and max_gap_m from that
    cuboid's mid-plane along its normal: nearer is the same surface, farther a
    distinct one. Unlike parallel_plane_stacks() it weighs stacks by area, and counts
    planes of any orientation.

    Parameters
    ----------
    m : PlanarGridMap
        The map.
    angle_rad : float
        Largest angle between the two normals, radians.
    min_gap_m, max_gap_m : float
        The gap along the normal that counts as a stack, meters.

    Returns
    -------
    (area, stacked, over, plane_ids), arrays over the map's planar cuboids (those with a
    plane) in the map's order: face area (m^2, float64), stacked (bool), the plane id it
    lies over (int, -1 when not stacked), its own plane id (int).
    """
    c = m.cuboids
    planar = np.flatnonzero(np.asarray(c.is_planar) & (np.asarray(c.plane_ids) >= 0))
    ids = np.asarray(c.plane_ids)[planar]
    centres = np.asarray(c.centres)[planar]
    extents = np.asarray(c.extents_m)[planar]
    rotations = np.asarray(c.rotations)[planar]
    normals = np.asarray(c.normals)[planar]
    # the box axis along the normal is the thin one; the other two span the face
    along = np.argmax(np.abs(np.einsum("kij,ki->kj", rotations, normals)), axis=1)
    face = np.sort(extents, axis=1)[:, 1:]
    area = face[:, 0] * face[:, 1]
    over = np.full(len(planar), -1)
    cos_angle = np.cos(angle_rad)
    for k in range(len(planar)):
        parallel = (np.abs(normals @ normals[k]) >= cos_angle) & (ids != ids[k])
        q = np.flatnonzero(parallel)
        if q.size == 0:
            continue
        local = np.einsum("kji,kj->ki", rotations[q], centres[k] - centres[q])
        inside = np.ones(q.size, bool)
        gap = np.zeros(q.size)
        for a in range(3):
            is_normal = along[q] == a
            half = 0.5 * extents[q, a]
            inside &= is_normal | (np.abs(local[:, a]) <= half)
            gap = np.where(is_normal, np.abs(local[:, a]), gap)
        hit = inside & (gap > min_gap_m) & (gap <= max_gap_m)
        if hit.any():
            over[k] = ids[q[np.argmax(hit)]]
    return area, over >= 0, over, ids
