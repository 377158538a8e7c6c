"""The catch that follows the object (issue 60, item 2): the palm moving
with the object along and across the palm, and turning with its pitch,
over the contact.

The lowering (catch_state_machine, LOWER) meets the object's fall; the
object also moves along the palm (0.3-0.9 m/s: a fall onto a palm tilted
parallel to the object's axis has a part along it) and turns end over end
(5.3-5.7 rad/s under flip). A
palm that waits still under it takes that motion at the impact: the
object slides and tips. Here the palm's own motion is the object's at the
planned catch moment t_c (the plan's catch point, `CatchPoint`):

- `palm_twist`: the palm frame's spatial velocity [ω; v] in W that moves
  with the object there: ω its angular velocity about the palm's +x (the
  pitch: the axis across the object, about which it turns end over end),
  v its centre of mass's velocity in the palm's plane plus
  ω × (p_P - p_Cm), so that the palm turns about the centre of mass. The
  lowering (h_down) then goes along the palm's normal
  (catch_state_machine.lowered_pose): it meets the object's velocity
  normal to the palm, the follow the rest;
- `FollowLaw`: the scalar time law G(t) of the palm's offset from the
  planned motion, o(t) = G(t) · q̇_f, with q̇_f the joint velocity that
  gives the twist at the grasp pose (`joint_follow`). The offset's rate G'
  ramps from 0 to 1 over `ramp_s` before t_c, holds 1 for `hold_s` (the
  impact, which comes after t_c: the palm lowers to meet the object), comes
  back to 0 over `stop_s` and the offset itself back to 0 over `back_s`, so
  that the hand holds at the planned grasp pose. Before the ramp the palm
  waits at -ramp_s/2 · q̇_f from the plan, so that the ramp brings it to the
  planned pose exactly at t_c;
- `joint_follow`: q̇_f, scaled down where the offset's acceleration with
  the arm's weight at the grasp pose would take more than
  catch.follow_max_torque_fraction of a servo's torque limit (the PUMA's
  limits, robot.ARM_EFFORT_LIMITS): the velocity is matched as far as the
  limits allow.

The plant still applies the effort limits (a commanded torque above them
is clipped): the scaling keeps the commanded follow within them rather
than leaving it to the clip.
"""

import dataclasses as dc

import numpy as np
from pydrake.multibody.tree import JacobianWrtVariable

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.planning.time_law import quintic
from regrasp_drake.station.scenario import target_of
from regrasp_drake.world.robot import ARM_EFFORT_LIMITS

# |s'(u)| and |s''(u)| of the quintic smoothstep s(u) = 10u³ - 15u⁴ + 6u⁵
# at most: 15/8 at u = 1/2, 10/√3 at u = (3 ∓ √3)/6.
_MAX_DS = 1.875
_MAX_DDS = 10.0 / np.sqrt(3.0)

# The palm_follow vector: t_c, then the twist [ω; v] in W.
FOLLOW_SIZE = 7
NO_FOLLOW = np.zeros(FOLLOW_SIZE)


def _smooth(u):
    """s, s', s'' of the quintic smoothstep (time_law.quintic) and its
    integral S (S(1) = 1/2), at u clipped to [0, 1] (a number or an
    array)."""
    s, ds, dds = quintic(u)
    u = np.clip(u, 0.0, 1.0)
    u2 = u * u
    return s, ds, dds, u2 * u2 * (2.5 - 3.0 * u + u2)


@dc.dataclass(frozen=True)
class FollowLaw:
    """The offset's scalar time law around the catch moment t_c (see the
    module's docstring), [s]."""
    ramp_s: float
    hold_s: float
    stop_s: float
    back_s: float

    @staticmethod
    def of(catch) -> "FollowLaw":
        """The law of a scenario's `catch` section."""
        return FollowLaw(catch.follow_ramp_s, catch.follow_hold_s,
                         catch.follow_stop_s, catch.follow_back_s)

    def at(self, t, t_c):
        """(G, G', G'') at time t (a number, or an array of times)."""
        r, h, s_, b = self.ramp_s, self.hold_s, self.stop_s, self.back_s
        t = np.asarray(t, float)
        t0, t1 = t_c - r, t_c + h
        t2 = t1 + s_
        # Ramp: G' = s(u), G = r S(u) - r/2.
        s, ds, _, S = _smooth((t - t0) / r)
        G = r * S - 0.5 * r
        dG, ddG = s, ds / r
        # Hold: G' = 1.
        hold = t >= t_c
        G = np.where(hold, t - t_c, G)
        dG = np.where(hold, 1.0, dG)
        ddG = np.where(hold, 0.0, ddG)
        # Stop: G' = 1 - s(u), G = h + s_ (u - S(u)).
        u = np.clip((t - t1) / s_, 0.0, 1.0)
        s, ds, _, S = _smooth(u)
        stop = t >= t1
        G = np.where(stop, h + s_ * (u - S), G)
        dG = np.where(stop, 1.0 - s, dG)
        ddG = np.where(stop, -ds / s_, ddG)
        # Back: G = G2 (1 - s(u)), G2 = h + s_/2.
        G2 = h + 0.5 * s_
        s, ds, dds, _ = _smooth((t - t2) / b)
        back = t >= t2
        G = np.where(back, G2 * (1.0 - s), G)
        dG = np.where(back, -G2 * ds / b, dG)
        ddG = np.where(back, -G2 * dds / (b * b), ddG)
        if G.ndim == 0:
            return float(G), float(dG), float(ddG)
        return G, dG, ddG

    def max_acceleration(self) -> float:
        """max |G''| over the law, [1/s]."""
        G2 = self.hold_s + 0.5 * self.stop_s
        return max(_MAX_DS / self.ramp_s, _MAX_DS / self.stop_s,
                   G2 * _MAX_DDS / self.back_s**2)

    def start_s(self, t_c: float) -> float:
        """When the palm starts to move off its planned motion, [s]."""
        return t_c - self.ramp_s

    def end_s(self, t_c: float) -> float:
        """When the offset is back to zero, [s]."""
        return t_c + self.hold_s + self.stop_s + self.back_s


def palm_twist(catch_point, X_WG, obj, *, along: bool, pitch: bool
               ) -> np.ndarray:
    """The palm frame's spatial velocity [ω; v] in W (6) that follows the
    object at `catch_point` (with its orientation and velocities) under the
    grasp pose X_WG: `along`, the centre of mass's velocity in the palm's
    plane;
    `pitch`, its angular velocity about the palm's +x, the palm turning
    about the centre of mass."""
    R_WP = X_WG.rotation().matrix()
    p_WP = X_WG.translation()
    R_WO = np.asarray(catch_point.R_WO)
    w_W = np.asarray(catch_point.w_W, float)
    p_OCm_W = R_WO @ obj.p_OCm
    p_WCm = np.asarray(catch_point.p_WO) + p_OCm_W
    omega = np.zeros(3)
    v = np.zeros(3)
    if pitch:
        x_P = R_WP[:, 0]
        omega = (w_W @ x_P) * x_P
        v = v + np.cross(omega, p_WP - p_WCm)
    if along:
        # The centre of mass's velocity in the palm's plane (the lowering,
        # along the palm's normal, meets the rest).
        v_Cm = np.asarray(catch_point.v_W, float) + np.cross(w_W, p_OCm_W)
        z_P = R_WP[:, 2]
        v = v + v_Cm - (v_Cm @ z_P) * z_P
    return np.concatenate([omega, v])


def plan_follow(scenario, obj, catch_point, X_WG) -> np.ndarray:
    """The palm_follow vector (t_c, twist) of a catch at `catch_point` with
    the grasp pose X_WG under `scenario` (catch.follow_along and
    catch.follow_pitch, `follows`); NO_FOLLOW when it follows nothing or
    the point has no velocities."""
    along, pitch = follows(scenario)
    if (not (along or pitch) or catch_point.w_W is None
            or catch_point.v_W is None or catch_point.R_WO is None):
        return NO_FOLLOW
    twist = palm_twist(catch_point, X_WG, obj, along=along, pitch=pitch)
    return np.concatenate([[catch_point.t_s], twist])


def follows(scenario) -> tuple[bool, bool]:
    """(along, pitch): whether a catch under `scenario` follows the object
    along the palm and turns with its pitch. None (the default) in either:
    on under a grasp target, off under the paper's `any` catch."""
    target = target_of(scenario).kind != "any"
    c = scenario.catch
    return (target if c.follow_along is None else bool(c.follow_along),
            target if c.follow_pitch is None else bool(c.follow_pitch))


def joint_follow(ik: ArmIk, q_grasp, twist, law: FollowLaw,
                 max_torque_fraction: float) -> tuple[np.ndarray, float]:
    """(q̇_f, scale): the arm's joint velocity [rad/s] that gives the palm
    `twist` at q_grasp, scaled by `scale` ≤ 1 so that the offset's largest
    acceleration (law.max_acceleration · q̇_f), with the arm's weight
    there, needs at most `max_torque_fraction` of each servo's torque
    limit (the PUMA's, robot.ARM_EFFORT_LIMITS)."""
    twist = np.asarray(twist, float)
    if not np.any(twist):
        return np.zeros(6), 1.0
    plant = ik.plant
    context = plant.CreateDefaultContext()
    plant.SetPositions(context, np.asarray(q_grasp, float))
    frame = plant.GetFrameByName("link6")
    X_6P = ik.palm_in_flange
    world = plant.world_frame()
    J = plant.CalcJacobianSpatialVelocity(
        context, JacobianWrtVariable.kV, frame, X_6P.translation(), world,
        world)
    # The palm frame's angular velocity is link 6's; its origin's velocity
    # is that of the point of link 6 at the palm's origin.
    qdot = np.linalg.solve(J, twist)
    M = plant.CalcMassMatrix(context)
    torque = np.abs(M @ (law.max_acceleration() * qdot))
    gravity = np.abs(plant.CalcGravityGeneralizedForces(context))
    room = np.maximum(max_torque_fraction * ARM_EFFORT_LIMITS - gravity, 0.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratios = np.where(torque > 0.0, room / torque, np.inf)
    scale = float(min(1.0, np.min(ratios)))
    return scale * qdot, scale
