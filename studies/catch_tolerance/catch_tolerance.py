"""How far off the palm may wait and still catch, against the flight
predictor's error.

    .venv/bin/python studies/catch_tolerance/catch_tolerance.py
        [--objects holdout-… …] [--library F [F …]] [--step-mm 10]
        [--reach-mm 40] [--workers 2]
        [--maps DIR --map-step-ms X --scenario F]
        [--out studies/catch_tolerance/catch_tolerance]

For each object: the watching throw and its plan (the palm's grasp pose
X_WG); the object's learned cell (from the watch-first regrasp library that
`regrasp-drake table1 --library F` writes; the first of the files given that
has the object; by default the shipped network's, in
models/results/library_holdout.yaml and library_table1.yaml); then one
catching throw per offset of the palm in its own plane (x across the
object's axis, y along it; a square grid of --step-mm up to ±--reach-mm),
everything else as learned. The object's catch tolerance is the largest
radius r (on the grid) such that every offset within r catches: the error
the hand absorbs, as the simulated sensors judge it. Beside it: the flight
predictor's error for that object, the offset of the palm planned from the
predicted flight from the palm planned from the watched one, in the same
palm frame.

Writes <out>.jsonl (one line per throw, as it finishes; a rerun resumes),
<out>.json (per object: tolerance, predictor offset, inside or not) and
<out>.png (each object's grid, the predictor's offset marked).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

_HELD_OUT = ["holdout-dumbbell-d150", "holdout-dumbbell-d300",
             "holdout-mallet-d120", "holdout-mallet-d280",
             "holdout-scraper-d330"]


_SETUPS = {}  # per worker process: the watch and plan are made once


def _setup(name, library):
    """(scenario, object, ik, the watched plan, the learned parameters).
    `library`: a regrasp library's path, or ("cell", h_catch, h_down,
    scenario path or None) for a cell taken from a map."""
    if (name, library) not in _SETUPS:
        _SETUPS[(name, library)] = _make_setup(name, library)
    return _SETUPS[(name, library)]


def _make_setup(name, library):
    import torch

    from regrasp_drake.learning.library import lookup
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import load_scenario
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    from_map = isinstance(library, tuple)
    scenario = load_scenario(library[3] if from_map else None)
    obj = resolve_object(name=name)
    ik = ArmIk()
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    if from_map:
        return scenario, obj, ik, plan, (library[1], library[2])
    entry = lookup(library, name)
    return scenario, obj, ik, plan, (entry.h_catch, entry.h_down)


def robust_cell(map_path: Path) -> tuple[float, float]:
    """(h_catch, h_down) of a map's caught cell with the most caught cells
    in its 3x3 block (ties: the first in the map's order): where a learner
    that had seen the whole map would put the hand."""
    from regrasp_drake.grid import read_rows
    rows = read_rows(map_path)
    caught = {tuple(cell): row["outcome"] == "caught"
              for cell, row in rows.items()}
    best = max((sum(caught.get((i + di, j + dj), False)
                    for di in (-1, 0, 1) for dj in (-1, 0, 1)), -i, -j)
               for (i, j), ok in caught.items() if ok)
    row = rows[(-best[1], -best[2])]
    return float(row["h_catch"]), float(row["h_down"])


def _offset_throw(task):
    name, library, dx_mm, dy_mm = task
    from pydrake.math import RigidTransform

    from regrasp_drake.station.episode import run_episode
    scenario, obj, ik, plan, parameters = _setup(name, library)
    X_WG = plan.X_WG @ RigidTransform([dx_mm / 1e3, dy_mm / 1e3, 0.0])
    result = run_episode(scenario, obj, ik=ik, X_WG=X_WG,
                         catch_parameters=parameters)
    return {"object": name, "dx_mm": dx_mm, "dy_mm": dy_mm,
            "h_catch": parameters[0], "h_down": parameters[1],
            "outcome": result.outcome, "message": result.message,
            "drop_reason": result.drop_reason, "touching": result.touching,
            "held_by_contact": result.held_by_contact}


def _key(row) -> tuple:
    return row["object"], row["dx_mm"], row["dy_mm"]


def predictor_offset(name, library) -> dict:
    """The palm planned from the predicted flight, relative to the palm
    planned from the watched flight, in the latter's frame (mm, degrees)."""
    from regrasp_drake.learning.flight_predictor import FlightPredictor
    from regrasp_drake.paths import MODELS_DIR
    from regrasp_drake.throw_catch import plan_catch
    scenario, obj, ik, plan, _ = _setup(name, library)
    predictor = FlightPredictor.load(MODELS_DIR / "flight_predictor.json")
    predicted = plan_catch(scenario, obj, ik,
                           predictor.as_watched(obj, scenario))
    X_GP = plan.X_WG.inverse() @ predicted.X_WG
    d = X_GP.translation() * 1e3
    angle = float(np.degrees(X_GP.rotation().ToAngleAxis().angle()))
    return {"dx_mm": round(float(d[0]), 1), "dy_mm": round(float(d[1]), 1),
            "dz_mm": round(float(d[2]), 1), "rotation_deg": round(angle, 1),
            "dt_ms": round((predicted.catch_point.t_s
                            - plan.catch_point.t_s) * 1e3, 1)}


def tolerance_mm(rows) -> float | None:
    """The largest grid radius within which every offset caught (None: the
    learned pose itself did not catch)."""
    radii = sorted({float(np.hypot(r["dx_mm"], r["dy_mm"])) for r in rows})
    best = None
    for radius in radii:
        inside = [r for r in rows
                  if np.hypot(r["dx_mm"], r["dy_mm"]) <= radius + 1e-9]
        if any(r["outcome"] != "caught" for r in inside):
            break
        best = radius
    return best


def main() -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=_HELD_OUT)
    results = Path(__file__).parents[2] / "models" / "results"
    parser.add_argument("--library", type=Path, nargs="+",
                        default=[results / "library_holdout.yaml",
                                 results / "library_table1.yaml"])
    parser.add_argument("--maps", type=Path,
                        help="instead of --library: the cell of each object "
                        "is its map's most robust one (`robust_cell`), from "
                        "<maps>/<object>_<--map-step-ms>ms.jsonl (as "
                        "studies/timestep_convergence/timestep_study.py "
                        "writes them), the throw that of --scenario")
    parser.add_argument("--map-step-ms", type=float, default=1.0)
    parser.add_argument("--scenario", type=Path,
                        help="with --maps: the scenario (default: shipped)")
    parser.add_argument("--step-mm", type=int, default=10)
    parser.add_argument("--reach-mm", type=int, default=40)
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path,
                        default=Path(__file__).with_suffix(""))
    args = parser.parse_args()
    if args.step_mm <= 0 or args.reach_mm < 0:
        print(f"catch_tolerance: error: --step-mm {args.step_mm}, --reach-mm "
              f"{args.reach_mm}: expected a step > 0 and a reach >= 0",
              file=sys.stderr)
        return 2
    library = {}
    if args.maps:
        for name in args.objects:
            path = args.maps / f"{name}_{args.map_step_ms:g}ms.jsonl"
            if not path.is_file():
                print(f"catch_tolerance: error: --maps: no map {path}",
                      file=sys.stderr)
                return 2
            library[name] = ("cell", *robust_cell(path),
                             str(args.scenario) if args.scenario else None)
    from regrasp_drake.learning.library import load_library
    for name in [] if args.maps else args.objects:
        library[name] = next((str(p) for p in args.library
                              if name in load_library(p)), None)
        if library[name] is None:
            print(f"catch_tolerance: error: --library: nothing learned for "
                  f"{name} in {', '.join(map(str, args.library))} (run "
                  "`regrasp-drake table1 --library F` first)",
                  file=sys.stderr)
            return 2
    offsets = range(-args.reach_mm, args.reach_mm + 1, args.step_mm)
    from regrasp_drake.grid import append_rows, read_rows
    lines = args.out.with_suffix(".jsonl")
    done = read_rows(lines, key=_key)
    tasks = [(name, library[name], dx, dy) for name in args.objects
             for dx in offsets for dy in offsets
             if (name, dx, dy) not in done]
    append_rows(_offset_throw, tasks, lines, done, _key, workers=args.workers,
                label="catch tolerance", unit="throws")
    summary = {"step_mm": args.step_mm, "reach_mm": args.reach_mm,
               "objects": {}}
    for name in args.objects:
        rows = [done[(name, dx, dy)] for dx in offsets for dy in offsets]
        tolerance = tolerance_mm(rows)
        # The flight predictor is the finger throw's: no offset for a map's.
        offset = (predictor_offset(name, library[name]) if not args.maps
                  else {"dx_mm": 0.0, "dy_mm": 0.0, "dz_mm": 0.0,
                        "rotation_deg": 0.0, "dt_ms": 0.0})
        planar = float(np.hypot(offset["dx_mm"], offset["dy_mm"]))
        summary["objects"][name] = {
            "h_catch": rows[0]["h_catch"], "h_down": rows[0]["h_down"],
            "tolerance_mm": None if tolerance is None else round(tolerance, 1),
            "caught_offsets": sum(r["outcome"] == "caught" for r in rows),
            "offsets": len(rows),
            "predictor_offset": offset,
            "predictor_planar_offset_mm": round(planar, 1),
            "inside": tolerance is not None and planar <= tolerance}
    args.out.with_suffix(".json").write_text(
        json.dumps(summary, indent=1) + "\n")
    print(json.dumps(summary, indent=1))
    _plot(summary, done, offsets, args.out.with_suffix(".png"))
    return 0


def _plot(summary, done, offsets, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    names = list(summary["objects"])
    lim = 10 + max([max(offsets)] + [
        max(abs(o["predictor_offset"]["dx_mm"]), abs(o["predictor_offset"]["dy_mm"]))
        for o in summary["objects"].values()])
    fig, axes = plt.subplots(1, len(names), figsize=(3.2 * len(names), 3.4),
                             squeeze=False)
    for ax, name in zip(axes[0], names):
        s = summary["objects"][name]
        step = offsets.step
        for dx in offsets:
            for dy in offsets:
                caught = done[(name, dx, dy)]["outcome"] == "caught"
                ax.add_patch(plt.Rectangle(
                    (dx - 0.4 * step, dy - 0.4 * step), 0.8 * step, 0.8 * step,
                    color="tab:green" if caught else "lightgray"))
        if s["tolerance_mm"]:
            ax.add_patch(plt.Circle((0, 0), s["tolerance_mm"], fill=False,
                                    color="tab:green"))
        p = s["predictor_offset"]
        ax.plot(p["dx_mm"], p["dy_mm"], "rx", ms=10, mew=2)
        tolerance = ("none" if s["tolerance_mm"] is None
                     else f"{s['tolerance_mm']:.0f} mm")
        ax.set_title(f"{name}\ntolerance {tolerance}, predictor "
                     f"{s['predictor_planar_offset_mm']:.0f} mm", fontsize=8)
        ax.set_xlabel("palm x offset (mm)", fontsize=8)
        ax.set_ylabel("palm y offset (mm)", fontsize=8)
        ax.set_aspect("equal")
        ax.set_xlim(-lim, lim)
        ax.set_ylim(-lim, lim)
    fig.suptitle("Palm offsets that still catch (green); the flight "
                 "predictor's offset (red x)", fontsize=9)
    fig.tight_layout()
    fig.savefig(path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
