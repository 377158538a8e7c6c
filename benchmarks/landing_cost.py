"""What the landing's step costs a target catch: wall time of the catch
with its throw reused, at the shipped landing (0.25 ms through the landing,
then back at the catch's 1 ms) against the catch at 1 ms throughout
(`landing_time_step_s: null`, the design before), alternating in one run.

    .venv/bin/python benchmarks/landing_cost.py [--object table1-row2]
        [--target flip:0] [--h-catch 0.32] [--h-down -0.07] [--runs 7]
        [--designs '{}' '{landing_time_step_s: null}' ...]
        [--json out/landing_cost.json]

Each design's catch is the one `regrasp-drake catch --object OBJECT
--target KIND --offset-mm MM --h-catch H --h-down D` runs: watch (once per
design), plan, then --runs catches, each going on from the kept throw
(episode.ThrowCache), the designs taking turns. Prints each design's
median wall time, its ratio to the first design's, and its verdict; writes
JSON. Machines are noisy: compare figures of one run.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import statistics
import sys
import time

import torch

from regrasp_drake import atomic_io
from regrasp_drake.episode.episode import THROWS
from regrasp_drake.errors import InputError
from regrasp_drake.paths import OUT_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.throw_catch import catch_planned, plan_watched, watch
from regrasp_drake.world.objects import resolve_object


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--target", default="flip:0")
    parser.add_argument("--h-catch", type=float, default=0.32)
    parser.add_argument("--h-down", type=float, default=-0.07)
    parser.add_argument("--runs", type=int, default=7)
    parser.add_argument("--designs", nargs="+",
                        default=["{}", "{landing_time_step_s: null}",
                                 "{landing_settle_s: null}"])
    parser.add_argument("--json", default=str(OUT_DIR / "landing_cost.json"))
    args = parser.parse_args(argv)
    try:
        if args.runs < 1:
            raise InputError(f"--runs: got {args.runs}, expected an integer "
                             ">= 1")
        target = Target.parse(args.target, "--target")
        obj = resolve_object(name=args.object)
        scenarios = [with_target(load_scenario(text=text), target)
                     for text in args.designs]
    except InputError as e:
        print(f"landing_cost: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    # Every design's throw kept at once.
    THROWS.size = max(THROWS.size, len(scenarios))
    ik = ArmIk(scenarios[0].directives)
    parameters = (args.h_catch, args.h_down)
    plans = [plan_watched(s, obj, ik, watch(s, obj, ik)) for s in scenarios]
    walls = [[] for _ in scenarios]
    results = [None] * len(scenarios)
    for i, (scenario, plan) in enumerate(zip(scenarios, plans)):
        # Its throw kept, and its diagrams built, before it is timed.
        catch_planned(scenario, obj, ik, plan, parameters)
    for _ in range(args.runs):
        for i, (scenario, plan) in enumerate(zip(scenarios, plans)):
            t0 = time.perf_counter()
            results[i] = catch_planned(scenario, obj, ik, plan, parameters)
            walls[i].append(time.perf_counter() - t0)
    base = statistics.median(walls[0])
    rows = []
    for text, wall, result in zip(args.designs, walls, results):
        g = result.achieved_grasp
        rows.append({"design": text, "median_wall_s": round(
            statistics.median(wall), 3), "ratio": round(
            statistics.median(wall) / base, 2), "walls_s": [
            round(w, 3) for w in wall], "sim_time_s": result.sim_time_s,
            "success": result.success,
            "grasp": None if g is None else g})
        print(f"{text:32} {rows[-1]['median_wall_s']:6.3f} s  "
              f"×{rows[-1]['ratio']:.2f}  "
              f"{'in target' if result.success else 'missed'} {g}")
    atomic_io.write_json(args.json, {"object": args.object,
                                     "target": args.target,
                                     "parameters": parameters,
                                     "runs": args.runs, "designs": rows})
    return 0


if __name__ == "__main__":
    sys.exit(main())
