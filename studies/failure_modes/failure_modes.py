"""How the cells of a success map fail: the ending of every cell (grid.ending:
caught; not held with the object in the fingers, at rest against the arm, or
loose; fallen below the palm; near the ground; failed, mostly a lowered pose
out of the arm's reach), from the grasp monitor's drop reason and the bodies
the object touches when the episode ends.

    .venv/bin/python studies/failure_modes/failure_modes.py [--objects NAME ...]
        [--workers N] [--scenario F] [--out studies/failure_modes/failure_modes.json]

For each object (default: the five Table 1 objects and three training
objects whose centre of mass lies 20 mm or more off the grasp piece's axis),
the watching throw, the catch plan and the 150 cells, as `regrasp-drake
grid` runs them, written as JSON lines to studies/failure_modes/failure_modes/<object>
.jsonl as cells finish (a rerun resumes; with --scenario F, to
studies/failure_modes/failure_modes_<F's stem>/ and, by default, to
studies/failure_modes/failure_modes_<F's stem>.json). Each map's outcomes are checked
against the stored ones where there are any: models/results/maps/<object>
.jsonl (Table 1, `regrasp-drake table1`) and models/dataset/maps.npz (a
training object's first catch point); the JSON says whether they agree cell
for cell. The network's start cell of each Table 1 row
(models/results/table1.json) is looked up in its map.

Writes the JSON (per object: the ending counts, how many of the cells
ending in the fingers have the object touching the palm too, the start
cell's ending, the agreement) and a PNG of the maps coloured by ending.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import os
import sys
from pathlib import Path

import numpy as np

from regrasp_drake.errors import InputError, check_output_path
from regrasp_drake.grid import (
    ending,
    ending_counts,
    plan_object,
    read_rows,
    run_map,
)
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.plots import draw_endings, ending_legend

HERE = Path(__file__).parent / "failure_modes"
DEFAULT_OBJECTS = ("table1-row1", "table1-row2", "table1-row3", "table1-row4",
                   "table1-row5", "adze-d300-3", "hook-d300-4",
                   "flashlight-d250-4")


def _shown(path: Path) -> str:
    """A stored file's path, relative to the repository."""
    return str(path.relative_to(MODELS_DIR.parent))


def stored_outcomes(name: str) -> dict:
    """{source: {cell: caught?}} of the stored maps of `name`."""
    out = {}
    table1_map = MODELS_DIR / "results" / "maps" / f"{name}.jsonl"
    if table1_map.is_file():
        out[_shown(table1_map)] = {c: r["outcome"] == "caught"
                                for c, r in read_rows(table1_map).items()}
    maps = MODELS_DIR / "dataset" / "maps.npz"
    with np.load(maps, allow_pickle=False) as data:
        names = [str(n) for n in data["objects"]]
        if name in names:
            caught = data["caught"][names.index(name)]
            out[_shown(maps)] = {(i, j): bool(caught[i, j])
                              for i in range(caught.shape[0])
                              for j in range(caught.shape[1])}
    return out


def start_cells() -> dict:
    path = MODELS_DIR / "results" / "table1.json"
    if not path.is_file():
        return {}
    return {r["object"]: tuple(r["start_cell"])
            for r in json.loads(path.read_text())}


def summarize(name: str, rows: dict, start) -> dict:
    caught = {c: r["outcome"] == "caught" for c, r in rows.items()}
    agree = {source: outcomes == caught
             for source, outcomes in stored_outcomes(name).items()}
    return {"object": name, "cells": len(rows),
            "endings": ending_counts(rows.values()),
            # In the fingers and against the palm too, yet not recognized.
            "in_fingers_touching_palm": sum(
                ending(r) == "in_fingers" and "palm" in r["touching"]
                for r in rows.values()),
            "start_cell": None if start is None else list(start),
            "start_cell_ending": None if start is None
            else ending(rows[start]),
            "agrees_with_stored": agree}


def plot(results: list, maps: dict, path: Path, title: str) -> None:
    import matplotlib.pyplot as plt

    n = len(results)
    cols = min(4, n)
    rows_ = (n + cols - 1) // cols
    fig, axes = plt.subplots(rows_, cols, figsize=(4.2 * cols, 3.4 * rows_ + 1),
                             squeeze=False)
    for ax, result in zip(axes.flat, results):
        start = result["start_cell"]
        draw_endings(ax, maps[result["object"]],
                     marks=[] if start is None else [(tuple(start), "gold")])
        e = result["endings"]
        ax.set_title(f"{result['object']}: {e['caught']} caught, "
                     f"{e['on_arm']} on the arm", fontsize=9)
    for ax in list(axes.flat)[n:]:
        ax.axis("off")
    fig.legend(handles=ending_legend(extra=[
        ("the network's start cell (Table 1)", "gold")]),
        loc="lower center", ncol=2, fontsize=8)
    fig.suptitle(title)
    fig.tight_layout(rect=(0, 0.16 if rows_ == 1 else 0.1, 1, 0.97))
    fig.savefig(path, dpi=110)
    plt.close(fig)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--objects", nargs="+", default=list(DEFAULT_OBJECTS),
                   metavar="NAME")
    p.add_argument("--workers", type=int, default=os.cpu_count() or 1)
    p.add_argument("--scenario", type=Path, default=None,
                   help="a scenario YAML file (default: the shipped one)")
    p.add_argument("--out", type=Path, default=None)
    args = p.parse_args(argv)
    rows_dir = (HERE if args.scenario is None
                else HERE.with_name(f"{HERE.name}_{args.scenario.stem}"))
    out_path = args.out or rows_dir.parent / f"{rows_dir.name}.json"
    try:
        check_output_path("--out", out_path)
    except InputError as e:
        print(f"failure_modes: error: {e}", file=sys.stderr)
        return 2
    if args.workers < 1:
        print(f"failure_modes: error: --workers: {args.workers} (expected a "
              "whole number >= 1)", file=sys.stderr)
        return 2
    import torch

    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import load_scenario
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    try:
        objects = [resolve_object(name=name) for name in args.objects]
        scenario = load_scenario(args.scenario)
    except InputError as e:
        print(f"failure_modes: error: {e}", file=sys.stderr)
        return 2
    ik = ArmIk()
    rows_dir.mkdir(exist_ok=True)
    starts = start_cells()
    results, maps = [], {}
    for obj in objects:
        plan = plan_object(scenario, obj, ik)
        rows = run_map(scenario, obj, ik, plan, rows_dir / f"{obj.name}.jsonl",
                       workers=args.workers)
        maps[obj.name] = rows
        result = summarize(obj.name, rows, starts.get(obj.name))
        results.append(result)
        e = result["endings"]
        print(f"{obj.name:20s} " + ", ".join(f"{k} {v}" for k, v in e.items())
              + f"; start cell: {result['start_cell_ending']}; agrees with "
              f"stored: {result['agrees_with_stored']}", flush=True)
    total = ending_counts(r for m in maps.values() for r in m.values())
    out = {"scenario": None if args.scenario is None else str(args.scenario),
           "objects": results, "total": total}
    out_path.write_text(json.dumps(out, indent=1) + "\n")
    png = out_path.parent / f"{out_path.stem}.png"
    plot(results, maps, png, "How each cell ends (failure_modes.py"
         + ("" if args.scenario is None else f", {args.scenario}") + ")")
    print(f"total: {total}\nwrote {out_path} and {png}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
