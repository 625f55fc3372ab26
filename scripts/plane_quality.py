# SPDX-License-Identifier: BSD-3-Clause
"""Whether a map's planes look like a scene's surfaces: their tilt, size and stacking.

    PYTHONPATH=build/python /usr/bin/python3 scripts/plane_quality.py MAP.pgmap [--json]

Prints, over the map's cuboids: the count, the planar ones and the planes; the share of
the cuboids that are non-planar boxes and how many of those are a single minimum cell;
over the planar face area (m^2): the share within 10 degrees of vertical (walls), of
horizontal (floors, roads), and tilted 20-70 degrees from both (slabs across a facade
or through clutter: a street or a room has next to none); the median planar face area;
the stacked share (scripts/stacked_planes.py's rule, default arguments). The minimum
cell is the map's resolution."""
import argparse
import json
import sys

import numpy as np

import planar_grid as pg
from planar_grid.analysis import stacked_planar_cuboids


def plane_quality(m):
    """The figures above as a dict (areas in m^2, shares in [0, 1])."""
    c = m.cuboids
    is_planar = np.asarray(c.is_planar) & (np.asarray(c.plane_ids) >= 0)
    extents = np.asarray(c.extents_m)
    count = len(is_planar)
    cell = m.resolution_m
    boxes = ~is_planar
    single = boxes & np.all(extents <= cell * 1.001, axis=1)
    area, stacked, _, ids = stacked_planar_cuboids(m)
    normals = np.asarray(c.normals)[is_planar]
    up = np.abs(normals[:, 2]) if len(normals) else np.zeros(0)
    tilt_deg = np.degrees(np.arccos(np.clip(up, 0.0, 1.0)))  # 0 horizontal, 90 vertical
    total = float(area.sum())

    def share(mask):
        return float(area[mask].sum()) / total if total > 0 else float("nan")

    return {
        "cuboids": int(count),
        "planar_cuboids": int(is_planar.sum()),
        "planes": int(len(np.unique(ids))),
        "non_planar_share": float(boxes.sum()) / count if count else float("nan"),
        "single_cell_boxes": int(single.sum()),
        "planar_area_m2": total,
        "vertical_share": share(tilt_deg >= 80.0),
        "horizontal_share": share(tilt_deg <= 10.0),
        "tilted_share": share((tilt_deg >= 20.0) & (tilt_deg <= 70.0)),
        "median_face_m2": float(np.median(area)) if len(area) else float("nan"),
        "stacked_share": share(stacked),
    }


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", help="a .pgmap file")
    parser.add_argument("--json", action="store_true", help="print the figures as JSON")
    args = parser.parse_args()
    try:
        m = pg.PlanarGridMap.load(args.map)
    except (OSError, pg.Error) as e:
        sys.exit(f"plane_quality.py: {e}")
    q = plane_quality(m)
    if args.json:
        print(json.dumps(q, indent=1))
        return
    print(f"{q['cuboids']} cuboids, {q['planar_cuboids']} planar on {q['planes']} planes; "
          f"non-planar {100 * q['non_planar_share']:.1f} %, "
          f"{q['single_cell_boxes']} single-cell boxes")
    print(f"planar area {q['planar_area_m2']:.1f} m^2: vertical "
          f"{100 * q['vertical_share']:.1f} %, horizontal {100 * q['horizontal_share']:.1f} %, "
          f"tilted 20-70 deg {100 * q['tilted_share']:.1f} %, stacked "
          f"{100 * q['stacked_share']:.1f} %; median face {q['median_face_m2']:.3f} m^2")


if __name__ == "__main__":
    main()
