# SPDX-License-Identifier: BSD-3-Clause
"""PlanarGridMap through the Python module: a map of known geometry built from Python,
its state, occupancy and ray queries, and the map file round trip."""

import inspect
import math
import pathlib
import pickle
from typing import List, Tuple

import numpy as np
import numpy.typing as npt
import pytest

import planar_grid as pg
from conftest import plane_patch

# OctoMap's clamping bounds, the occupancy of an occupied / free voxel.
P_OCCUPIED, P_FREE = 0.971, 0.1192


def wall_scan() -> npt.NDArray[np.float64]:
    """A 2 m x 2 m wall of points at x = 5.02 m seen from the origin: voxel row x in
    [5.0, 5.1) at 0.1 m."""
    ys, zs = np.meshgrid(np.arange(-1.0, 1.0, 0.05), np.arange(-1.0, 1.0, 0.05))
    return np.column_stack([np.full(ys.size, 5.02), ys.ravel(), zs.ravel()])


@pytest.fixture
def scanned_map() -> pg.PlanarGridMap:
    m = pg.PlanarGridMap(resolution_m=0.1)
    m.integrate_point_cloud(wall_scan(), sensor_origin=[0.0, 0.0, 0.0])
    return m


def test_ray_cast_scan_gives_free_occupied_and_unknown_space(
        scanned_map: pg.PlanarGridMap) -> None:
    m = scanned_map
    # On a ray to the wall: free; at the wall: occupied; behind it and never seen: the
    # prior (unknown).
    queries = np.array([[2.55, 0.05, 0.05], [5.05, 0.05, 0.05], [7.0, 0.05, 0.05],
                        [0.0, 0.0, -3.0]])
    S = pg.SpaceState
    np.testing.assert_array_equal(np.asarray(m.get_state(queries)),
                                  [S.FREE, S.OCCUPIED, S.UNKNOWN, S.UNKNOWN])
    np.testing.assert_allclose(np.asarray(m.get_occupancy(queries)),
                               [P_FREE, P_OCCUPIED, 0.5, 0.5], atol=1e-4)
    # The wall is 20 x 20 voxels of the row x in [5.0, 5.1).
    occupied = m.voxel_centres(S.OCCUPIED)
    assert len(occupied) == 400 == m.voxel_counts["occupied"]
    np.testing.assert_allclose(occupied[:, 0], 5.05, atol=1e-5)
    assert m.voxel_counts["free"] > 0 and m.voxel_counts["unknown"] == 0  # unknown is the prior


def test_rays_stop_at_the_wall(scanned_map: pg.PlanarGridMap) -> None:
    origins = [0.0, 0.05, 0.05]
    directions = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.1, 0.0]])
    hit, points = scanned_map.cast_rays(origins, directions, max_range_m=20.0)
    np.testing.assert_array_equal(hit, [True, False, True])
    np.testing.assert_allclose(points[0], [5.05, 0.05, 0.05], atol=1e-5)
    assert np.isnan(points[1]).all()
    assert points[2][0] == pytest.approx(5.05, abs=1e-5)
    hit, _ = scanned_map.cast_rays(origins, [1.0, 0.0, 0.0], max_range_m=3.0)
    np.testing.assert_array_equal(hit, [False])
    # Without a range limit (or one beyond the 2^30 cells the keys hold): the same hits.
    for max_range_m in (math.inf, 1e12):
        hit, points = scanned_map.cast_rays(origins, directions, max_range_m)
        np.testing.assert_array_equal(hit, [True, False, True])
        np.testing.assert_allclose(points[0], [5.05, 0.05, 0.05], atol=1e-5)
    # A ray that is no ray is an error naming it, not a miss.
    with pytest.raises(ValueError, match="ray 1"):
        scanned_map.cast_rays(origins, [[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]], 20.0)
    for bad_range in (-1.0, math.nan):
        with pytest.raises(ValueError, match="max_range_m"):
            scanned_map.cast_rays(origins, [1.0, 0.0, 0.0], bad_range)


def test_set_state_and_errors() -> None:
    m = pg.PlanarGridMap(resolution_m=0.2, prior="free")
    assert m.params["prior"] == "free" and m.resolution_m == pytest.approx(0.2)
    m.set_state([[1.0, 1.0, 1.0]], "occupied")
    m.set_state([[2.0, 2.0, 2.0]], pg.SpaceState.UNKNOWN)
    points: List[List[float]] = [[1.05, 1.05, 1.05], [2.1, 2.1, 2.1], [9, 9, 9]]
    np.testing.assert_array_equal(np.asarray(m.get_state(points)), [1, 2, 0])
    with pytest.raises(ValueError, match="state 7"):
        m.set_state([[0, 0, 0]], 7)
    with pytest.raises(ValueError, match="resolution"):
        pg.PlanarGridMap(resolution_m=-1.0)
    with pytest.raises(ValueError, match="prior: Unknown space state 'occupied-ish'"):
        pg.PlanarGridMap(prior="occupied-ish")
    with pytest.raises(ValueError, match=r"\(N, 3\)"):
        m.get_state(np.zeros(4))


def surface_map() -> pg.PlanarGridMap:
    """A map with a wall of planar cuboids at x = 3 whose features have probability 0.9,
    and the wall's ray-cast scan."""
    wall = plane_patch([-1.0, 0.0, 0.0], 3.0, 2.0, 0.05)
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=100).segment(wall)
    cuboids = pg.PlanarCuboidApproximation().approximate(wall, planes)
    features = wall[::7]
    m = pg.PlanarGridMap(resolution_m=0.1)
    m.integrate_surface(cuboids, planes.model_coefficients, features,
                        np.full(len(features), 0.9))
    m.integrate_point_cloud(wall, sensor_origin=[0.0, 0.0, 0.0])
    return m


def test_surface_cuboids_carry_the_feature_occupancy() -> None:
    m = surface_map()
    np.testing.assert_allclose(m.planes, [[-1.0, 0.0, 0.0, 3.0]], atol=1e-4)
    cuboids = m.cuboids
    assert len(cuboids) > 0 and cuboids.is_planar.all()
    # Every cell holds features of probability 0.9 (or takes its neighbours' mean).
    np.testing.assert_allclose(cuboids.probabilities, 0.9, atol=1e-6)
    # Inside the wall's box (behind the face at x = 3): the cuboid decides.
    inside = [[3.05, 0.02, 0.03]]
    assert np.asarray(m.get_state(inside))[0] == pg.SpaceState.OCCUPIED
    assert np.asarray(m.get_occupancy(inside))[0] == pytest.approx(0.9, abs=1e-6)
    hit, points = m.cast_rays([0.0, 0.02, 0.03], [1.0, 0.0, 0.0], 10.0)
    assert hit[0] and points[0][0] == pytest.approx(2.95, abs=0.06)
    memory = m.memory
    assert memory["total_bytes"] == memory["surface_bytes"] + memory["space_bytes"] > 0
    assert m.cell_count > 0


def test_map_saved_from_python_loads_back_identically(tmp_path: pathlib.Path) -> None:
    m = surface_map()
    path = tmp_path / "wall.pgmap"
    m.save(path)
    loaded = pg.PlanarGridMap.load(str(path))
    assert loaded == m
    for name in ("centres", "extents_m", "rotations", "probabilities", "plane_ids"):
        np.testing.assert_array_equal(getattr(loaded.cuboids, name), getattr(m.cuboids, name))
    grid = np.random.default_rng(0).uniform([-1, -2, -2], [8, 2, 2], size=(5000, 3))
    np.testing.assert_array_equal(np.asarray(loaded.get_state(grid)),
                                  np.asarray(m.get_state(grid)))
    np.testing.assert_array_equal(np.asarray(loaded.get_occupancy(grid)),
                                  np.asarray(m.get_occupancy(grid)))
    assert pickle.loads(pickle.dumps(m)) == m
    loaded.set_state([[-5.0, -5.0, -5.0]], "occupied")
    assert loaded != m


def test_bad_map_files_raise_io_errors_naming_the_file(tmp_path: pathlib.Path) -> None:
    missing = tmp_path / "missing.pgmap"
    with pytest.raises(pg.IOError, match="missing.pgmap") as error:
        pg.PlanarGridMap.load(missing)
    assert isinstance(error.value, OSError) and isinstance(error.value, pg.Error)
    path = tmp_path / "cut.pgmap"
    surface_map().save(path)
    data = path.read_bytes()
    path.write_bytes(data[: len(data) - 10])
    with pytest.raises(OSError, match="cut.pgmap"):
        pg.PlanarGridMap.load(path)
    with pytest.raises(pg.IOError):
        surface_map().export_mesh(tmp_path / "mesh.obj")


def test_exports_write_files(tmp_path: pathlib.Path) -> None:
    m = surface_map()
    written = m.export_octomap(tmp_path / "m.bt")
    m.export_mesh(tmp_path / "m.ply")
    assert (tmp_path / "m.bt").stat().st_size > 0
    # The surface map has observed space around occupied cuboids; every leaf is one
    # of the two states, and a leaf holds at least one voxel.
    assert written["occupied_leaves"] > 0 and written["free_leaves"] > 0
    assert written["leaf_nodes"] == written["occupied_leaves"] + written["free_leaves"]
    assert written["nodes"] > written["leaf_nodes"]
    assert written["occupied_voxels"] >= written["occupied_leaves"]
    assert written["free_voxels"] >= written["free_leaves"]
    assert written["skipped_voxels"] == 0
    # Every occupied voxel of the space layer is in the tree (the cuboids add theirs).
    assert written["occupied_voxels"] >= len(m.voxel_centres("occupied"))
    assert (tmp_path / "m.ply").read_bytes().startswith(b"ply")


def test_get_distance_is_exact_to_a_voxel_with_its_gradient() -> None:
    m = pg.PlanarGridMap(resolution_m=0.1)
    m.set_state([[1.05, 0.05, 0.05]], "occupied")  # the voxel [1.0, 1.1] x [0, 0.1]^2
    points = np.array([[1.05, 0.05, 1.05],   # 0.95 above
                       [0.5, 0.05, 0.05],    # 0.5 before it along x
                       [1.4, 0.5, 0.05],     # off an edge: (0.3, 0.4) -> 0.5
                       [1.05, 0.05, 0.05],   # inside
                       [9.0, 0.0, 0.0]])     # beyond the cap
    d, g = m.get_distance(points, max_distance_m=2.0)
    assert d.shape == (5,) and g.shape == (5, 3)
    np.testing.assert_allclose(d, [0.95, 0.5, 0.5, 0.0, 2.0], atol=1e-5)
    np.testing.assert_allclose(g[0], [0, 0, 1], atol=1e-5)
    np.testing.assert_allclose(g[1], [-1, 0, 0], atol=1e-5)
    np.testing.assert_allclose(g[2], [0.6, 0.8, 0], atol=1e-5)
    np.testing.assert_allclose(np.linalg.norm(g[3]), 1.0, atol=1e-6)
    np.testing.assert_array_equal(g[4], [0, 0, 0])
    # unknown prior: with unknown counted, the unobserved space around is an obstacle
    d_unknown, _ = m.get_distance(points, max_distance_m=2.0, unknown_is_occupied=True)
    np.testing.assert_array_equal(d_unknown, 0.0)
    with pytest.raises(ValueError):
        m.get_distance(np.zeros((4, 2)), max_distance_m=1.0)
    with pytest.raises(pg.Error):
        m.get_distance(points, max_distance_m=0.0)


def test_is_collision_free_for_boxes_and_spheres(scanned_map: pg.PlanarGridMap) -> None:
    m = scanned_map  # an occupied wall at x in [5.0, 5.1), |y|, |z| < 1
    centres = np.array([[4.0, 0.0, 0.0], [4.6, 0.0, 0.0], [4.0, 0.0, 0.0]])
    # a 1.0 x 0.6 x 1.5 box: 0.5 m half length along x, or along y when turned 90 deg
    free = m.is_collision_free(centres, half_extents=[0.5, 0.3, 0.75], yaw=[0.0, 0.0, 0.0])
    np.testing.assert_array_equal(free, [True, False, True])
    free = m.is_collision_free(np.tile([4.55, 0.0, 0.0], (3, 1)),
                               half_extents=[0.5, 0.3, 0.75], yaw=[0.0, np.pi / 2, np.pi / 2])
    np.testing.assert_array_equal(free, [False, True, True])
    rotations = np.repeat(np.eye(3)[None], 3, axis=0)
    np.testing.assert_array_equal(
        m.is_collision_free(centres, half_extents=[0.5, 0.3, 0.75], rotations=rotations),
        [True, False, True])
    np.testing.assert_array_equal(
        m.is_collision_free(centres, radii=[0.99, 0.41, 1.01]), [True, False, False])
    with pytest.raises(ValueError):
        m.is_collision_free(centres, half_extents=[0.5, 0.3, 0.75], radii=1.0)
    with pytest.raises(ValueError):
        m.is_collision_free(centres, half_extents=np.ones((2, 3)))


def test_export_occupancy_grid_2d_reads_back_as_map_server(scanned_map: pg.PlanarGridMap,
                                                           tmp_path: pathlib.Path) -> None:
    m = scanned_map
    out = m.export_occupancy_grid_2d(tmp_path / "map.yaml", z_ref_m=-1.0, z_min_m=0.5,
                                     z_max_m=1.5)
    yaml = dict(line.split(": ", 1) for line in
                (tmp_path / "map.yaml").read_text().splitlines())
    assert yaml["image"] == "map.pgm" and yaml["negate"] == "0"
    assert float(yaml["resolution"]) == pytest.approx(0.1)
    origin = [float(v) for v in yaml["origin"].strip("[]").split(",")]
    data = (tmp_path / "map.pgm").read_bytes()
    header = data.split(b"\n", 4)
    assert header[0] == b"P5"
    w, h = (int(v) for v in header[2].split())
    image = np.frombuffer(header[4], dtype=np.uint8).reshape(h, w)
    cells: npt.NDArray[np.int8] = out["cells"]
    assert cells.shape == (h, w)
    # the image's top row is the largest y
    expected = np.where(cells == 100, 0, np.where(cells == 0, 254, 205))
    np.testing.assert_array_equal(image, expected[::-1])

    def cell(x: float, y: float) -> np.int8:
        value: np.int8 = cells[int((y - origin[1]) // 0.1), int((x - origin[0]) // 0.1)]
        return value

    assert cell(5.05, 0.05) == 100   # the wall
    assert cell(2.55, 0.05) == 0     # seen free on the way to it
    assert cell(5.45, 0.05) == -1    # behind it, never seen
    with pytest.raises(pg.IOError):
        m.export_occupancy_grid_2d(tmp_path / "map.png")
    with pytest.raises(pg.Error):
        m.export_occupancy_grid_2d(tmp_path / "bad.yaml", z_min_m=1.0, z_max_m=0.5)


def test_region_index_answers_as_the_map_inside_its_region(
        scanned_map: pg.PlanarGridMap) -> None:
    m = scanned_map
    region = pg.MapRegionIndex(m, [3.0, -1.0, -1.0], [6.0, 1.0, 1.0], max_distance_m=2.0)
    assert region.obstacle_count > 0
    points = np.array([[4.0, 0.0, 0.0], [4.5, 0.3, -0.2], [3.2, 0.9, 0.9],
                       [0.0, 0.0, 0.0]])  # the last one outside the region
    d, g = region.get_distance(points)
    d_map, g_map = m.get_distance(points, max_distance_m=2.0)
    np.testing.assert_allclose(d[:3], d_map[:3], atol=1e-6)
    np.testing.assert_allclose(g[:3], g_map[:3], atol=1e-5)
    assert np.isnan(d[3])
    centres = np.array([[4.0, 0.0, 0.0], [4.6, 0.0, 0.0]])
    np.testing.assert_array_equal(
        region.is_collision_free(centres, half_extents=[0.5, 0.3, 0.75], yaw=0.0),
        m.is_collision_free(centres, half_extents=[0.5, 0.3, 0.75], yaw=0.0))


def test_one_point_queries_take_a_3_vector_and_give_its_value(
        scanned_map: pg.PlanarGridMap) -> None:
    # A (3,) point gives a scalar (get_state, get_occupancy) or a (distance, (3,)
    # gradient) pair, equal to the row of the same point given as (1, 3).
    m = scanned_map
    for point in ([2.55, 0.05, 0.05], [5.05, 0.05, 0.05], [7.0, 0.05, 0.05]):
        state = np.asarray(m.get_state(np.array(point)))
        assert np.ndim(state) == 0
        assert state == np.asarray(m.get_state(np.array([point])))[0]
        occupancy = np.asarray(m.get_occupancy(point))
        assert np.ndim(occupancy) == 0
        assert occupancy == np.asarray(m.get_occupancy([point]))[0]
        d, g = m.get_distance(point, max_distance_m=2.0)
        assert np.ndim(d) == 0 and np.shape(g) == (3,)
        rows_d, rows_g = m.get_distance([point], max_distance_m=2.0)
        assert d == rows_d[0]
        np.testing.assert_array_equal(g, rows_g[0])
    assert m.get_state([5.05, 0.05, 0.05]) == pg.SpaceState.OCCUPIED
    with pytest.raises(ValueError, match=r"\(N, 3\) array .* or one \(3,\) point"):
        m.get_state([1.0, 2.0])


def test_the_map_documents_its_keywords_from_the_stage_table() -> None:
    # The keyword arguments are map_integration's keys, documented from its table.
    assert pg.PlanarGridMap.__doc__ is not None
    doc = " ".join(pg.PlanarGridMap.__doc__.split())
    keys = pg.PlanarGridMap().params
    rows = [row for row in pg.stage_parameters("map_integration") if row["key"] in keys]
    assert len(rows) == len(keys) == 23
    for row in rows:
        assert f"{row['key']} : " in doc, row["key"]
        assert " ".join(row["description"].split()) in doc, row["key"]


def test_the_map_defaults_are_the_pipelines_map_integration_defaults() -> None:
    # One Params struct: every key PlanarGridMap() takes has map_integration's default,
    # read from the stage table that --list-stages prints.
    import re
    described = pg.stage_types()["map_integration"]
    defaults = {}
    for line in described.splitlines():
        match = re.match(r"    (\w+)\s+.*?default ([^,\s]+)", line)
        if match:
            defaults[match.group(1)] = match.group(2)
    params = pg.PlanarGridMap().params
    for key, value in params.items():
        assert key in defaults, key
        if isinstance(value, bool):
            assert defaults[key] == ("true" if value else "false"), key
        elif isinstance(value, str):
            assert defaults[key] == value, key
        else:
            assert float(defaults[key]) == pytest.approx(value), key
    assert len(params) == 23
    # A configuration's map_integration keys give the tool's map.
    m = pg.PlanarGridMap(plane_merge_distance_m=0.2, merge_rule="density",
                         cover_density=0.7, planes_absorb_overlapping=False)
    assert m.params["planes_absorb_overlapping"] is False
    assert m.params["merge_rule"] == "density"


def test_the_map_constructor_has_a_signature_with_the_params_defaults() -> None:
    # inspect.signature (IDEs, help()) shows every keyword with the default a
    # PlanarGridMap() really gets
    import inspect
    signature = inspect.signature(pg.PlanarGridMap)
    params = pg.PlanarGridMap().params
    assert sorted(signature.parameters) == sorted(params)
    for name, parameter in signature.parameters.items():
        assert parameter.kind is inspect.Parameter.KEYWORD_ONLY, name
        assert parameter.default == params[name], name
    # and a class with a positional argument
    assert list(inspect.signature(pg.Mapper).parameters) == ["config"]


def test_keyword_arguments_are_the_generated_map_integration_table(source_dir: pathlib.Path) -> None:
    # One declaration per parameter: the constructor's keywords, their defaults, the
    # params dict and docs/STAGES.md's map_integration table (the tool's generated
    # reference) are made from the same C++ table.
    text = (source_dir / "docs" / "STAGES.md").read_text()
    section = text.split("## map_integration", 1)[1].split("\n## ", 1)[0]
    reference = {}
    for row in section.splitlines():
        cells = [c.strip() for c in row.split("|")]
        if len(cells) > 4 and cells[1].startswith("`") and cells[3].startswith("`"):
            reference[cells[1].strip("`")] = cells[3].strip("`")
    signature = inspect.signature(pg.PlanarGridMap)
    defaults = pg.PlanarGridMap().params
    assert list(defaults) == list(signature.parameters)
    assert len(defaults) >= 20
    for key, value in defaults.items():
        parameter = signature.parameters[key]
        assert parameter.kind is inspect.Parameter.KEYWORD_ONLY, key
        assert parameter.default == value and type(parameter.default) is type(value), key
        written = reference[key]
        if isinstance(value, bool):
            assert written == ("true" if value else "false"), key
        elif isinstance(value, (int, float)):
            assert float(written) == pytest.approx(value, rel=1e-9), key
        else:
            assert written == value, key
        assert key in (pg.PlanarGridMap.__doc__ or ""), key
    # The stage's own keys (how it sees a frame) are not the map's.
    assert set(reference) - set(defaults) == {
        "sensor_model", "depth_width_px", "depth_height_px", "depth_focal_length_px",
        "window_radius_m"}
    # Each keyword reaches the map with its type; others are refused by name.
    m = pg.PlanarGridMap(close_gaps_cells=3, merge_rule="paper", clear_planar=True)
    assert m.params["close_gaps_cells"] == 3 and m.params["merge_rule"] == "paper"
    assert m.params["clear_planar"] is True
    with pytest.raises(TypeError, match="unexpected keyword argument 'resolution'"):
        pg.PlanarGridMap(resolution=0.2)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="close_gaps_cells: expected int, got float"):
        pg.PlanarGridMap(close_gaps_cells=1.5)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="merge_rule: "):
        pg.PlanarGridMap(merge_rule="largest")


WallFrame = Tuple[npt.NDArray[np.float64], npt.NDArray[np.float64], pg.Cuboids,
                  npt.NDArray[np.float64], npt.NDArray[np.float64], npt.NDArray[np.float64]]


def wall_frame() -> WallFrame:
    """A wall at z = 3 (normal -z, toward a camera at the origin looking along +z): its
    points, planes, cuboids, features (probability 0.8) and a 64 x 48 depth image of it
    (3 m at every pixel; fx = fy = 50 px)."""
    wall = plane_patch([0.0, 0.0, -1.0], 3.0, 3.0, 0.05)
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                          min_inliers=100).segment(wall)
    cuboids = pg.PlanarCuboidApproximation().approximate(wall, planes)
    features = wall[::11]
    probabilities = np.full(len(features), 0.8)
    depth = np.full((48, 64), 3.0)
    return wall, planes.model_coefficients, cuboids, features, probabilities, depth


def test_integrate_gives_the_map_of_the_calls_it_stands_for() -> None:
    wall, planes, cuboids, features, probabilities, depth = wall_frame()
    pose = np.eye(4)
    # A depth image, then rays: each frame in one call and step by step.
    one_call = pg.PlanarGridMap(resolution_m=0.1)
    steps = pg.PlanarGridMap(resolution_m=0.1)
    removed = one_call.integrate(cuboids, planes, pose, features=features,
                                 probabilities=probabilities, depth=depth,
                                 fx=50.0, fy=50.0, cx=32.0, cy=24.0,
                                 observation_order=4.0)
    assert removed == dict(space_blocks=0, space_voxels=0, plane_cells=0, planes=0,
                           non_planar_cells=0)
    steps.integrate_surface(cuboids, planes, features, probabilities)
    steps.integrate_depth_image(depth, 50.0, 50.0, 32.0, 24.0, world_T_camera=pose)
    steps.note_observation_order(4.0)
    assert one_call == steps
    assert pickle.dumps(one_call) == pickle.dumps(steps)
    pose[:3, 3] = [0.2, 0.0, 0.0]
    one_call.integrate(cuboids, planes, pose, points=wall, observation_order=5.0)
    steps.integrate_surface(cuboids, planes, np.zeros((0, 3)), np.zeros(0))
    steps.integrate_point_cloud(wall, sensor_origin=[0.2, 0.0, 0.0])
    steps.note_observation_order(5.0)
    assert one_call == steps
    assert pickle.dumps(one_call) == pickle.dumps(steps)
    assert one_call.observation_span == (4.0, 5.0)
    assert len(one_call.cuboids) > 0 and one_call.voxel_counts["free"] > 0


def test_integrate_rolling_window_keeps_the_box_around_the_sensor() -> None:
    wall, planes, cuboids, _, _, _ = wall_frame()
    m = pg.PlanarGridMap(resolution_m=0.1)
    m.integrate(cuboids, planes, np.eye(4), points=wall)
    pose = np.eye(4)
    pose[:3, 3] = [2.0, 0.0, 0.0]
    # The box x in [1, 3], y in [-1, 1], every height: the wall's part with x < 1 goes.
    removed = m.integrate(cuboids, planes, pose, points=wall, window_half_size_m=1.0)
    assert removed["space_voxels"] > 0 and removed["plane_cells"] > 0
    occupied = m.voxel_centres(pg.SpaceState.OCCUPIED)
    assert len(occupied) > 0
    assert (occupied[:, 0] >= 1.0).all() and (np.abs(occupied[:, 1]) <= 1.0).all()


def test_integrate_rejects_a_bad_frame_and_leaves_the_map_unchanged() -> None:
    wall, planes, cuboids, features, probabilities, depth = wall_frame()
    m = pg.PlanarGridMap(resolution_m=0.1)
    m.integrate(cuboids, planes, np.eye(4), points=wall)
    before = pickle.dumps(m)
    bad_pose = np.eye(4)
    bad_pose[0, 3] = math.nan
    with pytest.raises(pg.Error, match="no space measurement"):
        m.integrate(cuboids, planes, np.eye(4))
    with pytest.raises(pg.Error, match="both a depth image and rays"):
        m.integrate(cuboids, planes, np.eye(4), points=wall, depth=depth, fx=50.0,
                    fy=50.0, cx=32.0, cy=24.0)
    with pytest.raises(pg.Error, match="feature points but"):
        m.integrate(cuboids, planes, np.eye(4), points=wall, features=features,
                    probabilities=probabilities[1:])
    with pytest.raises(pg.Error, match="observation order must be finite"):
        m.integrate(cuboids, planes, np.eye(4), points=wall, observation_order=math.nan)
    with pytest.raises(ValueError, match="rigid transform"):
        m.integrate(cuboids, planes, bad_pose, points=wall)
    with pytest.raises(pg.Error, match="window_half_size_m"):
        m.integrate(cuboids, planes, np.eye(4), points=wall, window_half_size_m=-1.0)
    with pytest.raises(ValueError, match="intrinsics"):
        m.integrate(cuboids, planes, np.eye(4), depth=depth, fx=50.0)
    assert pickle.dumps(m) == before
