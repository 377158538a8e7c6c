"""Do success maps converge as the catch's time step shrinks?

    .venv/bin/python benchmarks/map_convergence.py
        [--objects table1-row1 … table1-row5] [--steps-ms 1 0.5]
        [--flights-only] [--throw-step-ms X]
        [--scenario F] [--scenario-name NAME] [--workers 2]
        [--out out/map_convergence]

For each object and each step of the catch (the scenario, by default the
shipped one, with only `catch_time_step_s` changed: the plant's step from
the release time on; the throw at the scenario's plant_config.time_step, or
at --throw-step-ms): the watching throw, the object's
state when the throw ends (the release: its velocity and its angular
velocity in its own frame),
the planned catch point, and the whole 150-cell success map. Then, for every
pair of steps, how many cells have the same outcome, against the agreement
two unrelated maps with the same catch rates would show by chance,
p·q + (1 − p)·(1 − q) of the cells.

A map that is a converged function of the physics agrees more and more
closely as the step halves; one decided by the discretization agrees with
its neighbours no better than chance. For each map also the throws the
learning phase would count on it, offline: the watch, the shipped network's
cell for that step's catch point, then the wavefront's or the map prior's
cells up to the first that catches.

Writes <out>/<object>_<step>ms.jsonl (one line per cell, as it finishes; a
rerun resumes; <out>/scenario.json records the scenario, and an --out holding
another scenario's results is refused), <out>.json (the figures) and
<out>.png (every map, and the agreements against chance). With
--flights-only: the watching throws alone, `workers` at a time, into
<out>/flights.jsonl (resumable), and a PNG of each object's spin and
catch-point shift between the coarsest and finest steps.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import dataclasses as dc
import json
import sys
from pathlib import Path

import numpy as np
from regrasp_drake import atomic_io

from regrasp_drake import scenario_args
from regrasp_drake.convergence import agreement

_OBJECTS = [f"table1-row{k}" for k in range(1, 6)]
_STEPS_MS = [1.0, 0.5]


def release_state(scenario, obj, logs) -> dict:
    """The object's state at the first logged sample after the throw ends:
    v_WO (m/s) and w_O, the angular velocity in the object's frame (rad/s)."""
    from pydrake.common.eigen_geometry import Quaternion
    from pydrake.math import RotationMatrix

    from regrasp_drake.station import throw
    t_free = throw.free_time_s(scenario)
    k = int(np.searchsorted(logs.t, t_free))
    x = logs.object_state[:, k]
    R_WO = RotationMatrix(Quaternion(x[:4] / np.linalg.norm(x[:4]))).matrix()
    return {"t_s": round(float(logs.t[k]), 4),
            "v_WO": [round(float(c), 4) for c in x[10:13]],
            "w_O": [round(float(c), 4) for c in R_WO.T @ x[7:10]]}


def _scenario(step_ms, base=None, throw_step_ms=None):
    """The scenario `base` (default: the shipped one) with its catch at
    step_ms (and its throw at throw_step_ms, if given)."""
    from regrasp_drake.station.scenario import (
        load_scenario,
        with_catch_time_step,
        with_time_step,
    )
    scenario = base or load_scenario()
    if throw_step_ms:
        scenario = with_time_step(scenario, throw_step_ms / 1e3)
    return with_catch_time_step(scenario, step_ms / 1e3)


def claim_out_dir(out: Path, base=None, label=None) -> None:
    """Records in <out>/scenario.json the scenario (all but the catch's time
    step) the
    maps and flights in `out` come from, or refuses, naming --out and
    --scenario, a scenario other than the one recorded: the resumable files
    there are keyed by object, step and cell only, and would mix runs.
    base: the Scenario (default: the shipped one); label: how it was given."""
    from regrasp_drake.errors import InputError
    from regrasp_drake.station.scenario import (
        load_scenario,
        scenario_yaml,
    )
    # The scenario's YAML at one fixed catch step (a string: it holds tags).
    fields = scenario_yaml(dc.replace(base or load_scenario(),
                                      catch_time_step_s=None))
    record = out / "scenario.json"
    if record.is_file():
        if json.loads(record.read_text()) != fields:
            raise InputError(
                f"--out {out}: holds results of another scenario than "
                f"--scenario {label or '(the shipped one)'} (see "
                f"{record}); expected a fresh --out")
        return
    out.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(record, fields)


def flight(name, step_ms, base=None, throw_step_ms=None):
    """The watching throw at one catch step (of the Scenario `base`,
    None: the shipped one): the release state and the planned catch
    (catch_point None when no moment is reachable); also returns the plan,
    for the map."""
    from regrasp_drake.errors import InputError
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    scenario = _scenario(step_ms, base, throw_step_ms)
    obj, ik = resolve_object(name=name), ArmIk()
    watched = watch(scenario, obj, ik)
    row = {"object": name, "step_ms": step_ms,
           "release": release_state(scenario, obj, watched.logs),
           "catch_point": None}
    try:
        plan = plan_catch(scenario, obj, ik, watched)
    except InputError:
        return row, None
    cp = plan.catch_point
    row["catch_point"] = {"t_s": round(cp.t_s, 4),
                          "p_WO": [round(float(c), 4) for c in cp.p_WO],
                          "tilt": round(float(cp.tilt), 4),
                          "v_catch": round(float(cp.v_catch), 4)}
    return row, (scenario, obj, ik, plan)


def _flight_row(task):
    return flight(*task)[0]


def map_at_step(name, step_ms, out_dir: Path, workers: int,
                throw_step_ms=None, base=None) -> dict:
    """The flight and the 150-cell success map of one object at one catch
    step (the throw at `throw_step_ms`, if given)."""
    from regrasp_drake.grid import run_map
    row, setup = flight(name, step_ms, base, throw_step_ms)
    if setup is None:
        raise SystemExit(f"map_convergence: error: {name} at "
                         f"{step_ms:g} ms: no reachable catch point, no map")
    path = out_dir / f"{name}_{step_ms:g}ms.jsonl"
    if throw_step_ms:
        path = out_dir / f"{name}_{step_ms:g}ms_throw{throw_step_ms:g}ms.jsonl"
    rows = run_map(*setup, path, workers=workers)
    caught = np.zeros((10, 15), bool)
    for cell, cell_row in rows.items():
        caught[cell] = cell_row["outcome"] == "caught"
    if throw_step_ms:
        row = row | {"step_ms": step_ms, "throw_step_ms": throw_step_ms}
    return row | {"cells_caught": int(caught.sum()),
                  "caught": caught.astype(int).tolist(),
                  "table1": table1_throws(setup[1], setup[3], caught)}


def table1_throws(obj, plan, caught) -> dict:
    """What the learning phase would count on this map, offline: the shipped
    network's cell for this step's catch point (its v_catch), then each
    search's cells until one catches in `caught`; throws include the watch
    (None: no cell catches)."""
    from regrasp_drake.grid import nearest_cell
    from regrasp_drake.learning.learning_phase import network_features, predict
    from regrasp_drake.learning.search import (
        attempts_to_catch,
        feature_weighted_order,
        load_prior_maps,
        wavefront_order,
    )
    from regrasp_drake.paths import MODELS_DIR
    from regrasp_drake.station.mlp_system import load_weights
    model, _ = load_weights(MODELS_DIR / "catch_mlp.pt")
    features = network_features(obj, plan.catch_point)
    start = nearest_cell(*predict(model, features)[1])
    _, prior, prior_features = load_prior_maps(with_features=True)
    out = {"network_cell": list(start)}
    for search, order in (
            ("wavefront", wavefront_order(start)),
            ("map_prior", feature_weighted_order(start, prior, prior_features,
                                                 features))):
        n = attempts_to_catch(order, caught)
        out[f"throws_{search}"] = None if n is None else n + 1
    return out


def _shift(row, finest) -> dict:
    """How far `row`'s release spin and catch moment are from the finest
    step's."""
    out = {"w_O_rad_per_s": round(float(np.linalg.norm(
        np.subtract(row["release"]["w_O"], finest["release"]["w_O"]))), 3)}
    a, b = row["catch_point"], finest["catch_point"]
    if a and b:
        out["catch_t_ms"] = round(1e3 * (a["t_s"] - b["t_s"]), 1)
        out["catch_p_mm"] = round(1e3 * float(np.linalg.norm(
            np.subtract(a["p_WO"], b["p_WO"]))), 1)
    return out


def summarize(results: dict, steps_ms) -> dict:
    """results[name][step] as flight's rows (with map_at_step's fields when
    maps were run). Adds each step's shift from the finest step and, with
    maps, the pairwise agreement of the maps (steps in the order given)."""
    finest = min(steps_ms)
    summary = {"steps_ms": list(steps_ms), "objects": {}}
    for name, by_step in results.items():
        s = summary["objects"][name] = {
            "by_step": {f"{step:g}": by_step[step] for step in steps_ms},
            "shift_from_finest": {f"{step:g}": _shift(by_step[step],
                                                      by_step[finest])
                                  for step in steps_ms}}
        if all("caught" in by_step[step] for step in steps_ms):
            maps = [np.array(by_step[step]["caught"], bool)
                    for step in steps_ms]
            pairs = [[agreement(a, b) for b in maps] for a in maps]
            s["agreement_same"] = [[p["same"] for p in row] for row in pairs]
            s["agreement_chance"] = [[p["chance"] for p in row]
                                     for row in pairs]
    return summary


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--objects", nargs="+", default=_OBJECTS)
    parser.add_argument("--steps-ms", type=float, nargs="+", default=_STEPS_MS)
    parser.add_argument("--flights-only", action="store_true",
                        help="the watching throws only, no success maps")
    parser.add_argument("--throw-step-ms", type=float,
                        help="the throw's plant step (default: the "
                             "scenario's); the catch at each of --steps-ms")
    scenario_args.add(parser, target=False)  # only its time steps vary
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--out", type=Path, default=Path("out/map_convergence"),
                        help="a directory of rows; <out>.json and <out>.png "
                             "beside it")
    args = parser.parse_args(argv)
    return _run(args)


def _run(args) -> int:
    from regrasp_drake.errors import InputError
    from regrasp_drake.world.objects import resolve_object
    try:
        base, label = scenario_args.load(args)
        for step in args.steps_ms:
            try:
                _scenario(step, base, args.throw_step_ms)
            except InputError as e:
                raise InputError(
                    f"--steps-ms {step:g}"
                    + (f" --throw-step-ms {args.throw_step_ms:g}"
                       if args.throw_step_ms else "") + f": {e}") from None
        for name in args.objects:
            resolve_object(name=name)
        if args.workers < 1:
            raise InputError(f"--workers {args.workers}: expected >= 1")
        claim_out_dir(args.out, base, label)
    except InputError as e:
        print(f"map_convergence: error: {e}", file=sys.stderr)
        return 2
    import torch
    torch.set_num_threads(1)
    args.out.mkdir(parents=True, exist_ok=True)
    results = {name: {} for name in args.objects}
    if args.flights_only:
        from regrasp_drake.grid import append_rows, read_rows
        lines = args.out / "flights.jsonl"
        key = lambda row: (row["object"], row["step_ms"])  # noqa: E731
        done = read_rows(lines, key=key)
        tasks = [(name, step, base, args.throw_step_ms)
                 for name in args.objects
                 for step in args.steps_ms if (name, step) not in done]
        append_rows(_flight_row, tasks, lines, done, key,
                    workers=args.workers, label="flights", unit="throws")
        for (name, step), row in done.items():
            if name in results and step in args.steps_ms:
                results[name][step] = row
    else:
        for name in args.objects:
            for step in args.steps_ms:
                print(f"{name}, step {step:g} ms", file=sys.stderr)
                results[name][step] = map_at_step(
                    name, step, args.out, args.workers, args.throw_step_ms,
                    base)
    summary = summarize(results, args.steps_ms) | {
        "throw_step_ms": args.throw_step_ms,
        "scenario": label}
    atomic_io.write_json(args.out.with_suffix(".json"), summary, indent=None)
    _print(summary)
    (_plot_flights if args.flights_only else _plot_maps)(
        summary, args.out.with_suffix(".png"))
    return 0


def _print(summary):
    steps = summary["steps_ms"]
    for name, s in summary["objects"].items():
        print(f"\n{name}")
        for i, step in enumerate(steps):
            b = s["by_step"][f"{step:g}"]
            shift = s["shift_from_finest"][f"{step:g}"]
            cp = b["catch_point"]
            line = (f"  {step:>6g} ms: w_O at release "
                    f"{np.round(b['release']['w_O'], 2)} rad/s "
                    f"({shift['w_O_rad_per_s']:.2f} from the finest step); ")
            line += ("no reachable catch point" if cp is None else
                     f"catch at t {cp['t_s']:.3f} s, tilt {cp['tilt']:.2f}, "
                     f"v {cp['v_catch']:.2f} m/s")
            if "catch_p_mm" in shift:
                line += f" ({shift['catch_p_mm']:.0f} mm from the finest)"
            if "table1" in b:
                t = b["table1"]
                line += (f"; network cell {tuple(t['network_cell'])}, "
                         f"throws {t['throws_wavefront']} (wavefront), "
                         f"{t['throws_map_prior']} (map prior)")
            if "agreement_same" in s:
                same = " ".join(f"{n:>3}/{c:>5.1f}" for n, c in zip(
                    s["agreement_same"][i], s["agreement_chance"][i]))
                line += (f"; {b['cells_caught']:>3}/150 catch; same cells / "
                         f"chance vs each step: {same}")
            print(line)


def _plot_maps(summary, path):
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
        for ax, step in zip(row, steps):
            b = s["by_step"][f"{step:g}"]
            ax.imshow(np.array(b["caught"]), origin="lower", cmap="Greens",
                      vmin=0, vmax=1.3, extent=(-14.5, 0.5, 0.02, 0.42),
                      aspect="auto")
            ax.set_title(f"{name}, {step:g} ms\n{b['cells_caught']}/150, "
                         f"catch t {b['catch_point']['t_s']:.3f} s", fontsize=8)
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
                      fontsize=6)
        ax.set_xlabel("step pair (ms)", fontsize=7)
        ax.set_ylim(0, 150)
        ax.set_title("cells agreeing, neighbouring steps", fontsize=8)
        ax.legend(fontsize=6)
    throw = summary.get("throw_step_ms")
    fig.suptitle("Success maps against the catch's time step (green: "
                 "caught)" + (f"; every throw at {throw:g} ms" if throw else "")
                 + (f"; scenario {summary['scenario']}"
                    if summary.get("scenario") else ""), fontsize=9)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=100)
    plt.close(fig)


def _plot_flights(summary, path):
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    steps = summary["steps_ms"]
    coarse = f"{max(steps):g}"
    names = sorted(summary["objects"], key=lambda n: summary["objects"][n][
        "shift_from_finest"][coarse]["w_O_rad_per_s"])
    shifts = [summary["objects"][n]["shift_from_finest"][coarse]
              for n in names]
    fig, axes = plt.subplots(2, 1, figsize=(max(6, 0.16 * len(names)), 6),
                             sharex=True)
    x = np.arange(len(names))
    axes[0].bar(x, [s["w_O_rad_per_s"] for s in shifts])
    axes[0].set_ylabel("|Δ w_O| at release (rad/s)", fontsize=8)
    axes[1].bar(x, [s.get("catch_p_mm", np.nan) for s in shifts],
                color="tab:orange")
    axes[1].set_ylabel("catch point moved (mm)", fontsize=8)
    axes[1].set_xticks(x, names, rotation=90, fontsize=6)
    fig.suptitle(f"Watching throw at {coarse} ms against {min(steps):g} ms",
                 fontsize=9)
    fig.tight_layout()
    atomic_io.save_figure(fig, path, dpi=100)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
