"""The learned planner against its baselines, per grasp target: one table
and one JSON of every target's `regrasp-drake train --target` figures.

    .venv/bin/python benchmarks/learned_planner.py [--targets flip+0 ...]
        [--out models/results/learned_planner.json]

For each target (default the six of `dataset --all-targets`) whose data
set is in models/ (models/dataset_<target>): the planner judged and trained
as `train --target` does it (learning/planner.py `train_planner`; its file
models/planner_<target>.json and its report models/results/planner_<target>.json),
unless that report exists already (delete it to judge again: judging is
deterministic). Prints, per target, the maps' share in the target grasp and
the success rates by geometry and by object of the learned planner, the
paper's network, the best constant cell and the ceiling, the learned
planner's lead over the best constant cell by geometry (the issue's goal:
>= 10 points), its gap to the ceiling, and the chooser that won; writes
them to --out.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import torch

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError
from regrasp_drake.learning.dataset import TARGET_SETS, target_dir_name
from regrasp_drake.learning.planner import PlannerData, train_planner
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.progress import bar as progress_bar

DEFAULT_TARGETS = [target_dir_name(t).removeprefix("dataset_")
                   for t in TARGET_SETS]


def report_for(target: str) -> dict | None:
    """The target's planner report, judged now when not yet written; None
    when its data set is not in models/."""
    data = MODELS_DIR / f"dataset_{target}"
    report_path = MODELS_DIR / "results" / f"planner_{target}.json"
    if report_path.exists():
        return json.loads(report_path.read_text())
    if not (data / "maps.npz").exists():
        return None
    maps = PlannerData.load(data)
    splits = len(set(maps.geometries)) + len(set(maps.objects))
    with progress_bar(splits, f"planner {target}", "splits") as shown:
        report = train_planner(data, MODELS_DIR / f"planner_{target}.json",
                               maps=maps, progress=shown.update)
    atomic_io.write_json(report_path, report)
    return report


def row(target: str, report: dict) -> dict:
    geometry, objects = report["by_geometry"], report["by_object"]
    best = max(geometry[k] for k in ("learned", "paper_network",
                                      "best_constant"))
    return {"target": target, "maps": report["maps"],
            "cells_in_target": report["cells_in_target"],
            "maps_in_10_90": report["maps_in_10_90"],
            "by_geometry": geometry, "by_object": objects,
            "learned_lead_by_geometry": round(
                geometry["learned"] - geometry["best_constant"], 4),
            "gap_to_ceiling_by_geometry": round(geometry["ceiling"] - best, 4),
            "best_cell_per_geometry_in_sample": report.get(
                "best_cell_per_geometry_in_sample"),
            "planner": report["planner"]}


def markdown(rows: list[dict]) -> str:
    lines = ["| Target | Maps (10-90 %) | Cells in target | By geometry: learned / "
             "paper / constant / ceiling | By object: learned / paper / "
             "constant / ceiling | Learned - constant | Planner |",
             "|---|---|---|---|---|---|---|"]
    for r in rows:
        g, o = r["by_geometry"], r["by_object"]
        lines.append(
            f"| {r['target']} | {r['maps']} ({r['maps_in_10_90']}) | "
            f"{r['cells_in_target']:.1%} | {g['learned']:.3f} / "
            f"{g['paper_network']:.3f} / {g['best_constant']:.3f} / "
            f"{g['ceiling']:.3f} | {o['learned']:.3f} / "
            f"{o['paper_network']:.3f} / {o['best_constant']:.3f} / "
            f"{o['ceiling']:.3f} | {r['learned_lead_by_geometry']:+.3f} | "
            f"{r['planner']} |")
    return "\n".join(lines)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--targets", nargs="+", default=DEFAULT_TARGETS,
                        metavar="TARGET")
    parser.add_argument("--out", type=Path,
                        default=MODELS_DIR / "results" / "learned_planner.json")
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    rows = []
    try:
        for target in args.targets:
            if target not in DEFAULT_TARGETS:
                raise InputError(f"--targets: got {target!r}, expected one of "
                                 f"{DEFAULT_TARGETS}")
            report = report_for(target)
            if report is None:
                print(f"learned_planner: {target}: no data set "
                      f"models/dataset_{target} (regrasp-drake dataset "
                      "--all-targets --out models)", file=sys.stderr)
                continue
            rows.append(row(target, report))
    except InputError as e:
        print(f"learned_planner: error: {e}", file=sys.stderr)
        return 2
    atomic_io.write_json(args.out, {"targets": rows})
    print(markdown(rows))
    return 0


if __name__ == "__main__":
    sys.exit(main())
