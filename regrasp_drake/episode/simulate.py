"""Advancing an episode's simulation: to its release time (`start_episode`:
on from a throw simulated before, `ThrowCache`, or built, initialised and
handed over to the catch's plant step, `hand_over`), to its outcome
(`advance_to_outcome`, and what the grasp monitor decided, `read_outcome`);
and the signals its loggers kept (`Logs`)."""

import dataclasses as dc
import hashlib
import math
import pickle
import time

import numpy as np
from pydrake.math import RigidTransform

from regrasp_drake import memo
from regrasp_drake.episode.diagram import (
    EpisodeDiagram,
    Loggers,
    continue_with,
    initialize,
)
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.grasp_monitor import GraspMonitor
from regrasp_drake.station.scenario import (
    Scenario,
    catch_phase_scenario,
    hands_over,
    scenario_digest,
)


@dc.dataclass
class Logs:
    """Signals sampled at the sensors' rate."""
    t: np.ndarray           # [s]
    object_state: np.ndarray  # (13, n): quaternion wxyz, p_WO, w_WO, v_WO
    ir: np.ndarray          # (13, n) levels
    bumper: np.ndarray      # (n,)
    phase: np.ndarray       # (n,)
    actuation: np.ndarray   # (16, n) net actuation, [N·m]
    arm_state: np.ndarray   # (12, n)
    params: np.ndarray      # (2, n) h_catch, h_down



def release_time(scenario: Scenario) -> float:
    """The state machine's first update at or after the throw's end, [s]: it
    reads X_WG there and the arm leaves for the grasp pose. The object flies
    free from here (the flight predictor predicts its state at this moment
    too)."""
    period = scenario.sensors.period_s
    t = throw.free_time_s(scenario)
    return math.ceil(t / period - 1e-9) * period


@dc.dataclass
class Handover:
    """An episode handed over, at the release time, from the throw's plant
    step to the catch's (scenario.catch_time_step_s; see `hand_over`)."""
    # (simulator, episode, scenario) to go on with: the catch's, or the
    # throw's when there was no handover.
    now: tuple
    # The throw's (simulator, episode) when handed over, for its logs.
    before: tuple | None
    # A failure's message, if the episode failed before the release time.
    message: str
    # False when the episode ended before the release time.
    running: bool
    # The catch parameters of this episode when its throw was simulated
    # for another (ThrowCache): its logs show this episode's from the start.
    parameters: tuple | None = None

    def logs(self, after: Logs) -> Logs:
        """The whole episode's logs: the throw's, then `after`'s (the
        loggers of the catch's diagram, from the release time on)."""
        if self.before is None:
            return after
        simulator, episode = self.before
        first = read_logs(episode.loggers, simulator.get_context())
        if self.parameters is not None:
            first.params = np.tile(np.reshape(self.parameters, (2, 1)),
                                   (1, first.params.shape[1]))
        # Both diagrams log the release time: the throw's as its last step
        # ends, the catch's as its simulator starts there. The first is the
        # one a run without the handover logs.
        keep = after.t > first.t[-1]
        return Logs(**{f.name: np.concatenate(
            [getattr(first, f.name), getattr(after, f.name)[..., keep]],
            axis=-1) for f in dc.fields(Logs)})


def hand_over(simulator, episode: EpisodeDiagram, scenario: Scenario,
              rebuild) -> Handover:
    """Simulates `episode` to the release time and goes on from there with
    the diagram `rebuild(later)` builds for `later`, the scenario at the
    catch's plant step (scenario.catch_phase_scenario), state for state
    (diagram.continue_with). Without a catch step of its own, or when the
    episode ends first, nothing is handed over. Drake handles the update
    events of a time at the start of the next step, so every event at the
    release time runs in the catch's diagram."""
    later = catch_phase_scenario(scenario)
    if later is None:
        return Handover((simulator, episode, scenario), None, "", True)
    t = release_time(scenario)
    message = advance_to_outcome(simulator, episode, scenario, t)
    context = simulator.get_context()
    if (message or context.get_time() < t
            or read_outcome(episode, context, "")[0] != "running"):
        return Handover((simulator, episode, scenario), None, message, False)
    other = rebuild(later)
    simulator_later = continue_with(simulator, episode, other, later)
    return Handover((simulator_later, other, later), (simulator, episode),
                    "", True)


def start_episode(scenario: Scenario, obj, build, *, ik, X_WG,
                  catch_parameters, throw_number: int = 1, meshcat=None,
                  throws: "ThrowCache") -> tuple[Handover, float]:
    """An episode to its release time: its throw kept in `throws`, gone on
    from (ThrowCache.resume), or else built (`build(scenario)`, the
    episode's diagram for a scenario: the throw's, and at the handover the
    catch's), initialised, simulated to the release time and handed over
    (`hand_over`), and kept. Arguments as run_episode's; `meshcat` records
    from the start. Returns the Handover (its `now` holds the scenario the
    episode goes on under: the catch's, at its plant step) and the wall
    time to build and initialise (or resume), [s]."""
    t0 = time.perf_counter()
    key = throws.key(scenario, obj, throw_number, catch_parameters, meshcat)
    handover = throws.resume(key, build, X_WG, catch_parameters, ik)
    if handover is not None:
        return handover, time.perf_counter() - t0
    episode = build(scenario)
    if meshcat is not None:
        meshcat.StartRecording(set_visualizations_while_recording=False)
    simulator = initialize(episode, scenario)
    build_s = time.perf_counter() - t0
    handover = hand_over(simulator, episode, scenario, build)
    throws.keep(key, handover, ik)
    return handover, build_s


class ThrowCache:
    """The throws already simulated to their release, to go on from again.

    Every throw of an object repeats the same initial conditions, and until
    the release time nothing in an episode reads the grasp pose, the catch
    parameters or whether it watches: the throw's simulation to the release
    is the same for a watching throw and for every catch of the object. So
    the first episode of an object keeps its throw's simulator at the
    handover (`hand_over`'s `before`: it is only read from there on) and
    the diagram it went on in from there, and a later one goes on from that
    state in that diagram (`diagram.continue_with`, which copies the
    state), with its own grasp pose, parameters and whether it watches set
    (CatchController.set_task): the same episode bit for bit (tested),
    without the throw's 3 280 steps of 0.25 ms and without building a
    diagram (a diagram holds no state: that is in each simulator's
    context). Kept for the last `size` throws, in
    the process's cache THROWS (listed in memo.caches()) unless the caller
    passes its own; only for scenarios handed over at the release time
    (catch_time_step_s), fixed catch parameters and no Meshcat (which
    must record the throw). A throw with release noise is its own (the
    perturbation is part of the key). `enabled = False` turns it off."""

    def __init__(self, size: int = 2):
        self.size = size
        self.enabled = True
        # key -> (simulator, episode, the catch's scenario), oldest first
        self._kept = {}
        # key -> (ik, the diagram at the catch's step the throw's episodes
        # go on in, built with arm IK ik)
        self._diagrams = {}
        self.hits = 0

    def key(self, scenario, obj, throw_number, catch_parameters, meshcat):
        """The throw's key, or None when it cannot be reused (see above)."""
        if (not self.enabled or meshcat is not None
                or catch_parameters is None
                or not hands_over(scenario)):
            return None
        perturbation = ThrowPerturbation.draw(scenario.throw.noise,
                                              throw_number)
        return (scenario_digest(scenario),
                hashlib.sha256(pickle.dumps(obj)).hexdigest(),
                repr(perturbation))

    def keep(self, key, handover: "Handover", ik) -> None:
        """Keeps the throw `handover` handed over (at the release time) and
        the diagram it goes on in, built with arm IK `ik`."""
        if key is None or not handover.running or handover.before is None:
            return
        self._kept.pop(key, None)
        self._kept[key] = (*handover.before, handover.now[2])
        self._diagrams[key] = (ik, handover.now[1])
        while len(self._kept) > self.size:
            del self._kept[next(iter(self._kept))]
        self._diagrams = {k: v for k, v in self._diagrams.items()
                          if k in self._kept}

    def resume(self, key, rebuild, X_WG, catch_parameters, ik):
        """A Handover that goes on from the kept throw of `key` in the
        diagram kept with it (or, for another arm IK than `ik`, the one
        `rebuild(later)` builds), with its grasp pose X_WG (None: a
        watching throw) and catch parameters set; None when there is
        none."""
        if key is None or key not in self._kept:
            return None
        simulator, episode, later = self._kept[key]
        built = self._diagrams.get(key)
        if built is None or built[0] is not ik:
            built = self._diagrams[key] = (ik, rebuild(later))
        other = built[1]
        target = continue_with(simulator, episode, other, later)
        # continue_with copied the kept throw's task.
        other.controller.set_task(
            target.get_mutable_context(),
            X_WG=X_WG if X_WG is not None else RigidTransform(),
            catch_parameters=catch_parameters, watching=X_WG is None)
        self.hits += 1
        return Handover((target, other, later), (simulator, episode), "",
                        True, tuple(float(p) for p in catch_parameters))

    def clear(self) -> None:
        self._kept.clear()
        self._diagrams.clear()


THROWS = ThrowCache()
memo.register("throws", THROWS)


def advance_to_outcome(simulator, episode: EpisodeDiagram, scenario,
                       t_final=None) -> str:
    """Advances until the grasp monitor (or a failure) ends the episode, or
    to t_final. Returns "" or the failure's message: an unreachable pose, or
    a failed contact solve (recorded, never raised)."""
    if t_final is None:
        t_final = scenario.monitor.max_time_s + 1.0
    try:
        status = simulator.AdvanceTo(t_final)
        # An unreachable pose.
        if status.system() is episode.controller.state_machine:
            return status.message()
    except Exception as e:  # a failed contact solve
        return str(e).strip().splitlines()[0] if str(e).strip() else repr(e)
    return ""


def read_outcome(episode: EpisodeDiagram, context,
                 message: str) -> tuple[str, float | None]:
    """The episode's outcome name and the time the grasp was recognized."""
    state = monitor_state(episode, context)
    outcome = "failed" if message else GraspMonitor.outcome(
        state).name.lower()
    grasp_t = GraspMonitor.grasp_time(state)
    return outcome, (grasp_t if grasp_t >= 0 else None)


def monitor_state(episode: EpisodeDiagram, context) -> np.ndarray:
    """The grasp monitor's state in the diagram's context `context`."""
    monitor = episode.controller.monitor
    return monitor.GetOutputPort("monitor_state").Eval(
        monitor.GetMyContextFromRoot(context))


def read_logs(loggers: Loggers, context) -> Logs:
    """The signals the loggers kept in the diagram's context `context`."""
    def log(sink):
        return sink.FindLog(context).data().copy()
    times = loggers.object.FindLog(context).sample_times().copy()
    return Logs(t=times, object_state=log(loggers.object),
                ir=log(loggers.ir), bumper=log(loggers.bumper)[0],
                phase=log(loggers.phase)[0], actuation=log(loggers.actuation),
                arm_state=log(loggers.arm), params=log(loggers.params))
