# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid.Mapper on real Karlsruhe frames: the same map file as run_pipeline(), a
reader thread that sees whole frames only, and bad input."""

import pathlib
import threading
from typing import Callable, Dict, List

import numpy as np
import pytest

import planar_grid as pg

FRAMES = 3


@pytest.fixture
def main_job(source_dir: pathlib.Path, data_dir: pathlib.Path) -> pathlib.Path:
    return source_dir / "config" / "karlsruhe.yaml"


def test_mapper_writes_the_pipelines_map_file(main_job: pathlib.Path,
                                              tmp_path: pathlib.Path) -> None:
    # The user's code: the main job's frames fed one by one.
    frames = pg.InputFrames(main_job)
    mapper = pg.Mapper(main_job)
    for i in range(FRAMES):
        f = frames[i]
        stats = mapper.integrate_stereo(f["left"], f["right"], f["calibration"],
                                        f["world_T_camera"])
        assert stats["sequence_number"] == i and stats["cuboids"] > 0
    mapper.save(tmp_path / "map.pgmap")

    result = pg.run_pipeline(main_job, frames=(0, FRAMES), write_outputs=False)
    result.map.save(tmp_path / "run.pgmap")
    assert (tmp_path / "map.pgmap").read_bytes() == (tmp_path / "run.pgmap").read_bytes()
    np.testing.assert_array_equal(mapper.trajectory, result.trajectory)
    assert [s["type"] for s in stats["stages"]] == [s["type"] for s in
                                                      result.report["stages"]]
    assert mapper.map == result.map


def test_a_reader_thread_sees_whole_frames(main_job: pathlib.Path) -> None:
    frames = pg.InputFrames(main_job)
    mapper = pg.Mapper(main_job)
    after_frames = [mapper.map.__getstate__()]
    seen: List[bytes] = []
    done = threading.Event()

    def read() -> None:
        while True:
            with mapper.read_map() as m:
                state = m.__getstate__()
            if not seen or seen[-1] != state:
                seen.append(state)
            if done.is_set():
                break

    reader = threading.Thread(target=read)
    reader.start()
    for i in range(2):
        f = frames[i]
        mapper.integrate_stereo(f["left"], f["right"], f["calibration"], f["world_T_camera"])
        after_frames.append(mapper.map.__getstate__())
    done.set()
    reader.join()
    assert seen and all(state in after_frames for state in seen)
    assert seen[-1] == after_frames[-1]


def test_a_mappers_map_refuses_changes_from_python(main_job: pathlib.Path,
                                                   tmp_path: pathlib.Path) -> None:
    # Two reader threads changing the Mapper's map under the shared lock would corrupt
    # it: every changing method refuses, from mapper.map and from read_map() alike,
    # and the map is unchanged; a copy of it changes freely.
    frames = pg.InputFrames(main_job)
    mapper = pg.Mapper(main_job)
    f = frames[0]
    mapper.integrate_stereo(f["left"], f["right"], f["calibration"], f["world_T_camera"])
    before = mapper.map.__getstate__()
    point = np.array([[5.0, 0.0, 1.0]])
    changes: Dict[str, Callable[[pg.PlanarGridMap], None]] = {
        "set_state": lambda m: m.set_state(point, "occupied"),
        "integrate_point_cloud": lambda m: m.integrate_point_cloud(point, np.zeros(3)),
        "integrate_depth_image": lambda m: m.integrate_depth_image(
            np.full((4, 4), 2.0), 2.0, 2.0, 2.0, 2.0, np.eye(4)),
        "integrate_surface": lambda m: m.integrate_surface(
            m.cuboids, np.zeros((0, 4)), np.zeros((0, 3)), np.zeros(0)),
        "merge": lambda m: m.merge(m, np.eye(4)),
        "note_observation_order": lambda m: m.note_observation_order(7.0),
    }
    for name, change in changes.items():
        with pytest.raises(pg.Error, match=f"PlanarGridMap.{name}: this map is a Mapper's"):
            change(mapper.map)
        with mapper.read_map() as m:
            with pytest.raises(pg.Error, match=f"PlanarGridMap.{name}"):
                change(m)
    assert mapper.map.__getstate__() == before

    mapper.save(tmp_path / "map.pgmap")
    copy = pg.PlanarGridMap.load(tmp_path / "map.pgmap")
    copy.set_state(point, "occupied")
    assert np.asarray(copy.get_state(point))[0] == pg.SpaceState.OCCUPIED
    # the Mapper still integrates
    f = frames[1]
    mapper.integrate_stereo(f["left"], f["right"], f["calibration"], f["world_T_camera"])
    assert mapper.map.__getstate__() != before


def test_a_mapper_takes_the_configuration_as_a_dict(main_job: pathlib.Path,
                                                    tmp_path: pathlib.Path,
                                                    monkeypatch: pytest.MonkeyPatch) -> None:
    # The file's content as yaml.safe_load gives it maps like the file; its relative
    # paths are the working folder's; a bad value names the dict.
    yaml = pytest.importorskip("yaml")
    with open(main_job, encoding="utf-8") as stream:
        config = yaml.safe_load(stream)
    monkeypatch.chdir(main_job.parent)
    frames = pg.InputFrames(config)
    assert len(frames) == len(pg.InputFrames(main_job))
    from_dict, from_file = pg.Mapper(config), pg.Mapper(main_job)
    for i in range(2):
        f = frames[i]
        for mapper in (from_dict, from_file):
            mapper.integrate_stereo(f["left"], f["right"], f["calibration"],
                                    f["world_T_camera"])
    from_dict.save(tmp_path / "dict.pgmap")
    from_file.save(tmp_path / "file.pgmap")
    assert (tmp_path / "dict.pgmap").read_bytes() == (tmp_path / "file.pgmap").read_bytes()

    stage = next(s for s in config["pipeline"] if s["type"] == "map_integration")
    stage["params"]["resolution_m"] = -1.0
    with pytest.raises(pg.ConfigError, match=r"<config dict>:\d+:\d+: .*resolution_m"):
        pg.Mapper(config)
    stage["params"]["resolution_m"] = np.float32(0.1)
    with pytest.raises(TypeError):
        pg.Mapper(config)


def test_a_mapper_takes_the_stages_alone(main_job: pathlib.Path,
                                         tmp_path: pathlib.Path) -> None:
    # The file's stage list and its cell size, with no input section, maps like the
    # file; the list alone keeps each stage's own cell keys (a coarser voxel grid, so
    # another map); keys left out take their defaults; bad stages name "<stages>".
    yaml = pytest.importorskip("yaml")
    with open(main_job, encoding="utf-8") as stream:
        document = yaml.safe_load(stream)
    stages = document["pipeline"]
    frames = pg.InputFrames(main_job)
    mappers = [pg.Mapper({"cell_size_m": document["cell_size_m"], "pipeline": stages}),
               pg.Mapper(main_job), pg.Mapper(stages)]
    assert repr(mappers[2]) == "<planar_grid.Mapper: <stages>, 0 frames>"
    for i in range(2):
        f = frames[i]
        for mapper in mappers:
            mapper.integrate_stereo(f["left"], f["right"], f["calibration"],
                                    f["world_T_camera"])
    for k, mapper in enumerate(mappers):
        mapper.save(tmp_path / f"{k}.pgmap")
    expected = (tmp_path / "1.pgmap").read_bytes()
    assert (tmp_path / "0.pgmap").read_bytes() == expected
    assert (tmp_path / "2.pgmap").read_bytes() != expected

    # A point-cloud pipeline: no stage reads stereo images.
    clouds = pg.Mapper([{"type": "voxel_grid", "params": {"leaf_size_m": 0.05}},
                        {"type": "transform_to_world"},
                        {"type": "multi_plane_segmentation"},
                        {"type": "planar_cuboid_approximation"},
                        {"type": "map_integration"}])
    with pytest.raises(pg.Error, match="takes point clouds"):
        clouds.integrate_stereo(frames[0]["left"], frames[0]["right"],
                                frames[0]["calibration"], np.eye(4))
    with pytest.raises(pg.ConfigError, match=r"<stages>:\d+:\d+: .*'map_integration' needs"):
        pg.Mapper([{"type": "map_integration"}])
    with pytest.raises(pg.ConfigError, match=r"<stages>:\d+:\d+: .*'output'"):
        pg.Mapper({"pipeline": stages, "output": {}})


def test_bad_input_raises(main_job: pathlib.Path) -> None:
    frames = pg.InputFrames(main_job)
    f = frames[0]
    mapper = pg.Mapper(main_job)
    with pytest.raises(pg.Error, match="principal point .* lies outside the 1344x100 px"):
        mapper.integrate_stereo(f["left"][:100], f["right"][:100], f["calibration"],
                                f["world_T_camera"])
    with pytest.raises(pg.Error, match="no visual_odometry stage"):
        mapper.integrate_stereo(f["left"], f["right"], f["calibration"])
    with pytest.raises(ValueError, match="unknown key 'f'"):
        mapper.integrate_stereo(f["left"], f["right"], {"f": 1.0}, f["world_T_camera"])
    with pytest.raises(ValueError, match=r"\(H, W\) uint8"):
        mapper.integrate_stereo(np.zeros((4, 4, 3)), f["right"], f["calibration"])
    with pytest.raises(pg.Error, match="takes stereo pairs"):
        mapper.integrate_cloud(np.ones((10, 3)), np.eye(4))
    # A float image is not cast (one in [0, 1] would become black).
    with pytest.raises(ValueError, match="uint8 array .* got dtype float32"):
        mapper.integrate_stereo(f["left"].astype(np.float32) / 255, f["right"],
                                f["calibration"], f["world_T_camera"])
    # A broadcast image of a huge width is refused before it is copied.
    wide = np.broadcast_to(np.zeros(1, np.uint8), (372, 2**31 + 5))
    with pytest.raises(ValueError, match="left is 372 x 2147483653 px"):
        mapper.integrate_stereo(wide, wide, f["calibration"], f["world_T_camera"])
    with pytest.raises(ValueError, match="1 to 65536 px"):
        mapper.integrate_stereo(np.zeros((0, 1344), np.uint8), f["right"],
                                f["calibration"], f["world_T_camera"])
    # The first pair passed the wrong way round.
    with pytest.raises(pg.Error, match="the left and right images look swapped"):
        mapper.integrate_stereo(f["right"], f["left"], f["calibration"],
                                f["world_T_camera"])
    assert mapper.frame_count == 0


def test_the_example_maps_a_frame(main_job: pathlib.Path, source_dir: pathlib.Path,
                                  tmp_path: pathlib.Path) -> None:
    import subprocess
    import sys
    example = source_dir / "python" / "examples" / "map_live.py"
    out = subprocess.run([sys.executable, str(example), str(main_job), "1",
                          str(tmp_path / "live.pgmap")],
                         check=True, capture_output=True, text=True).stdout
    assert out.startswith("frame 0 (dense): ") and (tmp_path / "live.pgmap").stat().st_size > 1000


def test_a_depth_image_is_mapped_through_its_camera(data_dir: pathlib.Path,
                                                    tmp_path: pathlib.Path) -> None:
    # A wall 2 m ahead filling a 640 x 480 depth image (f = 525 px), in millimeters, seen
    # from the origin looking along z: occupied on the wall, free in front, unknown behind.
    config = tmp_path / "depth.yaml"
    config.write_text(f"""input:
  type: pcd_files
  files: {data_dir / "pcl_clouds" / "office1.pcd"}
pipeline:
  - type: voxel_grid
    params: {{leaf_size_m: 0.05}}
  - type: transform_to_world
  - type: multi_plane_segmentation
    params: {{distance_threshold_m: 0.03, max_planes: 4, min_inliers: 300}}
  - type: planar_cuboid_approximation
    params: {{min_cell_size_m: 0.1, thickness_m: 0.1}}
  - type: map_integration
    params: {{prior: unknown}}
""")
    mapper = pg.Mapper(config)
    depth = np.full((480, 640), 2000, dtype=np.uint16)
    stats = mapper.integrate_depth(depth, 525.0, 525.0, 320.0, 240.0, np.eye(4))
    assert stats["cuboids"] > 0
    states = np.asarray(mapper.map.get_state(np.array([[0.0, 0.3, 2.0], [0.0, 0.0, 1.0],
                                                       [0.0, 0.0, 3.0]])))
    assert list(states) == [int(pg.SpaceState.OCCUPIED), int(pg.SpaceState.FREE),
                            int(pg.SpaceState.UNKNOWN)]
    # The same wall in meters (float) gives the same map.
    again = pg.Mapper(config)
    again.integrate_depth(depth.astype(np.float32) / 1000.0, 525.0, 525.0, 320.0, 240.0,
                          np.eye(4))
    assert again.map.__getstate__() == mapper.map.__getstate__()
    with pytest.raises(ValueError, match=r"\(H, W\) array"):
        mapper.integrate_depth(np.zeros((4, 4, 3)), 525.0, 525.0, 2.0, 2.0, np.eye(4))
    with pytest.raises(pg.Error, match="focal lengths must be positive"):
        mapper.integrate_depth(depth, 0.0, 525.0, 320.0, 240.0, np.eye(4))
