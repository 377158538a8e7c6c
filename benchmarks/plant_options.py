"""Issue 42, third pass: the plant's own options, measured
(studies/physics_levers/FINDINGS.md §9).

    .venv/bin/python benchmarks/plant_options.py [--runs 5] [--pairs 7]
        [--map-objects table1-row2 hammer-d200-2 ...]
        [--json benchmarks/plant_options.json]

1. The physics alone (benchmarks/episode_benchmark.py's replay: the plant fed
   the recorded inputs of table1-row2's catch at (0.3, -0.07), no Python
   system), per plant step of the toss (0.25 ms) and of the catch (1 ms),
   under the shipped plant (point contact, the "similar" approximation,
   sampled output ports) and under each option: the "lagged" and "sap"
   approximations, and `use_sampled_output_ports: false`. The options run in
   turn in each of `--runs` rounds; the ratio to the shipped plant is taken
   round by round. "same bits": the replay ends in the episode's state.
2. The catch with its throw reused (as `regrasp-drake catch` runs it),
   sampled output ports on and off in turn, `--pairs` times, and the episode
   from the start (no throw cache), half as many: wall time ratio pair by
   pair, outcome and final position of each.
3. Success maps (150 cells, 2 workers) of `--map-objects` under both, in
   turn (which first alternating from object to object): wall time per
   map, cells with the same outcome; of the cells caught under both, the
   same grasp axis and side, and how far the grasp's offset and tilt moved
   (median, largest); and whether the watched plans (release state, catch
   point, palm pose) are equal.
"""

import regrasp_drake  # noqa: F401, I001 (first: pins NumPy's kernels)
import argparse
import copy
import json
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch
from tqdm import tqdm

from regrasp_drake import atomic_io
from regrasp_drake.episode.branching import run_cells
from regrasp_drake.errors import InputError
from regrasp_drake.episode.episode import THROWS
from regrasp_drake.parameter_space import cell_parameters, cells
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_watched, watch
from regrasp_drake.world.objects import resolve_object

from episode_benchmark import (
    catch_episode, record_plant_inputs, replayed_physics_wall_s)

PARAMETERS = (0.3, -0.07)
OPTIONS = {
    "shipped": {},
    "lagged": {"discrete_contact_approximation": "lagged"},
    "sap": {"discrete_contact_approximation": "sap"},
    "sampled_ports_off": {"use_sampled_output_ports": False},
}


def with_plant(scenario, **fields):
    """A copy of `scenario` with these fields of its MultibodyPlantConfig
    replaced."""
    out = copy.deepcopy(scenario)
    for name, value in fields.items():
        setattr(out.plant_config, name, value)
    return out


def physics_per_step(obj, segments, runs) -> dict:
    """µs per plant step of each option, per segment, and the ratio to the
    shipped plant round by round."""
    walls = {name: [[] for _ in segments] for name in OPTIONS}
    same = {name: True for name in OPTIONS}
    for _ in tqdm(range(runs), desc="physics replay", unit="round"):
        for name, fields in OPTIONS.items():
            for i, segment in enumerate(segments):
                wall, equal = replayed_physics_wall_s(
                    obj, segment, scenario=with_plant(segment.scenario, **fields))
                walls[name][i].append(wall / len(segment.u_arm))
                same[name] &= equal
    out = {}
    for name in OPTIONS:
        out[name] = {"same_bits": same[name], "segments": [
            {"time_step_s": segment.dt, "steps": len(segment.u_arm),
             "us_per_step": round(1e6 * statistics.median(walls[name][i]), 1),
             "over_shipped": round(statistics.median(
                 a / b for a, b in zip(walls[name][i], walls["shipped"][i])), 3)}
            for i, segment in enumerate(segments)]}
    return out


def catch_pairs(scenarios, obj, ik, pairs, *, reuse: bool) -> dict:
    """The catch, sampled output ports on and off in turn: with its throw
    reused (`reuse`, as `regrasp-drake catch` runs it) or from the start."""
    THROWS.enabled = True
    plans = {k: plan_watched(s, obj, ik, watch(s, obj, ik))
             for k, s in scenarios.items()}
    THROWS.enabled = reuse
    runs = {k: [] for k in scenarios}
    for _ in tqdm(range(pairs), desc="catch pairs", unit="pair"):
        for k, s in scenarios.items():
            runs[k].append(catch_episode(s, obj, ik, plans[k], PARAMETERS))
    THROWS.enabled = True
    on, off = runs["on"], runs["off"]
    return {
        "wall_s": {k: round(statistics.median(r.wall_s for r in v), 4)
                   for k, v in runs.items()},
        "off_over_on": round(statistics.median(
            b.wall_s / a.wall_s for a, b in zip(on, off)), 3),
        "real_time_factor": {k: round(statistics.median(
            r.sim_time_s / r.wall_s for r in v), 2) for k, v in runs.items()},
        "outcome": {k: sorted({r.outcome for r in v}) for k, v in runs.items()},
        "final_position_difference_mm": round(1e3 * float(np.linalg.norm(
            np.subtract(on[0].p_WO_final, off[0].p_WO_final))), 3),
    }


def map_pairs(scenarios, names, ik) -> list:
    """Per object of `names`: its watched plan and its 150-cell map under
    each scenario (sampled output ports on and off, which first alternating
    from object to object), compared."""
    parameters = [cell_parameters(c) for c in cells()]
    rows = []
    for n, name in enumerate(tqdm(names, desc="maps", unit="object")):
        obj = resolve_object(name=name)
        row = {"object": name}
        results, plans = {}, {}
        order = list(scenarios.items())
        for k, s in (order if n % 2 == 0 else order[::-1]):
            plan = plan_watched(s, obj, ik, watch(s, obj, ik))
            plans[k] = plan.as_dict()
            t0 = time.perf_counter()
            results[k] = run_cells(s, obj, ik=ik, X_WG=plan.X_WG,
                                   parameters=parameters, workers=2)
            row[f"wall_s_{k}"] = round(time.perf_counter() - t0, 2)
        row["plans_equal"] = plans["on"] == plans["off"]
        row["cells_same_outcome"] = sum(
            a.outcome == b.outcome for a, b in zip(results["on"], results["off"]))
        held = [(a.achieved_grasp, b.achieved_grasp)
                for a, b in zip(results["on"], results["off"])
                if a.outcome == b.outcome == "caught"
                and a.achieved_grasp and b.achieved_grasp]
        row["cells_caught_both_same_axis_and_side"] = sum(
            (a["axis"], a.get("side")) == (b["axis"], b.get("side"))
            for a, b in held)
        row["cells_caught_both"] = len(held)
        for key in ("offset_mm", "tilt_deg"):
            d = [abs(a[key] - b[key]) for a, b in held]
            row[f"{key}_difference_median_max"] = (
                [round(statistics.median(d), 2), round(max(d), 2)] if d else None)
        row["caught"] = {k: sum(r.outcome == "caught" for r in v)
                         for k, v in results.items()}
        rows.append(row)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__,
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--pairs", type=int, default=7)
    parser.add_argument("--map-objects", nargs="*",
                        default=["table1-row2", "table1-row3", "hammer-d200-2",
                                 "can-d300-3"])
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/plant_options.json"))
    args = parser.parse_args(argv)
    try:
        for flag, value in (("--runs", args.runs), ("--pairs", args.pairs)):
            if value < 1:
                raise InputError(f"{flag} {value}: expected >= 1")
        for name in args.map_objects:
            try:
                resolve_object(name=name)
            except InputError as e:
                raise InputError(f"--map-objects {name}: {e}") from None
    except InputError as e:
        print(f"plant_options: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    scenario = load_scenario()
    ik = ArmIk(scenario.directives)
    obj = resolve_object(name="table1-row2")
    THROWS.enabled = False
    plan = plan_watched(scenario, obj, ik, watch(scenario, obj, ik))
    segments, _ = record_plant_inputs(scenario, obj, ik, plan.X_WG, PARAMETERS)
    report = {"object": obj.name, "h_catch": PARAMETERS[0],
              "h_down": PARAMETERS[1]}
    report["physics_per_step"] = physics_per_step(obj, segments, args.runs)
    scenarios = {"on": scenario,
                 "off": with_plant(scenario, use_sampled_output_ports=False)}
    report["catch_throw_reused"] = catch_pairs(scenarios, obj, ik, args.pairs,
                                               reuse=True)
    report["episode_from_start"] = catch_pairs(
        scenarios, obj, ik, max(3, args.pairs // 2), reuse=False)
    report["maps"] = map_pairs(scenarios, args.map_objects, ik)
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(args.json, report)
    return 0


if __name__ == "__main__":
    sys.exit(main())
