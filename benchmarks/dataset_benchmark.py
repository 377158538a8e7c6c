"""How fast the data set is made, on 1 and on 2 workers, and how much memory
it takes.

    .venv/bin/python benchmarks/dataset_benchmark.py
        [--objects NAME ...] [--workers 1 2] [--full-run out/ds/]
        [--full-run-memory out/ds_mem.json]
        [--json benchmarks/dataset_benchmark.json]

Runs `regrasp-drake dataset` (the shipped scenario, one catch point each) on
the same objects (default: 8 of the 48 training objects, every sixth) once
per --workers value, one after the other in this run, each into a fresh
scratch directory, and samples the memory of the whole process tree
(benchmarks/tree_memory.py: the peak of the summed resident set sizes).
Prints and writes each run's wall time and peak memory, and the speed-up of
each worker count over the first: a ratio measured in one run, as these
machines are noisy. The rows of every run must be the same (checked: the
figures are only reported for runs that agree cell for cell).

With --full-run DIR: also reads the wall time and worker count of a whole
data set from DIR/provenance.json (`regrasp-drake dataset --workers 2 --out
DIR`), and with --full-run-memory the tree_memory.py JSON of that run, so
that the paper's 48 objects' figures sit in the same JSON.
"""

import argparse
import json
import sys
import tempfile
from pathlib import Path

from tree_memory import run_sampled  # beside this script

from regrasp_drake import atomic_io
from regrasp_drake.paths import REPO_DIR as _REPO


def _training_objects() -> list[str]:
    from regrasp_drake.world.objects import load_catalogue
    return [name for name, obj in load_catalogue().items()
            if obj.set == "train"]


def _rows(out_dir: Path) -> dict:
    """Every cell row of a data set directory, without its wall times."""
    rows = {}
    for path in sorted((out_dir / "cells").glob("*.jsonl")):
        for line in path.read_text().splitlines():
            row = json.loads(line)
            row.pop("wall_s", None)
            rows[(path.stem, tuple(row.get("cell", ())))] = row
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+")
    parser.add_argument("--workers", type=int, nargs="+", default=[1, 2])
    parser.add_argument("--full-run", type=Path)
    parser.add_argument("--full-run-memory", type=Path)
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/dataset_benchmark.json"))
    args = parser.parse_args(argv)
    if any(w < 1 for w in args.workers):
        parser.error(f"--workers {args.workers}: expected counts >= 1")
    for flag, path in (("--full-run", args.full_run and
                        args.full_run / "provenance.json"),
                       ("--full-run-memory", args.full_run_memory)):
        if path is not None and not path.is_file():
            parser.error(f"{flag}: {path} not found")
    objects = args.objects or _training_objects()[::6]
    report = {"objects": objects, "runs": []}
    rows = []
    with tempfile.TemporaryDirectory() as scratch:
        for workers in args.workers:
            out = Path(scratch) / f"w{workers}"
            print(f"dataset on {len(objects)} objects, {workers} worker(s)",
                  file=sys.stderr)
            run = run_sampled(
                [sys.executable, "-m", "regrasp_drake.cli", "dataset",
                 "--objects", *objects, "--workers", str(workers),
                 "--out", str(out)], cwd=_REPO)
            if run["returncode"] != 0:
                print(f"dataset_benchmark: error: the {workers}-worker run "
                      f"failed (exit {run['returncode']})", file=sys.stderr)
                return 1
            rows.append(_rows(out))
            report["runs"].append({"workers": workers, "wall_s": run["wall_s"],
                                   "peak_memory_gib": run["peak_tree_rss_gib"],
                                   "cells": len(rows[-1])})
    report["same_rows"] = all(r == rows[0] for r in rows)
    if not report["same_rows"]:
        print("dataset_benchmark: error: the runs' rows differ",
              file=sys.stderr)
        return 1
    base = report["runs"][0]
    for run in report["runs"]:
        run["speed_up"] = round(base["wall_s"] / run["wall_s"], 2)
    if args.full_run:
        p = json.loads((args.full_run / "provenance.json").read_text())
        report["full_run"] = {"objects": p["objects"],
                              "wall_s": p["generation_wall_s"],
                              "workers": p["workers"],
                              "code_version": p["code_version"]}
        if args.full_run_memory:
            m = json.loads(args.full_run_memory.read_text())
            report["full_run"]["peak_memory_gib"] = m["peak_tree_rss_gib"]
    for run in report["runs"]:
        print(f"{run['workers']} worker(s): {run['wall_s']:.0f} s for "
              f"{len(objects)} objects ({run['cells']} cells), speed-up "
              f"{run['speed_up']:.2f}x over {base['workers']}, peak memory "
              f"{run['peak_memory_gib']:.2f} GiB")
    if "full_run" in report:
        f = report["full_run"]
        print(f"whole data set: {f['objects']} objects in "
              f"{f['wall_s'] / 60:.1f} min on {f['workers']} workers"
              + (f", peak memory {f['peak_memory_gib']:.2f} GiB"
                 if "peak_memory_gib" in f else ""))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(args.json, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
