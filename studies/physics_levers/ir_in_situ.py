"""Issue 42, third pass: what an infrared sample costs inside a catch, and
what the same work costs in a warm loop (FINDINGS.md §9).

    .venv/bin/python studies/physics_levers/ir_in_situ.py [--catches 5]

Inside `--catches` catches of table1-row2 (throw reused, h_catch 0.3,
h_down -0.07), each infrared sample is timed in parts: the query port's
evaluation, the first pose read (SceneGraph's pose update, which the plant's
next step reuses), the readings (`read_levels`, the poses then cached), and
the same readings at once again. Then the last catch's casts (their poses
recorded) are repeated in a loop. The readings are the same each time; only
the time differs.
"""

import regrasp_drake  # noqa: F401, I001 (first: pins NumPy's kernels)
import argparse
import statistics
import time

import numpy as np
import torch

from regrasp_drake.episode.episode import run_episode
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import sensors
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_watched, watch
from regrasp_drake.world.objects import resolve_object

PARAMETERS = (0.3, -0.07)


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--catches", type=int, default=5)
    args = parser.parse_args()
    if args.catches < 1:
        parser.error(f"--catches {args.catches}: expected >= 1")
    torch.set_num_threads(1)
    parts = {"query port": [], "poses (first read)": [], "read_levels": [],
             "read_levels again": []}
    casts = []
    read_levels = sensors.InfraredSensors.read_levels
    entry = sensors._CastTargets.entry

    def timed_sample(system, context, discrete_state):
        t0 = time.perf_counter()
        query = system._query_port.Eval(context)
        t1 = time.perf_counter()
        for frame_id in system._frames:
            query.GetPoseInWorld(frame_id)
        t2 = time.perf_counter()
        levels = read_levels(system, query)
        t3 = time.perf_counter()
        sensors._CastTargets.entry = entry  # record each cast once
        again = read_levels(system, query)
        sensors._CastTargets.entry = recorded_entry
        t4 = time.perf_counter()
        assert np.array_equal(levels, again)
        for name, dt in zip(parts, (t1 - t0, t2 - t1, t3 - t2, t4 - t3)):
            parts[name].append(dt)
        discrete_state.set_value(0, levels)

    def recorded_entry(targets, X_FB):
        casts.append((targets, X_FB.copy()))
        return entry(targets, X_FB)

    sensors.InfraredSensors._sample = timed_sample
    sensors._CastTargets.entry = recorded_entry
    scenario = load_scenario()
    obj = resolve_object(name="table1-row2")
    ik = ArmIk(scenario.directives)
    plan = plan_watched(scenario, obj, ik, watch(scenario, obj, ik))
    for values in parts.values():
        values.clear()
    for _ in range(args.catches):
        casts.clear()
        run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                    catch_parameters=PARAMETERS)
    sensors._CastTargets.entry = entry
    print(f"inside {args.catches} catches, {len(parts['query port'])} samples, "
          "median µs:")
    for name, values in parts.items():
        print(f"  {name:20s} {1e6 * statistics.median(values):7.1f}")
    t0 = time.perf_counter()
    for targets, X_FB in casts:
        targets.entry(X_FB)
    print(f"the last catch's {len(casts)} casts again in a loop: "
          f"{1e6 * (time.perf_counter() - t0) / len(casts):.1f} µs each")


if __name__ == "__main__":
    main()
