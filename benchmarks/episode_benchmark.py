"""Benchmark of one catch episode: wall time, real-time factor, where the time goes.

    .venv/bin/python benchmarks/episode_benchmark.py [--object table1-row2] [--runs 5]
        [--json benchmarks/episode_benchmark.json]

Prints the figures and writes them as JSON. Not a test: machines are noisy;
compare figures from one run. For comparison, the same run times the bare
physics: the same plant (arm, hand, object, ground; same time step and
contact) and the arm's inverse-dynamics controller with constant references,
no Python system, for the same simulated time: the ceiling our Python systems
leave room for.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
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


def plant_only_wall_s(scenario, obj, sim_time_s: float) -> float:
    """Wall time of the bare physics over sim_time_s (see the docstring):
    the object falls onto the ground beside the arm, which holds the throw's
    first knot; the fingers hold open."""
    import numpy as np
    from pydrake.math import RigidTransform
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.controllers import InverseDynamicsController
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import ConstantVectorSource

    from regrasp_drake.station.station import add_world
    from regrasp_drake.world import robot
    builder = DiagramBuilder()
    plant, _, instances, body, _ = add_world(builder, scenario, obj)
    q0 = np.array(scenario.throw.knot_q_rad[0])
    controller = builder.AddSystem(InverseDynamicsController(
        robot.make_arm_control_plant(), scenario.arm.kp, scenario.arm.ki,
        scenario.arm.kd, has_reference_acceleration=True))
    builder.Connect(plant.get_state_output_port(instances.arm),
                    controller.get_input_port_estimated_state())
    builder.Connect(controller.get_output_port_control(),
                    plant.get_actuation_input_port(instances.arm))
    for port, value in (
            (controller.get_input_port_desired_state(),
             np.concatenate([q0, np.zeros(6)])),
            (controller.get_input_port_desired_acceleration(), np.zeros(6)),
            (plant.get_desired_state_input_port(instances.hand),
             np.zeros(2 * len(robot.HAND_JOINTS)))):
        builder.Connect(builder.AddSystem(
            ConstantVectorSource(value)).get_output_port(), port)
    simulator = Simulator(builder.Build())
    context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
    plant.SetPositions(context, instances.arm, q0)
    plant.SetFreeBodyPose(context, body, RigidTransform([1.2, 0.5, 0.6]))
    simulator.Initialize()
    t0 = time.perf_counter()
    simulator.AdvanceTo(sim_time_s)
    return time.perf_counter() - t0


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
    plant_walls = [plant_only_wall_s(scenario, obj, sim)
                   for _ in range(args.runs)]
    report["plant_and_controller_only"] = {
        "median_wall_s": round(statistics.median(plant_walls), 4),
        "real_time_factor": round(sim / statistics.median(plant_walls), 3),
        "episode_wall_over_plant_only": round(
            (statistics.median(walls) - statistics.median(builds))
            / statistics.median(plant_walls), 3)}
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
