# SPDX-License-Identifier: BSD-3-Clause
"""Whether the plane precision measures the map or its reference: the precision of a
map's planar cells beside that of copies of them turned by known angles.

    PYTHONPATH=build/python /usr/bin/python3 scripts/plane_precision_control.py \
        MAP.pgmap TRUTH.pcd [--up 0,0,1] [--planes N] [--region BOX]
        [--small-planes K]

MAP.pgmap and TRUTH.pcd are what `planar_grid_eval --save-maps` writes
(pg_DATASET_Rm.pgmap, truth_DATASET.pcd). The truth normal at each occupied planar cell
(probability >= 0.5) follows the evaluator's rule (docs/EVALUATION.md, "Plane
precision"): the PCA normal of the truth points within max(2 r, 0.4 m) of the cell's
centre, the radius doubling up to 1.6 m while they are no surface (smallest to middle
eigenvalue >= 0.5). A cell is precise when that normal lies within 20 degrees of the
cell's. Unlike the evaluator, which samples each face at step r, each cell counts once,
at its centre, weighted by its face area (m^2).

The same truth normals are then compared with the cells' normals turned by a known
angle: leaned by DEG (each normal turned towards --up, the world's up axis, by DEG
degrees: a wall's top away from the sensor; horizontal cells turned about the world's
first horizontal axis instead) and yawed by DEG (turned about --up). A measure of the
map must score the map above every turned copy, lower the more it is turned; where a
leaned copy scores higher, the reference's local normals lean against the cells by
about that angle, and the precision measures the reference as much as the map.

Prints one line per copy: the angle and its plane precision. With --planes N, then
the N planes of the largest face area: their cells, face area (m^2), unit normal, tilt
from the up axis (deg), extent along the up axis (m), precise share and the median
angle between the cells' and the truth normals (deg). With --region XMIN,XMAX,YMIN,YMAX,
ZMIN,ZMAX (m, the map's world), then the face area and precise share of the cells whose
centres lie inside that box and of the rest, each for all planar cells and for the
level ones (within 10 degrees of level). With --small-planes K, then the planes of at most
K occupied planar cuboids against the rest: their count, face area and precise share."""
import argparse
import struct
import sys
from typing import Dict, List, Optional, Tuple

import numpy as np

import planar_grid as pg

MIN_RADIUS_M = 0.4
MAX_RADIUS_M = 1.6
MAX_EIGENVALUE_RATIO = 0.5
MIN_POINTS = 5
MAX_ANGLE_DEG = 20.0
BUCKET_M = 0.8


def lzf_decompress(data: bytes, size: int) -> bytes:
    """LZF (liblzf's format, PCL's binary_compressed) of \a data into \a size bytes."""
    out = bytearray(size)
    ip = op = 0
    while ip < len(data):
        ctrl = data[ip]
        ip += 1
        if ctrl < 32:  # a literal run of ctrl + 1 bytes
            out[op:op + ctrl + 1] = data[ip:ip + ctrl + 1]
            ip += ctrl + 1
            op += ctrl + 1
            continue
        length = ctrl >> 5
        ref = op - ((ctrl & 0x1F) << 8) - 1
        if length == 7:
            length += data[ip]
            ip += 1
        ref -= data[ip]
        ip += 1
        for _ in range(length + 2):  # a back reference may overlap what it writes
            out[op] = out[ref]
            op += 1
            ref += 1
    if op != size:
        raise ValueError(f"LZF data decompress to {op} bytes, the header says {size}")
    return bytes(out)


def read_pcd_xyz(path: str) -> np.ndarray:
    """The x, y, z of a PCD file of three float fields (binary or binary_compressed),
    N x 3, meters."""
    with open(path, "rb") as f:
        header: Dict[str, List[str]] = {}
        while True:
            line = f.readline()
            if not line:
                raise ValueError(f"{path}: no DATA line in the header")
            words = line.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            header[words[0]] = words[1:]
            if words[0] == "DATA":
                break
        if header.get("FIELDS") != ["x", "y", "z"] or header.get("TYPE") != ["F"] * 3 \
                or header.get("SIZE") != ["4"] * 3:
            raise ValueError(f"{path}: expected the float fields x y z, got "
                             f"{header.get('FIELDS')}")
        count = int(header["POINTS"][0])
        kind = header["DATA"][0]
        if kind == "binary":
            raw = f.read(12 * count)
            return np.frombuffer(raw, dtype="<f4").reshape(count, 3).astype(np.float64)
        if kind == "binary_compressed":
            compressed, size = struct.unpack("<II", f.read(8))
            raw = lzf_decompress(f.read(compressed), size)
            # binary_compressed stores the fields one after the other.
            return np.frombuffer(raw, dtype="<f4").reshape(3, count).T.astype(np.float64)
        raise ValueError(f"{path}: DATA {kind} is not read here (binary or "
                         f"binary_compressed)")


class Buckets:
    """The truth points sorted into cubic buckets of BUCKET_M for radius searches."""

    def __init__(self, points: np.ndarray) -> None:
        keys = np.floor(points / BUCKET_M).astype(np.int64)
        order = np.lexsort(keys.T[::-1])
        self.points = points[order]
        unique, start, counts = np.unique(keys[order], axis=0, return_index=True,
                                          return_counts=True)
        self.ranges = {tuple(k): (s, s + n) for k, s, n in zip(unique, start, counts)}

    def within(self, centre: np.ndarray, radius_m: float) -> np.ndarray:
        key = np.floor(centre / BUCKET_M).astype(np.int64)
        reach = int(np.ceil(radius_m / BUCKET_M))
        parts = []
        for dx in range(-reach, reach + 1):
            for dy in range(-reach, reach + 1):
                for dz in range(-reach, reach + 1):
                    found = self.ranges.get((key[0] + dx, key[1] + dy, key[2] + dz))
                    if found:
                        parts.append(self.points[found[0]:found[1]])
        if not parts:
            return np.zeros((0, 3))
        near = np.concatenate(parts)
        return near[np.sum((near - centre) ** 2, axis=1) <= radius_m * radius_m]


def truth_normal(buckets: Buckets, centre: np.ndarray, first_radius_m: float
                 ) -> Optional[np.ndarray]:
    """The evaluator's truth normal at \a centre, or None (no truth, or no surface)."""
    radius = first_radius_m
    while True:
        near = buckets.within(centre, radius)
        if len(near) >= MIN_POINTS:
            values, vectors = np.linalg.eigh(np.cov((near - near.mean(axis=0)).T))
            if values[1] > 1e-6 * values[2] and values[0] < MAX_EIGENVALUE_RATIO * values[1]:
                return vectors[:, 0]
        elif radius == first_radius_m:
            return None
        if radius >= max(MAX_RADIUS_M, first_radius_m):
            return None
        radius = min(2.0 * radius, max(MAX_RADIUS_M, first_radius_m))


def turned(normals: np.ndarray, up: np.ndarray, lean_deg: float, yaw_deg: float
           ) -> np.ndarray:
    """\a normals leaned towards \a up by lean_deg, then yawed about \a up by yaw_deg."""
    out = normals.copy()
    if lean_deg:
        side = np.cross(up, [1.0, 0.0, 0.0] if abs(up[0]) < 0.9 else [0.0, 1.0, 0.0])
        horizontal = np.cross(side, up)
        for k, n in enumerate(normals):
            towards = up - (up @ n) * n
            if np.linalg.norm(towards) < np.sin(np.radians(10.0)):
                towards = horizontal - (horizontal @ n) * n
            towards /= np.linalg.norm(towards)
            t = np.radians(lean_deg)
            out[k] = np.cos(t) * n + np.sin(t) * towards
    if yaw_deg:
        t = np.radians(yaw_deg)
        # Rodrigues' rotation about the unit axis up.
        out = (out * np.cos(t) + np.cross(up, out) * np.sin(t)
               + np.outer(out @ up, up) * (1.0 - np.cos(t)))
    return out


def precision(truth: List[Optional[np.ndarray]], normals: np.ndarray,
              areas: np.ndarray) -> float:
    return precise_share(areas, precise_cells(truth, normals), np.ones(len(areas), bool))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("map", help="a .pgmap file (planar_grid_eval --save-maps)")
    parser.add_argument("truth", help="its truth or reference points, a .pcd file")
    parser.add_argument("--up", default="0,0,1",
                        help="the world's up axis, x,y,z (KITTI's poses: 0,-1,0)")
    parser.add_argument("--planes", type=int, default=0,
                        help="also list the N planes of the largest face area")
    parser.add_argument("--region", default="",
                        help="a box XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX (m): the precision "
                             "inside it and outside")
    parser.add_argument("--small-planes", type=int, default=0,
                        help="also split the precision between the planes of at most K "
                             "occupied planar cuboids and the rest")
    args = parser.parse_args()
    try:
        region = None
        if args.region:
            region = np.array([float(v) for v in args.region.split(",")])
        if region is not None and (region.shape != (6,)
                                   or np.any(region[0::2] > region[1::2])):
            raise ValueError(f"--region must be XMIN,XMAX,YMIN,YMAX,ZMIN,ZMAX with each "
                             f"minimum at most its maximum, got {args.region}")
        up = np.array([float(v) for v in args.up.split(",")])
        if up.shape != (3,) or not np.linalg.norm(up) > 0:
            raise ValueError(f"--up must be three numbers not all 0, got {args.up}")
        up /= np.linalg.norm(up)
        m = pg.PlanarGridMap.load(args.map)
        points = read_pcd_xyz(args.truth)
    except (OSError, ValueError, pg.Error) as e:
        sys.exit(f"plane_precision_control.py: {e}")
    c = m.cuboids
    keep = (np.asarray(c.is_planar) & (np.asarray(c.plane_ids) >= 0)
            & (np.asarray(c.probabilities) >= 0.5))
    ids = np.asarray(c.plane_ids)[keep]
    centres = np.asarray(c.centres)[keep]
    normals = np.asarray(c.normals)[keep]
    extents = np.sort(np.asarray(c.extents_m)[keep], axis=1)
    areas = extents[:, 1] * extents[:, 2]
    buckets = Buckets(points)
    first_radius = max(MIN_RADIUS_M, 2.0 * m.resolution_m)
    truth = [truth_normal(buckets, x, first_radius) for x in centres]
    print(f"{len(areas)} occupied planar cells, {areas.sum():.1f} m^2 of faces; "
          f"{sum(t is not None for t in truth)} with a truth surface")
    copies: List[Tuple[str, float, float]] = [("the map", 0.0, 0.0)]
    copies += [(f"leaned {d:+.0f} deg", d, 0.0) for d in (-30, -20, -10, 10, 20, 30)]
    copies += [(f"yawed {d:.0f} deg", 0.0, d) for d in (10, 20, 45)]
    for name, lean, yaw in copies:
        print(f"{name:>16}: plane precision "
              f"{precision(truth, turned(normals, up, lean, yaw), areas):.3f}")
    if args.planes > 0:
        print_planes(ids, centres, normals, areas, truth, up, args.planes)
    if region is not None:
        print_region(centres, normals, areas, truth, up, region)
    if args.small_planes > 0:
        print_small_planes(ids, normals, areas, truth, args.small_planes)


def precise_cells(truth: List[Optional[np.ndarray]], normals: np.ndarray) -> np.ndarray:
    """Per cell: whether its truth normal lies within MAX_ANGLE_DEG of its normal."""
    min_cos = np.cos(np.radians(MAX_ANGLE_DEG))
    return np.array([t is not None and abs(float(t @ n)) >= min_cos
                     for t, n in zip(truth, normals)], dtype=bool)


def precise_share(areas: np.ndarray, precise: np.ndarray, s: np.ndarray) -> float:
    """The share of the face area of the cells \a s that is precise (nan: no area)."""
    area = areas[s].sum()
    return float(areas[s & precise].sum() / area) if area > 0 else float("nan")


def print_region(centres: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                 truth: List[Optional[np.ndarray]], up: np.ndarray,
                 region: np.ndarray) -> None:
    """The --region lines: face area and precise share inside the box and outside."""
    inside = np.all((centres >= region[0::2]) & (centres <= region[1::2]), axis=1)
    level = np.abs(normals @ up) >= np.cos(np.radians(10.0))
    precise = precise_cells(truth, normals)
    for name, s in (("inside, all", inside), ("inside, level", inside & level),
                    ("outside, all", ~inside), ("outside, level", ~inside & level)):
        print(f"{name:>16}: {int(s.sum()):6d} cells, {areas[s].sum():7.2f} m^2, "
              f"precise {precise_share(areas, precise, s):.3f}")


def print_small_planes(ids: np.ndarray, normals: np.ndarray, areas: np.ndarray,
                       truth: List[Optional[np.ndarray]], max_cuboids: int) -> None:
    """The --small-planes lines: the planes of at most \a max_cuboids cuboids, the rest."""
    plane_ids, counts = np.unique(ids, return_counts=True)
    small_ids = plane_ids[counts <= max_cuboids]
    small = np.isin(ids, small_ids)
    precise = precise_cells(truth, normals)
    for name, s, planes in ((f"<= {max_cuboids} cuboids", small, len(small_ids)),
                            ("the rest", ~small, len(plane_ids) - len(small_ids))):
        print(f"{name:>16}: {planes:4d} planes, {int(s.sum()):6d} cells, "
              f"{areas[s].sum():7.2f} m^2, precise {precise_share(areas, precise, s):.3f}")


def print_planes(ids: np.ndarray, centres: np.ndarray, normals: np.ndarray,
                 areas: np.ndarray, truth: List[Optional[np.ndarray]], up: np.ndarray,
                 count: int) -> None:
    """The --planes listing of the \a count planes of the largest face area."""
    angles = np.array([np.degrees(np.arccos(min(1.0, abs(float(t @ n)))))
                       if t is not None else np.nan for t, n in zip(truth, normals)])
    planes = sorted(np.unique(ids), key=lambda p: -areas[ids == p].sum())[:count]
    print("plane  cells  area m^2  normal              tilt deg  up extent m    "
          "precise  median angle deg")
    for p in planes:
        s = ids == p
        n = normals[s][0]
        heights = centres[s] @ up
        known = s & np.isfinite(angles)
        precise = areas[known & (angles < MAX_ANGLE_DEG)].sum() / areas[s].sum()
        median = np.median(angles[known]) if known.any() else float("nan")
        tilt = np.degrees(np.arccos(min(1.0, abs(float(n @ up)))))
        print(f"{p:5d} {int(s.sum()):6d} {areas[s].sum():9.2f}  "
              f"({n[0]:+.2f}, {n[1]:+.2f}, {n[2]:+.2f})  {tilt:8.1f}  "
              f"{heights.min():+5.2f}..{heights.max():+5.2f}  {precise:7.2f}  {median:16.1f}")


if __name__ == "__main__":
    main()
