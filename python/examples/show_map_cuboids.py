#!/usr/bin/env python3
# SPDX-License-Identifier: BSD-3-Clause
"""Shows the cuboids of a planar grid map (.pgmap) with Open3D.

The map's oriented cuboids become one triangle mesh (12 triangles per box) coloured by
occupancy probability (blue 0, green 0.5, red 1, as planar_grid_viewer colours them) or
by plane, with their edges as a line set; optionally the occupied voxels that no cuboid
covers as a point cloud.

    python3 python/examples/show_map_cuboids.py output/karlsruhe/map.pgmap
    python3 python/examples/show_map_cuboids.py MAP.pgmap --colour-by plane
    python3 python/examples/show_map_cuboids.py MAP.pgmap --no-window            # headless
    xvfb-run -a python3 python/examples/show_map_cuboids.py MAP.pgmap --no-window \\
        --screenshot cuboids.png                                                  # a picture

Needs the planar_grid module (build folder's python/ on PYTHONPATH, see docs/PYTHON.md),
numpy and Open3D (Debian: python3-open3d).
"""

import argparse
import sys
from typing import Any, List, Optional, Sequence, Tuple

import numpy as np
import numpy.typing as npt

import planar_grid as pg

# The corners of planar_grid.Cuboids.corners, in a box frame (horizontal, vertical,
# normal) of unit extents: the face (+normal side) (-,-), (+,-), (+,+), (-,+), then the
# back. Each side as a quad wound counter-clockwise seen from outside.
BOX_QUADS = np.array([[0, 1, 2, 3],   # face (+normal)
                      [4, 7, 6, 5],   # back
                      [0, 4, 5, 1],   # -vertical
                      [3, 2, 6, 7],   # +vertical
                      [0, 3, 7, 4],   # -horizontal
                      [1, 5, 6, 2]])  # +horizontal
BOX_TRIANGLES = np.concatenate([BOX_QUADS[:, [0, 1, 2]], BOX_QUADS[:, [0, 2, 3]]])
BOX_EDGES = np.array([[0, 1], [1, 2], [2, 3], [3, 0], [4, 5], [5, 6], [6, 7], [7, 4],
                      [0, 4], [1, 5], [2, 6], [3, 7]])


def occupancy_colours(probabilities: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """RGB in [0, 1] per probability: blue at 0, green at 0.5, red at 1, linear between."""
    p = np.clip(np.asarray(probabilities, dtype=float), 0.0, 1.0)[:, None]
    blue, green, red = np.array([0.0, 0.0, 1.0]), np.array([0.0, 0.8, 0.0]), np.array([1.0, 0.0, 0.0])
    low = blue + (green - blue) * (p / 0.5)
    high = green + (red - green) * ((p - 0.5) / 0.5)
    return np.where(p < 0.5, low, high)


def plane_colours(plane_ids: npt.ArrayLike) -> npt.NDArray[np.float64]:
    """RGB in [0, 1] per plane id from a fixed palette; grey for non-planar (-1)."""
    palette = np.array([[0.90, 0.10, 0.10], [0.12, 0.47, 0.71], [0.17, 0.63, 0.17],
                        [1.00, 0.50, 0.05], [0.58, 0.40, 0.74], [0.55, 0.34, 0.29],
                        [0.89, 0.47, 0.76], [0.74, 0.74, 0.13], [0.09, 0.75, 0.81]])
    ids = np.asarray(plane_ids)
    colours: npt.NDArray[np.float64] = palette[np.mod(ids, len(palette))]
    colours[ids < 0] = 0.6
    return colours


def cuboid_mesh_arrays(cuboids: pg.Cuboids, colours: npt.NDArray[np.float64]
                       ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int32],
                                  npt.NDArray[np.float64]]:
    """The cuboids as one triangle mesh.

    Parameters
    ----------
    cuboids : planar_grid.Cuboids
        M boxes.
    colours : numpy.ndarray, shape (M, 3)
        RGB in [0, 1] per box.

    Returns
    -------
    vertices : numpy.ndarray, shape (8 M, 3)
        The corners, meters.
    triangles : numpy.ndarray, shape (12 M, 3), int32
        Vertex indices, counter-clockwise seen from outside each box.
    vertex_colours : numpy.ndarray, shape (8 M, 3)
    """
    m = len(cuboids)
    vertices = cuboids.corners.reshape(-1, 3)
    triangles = (BOX_TRIANGLES[None, :, :] + 8 * np.arange(m)[:, None, None]).reshape(-1, 3)
    return vertices, triangles.astype(np.int32), np.repeat(colours, 8, axis=0)


def cuboid_line_arrays(cuboids: pg.Cuboids
                       ) -> Tuple[npt.NDArray[np.float64], npt.NDArray[np.int32]]:
    """The cuboids' 12 edges each: points (8 M, 3) in meters and lines (12 M, 2) int32."""
    m = len(cuboids)
    lines = (BOX_EDGES[None, :, :] + 8 * np.arange(m)[:, None, None]).reshape(-1, 2)
    return cuboids.corners.reshape(-1, 3), lines.astype(np.int32)


def open3d_geometries(grid_map: pg.PlanarGridMap, colour_by: str = "occupancy",
                      occupied_voxels: bool = False) -> List[Any]:
    """Open3D geometries of a map: the cuboid mesh, its edges and, optionally, the
    occupied voxel centres (grey points)."""
    import open3d as o3d

    cuboids = grid_map.cuboids
    colours = (occupancy_colours(cuboids.probabilities) if colour_by == "occupancy"
               else plane_colours(cuboids.plane_ids))
    vertices, triangles, vertex_colours = cuboid_mesh_arrays(cuboids, colours)
    mesh = o3d.geometry.TriangleMesh(o3d.utility.Vector3dVector(vertices),
                                     o3d.utility.Vector3iVector(triangles))
    mesh.vertex_colors = o3d.utility.Vector3dVector(vertex_colours)
    mesh.compute_triangle_normals()
    mesh.compute_vertex_normals()
    points, lines = cuboid_line_arrays(cuboids)
    edges = o3d.geometry.LineSet(o3d.utility.Vector3dVector(points),
                                 o3d.utility.Vector2iVector(lines))
    edges.paint_uniform_color([0.15, 0.15, 0.15])
    geometries = [mesh, edges]
    if occupied_voxels:
        centres = grid_map.voxel_centres(pg.SpaceState.OCCUPIED)
        if len(centres):
            cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(centres))
            cloud.paint_uniform_color([0.5, 0.5, 0.5])
            geometries.append(cloud)
    return geometries


def save_screenshot(geometries: Sequence[Any], path: str, width: int = 1280,
                    height: int = 800) -> None:
    """Renders the geometries in a hidden Open3D window (needs an X display, e.g.
    xvfb-run) and writes a PNG."""
    import open3d as o3d

    vis = o3d.visualization.Visualizer()
    if not vis.create_window(visible=False, width=width, height=height):
        raise RuntimeError("Open3D could not create a window (no display? run under "
                           "xvfb-run -a)")
    for geometry in geometries:
        vis.add_geometry(geometry)
    vis.get_render_option().background_color = np.array([1.0, 1.0, 1.0])
    vis.get_render_option().mesh_show_back_face = True
    control = vis.get_view_control()
    control.set_front([-0.5, -0.6, 0.62])  # from above and behind, z up
    control.set_up([0.0, 0.0, 1.0])
    control.set_zoom(0.45)
    vis.poll_events()
    vis.update_renderer()
    vis.capture_screen_image(str(path), do_render=True)
    vis.destroy_window()


def main(argv: Optional[Sequence[str]] = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("map", help="the map file (.pgmap)")
    parser.add_argument("--colour-by", choices=("occupancy", "plane"), default="occupancy",
                        help="colour of the cuboids (default: occupancy)")
    parser.add_argument("--occupied-voxels", action="store_true",
                        help="also show the occupied voxels (grey points)")
    parser.add_argument("--no-window", action="store_true",
                        help="build the geometry and print a summary, open no window")
    parser.add_argument("--screenshot", metavar="PNG",
                        help="render to this PNG (hidden window; needs a display or xvfb-run)")
    args = parser.parse_args(argv)

    try:
        grid_map = pg.PlanarGridMap.load(args.map)
    except pg.IOError as error:
        print(f"show_map_cuboids: {error}", file=sys.stderr)
        return 1
    try:
        geometries = open3d_geometries(grid_map, args.colour_by, args.occupied_voxels)
    except ImportError:
        print("show_map_cuboids: Open3D is not installed (Debian: python3-open3d)",
              file=sys.stderr)
        return 1
    cuboids = grid_map.cuboids
    print(f"{args.map}: {len(cuboids)} cuboids ({int(cuboids.is_planar.sum())} planar), "
          f"{len(grid_map.planes)} planes, resolution {grid_map.resolution_m} m, "
          f"{grid_map.memory['total_bytes']} bytes; mesh of "
          f"{len(geometries[0].triangles)} triangles")
    if args.screenshot:
        save_screenshot(geometries, args.screenshot)
        print(f"wrote {args.screenshot}")
    if not args.no_window:
        import open3d as o3d
        o3d.visualization.draw_geometries(geometries, window_name=f"PlanarGrid: {args.map}",
                                          mesh_show_back_face=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
