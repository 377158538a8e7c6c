"""One episode: build the station, throw, (watch or catch), read the outcome."""

import dataclasses as dc
import hashlib
import math
import pickle
import time

import numpy as np
from pydrake.math import RigidTransform

from regrasp_drake import memo
from regrasp_drake.parameter_space import HELD_OUTCOMES
from regrasp_drake.planning import grasp
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.grasp_monitor import (
    GraspMonitor,
    Outcome,
    contact_verdict,
)
from regrasp_drake.station.scenario import (
    Scenario,
    catch_phase_scenario,
    scenario_digest,
    target_of,
)
from regrasp_drake.station.start_pose import start_poses
from regrasp_drake.station.station import (
    EpisodeDiagram,
    Loggers,
    build_episode_diagram,
    continue_with,
    fixed_catch_parameters,
    initialize,
)
from regrasp_drake.world.objects import ObjectSpec


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


@dc.dataclass
class EpisodeResult:
    object: str
    outcome: str            # caught | dropped | timeout | landed | failed
    h_catch: float | None
    h_down: float | None
    # None only for a forked cell whose process died (branching.run_cells).
    sim_time_s: float | None
    wall_s: float | None
    build_s: float          # 0 for a forked cell: it builds nothing
    catch_time_s: float | None  # when the grasp was recognized, [s]
    message: str
    logs: Logs | None
    p_WO_final: list | None = None  # the object's final position, [m]
    # Why a dropped episode counts as dropped (DropReason, lower case); the
    # bodies the object touches at the end, whether they hold it, and its
    # slip (m/s) and spin (rad/s) relative to the palm then (`read_ending`).
    drop_reason: str | None = None
    touching: list | None = None
    held_by_contact: bool | None = None
    slip_m_per_s: float | None = None
    spin_rad_per_s: float | None = None
    # The grasp (planning/grasp.py): the scenario's target, how the object
    # lay on the palm before the throw, the grasp it is held in at the end
    # (None when not held) and its error against the target.
    target: dict | None = None
    start_grasp: dict | None = None
    achieved_grasp: dict | None = None
    grasp_error: dict | None = None

    @property
    def caught(self) -> bool:
        """Held at the end, in whatever grasp."""
        return self.outcome in HELD_OUTCOMES

    @property
    def success(self) -> bool:
        """Held in the target grasp (for target `any`: held)."""
        return self.outcome == "caught"

    def regrasp_line(self) -> str:
        """e.g. "flip, +0 mm: achieved flip, +3 mm, tilt 12°"."""
        return grasp.describe(self.target, self.achieved_grasp)

    def summary(self) -> dict:
        return {
            "object": self.object, "success": self.success,
            "caught": self.caught, "target": self.target,
            "start_grasp": self.start_grasp,
            "achieved_grasp": self.achieved_grasp,
            "grasp_error": self.grasp_error,
            "outcome": self.outcome, "h_catch": self.h_catch,
            "h_down": self.h_down, "sim_time_s": round(self.sim_time_s, 4),
            "wall_s": round(self.wall_s, 3),
            "catch_time_s": self.catch_time_s, "message": self.message,
            "drop_reason": self.drop_reason, "touching": self.touching,
            "held_by_contact": self.held_by_contact,
        }

    def cell_row(self) -> dict:
        """The row a success map keeps of a cell (grid.run_map): JSON, its
        times rounded (0.1 ms simulated, 1 ms wall), the object's final
        position unrounded (it shows any difference)."""
        return {
            "h_catch": self.h_catch, "h_down": self.h_down,
            "outcome": self.outcome,
            "sim_time_s": _rounded(self.sim_time_s, 4),
            "catch_time_s": self.catch_time_s, "message": self.message,
            "wall_s": _rounded(self.wall_s, 3),
            "p_WO_final": self.p_WO_final,
            "drop_reason": self.drop_reason, "touching": self.touching,
            "held_by_contact": self.held_by_contact,
            "slip_m_per_s": self.slip_m_per_s,
            "spin_rad_per_s": self.spin_rad_per_s,
            "target": self.target, "start_grasp": self.start_grasp,
            "achieved_grasp": self.achieved_grasp,
            "grasp_error": self.grasp_error,
        }


def _rounded(value: float | None, digits: int) -> float | None:
    return None if value is None else round(value, digits)


def run_episode(scenario: Scenario, obj: ObjectSpec, *, ik: ArmIk,
                X_WG: RigidTransform | None, catch_parameters=None,
                mlp_features=None, meshcat=None,
                throw_number: int = 1, at_release=None,
                throws: "ThrowCache | None" = None) -> EpisodeResult:
    """Throws `obj` and, unless X_WG is None (a watching throw), catches it.
    throw_number seeds the release noise, if the scenario has any.
    throws: the cache of throws simulated to their release this episode
    goes on from and keeps its throw in (default: the process's, THROWS).

    at_release: plans the catch while the object flies. Called once, when
    the throw ends (`release_time`, before the state machine reads the grasp
    pose), with the object's state then (13: quaternion wxyz, p_WO, w_WO,
    v_WO) and the time; it returns the grasp pose X_WG and the catch
    parameters (h_catch, h_down) that replace the ones given, None (the
    ones given stay: nothing in the episode changes), or raises
    InputError (no catch planned: the episode ends there and the error
    propagates). Requires catch_parameters and an X_WG (any: it is
    replaced)."""
    t0 = time.perf_counter()
    start = start_grasp(scenario, obj)

    def rebuild(later):
        return build_episode_diagram(
            later, obj, ik=ik, X_WG=X_WG, catch_parameters=catch_parameters,
            mlp_features=mlp_features, meshcat=meshcat,
            throw_number=throw_number)

    catch_parameters = fixed_catch_parameters(scenario, X_WG,
                                              catch_parameters)
    throws = THROWS if throws is None else throws
    key = throws.key(scenario, obj, throw_number, catch_parameters, meshcat)
    handover = throws.resume(key, rebuild, X_WG, catch_parameters, ik)
    if handover is not None:  # this throw's release, simulated before
        build_s = time.perf_counter() - t0
    else:
        episode = build_episode_diagram(
            scenario, obj, ik=ik, X_WG=X_WG,
            catch_parameters=catch_parameters, mlp_features=mlp_features,
            meshcat=meshcat, throw_number=throw_number)
        if meshcat is not None:
            meshcat.StartRecording(set_visualizations_while_recording=False)
        simulator = initialize(episode, scenario)
        build_s = time.perf_counter() - t0
        handover = hand_over(simulator, episode, scenario, rebuild)
        throws.keep(key, handover)
    simulator, episode, scenario = handover.now
    message = handover.message
    if handover.running:
        if at_release is not None:
            try:
                _plan_at_release(simulator, episode, scenario, at_release)
            except Exception:
                if meshcat is not None:
                    meshcat.StopRecording()
                raise
        message = advance_to_outcome(simulator, episode, scenario)
    wall_s = time.perf_counter() - t0
    if meshcat is not None:
        meshcat.StopRecording()
        meshcat.PublishRecording()
    context = simulator.get_context()
    logs = handover.logs(_read_logs(episode.loggers, context))
    h = logs.params[:, -1] if logs.params.shape[1] else (None, None)
    return read_result(
        episode, context, scenario, obj, start, message=message,
        h_catch=None if X_WG is None else float(h[0]),
        h_down=None if X_WG is None else float(h[1]),
        wall_s=wall_s, build_s=build_s, logs=logs)


def read_result(episode: EpisodeDiagram, context, scenario: Scenario,
                obj: ObjectSpec, start: grasp.Grasp, *, message: str,
                h_catch: float | None, h_down: float | None, wall_s: float,
                build_s: float = 0.0, logs: Logs | None = None
                ) -> EpisodeResult:
    """The result of the episode that ended in `context` (its simulator's,
    at the end) with `message` (advance_to_outcome's): its outcome, how it
    ended (read_ending) and the grasp against the scenario's target
    (judge_grasp). The one reader of an episode's end, for `run_episode`
    and for every forked cell (branching.run_cells)."""
    outcome, grasp_t = read_outcome(episode, context, message)
    ending = read_ending(episode, context, outcome)
    outcome, grasp_fields = judge_grasp(scenario, obj, episode, context,
                                        outcome, start)
    station = episode.station
    return EpisodeResult(
        object=obj.name, outcome=outcome, h_catch=h_catch, h_down=h_down,
        sim_time_s=context.get_time(), wall_s=wall_s, build_s=build_s,
        catch_time_s=grasp_t, message=message, logs=logs,
        p_WO_final=station.plant.EvalBodyPoseInWorld(
            station.plant.GetMyContextFromRoot(context),
            station.object_body).translation().tolist(),
        **ending, **grasp_fields)


def start_grasp(scenario: Scenario, obj: ObjectSpec) -> grasp.Grasp:
    """How the object lies on the palm before the throw (the station's
    start poses)."""
    X_WP, X_WO = start_poses(scenario, obj)
    X_PO = X_WP.inverse() @ X_WO
    return grasp.measure(obj, X_PO.rotation().matrix(), X_PO.translation())


def read_grasp(episode: EpisodeDiagram, context, obj: ObjectSpec,
               start: grasp.Grasp) -> grasp.Grasp:
    """The grasp the object is in now, from the plant's poses of the palm's
    palm_surface frame and the object."""
    station = episode.station
    plant = station.plant
    plant_context = plant.GetMyContextFromRoot(context)
    X_WP = plant.GetFrameByName("palm_surface", station.hand).CalcPoseInWorld(
        plant_context)
    X_PO = X_WP.inverse() @ plant.EvalBodyPoseInWorld(plant_context,
                                                      station.object_body)
    return grasp.measure(obj, X_PO.rotation().matrix(), X_PO.translation(),
                         np.asarray(start.R_PO))


def judge_grasp(scenario: Scenario, obj: ObjectSpec, episode: EpisodeDiagram,
                context, outcome: str, start: grasp.Grasp) -> tuple[str, dict]:
    """The outcome against the scenario's target, and the grasp's fields
    of a result (EpisodeResult's `target` ... `grasp_error`): a catch the
    grasp monitor recognized ("caught") becomes "wrong_grasp" when the
    grasp it ends in is not the target's (planning/grasp.judge)."""
    target = target_of(scenario)
    held = outcome == "caught"
    achieved = read_grasp(episode, context, obj, start) if held else None
    verdict = grasp.judge(target, obj, start, achieved, held)
    if held and not verdict.success:
        outcome = "wrong_grasp"
    return outcome, {
        "target": target.as_dict(), "start_grasp": start.as_dict(),
        "achieved_grasp": None if achieved is None else achieved.as_dict() | {
            "kind": grasp.kind_of(obj, start, achieved)},
        "grasp_error": verdict.as_dict()}


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
        first = _read_logs(episode.loggers, simulator.get_context())
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
    (station.continue_with). Without a catch step of its own, or when the
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


class ThrowCache:
    """The throws already simulated to their release, to go on from again.

    Every throw of an object repeats the same initial conditions, and until
    the release time nothing in an episode reads the grasp pose, the catch
    parameters or whether it watches: the throw's simulation to the release
    is the same for a watching throw and for every catch of the object. So
    the first episode of an object keeps its throw's simulator at the
    handover (`hand_over`'s `before`: it is only read from there on), and a
    later one builds its catch's diagram and goes on from that state
    (`station.continue_with`, which copies it), with its own grasp pose and
    parameters set: the same episode bit for bit (tested), without the
    throw's 3 280 steps of 0.25 ms. Kept for the last `size` throws, in
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
        # (key, watching) -> (ik, the catch's diagram built for it): a
        # diagram holds no state (that is in each simulator's context), so
        # the later episodes of a throw go on in the same one.
        self._diagrams = {}
        self.hits = 0

    def key(self, scenario, obj, throw_number, catch_parameters, meshcat):
        """The throw's key, or None when it cannot be reused (see above)."""
        if (not self.enabled or meshcat is not None
                or catch_parameters is None
                or catch_phase_scenario(scenario) is None):
            return None
        perturbation = ThrowPerturbation.draw(scenario.throw.noise,
                                              throw_number)
        return (scenario_digest(scenario),
                hashlib.sha256(pickle.dumps(obj)).hexdigest(),
                repr(perturbation))

    def keep(self, key, handover: "Handover") -> None:
        if key is None or not handover.running or handover.before is None:
            return
        self._kept.pop(key, None)
        self._kept[key] = (*handover.before, handover.now[2])
        while len(self._kept) > self.size:
            del self._kept[next(iter(self._kept))]
        self._diagrams = {k: v for k, v in self._diagrams.items()
                          if k[0] in self._kept}

    def resume(self, key, rebuild, X_WG, catch_parameters, ik):
        """A Handover that goes on from the kept throw of `key` with the
        diagram `rebuild(later)` builds (built once per throw, watching or
        not, and arm IK `ik`), its grasp pose and catch parameters set;
        None when there is none."""
        if key is None or key not in self._kept:
            return None
        simulator, episode, later = self._kept[key]
        built = self._diagrams.get((key, X_WG is None))
        if built is None or built[0] is not ik:
            built = self._diagrams[key, X_WG is None] = (ik, rebuild(later))
        other = built[1]
        target = continue_with(simulator, episode, other, later)
        # continue_with copied the kept throw's pose and parameters.
        other.controller.set_task(
            target.get_mutable_context(),
            X_WG=X_WG if X_WG is not None else RigidTransform(),
            catch_parameters=catch_parameters)
        self.hits += 1
        return Handover((target, other, later), (simulator, episode), "",
                        True, tuple(float(p) for p in catch_parameters))

    def clear(self) -> None:
        self._kept.clear()
        self._diagrams.clear()


THROWS = ThrowCache()
memo.register("throws", THROWS)


def _plan_at_release(simulator, episode: EpisodeDiagram, scenario,
                     at_release) -> None:
    """Advances to the release time, asks at_release for the plan, and sets
    the grasp pose and catch parameters in the context (none, when it
    returns None). Drake handles the update events of a time at the start
    of the next step, so the state machine's update at this time reads the
    new values."""
    t = release_time(scenario)
    if simulator.get_context().get_time() < t:  # not handed over there
        simulator.AdvanceTo(t)
    context = simulator.get_mutable_context()
    station, controller = episode.station, episode.controller
    state = station.Eval("object_state", context)
    planned = at_release(np.asarray(state).copy(), t)
    if planned is None:
        return
    X_WG, parameters = planned
    controller.set_task(context, X_WG=X_WG, catch_parameters=parameters)


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
    monitor_state = _monitor_state(episode, context)
    outcome = "failed" if message else GraspMonitor.outcome(
        monitor_state).name.lower()
    grasp_t = GraspMonitor.grasp_time(monitor_state)
    return outcome, (grasp_t if grasp_t >= 0 else None)


def read_ending(episode: EpisodeDiagram, context, outcome: str) -> dict:
    """How the episode ended, beyond its outcome: `drop_reason`, which of
    the grasp monitor's tests made it dropped ("near_ground", "below_palm",
    "not_held"; None unless dropped), and, from the plant's contact results
    in the final state (grasp_monitor.contact_verdict), `touching`, the
    names of the bodies in contact with the object, sorted (a held object
    touches fingers and the palm; one that came to rest on the palm against
    the arm touches the palm and an arm link), `held_by_contact`, whether
    the contacts hold it, and the object's `slip_m_per_s` and
    `spin_rad_per_s` relative to the palm. The contact fields are None when
    they cannot be computed, as after a failed contact solve. Reading them
    does not change the simulation."""
    reason = None
    if outcome == "dropped":
        reason = GraspMonitor.drop_reason(
            _monitor_state(episode, context)).name.lower()
    station = episode.station
    plant = station.plant
    try:
        contacts = contact_verdict(
            plant, plant.GetMyContextFromRoot(context), station.object_body,
            plant.GetBodyByName("palm", station.hand))
    except Exception:  # the solve that ended the episode fails again
        contacts = dict.fromkeys(_CONTACT_FIELDS)
    return {"drop_reason": reason} | contacts


_CONTACT_FIELDS = ("touching", "held_by_contact", "slip_m_per_s",
                   "spin_rad_per_s")


def _monitor_state(episode: EpisodeDiagram, context) -> np.ndarray:
    monitor = episode.controller.monitor
    return monitor.GetOutputPort("monitor_state").Eval(
        monitor.GetMyContextFromRoot(context))


def _read_logs(loggers: Loggers, context) -> Logs:
    def log(sink):
        return sink.FindLog(context).data().copy()
    times = loggers.object.FindLog(context).sample_times().copy()
    return Logs(t=times, object_state=log(loggers.object),
                ir=log(loggers.ir), bumper=log(loggers.bumper)[0],
                phase=log(loggers.phase)[0], actuation=log(loggers.actuation),
                arm_state=log(loggers.arm), params=log(loggers.params))


__all__ = ["EpisodeResult", "Logs", "Outcome", "read_result",
           "run_episode"]
