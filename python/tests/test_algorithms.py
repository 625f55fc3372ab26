# SPDX-License-Identifier: BSD-3-Clause
"""SACMultiPlaneSegmentation, PlanarCuboidApproximation and KLDivergenceOccupancyFilter
through the Python module, against known planes, boxes and the paper's formulas."""

import inspect
import math
import pathlib
import re
from typing import Any, Dict, List, Type, cast

import numpy as np
import numpy.typing as npt
import pytest

import planar_grid as pg
from conftest import plane_patch


def unit(v: npt.ArrayLike) -> npt.NDArray[np.float64]:
    a: npt.NDArray[np.float64] = np.asarray(v, dtype=float)
    return a / np.linalg.norm(a)


def test_tilted_plane_gives_its_normal_and_offset() -> None:
    # 3 m x 3 m of a tilted plane with 5 mm noise, 3 m from the origin, plus 20 % outliers
    # spread over a 6 m cube: the one plane found must be the plane, normal within 1 deg
    # (the refit on ~3700 points with 5 mm noise is far better), d within 1 cm.
    rng = np.random.default_rng(7)
    normal, d = unit([0.3, -0.2, 0.9]), 3.0
    on_plane = plane_patch(normal, d, 3.0, 0.05, rng, noise_m=0.005)
    outliers = rng.uniform(-3.0, 3.0, size=(len(on_plane) // 5, 3))
    points = np.vstack([on_plane, outliers])

    seg = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=500, seed=0)
    planes = seg.segment(points)

    assert len(planes) == 1
    a, b, c, d_found = planes.model_coefficients[0]
    found = np.array([a, b, c])
    assert abs(np.linalg.norm(found) - 1.0) < 1e-5
    # The normal points toward the sensor origin (0, 0, 0): d >= 0, so it is +normal.
    assert d_found >= 0.0
    assert math.degrees(math.acos(min(1.0, float(found @ normal)))) < 1.0
    assert d_found == pytest.approx(d, abs=0.01)
    # Every plane point is within 4 sigma = 2 cm (the threshold), so all are inliers;
    # the outliers within 2 cm of the plane (a slab of 4 cm in a 6 m cube: < 1 %) may join.
    inliers = planes.inliers[0]
    assert np.all(np.diff(inliers) > 0)
    n_plane = len(on_plane)
    assert np.count_nonzero(inliers < n_plane) >= 0.99 * n_plane
    assert np.count_nonzero(inliers >= n_plane) <= 0.02 * len(outliers)
    # Eq. 2: theta is the angle between the normal and the up axis (0, 0, 1).
    assert planes.tilt_rad[0] == pytest.approx(math.acos(normal[2]), abs=0.02)
    assert planes.centroids.shape == (1, 3)


def test_floor_and_wall_are_two_planes_with_their_tilts() -> None:
    # A floor z = -1 and a wall x = 4 (seen from the origin): normals (0, 0, 1) and
    # (-1, 0, 0) toward the origin, tilts 0 and pi/2 (eq. 2).
    floor = plane_patch([0, 0, 1], 1.0, 4.0, 0.05)
    wall = plane_patch([-1, 0, 0], 4.0, 3.0, 0.05)
    seg = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=300)
    planes = seg.segment(np.vstack([floor, wall]))

    assert len(planes) == 2
    by_tilt = np.argsort(planes.tilt_rad)
    np.testing.assert_allclose(planes.normals[by_tilt[0]], [0, 0, 1], atol=1e-3)
    np.testing.assert_allclose(planes.normals[by_tilt[1]], [-1, 0, 0], atol=1e-3)
    np.testing.assert_allclose(planes.tilt_rad[by_tilt], [0.0, math.pi / 2], atol=1e-3)
    # Sorted by descending inlier count: the floor (81 x 81 points) before the wall. The
    # floor, found first, also takes the wall's row within d_T of its (infinite) plane.
    wall_row = np.abs(wall[:, 2] + 1.0) <= 0.02
    assert wall_row.sum() == 61
    assert [len(i) for i in planes.inliers] == [len(floor) + 61, len(wall) - 61]
    np.testing.assert_array_equal(planes.inliers[1],
                                  len(floor) + np.flatnonzero(~wall_row))


def test_segmentation_parameters_are_checked_by_the_library() -> None:
    seg = pg.SACMultiPlaneSegmentation(max_planes=3)
    assert seg.max_planes == 3
    assert seg.distance_threshold_m == pytest.approx(0.05)
    with pytest.raises(ValueError, match=r"distance_threshold_m must be in \(0, 1\] m"):
        seg.distance_threshold_m = -1.0
    assert seg.distance_threshold_m == pytest.approx(0.05)  # unchanged
    with pytest.raises(ValueError, match="probability must be in"):
        pg.SACMultiPlaneSegmentation(probability=1.5)
    # A misspelt keyword on purpose, given through a dict (mypy checks no dict's keys).
    misspelt: Dict[str, Any] = {"distance_threshold": 0.1}
    with pytest.raises(TypeError, match="distance_threshold"):
        pg.SACMultiPlaneSegmentation(**misspelt)
    with pytest.raises(ValueError, match="method 'lmeds'"):
        seg.method = "lmeds"
    seg.method = "msac"
    assert seg.method == "msac"
    # What describes the sensor goes to segment(), checked there.
    with pytest.raises(ValueError, match="up_axis must not be zero"):
        seg.segment(np.zeros((10, 3)), up_axis=(0, 0, 0))
    with pytest.raises(ValueError, match="depth_noise_coefficient_per_m must be in"):
        seg.segment(np.zeros((10, 3)), depth_noise_coefficient_per_m=-1.0)


def test_approximate_stands_the_cells_along_the_up_axis() -> None:
    # A wall x = 4 (3 m square, 5 cm grid): its cells' vertical axis (rotations[:, :, 1])
    # is the up axis given, +z or +y, and their horizontal axis the wall's other one.
    wall = plane_patch([-1, 0, 0], 4.0, 3.0, 0.05)
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02,
                                          min_inliers=300).segment(wall)
    approx = pg.PlanarCuboidApproximation(min_cell_size_m=0.1)
    for up, side in (([0, 0, 1], [0, 1, 0]), ([0, 3, 0], [0, 0, 1])):
        cuboids = approx.approximate(wall, planes, up_axis=up)
        assert len(cuboids) > 0 and all(cuboids.is_planar)
        np.testing.assert_allclose(np.abs(cuboids.rotations[:, :, 1]),
                                   np.tile(np.abs(unit(up)), (len(cuboids), 1)), atol=1e-5)
        np.testing.assert_allclose(np.abs(cuboids.rotations[:, :, 0]),
                                   np.tile(side, (len(cuboids), 1)), atol=1e-5)
    with pytest.raises(ValueError, match="up_axis must not be zero"):
        approx.approximate(wall, planes, up_axis=(0, 0, 0))


def test_segment_takes_the_up_axis_and_the_depth_noise_of_the_sensor() -> None:
    # Eq. 2's tilt is measured from the up axis: a floor z = -1 is level for +z and
    # upright for +x.
    floor = plane_patch([0, 0, 1], 1.0, 4.0, 0.05)
    seg = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=300)
    assert seg.segment(floor).tilt_rad[0] == pytest.approx(0.0, abs=1e-3)
    assert seg.segment(floor, up_axis=(2, 0, 0)).tilt_rad[0] == pytest.approx(
        math.pi / 2, abs=1e-3)
    # A wall 8 m away whose points scatter 5 cm along the plane's normal: within d_T = 2
    # cm alone a third are inliers; with the stereo noise of eq. 4 (coefficient c:
    # max(d_T, c r^2) >= 0.256 m from 8 m, over 5 sigma) all are. Distance alone
    # (eq. 11): the points' own normals scatter at this noise.
    rng = np.random.default_rng(4)
    wall = plane_patch([-1, 0, 0], 8.0, 3.0, 0.05, rng, noise_m=0.05)
    seg.max_normal_angle_rad = 0.0
    fixed = seg.segment(wall)
    widened = seg.segment(wall, depth_noise_coefficient_per_m=0.004)
    assert len(widened) == 1 and len(widened.inliers[0]) == len(wall)
    assert len(fixed) == 0 or len(fixed.inliers[0]) < 0.5 * len(wall)


def test_segmentation_of_degenerate_input_is_empty_and_bad_shapes_raise() -> None:
    seg = pg.SACMultiPlaneSegmentation()
    assert len(seg.segment(np.zeros((0, 3)))) == 0
    assert len(seg.segment(np.full((100, 3), np.nan))) == 0
    with pytest.raises(ValueError, match=r"\(N, 3\).*shape \(10, 2\)"):
        seg.segment(np.zeros((10, 2)))


def test_same_seed_gives_same_planes() -> None:
    rng = np.random.default_rng(3)
    points = np.vstack([plane_patch([0, 0, 1], 1.0, 4.0, 0.05, rng, 0.01),
                        rng.uniform(-2, 2, size=(2000, 3))])
    a = pg.SACMultiPlaneSegmentation(seed=5).segment(points)
    b = pg.SACMultiPlaneSegmentation(seed=5).segment(points)
    np.testing.assert_array_equal(a.model_coefficients, b.model_coefficients)
    for x, y in zip(a.inliers, b.inliers):
        np.testing.assert_array_equal(x, y)


def as_inliers(indices: List[List[int]]) -> List[npt.NDArray[np.int64]]:
    """Index lists given as PlanarSegments' inliers as they are: the binding converts
    each to an array, the stub (pybind11's signature) names the arrays only."""
    return cast(List[npt.NDArray[np.int64]], indices)


def box_frame_coordinates(cuboids: pg.Cuboids,
                          points: npt.NDArray[np.float64]) -> npt.NDArray[np.float64]:
    """Coordinates of every point in every box frame: (M, N, 3), along the columns of
    rotations, relative to the centres."""
    rel = points[None, :, :] - cuboids.centres[:, None, :]
    local: npt.NDArray[np.float64] = np.einsum("mnk,mkj->mnj", rel, cuboids.rotations)
    return local


def test_wall_becomes_planar_cuboids_that_cover_every_point() -> None:
    # A 2 m x 1 m wall at x = 3 (normal toward the origin: (-1, 0, 0)), points every
    # 0.05 m. With min_points_per_cell = 1 every point lies in some cuboid (the class's
    # guarantee); the faces lie on the wall and the boxes reach thickness_m behind it.
    ys, zs = np.meshgrid(np.arange(-1.0, 1.0 + 1e-9, 0.05), np.arange(0.0, 1.0 + 1e-9, 0.05))
    wall = np.column_stack([np.full(ys.size, 3.0), ys.ravel(), zs.ravel()])
    planes = pg.PlanarSegments([[-1.0, 0.0, 0.0, 3.0]], [np.arange(len(wall))])
    approx = pg.PlanarCuboidApproximation(min_cell_size_m=0.1, thickness_m=0.1,
                                          min_points_per_cell=1)
    cuboids = approx.approximate(wall, planes)

    assert len(cuboids) >= 1
    assert cuboids.is_planar.all()
    np.testing.assert_array_equal(cuboids.plane_ids, 0)
    np.testing.assert_allclose(cuboids.normals, np.tile([-1.0, 0.0, 0.0], (len(cuboids), 1)),
                               atol=1e-6)
    # Face at the wall (x = 3), back at x = 3 + thickness.
    np.testing.assert_allclose(cuboids.min_bounds[:, 0], 3.0, atol=1e-5)
    np.testing.assert_allclose(cuboids.max_bounds[:, 0], 3.1, atol=1e-5)
    local = box_frame_coordinates(cuboids, wall)
    inside = np.all(np.abs(local) <= cuboids.extents_m[:, None, :] / 2 + 1e-5, axis=2)
    assert inside.any(axis=0).all()
    # The rectangles are tightened to their points: the faces cover at most the wall's
    # 2 m^2, and the point counts add up to the points.
    assert (cuboids.extents_m[:, 0] * cuboids.extents_m[:, 1]).sum() <= 2.0 + 1e-4
    assert cuboids.point_counts.sum() == len(wall)
    # The corners are the face's four then the back's four.
    np.testing.assert_allclose(cuboids.corners[:, :4, 0], 3.0, atol=1e-5)
    np.testing.assert_allclose(cuboids.corners[:, 4:, 0], 3.1, atol=1e-5)


def test_without_planes_every_point_is_in_a_non_planar_cuboid() -> None:
    rng = np.random.default_rng(1)
    points = rng.uniform(0.0, 1.0, size=(500, 3)) + [2.0, 0.0, 0.0]
    cuboids = pg.PlanarCuboidApproximation(min_points_per_cell=1).approximate(points)
    assert len(cuboids) > 0 and not cuboids.is_planar.any()
    np.testing.assert_array_equal(cuboids.plane_ids, -1)
    local = box_frame_coordinates(cuboids, points)
    inside = np.all(np.abs(local) <= cuboids.extents_m[:, None, :] / 2 + 1e-5, axis=2)
    assert inside.any(axis=0).all()


def test_approximation_rejects_bad_planes_and_parameters() -> None:
    points = np.zeros((10, 3))
    with pytest.raises(IndexError, match="inlier index 10, outside the 10 points"):
        pg.PlanarCuboidApproximation().approximate(
            points, pg.PlanarSegments([[0, 0, 1, 0]], as_inliers([[0, 10]])))
    with pytest.raises(TypeError, match="PlanarSegments"):
        pg.PlanarCuboidApproximation().approximate(points, [[0, 0, 1, 0]])
    with pytest.raises(ValueError, match=r"thickness_m must be in \(0, 10\] m"):
        pg.PlanarCuboidApproximation(thickness_m=0.0)
    with pytest.raises(ValueError, match="2 inlier arrays for 1 planes"):
        pg.PlanarSegments([[0, 0, 1, 0]], as_inliers([[0], [1]]))


# Eq. 4 and eq. 10 written out here from the paper, independently of the library.
def eq4(r: npt.NDArray[np.float64], r_bar: npt.NDArray[np.float64],
        z: npt.NDArray[np.float64], f: float, b: float, dd: float) -> npt.NDArray[np.float64]:
    dz = z * z / (b * f) * dd
    dr = r_bar / z * dz
    p: npt.NDArray[np.float64] = np.exp(-0.5 * ((r - r_bar) / dr) ** 2)
    return p


def eq10(p: float, q: float, a: float) -> float:
    q = min(max(q, 1e-9), 1 - 1e-9)
    kl = sum(x * math.log(x / y) for x, y in ((p, q), (1 - p, 1 - q)) if x > 0)
    e = abs(kl) + (a if p <= 0.5 and q <= 0.5 else 0.0)
    return math.exp(-e)


F_PX, B_M = 645.24, 0.5707  # the Karlsruhe rig


def test_occupancy_of_features_follows_eq4_and_the_kl_rule() -> None:
    # Camera frame (z forward). Two features share a 0.5 m neighbourhood cell at ~10 m
    # (r_bar is their mean range), one is alone in its cell (r = r_bar: p = 1, clamped to
    # 0.971). Frame 2 observes the same tracks again: p <- eq. 10 with q = p_new.
    features = np.array([[0.10, 0.10, 10.05], [0.20, 0.10, 10.40], [3.10, 0.10, 5.10]])
    kl = pg.KLDivergenceOccupancyFilter(F_PX, B_M)
    ids = np.array([1, 2, 3])
    kept = kl.filter(features, track_ids=ids)

    r = np.linalg.norm(features, axis=1)
    r_bar = np.array([r[:2].mean(), r[:2].mean(), r[2]])
    expected = np.clip(eq4(r, r_bar, features[:, 2], F_PX, B_M, 0.5), 0.1192, 0.971)
    np.testing.assert_allclose(kl.probabilities, expected, rtol=1e-5)
    np.testing.assert_array_equal(kept, np.flatnonzero(expected >= 0.5))
    np.testing.assert_allclose(
        np.asarray(pg.range_occupancy_probability(r, r_bar, features[:, 2], F_PX, B_M, 0.5)),
        eq4(r, r_bar, features[:, 2], F_PX, B_M, 0.5), rtol=1e-12)
    np.testing.assert_array_equal(kl.assigned_track_ids, ids)
    assert kl.track_count == 3

    kl.filter(features, track_ids=ids)
    second = [min(max(eq10(p, q, 1.07), 0.1192), 0.971) for p, q in zip(expected, expected)]
    np.testing.assert_allclose(kl.probabilities, second, rtol=1e-5)
    for track, p in zip(ids, second):
        assert kl.track_probability(int(track)) == pytest.approx(p, rel=1e-5)
    assert kl.track_probability(99) is None
    assert pg.kl_divergence_update(0.3, 0.3, 1.07) == pytest.approx(eq10(0.3, 0.3, 1.07))

    kl.reset()
    assert kl.track_count == 0


def test_occupancy_filter_errors_carry_the_library_message() -> None:
    with pytest.raises(ValueError, match="stereo parameters not set"):
        pg.KLDivergenceOccupancyFilter(0.0, B_M)
    kl = pg.KLDivergenceOccupancyFilter(F_PX, B_M, occupancy_thres=0.6, update_rule="log_odds")
    assert kl.occupancy_thres == pytest.approx(0.6) and kl.update_rule == "log_odds"
    with pytest.raises(ValueError, match="clamping_thres_max must be in"):
        kl.clamping_thres_max = 1.2
    with pytest.raises(ValueError, match="motion likelihood must be in"):
        kl.filter(np.ones((3, 3)), motion_likelihood=1.5)
    with pytest.raises(ValueError, match="one id per feature"):
        kl.filter(np.ones((3, 3)), track_ids=[1, 2])
    with pytest.raises(ValueError, match="update_rule: Unknown occupancy update rule 'bayes'"):
        kl.update_rule = "bayes"


def test_occupancy_filter_stereo_rig_is_positional_or_keyword() -> None:
    # The rig by position, by name in any order, or mixed; not twice, not missing.
    by_name = pg.KLDivergenceOccupancyFilter(baseline_m=B_M, focal_length_px=F_PX)
    mixed = pg.KLDivergenceOccupancyFilter(F_PX, baseline_m=B_M)
    assert repr(by_name) == repr(mixed) == repr(pg.KLDivergenceOccupancyFilter(F_PX, B_M))
    with pytest.raises(TypeError, match="multiple values for argument 'focal_length_px'"):
        pg.KLDivergenceOccupancyFilter(F_PX, B_M, focal_length_px=F_PX)  # type: ignore[misc]
    with pytest.raises(TypeError, match="missing required argument: 'baseline_m'"):
        pg.KLDivergenceOccupancyFilter(F_PX)  # type: ignore[call-arg]
    with pytest.raises(TypeError, match="takes 2 positional arguments but 3 were given"):
        pg.KLDivergenceOccupancyFilter(F_PX, B_M, 0.5)  # type: ignore[misc, arg-type]
    with pytest.raises(TypeError, match="focal_length_px: expected float"):
        pg.KLDivergenceOccupancyFilter("f", B_M)  # type: ignore[arg-type]
    # The other sensors' keys are the pipeline's, not keywords of the stereo filter.
    with pytest.raises(TypeError, match="unexpected keyword argument 'range_error_m'"):
        pg.KLDivergenceOccupancyFilter(F_PX, B_M, range_error_m=0.1)  # type: ignore[call-arg]
    # A rig the filter refuses leaves the old value.
    with pytest.raises(ValueError, match="stereo parameters not set"):
        mixed.baseline_m = -1.0
    assert mixed.baseline_m == pytest.approx(B_M)


def test_repr_is_the_constructor_call_with_every_parameter() -> None:
    # repr() names each parameter with its value; evaluated, it rebuilds an object of the
    # same parameters.
    objects = [pg.SACMultiPlaneSegmentation(max_planes=3, distance_threshold_m=0.02),
               pg.PlanarCuboidApproximation(min_cell_size_m=0.2),
               pg.KLDivergenceOccupancyFilter(500.0, 0.1, neighbourhood_size_m=0.3)]
    for obj, expected in zip(objects, ["max_planes=3", "min_cell_size_m=0.2",
                                       "focal_length_px=500.0, baseline_m=0.1"]):
        text = repr(obj)
        assert text.startswith("planar_grid." + type(obj).__name__ + "(")
        assert expected in text
        assert repr(eval(text, {"planar_grid": pg})) == text


# A value other than the default, in range, for every parameter of each class: the
# constructor takes each by name and the property reads it back.
CONSTRUCTOR_VALUES: Dict[Type[Any], Dict[str, object]] = {
    pg.SACMultiPlaneSegmentation: dict(
        distance_threshold_m=0.02, depth_noise_along_sight=True,
        sample_distance_threshold_m=0.04, max_planes=5, min_inliers=100,
        min_sample_inliers=10, min_remaining_fraction=0.1, max_iterations=200,
        probability=0.95, method="msac", optimize_coefficients=False,
        dense_hypothesis=False, lo_iterations=10, merge_planes=False,
        merge_angle_rad=0.2, merge_distance_m=0.05, seed=7, max_sample_size=5000,
        max_visibility_conflict_ratio=0.2, visibility_margin_m=0.2,
        visibility_cell_m=0.1, min_sensor_distance_m=0.5, min_sensor_height_m=1.0,
        max_terrain_below_ratio=0.5, min_cluster_size=50, cluster_cell_m=0.1,
        max_shell_ratio=0.3, shell_width_m=0.2, count_inlier_only_points=False,
        inlier_only_distance_threshold_m=0.1, max_normal_angle_rad=0.3,
        normal_cell_m=0.1, min_normal_agreement=0.5),
    pg.PlanarCuboidApproximation: dict(
        min_cell_size_m=0.05, density_threshold=0.8, non_planar_density_threshold=0.7,
        min_width_m=0.2, min_height_m=0.3, thickness_m=0.05, min_points_per_cell=1),
    pg.KLDivergenceOccupancyFilter: dict(
        focal_length_px=500.0, baseline_m=0.1, disparity_error_px=1.0,
        neighbourhood_size_m=0.3, clamping_thres_min=0.2, clamping_thres_max=0.9,
        occupancy_thres=0.6, kl_offset_nats=0.5, prob_hit=0.8, prob_miss=0.3,
        association_radius_m=0.3, update_rule="log_odds"),
}
# The stereo rig, the filter's leading (positional or keyword) arguments.
LEADING: Dict[Type[Any], List[str]] = {
    pg.KLDivergenceOccupancyFilter: ["focal_length_px", "baseline_m"]}
# The unit a parameter name's suffix states, and the word its documentation uses.
UNITS = {"_m": "meters", "_rad": "radians", "_px": "pixels", "_nats": "nats",
         "_per_m": "1/m"}
# The parameters that are probabilities in [0, 1].
PROBABILITIES = {"probability", "clamping_thres_min", "clamping_thres_max",
                 "occupancy_thres", "prob_hit", "prob_miss"}


def default_object(cls: Type[Any]) -> object:
    return cls(F_PX, B_M) if cls is pg.KLDivergenceOccupancyFilter else cls()


def read_back(value: object) -> object:
    return value.tolist() if isinstance(value, np.ndarray) else value


def class_name(cls: Type[Any]) -> str:
    """A parametrized class's test id."""
    return cls.__name__


@pytest.mark.parametrize("cls", list(CONSTRUCTOR_VALUES), ids=class_name)
def test_constructor_signature_names_every_parameter_with_the_cpp_default(
        cls: Type[Any]) -> None:
    signature = inspect.signature(cls)
    names = list(signature.parameters)
    assert set(names) == set(CONSTRUCTOR_VALUES[cls])
    leading = LEADING.get(cls, [])
    assert names[:len(leading)] == leading
    obj = default_object(cls)
    for name, parameter in signature.parameters.items():
        assert isinstance(getattr(type(obj), name), property), name
        assert parameter.annotation is not inspect.Parameter.empty, name
        if name in leading:
            assert parameter.kind is inspect.Parameter.POSITIONAL_OR_KEYWORD
            assert parameter.default is inspect.Parameter.empty
            continue
        assert parameter.kind is inspect.Parameter.KEYWORD_ONLY, name
        # The default is the C++ object's own: what an object built without it holds.
        if parameter.default is None:
            assert name == "sample_distance_threshold_m"
            continue
        default = parameter.default
        expected = read_back(getattr(obj, name))
        assert (list(default) if isinstance(default, tuple) else default) == expected, name


def test_signature_defaults_are_the_library_defaults() -> None:
    # A few of the C++ in-class initialisers, spelled out once here as the check.
    seg = inspect.signature(pg.SACMultiPlaneSegmentation).parameters
    assert seg["distance_threshold_m"].default == pytest.approx(0.05)
    assert seg["max_planes"].default == 8 and seg["min_inliers"].default == 500
    assert seg["method"].default == "ransac" and seg["max_sample_size"].default == 20000
    assert seg["probability"].default == pytest.approx(0.99)
    approx = inspect.signature(pg.PlanarCuboidApproximation).parameters
    assert approx["min_cell_size_m"].default == pytest.approx(0.1)
    assert approx["min_points_per_cell"].default == 3
    kl = inspect.signature(pg.KLDivergenceOccupancyFilter).parameters
    assert kl["occupancy_thres"].default == pytest.approx(0.5)
    assert kl["update_rule"].default == "kl_divergence"
    # The sample threshold is the pipeline's 0.1 m; it does not follow the distance
    # threshold.
    assert pg.SACMultiPlaneSegmentation(
        distance_threshold_m=0.02).sample_distance_threshold_m == pytest.approx(0.1)


@pytest.mark.parametrize("cls", list(CONSTRUCTOR_VALUES), ids=class_name)
def test_constructor_docstring_lists_each_parameter_with_unit_and_default(
        cls: Type[Any]) -> None:
    doc = cls.__init__.__doc__
    # numpydoc entries: "name : type[, optional]" then the indented description.
    entries = dict(re.findall(r"^(\w+) : [^\n]*\n((?:    [^\n]*\n)+)", doc, re.M))
    signature = inspect.signature(cls)
    assert set(entries) == set(signature.parameters)
    for name, parameter in signature.parameters.items():
        text = " ".join(entries[name].split())
        if parameter.default is not inspect.Parameter.empty:
            assert f"Default {parameter.default!r}." in text, name
        suffix = max((s for s in UNITS if name.endswith(s)), key=len, default=None)
        if suffix:
            assert UNITS[suffix] in text, name
        if name in PROBABILITIES:
            assert "probability" in text, name


@pytest.mark.parametrize("cls", list(CONSTRUCTOR_VALUES), ids=class_name)
def test_constructor_values_read_back_and_show_in_repr(cls: Type[Any]) -> None:
    values = CONSTRUCTOR_VALUES[cls]
    obj = cls(**values)
    text = repr(obj)
    for name, value in values.items():
        got = read_back(getattr(obj, name))
        if isinstance(value, float):
            assert got == pytest.approx(value), name
        else:
            assert got == value, name
        assert f" {name}=" in text or f"({name}=" in text, name
    # The leading arguments also go by position; the others only by name.
    if cls in LEADING:
        assert repr(cls(500.0, 0.1)) == repr(cls(focal_length_px=500.0, baseline_m=0.1))
    with pytest.raises(TypeError):
        cls(*[values[n] for n in LEADING.get(cls, [])], 0.5)


@pytest.mark.parametrize("cls", list(CONSTRUCTOR_VALUES), ids=class_name)
def test_unknown_keyword_is_a_type_error_naming_it(cls: Type[Any]) -> None:
    leading = {n: CONSTRUCTOR_VALUES[cls][n] for n in LEADING.get(cls, [])}
    with pytest.raises(TypeError, match="resolution_cm"):
        cls(**leading, resolution_cm=5)
    # A value of another type for a known keyword is a TypeError too.
    number = next(n for n, p in inspect.signature(cls).parameters.items()
                  if p.annotation is float and n not in leading)
    with pytest.raises(TypeError,
                       match="incompatible constructor arguments|expected float"):
        cls(**leading, **{number: "not a number"})


def floor_wall_pebbles() -> npt.NDArray[np.float64]:
    """A floor z = -1 (1 m below the origin), a wall x = 4 standing on it and 200 loose
    pebbles 3-10 cm above the floor: rows floor, then wall, then pebbles."""
    floor = plane_patch([0, 0, 1], 1.0, 4.0, 0.05)
    wall = plane_patch([-1, 0, 0], 4.0, 3.0, 0.05)
    wall = wall[wall[:, 2] > -0.9]
    rng = np.random.default_rng(3)
    pebbles = np.column_stack([rng.uniform(-1.5, 1.5, 200), rng.uniform(-1.5, 1.5, 200),
                               rng.uniform(-0.97, -0.9, 200)])
    return np.vstack([floor, wall, pebbles])


def test_terrain_removal_takes_the_floor_and_what_lies_on_it() -> None:
    points = floor_wall_pebbles()
    n_floor, n_pebbles = 81 * 81, 200
    n_wall = len(points) - n_floor - n_pebbles
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.02, min_inliers=300,
                                          seed=0).segment(points)
    assert len(planes) == 2
    is_terrain, kept, ground = pg.TerrainRemoval().segment(points, planes)
    # The floor and the pebbles on it are terrain; the wall (its foot too) is not.
    assert is_terrain.dtype == np.bool_ and is_terrain.shape == (len(points),)
    assert is_terrain[:n_floor].all() and is_terrain[-n_pebbles:].all()
    assert not is_terrain[n_floor:n_floor + n_wall].any()
    assert len(kept) == 1
    np.testing.assert_allclose(kept.normals[0], [-1, 0, 0], atol=1e-3)
    # The ground's normal is up, so that the sensor's signed distance is its height.
    assert ground is not None
    np.testing.assert_allclose(ground, [0, 0, 1, 1], atol=1e-3)

    # The sensor must stand min_sensor_height_m above the ground: at 1.5 m it does not.
    is_terrain, kept, ground = pg.TerrainRemoval(min_sensor_height_m=1.5).segment(
        points, planes)
    assert ground is None and not is_terrain.any() and len(kept) == 2

    # The ground as planar cells: the floor (x, y in [-2, 2]) stays as four planes, one
    # per 3 m tile of x, y; only the loose pebbles go.
    is_terrain, kept, ground = pg.TerrainRemoval(terrain_plane_tile_m=3.0).segment(
        points, planes)
    assert ground is not None
    assert not is_terrain[:n_floor + n_wall].any() and is_terrain[-n_pebbles:].all()
    level = [i for i in range(len(kept)) if abs(kept.normals[i][2]) > 0.999]
    assert len(level) == 4 and len(kept) == 5
    assert sum(len(kept.inliers[i]) for i in level) == n_floor
    # Planes that index points not given are refused, as the approximation refuses them.
    with pytest.raises(IndexError, match="plane 0 has the inlier index"):
        pg.TerrainRemoval().segment(points[:100], planes)
    # No plane keeps a terrain point, so the planes re-index onto the points kept
    # (docs/PYTHON.md) and the approximation makes the floor's cells.
    keep = np.flatnonzero(~is_terrain)
    index = np.full(len(points), -1)
    index[keep] = np.arange(len(keep))
    remapped = pg.PlanarSegments(kept.model_coefficients, [index[i] for i in kept.inliers])
    assert all((i >= 0).all() for i in remapped.inliers)
    cuboids = pg.PlanarCuboidApproximation().approximate(points[keep], remapped)
    assert set(cuboids.plane_ids[cuboids.is_planar]) == set(range(5))


def test_terrain_removal_parameters_are_the_ground_removal_stage_keys(
        source_dir: pathlib.Path) -> None:
    # Declared once in C++: the keywords, their defaults and the generated reference.
    text = (source_dir / "docs" / "STAGES.md").read_text()
    section = text.split("## ground_removal", 1)[1].split("\n## ", 1)[0]
    reference = {}
    for row in section.splitlines():
        cells = [c.strip() for c in row.split("|")]
        if len(cells) > 4 and cells[1].startswith("`") and cells[3].startswith("`"):
            reference[cells[1].strip("`")] = float(cells[3].strip("`"))
    signature = inspect.signature(pg.TerrainRemoval)
    assert list(signature.parameters) == list(reference)
    removal = pg.TerrainRemoval()
    for key, value in reference.items():
        assert signature.parameters[key].default == pytest.approx(value), key
        assert getattr(removal, key) == pytest.approx(value), key
    # A value out of its range is refused by name and leaves the object as it was.
    with pytest.raises(ValueError, match=r"terrain_cell_m must be in \[0.05, 100\] m"):
        removal.terrain_cell_m = 0.0
    assert removal.terrain_cell_m == pytest.approx(reference["terrain_cell_m"])
    with pytest.raises(ValueError, match="eps_angle_rad must be in"):
        pg.TerrainRemoval(eps_angle_rad=2.0)
    with pytest.raises(TypeError, match="unexpected keyword argument 'eps_angle'"):
        pg.TerrainRemoval(**cast(Dict[str, Any], {"eps_angle": 0.1}))
    removal.terrain_plane_tile_m = 4
    rebuilt = eval(repr(removal), {"planar_grid": pg})
    assert rebuilt.terrain_plane_tile_m == 4.0 and repr(rebuilt) == repr(removal)
