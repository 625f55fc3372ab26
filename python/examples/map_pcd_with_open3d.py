# SPDX-License-Identifier: BSD-3-Clause
"""Maps a PCD scan loaded with Open3D: planes, planar cuboids and the explicit space, saved
as a PlanarGrid map.

    PYTHONPATH=build/python python3 python/examples/map_pcd_with_open3d.py \
        ../shared/data/pcl_clouds/office1.pcd office1.pgmap

The scan is taken as seen from the origin by a camera with PCL's axes (x right, y down,
z forward), as PCL's own scans are; the map's world is z-up (x forward, y left)."""

import sys
from typing import Tuple

import numpy as np
import open3d as o3d

import planar_grid as pg


def map_scan(pcd_path: str, resolution_m: float = 0.05
             ) -> Tuple[pg.PlanarSegments, pg.Cuboids, pg.PlanarGridMap]:
    """Returns (planes, cuboids, map) of the scan in pcd_path, cells of resolution_m m."""
    camera = np.asarray(o3d.io.read_point_cloud(pcd_path, remove_nan_points=True).points)
    points = np.column_stack([camera[:, 2], -camera[:, 0], -camera[:, 1]])  # z up
    planes = pg.SACMultiPlaneSegmentation(distance_threshold_m=0.03, min_inliers=2000,
                                          seed=0).segment(points)
    cuboids = pg.PlanarCuboidApproximation(min_cell_size_m=resolution_m,
                                           thickness_m=resolution_m).approximate(
        points, planes, sensor_origin=[0.0, 0.0, 0.0])
    m = pg.PlanarGridMap(resolution_m=resolution_m, thickness_m=resolution_m)
    m.integrate_point_cloud(points, [0.0, 0.0, 0.0])      # free / occupied by ray casting
    m.integrate_surface(cuboids, planes.model_coefficients, np.empty((0, 3)), np.empty(0))
    return planes, cuboids, m


if __name__ == "__main__":
    if len(sys.argv) != 3:
        sys.exit("usage: map_pcd_with_open3d.py SCAN.pcd OUT.pgmap")
    planes, cuboids, m = map_scan(sys.argv[1])
    m.save(sys.argv[2])
    print(f"{len(planes.model_coefficients)} planes, {len(cuboids.centres)} cuboids "
          f"({int(cuboids.is_planar.sum())} planar), {m.memory['total_bytes']} bytes: "
          f"{sys.argv[2]}")
