"""The throw's timing and poses, whichever throw the scenario names
(throw.kind): "fingers", the fingers hold the object through the arm's
swing along the scenario's knots and open at the release time; or
"palm_toss", the palm tosses it (station/palm_toss.py).

Times are counted from the end of the settling, [s].
"""

import math

import numpy as np

from regrasp_drake.station.palm_toss import TossDesign, toss_trajectory


def is_toss(throw) -> bool:
    return throw.kind == "palm_toss"


def start_q(throw) -> np.ndarray:
    """The arm's joint angles at rest before the throw, [rad]."""
    if is_toss(throw):
        return np.array(throw.toss.start_q_rad, float)
    return np.array(throw.knot_q_rad[0], float)


def release_s(throw, brake_delay_s: float = 0.0) -> float:
    """When the object is let go: the fingers open, or the palm starts to
    brake (the object leaves a few ms later), `brake_delay_s` later with
    release noise (catch_state_machine.ThrowPerturbation)."""
    if is_toss(throw):
        return TossDesign.of(throw.toss, brake_delay_s=brake_delay_s
                             ).brake_start_s
    return throw.release_time_s + brake_delay_s


def let_go_time_s(scenario, brake_delay_s: float = 0.0) -> float:
    """release_s in an episode's time (the settling first), [s]."""
    throw = scenario.throw
    if is_toss(throw):
        return throw.settle_s + release_s(throw, brake_delay_s)
    return throw.settle_s + throw.release_time_s + brake_delay_s


def end_s(throw, brake_delay_s: float = 0.0) -> float:
    """When the move toward the grasp pose (or the park pose) takes over:
    the swing's last knot, or the palm toss's hand-off (the arm still
    moving, the object long gone), the toss's brake delayed by
    `brake_delay_s` (release noise, catch_state_machine.ThrowPerturbation)."""
    if is_toss(throw):
        return TossDesign.of(throw.toss, brake_delay_s=brake_delay_s).handoff_s
    return throw.knot_times_s[-1]


def free_time_s(scenario, brake_delay_s: float = 0.0) -> float:
    """end_s in an episode's time (the settling first): when the object is
    in free flight and the move toward the grasp pose takes over, [s]."""
    return scenario.throw.settle_s + end_s(scenario.throw, brake_delay_s)


def release_time(scenario) -> float:
    """The catch state machine's first update at or after the throw's end
    (free_time_s), [s]: it reads X_WG there and the arm leaves for the
    grasp pose. The object flies free from here (the flight predictor
    predicts its state at this moment too)."""
    period = scenario.sensors.period_s
    return math.ceil(free_time_s(scenario) / period - 1e-9) * period


def end_state(throw, ik) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The arm's joint angles, velocities and accelerations at end_s, [rad,
    rad/s, rad/s²] (the finger throw ends at rest)."""
    if not is_toss(throw):
        q = np.array(throw.knot_q_rad[-1], float)
        return q, np.zeros(6), np.zeros(6)
    design = TossDesign.of(throw.toss)
    trajectory = toss_trajectory(design, ik)
    return tuple(trajectory.EvalDerivative(design.handoff_s, k).ravel()
                 for k in range(3))


def grasp_ik_seed(scenario, ik) -> np.ndarray:
    """Where the inverse kinematics of the grasp pose starts: the scenario's
    catch.ik_seed_q_rad (the finger throw's last knot), or the palm toss's
    pose at its hand-off."""
    if is_toss(scenario.throw):
        return end_state(scenario.throw, ik)[0]
    return np.array(scenario.catch.ik_seed_q_rad, float)
