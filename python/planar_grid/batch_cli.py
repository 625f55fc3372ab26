# SPDX-License-Identifier: BSD-3-Clause
"""planar_grid_batch, the command line of planar_grid.distributed.map_segments():
options, exit statuses by class of failure (planar_grid.distributed.exit_status), the
final summary line."""
from __future__ import annotations

import argparse
import os
import sys
from typing import Optional, Sequence, Tuple

import planar_grid as pg
from planar_grid.distributed import (EXIT_INPUT, EXIT_USAGE, exit_status,
                                     map_segments)


class _ArgumentParser(argparse.ArgumentParser):
    """argparse with the pipeline tool's usage status."""

    def error(self, message: str) -> None:  # type: ignore[override]
        self.print_usage(sys.stderr)
        self.exit(EXIT_USAGE, f"{self.prog}: error: {message}\n")


def _frame_range(text: str) -> Tuple[Optional[int], Optional[int]]:
    begin, sep, end = text.partition(":")
    try:
        if not sep:
            raise ValueError
        b = int(begin) if begin else None
        e = int(end) if end else None
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"'{text}' is not a frame range A:B (0-based, B excluded)") from None
    if (b is not None and b < 0) or (b is not None and e is not None and e <= b):
        raise argparse.ArgumentTypeError(f"the frame range '{text}' is empty")
    return b, e


def _positive_int(text: str) -> int:
    try:
        value = int(text)
    except ValueError:
        value = 0
    if value < 1:
        raise argparse.ArgumentTypeError(f"'{text}' is not a whole number >= 1")
    return value


def _positive_float(text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not value > 0:
        raise argparse.ArgumentTypeError(f"'{text}' is not a number > 0")
    return value


def main(argv: Optional[Sequence[str]] = None) -> int:
    """planar_grid_batch: the command-line entry point of map_segments().

    Returns
    -------
    int
        The exit status: 0 success, 2 usage (options, frame ranges), 3 configuration,
        4 input, 5 output, 1 anything else (e.g. a task that failed on a frame).
    """
    parser = _ArgumentParser(
        prog="planar_grid_batch",
        description="Maps recordings in frame segments on a Dask cluster (one task per "
                    "segment) and merges the segment maps pairwise into one map "
                    "(OUTPUT/map.pgmap, OUTPUT/batch_report.json). docs/SCALE.md.",
        epilog="Exit status: 0 success, 2 command line, 3 configuration, 4 input, "
               "5 output, 1 anything else (planar_grid_pipeline's classes).")
    parser.add_argument("--config", action="append", required=True, metavar="YAML",
                        help="a configuration file with a map_integration stage; "
                             "repeat for several recordings in one world frame")
    parser.add_argument("--segments", type=_positive_int, default=4, metavar="N",
                        help="segments per recording (default 4)")
    parser.add_argument("--frames", type=_frame_range, default=None, metavar="A:B",
                        help="split only frame positions A..B-1 of each recording "
                             "(default: every frame)")
    parser.add_argument("--scheduler", default=None, metavar="ADDRESS",
                        help="a running Dask scheduler (tcp://host:port); default: a "
                             "local cluster on 127.0.0.1, stopped at the end")
    parser.add_argument("--workers", type=_positive_int, default=2, metavar="N",
                        help="worker processes of the local cluster (default 2)")
    parser.add_argument("--output", default="output/batch", metavar="DIR",
                        help="the job's folder (default output/batch)")
    parser.add_argument("--tile-size", type=_positive_float, default=None, metavar="M",
                        help="also save the merged map as tiles of M meters "
                             "(default: no tiles); with --merge tiles, the size of "
                             "the tiles merged (required)")
    parser.add_argument("--merge", choices=("tree", "tiles"), default="tree",
                        help="tree (default): merge the segment maps pairwise; tiles: "
                             "save each segment's map as tiles and merge tile by tile "
                             "(OUTPUT/tiles, no OUTPUT/map.pgmap)")
    parser.add_argument("--tiles-per-task", type=_positive_int, default=1, metavar="N",
                        help="with --merge tiles: N neighbouring tile keys per merge "
                             "task (default 1; fewer tasks on a large job)")
    parser.add_argument("-q", "--quiet", action="store_true",
                        help="no progress lines, only errors")
    parser.add_argument("--version", action="version",
                        version=f"planar_grid_batch {pg.__version__}")
    args = parser.parse_args(argv)
    for c in args.config:
        if not os.path.isfile(c):
            print(f"planar_grid_batch: error: the configuration {c} does not exist",
                  file=sys.stderr)
            return EXIT_INPUT
    try:
        report = map_segments(args.config, num_segments=args.segments,
                              frames=args.frames, output_dir=args.output,
                              scheduler_address=args.scheduler, n_workers=args.workers,
                              tile_size_m=args.tile_size, merge=args.merge,
                              tiles_per_task=args.tiles_per_task,
                              progress=not args.quiet)
    except KeyboardInterrupt:
        print("planar_grid_batch: interrupted; the maps already written stay in "
              f"{args.output}", file=sys.stderr)
        return 130
    except Exception as e:  # every error ends here with its class's status
        print(f"planar_grid_batch: error: {e}", file=sys.stderr)
        return exit_status(e)
    if not args.quiet and report["merge"] == "tiles":
        print(f"planar_grid_batch: {report['tiles']['folder']}: "
              f"{report['tiles']['tiles']} tiles from {len(report['segments'])} "
              f"segments in {report['wall_time_s']:.1f} s")
    elif not args.quiet:
        print(f"planar_grid_batch: {report['map']}: {report['planes']} planes, "
              f"{report['planar_cuboids']} planar cuboids, {report['cells']} cells from "
              f"{len(report['segments'])} segments in {report['wall_time_s']:.1f} s")
    return 0
