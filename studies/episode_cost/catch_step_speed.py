"""How fast a catch episode runs with its throw reused, at a coarser catch step.

    .venv/bin/python studies/episode_cost/catch_step_speed.py
        [--object table1-row2] [--steps-ms 1 2 4] [--runs 3]
        [--json studies/episode_cost/catch_step_speed.json]

For each catch step (scenario catch_time_step_s; the throw stays at its
0.25 ms): the watching throw (which keeps the throw at its release,
episode.ThrowCache), then `runs` catch episodes at the shipped cell going on
from it; prints and writes the median wall time and simulated over wall
time. Whether the maps at those steps converge is
benchmarks/map_convergence.py's question (FINDINGS.md has both).
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels.
import regrasp_drake  # noqa: F401, I001
import argparse
import json
import statistics
import sys
from pathlib import Path


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--steps-ms", type=float, nargs="+", default=[1, 2, 4])
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--json", type=Path, default=Path(
        "studies/episode_cost/catch_step_speed.json"))
    args = parser.parse_args(argv)
    import torch

    from regrasp_drake.episode.run import THROWS, run_episode
    from regrasp_drake.planning.ik import ArmIk
    from regrasp_drake.station.scenario import (
        load_scenario,
        with_catch_time_step,
    )
    from regrasp_drake.throw_catch import plan_catch, watch
    from regrasp_drake.world.objects import resolve_object
    torch.set_num_threads(1)
    obj = resolve_object(name=args.object)
    ik = ArmIk()
    base = load_scenario()
    cell = (base.catch.h_catch_m, base.catch.h_down_m)
    report = {"object": obj.name, "cell": list(cell), "runs": args.runs,
              "steps": []}
    for step_ms in args.steps_ms:
        scenario = with_catch_time_step(base, step_ms * 1e-3)
        THROWS.clear()
        plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
        results = [run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                               catch_parameters=cell)
                   for _ in range(args.runs)]
        wall = statistics.median(r.wall_s for r in results)
        row = {"catch_step_ms": step_ms, "outcome": results[0].outcome,
               "sim_time_s": round(results[0].sim_time_s, 4),
               "median_wall_s": round(wall, 4),
               "real_time_factor": round(results[0].sim_time_s / wall, 2)}
        report["steps"].append(row)
        print(json.dumps(row))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
