"""Whether the hand holds an object laid at rest in a target grasp: the
static test a target must pass before a throw aims for it.

The object is laid in the target grasp (the start grasp turned as the
target asks, slid to its offset along the object's axis) on the open hand
at the throw's start pose (the palm level, facing up), let come to rest
there (start_pose.rest_pose), and the fingers close on it at the catch's
finger speed, the arm's joints held; `hold_s` after they are closed, the
object must be held by the contacts (the thumb and another finger, no
slip: grasp_monitor.contact_verdict) in the target grasp
(planning/grasp.judge). How the hand closes is tried several ways
(`CLOSINGS`: where across the palm the object lies, whether the fingers
start from the catch's pre-shape, the order and speed they close in); a
target no closing holds is one the
catch cannot end in whatever it does before the fingers close
(`check_holdable` refuses it before the throw, when the scenario asks).
No throw, no landing: what it tests is the closing alone.
"""

import copy
import dataclasses as dc
import pickle

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.episode.result import palm_grasp
from regrasp_drake.errors import InputError
from regrasp_drake.memo import Memo
from regrasp_drake.planning import grasp
from regrasp_drake.planning.catch_plan import lowest_point_along
from regrasp_drake.station import throw
from regrasp_drake.station.catch_state_machine import (
    FingerRamp,
    closing_delays,
    preshape_posture,
)
from regrasp_drake.station.grasp_monitor import contact_verdict
from regrasp_drake.station.plant import BUMPER_THICKNESS_M, add_world
from regrasp_drake.station.scenario import (
    Scenario,
    catch_step_s,
    scenario_digest,
    target_of,
)
from regrasp_drake.station.start_pose import rest_pose, start_poses
from regrasp_drake.world import robot
from regrasp_drake.world.object_model import ObjectSpec


@dc.dataclass(frozen=True)
class Closing:
    """How the hand closes on the laid object: where across the palm it
    lies (toward the fingertips, [m]; None: where the catch's palm pose puts
    it, catch.palm_toward_fingers_m), whether the fingers start from the
    catch's pre-shape (catch.preshape_closure) instead of open, in which
    order they close (robot.CLOSING_ORDERS) and at what
    fraction of their speed."""
    name: str
    across_m: float | None = None
    from_preshape: bool = False
    order: str = "together"
    speed_fraction: float = 1.0


# Where across the palm the object lies and whether the fingers start from
# the pre-shape, all closing together at full speed.
PLACED_CLOSINGS = (
    Closing("open, at the catch's place"),
    Closing("pre-shaped, at the catch's place", from_preshape=True),
    Closing("open, centred", across_m=0.0),
    Closing("open, 20 mm toward the fingertips", across_m=0.02))
# The orders and speeds the fingers can close in (catch.closing_order; half
# speed as a check that the servos' speed is not what drops the object).
ORDERED_CLOSINGS = tuple(
    Closing(f"{start}, {how}, at the catch's place", from_preshape=pre,
            order=order, speed_fraction=speed)
    for start, pre in (("open", False), ("pre-shaped", True))
    for how, order, speed in (("thumb first", "thumb_first", 1.0),
                              ("fingers first", "fingers_first", 1.0),
                              ("half speed", "together", 0.5)))
# The closings tried, in turn, until one holds.
CLOSINGS = PLACED_CLOSINGS + ORDERED_CLOSINGS


def closing_named(name: str, field: str = "closing") -> Closing:
    """The closing of CLOSINGS called `name` (InputError naming `field`)."""
    for closing in CLOSINGS:
        if closing.name == name:
            return closing
    raise InputError(f"{field}: got {name!r}, expected one of "
                     f"{[c.name for c in CLOSINGS]}")


@dc.dataclass(frozen=True)
class StaticHold:
    """What the static test saw: the grasp the object rested in on the open
    hand (`rest`, None: it did not come to rest there), the grasp after the
    fingers closed and held (`closed`, None: not measured), whether the
    contacts held it, the verdict against the target and why it missed."""
    object: str
    target: grasp.Target
    rest: dict | None
    closed: dict | None
    held: bool
    success: bool
    reason: str | None
    grasp_error: dict | None
    # The closing that held (success), or the last one tried; how many were.
    closing: str = CLOSINGS[0].name
    tried: int = 1

    def line(self) -> str:
        """One line: the object, the target and what the test saw."""
        head = f"object {self.object}, target {self.target.label()}"
        if self.rest is None:
            return f"{head}: does not rest on the open palm in that grasp"
        seen = (f"rests at {self.rest['offset_mm']:+.1f} mm, "
                f"{self.rest['tilt_deg']:.0f}° on the open hand")
        if self.success:
            return f"{head}: held at rest ({seen}; closed: " \
                   f"{grasp.describe_grasp(self.closed)})"
        closed = ("not held once the fingers close" if not self.held
                  else f"closed: {grasp.describe_grasp(self.closed)}")
        return f"{head}: no closing of the hand holds it at rest " \
               f"({self.tried} tried; the last, {self.closing}: " \
               f"{self.reason}; {seen}; {closed})"


def static_hold(scenario: Scenario, obj: ObjectSpec,
                target: grasp.Target | None = None, *, hold_s: float = 1.0,
                step_s: float | None = None,
                closings: tuple = CLOSINGS) -> StaticHold:
    """The static test of `obj` in `target` (None: the scenario's), at the
    plant step `step_s` (None: the catch's; no impact to resolve, the
    contacts slow: benchmarks/static_hold.py checks it at the landing's),
    with each of `closings` in turn until one holds. Computed once per
    scenario, object, target and step in a process (STATIC_HOLDS)."""
    target = target or target_of(scenario)
    key = (scenario_digest(scenario), pickle.dumps(obj), target, hold_s,
           step_s, closings)

    def compute():
        for n, closing in enumerate(closings, 1):
            test = dc.replace(_static_hold(scenario, obj, target, hold_s,
                                           step_s, closing),
                              closing=closing.name, tried=n)
            if test.success:
                break
        return test
    return STATIC_HOLDS.get(key, compute)


STATIC_HOLDS = Memo("static holds")


def check_holdable(scenario: Scenario, obj: ObjectSpec) -> None:
    """Refuses (InputError) a grasp target the closed hand does not hold at
    rest (`static_hold`), when the scenario asks for the check
    (regrasp.check_hold); `any` is never refused."""
    if scenario.regrasp.target == "any" or not scenario.regrasp.check_hold:
        return
    test = static_hold(scenario, obj)
    if not test.success:
        raise InputError(test.line() + "; expected a target the hand can "
                         "hold (regrasp.check_hold: false, the default, runs "
                         "it anyway)")


def target_pose(scenario: Scenario, obj: ObjectSpec, target: grasp.Target,
                across_m: float | None = None
                ) -> tuple[RigidTransform, RigidTransform, grasp.Grasp]:
    """(X_WP, X_WO, start grasp): the palm at the throw's start pose and
    the object in `target`'s grasp there, across_m toward the fingertips
    (None: where the catch's palm pose puts it,
    catch.palm_toward_fingers_m), its lowest point 1 mm above the bumper
    (not yet at rest)."""
    X_WP, X_WO_start = start_poses(scenario, obj)
    start = palm_grasp(obj, X_WP, X_WO_start)
    R_PO = grasp.target_orientation(target, start)
    p_PO = (X_WP.inverse() @ X_WO_start).translation().copy()
    p_PO[0] += (scenario.catch.palm_toward_fingers_m if across_m is None
                else across_m)
    # Slid along the object's axis (R_PO's y): the offset, the palm
    # centre's place on the axis, moves the other way.
    laid = grasp.measure(obj, R_PO, p_PO, np.asarray(start.R_PO))
    p_PO = p_PO - R_PO[:, 1] * 1e-3 * (target.offset_mm - laid.offset_mm)
    lowest = lowest_point_along(obj, R_PO, p_PO, [0.0, 0.0, 1.0])
    p_PO[2] += BUMPER_THICKNESS_M + 1e-3 - lowest
    X_PO = RigidTransform(RotationMatrix(R_PO), p_PO)
    return X_WP, X_WP @ X_PO, start


def _static_hold(scenario, obj, target, hold_s, step_s,
                 closing: Closing) -> StaticHold:
    def result(rest, closed, held, verdict):
        error = None if verdict is None else verdict.as_dict()
        success = bool(verdict is not None and verdict.success)
        return StaticHold(
            object=obj.name, target=target, rest=rest, closed=closed,
            held=held, success=success,
            reason=None if success else grasp.miss_reason(held, error),
            grasp_error=error)

    X_WP, X_WO, start = target_pose(scenario, obj, target, closing.across_m)
    try:
        X_WO = rest_pose(scenario, obj, X_WO)
    except InputError:
        return result(None, None, False, None)
    rest = palm_grasp(obj, X_WP, X_WO, start).as_dict()
    plant_scenario = copy.deepcopy(scenario)
    plant_scenario.plant_config.time_step = step_s or (
        catch_step_s(scenario) or scenario.plant_config.time_step)
    builder = DiagramBuilder()
    plant, _, instances, body, _ = add_world(builder, plant_scenario, obj)
    simulator = Simulator(builder.Build())
    context = simulator.get_mutable_context()
    pc = plant.GetMyMutableContextFromRoot(context)
    plant.SetPositions(pc, instances.arm, throw.start_q(scenario.throw))
    for index in plant.GetJointIndices(instances.arm):
        plant.get_joint(index).Lock(pc)
    for instance in (instances.arm, instances.hand):
        plant.get_actuation_input_port(instance).FixValue(
            pc, np.zeros(plant.num_actuated_dofs(instance)))
    plant.SetFreeBodyPose(pc, body, X_WO)
    desired = plant.get_desired_state_input_port(instances.hand)
    q_open = np.asarray(robot.HAND_OPEN, float)
    q_closed = np.asarray(robot.HAND_CLOSED, float)
    q_from = (preshape_posture(scenario.catch, q_open, q_closed)
              if closing.from_preshape else q_open)
    plant.SetPositions(pc, instances.hand, q_from)
    speed = closing.speed_fraction * robot.FINGER_MAX_SPEED
    ramp = FingerRamp(q_from, q_closed, speed, delay=closing_delays(
        closing.order, q_from, q_closed, speed))
    simulator.Initialize()
    # The fingers' reference, from open to closed at their speed as the
    # catch ramps it, set every sensor period (the catch's update rate).
    period = scenario.sensors.period_s
    closing_s = ramp.duration
    for k in range(int(np.ceil((closing_s + hold_s) / period))):
        desired.FixValue(pc, np.concatenate(ramp.at(k * period)))
        simulator.AdvanceTo((k + 1) * period)
    palm = plant.GetBodyByName("palm", instances.hand)
    held = contact_verdict(plant, pc, body, palm)["held_by_contact"]
    X_WP_end = plant.GetFrameByName("palm_surface", instances.hand
                                    ).CalcPoseInWorld(pc)
    closed = palm_grasp(obj, X_WP_end, plant.EvalBodyPoseInWorld(pc, body),
                        start)
    verdict = grasp.judge(target, obj, start, closed, held)
    return result(rest, closed.as_dict() | {
        "kind": grasp.kind_of(obj, start, closed)}, held, verdict)
