"""Is the palm toss converged in the plant's time step? For every object of
the catalogue (training, Table 1 and held-out sets), the watching throw at
the scenario's step and at a finer one (default 4x finer), side by side.

    .venv/bin/python benchmarks/release_convergence.py
        [--scenario F] [--scenario-name NAME] [--scenario-text YAML]
        [--fine-step-s S | --fine-scenario-text YAML]
        [--objects NAME ...] [--workers 1] [--out out/release_convergence]

The scenario: by default the shipped one (the throw at 0.25 ms, the flight
from the release time at its catch step, 1 ms; --scenario-name Fast for
1 ms throughout; studies/palm_toss/FINDINGS.md). A finer --fine-step-s
refines the throw only; to refine the flight too, give both steps:
--fine-scenario-text '{plant_config: {time_step: 0.0000625},
catch_time_step_s: 0.00025}'.

--scenario-text overrides fields of the scenario for both settings;
--fine-scenario-text makes the fine setting the scenario with these fields
overridden instead of a finer step: a tighter CENIC accuracy, say
(studies/cenic/FINDINGS.md):

    --scenario-text '{plant_config: {time_step: 0}, catch_time_step_s: null,
        simulator_config: {integration_scheme: cenic, accuracy: 1e-3}}'
    --fine-scenario-text '{simulator_config: {accuracy: 1e-4}}'

Per object and step: the object's state in free flight at the end of the
throw (after it has left the palm: the palm toss's release is over), its
angular velocity w_WO (rad/s), velocity v_WO (m/s) and position p_WO (m);
and the planned catch point (the moment the axis is horizontal, its
position). Printed: each object's differences between the two steps, then
how many objects meet the targets of issue 26: spin within 0.05 rad/s,
velocity within 10 mm/s, catch point within 10 mm, catch moment within
4 ms. Rows are appended to OUT/rows.jsonl as they finish (a killed run
resumes); the summary goes to OUT/summary.json.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import json
import sys
from pathlib import Path

import numpy as np

from regrasp_drake import atomic_io, scenario_args
from regrasp_drake.convergence import release_differences
from regrasp_drake.errors import InputError, check_output_path
from regrasp_drake.grid import append_rows, read_rows
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.episode.episode import release_time
from regrasp_drake.station.scenario import with_time_step
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import load_catalogue

TARGETS = {"spin_rad_per_s": 0.05, "velocity_mm_per_s": 10.0,
           "catch_point_mm": 10.0, "catch_moment_ms": 4.0}


def throw_at(scenario, obj, ik) -> dict:
    """The watching throw's state at the end of the throw and its plan."""
    watched = watch(scenario, obj, ik)
    t, x = watched.logs.t, watched.logs.object_state
    k = int(np.searchsorted(t, release_time(scenario) - 1e-9))
    row = {"t_s": float(t[k]), "w_WO": x[7:10, k].tolist(),
           "v_WO": x[10:13, k].tolist(), "p_WO": x[4:7, k].tolist(),
           "catch_t_s": None, "catch_p_WO": None, "plan_error": None,
           "wall_s": watched.wall_s}
    try:
        point = plan_catch(scenario, obj, ik, watched).catch_point
        row["catch_t_s"] = point.t_s
        row["catch_p_WO"] = point.p_WO.tolist()
    except InputError as e:
        row["plan_error"] = str(e)
    return row


def settings(args, fine_step, fine_text):
    """The (coarse, fine) scenarios: the scenario of `args`' options
    (--scenario, --scenario-name, --scenario-text), and that with
    `fine_text` over it too, or at `fine_step` [s]."""
    coarse, _ = scenario_args.load(args)
    if fine_text is None:
        return coarse, with_time_step(coarse, fine_step)
    return coarse, scenario_args.load(args, over=fine_text)[0]


def describe(scenario) -> dict:
    """The setting that differs between the two runs."""
    c = scenario.simulator_config
    return {"time_step_s": scenario.time_step_s,
            "integration_scheme": c.integration_scheme,
            "accuracy": c.accuracy}


def _task(args) -> dict:
    name, scenario, fine_scenario = args
    obj = load_catalogue()[name]
    ik = ArmIk()
    coarse_row = throw_at(scenario, obj, ik)
    fine_row = throw_at(fine_scenario, obj, ik)
    return {"object": name, "set": obj.set, "geometry": obj.geometry,
            "steps_s": [scenario.time_step_s, fine_scenario.time_step_s],
            "settings": [describe(scenario), describe(fine_scenario)],
            "coarse": coarse_row, "fine": fine_row, **release_differences(
                coarse_row, fine_row)}


def summarize(rows: list[dict]) -> dict:
    summary = {"objects": len(rows),
               "planned_at_both": sum(r["catch_point_mm"] is not None
                                      for r in rows),
               "targets": TARGETS}
    for key, limit in TARGETS.items():
        values = [r[key] for r in rows if r[key] is not None]
        summary[key] = {
            "median": round(float(np.median(values)), 4) if values else None,
            "max": round(float(np.max(values)), 4) if values else None,
            "within_target": sum(v <= limit for v in values),
            "worst": max(rows, key=lambda r: -1 if r[key] is None
                         else r[key])["object"]}
    summary["all_within_targets"] = sum(
        all(r[k] is not None and r[k] <= v for k, v in TARGETS.items())
        for r in rows)
    return summary


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    scenario_args.add(parser, target=False)  # the text: both settings
    parser.add_argument("--fine-step-s", type=float, default=None,
                        help="default: the scenario's step / 4")
    parser.add_argument("--fine-scenario-text", default=None,
                        help="the fine setting: these YAML fields over the "
                        "scenario's (instead of a finer step)")
    parser.add_argument("--objects", nargs="+", default=None)
    parser.add_argument("--workers", type=int, default=1)
    parser.add_argument("--out", type=Path,
                        default=Path("out/release_convergence"))
    return _run(parser.parse_args(argv))


def _run(args) -> int:
    try:
        if args.fine_step_s is not None and args.fine_scenario_text:
            raise InputError("--fine-step-s and --fine-scenario-text: "
                             "give one of them, not both")
        scenario, _ = scenario_args.load(args)
        fine = args.fine_step_s or scenario.time_step_s / 4
        scenario, fine_scenario = settings(args, fine,
                                           args.fine_scenario_text)
        catalogue = load_catalogue()
        names = args.objects or list(catalogue)
        for name in names:
            if name not in catalogue:
                raise InputError(f"--objects: got {name!r}, expected a "
                                 "catalogue object")
        args.out.mkdir(parents=True, exist_ok=True)
        check_output_path("--out", args.out / "rows.jsonl")
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    rows_path = args.out / "rows.jsonl"
    try:
        done = read_rows(rows_path, key=lambda r: r["object"])
    except InputError as e:
        print(f"error: {e}", file=sys.stderr)
        return 2
    todo = [(n, scenario, fine_scenario) for n in names if n not in done]
    if todo:
        append_rows(_task, todo, rows_path, done, lambda r: r["object"],
                    workers=args.workers, label="objects", unit="object")
    rows = [done[n] for n in names]
    print(f"{'object':24s} {'dw rad/s':>9s} {'dv mm/s':>8s} "
          f"{'dp mm':>7s} {'catch mm':>9s} {'catch ms':>9s}")
    for r in rows:
        cp = ("no plan" if r["catch_point_mm"] is None
              else f"{r['catch_point_mm']:9.2f} {r['catch_moment_ms']:9.2f}")
        print(f"{r['object']:24s} {r['spin_rad_per_s']:9.4f} "
              f"{r['velocity_mm_per_s']:8.2f} {r['position_mm']:7.2f} {cp}")
    summary = summarize(rows)
    summary["steps_s"] = [scenario.time_step_s, fine_scenario.time_step_s]
    summary["settings"] = [describe(scenario), describe(fine_scenario)]
    summary["wall_s"] = [round(sum(r[k]["wall_s"] for r in rows), 2)
                         for k in ("coarse", "fine")]
    atomic_io.write_json((args.out / "summary.json"), summary)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
