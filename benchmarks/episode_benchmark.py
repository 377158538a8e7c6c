"""Benchmark of one catch episode: wall time, real-time factor, where the time goes.

    .venv/bin/python benchmarks/episode_benchmark.py [--object table1-row2] [--runs 5]
        [--json benchmarks/episode_benchmark.json]

Prints the figures and writes them as JSON. Not a test: machines are noisy;
compare figures from one run. For comparison, the same run times the
episode's physics alone: the same plant (arm, hand, object, ground; same
time step and contact) replayed with the inputs the episode gave it at every
step, with no controller and no Python system. It ends in the episode's
final state bit for bit (checked: `identical_final_state`), so it is the
same physics, contact for contact: what no change to the systems around the
plant can go below. It is timed over the whole episode and from the cell's
fork (the trigger: what each forked cell of a success map simulates).
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

from regrasp_drake.errors import InputError
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.episode import advance_to_outcome, run_episode
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.station.station import build_station, initialize
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

# Python callbacks of our systems, grouped by system.
_PYTHON_SYSTEMS = {
    "infrared sensors": ("sensors.py", "read_levels"),
    "tactile bumper": ("sensors.py", "_sample"),
    "catch state machine": ("catch_state_machine.py", None),
    "grasp monitor": ("grasp_monitor.py", "_update"),
}


def record_plant_inputs(scenario, obj, ik, X_WG, params, t_split):
    """Runs the episode step by step to its end and returns what its plant
    was given: the arm's actuation and the fingers' desired state at every
    plant step (each a (steps, n) array), the plant's state at t_split
    (None past the end) and at the end, and the object's final position (to
    compare with the episode's: stepping this way changes nothing). An input
    port evaluated between steps gives the value the plant's next step
    reads."""
    import numpy as np
    station = build_station(scenario, obj, ik=ik, X_WG=X_WG,
                            catch_parameters=params)
    simulator = initialize(station, scenario)
    plant = station.plant
    context = plant.GetMyContextFromRoot(simulator.get_context())
    dt = scenario.time_step_s
    k_split = round(t_split / dt)
    x_split = None
    u_arm, u_hand = [], []
    k = 0
    while True:
        if k:  # AdvanceTo(0) would already take the first step's updates
            status = simulator.AdvanceTo(k * dt)
            if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                break  # the monitor ended the episode in step k - 1
        if k == k_split:
            x_split = plant.GetPositionsAndVelocities(context).copy()
        u_arm.append(plant.get_actuation_input_port(station.arm).Eval(
            context).copy())
        u_hand.append(plant.get_desired_state_input_port(station.hand).Eval(
            context).copy())
        k += 1
    p_WO = plant.EvalBodyPoseInWorld(
        context, station.object_body).translation().tolist()
    return (np.array(u_arm), np.array(u_hand), x_split,
            plant.GetPositionsAndVelocities(context).copy(), p_WO)


def replayed_physics_wall_s(scenario, obj, X_WO_initial, u_arm, u_hand,
                            t_start, x_start, x_end):
    """Wall time of the episode's physics alone from t_start: the same plant
    (add_world), fed the recorded inputs by zero-order holds (Drake's
    TrajectorySource, in C++), with no controller, sensor, state machine or
    monitor. Returns (wall s, whether the plant's final state equals the
    episode's bit for bit): equal, it is the same physics, contact for
    contact."""
    import numpy as np
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from regrasp_drake.station.station import add_world
    from regrasp_drake.world import robot
    dt = scenario.time_step_s
    steps = len(u_arm)
    # Step k's input holds on [(k - 1/2) dt, (k + 1/2) dt).
    breaks = [(k - 0.5) * dt for k in range(steps + 1)]

    def hold(values):
        v = values.T
        return TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
            breaks, np.hstack([v, v[:, -1:]])))

    builder = DiagramBuilder()
    plant, _, instances, body, _ = add_world(builder, scenario, obj)
    builder.Connect(builder.AddSystem(hold(u_arm)).get_output_port(),
                    plant.get_actuation_input_port(instances.arm))
    builder.Connect(builder.AddSystem(hold(u_hand)).get_output_port(),
                    plant.get_desired_state_input_port(instances.hand))
    simulator = Simulator(builder.Build())
    root = simulator.get_mutable_context()
    context = plant.GetMyMutableContextFromRoot(root)
    if x_start is None:
        plant.SetPositions(context, instances.arm,
                           np.array(scenario.throw.knot_q_rad[0], float))
        plant.SetPositions(context, instances.hand, robot.HAND_OPEN)
        plant.SetFreeBodyPose(context, body, X_WO_initial)
    else:
        root.SetTime(t_start)
        plant.SetPositionsAndVelocities(context, x_start)
    simulator.Initialize()
    t0 = time.perf_counter()
    simulator.AdvanceTo(steps * dt)
    wall = time.perf_counter() - t0
    return wall, bool(np.array_equal(
        plant.GetPositionsAndVelocities(context), x_end))


def episode_from_wall_s(scenario, obj, ik, X_WG, params, t_start) -> float:
    """Wall time of the whole episode's simulation from t_start to its end
    (what a forked cell of a success map runs, when t_start is the fork)."""
    station = build_station(scenario, obj, ik=ik, X_WG=X_WG,
                            catch_parameters=params)
    simulator = initialize(station, scenario)
    simulator.AdvanceTo(t_start)
    t0 = time.perf_counter()
    advance_to_outcome(simulator, station, scenario)
    return time.perf_counter() - t0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/episode_benchmark.json"))
    args = parser.parse_args(argv)
    try:
        if args.runs < 1:
            raise InputError(f"--runs {args.runs}: expected >= 1")
        try:
            obj = resolve_object(name=args.object)
        except InputError as e:
            raise InputError(f"--object {args.object}: {e}") from None
    except InputError as e:
        print(f"episode_benchmark: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    scenario = load_scenario()
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
    # The physics alone, replayed (see replayed_physics_wall_s): over the
    # whole episode, and from the trigger (the first sample in LOWER, less
    # one sample: where a success map forks this cell) to the end.
    logs = results[0].logs
    lower = [t for t, p in zip(logs.t, logs.phase) if p >= Phase.LOWER]
    if not lower:
        print(f"episode_benchmark: error: --object {obj.name}: the hand never "
              f"lowered (outcome {results[0].outcome}), expected an object "
              "whose episode reaches the catch", file=sys.stderr)
        return 2
    t_fork = round(lower[0] - scenario.sensors.period_s, 6)
    u_arm, u_hand, x_fork, x_end, p_WO_end = record_plant_inputs(
        scenario, obj, ik, plan.X_WG, params, t_fork)
    X_WO = build_station(scenario, obj, ik=ik, X_WG=plan.X_WG,
                         catch_parameters=params).X_WO_initial
    replay, replay_tail, tail = [], [], []
    for _ in range(args.runs):
        replay.append(replayed_physics_wall_s(
            scenario, obj, X_WO, u_arm, u_hand, 0.0, None, x_end))
        replay_tail.append(replayed_physics_wall_s(
            scenario, obj, X_WO, u_arm, u_hand, t_fork, x_fork, x_end))
        tail.append(episode_from_wall_s(
            scenario, obj, ik, plan.X_WG, params, t_fork))
    episode_sim_wall = statistics.median(walls) - statistics.median(builds)
    physics = statistics.median(w for w, _ in replay)
    physics_tail = statistics.median(w for w, _ in replay_tail)
    report["physics_replayed"] = {
        "identical_final_state": (
            p_WO_end == results[0].p_WO_final
            and all(same for _, same in replay + replay_tail)),
        "whole_episode": {
            "physics_wall_s": round(physics, 4),
            "physics_real_time_factor": round(sim / physics, 3),
            "physics_share_of_episode": round(physics / episode_sim_wall, 3)},
        "from_fork": {
            "fork_time_s": t_fork, "sim_time_s": round(sim - t_fork, 4),
            "episode_wall_s": round(statistics.median(tail), 4),
            "physics_wall_s": round(physics_tail, 4),
            "physics_share": round(physics_tail / statistics.median(tail), 3)},
    }
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    args.json.write_text(json.dumps(report, indent=1) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
