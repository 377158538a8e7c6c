"""The grasp monitor: recognizes a grasp from the sensors and ends the episode.

Paper §V.B: the object is grasped when all palm infrared sensors read below a
level for a sustained window, or the tactile bumper reads 1 for longer than a
window. Those two miss an object held off the palm's centre line (one palm
ray passes beside it, and it rests on the palm beside the bumper:
studies/grasp_monitor/FINDINGS.md), so a third sensor joins them, the finger
servos' encoders: the object is also grasped when the thumb and another
finger have stopped short of their goal on it while a palm sensor sees it,
for a window. The episode's outcome:
  caught   a grasp was recognized, and the object is still held (a grasp
           sensor reads a grasp) `hold_s` after the hand is back at the
           grasp position;
  dropped  the object fell below the palm, neared the ground, or was not held
           at the end of the hold (which of the three: `DropReason`);
  timeout  nothing decided by `max_time_s`;
  landed   (watching throws only) the object neared the ground.
The simulator stops as soon as the outcome is known: the periodic update
returns EventStatus.ReachedTermination.

`contact_verdict`, below, is the check of the verdict: what the plant's
contact results say is held (no sensor of a real hand gives them).
"""

import enum

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem

from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.world.robot import FINGER_LINKS, HAND_JOINTS


class Outcome(enum.IntEnum):
    RUNNING = 0
    CAUGHT = 1
    DROPPED = 2
    TIMEOUT = 3
    LANDED = 4


class DropReason(enum.IntEnum):
    """Which test of the monitor ended an episode as dropped."""
    NONE = 0         # not dropped
    NEAR_GROUND = 1  # the object's origin neared the ground
    BELOW_PALM = 2   # it fell below the palm's plane (LOWER and after)
    NOT_HELD = 3     # at the end of the hold, no grasp was recognized


# Discrete state layout.
(_OUTCOME, _IR_SINCE, _BUMPER_SINCE, _GRASP_T, _HOLD_T, _REASON,
 _FINGERS_SINCE) = range(7)
_N_HAND = len(HAND_JOINTS)
# Each finger's knuckle and distal joints (HAND_JOINTS order: each finger's
# j1 then j2, the thumb first).
_KNUCKLES, _DISTALS = slice(0, _N_HAND, 2), slice(1, _N_HAND, 2)


class GraspMonitor(LeafSystem):
    """Inputs: `ir_levels` (13), `bumper` (1), `hand_state` (the finger
    joints' q then v, HAND_JOINTS order, 20), `hand_desired_state` (their
    commanded q then v, 20), `phase` (1), `body_poses` (the plant's body
    poses). Output: `monitor_state` (the discrete state; read it with the
    static methods)."""

    def __init__(self, scenario, object_body_index, palm_body_index,
                 X_BP_palm, object_clearance_m: float, watching: bool):
        """`X_BP_palm`: the palm surface frame P in the palm body B;
        `object_clearance_m`: the object's largest distance from its frame
        origin (it is near the ground when its origin is this high);
        `watching`: whether the episode only watches (a parameter,
        `set_watching` sets it in a context)."""
        LeafSystem.__init__(self)
        m = scenario.monitor
        self._m = m
        self._object = int(object_body_index)
        self._palm = int(palm_body_index)
        self._X_BP = X_BP_palm
        self._ground_z = object_clearance_m + m.ground_clearance_m
        self._watching = self.DeclareNumericParameter(
            BasicVector([float(watching)]))
        self._ir = self.DeclareVectorInputPort("ir_levels", 13)
        self._bumper = self.DeclareVectorInputPort("bumper", 1)
        self._hand = self.DeclareVectorInputPort("hand_state", 2 * _N_HAND)
        self._hand_goal = self.DeclareVectorInputPort("hand_desired_state",
                                                      2 * _N_HAND)
        self._phase = self.DeclareVectorInputPort("phase", 1)
        self._poses = self.DeclareAbstractInputPort(
            "body_poses", AbstractValue.Make([RigidTransform()]))
        x0 = np.array([Outcome.RUNNING, -1.0, -1.0, -1.0, -1.0,
                       DropReason.NONE, -1.0])
        self._state = self.DeclareDiscreteState(x0)
        self.DeclarePeriodicDiscreteUpdateEvent(
            scenario.sensors.period_s, 0.0, self._update)
        self.DeclareStateOutputPort("monitor_state", self._state)

    def set_watching(self, context, watching: bool) -> None:
        """Judges the episode in this monitor's `context` as a watching
        throw (True: landed) or a catch (False)."""
        context.get_mutable_numeric_parameter(self._watching).SetAtIndex(
            0, float(watching))

    def _update(self, context, discrete_state):
        """The sensors' grasp readings and the outcome, every sensor sample.
        Returns None (Drake reads it as success) while running."""
        t = context.get_time()
        m = self._m
        state = discrete_state.get_mutable_value(self._state)
        x = state.tolist()
        phase = int(self._phase.Eval(context)[0])

        levels = self._ir.Eval(context)[:3]
        low_1, low_2, low_3 = levels.tolist()
        level = m.palm_grasp_level
        ir_grasp = low_1 < level and low_2 < level and low_3 < level
        bumper = self._bumper.Eval(context)[0] > 0.5
        # The cheap test first: a palm sensor sees the object.
        fingers_grasp = (m.read_fingers
                         and (bumper or ir_grasp or levels.min() < level)
                         and self._fingers_closed_on_object(context))
        x[_IR_SINCE] = _since(x[_IR_SINCE], ir_grasp, t)
        x[_BUMPER_SINCE] = _since(x[_BUMPER_SINCE], bumper, t)
        x[_FINGERS_SINCE] = _since(x[_FINGERS_SINCE], fingers_grasp, t)
        grasped = ((ir_grasp and t - x[_IR_SINCE] >= m.ir_window_s)
                   or (bumper and t - x[_BUMPER_SINCE] >= m.bumper_window_s)
                   or (fingers_grasp
                       and t - x[_FINGERS_SINCE] >= m.finger_window_s))
        if grasped and phase >= Phase.LOWER and x[_GRASP_T] < 0:
            x[_GRASP_T] = t
        if phase == Phase.HOLD and x[_HOLD_T] < 0:
            x[_HOLD_T] = t

        outcome, reason = Outcome.RUNNING, DropReason.NONE
        poses = self._poses.Eval(context)
        p_WO = poses[self._object].translation()
        near_ground = p_WO[2] < self._ground_z
        if context.get_numeric_parameter(self._watching)[0] != 0.0:
            if near_ground:
                outcome = Outcome.LANDED
        elif near_ground:
            outcome, reason = Outcome.DROPPED, DropReason.NEAR_GROUND
        elif phase >= Phase.LOWER and ((poses[self._palm] @ self._X_BP)
                                       .inverse() @ p_WO)[2] < -m.below_palm_m:
            outcome, reason = Outcome.DROPPED, DropReason.BELOW_PALM
        elif x[_HOLD_T] >= 0 and t - x[_HOLD_T] >= m.hold_s:
            held = x[_GRASP_T] >= 0 and (ir_grasp or bumper or fingers_grasp)
            outcome, reason = ((Outcome.CAUGHT, DropReason.NONE) if held else
                               (Outcome.DROPPED, DropReason.NOT_HELD))
        if outcome == Outcome.RUNNING and t >= m.max_time_s:
            outcome = Outcome.TIMEOUT
        x[_OUTCOME] = float(outcome)
        x[_REASON] = float(reason)
        state[:] = x
        if outcome != Outcome.RUNNING:
            return EventStatus.ReachedTermination(self, outcome.name.lower())
        return None

    def _fingers_closed_on_object(self, context) -> bool:
        """Whether the thumb and another finger have closed on something:
        each stopped short of its goal (a joint more than finger_stall_rad
        short of its commanded angle, toward closing) and at rest (every
        joint slower than finger_rest_rad_per_s). With the robot's
        self-collisions filtered, only the object stops a finger."""
        hand = self._hand.Eval(context)
        goal = self._hand_goal.Eval(context)
        short = goal[:_N_HAND] - hand[:_N_HAND]
        speed = np.abs(hand[_N_HAND:])
        # Per finger, its joints' largest: the joints' max, NaN as NumPy's.
        short = np.maximum(short[_KNUCKLES], short[_DISTALS])
        speed = np.maximum(speed[_KNUCKLES], speed[_DISTALS])
        m = self._m
        stopped = ((short > m.finger_stall_rad)
                   & (speed < m.finger_rest_rad_per_s)).tolist()
        return stopped[0] and any(stopped[1:])

    @staticmethod
    def outcome(monitor_state) -> Outcome:
        return Outcome(int(monitor_state[_OUTCOME]))

    @staticmethod
    def drop_reason(monitor_state) -> DropReason:
        return DropReason(int(monitor_state[_REASON]))

    @staticmethod
    def grasp_time(monitor_state) -> float:
        return float(monitor_state[_GRASP_T])


def _since(since: float, on: bool, t: float) -> float:
    """When a sensor's reading began to read a grasp: kept while it does,
    set to t when it starts, -1 while it does not."""
    return (since if since >= 0 else t) if on else -1.0


# ---- the check: what the plant's contact results say is held ---------------
# The object is held when, at the end of an episode, it touches the thumb and
# at least one finger facing the thumb, and moves with the palm: its origin
# slips slower than HELD_SLIP_M_PER_S and it turns slower than
# HELD_SPIN_RAD_PER_S relative to the palm. (At the end of the hold the hand
# is at rest; a falling or rolling object moves at decimetres per second.)
# Against the palm (its box, bumper or pads) too, it is a power grasp; off
# it, a fingertip grasp, which holds it as well: on the palm toss the
# fingers closing on an object that lands beside the palm's centre pinch it
# above the palm (studies/grasp_monitor/FINDINGS.md).
HELD_SLIP_M_PER_S = 0.02
HELD_SPIN_RAD_PER_S = 0.5
_THUMB = frozenset(FINGER_LINKS["thumb"])
_OPPOSING = frozenset(b for f, links in FINGER_LINKS.items() if f != "thumb"
                      for b in links)


def contact_verdict(plant, plant_context, object_body, palm_body) -> dict:
    """What the plant's contact results say of the object now (the check of
    the grasp monitor's verdict, not a sensor: no real hand has them).

    Returns `touching`, the names of the bodies in contact with the object,
    sorted; `slip_m_per_s` and `spin_rad_per_s`, the speed of the object's
    origin and its angular speed relative to the palm body; and
    `held_by_contact`, whether it is held: touching the thumb and another
    finger, slip and spin below HELD_SLIP_M_PER_S and HELD_SPIN_RAD_PER_S
    (`held`; `grasp_kind` tells a power grasp from a fingertip one).
    Raises what the plant raises when the contact results cannot be
    computed (after a failed contact solve)."""
    results = plant.get_contact_results_output_port().Eval(plant_context)
    me = object_body.index()
    touching = set()
    for i in range(results.num_point_pair_contacts()):
        info = results.point_pair_contact_info(i)
        a, b = info.bodyA_index(), info.bodyB_index()
        if me in (a, b):
            touching.add(plant.get_body(b if a == me else a).name())
    V_WO = plant.EvalBodySpatialVelocityInWorld(plant_context, object_body)
    V_WP = plant.EvalBodySpatialVelocityInWorld(plant_context, palm_body)
    p_PO_W = (plant.EvalBodyPoseInWorld(plant_context, object_body)
              .translation()
              - plant.EvalBodyPoseInWorld(plant_context, palm_body)
              .translation())
    # The velocity of the palm-fixed point at the object's origin: V_WP
    # shifted from the palm's origin to there.
    v_rel = V_WO.translational() - V_WP.Shift(p_PO_W).translational()
    w_rel = V_WO.rotational() - V_WP.rotational()
    slip, spin = float(np.linalg.norm(v_rel)), float(np.linalg.norm(w_rel))
    is_held = held(touching, slip, spin)
    return {"touching": sorted(touching), "held_by_contact": is_held,
            "slip_m_per_s": round(slip, 4), "spin_rad_per_s": round(spin, 4)}


def held(touching, slip_m_per_s: float, spin_rad_per_s: float) -> bool:
    """The contact verdict from the bodies touching the object and its slip
    and spin relative to the palm (a map row's `touching`, `slip_m_per_s`,
    `spin_rad_per_s` give it again)."""
    touching = set(touching)
    return bool(touching & _THUMB and touching & _OPPOSING
                and slip_m_per_s < HELD_SLIP_M_PER_S
                and spin_rad_per_s < HELD_SPIN_RAD_PER_S)


def grasp_kind(touching) -> str:
    """"power" when the palm touches the object, else "fingertip"."""
    return "power" if "palm" in set(touching) else "fingertip"
