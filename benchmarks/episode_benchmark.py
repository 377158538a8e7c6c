"""Benchmark of one catch episode: wall time, real-time factor, where the time goes.

    .venv/bin/python benchmarks/episode_benchmark.py [--object table1-row2] [--runs 5]
        [--json benchmarks/episode_benchmark.json]

Prints the figures and writes them as JSON. Not a test: machines are noisy;
compare figures from one run.
"""

import argparse
import cProfile
import json
import pstats
import statistics
import sys
import time
from pathlib import Path

import torch

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.episode import run_episode
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

# Python callbacks of our systems, grouped by system.
_PYTHON_SYSTEMS = {
    "infrared sensors": ("sensors.py", "read_levels"),
    "tactile bumper": ("sensors.py", "_sample"),
    "catch state machine": ("catch_state_machine.py", None),
    "grasp monitor": ("grasp_monitor.py", "_update"),
}


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/episode_benchmark.json"))
    args = parser.parse_args()
    torch.set_num_threads(1)
    scenario = load_scenario()
    obj = resolve_object(name=args.object)
    ik = ArmIk()
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    params = (scenario.catch.h_catch_m, scenario.catch.h_down_m)
    results = []
    for _ in range(args.runs):
        results.append(run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                                   catch_parameters=params))
    walls = [r.wall_s for r in results]
    builds = [r.build_s for r in results]
    sim = results[0].sim_time_s
    # One more run under the profiler, to split the simulation's time.
    profiler = cProfile.Profile()
    profiler.enable()
    t0 = time.perf_counter()
    profiled = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                           catch_parameters=params)
    profiled_wall = time.perf_counter() - t0
    profiler.disable()
    stats = pstats.Stats(profiler).stats
    python = {}
    for name, (file, func) in _PYTHON_SYSTEMS.items():
        python[name] = round(sum(
            tt for (f, _, fn), (_, _, tt, _, _) in stats.items()
            if f.endswith(file) and (func is None or fn == func)), 4)
    # Cumulative time of the sensors includes the geometry queries they make.
    python["infrared sensors"] = round(sum(
        ct for (f, _, fn), (_, _, _, ct, _) in stats.items()
        if f.endswith("sensors.py") and fn == "read_levels"), 4)
    report = {
        "object": obj.name, "outcome": results[0].outcome,
        "runs": args.runs, "sim_time_s": round(sim, 4),
        "median_wall_s": round(statistics.median(walls), 4),
        "median_build_s": round(statistics.median(builds), 4),
        "real_time_factor": round(sim / statistics.median(walls), 3),
        "simulation_only_real_time_factor": round(
            sim / (statistics.median(walls) - statistics.median(builds)), 3),
        "profiled_wall_s": round(profiled_wall, 4),
        "python_systems_s (profiled run)": python,
        "outcomes_identical": len({r.outcome for r in results + [profiled]}) == 1,
    }
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
