"""Side by side: the release's convergence figures of several runs of
benchmarks/release_convergence.py (discrete steps, CENIC accuracies),
as one Markdown table per figure, and each run's wall time.

    .venv/bin/python studies/cenic/release_table.py
        --runs "discrete 0.25/0.0625 ms=out/palm_toss_release_q"
               "CENIC 1e-3/1e-4=out/cenic_release_1e-3" ...
        [--objects NAME ...] [--cross LABEL LABEL]

Each run is LABEL=DIR, DIR holding the script's rows.jsonl. Objects: those
given, or the first run's; a run without an object shows "-". --cross
compares the fine settings of two of the runs with each other (do a
discrete step and a CENIC accuracy tend to the same release?).
"""

import argparse
import json
import sys
from pathlib import Path

from regrasp_drake.convergence import release_differences

FIGURES = (("spin_rad_per_s", "spin change, rad/s", 0.05, 3),
           ("velocity_mm_per_s", "velocity change, mm/s", 10.0, 2),
           ("catch_point_mm", "catch point change, mm", 10.0, 2),
           ("catch_moment_ms", "catch moment change, ms", 4.0, 2))


def read_run(directory: Path) -> dict:
    rows = {}
    for line in (directory / "rows.jsonl").read_text().splitlines():
        if line.strip():
            row = json.loads(line)
            rows[row["object"]] = row
    return rows


def table(runs: dict, objects: list) -> str:
    labels = list(runs)
    out = []
    for key, title, target, digits in FIGURES:
        out.append(f"\n**{title}** (target {target})\n")
        out.append("| object | " + " | ".join(labels) + " |")
        out.append("|---|" + "---:|" * len(labels))
        for name in objects:
            cells = []
            for label in labels:
                row = runs[label].get(name)
                value = None if row is None else row.get(key)
                cells.append("-" if value is None else
                             f"{value:.{digits}f}" + ("" if value <= target
                                                      else " ✗"))
            out.append(f"| {name} | " + " | ".join(cells) + " |")
        within = []
        for label in labels:
            values = [runs[label][n].get(key) for n in objects
                      if n in runs[label]]
            within.append(f"{sum(v is not None and v <= target for v in values)}"
                          f"/{len(values)}")
        out.append("| within target | " + " | ".join(within) + " |")
    out.append("\n**all four targets, and wall time (s, sum over the objects: "
               "coarse setting + fine setting)**\n")
    out.append("| | " + " | ".join(labels) + " |")
    out.append("|---|" + "---:|" * len(labels))
    all_four, walls = [], []
    for label in labels:
        rows = [runs[label][n] for n in objects if n in runs[label]]
        met = sum(all(r.get(k) is not None and r[k] <= t
                      for k, _, t, _ in FIGURES) for r in rows)
        all_four.append(f"{met}/{len(rows)}")
        walls.append(f"{sum(r['coarse']['wall_s'] for r in rows):.0f} + "
                     f"{sum(r['fine']['wall_s'] for r in rows):.0f}")
    out.append("| all four | " + " | ".join(all_four) + " |")
    out.append("| wall s | " + " | ".join(walls) + " |")
    return "\n".join(out)


def cross(runs: dict, a: str, b: str, objects: list) -> str:
    """The four figures between run a's fine setting and run b's."""
    out = [f"\n**{a} (fine) against {b} (fine)**\n",
           "| object | " + " | ".join(t for _, t, _, _ in FIGURES) + " |",
           "|---|" + "---:|" * len(FIGURES)]
    for name in objects:
        if name not in runs[a] or name not in runs[b]:
            continue
        d = release_differences(runs[a][name]["fine"], runs[b][name]["fine"])
        out.append(f"| {name} | " + " | ".join(
            "-" if d[k] is None else f"{d[k]:.{n}f}"
            for k, _, _, n in FIGURES) + " |")
    return "\n".join(out)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", nargs="+", required=True)
    parser.add_argument("--objects", nargs="+", default=None)
    parser.add_argument("--cross", nargs=2, default=None,
                        metavar="LABEL")
    args = parser.parse_args(argv)
    runs = {}
    for run in args.runs:
        label, sep, directory = run.partition("=")
        if not sep or not (Path(directory) / "rows.jsonl").is_file():
            print(f"error: --runs: got {run!r}, expected LABEL=DIR with "
                  "DIR/rows.jsonl", file=sys.stderr)
            return 2
        runs[label] = read_run(Path(directory))
    objects = args.objects or list(next(iter(runs.values())))
    print(table(runs, objects))
    if args.cross:
        for label in args.cross:
            if label not in runs:
                print(f"error: --cross: got {label!r}, expected one of "
                      f"{list(runs)}", file=sys.stderr)
                return 2
        print(cross(runs, *args.cross, objects))
    return 0


if __name__ == "__main__":
    sys.exit(main())
