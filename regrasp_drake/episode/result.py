"""What an episode came to (`EpisodeResult`), read at its end
(`read_result`: the outcome, how it ended, the grasp against the target),
and the signals its loggers kept (`Logs`, `read_logs`)."""

import dataclasses as dc

import numpy as np

from regrasp_drake.episode.diagram import EpisodeDiagram, Loggers
from regrasp_drake.parameter_space import HELD_OUTCOMES
from regrasp_drake.planning import grasp
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

    @property
    def miss_reason(self) -> str | None:
        """Why it is not in the target grasp (grasp.miss_reason): dropped
        (not held), wrong_way_round, wrong_side, tilted, off_offset; None
        when it is."""
        return grasp.miss_reason(self.caught, self.grasp_error,
                                 side_apart=True)

    def regrasp_line(self) -> str:
        """The verdict first, then why (grasp.describe): e.g. "flip, +0 mm:
        in the target grasp (held flip, +3 mm, tilt 12°)", "keep, +0 mm:
        missed, tilted 29° > 20° (held keep, +2 mm, tilt 29°)"."""
        return grasp.describe(self.target, self.achieved_grasp,
                              self.grasp_error, outcome=self.outcome,
                              message=self.message)

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


def read_result(episode: EpisodeDiagram, context, scenario: Scenario,
                obj: ObjectSpec, *, message: str, h_catch: float | None,
                h_down: float | None, wall_s: float, build_s: float = 0.0,
                logs: Logs | None = None) -> EpisodeResult:
    """The result of the episode that ended in `context` (its simulator's,
    at the end) with `message` (advance_to_outcome's): its outcome, how it
    ended (read_ending) and the grasp against the scenario's target
    (judge_grasp), from the start grasp (how the object lay in the palm
    before the throw: the diagram's start poses). The one reader of an
    episode's end, for `Episode` and for every forked cell
    (branching.run_cells)."""
    outcome, grasp_t = read_outcome(episode, context, message)
    ending = read_ending(episode, context, outcome)
    start = palm_grasp(obj, episode.X_WP_initial, episode.X_WO_initial)
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
    """How the object lies on the palm before the throw (start_pose's
    start poses)."""
    return palm_grasp(obj, *start_poses(scenario, obj))


def palm_grasp(obj: ObjectSpec, X_WP, X_WO,
               start: grasp.Grasp | None = None) -> grasp.Grasp:
    """The grasp of the object at X_WO in the palm (its palm_surface frame)
    at X_WP (grasp.measure; `start`, the start grasp, says which way is
    "same"; None: this is the start grasp)."""
    X_PO = X_WP.inverse() @ X_WO
    return grasp.measure(obj, X_PO.rotation().matrix(), X_PO.translation(),
                         None if start is None else np.asarray(start.R_PO))


def read_grasp(episode: EpisodeDiagram, context, obj: ObjectSpec,
               start: grasp.Grasp) -> grasp.Grasp:
    """The grasp the object is in now, from the plant's poses of the palm's
    palm_surface frame and the object."""
    station = episode.station
    plant = station.plant
    plant_context = plant.GetMyContextFromRoot(context)
    X_WP = plant.GetFrameByName("palm_surface", station.hand).CalcPoseInWorld(
        plant_context)
    return palm_grasp(obj, X_WP, plant.EvalBodyPoseInWorld(
        plant_context, station.object_body), start)


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
    except RuntimeError:
        if outcome != "failed":
            raise
        # The contact solve that ended the episode fails again.
        contacts = dict.fromkeys(_CONTACT_FIELDS)
    return {"drop_reason": reason} | contacts


_CONTACT_FIELDS = ("touching", "held_by_contact", "slip_m_per_s",
                   "spin_rad_per_s")


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


__all__ = ["EpisodeResult", "Logs", "Outcome", "read_result"]
