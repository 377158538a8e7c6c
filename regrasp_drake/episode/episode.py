"""One episode you can hold, run in stages:

    episode = Episode(scenario, obj, ik=ik, X_WG=X_WG, catch_parameters=h)
    episode.start()                      # built (or a kept throw resumed)
    release = episode.advance_to_release()   # the object at the release
    episode.set_task(X_WG=..., catch_parameters=...)  # the catch planned
    episode.advance_to_outcome()         # until the grasp monitor ends it
    result = episode.result()            # the outcome, the grasp, the logs

`run_episode` is those stages in one call, with an optional `at_release`
plan. Here too, the handover at the release time (station/throw.py's
`release_time`) to the catch's plant step (`hand_over`), and the throws
kept to go on from (`ThrowCache`). What it simulates, and how a simulator
of it is started and advanced, is episode/diagram.py's; what it came to,
episode/result.py's.

What the episode derives from its scenario before it runs is derived once,
here, and handed on: the throw's release noise (`Episode.perturbation`, for
the kept throw's key and the state machine) and the catch parameters held
fixed."""

import dataclasses as dc
import hashlib
import math
import pickle
import time

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from regrasp_drake import memo
from regrasp_drake.episode.diagram import (
    EpisodeDiagram,
    advance_to_outcome,
    build_episode_diagram,
    continue_with,
    fixed_catch_parameters,
    initialize,
)
from regrasp_drake.episode.result import (
    EpisodeResult,
    Logs,
    read_logs,
    read_outcome,
    read_result,
)
from regrasp_drake.planning.follow import NO_FOLLOW
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.scenario import (
    Scenario,
    catch_phase_scenario,
    hands_over,
    landing_phase_scenario,
    scenario_digest,
)
from regrasp_drake.station.throw import release_time
from regrasp_drake.world.objects import ObjectSpec


@dc.dataclass
class Handover:
    """An episode handed over, at the release time, from the throw's plant
    step to the catch's (scenario.catch_time_step_s; see `hand_over`)."""
    # What the episode goes on with: the catch's simulator, diagram and
    # scenario, or the throw's when there was no handover.
    simulator: Simulator
    diagram: EpisodeDiagram
    scenario: Scenario
    # The throw's (simulator, diagram) when handed over, for its logs.
    before: tuple[Simulator, EpisodeDiagram] | None = None
    # A failure's message, if the episode failed before the release time.
    message: str = ""
    # False when the episode ended before the release time.
    running: bool = True
    # The catch parameters of this episode when its throw was simulated
    # for another (ThrowCache): its logs show this episode's from the start.
    parameters: tuple | None = None
    # The catch's (simulator, diagram, scenario) when handed over again, to
    # the landing's plant step (Episode.advance_to_outcome), for its logs;
    # and the landing's (simulator, diagram) when handed back.
    landed: tuple | None = None
    settled: tuple[Simulator, EpisodeDiagram] | None = None

    def logs(self, after: Logs) -> Logs:
        """The whole episode's logs: the throw's, the catch's before the
        landing when handed over there, then `after`'s (the loggers of the
        diagram it ended in)."""
        logs = None
        for segment in (self.before, self.landed, self.settled):
            if segment is None:
                continue
            simulator, episode = segment[:2]
            part = read_logs(episode.loggers, simulator.get_context())
            if segment is self.before and self.parameters is not None:
                part.params = np.tile(np.reshape(self.parameters, (2, 1)),
                                      (1, part.params.shape[1]))
            logs = part if logs is None else _joined(logs, part)
        return after if logs is None else _joined(logs, after)


def _joined(first: Logs, then: Logs) -> Logs:
    """`first`'s logs, then `then`'s after them. Both diagrams log the
    handover's time: the first as its last step ends, the next as its
    simulator starts there. The first is the one a run without the
    handover logs."""
    keep = then.t > first.t[-1]
    return Logs(**{f.name: np.concatenate(
        [getattr(first, f.name), getattr(then, f.name)[..., keep]],
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
    t = release_time(scenario)
    later = catch_phase_scenario(scenario)
    if later is None:
        return Handover(simulator, episode, scenario)
    message = advance_to_outcome(simulator, episode, scenario, t)
    context = simulator.get_context()
    if (message or context.get_time() < t
            or read_outcome(episode, context, "")[0] != "running"):
        return Handover(simulator, episode, scenario, message=message,
                        running=False)
    other = rebuild(later)
    simulator_later = continue_with(simulator, episode, other, later)
    return Handover(simulator_later, other, later,
                    before=(simulator, episode))


def landing_time(episode: EpisodeDiagram, context,
                 scenario: Scenario) -> tuple[float, float]:
    """When a catch goes on at the landing's plant step, [s]:
    scenario.landing_lead_s before the object's centre of mass, in free
    flight from its state in `context`, falls to the height of the palm's
    grasp pose (its wait pose: the lowering only takes the palm away). Now,
    if it is not above that height or not falling to it. Also the time of
    that fall, [s]."""
    x = episode.station.Eval("object_state", context)
    z, v_z = x[6], x[12]  # p_WO's and v_WO's z
    X_WG = episode.controller.grasp_pose.GetOutputPort("X_WG").Eval(
        episode.controller.grasp_pose.GetMyContextFromRoot(context))
    height = z - X_WG.translation()[2]
    g = scenario.gravity_m_per_s2
    t = context.get_time()
    fall = ((v_z + np.sqrt(v_z ** 2 + 2.0 * g * height)) / g
            if height > 0.0 and g > 0.0 else 0.0)
    t_landing = on_sample(t + fall - scenario.landing_lead_s,
                          scenario.sensors.period_s)
    return max(t, t_landing), t + fall


def on_sample(t: float, period: float) -> float:
    """The first of the sensors' samples (every `period`, [s]) at or after
    t, [s]: a handover's time, as the release's (a whole step of either
    plant ends there, and its events run in the next diagram)."""
    return math.ceil(t / period - 1e-9) * period


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
    (catch_time_step_s) and no Meshcat (which must record the throw). A
    catch whose parameters the MLP system predicts goes on in a diagram
    built for it (its network and features), where the MLP predicts them
    at the release time (diagram.continue_with). A throw with release
    noise is its own (its perturbation is part of the key). `enabled =
    False` turns it off."""

    def __init__(self, size: int = 2):
        self.size = size
        self.enabled = True
        # key -> (simulator, episode, the catch's scenario), oldest first
        self._kept = {}
        # key -> (ik, the diagram at the catch's step the throw's episodes
        # go on in, built with arm IK ik)
        self._diagrams = {}
        # key -> (ik, the diagram at the landing's step, Episode._land)
        self._landings = {}
        self.hits = 0

    def key(self, scenario, obj, perturbation: ThrowPerturbation,
            catch_parameters, meshcat):
        """The key of the throw of `obj` perturbed by `perturbation`, or None
        when it cannot be reused (see above)."""
        if (not self.enabled or meshcat is not None
                or not hands_over(scenario)):
            return None
        return (scenario_digest(scenario),
                hashlib.sha256(pickle.dumps(obj)).hexdigest(),
                repr(perturbation))

    def keep(self, key, handover: "Handover", ik) -> None:
        """Keeps the throw `handover` handed over (at the release time) and
        the diagram it goes on in, built with arm IK `ik`."""
        if key is None or not handover.running or handover.before is None:
            return
        self._kept.pop(key, None)
        self._kept[key] = (*handover.before, handover.scenario)
        # The diagram goes on with fixed parameters (set_task), not an MLP's.
        if handover.diagram.controller.features is None:
            self._diagrams[key] = (ik, handover.diagram)
        else:
            self._diagrams.pop(key, None)
        while len(self._kept) > self.size:
            del self._kept[next(iter(self._kept))]
        self._diagrams = {k: v for k, v in self._diagrams.items()
                          if k in self._kept}
        self._landings = {k: v for k, v in self._landings.items()
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
        if catch_parameters is None:  # the MLP's: a diagram of its own
            other = rebuild(later)
        else:
            if built is None or built[0] is not ik:
                built = self._diagrams[key] = (ik, rebuild(later))
            other = built[1]
        target = continue_with(simulator, episode, other, later)
        # continue_with copied the kept throw's task (but for the MLP's
        # parameters).
        context = target.get_mutable_context()
        other.controller.set_task(
            context, X_WG=X_WG if X_WG is not None else RigidTransform(),
            catch_parameters=catch_parameters, watching=X_WG is None)
        self.hits += 1
        parameters = other.controller.parameters
        return Handover(target, other, later, before=(simulator, episode),
                        parameters=tuple(float(p) for p in
                                         parameters.get_output_port().Eval(
                                             parameters.GetMyContextFromRoot(
                                                 context))))

    def landing_diagram(self, episode: "Episode", later: Scenario
                        ) -> EpisodeDiagram:
        """The diagram at the landing's step `later` that `episode` goes on
        in (Episode._land): the one kept with its throw, else built."""
        # Kept for catches with fixed parameters only, as the catch's
        # diagram is (`keep`): one with the MLP's is built for it.
        key = episode.throw_key if episode.catch_parameters is not None else None
        kept = self._landings.get(key) if key is not None else None
        if kept is None or kept[0] is not episode.ik:
            kept = (episode.ik, episode.build(later))
            if key is not None and key in self._kept:
                self._landings[key] = kept
        return kept[1]

    def clear(self) -> None:
        self._kept.clear()
        self._diagrams.clear()
        self._landings.clear()


THROWS = ThrowCache()
memo.register("throws", THROWS)


@dc.dataclass(frozen=True)
class Release:
    """The object at the release time, when the catch may still be planned
    (`Episode.set_task`): the state machine reads the grasp pose at the
    first update from here on."""
    t: float                  # the release time, [s]
    object_state: np.ndarray  # (13,): quaternion wxyz, p_WO, w_WO, v_WO


class Episode:
    """One throw of `obj` and, unless X_WG is None (a watching throw), its
    catch, held between the stages of its run (see the module's docstring).

    X_WG: the palm's grasp pose; catch_parameters: (h_catch, h_down), [m],
    or None: the grid cell of the MLP system in the diagram, fed with
    `mlp_features`, with the network `model` (None: the scenario's
    catch.weights; build_episode_diagram); meshcat records the episode from
    its start; throw_number: which throw of a run this is: with it the
    scenario's throw.noise draws this throw's release noise, once
    (`perturbation`); throws: the cache of throws simulated to their release
    this episode goes on from and keeps its throw in (default: the
    process's, THROWS); follow: how the palm follows the object
    (planning/follow.plan_follow; None: not at all)."""

    def __init__(self, scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                 X_WG: RigidTransform | None, catch_parameters=None,
                 mlp_features=None, model=None, meshcat=None,
                 throw_number: int = 1, throws: ThrowCache | None = None,
                 follow=None):
        self._t0 = time.perf_counter()
        self.obj, self.ik = obj, ik
        self.follow = follow
        self.X_WG, self.mlp_features, self.model = X_WG, mlp_features, model
        self.meshcat = meshcat
        # This throw's release noise, for the kept throw's key and the
        # state machine.
        self.perturbation = ThrowPerturbation.draw(scenario.throw.noise,
                                                   throw_number)
        self.throws = THROWS if throws is None else throws
        self.catch_parameters = fixed_catch_parameters(
            scenario, X_WG, catch_parameters, mlp_features)
        # The throw's scenario; the catch's (at its plant step) once handed
        # over at the release time.
        self.scenario = scenario
        self.simulator = None
        self.diagram: EpisodeDiagram | None = None
        self.handover: Handover | None = None
        self.message = ""   # a failure's, once the episode failed
        # The handovers to come through the landing (advance_to_outcome):
        # [(time [s], what hands over)], made at its first call.
        self._handovers: list | None = None
        self.landing_at = None  # when handed over to the landing's step, [s]
        self.throw_key = None  # its throw's in `throws` (ThrowCache.key)
        self.build_s = 0.0  # the wall time to build and initialise, [s]
        self._recording = meshcat is not None

    def build(self, scenario: Scenario) -> EpisodeDiagram:
        """The episode's diagram for `scenario` (the throw's, or the
        catch's at the handover)."""
        return build_episode_diagram(
            scenario, self.obj, ik=self.ik, X_WG=self.X_WG,
            catch_parameters=self.catch_parameters,
            mlp_features=self.mlp_features, model=self.model,
            meshcat=self.meshcat, perturbation=self.perturbation)

    def start(self) -> None:
        """Stage 1: the episode to its release time: its throw kept in
        `throws` gone on from (ThrowCache.resume), or else built, initialised
        (Meshcat recording from the start), simulated to the release time
        and handed over to the catch's plant step when the scenario has one
        (`hand_over`), and kept. The scenario it goes on under is the
        catch's from here."""
        t0 = time.perf_counter()
        key = self.throw_key = self.throws.key(
            self.scenario, self.obj, self.perturbation,
            self.catch_parameters, self.meshcat)
        handover = self.throws.resume(key, self.build, self.X_WG,
                                      self.catch_parameters, self.ik)
        if handover is None:
            diagram = self.build(self.scenario)
            if self.meshcat is not None:
                self.meshcat.StartRecording(
                    set_visualizations_while_recording=False)
            simulator = initialize(diagram, self.scenario)
            self.build_s = time.perf_counter() - t0
            handover = hand_over(simulator, diagram, self.scenario,
                                 self.build)
            self.throws.keep(key, handover, self.ik)
        else:
            self.build_s = time.perf_counter() - t0
        self.handover = handover
        self.simulator = handover.simulator
        self.diagram = handover.diagram
        self.scenario = handover.scenario
        self.message = handover.message
        if self.running:  # read with the grasp pose, after the release
            self.set_task(follow=(NO_FOLLOW if self.follow is None
                                  else self.follow))

    @property
    def running(self) -> bool:
        """Started, and not ended before the release time."""
        return self.handover is not None and self.handover.running

    def advance_to_release(self) -> Release:
        """Stage 2: the episode at its release time (where a handover left
        it already), and the object's state there."""
        t = release_time(self.scenario)
        if self.simulator.get_context().get_time() < t:  # not handed over
            self.simulator.AdvanceTo(t)
        state = self.diagram.station.Eval("object_state",
                                          self.simulator.get_context())
        return Release(t=t, object_state=np.asarray(state).copy())

    def set_task(self, *, X_WG: RigidTransform | None = None,
                 catch_parameters=None, follow=None) -> None:
        """Stage 3: the grasp pose, the catch parameters (h_catch,
        h_down), [m], and the palm's follow (planning/follow.plan_follow)
        set in the running context (None leaves one as it is). Drake
        handles the update events of a time at the start of the next step,
        so the state machine's update at the release time reads them."""
        self.diagram.controller.set_task(
            self.simulator.get_mutable_context(), X_WG=X_WG,
            catch_parameters=catch_parameters, follow=follow)

    def advance_to_outcome(self, t_final: float | None = None) -> str:
        """Stage 4: on until the grasp monitor (or a failure) ends the
        episode, or to t_final, [s]. Returns "" or the failure's message.

        Under a grasp target with a landing step of its own
        (scenario.landing_time_step_s), the catch is handed over to it, state
        for state, landing_lead_s before the object's predicted fall to the
        palm (`landing_time`), and back to the catch's step
        landing_settle_s after that fall, if set."""
        if t_final is None:
            t_final = self.scenario.monitor.max_time_s + 1.0
        if self._handovers is None:
            # Planned from the object's flight, at the release time.
            self._handovers = [(release_time(self.scenario),
                                self._plan_handovers)]
        while self._handovers and self._handovers[0][0] < t_final:
            t, handover = self._handovers.pop(0)
            # Not advanced to a time it is at: Drake would handle the events
            # of that time, which belong to the next diagram (hand_over).
            if self.simulator.get_context().get_time() < t:
                self.message = advance_to_outcome(
                    self.simulator, self.diagram, self.scenario, t)
                if self.message or self.outcome() != "running":
                    return self.message
            handover()
        self.message = advance_to_outcome(self.simulator, self.diagram,
                                          self.scenario, t_final)
        return self.message

    def _plan_handovers(self) -> None:
        """The landing's handovers of this catch, planned from the object's
        flight now (the release time), put first in the list of those to
        come: [(time [s], what hands over)]; none for a watching throw or
        without a landing step of its own. `landing_at`: the first's
        time."""
        later = landing_phase_scenario(self.scenario)
        if self.X_WG is None or later is None:
            return
        t_landing, t_fall = landing_time(
            self.diagram, self.simulator.get_context(), self.scenario)
        self.landing_at = t_landing
        handovers = [(t_landing, lambda: self._land(later))]
        settle = self.scenario.landing_settle_s
        if settle is not None:
            period = self.scenario.sensors.period_s
            t_back = max(t_landing, on_sample(t_fall + settle, period))
            handovers.append((t_back, self._land_back))
        self._handovers[:0] = handovers

    def _land(self, later: Scenario) -> None:
        """The episode handed over to the landing's plant step `later`
        (scenario.landing_phase_scenario), state for state."""
        other = self.throws.landing_diagram(self, later)
        simulator = continue_with(self.simulator, self.diagram, other, later)
        self.handover.landed = (self.simulator, self.diagram, self.scenario)
        self.simulator, self.diagram, self.scenario = simulator, other, later

    def _land_back(self) -> None:
        """The episode handed back from the landing's plant step to the
        catch's, in the diagram it ran in before the landing."""
        _, other, before = self.handover.landed
        simulator = continue_with(self.simulator, self.diagram, other, before)
        self.handover.settled = (self.simulator, self.diagram)
        self.simulator, self.diagram, self.scenario = simulator, other, before

    def outcome(self) -> str:
        """What the grasp monitor has decided so far: "running" until the
        episode ends (result.read_outcome; a failure is not counted)."""
        return read_outcome(self.diagram, self.simulator.get_context(),
                            "")[0]

    def stop_recording(self) -> None:
        """Meshcat's recording of this episode stopped, once."""
        if self._recording:
            self._recording = False
            self.meshcat.StopRecording()

    def result(self) -> EpisodeResult:
        """Stage 5: what the episode came to (result.read_result), with the
        whole episode's logs; Meshcat's recording published."""
        wall_s = time.perf_counter() - self._t0
        if self._recording:
            self.stop_recording()
            self.meshcat.PublishRecording()
        context = self.simulator.get_context()
        logs = self.handover.logs(read_logs(self.diagram.loggers, context))
        watching = self.X_WG is None
        h = logs.params[:, -1] if logs.params.shape[1] else (None, None)
        return read_result(
            self.diagram, context, self.scenario, self.obj, message=self.message,
            h_catch=None if watching else float(h[0]),
            h_down=None if watching else float(h[1]),
            wall_s=wall_s, build_s=self.build_s, logs=logs)

    def run(self, at_release=None) -> EpisodeResult:
        """Every stage in turn; `at_release` as run_episode's."""
        self.start()
        if self.running:
            if at_release is not None:
                try:
                    release = self.advance_to_release()
                    planned = at_release(release.object_state, release.t)
                except Exception:
                    self.stop_recording()
                    raise
                if planned is not None:
                    X_WG, parameters, *follow = planned
                    self.set_task(X_WG=X_WG, catch_parameters=parameters,
                                  follow=follow[0] if follow else None)
            self.advance_to_outcome()
        return self.result()


def run_episode(scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                X_WG: RigidTransform | None, catch_parameters=None,
                mlp_features=None, model=None, meshcat=None,
                throw_number: int = 1, at_release=None,
                throws: ThrowCache | None = None,
                follow=None) -> EpisodeResult:
    """Throws `obj` and, unless X_WG is None (a watching throw), catches it:
    an `Episode` run through its stages. Arguments as Episode's.

    at_release: plans the catch while the object flies. Called once, at the
    release time (before the state machine reads the grasp pose), with the
    object's state then (13: quaternion wxyz, p_WO, w_WO, v_WO) and the
    time; it returns the grasp pose X_WG and the catch parameters (h_catch,
    h_down) that replace the ones given (None: they stay), and optionally
    the palm's follow (planning/follow.plan_follow), None (nothing
    in the episode changes), or raises InputError (no catch planned: the
    episode ends there and the error propagates). Requires an X_WG (any:
    it is replaced), and catch_parameters to replace them."""
    return Episode(scenario, obj, ik=ik, X_WG=X_WG,
                   catch_parameters=catch_parameters,
                   mlp_features=mlp_features, model=model, meshcat=meshcat,
                   throw_number=throw_number, throws=throws, follow=follow
                   ).run(at_release)
