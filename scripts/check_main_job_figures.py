# SPDX-License-Identifier: BSD-3-Clause
"""The main job's map figures quoted in the docs, checked against a run of the main job.

    build/tools/planar_grid_pipeline --config config/karlsruhe.yaml --output OUT
    python3 scripts/check_main_job_figures.py OUT [--repo .]

Reads OUT/report.json (its `map` object) and the size of OUT/map.pgmap, then finds each
place in README.md and docs/ that quotes the main job's map (the patterns below, each
expected at least once in its file) and compares every number it quotes with the run.
Exits 1 naming the file, the line and the figure that differs, or a place that is no
longer found."""
import argparse
import json
import os
import re
import sys

NUMBER = r"([0-9][0-9,]*)"

# (file, pattern, the report figures its numbers are, in order). "map_file_bytes" is the
# size of map.pgmap; the others are keys of report.json's `map`.
PLACES = [
    ("docs/BENCHMARKS.md",
     rf"\*\*{NUMBER} / {NUMBER} / {NUMBER} / {NUMBER}\*\* \(",
     ["cuboids", "planar_cuboids", "planes", "raster_cells"]),
    ("docs/BENCHMARKS.md",
     rf"surface layer \(`report.json` `map`\) \| \*\*{NUMBER} B\*\*",
     ["surface_bytes"]),
    ("docs/BENCHMARKS.md",
     rf"The main job's final map: {NUMBER} cuboids, [0-9.]+ MB \(`map.pgmap`, {NUMBER} B\)",
     ["cuboids", "map_file_bytes"]),
    ("docs/BENCHMARKS.md",
     rf"the main job now has {NUMBER} cuboids \({NUMBER}",
     ["cuboids", "planar_cuboids"]),
    ("docs/EVALUATION.md",
     rf"main job: planar cuboid >= 15 raster cells \| [0-9.]+ \({NUMBER} / {NUMBER}\)",
     ["raster_cells", "planar_cuboids"]),
    ("docs/EVALUATION.md", rf"main job: map cuboids <= 40,000 \| {NUMBER} \|", ["cuboids"]),
    ("docs/EVALUATION.md", rf"main job: surface layer <= 10 MB \| {NUMBER} B", ["surface_bytes"]),
    ("docs/EVALUATION.md", rf"split is {NUMBER} and {NUMBER} bytes",
     ["surface_bytes", "space_bytes"]),
    ("docs/MAP.md",
     rf"{NUMBER} cuboids\s+\({NUMBER} planar\) on {NUMBER} planes, {NUMBER} plane raster cells",
     ["cuboids", "planar_cuboids", "planes", "raster_cells"]),
    ("docs/MAP.md",
     rf"surface layer {NUMBER} B; `map_integration`", ["surface_bytes"]),
    ("docs/MAP.md",
     rf"\*\*`absorb_distance_m: 0.5` \(default\)\*\* \| \*\*{NUMBER}\*\* \| \*\*{NUMBER}\*\* \| "
     rf"\*\*{NUMBER}\*\* \|",
     ["cuboids", "planar_cuboids", "planes"]),
    ("docs/MAP.md", rf"the map spans\s+[0-9.]+ m x [0-9.]+ m; {NUMBER} bytes\)",
     ["map_file_bytes"]),
    ("docs/RELIABILITY.md", rf"The main job, one pass: {NUMBER} cuboids", ["cuboids"]),
]


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("output", help="the main job's output folder")
    parser.add_argument("--repo", default=os.path.join(os.path.dirname(__file__), ".."))
    args = parser.parse_args()
    try:
        with open(os.path.join(args.output, "report.json"), encoding="utf-8") as f:
            figures = dict(json.load(f)["map"])
        figures["map_file_bytes"] = os.path.getsize(os.path.join(args.output, "map.pgmap"))
    except (OSError, ValueError, KeyError) as e:
        sys.exit(f"check_main_job_figures: {args.output}: {e}")

    problems = []
    checked = 0
    for path, pattern, keys in PLACES:
        with open(os.path.join(args.repo, path), encoding="utf-8") as f:
            text = f.read()
        matches = list(re.finditer(pattern, text))
        if not matches:
            problems.append(f"{path}: no longer quotes the figures /{pattern}/")
            continue
        for m in matches:
            line = text.count("\n", 0, m.start()) + 1
            for key, quoted in zip(keys, m.groups()):
                checked += 1
                value = int(quoted.replace(",", ""))
                if value != figures[key]:
                    problems.append(f"{path}:{line}: {key} quoted as {quoted}, "
                                    f"the run gives {figures[key]:,}")
    for p in problems:
        print(f"check_main_job_figures: {p}", file=sys.stderr)
    if problems:
        sys.exit(1)
    print(f"check_main_job_figures: {checked} figures in {len(PLACES)} places match the run "
          f"({figures['cuboids']:,} cuboids, map.pgmap {figures['map_file_bytes']:,} B)")


if __name__ == "__main__":
    main()
