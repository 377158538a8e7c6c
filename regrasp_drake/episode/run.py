"""One episode: build the station, throw, (watch or catch), read the outcome.

The steps, each with one home: to the release time
(episode.simulate.start_episode: a throw simulated before gone on from, or
build, station.build_episode_diagram; initialise, station.initialize; and
hand over at the release time to the catch's plant step, under the catch's
scenario), advance (episode.simulate.advance_to_outcome), read
(`read_result`: the outcome, how it ended, the grasp against the target)."""

import dataclasses as dc
import time

import numpy as np
from pydrake.math import RigidTransform

from regrasp_drake.episode.simulate import (
    THROWS,
    Logs,
    ThrowCache,
    advance_to_outcome,
    monitor_state,
    read_logs,
    read_outcome,
    release_time,
    start_episode,
)
from regrasp_drake.parameter_space import HELD_OUTCOMES
from regrasp_drake.planning import grasp
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.grasp_monitor import (
    GraspMonitor,
    Outcome,
    contact_verdict,
)
from regrasp_drake.station.scenario import (
    Scenario,
    target_of,
)
from regrasp_drake.station.start_pose import start_poses
from regrasp_drake.station.station import (
    EpisodeDiagram,
    build_episode_diagram,
    fixed_catch_parameters,
)
from regrasp_drake.world.objects import ObjectSpec


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
    start_pose = start_grasp(scenario, obj)
    catch_parameters = fixed_catch_parameters(scenario, X_WG,
                                              catch_parameters)

    def build(s):
        return build_episode_diagram(
            s, obj, ik=ik, X_WG=X_WG, catch_parameters=catch_parameters,
            mlp_features=mlp_features, meshcat=meshcat,
            throw_number=throw_number)

    handover, build_s = start_episode(
        scenario, obj, build, ik=ik, X_WG=X_WG,
        catch_parameters=catch_parameters, throw_number=throw_number,
        meshcat=meshcat, throws=THROWS if throws is None else throws)
    # From here on the episode goes on under the catch's scenario.
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
    logs = handover.logs(read_logs(episode.loggers, context))
    h = logs.params[:, -1] if logs.params.shape[1] else (None, None)
    return read_result(
        episode, context, scenario, obj, start_pose, message=message,
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
            monitor_state(episode, context)).name.lower()
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


__all__ = ["EpisodeResult", "Logs", "Outcome", "read_result",
           "run_episode"]
