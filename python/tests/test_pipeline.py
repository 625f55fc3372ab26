# SPDX-License-Identifier: BSD-3-Clause
"""run_pipeline() on three real Karlsruhe frames with the main job's configuration, and
its configuration errors."""

import pathlib
from typing import List, Tuple

import numpy as np
import pytest

import planar_grid as pg

# The karlsruhe_run fixture: the run's result, its output folder and the progress calls'
# (done, total) pairs.
KarlsruheRun = Tuple[pg.PipelineResult, pathlib.Path, List[Tuple[int, int]]]


@pytest.fixture(scope="module")
def karlsruhe_run(tmp_path_factory: pytest.TempPathFactory,
                  source_dir_module: pathlib.Path) -> KarlsruheRun:
    """config/karlsruhe.yaml (the main job) on frames 10-12, outputs in a temporary
    folder."""
    out = tmp_path_factory.mktemp("karlsruhe")
    progress: List[Tuple[int, int]] = []
    result = pg.run_pipeline(source_dir_module / "config" / "karlsruhe.yaml", frames=(10, 13),
                             output_folder=out,
                             progress=lambda done, total, s: progress.append((done, total)))
    return result, out, progress


@pytest.fixture(scope="module")
def source_dir_module() -> pathlib.Path:
    from conftest import SOURCE_DIR, DATA_DIR
    if not DATA_DIR.is_dir():
        pytest.fail(f"the shared data folder {DATA_DIR} is missing (PLANAR_GRID_DATA_DIR)")
    return SOURCE_DIR


def test_run_gives_the_report_poses_and_map(karlsruhe_run: KarlsruheRun) -> None:
    result, out, progress = karlsruhe_run
    assert result.frames == 3 and result.report["frames"] == 3
    # report.json's layout (docs/OUTPUTS.md): its version, the writer's version, and
    # counts as integers, not floats.
    report = result.report
    assert report["schema_version"] == 1
    assert report["planar_grid_version"] == pg.__version__
    assert isinstance(report["map"]["cuboids"], int)
    assert isinstance(report["map"]["resolution_m"], float)
    assert progress == [(1, 3), (2, 3), (3, 3)]
    # GPS/INS poses of consecutive frames: the car moves 0.74 m a frame (median over the
    # sequence, data README), level along the track.
    trajectory = result.trajectory
    assert trajectory.shape == (3, 4, 4)
    steps = np.linalg.norm(np.diff(trajectory[:, :3, 3], axis=0), axis=1)
    assert np.all((steps > 0.3) & (steps < 1.5))
    np.testing.assert_allclose(trajectory[:, 3], np.tile([0, 0, 0, 1], (3, 1)))
    m = result.map
    # three frames of a street: tens of cuboids, planar ones among them (74 and 35 with
    # the main job's density merge)
    assert m is not None and len(m.cuboids) > 30 and m.cuboids.is_planar.sum() > 10
    # The cameras are in free space, not in a cell.
    cameras = trajectory[:, :3, 3]
    assert not np.any(m.get_state(cameras) == pg.SpaceState.OCCUPIED)
    # A street: facades are vertical planes (normal's z component ~ 0).
    assert np.any(np.abs(m.planes[:, 2]) < 0.1)
    assert len(result.world_cloud) > 1000
    assert result.world_cloud.shape[1] == 3
    assert len(result.plane_labels) == len(result.plane_cloud)
    assert result.plane_labels.max() < len(result.plane_models)
    assert "multi_plane_segmentation" in result.timing_table


def test_written_map_is_the_returned_one(karlsruhe_run: KarlsruheRun) -> None:
    result, out, _ = karlsruhe_run
    outputs = result.outputs
    assert outputs["map"] == str(out / "map.pgmap")
    loaded = pg.PlanarGridMap.load(outputs["map"])
    assert loaded == result.map
    for kind in ("cloud", "trajectory", "report", "map_octomap", "map_mesh"):
        assert (out / outputs[kind].split("/")[-1]).is_file(), kind
    assert not (out / "snapshot.png").exists()  # the module renders no snapshot


def test_points_of_the_map_surface_are_known_space(karlsruhe_run: KarlsruheRun) -> None:
    # Every cuboid centre lies in its own cuboid, so the map answers from the surface
    # layer there: occupied or free by the cuboid's probability, never unknown.
    result, _, _ = karlsruhe_run
    m = result.map
    cuboids = m.cuboids
    states = m.get_state(cuboids.centres)
    assert not np.any(states == pg.SpaceState.UNKNOWN)
    occupancy = m.get_occupancy(cuboids.centres)
    expected = np.where(states == pg.SpaceState.OCCUPIED, occupancy >= 0.5, occupancy < 0.5)
    assert expected.all()


def test_configuration_errors_name_the_place(tmp_path: pathlib.Path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("input:\n  type: stereo_sequence\n  bogus_key_m: 1\n")
    with pytest.raises(pg.ConfigError) as error:
        pg.run_pipeline(bad, write_outputs=False)
    assert isinstance(error.value, ValueError)
    file: str = error.value.file
    assert file.endswith("bad.yaml")
    assert (error.value.line, error.value.column) == (3, 3)
    assert str(error.value).startswith(f"{file}:3:3: ")
    assert "bogus_key_m" in str(error.value)
    with pytest.raises(pg.IOError, match="missing.yaml"):
        pg.run_pipeline(tmp_path / "missing.yaml")


def test_outputs_that_would_overwrite_an_input_or_a_folder_are_refused(
        data_dir: pathlib.Path, tmp_path: pathlib.Path) -> None:
    # The report named as the configuration file, in the folder that holds it: the run
    # would read the file, then replace it with its report.
    karlsruhe = data_dir / "karlsruhe_2010_03_09_drive_0023"
    config = tmp_path / "run.yaml"
    config.write_text(
        "input:\n  type: stereo_sequence\n"
        f"  left_images: {karlsruhe}/left/I1_%06d.png\n"
        f"  right_images: {karlsruhe}/right/I2_%06d.png\n"
        "  first_index: 10\n  frame_count: 1\n"
        f"  calibration: {{format: karlsruhe, file: {karlsruhe}/calib.txt}}\n"
        "pipeline:\n  - type: stereo_disparity\n"
        "output:\n  report: run.yaml\n")
    text = config.read_text()
    with pytest.raises(pg.IOError, match="would overwrite the configuration file"):
        pg.run_pipeline(config, output_folder=tmp_path)
    assert config.read_text() == text
    # An output name that is a folder.
    config.write_text(text.replace("report: run.yaml", "report: report.json"))
    (tmp_path / "out" / "report.json").mkdir(parents=True)
    with pytest.raises(pg.IOError, match="names an existing folder"):
        pg.run_pipeline(config, output_folder=tmp_path / "out")


def test_frame_range_outside_the_input_is_an_error(source_dir_module: pathlib.Path,
                                                   tmp_path: pathlib.Path) -> None:
    with pytest.raises(pg.Error, match="200"):
        pg.run_pipeline(source_dir_module / "config" / "karlsruhe.yaml", frames=(200, 201),
                        output_folder=tmp_path)


def test_stage_types_list_the_registry() -> None:
    stages = pg.stage_types()
    assert "multi_plane_segmentation" in stages
    assert "distance_threshold_m" in stages["multi_plane_segmentation"]


def test_stage_parameters_give_the_table() -> None:
    rows = {row["key"]: row for row in pg.stage_parameters("voxel_grid")}
    assert set(rows) == {"leaf_size_m", "min_points_per_voxel"}
    leaf = rows["leaf_size_m"]
    assert leaf["type"] == "float" and leaf["unit"] == "m"
    assert leaf["default"] == pytest.approx(0.05)
    assert leaf["min"] <= leaf["default"] <= leaf["max"]
    assert leaf["min_open"] is False and leaf["max_open"] is False
    dist = {row["key"]: row for row in
            pg.stage_parameters("multi_plane_segmentation")}["distance_threshold_m"]
    assert dist["min"] == 0.0 and dist["min_open"] is True
    assert rows["min_points_per_voxel"]["default"] == 1
    method = {row["key"]: row for row in
              pg.stage_parameters("multi_plane_segmentation")}["method"]
    assert method["default"] in method["choices"] and method["min"] is None
    for stage in pg.stage_types():
        for row in pg.stage_parameters(stage):
            assert row["description"] and row["key"] in pg.stage_types()[stage]
    with pytest.raises(pg.Error, match="voxel_grid"):
        pg.stage_parameters("voxel_grd")


def _stereo_config(data_dir: pathlib.Path, path: pathlib.Path, frames: int) -> pathlib.Path:
    karlsruhe = data_dir / "karlsruhe_2010_03_09_drive_0023"
    path.write_text(
        "input:\n  type: stereo_sequence\n"
        f"  left_images: {karlsruhe}/left/I1_%06d.png\n"
        f"  right_images: {karlsruhe}/right/I2_%06d.png\n"
        f"  first_index: 10\n  frame_count: {frames}\n"
        f"  calibration: {{format: karlsruhe, file: {karlsruhe}/calib.txt}}\n"
        f"  poses: {{format: karlsruhe_insdata, file: {karlsruhe}/insdata.txt,\n"
        "          camera_height_m: 1.57, camera_pitch_rad: 0.09}\n"
        "pipeline:\n  - type: stereo_disparity\n  - type: transform_to_world\n"
        "  - type: accumulate\n"
        "output:\n  report: report.json\n")
    return path


def test_ctrl_c_stops_after_the_frame_and_writes_nothing(
        data_dir: pathlib.Path, tmp_path: pathlib.Path) -> None:
    # SIGINT during the second frame (sent from the progress callback of the first):
    # KeyboardInterrupt once that frame is done, no output written.
    import os
    import signal
    config = _stereo_config(data_dir, tmp_path / "run.yaml", 5)
    done_frames: List[int] = []

    def progress(done: int, total: int, seconds: float) -> None:
        done_frames.append(done)
        if done == 1:
            os.kill(os.getpid(), signal.SIGINT)

    with pytest.raises(KeyboardInterrupt, match="stopped on request after frame"):
        pg.run_pipeline(config, output_folder=tmp_path / "out", progress=progress)
    assert done_frames and max(done_frames) < 5
    assert not (tmp_path / "out" / "report.json").exists()


def test_memory_limit_refuses_a_run_that_cannot_fit(
        data_dir: pathlib.Path, tmp_path: pathlib.Path) -> None:
    config = _stereo_config(data_dir, tmp_path / "run.yaml", 1)
    config.write_text(config.read_text().replace(
        "  - type: transform_to_world\n  - type: accumulate\n",
        "  - type: voxel_grid\n  - type: transform_to_world\n"
        "  - type: multi_plane_segmentation\n    params: {sample: cloud}\n"
        "  - type: planar_cuboid_approximation\n  - type: map_integration\n"))
    with pytest.raises(pg.ConfigError, match="more than the limit of 1 MiB"):
        pg.run_pipeline(config, output_folder=tmp_path / "out", memory_limit="1M")
    with pytest.raises(ValueError, match="memory_limit"):
        pg.run_pipeline(config, output_folder=tmp_path / "out", memory_limit="lots")
    result = pg.run_pipeline(config, output_folder=tmp_path / "out", memory_limit=0)
    assert result.report["frames"] == 1
