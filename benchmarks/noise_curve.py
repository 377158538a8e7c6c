"""Catch rate against release noise, watching first, in first-throw mode and at release.

    .venv/bin/python benchmarks/noise_curve.py [--objects table1-row1 …]
        [--levels 0 0.25 0.5 1 2 4] [--trials 12] [--workers 2]
        [--scenario F] [--scenario-name NAME]
        [--library models/results/library_table1.yaml]
        [--first-throw-library models/results/library_table1_ft.yaml]
        [--at-release-library models/results/library_table1_ar.yaml]
        [--modes watch first-throw at-release watch-uncorrected
                 first-throw-uncorrected]
        [--flight-model models/flight_predictor.json]
        [--out out/noise_curve/noise_curve]

Noise level k (a number ≥ 0) perturbs every throw (scenario throw.noise):
the release time with a standard deviation of k × 2 ms and each arm joint's
velocity at the release with k × 0.03 rad/s, seeded by (trial, throw
number), so every figure is reproducible.

Each object's parameters are the ones its learning phase found without
noise (the regrasp library files that `regrasp-drake table1 --library …`,
with `--first-throw` and with `--at-release`, write; those of the shipped
network are in models/results/library_table1*.yaml). The scenario (default:
the shipped one) is that of the libraries' learning phase. A trial:
  watch (watch-then-catch): a noisy watching throw, the catch planned from
      it, then a noisy catching throw (a different perturbation) with those
      parameters, which corrects the watched plan at its own release
      (`throw_catch.release_correction`: the palm moved by the difference
      between the plans from the two releases, propagated in free flight);
  watch-uncorrected: the same without that correction (the design before
      it; not in the default modes);
  first-throw: no watching throw: one noisy catching throw at the plan of
      the predicted flight (--flight-model, from the object's features),
      with the cell the first-throw learning phase found (after a replan,
      too: the cell is what the phase learned, the plan is the predicted
      one), which corrects the predicted plan at its own release as the
      watching mode does (the reference is the predictor's state then);
  first-throw-uncorrected: the same without that correction (the design
      before it; not in the default modes).
  at-release: no watching throw: one noisy catching throw whose catch is
      planned when it releases the object, from the object's state seen
      then (`learn --at-release`), with the parameters that mode learned.
Writes <out>.jsonl (one line per trial, as it finishes, with the scenario's
digest and the cell; a rerun resumes them, and refuses an output holding
trials of another scenario or at another cell than the libraries': that
needs another --out),
<out>.json (catch rate per mode and level, with its 95 % Wilson interval and
every outcome's count) and <out>.png (the curves, the intervals as bars).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import dataclasses as dc
import json
import math
import sys
import time
from collections import Counter
from pathlib import Path
from regrasp_drake import atomic_io

from regrasp_drake import scenario_args
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.station.scenario import ThrowNoise

_MODES = ("watch", "first-throw", "at-release", "watch-uncorrected",
          "first-throw-uncorrected")
RESULTS = MODELS_DIR / "results"


def wilson_interval(caught: int, trials: int, z: float = 1.96):
    """The 95 % Wilson score interval of a catch rate, (low, high)."""
    if trials == 0:
        return None
    p = caught / trials
    centre = (p + z * z / (2 * trials)) / (1 + z * z / trials)
    half = (z / (1 + z * z / trials)) * math.sqrt(
        p * (1 - p) / trials + z * z / (4 * trials * trials))
    return max(0.0, centre - half), min(1.0, centre + half)


def _scenario(level, trial, scenario):
    noise = ThrowNoise.at_level(level, seed=trial)
    return dc.replace(scenario, throw=dc.replace(scenario.throw, noise=noise))


def _base_digest(scenario) -> str:
    """The digest of the scenario the trials perturb (without the noise)."""
    from regrasp_drake.station.scenario import scenario_digest
    return scenario_digest(scenario)


def _foreign_rows(done: dict, cells: dict, digest: str) -> str | None:
    """Why rows already in the output cannot be resumed, or None: a row of
    another scenario (or one written before rows carried it), or at another
    cell than the library's for its mode and object."""
    for (mode, name, *_), row in done.items():
        if row.get("scenario") != digest:
            return (f"a trial of {name} ({mode}) made under scenario "
                    f"{row.get('scenario')}, not this one ({digest})")
        cell = cells.get((mode, name))
        if cell is not None and (row["h_catch"], row["h_down"]) != cell:
            return (f"a trial of {name} ({mode}) at ({row['h_catch']}, "
                    f"{row['h_down']}) m, where the library's cell is "
                    f"({cell[0]}, {cell[1]}) m")
    return None


def _key(row) -> tuple:
    return row["mode"], row["object"], row["level"], row["trial"]


def _trial(task):
    mode, name, level, trial, library, base, flight_model = task
    import torch

    from regrasp_drake.episode.episode import run_episode
    from regrasp_drake.errors import InputError
    from regrasp_drake.learning.flight_predictor import FlightPredictor
    from regrasp_drake.learning.library import lookup
    from regrasp_drake.planning.free_flight import flight_from_release
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.throw_catch import (
        ReleaseCorrection,
        plan_catch,
        plan_watched,
        release_correction,
    )
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    scenario = _scenario(level, trial, base)
    obj = resolve_object(name=name)
    ik = ArmIk()
    entry = lookup(library, name)
    row = {"mode": mode, "object": name, "level": level, "trial": trial,
           "h_catch": entry.h_catch, "h_down": entry.h_down,
           "scenario": _base_digest(base)}
    parameters = (entry.h_catch, entry.h_down)

    def at_release(state, t):
        flight = flight_from_release(state, t, obj, scenario)
        return plan_catch(scenario, obj, ik, flight).X_WG, parameters

    t0 = time.perf_counter()
    correction = ReleaseCorrection()
    try:
        hook = at_release if mode == "at-release" else None
        if mode in ("watch", "watch-uncorrected"):
            watched = run_episode(scenario, obj, ik=ik, X_WG=None,
                                  throw_number=1)
            plan = plan_watched(scenario, obj, ik, watched)
            X_WG = plan.X_WG
            if mode == "watch":
                hook = release_correction(scenario, obj, ik, plan, parameters,
                                          correction)
        elif mode.startswith("first-throw"):
            plan = FlightPredictor.load(flight_model).plan(obj, scenario, ik)
            X_WG = plan.X_WG
            if mode == "first-throw":
                hook = release_correction(scenario, obj, ik, plan, parameters,
                                          correction)
        else:
            X_WG = entry.X_WG
        result = run_episode(
            scenario, obj, ik=ik, X_WG=X_WG, catch_parameters=parameters,
            throw_number=2, at_release=hook)
        if mode in ("watch", "first-throw"):
            row["release_correction"] = correction.as_dict()
        row["outcome"] = result.outcome
        if result.message:  # why a "failed" episode failed
            row["message"] = result.message
    except InputError as e:  # the noisy flight gave no reachable catch point
        row["outcome"] = "no plan"
        row["message"] = str(e)
    row["wall_s"] = round(time.perf_counter() - t0, 2)
    return row


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=[
        f"table1-row{k}" for k in range(1, 6)])
    parser.add_argument("--levels", nargs="+", type=float,
                        default=[0, 0.25, 0.5, 1, 2, 4])
    parser.add_argument("--trials", type=int, default=12)
    parser.add_argument("--workers", type=int, default=2)
    scenario_args.add(parser, target=False)
    parser.add_argument("--library", type=Path,
                        default=RESULTS / "library_table1.yaml")
    parser.add_argument("--first-throw-library", type=Path,
                        default=RESULTS / "library_table1_ft.yaml")
    parser.add_argument("--at-release-library", type=Path,
                        default=RESULTS / "library_table1_ar.yaml")
    parser.add_argument("--flight-model", type=Path,
                        default=RESULTS.parent / "flight_predictor.json",
                        help="the first-throw modes' flight predictor")
    parser.add_argument("--modes", nargs="+", choices=_MODES,
                        default=list(_MODES[:3]),
                        help="the modes to run (default: the first three)")
    parser.add_argument("--out", type=Path,
                        default=Path("out/noise_curve/noise_curve"),
                        help="<out>.jsonl, <out>.json and <out>.png")
    return _run(parser.parse_args(argv))


def _run(args) -> int:
    for flag, value, ok, expected in (
            ("--levels", min(args.levels), min(args.levels) >= 0,
             "noise levels ≥ 0"),
            ("--trials", args.trials, args.trials >= 1, "an integer ≥ 1"),
            ("--workers", args.workers, args.workers >= 1, "an integer ≥ 1")):
        if not ok:
            print(f"noise_curve: error: {flag}: got {value}, expected "
                  f"{expected}", file=sys.stderr)
            return 2
    from regrasp_drake.errors import InputError
    from regrasp_drake.learning.library import load_library
    from regrasp_drake.world.objects import load_catalogue
    try:
        scenario, label = scenario_args.load(args)
    except InputError as e:
        print(f"noise_curve: error: {e}", file=sys.stderr)
        return 2
    catalogue = load_catalogue()
    for name in args.objects:
        if name not in catalogue:
            print(f"noise_curve: error: --objects: got {name!r}, expected a "
                  "catalogue object (see `regrasp-drake objects`)",
                  file=sys.stderr)
            return 2
    libraries = {"watch": args.library, "first-throw": args.first_throw_library,
                 "at-release": args.at_release_library,
                 "watch-uncorrected": args.library,
                 "first-throw-uncorrected": args.first_throw_library}
    flags = dict(zip(_MODES, ("--library", "--first-throw-library",
                              "--at-release-library", "--library",
                              "--first-throw-library")))
    libraries = {mode: path for mode, path in libraries.items()
                 if mode in args.modes}
    learned = {}
    for mode, path in libraries.items():
        flag = flags[mode]
        if not path.is_file():  # a typo would silently drop the mode
            print(f"noise_curve: error: {flag}: got {path}, expected an "
                  "existing regrasp library file (`regrasp-drake table1 "
                  "--library F` writes one)", file=sys.stderr)
            return 2
        learned[mode] = set(load_library(path))
        missing = [n for n in args.objects if n not in learned[mode]]
        if missing:
            print(f"noise_curve: {mode}: nothing learned for {missing} in "
                  f"{path}; those objects are left out of this mode",
                  file=sys.stderr)
    if not any(n in learned[mode] for mode in learned for n in args.objects):
        print(f"noise_curve: error: --objects: got {args.objects}, expected "
              "objects learned in --library, --first-throw-library or "
              "--at-release-library (`regrasp-drake table1 --objects … "
              "--library F` writes one)", file=sys.stderr)
        return 2
    from regrasp_drake.grid import append_rows, read_rows
    lines = args.out.with_suffix(".jsonl")
    lines.parent.mkdir(parents=True, exist_ok=True)
    done = read_rows(lines, key=_key)
    cells = {}
    for mode, path in libraries.items():
        entries = load_library(path)
        cells.update({(mode, name): (entries[name].h_catch,
                                     entries[name].h_down)
                      for name in args.objects if name in entries})
    foreign = _foreign_rows(done, cells, _base_digest(scenario))
    if foreign:
        print(f"noise_curve: error: --out: {lines} holds {foreign}, expected "
              "trials of this run to resume (another scenario or library "
              "needs another --out)", file=sys.stderr)
        return 2
    if any(m.startswith("first-throw") for m in libraries):
        from regrasp_drake.learning.flight_predictor import FlightPredictor
        try:
            FlightPredictor.load(args.flight_model)
        except InputError as e:
            print(f"noise_curve: error: --flight-model: {e}", file=sys.stderr)
            return 2
    tasks = [(mode, name, level, trial, str(libraries[mode]), scenario,
              str(args.flight_model))
             for mode in libraries for level in args.levels
             for name in args.objects for trial in range(args.trials)
             if name in learned[mode]
             and (mode, name, level, trial) not in done]
    append_rows(_trial, tasks, lines, done, _key, workers=args.workers,
                label="noise curve", unit="trials")
    curves = {}
    for mode in libraries:
        curves[mode] = []
        for level in args.levels:
            noise = ThrowNoise.at_level(level, seed=0)
            rows = [r for k, r in done.items() if k[0] == mode
                    and k[2] == level and k[1] in args.objects
                    and k[1] in learned[mode] and k[3] < args.trials]
            caught = sum(r["outcome"] == "caught" for r in rows)
            interval = wilson_interval(caught, len(rows))
            curves[mode].append({
                "level": level,
                "release_time_std_ms": 1e3 * noise.release_time_std_s,
                "joint_velocity_std_rad_per_s":
                    noise.joint_velocity_std_rad_per_s,
                "trials": len(rows), "caught": caught,
                "objects": len({k[1] for k in done if k[0] == mode
                                and k[2] == level and k[1] in args.objects
                                and k[1] in learned[mode]}),
                # How the others ended: dropped, failed (the state
                # machine's message, e.g. a pose out of reach), no plan.
                "outcomes": dict(sorted(Counter(
                    r["outcome"] for r in rows).items())),
                "catch_rate": caught / len(rows) if rows else None,
                "catch_rate_95": interval and [round(v, 3) for v in interval]})
    summary = {"objects": args.objects, "trials_per_object": args.trials,
               "scenario": label, "curves": curves}
    atomic_io.write_json(args.out.with_suffix(".json"), summary)
    print(json.dumps(summary, indent=1))
    _plot(curves, args.out.with_suffix(".png"))
    return 0


def _plot(curves, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    import numpy as np
    fig, ax = plt.subplots(figsize=(7, 4.5))
    for k, (mode, points) in enumerate(curves.items()):
        if not any(p["trials"] for p in points):
            continue
        shift = 0.06 * (k - 1)  # ms: the modes' bars side by side
        points = [p for p in points if p["trials"]]
        objects = max(p["objects"] for p in points)
        trials = max(p["trials"] for p in points)
        rate = np.array([p["catch_rate"] for p in points])
        low, high = np.array([p["catch_rate_95"] for p in points]).T
        ax.errorbar([p["release_time_std_ms"] + shift for p in points], rate,
                    yerr=[rate - low, high - rate], capsize=3,
                    fmt="o--" if mode.endswith("-uncorrected") else "o-",
                    label=f"{mode} ({objects} objects, {trials} trials a level)")
    ax.set_xlabel("release time std (ms); joint velocity std = 15 × that "
                  "(mrad/s)", fontsize=8)
    ax.set_ylabel("catch rate")
    ax.set_ylim(-0.05, 1.05)
    ax.set_title("Catch rate of the learned parameters under release noise\n"
                 "(bars: 95 % Wilson intervals)", fontsize=10)
    ax.legend(fontsize=8)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
