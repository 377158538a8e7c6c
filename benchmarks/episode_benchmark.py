"""Benchmark of one catch episode: wall time, real-time factor, where the time goes.

    .venv/bin/python benchmarks/episode_benchmark.py [--object table1-row2] [--runs 5]
        [--json benchmarks/episode_benchmark.json]
        [--png benchmarks/episode_benchmark.png]

Prints the figures and writes them as JSON, and a PNG of the split (physics
alone, our Python callbacks, the rest). Not a test: machines are noisy;
compare figures from one run. Our Python callbacks are timed from inside
(CallbackTimer). For comparison, the same run times the episode's physics
alone: the same plant (arm, hand, object, ground; same time step and
contact) replayed with the inputs the episode gave it at every step, with no
controller and no Python system. It ends in the episode's final state bit
for bit (checked: `identical_final_state`), so it is the same physics,
contact for contact: what no change to the systems around the plant can go
below. Both are measured over the whole episode and from the cell's fork
(the trigger: what each forked cell of a success map simulates). The
episode runs at two plant steps (the throw's to the release time, the
catch's, `catch_time_step_s`, from there: `plant_steps`), so its physics is
replayed in two segments, each on the plant of its step. `peak_memory_gib`:
this process's peak resident set size (an episode's, its replays' and the
arm's inverse kinematics'). `throw_reused`: the same episode going on from
its throw simulated before (episode.ThrowCache, what an object's episodes
after its first do), its wall time and real-time factors, checked equal to
the episode simulated from the start.
"""

# regrasp_drake before NumPy: it pins NumPy's and OpenBLAS's kernels
# (regrasp_drake/numerics.py), so that results match across x86-64 machines.
import regrasp_drake  # noqa: F401, I001 (first, see above)
import argparse
import dataclasses as dc
import json
import math
import resource
import statistics
import sys
import time
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import atomic_io
from regrasp_drake.errors import InputError
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.episode import (
    THROWS,
    advance_to_outcome,
    hand_over,
    release_time,
    run_episode,
)
from regrasp_drake.station.scenario import catch_phase_scenario, load_scenario
from regrasp_drake.station.station import (
    build_episode_diagram,
    continue_with,
    initialize,
)
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import resolve_object

class CallbackTimer:
    """Times our systems' Python callbacks from inside (perf_counter around
    each call; cProfile, used here before, inflated these small calls
    several times). Use as a context manager around building and running a
    station: the events bind the callbacks when a system is constructed."""

    def __init__(self):
        from regrasp_drake.station.catch_state_machine import CatchStateMachine
        from regrasp_drake.station.grasp_monitor import GraspMonitor
        from regrasp_drake.station.sensors import InfraredSensors, TactileBumper
        self._callbacks = {
            "infrared sensors": (InfraredSensors, "_sample"),
            "tactile bumper": (TactileBumper, "_sample"),
            "catch state machine": (CatchStateMachine, "_update"),
            "grasp monitor": (GraspMonitor, "_update"),
        }
        self.seconds = dict.fromkeys(self._callbacks, 0.0)
        self.calls = dict.fromkeys(self._callbacks, 0)
        self._originals = {}

    def reset(self):
        """Counts from here on only."""
        for name in self.seconds:
            self.seconds[name], self.calls[name] = 0.0, 0

    def __enter__(self):
        for name, (cls, attr) in self._callbacks.items():
            original = self._originals[name] = getattr(cls, attr)

            def timed(system, *args, _original=original, _name=name):
                t0 = time.perf_counter()
                try:
                    return _original(system, *args)
                finally:
                    self.seconds[_name] += time.perf_counter() - t0
                    self.calls[_name] += 1
            setattr(cls, attr, timed)
        return self

    def __exit__(self, *exc):
        for name, (cls, attr) in self._callbacks.items():
            setattr(cls, attr, self._originals[name])

    def report(self) -> dict:
        return {name: {"s": round(self.seconds[name], 4),
                       "calls": self.calls[name],
                       "us_per_call": round(1e6 * self.seconds[name]
                                            / max(1, self.calls[name]), 1)}
                for name in self.seconds}


@dc.dataclass
class Segment:
    """The plant's inputs over one part of an episode simulated at one plant
    step (the throw's, then the catch's after the handover): per plant step
    k0, k0 + 1, ..., the arm's actuation, the fingers' desired state and the
    plant's state before the step ((steps, n) arrays), and the plant's state
    at the segment's end."""
    scenario: object
    k0: int
    u_arm: np.ndarray
    u_hand: np.ndarray
    x: np.ndarray
    x_end: np.ndarray

    @property
    def dt(self) -> float:
        return self.scenario.plant_config.time_step


def record_plant_inputs(scenario, obj, ik, X_WG, params):
    """Runs the episode step by step to its end (handed over to the catch's
    step at the release time, as run_episode does) and returns what its
    plant was given and where it was, as Segments (one per plant step), and
    the object's final position (to compare with the episode's: stepping
    this way changes nothing). An input port evaluated between steps gives
    the value the plant's next step reads."""
    episode = build_episode_diagram(scenario, obj, ik=ik, X_WG=X_WG,
                                    catch_parameters=params)
    simulator = initialize(episode, scenario)
    later = catch_phase_scenario(scenario)
    t_stop = release_time(scenario) if later else math.inf
    segment, done = _record(simulator, episode, scenario, t_stop)
    segments = [segment]
    if later is not None and not done:
        other = build_episode_diagram(later, obj, ik=ik, X_WG=X_WG,
                                      catch_parameters=params)
        simulator = continue_with(simulator, episode, other, later)
        episode = other
        segments.append(_record(simulator, episode, later, math.inf)[0])
    station = episode.station
    context = station.plant.GetMyContextFromRoot(simulator.get_context())
    p_WO = station.plant.EvalBodyPoseInWorld(
        context, station.object_body).translation().tolist()
    return segments, p_WO


def _record(simulator, episode, scenario, t_stop):
    """Steps from the simulator's time to the episode's end or to t_stop;
    returns (Segment, whether the episode ended)."""
    station = episode.station
    plant = station.plant
    context = plant.GetMyContextFromRoot(simulator.get_context())
    dt = scenario.plant_config.time_step
    k0 = k = round(simulator.get_context().get_time() / dt)
    u_arm, u_hand, x = [], [], []
    done = False
    while True:
        if k > k0:  # AdvanceTo(now) would already take the first step's updates
            status = simulator.AdvanceTo(k * dt)
            if status.reason() == status.ReturnReason.kReachedTerminationCondition:
                done = True
                break  # the monitor ended the episode in step k - 1
        if k * dt >= t_stop - 1e-12:
            break
        x.append(plant.GetPositionsAndVelocities(context).copy())
        u_arm.append(plant.get_actuation_input_port(station.arm).Eval(
            context).copy())
        u_hand.append(plant.get_desired_state_input_port(station.hand).Eval(
            context).copy())
        k += 1
    return Segment(scenario, k0, np.array(u_arm), np.array(u_hand),
                   np.array(x),
                   plant.GetPositionsAndVelocities(context).copy()), done


def replayed_physics_wall_s(obj, segment: Segment, k_start=None, *,
                            k_end=None, scenario=None, configure=None):
    """Wall time of the episode's physics alone over `segment` from its plant
    step k_start (default its first) to k_end (default its end): the same
    plant (add_world), fed the recorded inputs by zero-order holds (Drake's
    TrajectorySource, in C++), with no controller, sensor, state machine or
    monitor. Returns (wall s, whether the plant's final state equals the
    segment's, bit for bit; False when stopped before its end): equal, it is
    the same physics, contact for contact. For studies of what the physics
    costs: `scenario` (default the segment's) builds the plant instead,
    and `configure(plant, scene_graph)` changes it before it runs."""
    from pydrake.systems.analysis import Simulator
    from pydrake.systems.framework import DiagramBuilder
    from pydrake.systems.primitives import TrajectorySource
    from pydrake.trajectories import PiecewisePolynomial

    from regrasp_drake.station.station import add_world
    dt, k0 = segment.dt, segment.k0
    k_start = k0 if k_start is None else k_start
    steps = len(segment.u_arm)
    k_end = k0 + steps if k_end is None else k_end
    # Step k's input holds on [(k - 1/2) dt, (k + 1/2) dt).
    breaks = [(k0 + k - 0.5) * dt for k in range(steps + 1)]

    def hold(values):
        v = values.T
        return TrajectorySource(PiecewisePolynomial.ZeroOrderHold(
            breaks, np.hstack([v, v[:, -1:]])))

    builder = DiagramBuilder()
    plant, scene_graph, instances, _, _ = add_world(
        builder, scenario or segment.scenario, obj)
    if configure is not None:
        configure(plant, scene_graph)
    builder.Connect(builder.AddSystem(hold(segment.u_arm)).get_output_port(),
                    plant.get_actuation_input_port(instances.arm))
    builder.Connect(builder.AddSystem(hold(segment.u_hand)).get_output_port(),
                    plant.get_desired_state_input_port(instances.hand))
    simulator = Simulator(builder.Build())
    root = simulator.get_mutable_context()
    root.SetTime(k_start * dt)
    context = plant.GetMyMutableContextFromRoot(root)
    plant.SetPositionsAndVelocities(context, segment.x[k_start - k0])
    simulator.Initialize()
    t0 = time.perf_counter()
    simulator.AdvanceTo(k_end * dt)
    wall = time.perf_counter() - t0
    return wall, bool(k_end == k0 + steps and np.array_equal(
        plant.GetPositionsAndVelocities(context), segment.x_end))


def episode_from_wall_s(scenario, obj, ik, X_WG, params, t_start,
                        timer=None) -> float:
    """Wall time of the whole episode's simulation from t_start (after the
    release time) to its end (what a forked cell of a success map runs,
    when t_start is the fork). `timer`, a CallbackTimer already entered: it
    counts from t_start."""
    episode = build_episode_diagram(scenario, obj, ik=ik, X_WG=X_WG,
                                    catch_parameters=params)
    simulator = initialize(episode, scenario)
    simulator, episode, scenario = hand_over(
        simulator, episode, scenario,
        lambda later: build_episode_diagram(later, obj, ik=ik, X_WG=X_WG,
                                            catch_parameters=params)).now
    simulator.AdvanceTo(t_start)
    if timer is not None:
        timer.reset()
    t0 = time.perf_counter()
    advance_to_outcome(simulator, episode, scenario)
    return time.perf_counter() - t0


def throw_reused(scenario, obj, ik, plan, params, runs, fresh,
                 fresh_wall_s) -> dict:
    """The same episode going on from its throw simulated before
    (episode.ThrowCache: what every episode of an object after its first
    does): median wall time of `runs`, checked equal to the episode
    simulated from the start (`fresh`; its median wall time
    `fresh_wall_s`)."""
    THROWS.enabled = True
    THROWS.clear()
    watch(scenario, obj, ik)  # simulates the throw, kept from the release
    results = [run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                           catch_parameters=params) for _ in range(runs)]
    THROWS.enabled = False
    wall = statistics.median(r.wall_s for r in results)
    t_release = release_time(scenario)
    return {
        "median_wall_s": round(wall, 4),
        "simulated_from_s": round(t_release, 4),
        # The episode's simulated time (the throw's included) over the wall
        # time it took with the throw reused ...
        "episode_real_time_factor": round(fresh.sim_time_s / wall, 3),
        # ... and the part simulated in it (from the release) over the same.
        "simulated_part_real_time_factor": round(
            (fresh.sim_time_s - t_release) / wall, 3),
        "speedup_over_fresh": round(fresh_wall_s / wall, 2),
        "identical_to_fresh": all(
            r.outcome == fresh.outcome and r.p_WO_final == fresh.p_WO_final
            for r in results)}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/episode_benchmark.json"))
    parser.add_argument("--png", type=Path,
                        default=Path("benchmarks/episode_benchmark.png"))
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
    # Every episode simulated from the start (the throw cache is measured
    # on its own below).
    THROWS.enabled = False
    scenario = load_scenario()
    ik = ArmIk(scenario.directives)
    plan = plan_catch(scenario, obj, ik, watch(scenario, obj, ik))
    params = (scenario.catch.h_catch_m, scenario.catch.h_down_m)
    results = []
    for _ in range(args.runs):
        results.append(run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                                   catch_parameters=params))
    walls = [r.wall_s for r in results]
    builds = [r.build_s for r in results]
    sim = results[0].sim_time_s
    # One more run with our Python callbacks timed.
    with CallbackTimer() as timer:
        timed = run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                            catch_parameters=params)
    python = timer.report()
    report = {
        "object": obj.name, "outcome": results[0].outcome,
        "runs": args.runs, "sim_time_s": round(sim, 4),
        "median_wall_s": round(statistics.median(walls), 4),
        "median_build_s": round(statistics.median(builds), 4),
        "real_time_factor": round(sim / statistics.median(walls), 3),
        "simulation_only_real_time_factor": round(
            sim / (statistics.median(walls) - statistics.median(builds)), 3),
        "timed_callbacks_run": {
            "wall_s": round(timed.wall_s - timed.build_s, 4),
            "python_callbacks": python,
            "python_s": round(sum(v["s"] for v in python.values()), 4)},
        "outcomes_identical": len({r.outcome for r in results + [timed]}) == 1,
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
    segments, p_WO_end = record_plant_inputs(scenario, obj, ik, plan.X_WG,
                                             params)
    last = segments[-1]
    k_fork = round(t_fork / last.dt)
    if k_fork < last.k0:
        print(f"episode_benchmark: error: the fork (t = {t_fork} s) comes "
              "before the handover to the catch's step", file=sys.stderr)
        return 2
    replay, replay_tail, tail = [], [], []
    for _ in range(args.runs):
        parts = [replayed_physics_wall_s(obj, segment)
                 for segment in segments]
        replay.append((sum(w for w, _ in parts),
                       all(same for _, same in parts)))
        replay_tail.append(replayed_physics_wall_s(obj, last, k_fork))
        tail.append(episode_from_wall_s(
            scenario, obj, ik, plan.X_WG, params, t_fork))
    with CallbackTimer() as timer:
        tail_timed = episode_from_wall_s(scenario, obj, ik, plan.X_WG, params,
                                         t_fork, timer)
    python_tail = timer.report()
    episode_sim_wall = statistics.median(walls) - statistics.median(builds)
    physics = statistics.median(w for w, _ in replay)
    physics_tail = statistics.median(w for w, _ in replay_tail)
    report["plant_steps"] = [
        {"time_step_s": segment.dt,
         "from_s": round(segment.k0 * segment.dt, 6),
         "steps": len(segment.u_arm)} for segment in segments]
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
            "physics_share": round(physics_tail / statistics.median(tail), 3),
            "timed_callbacks_run": {
                "wall_s": round(tail_timed, 4),
                "python_callbacks": python_tail,
                "python_s": round(sum(v["s"] for v in python_tail.values()),
                                  4)}},
    }
    report["throw_reused"] = throw_reused(
        scenario, obj, ik, plan, params, args.runs, results[0],
        statistics.median(walls))
    report["peak_memory_gib"] = round(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 3)
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(args.json, report)
    plot_shares(report, args.png)
    return 0


def shares(report) -> dict:
    """Per part (whole episode, forked cell): the shares of its simulation's
    wall time taken by the physics alone, our Python callbacks and the rest
    (the arm controller, Drake's events and caches)."""
    replayed = report["physics_replayed"]
    whole_wall = report["median_wall_s"] - report["median_build_s"]
    parts = {
        f"whole episode ({report['sim_time_s']:g} s simulated)": (
            replayed["whole_episode"]["physics_wall_s"] / whole_wall,
            report["timed_callbacks_run"]["python_s"]
            / report["timed_callbacks_run"]["wall_s"]),
        f"forked cell ({replayed['from_fork']['sim_time_s']:g} s simulated)": (
            replayed["from_fork"]["physics_share"],
            replayed["from_fork"]["timed_callbacks_run"]["python_s"]
            / replayed["from_fork"]["timed_callbacks_run"]["wall_s"]),
    }
    return {name: {"physics": p, "python": q, "rest": 1.0 - p - q}
            for name, (p, q) in parts.items()}


def plot_shares(report, path: Path) -> None:
    """A PNG: one stacked bar per part (see shares)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    parts = shares(report)
    fig, ax = plt.subplots(figsize=(8, 3.2))
    colours = {"physics": "#4c72b0", "python": "#dd8452", "rest": "#bbbbbb"}
    labels = {"physics": "physics alone (replayed bit for bit)",
              "python": "our Python callbacks",
              "rest": "the rest (arm controller, Drake's events, caches)"}
    for i, (name, share) in enumerate(parts.items()):
        left = 0.0
        for key in ("physics", "python", "rest"):
            ax.barh(i, share[key], left=left, color=colours[key],
                    label=labels[key] if i == 0 else None)
            ax.text(left + share[key] / 2, i, f"{100 * share[key]:.0f} %",
                    ha="center", va="center", fontsize=9)
            left += share[key]
    ax.set_yticks(range(len(parts)))
    ax.set_yticklabels(list(parts), fontsize=8)
    ax.invert_yaxis()
    ax.set_xlim(0, 1)
    ax.set_xlabel("share of the simulation's wall time")
    ax.set_title(f"{report['object']}: where an episode's time goes "
                 f"({report['real_time_factor']:g}x real time)", fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.3),
              ncol=2, frameon=False)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
