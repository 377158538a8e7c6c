"""Are the learned planner's figures a property of the objects, or of the
catch's time step? A target data set's maps computed again at a finer step,
and the planner's judging scored on both.

    .venv/bin/python benchmarks/planner_convergence.py --target flip+0
        [--objects NAME ... | --each N] [--steps-ms 0.25 [0.125 ...]] [--workers 2]
        [--out models/results/planner_convergence_flip+0.json]

For the target's data set (models/dataset_<target>, made at the shipped
1 ms catch step) and the chosen objects (default: the first 11 maps the
best constant cell fails, and as many it holds, in the data set's order;
--each N for N of each):
the same entries computed again with only the catch's time step changed
(`dataset.generate` on the data set's own scenario; resumable, in
out/planner_convergence/<target>_<step>ms/, for each finer step). Then
for each step against the next coarser one, per map and over them, apart
for the lopsided objects (an off-axis centre of mass: the grasp has a side,
planning/grasp.py) and the round ones:
  - the cells with the same outcome at both steps, against the agreement
    two unrelated maps with the same rates would show by chance;
  - of the cells in the target grasp at the coarser step, the share still
    in it at the finer one;
  - the rates of the choosers `regrasp-drake train --target` judges by
    geometry (learning/planner.py `judge`: each held-out map's learned,
    paper network and best constant cell, and the ceiling, any cell), at
    both steps.
With --designs, the maps are made again under each scenario override
instead (resumable, in out/planner_convergence/<target>_<digest>/), and
each design compared with the next as a coarser step with a finer one;
the report's steps_ms are then the designs' positions.
And per map: each chooser's cell (the ceiling's: the 1 ms map's most
robust cell, learning/labels.py) and whether it is in the target grasp at
each step. Prints a table and writes the JSON.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.convergence import agreement
from regrasp_drake.errors import InputError
from regrasp_drake.learning import dataset
from regrasp_drake.learning.dataset_files import load_map
from regrasp_drake.learning.planner import CHOOSERS, PlannerData, judge
from regrasp_drake.learning.provenance import load_provenance
from regrasp_drake.paths import MODELS_DIR, REPO_DIR
from regrasp_drake.planning.grasp import has_side
from regrasp_drake.station.scenario import (
    load_scenario,
    merged_text,
    scenario_digest,
    with_catch_time_step,
)
from regrasp_drake.world.objects import resolve_object

# At most this many maps the best constant cell fails, and as many it holds.
DEFAULT_EACH = 11
OUT_DIR = (REPO_DIR or Path.cwd()) / "out" / "planner_convergence"


def default_objects(data: PlannerData, most: int = DEFAULT_EACH) -> list[str]:
    """The first `most` maps (in the data set's order) that the best
    constant cell of all the maps fails, and as many it holds."""
    counts = data.caught.reshape(len(data.objects), -1)
    best = counts.sum(axis=0).argmax()
    held = [o for o, c in zip(data.objects, counts[:, best]) if c]
    failed = [o for o, c in zip(data.objects, counts[:, best]) if not c]
    failed = failed[:most]
    return failed + held[:len(failed)]


def scored(maps: dict, picks: dict) -> dict:
    """Each chooser's rate over `maps` (name -> 10 x 15 booleans) with the
    cells in `picks` (name -> chooser -> cell); the ceiling is any cell."""
    rates = {}
    for chooser in CHOOSERS:
        if chooser == "ceiling":
            hits = [m.any() for m in maps.values()]
        else:
            hits = [m[tuple(picks[n][chooser])] for n, m in maps.items()]
        rates[chooser] = round(float(np.mean(hits)), 4) if hits else None
    return rates


def compare(names, coarse: dict, fine: dict, picks: dict) -> dict:
    """The figures of one group of maps at both steps (module docstring)."""
    if not names:
        return {"maps": 0}
    a = np.stack([coarse[n].ravel() for n in names])
    b = np.stack([fine[n].ravel() for n in names])
    same = float((a == b).mean())
    chance = float(np.mean([agreement(x, y)["chance"] / x.size
                            for x, y in zip(a, b)]))
    kept = float(b[a].mean()) if a.any() else None
    return {"maps": len(names),
            "cells_same": round(same, 4), "cells_same_by_chance": round(chance, 4),
            "cells_in_target": [round(float(a.mean()), 4),
                                round(float(b.mean()), 4)],
            "in_target_still_at_finer_step": (None if kept is None
                                              else round(kept, 4)),
            "coarse": scored({n: coarse[n] for n in names}, picks),
            "fine": scored({n: fine[n] for n in names}, picks)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--target", default="flip+0",
                        help="a target data set in models/ (flip+0, keep-30, ...)")
    parser.add_argument("--objects", nargs="+", metavar="NAME")
    parser.add_argument("--each", type=int, default=DEFAULT_EACH,
                        metavar="N", help="without --objects: the first N "
                        "maps the best constant cell fails and as many it "
                        f"holds (default {DEFAULT_EACH})")
    parser.add_argument("--steps-ms", type=float, nargs="+", default=[0.25],
                        metavar="MS", help="finer catch steps than 1 ms")
    parser.add_argument("--designs", nargs="+", metavar="YAML",
                        help="instead of the data set's maps against finer "
                             "catch steps: the maps made again under each "
                             "override of the data set's scenario (e.g. '{}' "
                             "for today's defaults, then '{landing_time_step_s:"
                             " 0.000125, catch_time_step_s: 0.0005}' for half "
                             "their steps), compared in turn")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path)
    args = parser.parse_args(argv)
    data_dir = MODELS_DIR / f"dataset_{args.target}"
    try:
        if not (data_dir / "maps.npz").exists():
            raise InputError(f"--target: {args.target!r}: no data set "
                             f"{data_dir}, expected one of models/dataset_*")
        if args.each < 1:
            raise InputError(f"--each: got {args.each}, expected an "
                             "integer >= 1")
        if args.workers < 1:
            raise InputError(f"--workers: got {args.workers}, expected an "
                             "integer >= 1")
        made_with = load_provenance(data_dir / "provenance.json")["scenario"]
        # The data set's maps were made before the landing's own step: its
        # scenario as it was, then (below) only the catch's step changed.
        base = load_scenario(text=merged_text(
            made_with, "{landing_time_step_s: null}"))
        designs = [load_scenario(text=merged_text(made_with, text))
                   for text in args.designs or ()]
        throw_ms = 1e3 * base.plant_config.time_step
        coarse_ms = 1e3 * (base.catch_time_step_s or base.plant_config.time_step)
        for step in args.steps_ms:
            if not step < coarse_ms:
                raise InputError(f"--steps-ms: got {step}, expected steps "
                                 f"finer than the data set's {coarse_ms:g} ms")
            if step < throw_ms - 1e-9:
                raise InputError(f"--steps-ms: got {step}, expected steps at "
                                 f"least the throw's plant step, {throw_ms:g} ms")
        data = PlannerData.load(data_dir)
        names = args.objects or default_objects(data, args.each)
        unknown = sorted(set(names) - set(data.objects))
        if unknown:
            raise InputError(f"--objects: {unknown[0]!r} has no map in "
                             f"{data_dir}, expected one of its objects")
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    if designs:
        # Each design's maps, labelled by its position (steps_ms holds
        # the labels then; the report names the designs).
        steps = list(range(len(designs)))
        maps = {}
        for i, scenario in enumerate(designs):
            design_dir = OUT_DIR / f"{args.target}_{scenario_digest(scenario)}"
            dataset.generate(names, design_dir, workers=args.workers,
                             scenario=scenario)
            maps[i] = {n: load_map(design_dir, n) for n in names}
    else:
        steps = [coarse_ms] + sorted(set(args.steps_ms), reverse=True)
        maps = {coarse_ms: {n: data.caught[data.objects.index(n)]
                            for n in names}}
        for step in steps[1:]:
            fine_dir = OUT_DIR / f"{args.target}_{step:g}ms"
            dataset.generate(names, fine_dir, workers=args.workers,
                             scenario=with_catch_time_step(base, step / 1e3))
            maps[step] = {n: load_map(fine_dir, n) for n in names}
    def label(step):
        return f"design {step}" if designs else f"{step:g} ms"

    choices: dict = {}
    judge(data, choices=choices)
    picks = choices["by_geometry"]
    lopsided = [n for n in names if has_side(resolve_object(name=n))]
    round_ = [n for n in names if n not in lopsided]
    report = {"target": args.target, "data": str(data_dir.relative_to(
        REPO_DIR) if REPO_DIR else data_dir), "steps_ms": steps,
        "designs": args.designs,
        "objects": names, "lopsided": lopsided, "pairs": []}
    print(f"{args.target}: {len(names)} maps ({len(lopsided)} lopsided); "
          "the choosers by geometry: learned / paper / constant / ceiling")
    # Each step's (design's) share of cells in the target grasp, also with
    # one design alone (a data set made again at a new default).
    report["in_target"] = {
        f"{step:g}": {group: round(float(np.mean(
            [maps[step][n] for n in group_names])), 4) if group_names else None
            for group, group_names in (("all", names),
                                       ("lopsided", lopsided),
                                       ("round", round_))}
        for step in steps}
    for step in steps:
        shares = report["in_target"][f"{step:g}"]
        print(f"{label(step)}: cells in the target " + ", ".join(
            f"{group} {share:.3f}" for group, share in shares.items()
            if share is not None))
    for coarse_step, fine_step in zip(steps, steps[1:]):
        coarse, fine = maps[coarse_step], maps[fine_step]
        pair = {"steps_ms": [coarse_step, fine_step]} | {
            group: compare(group_names, coarse, fine, picks)
            for group, group_names in (("all", names), ("lopsided", lopsided),
                                       ("round", round_))}
        report["pairs"].append(pair)
        print(f"{label(coarse_step)} vs {label(fine_step)}:")
        for group in ("all", "lopsided", "round"):
            g = pair[group]
            if not g["maps"]:
                continue
            rates = " | ".join(
                f"{label(step)} " + " / ".join(f"{g[key][c]:.3f}" for c in CHOOSERS)
                for key, step in (("coarse", coarse_step), ("fine", fine_step)))
            print(f"  {group:8s} {g['maps']:2d} maps: cells same "
                  f"{g['cells_same']:.3f} (chance {g['cells_same_by_chance']:.3f})"
                  f"; in target at {label(coarse_step)} still so "
                  f"{g['in_target_still_at_finer_step']}; {rates}")
    report["per_map"] = {
        n: {"lopsided": n in lopsided,
            "picks": {c: list(map(int, v)) if v else None
                      for c, v in picks[n].items()},
            "cells_in_target": {f"{s:g}": round(float(maps[s][n].mean()), 3)
                                for s in steps},
            "picked_in_target": {f"{s:g}": {c: bool(maps[s][n][tuple(v)])
                                            if v else False
                                            for c, v in picks[n].items()}
                                 for s in steps}}
        for n in names}
    out = args.out or (MODELS_DIR / "results"
                       / f"planner_convergence_{args.target}.json")
    atomic_io.write_json(out, report)
    print(f"wrote {out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
