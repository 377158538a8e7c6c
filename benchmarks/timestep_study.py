"""Do success maps converge as the plant's time step shrinks?

    .venv/bin/python benchmarks/timestep_study.py [--objects table1-row2 …]
        [--steps-ms 2 1 0.5 0.25 0.125] [--workers 2]
        [--out benchmarks/timestep_study]

For each object and each time step (the shipped scenario with only
`time_step_s` changed): the watching throw, the object's state when the throw
ends (the release: its velocity and its angular velocity in its own frame),
the planned catch point, and the whole 150-cell success map. Then, for every
pair of steps, how many cells have the same outcome, against the agreement
two unrelated maps with the same catch rates would show by chance,
p·q + (1 − p)·(1 − q) of the cells.

A map that is a converged function of the physics agrees more and more
closely as the step halves; one decided by the discretization agrees with
its neighbours no better than chance.

Writes <out>/<object>_<step>ms.jsonl (one line per cell, as it finishes; a
rerun resumes), <out>.json (the figures) and <out>.png (every map, and the
agreements against chance).
"""

import argparse
import json
import sys
from pathlib import Path

import numpy as np

_OBJECTS = ["table1-row2", "table1-row4", "table1-row5"]
_STEPS_MS = [2.0, 1.0, 0.5, 0.25, 0.125]


def agreement(a, b) -> dict:
    """Cells with the same outcome in boolean maps a and b, and the number
    two independent maps with their catch rates would share by chance."""
    a, b = np.asarray(a, bool), np.asarray(b, bool)
    p, q = a.mean(), b.mean()
    return {"same": int((a == b).sum()),
            "chance": round(float(a.size * (p * q + (1 - p) * (1 - q))), 1),
            "cells": int(a.size)}


def release_state(scenario, obj, logs) -> dict:
    """The object's state at the first logged sample after the throw ends:
    v_WO (m/s) and w_O, the angular velocity in the object's frame (rad/s)."""
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RotationMatrix
    t_free = scenario.throw.settle_s + scenario.throw.knot_times_s[-1]
    k = int(np.searchsorted(logs.t, t_free))
    x = logs.object_state[:, k]
    R_WO = RotationMatrix(Quaternion(x[:4] / np.linalg.norm(x[:4]))).matrix()
    return {"t_s": round(float(logs.t[k]), 4),
            "v_WO": [round(float(c), 4) for c in x[10:13]],
            "w_O": [round(float(c), 4) for c in R_WO.T @ x[7:10]]}


def run_object_step(name, step_ms, out_dir: Path, workers: int) -> dict:
    """The watch, the plan and the success map of one object at one step."""
    import dataclasses as dc

    from regrasp_drake.grid import run_map
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import load_scenario, validate
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    scenario = validate(dc.replace(load_scenario(), time_step_s=step_ms / 1e3))
    obj = resolve_object(name=name)
    ik = ArmIk()
    watched = watch(scenario, obj, ik)
    plan = plan_catch(scenario, obj, ik, watched)
    rows = run_map(scenario, obj, ik, plan,
                   out_dir / f"{name}_{step_ms:g}ms.jsonl", workers=workers)
    caught = np.zeros((10, 15), bool)
    for cell, row in rows.items():
        caught[cell] = row["outcome"] == "caught"
    cp = plan.catch_point
    return {"release": release_state(scenario, obj, watched.logs),
            "catch_point": {"t_s": round(cp.t_s, 4),
                            "p_WO": [round(float(c), 4) for c in cp.p_WO],
                            "tilt": round(float(cp.tilt), 4),
                            "v_catch": round(float(cp.v_catch), 4)},
            "cells_caught": int(caught.sum()),
            "caught": caught.astype(int).tolist()}


def summarize(results: dict, steps_ms) -> dict:
    """results[name][step] as run_object_step's; adds the pairwise agreement
    of the maps (steps in the order given)."""
    summary = {"steps_ms": list(steps_ms), "objects": {}}
    for name, by_step in results.items():
        maps = [np.array(by_step[s]["caught"], bool) for s in steps_ms]
        pairs = [[agreement(a, b) for b in maps] for a in maps]
        summary["objects"][name] = {
            "by_step": {f"{s:g}": by_step[s] for s in steps_ms},
            "agreement_same": [[p["same"] for p in row] for row in pairs],
            "agreement_chance": [[p["chance"] for p in row] for row in pairs]}
    return summary


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+", default=_OBJECTS)
    parser.add_argument("--steps-ms", type=float, nargs="+", default=_STEPS_MS)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path,
                        default=Path("benchmarks/timestep_study"))
    args = parser.parse_args(argv)
    import dataclasses as dc

    from regrasp_drake.errors import InputError
    from regrasp_drake.station.scenario import load_scenario, validate
    from regrasp_drake.world.objects import resolve_object
    try:
        for step in args.steps_ms:
            try:
                validate(dc.replace(load_scenario(), time_step_s=step / 1e3))
            except InputError as e:
                raise InputError(f"--steps-ms {step:g}: {e}") from None
        for name in args.objects:
            resolve_object(name=name)
        if args.workers < 1:
            raise InputError(f"--workers {args.workers}: expected >= 1")
    except InputError as e:
        print(f"timestep_study: error: {e}", file=sys.stderr)
        return 2
    import torch
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    results = {}
    for name in args.objects:
        results[name] = {}
        for step in args.steps_ms:
            print(f"{name}, step {step:g} ms", file=sys.stderr)
            results[name][step] = run_object_step(name, step, args.out,
                                                  args.workers)
    summary = summarize(results, args.steps_ms)
    args.out.with_suffix(".json").write_text(json.dumps(summary) + "\n")
    _print(summary)
    _plot(summary, args.out.with_suffix(".png"))
    return 0


def _print(summary):
    steps = summary["steps_ms"]
    for name, s in summary["objects"].items():
        print(f"\n{name}")
        for i, step in enumerate(steps):
            b = s["by_step"][f"{step:g}"]
            cp, rel = b["catch_point"], b["release"]
            same = " ".join(f"{n:>3}/{c:>5.1f}" for n, c in zip(
                s["agreement_same"][i], s["agreement_chance"][i]))
            print(f"  {step:>5g} ms: {b['cells_caught']:>3}/150 catch; "
                  f"catch at t {cp['t_s']:.3f} s, tilt {cp['tilt']:.2f}, "
                  f"v {cp['v_catch']:.2f} m/s; w_O at release "
                  f"{np.round(rel['w_O'], 2)} rad/s; same cells / chance "
                  f"vs each step: {same}")


def _plot(summary, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    steps = summary["steps_ms"]
    names = list(summary["objects"])
    fig, axes = plt.subplots(len(names), len(steps) + 1,
                             figsize=(2.6 * (len(steps) + 1), 2.5 * len(names)),
                             squeeze=False)
    for row, name in zip(axes, names):
        s = summary["objects"][name]
        for i, (ax, step) in enumerate(zip(row, steps)):
            b = s["by_step"][f"{step:g}"]
            ax.imshow(np.array(b["caught"]), origin="lower", cmap="Greens",
                      vmin=0, vmax=1.3, extent=(-14.5, 0.5, 0.02, 0.42),
                      aspect="auto")
            ax.set_title(f"{name}, {step:g} ms\n{b['cells_caught']}/150, tilt "
                         f"{b['catch_point']['tilt']:.2f}", fontsize=8)
            ax.set_xlabel("h_down (cm)", fontsize=7)
            ax.set_ylabel("h_catch (m)", fontsize=7)
            ax.tick_params(labelsize=6)
        ax = row[-1]
        x = np.arange(len(steps) - 1)
        same = [s["agreement_same"][i][i + 1] for i in x]
        chance = [s["agreement_chance"][i][i + 1] for i in x]
        ax.bar(x - 0.2, same, 0.4, label="same outcome")
        ax.bar(x + 0.2, chance, 0.4, color="lightgray", label="chance")
        ax.set_xticks(x, [f"{a:g}-{b:g}" for a, b in zip(steps, steps[1:])],
                      fontsize=7)
        ax.set_xlabel("step pair (ms)", fontsize=7)
        ax.set_ylim(0, 150)
        ax.set_title("cells agreeing, neighbouring steps", fontsize=8)
        ax.legend(fontsize=6)
    fig.suptitle("Success maps against the plant's time step (green: caught)",
                 fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
