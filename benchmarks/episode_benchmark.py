"""Benchmark of one catch episode: real-time factors, and where the time goes.

    .venv/bin/python benchmarks/episode_benchmark.py [--object table1-row2]
        [--h-catch 0.3] [--h-down -0.07] [--runs 5]
        [--json benchmarks/episode_benchmark.json]
        [--png benchmarks/episode_benchmark.png]

The episode is the one `regrasp-drake catch --object OBJECT --h-catch H
--h-down D` runs: watch, plan (`plan_watched`), catch with the release's
correction. Three figures, each the median of --runs in this one run
(machines are noisy: compare figures from one run, not across runs):
`catch_throw_reused`, the catch going on from its throw simulated before
(episode.ThrowCache: what `catch`, `learn`, `apply` and every map cell
run), its `sim_time_s` over its `wall_s` as `catch --json` reports them;
`episode_from_start`, the same episode simulated from the start, no cache;
and `split`, for each of the two and for a forked map cell, the shares of
the simulation's wall time taken by the physics alone, our systems and
Drake's framework (the arm controller, events, caches: the rest).

Our systems' Python callbacks are timed from inside (CallbackTimer). The
physics alone is the same plant (arm, hand, object, ground; same time step
and contact) replayed with the inputs the episode gave it at every step,
with no controller and no Python system. It ends in the episode's final
state bit for bit (checked: `identical_final_state`), so it is the same
physics, contact for contact: what no change to the systems around the
plant can go below. The episode runs at two plant steps (the throw's to
the release time, the catch's, `catch_time_step_s`, from there:
`plant_steps`), so its physics is replayed in two segments, each on the
plant of its step; the catch with its throw reused simulates the second.
The forked cell's part runs from the trigger (the first sample in LOWER,
less one sample: what each forked cell of a success map simulates).
`peak_memory_gib`: this process's peak resident set size. Also printed as
JSON and drawn as a PNG of the split.

Over 500 lines as one benchmark: its runs, the physics replay, the split and its plot.
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
from regrasp_drake.episode.episode import (
    THROWS,
    advance_to_outcome,
    hand_over,
    release_time,
    run_episode,
)
from regrasp_drake.station.scenario import catch_phase_scenario, load_scenario
from regrasp_drake.station.scenario_checks import check_catch_parameters
from regrasp_drake.episode.diagram import (
    build_episode_diagram,
    continue_with,
    hand_idle_until_handover,
    initialize,
    lock_hand,
)
from regrasp_drake.throw_catch import (
    plan_watched,
    release_correction,
    watch,
)
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

    from regrasp_drake.station.plant import add_world
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
    if hand_idle_until_handover(segment.scenario):  # as the episode's throw
        lock_hand(plant, context, instances.hand)
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
    handed = hand_over(
        simulator, episode, scenario,
        lambda later: build_episode_diagram(later, obj, ik=ik, X_WG=X_WG,
                                            catch_parameters=params))
    simulator, episode, scenario = (handed.simulator, handed.diagram,
                                    handed.scenario)
    simulator.AdvanceTo(t_start)
    if timer is not None:
        timer.reset()
    t0 = time.perf_counter()
    advance_to_outcome(simulator, episode, scenario)
    return time.perf_counter() - t0


def catch_episode(scenario, obj, ik, plan, params):
    """The catching episode `regrasp-drake catch` runs after its watch:
    `plan` (plan_watched) and the release's correction, with the throw
    cache as it is (episode.THROWS)."""
    return run_episode(scenario, obj, ik=ik, X_WG=plan.X_WG,
                       catch_parameters=params,
                       at_release=release_correction(scenario, obj, ik, plan,
                                                     params))


def real_time_factors(results) -> dict:
    """Median over `results` of sim_time_s / wall_s (as `catch --json`
    reports both), and the median wall time."""
    return {"real_time_factor": round(statistics.median(
                r.sim_time_s / r.wall_s for r in results), 3),
            "median_wall_s": round(statistics.median(
                r.wall_s for r in results), 4),
            "median_build_s": round(statistics.median(
                r.build_s for r in results), 4)}


def throw_reused(scenario, obj, ik, plan, params, runs, fresh) -> tuple:
    """The catch going on from its throw simulated before, as `regrasp-drake
    catch` runs it: a watch (episode.ThrowCache keeps its throw), then the
    catch, which goes on from the kept throw in the watch's diagram;
    `runs` times (the watches not timed), checked equal to the episode
    simulated from the start (`fresh`), and once more with our callbacks
    timed. Returns (report, the timed run's CallbackTimer report, that
    run's simulation wall s)."""
    THROWS.enabled = True

    def catch(timer=None):
        THROWS.clear()
        watch(scenario, obj, ik)
        if timer is not None:
            timer.reset()
        return catch_episode(scenario, obj, ik, plan, params)

    results = [catch() for _ in range(runs)]
    with CallbackTimer() as timer:
        timed = catch(timer)
    THROWS.enabled = False
    report = {"sim_time_s": round(fresh.sim_time_s, 4),
              "simulated_from_s": round(release_time(scenario), 4)}
    report |= real_time_factors(results)
    report["identical_to_from_start"] = all(
        r.outcome == fresh.outcome and r.p_WO_final == fresh.p_WO_final
        for r in results + [timed])
    return report, timer.report(), timed.wall_s - timed.build_s


def split(physics_s, wall_s, callbacks, timed_wall_s) -> dict:
    """Shares of a simulation's wall time: the physics alone (`physics_s`,
    replayed) of `wall_s` (the median of the untimed runs), our systems
    (the CallbackTimer report `callbacks`) of `timed_wall_s` (the run they
    were timed in), Drake's framework the rest."""
    ours = sum(v["s"] for v in callbacks.values())
    physics, our_systems = physics_s / wall_s, ours / timed_wall_s
    return {"wall_s": round(wall_s, 4), "physics_s": round(physics_s, 4),
            "our_systems_s": round(ours, 4),
            "timed_run_wall_s": round(timed_wall_s, 4),
            "physics": round(physics, 3),
            "our_systems": round(our_systems, 3),
            "framework": round(1.0 - physics - our_systems, 3),
            "our_systems_callbacks": callbacks}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(
        description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--object", default="table1-row2")
    parser.add_argument("--h-catch", type=float, default=0.3)
    parser.add_argument("--h-down", type=float, default=-0.07)
    parser.add_argument("--runs", type=int, default=5)
    parser.add_argument("--json", type=Path,
                        default=Path("benchmarks/episode_benchmark.json"))
    parser.add_argument("--png", type=Path,
                        default=Path("benchmarks/episode_benchmark.png"))
    args = parser.parse_args(argv)
    try:
        if args.runs < 1:
            raise InputError(f"--runs {args.runs}: expected >= 1")
        check_catch_parameters(args.h_catch, args.h_down,
                               names=("--h-catch", "--h-down"))
        try:
            obj = resolve_object(name=args.object)
        except InputError as e:
            raise InputError(f"--object {args.object}: {e}") from None
    except InputError as e:
        print(f"episode_benchmark: error: {e}", file=sys.stderr)
        return 2
    torch.set_num_threads(1)
    scenario = load_scenario()
    params = (args.h_catch, args.h_down)
    # The episode from the start: no throw cache (measured on its own below).
    THROWS.enabled = False
    ik = ArmIk(scenario.directives)
    plan = plan_watched(scenario, obj, ik, watch(scenario, obj, ik))
    results = [catch_episode(scenario, obj, ik, plan, params)
               for _ in range(args.runs)]
    sim = results[0].sim_time_s
    with CallbackTimer() as timer:  # one more run, our callbacks timed
        timed = catch_episode(scenario, obj, ik, plan, params)
    callbacks = timer.report()
    report = {
        "object": obj.name, "h_catch": params[0], "h_down": params[1],
        "outcome": results[0].outcome, "runs": args.runs,
        "sim_time_s": round(sim, 4),
        "outcomes_identical": len({r.outcome for r in results + [timed]}) == 1,
    }
    report["episode_from_start"] = real_time_factors(results)
    reused, reused_callbacks, reused_timed_wall = throw_reused(
        scenario, obj, ik, plan, params, args.runs, results[0])
    report["catch_throw_reused"] = reused
    report["catch_throw_reused_over_from_start"] = round(
        reused["real_time_factor"]
        / report["episode_from_start"]["real_time_factor"], 3)

    # The physics alone, replayed (see replayed_physics_wall_s): over the
    # whole episode, over the catch from the release (what the catch with
    # its throw reused simulates), and from the trigger (the first sample
    # in LOWER, less one sample: where a success map forks this cell).
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
    replay, replay_catch, replay_tail, tail = [], [], [], []
    for _ in range(args.runs):
        parts = [replayed_physics_wall_s(obj, segment)
                 for segment in segments]
        replay.append((sum(w for w, _ in parts),
                       all(same for _, same in parts)))
        replay_catch.append(parts[-1][0])
        replay_tail.append(replayed_physics_wall_s(obj, last, k_fork))
        tail.append(episode_from_wall_s(
            scenario, obj, ik, plan.X_WG, params, t_fork))
    with CallbackTimer() as timer:
        tail_timed = episode_from_wall_s(scenario, obj, ik, plan.X_WG, params,
                                         t_fork, timer)
    median = statistics.median
    report["plant_steps"] = [
        {"time_step_s": segment.dt,
         "from_s": round(segment.k0 * segment.dt, 6),
         "steps": len(segment.u_arm)} for segment in segments]
    report["identical_final_state"] = (
        p_WO_end == results[0].p_WO_final
        and all(same for _, same in replay + replay_tail))
    from_start = report["episode_from_start"]
    report["split"] = {
        "episode_from_start": split(
            median(w for w, _ in replay),
            from_start["median_wall_s"] - from_start["median_build_s"],
            callbacks, timed.wall_s - timed.build_s),
        "catch_throw_reused": split(
            median(replay_catch),
            reused["median_wall_s"] - reused["median_build_s"],
            reused_callbacks, reused_timed_wall),
        "forked_cell": split(median(w for w, _ in replay_tail), median(tail),
                             timer.report(), tail_timed)
        | {"from_s": t_fork, "sim_time_s": round(sim - t_fork, 4)},
    }
    report["peak_memory_gib"] = round(
        resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20, 3)
    print(json.dumps(report, indent=1))
    args.json.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.write_json(args.json, report)
    plot_shares(report, args.png)
    return 0


def shares(report) -> dict:
    """Per part (the episode from the start, the catch with its throw
    reused, a forked cell): the shares of its simulation's wall time taken
    by the physics alone, our systems and the framework (report["split"])."""
    sim = report["sim_time_s"]
    reused = report["catch_throw_reused"]["simulated_from_s"]
    names = {"episode_from_start": f"episode from the start ({sim:g} s)",
             "catch_throw_reused":
                 f"catch, throw reused ({sim - reused:g} s simulated)",
             "forked_cell": "forked map cell "
                            f"({report['split']['forked_cell']['sim_time_s']:g} s)"}
    return {names[k]: {key: v[key] for key in ("physics", "our_systems",
                                                "framework")}
            for k, v in report["split"].items()}


def plot_shares(report, path: Path) -> None:
    """A PNG: one stacked bar per part (see shares)."""
    import matplotlib
    matplotlib.use("Agg")
    import matplotlib.pyplot as plt
    parts = shares(report)
    fig, ax = plt.subplots(figsize=(8, 3.2))
    colours = {"physics": "#4c72b0", "our_systems": "#dd8452",
               "framework": "#bbbbbb"}
    labels = {"physics": "physics alone (replayed bit for bit)",
              "our_systems": "our systems (Python callbacks)",
              "framework": "framework (arm controller, Drake's events, caches)"}
    for i, (name, share) in enumerate(parts.items()):
        left = 0.0
        for key in ("physics", "our_systems", "framework"):
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
    ax.set_title(
        f"{report['object']}: where an episode's time goes (from the start "
        f"{report['episode_from_start']['real_time_factor']:g}x real time, "
        f"throw reused {report['catch_throw_reused']['real_time_factor']:g}x)",
        fontsize=9)
    ax.legend(fontsize=7, loc="upper center", bbox_to_anchor=(0.5, -0.3),
              ncol=2, frameon=False)
    fig.tight_layout()
    path.parent.mkdir(parents=True, exist_ok=True)
    atomic_io.save_figure(fig, path, dpi=110)
    plt.close(fig)


if __name__ == "__main__":
    sys.exit(main())
