# SPDX-License-Identifier: BSD-3-Clause
"""Maps the Karlsruhe main job frame by frame with planar_grid.Mapper, as a live camera
would feed it, and prints each frame's statistics (config/karlsruhe_live.yaml: dense
stereo on keyframes, the features and the pose on every frame).

    PYTHONPATH=build/python python3 python/examples/map_live.py config/karlsruhe_live.yaml \
        5 karlsruhe_live.pgmap

InputFrames reads the configuration's stereo pairs, calibration and INS poses in place of
the camera; the map equals planar_grid_pipeline's over the same frames."""

import sys
from typing import Any, Dict, List

import planar_grid as pg


def map_frames(config: str, frame_count: int, map_path: str) -> List[Dict[str, Any]]:
    """Integrates the first frame_count frames of config's input, saves the map to
    map_path and returns each frame's statistics (dicts)."""
    frames = pg.InputFrames(config)
    mapper = pg.Mapper(config)
    stats: List[Dict[str, Any]] = []
    for i in range(frame_count):
        f = frames[i]
        stats.append(mapper.integrate_stereo(f["left"], f["right"], f["calibration"],
                                             f["world_T_camera"]))
    mapper.save(map_path)
    return stats


if __name__ == "__main__":
    if len(sys.argv) != 4:
        sys.exit(f"usage: {sys.argv[0]} config.yaml frame_count map.pgmap")
    for s in map_frames(sys.argv[1], int(sys.argv[2]), sys.argv[3]):
        stereo = [stage for stage in s["stages"] if stage["type"] == "stereo_disparity"]
        dense = not stereo or stereo[0].get("dense_frames", 1.0) > 0.0
        print(f"frame {s['sequence_number']}{' (dense)' if dense else ''}: "
              f"{s['total_ms']:.0f} ms, {s['cuboids']} cells, map {s['map_cells']} "
              f"cells, readers locked out {s['exclusive_ms']:.1f} ms")
