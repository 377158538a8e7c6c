"""Regrasp to a chosen grasp: throws to a catch in the target grasp, per
target, watching first and on the first throw, and the achieved grasp's
error.

    .venv/bin/python benchmarks/regrasp_targets.py [--objects NAME ...]
        [--targets keep:0 flip:30 ...] [--modes watch first-throw]
        [--max-throws N] [--out models/results/regrasp_targets]

Each (object, target, mode) is the learning phase of `regrasp-drake
regrasp` (the shipped network picks the first cell, the wavefront search
the next ones, a throw held off the target's offset moves the palm; with
--offset-prior the palm starts against the prior's slide; success = held in
the target grasp), capped at --max-throws throws. Rows go to <out>.jsonl as they
finish (a rerun resumes, refusing rows of another scenario); the summary
per target to <out>.json and is printed. Default: Table 1's five objects
and the six held-out ones, the six targets keep/flip at -30, 0, +30 mm (an
offset out of an object's reach is recorded as refused), both modes. With
--rehearse, a pair refused after its rehearsal (no cell lands anywhere and
no closing holds it at rest: learning_phase.Unholdable) is recorded as
stopped "unholdable" and counted as a miss.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import copy
import json
import sys
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io, scenario_args
from regrasp_drake.grid import append_rows
from regrasp_drake.map_rows import read_rows
from regrasp_drake.errors import InputError
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import (
    NoCatchPoint,
    Unholdable,
    learn,
)
from regrasp_drake.learning.offset_prior import OffsetPrior
from regrasp_drake.learning.planner import PAPER_NETWORK
from regrasp_drake.learning.rehearsal import rehearsal_scenario
from regrasp_drake.learning.table1 import object_names
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning import grasp
from regrasp_drake.planning.grasp import Target, check_reachable, miss_reason
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import (
    ThrowNoise,
    scenario_digest,
    with_target,
)
from regrasp_drake.throw_catch import planned_grasp
from regrasp_drake.world.objects import load_catalogue, resolve_object

DEFAULT_TARGETS = [f"{kind}:{offset}" for kind in ("keep", "flip")
                   for offset in (-30, 0, 30)]


def run_one(scenario, obj, model, ik, mode, max_throws, predictor,
            offset_prior, planner=None, rehearse=False,
            rehearsed=None) -> dict:
    try:
        check_reachable(Target(scenario.regrasp.target,
                               scenario.regrasp.offset_mm), obj)
    except InputError as e:
        return {"stopped": "refused", "error": str(e), "success": False,
                "caught": False, "throws": 0}
    try:
        result = learn(scenario, obj, model, ik=ik, max_throws=max_throws,
                       progress=None, offset_prior=offset_prior,
                       flight_predictor=predictor if mode == "first-throw"
                       else None, planner=planner, rehearse=rehearse,
                       rehearsed=rehearsed)
    except Unholdable as e:  # refused after the rehearsal: a miss, counted
        return {"stopped": "unholdable", "error": str(e), "success": False,
                "caught": False, "throws": e.throws}
    except (NoCatchPoint, InputError) as e:
        return {"stopped": "no_catch_point", "error": str(e),
                "success": False, "caught": False,
                "throws": getattr(e, "throws", 1)}
    d = result.as_dict()
    # The landing model's prediction before the first catching throw: the
    # grasp the plan's palm holds the object in as it is at the catch point
    # (studies/landing: it rests where it first touches).
    predicted = planned_grasp(scenario, obj, result.plan.catch_point,
                              result.plan.X_WG)
    return {k: d[k] for k in ("success", "caught", "throws", "stopped",
                              "start_grasp", "achieved_grasp", "grasp_error",
                              "wall_s", "planner")} | {
        "start_cell": d["prediction"]["start_cell"],
        "attempts": [a["outcome"] for a in d["attempts"]],
        "chosen_by": [a["chosen_by"] for a in d["attempts"]],
        "rehearsal": d.get("rehearsal"),
        "predicted_grasp": predicted.as_dict()}


_MODELS = {}


def _job(task) -> dict:
    """One (object, target, mode, trial) row, in a worker process: the
    shipped network, flight predictor and offset prior loaded once per
    process."""
    (scenario, target, name, mode, level, trial, max_throws,
     use_prior, paper, rehearse, rehearsed) = task
    torch.set_num_threads(1)
    if not _MODELS:
        _MODELS["model"] = load_weights(MODELS_DIR / scenario.catch.weights)[0]
        _MODELS["predictor"] = FlightPredictor.load(
            MODELS_DIR / "flight_predictor.json")
        _MODELS["prior"] = (OffsetPrior.load(MODELS_DIR / "offset_prior.json")
                            if use_prior else None)
        _MODELS["ik"] = ArmIk(scenario.directives)
    return {"object": name, "target": target.as_dict(), "mode": mode,
            "level": level, "trial": trial,
            "scenario_digest": scenario_digest(scenario),
            "planners": ("paper" if paper else "shipped")
            + ("+rehearsal" if rehearse else ""),
            "rehearsal_replayed": rehearsed is not None,
            "rehearsal_digest": (scenario_digest(rehearsal_scenario(scenario))
                                 if rehearse else None)} | run_one(
        scenario, resolve_object(name=name), _MODELS["model"], _MODELS["ik"],
        mode, max_throws, _MODELS["predictor"], _MODELS["prior"],
        PAPER_NETWORK if paper else None, rehearse, rehearsed)


def pair_key(r: dict) -> tuple:
    """A row's (object, target kind, offset, mode), for --rehearsal-from."""
    return (r["object"], r["target"]["kind"], r["target"]["offset_mm"],
            r["mode"])


def row_key(r: dict) -> tuple:
    """A row's pair (pair_key), noise level and trial."""
    return pair_key(r) + (r.get("level", 0.0), r.get("trial", 0))


def landing(rows: list[dict]) -> dict:
    """How the reachable rows in `rows` ended: the share in the target grasp;
    of those held the right way round (the axis within 90° of the target's
    direction, the side right), the median |offset error| and tilt; and
    each miss by its reason."""
    done = [r for r in rows if r["stopped"] != "refused"]
    ok = [r for r in done if r["success"]]
    misses = dict.fromkeys(("no_catch_point", "unholdable",
                            *grasp.MISS_REASONS), 0)
    right = []
    for r in done:
        if r["stopped"] in ("no_catch_point", "unholdable"):
            misses[r["stopped"]] += not r["success"]
            continue
        reason = miss_reason(r.get("caught", False), r.get("grasp_error"))
        if reason is not None and not r["success"]:
            misses[reason] += 1
        if reason not in ("dropped", "wrong_way_round") and r["caught"]:
            right.append(r)

    def median(values):
        return round(float(np.median(values)), 2) if values else None

    predicted = [r for r in right if r.get("predicted_grasp")]
    return {
        "pairs": len(rows), "refused": len(rows) - len(done),
        "in_target": len(ok),
        "share_in_target": round(len(ok) / len(done), 3) if done else None,
        "held_right_way_round": len(right),
        "median_abs_offset_error_mm": median(
            [abs(r["grasp_error"]["offset_error_mm"]) for r in right]),
        "median_tilt_deg": median(
            [r["grasp_error"]["axis_error_deg"] for r in right]),
        "misses": misses,
        # The landing model against the grasp achieved, of those held the
        # right way round.
        "median_abs_predicted_offset_error_mm": median(
            [abs(r["predicted_grasp"]["offset_mm"]
                 - r["achieved_grasp"]["offset_mm"]) for r in predicted]),
        "median_abs_predicted_tilt_error_deg": median(
            [abs(r["predicted_grasp"]["tilt_deg"]
                 - r["achieved_grasp"]["tilt_deg"]) for r in predicted])}


def summarize(rows: list[dict], targets, modes, level: float) -> dict:
    """Per target and mode: the throws each object took (None: not in the
    target grasp), and `landing`'s figures; under "all", `landing`'s over
    every target."""
    out = {}
    for target in targets:
        key = f"{target.kind}:{target.offset_mm:+.0f}"
        out[key] = {}
        for mode in modes:
            mine = [r for r in rows if r["target"] == target.as_dict()
                    and r["mode"] == mode and r.get("level", 0.0) == level]
            ok = [r for r in mine if r["success"]]
            errors = [r["grasp_error"] for r in ok]
            out[key][mode] = landing(mine) | {
                "throws": {f"{r['object']}#{r.get('trial', 0)}":
                           (r["throws"] if r["success"] else None)
                           for r in mine},
                "on_first_catching_throw": sum(
                    r["throws"] == (2 if mode == "watch" else 1) for r in ok),
                "max_offset_error_mm": max(
                    (abs(e["offset_error_mm"]) for e in errors), default=None),
                "max_axis_error_deg": max(
                    (e["axis_error_deg"] for e in errors), default=None),
            }
    wanted = {t.as_dict()["kind"] + str(t.as_dict()["offset_mm"])
              for t in targets}
    out["all"] = {mode: landing([
        r for r in rows if r["mode"] == mode and r.get("level", 0.0) == level
        and r["target"]["kind"] + str(r["target"]["offset_mm"]) in wanted])
        for mode in modes}
    return out


def noisy(scenario, level: float, trial: int):
    """`scenario` with release noise of `level` (noise_curve.py's levels),
    seeded by the trial; unchanged at level 0."""
    if not level:
        return scenario
    out = copy.deepcopy(scenario)
    out.throw.noise = ThrowNoise.at_level(level, seed=trial)
    return out


def object_list(names) -> list[str]:
    """`names`, or Table 1's five and the held-out objects."""
    if names:
        return names
    return object_names() + [o.name for o in load_catalogue().values()
                             if o.set == "holdout"]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--objects", nargs="+")
    parser.add_argument("--targets", nargs="+", default=DEFAULT_TARGETS)
    parser.add_argument("--modes", nargs="+", default=["watch", "first-throw"],
                        choices=("watch", "first-throw"))
    parser.add_argument("--max-throws", type=int, default=8)
    parser.add_argument("--offset-prior", action="store_true",
                        help="the palm against models/offset_prior.json's "
                             "slide from the first throw (default: at the "
                             "target's offset, as the command line)")
    parser.add_argument("--paper-network", action="store_true",
                        help="start every search from the paper network's "
                             "cell (default: the target's shipped planner, "
                             "models/planner_<target>.json's winner)")
    parser.add_argument("--noise-level", type=float, default=0.0,
                        help="release noise as benchmarks/noise_curve.py's "
                             "level k: release time std k x 2 ms, joint "
                             "velocities k x 0.03 rad/s (default 0)")
    parser.add_argument("--trials", type=int, default=1,
                        help="noise seeds per (object, target, mode)")
    parser.add_argument("--rehearse", action="store_true",
                        help="the first catch is rehearsed at a lattice of "
                             "cells in each catch mode (learning/rehearsal.py's "
                             "MODES) and places before the throw and "
                             "starts from the cell with the most margin")
    parser.add_argument("--rehearsal-from", type=Path, metavar="ROWS",
                        help="with --rehearse: replay each pair's rehearsal "
                             "from the rows of a run without release noise "
                             "(a .jsonl of this script) instead of "
                             "rehearsing again: the rehearsal sees neither "
                             "the release noise nor the judged steps")
    parser.add_argument("--workers", type=int, default=1,
                        help="episodes run side by side in forked processes "
                             "(default 1)")
    parser.add_argument("--out", type=Path,
                        default=MODELS_DIR / "results" / "regrasp_targets")
    scenario_args.add(parser, target=False)
    args = parser.parse_args(argv)
    torch.set_num_threads(1)
    least_throws = 2 if "watch" in args.modes else 1
    try:
        for flag, value, least in (("--workers", args.workers, 1),
                                   ("--trials", args.trials, 1),
                                   ("--max-throws", args.max_throws,
                                    least_throws)):
            if value < least:
                raise InputError(f"{flag}: got {value}, expected an integer "
                                 f">= {least}")
        targets = [Target.parse(t) for t in args.targets]
        base, _ = scenario_args.load(args)
        if args.rehearsal_from is not None and not args.rehearse:
            raise InputError(f"--rehearsal-from: got {args.rehearsal_from} "
                             "without --rehearse, expected it with "
                             "--rehearse")
        recorded = ({} if args.rehearsal_from is None
                    else read_rows(args.rehearsal_from, key=row_key))
    except InputError as e:
        print(f"regrasp_targets: error: {e}", file=sys.stderr)
        return 2
    rows_path = args.out.with_suffix(".jsonl")

    def rehearsed(scenario, key):
        """The rehearsal recorded for the pair `key` without release noise
        under `scenario` (None: rehearse)."""
        if args.rehearsal_from is None:
            return None
        row = recorded.get(key + (0.0, 0))
        if row is None:
            raise InputError(f"--rehearsal-from: {args.rehearsal_from} has "
                             f"no row {key} at noise level 0, expected one "
                             "per pair run")
        # What the rehearsal simulates (rehearsal_scenario: the shipped
        # steps, no noise) must match; rows without its digest, the whole
        # scenario but for the noise.
        if (row["rehearsal_digest"] != scenario_digest(
                rehearsal_scenario(scenario))
                if row.get("rehearsal_digest") is not None
                else row["scenario_digest"] != scenario_digest(scenario)):
            raise InputError(f"--rehearsal-from: row {key} of "
                             f"{args.rehearsal_from} was rehearsed under "
                             "another scenario, expected this run's (the "
                             "judged steps and the release noise may "
                             "differ)")
        # (None where the pair stopped before its rehearsal: refused as out
        # of reach, or no catch point; it stops there again.)
        return row.get("rehearsal")

    done = read_rows(rows_path, key=row_key)
    jobs = []
    for target, name, mode, trial in [
            (target, name, mode, trial) for target in targets
            for name in object_list(args.objects) for mode in args.modes
            for trial in range(args.trials)]:
        clean = with_target(base, target)
        scenario = noisy(clean, args.noise_level, trial)
        key = (name, target.kind, target.offset_mm, mode, args.noise_level,
               trial)
        if key not in done:
            try:
                replayed = rehearsed(clean, (name, target.kind,
                                             target.offset_mm, mode))
            except InputError as e:
                print(f"regrasp_targets: error: {e}", file=sys.stderr)
                return 2
            jobs.append((scenario, target, name, mode, args.noise_level,
                         trial, args.max_throws, args.offset_prior,
                         args.paper_network, args.rehearse, replayed))
        elif done[key]["scenario_digest"] != scenario_digest(scenario):
            raise SystemExit(f"{rows_path}: row {key} was made under "
                             "another scenario; move the file away to "
                             "start again")
        elif done[key].get("planners", "paper") != (
                ("paper" if args.paper_network else "shipped")
                + ("+rehearsal" if args.rehearse else "")):
            raise SystemExit(f"{rows_path}: row {key} was made with other "
                             "planners (--paper-network); move the file "
                             "away to start again")

    # Each job is deterministic on its own: forked workers give the same
    # rows as a serial run, in the jobs' order.
    append_rows(_job, jobs, rows_path, done, row_key,
                workers=args.workers, label="regrasp targets",
                unit="episodes")
    rows = list(done.values())
    summary = summarize(rows, targets, args.modes, args.noise_level)
    atomic_io.write_json(args.out.with_suffix(".json"), summary)
    print(json.dumps(summary, indent=1))
    return 0


if __name__ == "__main__":
    sys.exit(main())
