# SPDX-License-Identifier: BSD-3-Clause
"""python/examples/show_map_cuboids.py: the cuboid mesh it builds (numpy only), and the
script run headless when Open3D is installed."""

import importlib.util
import os
import pathlib
import subprocess
import sys
import types
from typing import Tuple

import numpy as np
import pytest

import planar_grid as pg
from conftest import SOURCE_DIR, plane_patch

EXAMPLE = SOURCE_DIR / "python" / "examples" / "show_map_cuboids.py"
# The wall_map fixture: the map and the file it is saved in.
WallMap = Tuple[pg.PlanarGridMap, pathlib.Path]


def load_example() -> types.ModuleType:
    spec = importlib.util.spec_from_file_location("show_map_cuboids", EXAMPLE)
    assert spec is not None and spec.loader is not None, EXAMPLE
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


@pytest.fixture
def wall_map(tmp_path: pathlib.Path) -> WallMap:
    """A saved map of a wall at x = 3 whose cells have occupancy 0.9."""
    wall = plane_patch([-1.0, 0.0, 0.0], 3.0, 2.0, 0.05)
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=100).segment(wall)
    cuboids = pg.PlanarCuboidApproximation().approximate(wall, planes)
    m = pg.PlanarGridMap()
    m.integrate_surface(cuboids, planes.model_coefficients, wall, np.full(len(wall), 0.9))
    path = tmp_path / "wall.pgmap"
    m.save(path)
    return m, path


def test_mesh_triangles_face_out_of_every_box(wall_map: WallMap) -> None:
    example = load_example()
    m, _ = wall_map
    cuboids = m.cuboids
    colours = example.occupancy_colours(cuboids.probabilities)
    vertices, triangles, vertex_colours = example.cuboid_mesh_arrays(cuboids, colours)
    assert vertices.shape == (8 * len(cuboids), 3)
    assert triangles.shape == (12 * len(cuboids), 3) and triangles.max() < len(vertices)
    # Each triangle's normal (right-hand rule) points away from its box's centre.
    a, b, c = (vertices[triangles[:, k]] for k in range(3))
    outward = (a + b + c) / 3 - np.repeat(cuboids.centres, 12, axis=0)
    assert np.all(np.einsum("ij,ij->i", np.cross(b - a, c - a), outward) > 0)
    # 0.9 is 4/5 of the way from green (0, 0.8, 0) to red (1, 0, 0); the probability is
    # a float32.
    np.testing.assert_allclose(vertex_colours[0], [0.8, 0.16, 0.0], atol=1e-6)
    points, lines = example.cuboid_line_arrays(cuboids)
    assert lines.shape == (12 * len(cuboids), 2)
    # Every edge is one of the box's extents long.
    lengths = np.linalg.norm(points[lines[:, 0]] - points[lines[:, 1]], axis=1)
    extents = np.repeat(cuboids.extents_m, 12, axis=0)
    assert np.all(np.isclose(lengths[:, None], extents, atol=1e-5).any(axis=1))
    np.testing.assert_allclose(example.plane_colours([-1])[0], [0.6, 0.6, 0.6])


def run_example(*args: object) -> "subprocess.CompletedProcess[str]":
    env = dict(os.environ)
    return subprocess.run([sys.executable, str(EXAMPLE), *map(str, args)], env=env,
                          capture_output=True, text=True, timeout=120)


def test_example_reports_a_missing_map() -> None:
    done = run_example("/nonexistent/map.pgmap", "--no-window")
    assert done.returncode == 1
    assert "/nonexistent/map.pgmap" in done.stderr


def test_example_builds_the_open3d_geometry_headless(wall_map: WallMap) -> None:
    pytest.importorskip("open3d")  # the example is optional: Debian's python3-open3d
    m, path = wall_map
    done = run_example(path, "--no-window")
    assert done.returncode == 0, done.stderr
    assert f"{len(m.cuboids)} cuboids" in done.stdout
    assert f"mesh of {12 * len(m.cuboids)} triangles" in done.stdout


def test_office1_mapped_from_open3d_in_a_dozen_lines(data_dir: pathlib.Path,
                                                     tmp_path: pathlib.Path) -> None:
    """python/examples/map_pcd_with_open3d.py on PCL's office1.pcd (loaded by Open3D):
    every scan point is in an occupied voxel, every planar cuboid lies on its plane, the
    planes hold their inliers, and the saved map loads back equal."""
    o3d = pytest.importorskip("open3d")  # the example needs Debian's python3-open3d
    spec = importlib.util.spec_from_file_location(
        "map_pcd_with_open3d", SOURCE_DIR / "python" / "examples" / "map_pcd_with_open3d.py")
    assert spec is not None and spec.loader is not None
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    scan = str(data_dir / "pcl_clouds" / "office1.pcd")
    planes, cuboids, m = example.map_scan(scan, resolution_m=0.05)
    camera = np.asarray(o3d.io.read_point_cloud(scan, remove_nan_points=True).points)
    points = np.column_stack([camera[:, 2], -camera[:, 0], -camera[:, 1]])
    assert len(points) > 100000
    states = m.get_state(points)
    assert np.mean(states == pg.SpaceState.OCCUPIED) > 0.99
    coefficients = planes.model_coefficients
    assert len(coefficients) >= 3
    for k, inliers in enumerate(planes.inliers):
        assert len(inliers) >= 2000
        distances = np.abs(points[inliers] @ coefficients[k, :3] + coefficients[k, 3])
        # eq. 11 selects within d_T = 0.03 m; the plane is then refitted to them
        assert np.median(distances) <= 0.03
        assert np.quantile(distances, 0.99) <= 0.1
    planar = np.flatnonzero(cuboids.is_planar)
    assert len(planar) > 0
    # each box spans its inliers across the plane: the plane passes within the inliers'
    # reach (0.1 m, as above) of the box's extent along the normal
    normals = coefficients[cuboids.plane_ids[planar], :3]
    offsets = coefficients[cuboids.plane_ids[planar], 3]
    distances = np.abs(np.einsum("ij,ij->i", cuboids.centres[planar], normals) + offsets)
    assert np.all(distances <= cuboids.extents_m[planar, 2] / 2 + 0.1)
    path = tmp_path / "office1.pgmap"
    m.save(path)
    assert pg.PlanarGridMap.load(path) == m
