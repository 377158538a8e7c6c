"""The palm toss (throw.kind: palm_toss), the same motion for every object.

The object lies on the open palm (no finger touches it). The palm, facing up,
is lifted straight up and rolled about its own x axis (the fingertip
direction) at the same time; then it brakes harder than gravity, so the
contacts unload together and the object leaves with the palm's velocity and
angular velocity of that instant: the contact force falls continuously to
zero, with no fingers for the object to roll across (how far that makes the
release converge in the time step: studies/palm_toss/FINDINGS.md). The roll
gives the object a designed spin about the palm's x,
so its symmetry axis (along the palm's y) turns end over end in flight and
is horizontal again half a turn later: the catch is another grasp.

Palm motion, t from the start of the throw (velocities as quintic
smoothsteps s(τ) = 10τ³ - 15τ⁴ + 6τ⁵, so accelerations are continuous and
start and end at zero; the roll angle φ during the lift follows the quintic
p(τ) = -4τ³ + 7τ⁴ - 3τ⁵, with p = p' = p'' = 0 at τ = 0 and p = 0, p' = 1,
p'' = 0 at τ = 1: the palm first rolls back by at most 0.2 Ω T_l (28° for
the default toss, the object pressed on by the lift) and is level again,
rolling at Ω, when it starts to brake, so that the object is pressed straight
onto it as the contacts unload):
  lift   0 ≤ t < T_l:   v_z = V s(t/T_l),       φ = Ω T_l p(t/T_l)
  cruise T_l ≤ t < T_l + d: v_z = V, ω_x = Ω    (d: a late release, noise)
  brake  then the deceleration rises to A over T_r (a smoothstep), stays
         there, and falls back to 0 over T_r as v_z reaches 0;
         the roll keeps ω_x = Ω for T_h more, then stops over T_s:
         ω_x = Ω (1 - s(·/T_s)).
A exceeds g (1.6 g by default): the object separates as the deceleration
passes g, a few ms into the brake, where v_z ≈ V, at the constant roll rate
Ω. The quick rise matters: with a slow one (a smoothstep brake over 0.2 s,
the object leaving 45 ms in), the unloading object rocks on its supports and
leaves at a phase of that rocking that depends on the time step (table1-row4:
5.87 against 5.59 rad/s at 1 and 0.25 ms). And were the roll to slow while
the object still pressed on the palm, friction at its base would tip it
forward like a block on a braking cart (the spin grew from 4.0 to 5.5
rad/s).

The coordinated palm (throw.toss.coordinated): while the palm is tilted by
φ, the object is pressed onto it by gravity and the lift's acceleration,
straight down, and an object resting on a narrow base (a box head, a
flange) tips over its edge once tan φ passes its base's half-width over its
height (table1-row4 at about τ = 0.44, the palm 28° back). The coordinated
palm also accelerates along its start pose's y by a_y = -(g + a_z) tan φ,
so that gravity and its acceleration together press along its normal at
every tilt; the roll gains the term C τ³(1 - τ)³ (forward first, every end
condition kept), C chosen so that the sideways velocity is 0 again when
the palm brakes (about 13 for the default toss: forward 10°, back 16°,
sideways 82 mm). The object then leaves with the same velocity and spin as
without it.

The arm follows the palm's pose by inverse kinematics every `IK_PERIOD_S`,
joined by a C2 cubic spline (`toss_trajectory`).
"""

import dataclasses as dc

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial

from regrasp_drake import memo

# Inverse kinematics samples of the palm's motion, [s].
IK_PERIOD_S = 0.005
# The roll's axis runs along the palm's x this high above the palm's surface,
# [m]: about where a lying object's centre of mass is (1.5-4 cm), so the roll
# gives it little sideways velocity.
ROLL_AXIS_HEIGHT_M = 0.03


def _smoothstep(tau):
    """s(τ) and its integral S(τ) = ∫₀^τ s, τ clipped to [0, 1]."""
    tau = min(max(tau, 0.0), 1.0)
    s = tau**3 * (10.0 - 15.0 * tau + 6.0 * tau**2)
    integral = tau**4 * (2.5 - 3.0 * tau + tau**2)
    return s, integral


def _brake(u, v0, a, T_r):
    """(Δz, v) a time u into the brake from speed v0: the deceleration
    rises to a over T_r as a smoothstep, stays at a, and falls back over
    T_r, reaching 0 with the speed (module docstring)."""
    T_c = max(v0 / a - T_r, 0.0)  # at the full deceleration
    a = v0 / (T_r + T_c)  # (lower, when v0 is too small to reach a)

    def integral(tau):  # ∫₀^τ S, S the smoothstep's integral
        tau = min(max(tau, 0.0), 1.0)
        return tau**5 * (0.5 - 0.5 * tau + tau**2 / 7.0)

    if u < T_r:
        tau = u / T_r
        return (v0 * u - a * T_r**2 * integral(tau),
                v0 - a * T_r * _smoothstep(tau)[1])
    v1 = v0 - a * T_r / 2.0
    z1 = v0 * T_r - a * T_r**2 / 7.0
    w = min(u - T_r, T_c)
    if u < T_r + T_c:
        return z1 + v1 * w - a * w * w / 2.0, v1 - a * w
    v2 = v1 - a * T_c
    z2 = z1 + v1 * T_c - a * T_c**2 / 2.0
    tau = min((u - T_r - T_c) / T_r, 1.0)
    S = _smoothstep(tau)[1]
    return (z2 + v2 * T_r * tau - a * T_r**2 * (tau**2 / 2.0 - integral(tau)),
            max(v2 - a * T_r * (tau - S), 0.0) if tau < 1.0 else 0.0)


def _roll_profile(tau, forward: float = 0.0):
    """p(τ) and p'(τ) of the lift's roll (module docstring), plus
    `forward` · τ³(1 - τ)³, which tilts the palm forward first and keeps
    every end condition (the coordinated palm, TossDesign.coordinated)."""
    tau = min(max(tau, 0.0), 1.0)
    bump = tau**3 * (1.0 - tau)**3
    dbump = 3.0 * tau**2 * (1.0 - tau)**2 * (1.0 - 2.0 * tau)
    return (tau**3 * (-4.0 + 7.0 * tau - 3.0 * tau**2) + forward * bump,
            tau**2 * (-12.0 + 28.0 * tau - 15.0 * tau**2) + forward * dbump)


@dc.dataclass(frozen=True)
class TossDesign:
    """The toss's constants (see the module docstring); hashable so that a
    trajectory is computed once per design."""
    start_q: tuple          # arm joint angles at rest before the throw, [rad]
    launch_speed: float     # V, [m/s]
    lift_s: float           # T_l, [s]
    brake_deceleration: float  # A, [m/s²]
    brake_ramp_s: float     # T_r, [s]
    spin: float             # Ω, [rad/s] about the palm's x
    spin_stop_s: float      # T_s, [s]
    spin_hold_s: float      # T_h, [s]
    brake_delay_s: float = 0.0  # d, [s]
    # The coordinated palm: while tilted by φ in the lift it accelerates
    # along its start pose's y by -(g + a_z) tan φ (module docstring) ...
    coordinated: bool = False
    # ... and its roll gains forward_tilt · τ³(1 - τ)³ (_roll_profile;
    # TossDesign.of solves it, _forward_tilt), [-].
    forward_tilt: float = 0.0

    @staticmethod
    def of(toss, brake_delay_s: float = 0.0) -> "TossDesign":
        """The design of a scenario's PalmTossConfig (throw.toss); a
        coordinated palm's forward_tilt is the one for the undelayed lift."""
        design = TossDesign(
            start_q=tuple(float(q) for q in toss.start_q_rad),
            launch_speed=float(toss.launch_speed_m_per_s),
            lift_s=float(toss.lift_s),
            brake_deceleration=float(toss.brake_deceleration_m_per_s2),
            brake_ramp_s=float(toss.brake_ramp_s),
            spin=float(toss.spin_rad_per_s),
            spin_stop_s=float(toss.spin_stop_s),
            spin_hold_s=float(toss.spin_hold_s),
            coordinated=bool(toss.coordinated))
        if design.coordinated:
            design = dc.replace(design, forward_tilt=_forward_tilt(design))
        return dc.replace(
            design, brake_delay_s=float(max(brake_delay_s, -toss.lift_s / 2)))

    @property
    def brake_start_s(self) -> float:
        return self.lift_s + self.brake_delay_s

    @property
    def duration_s(self) -> float:
        """The throw's length: the palm and its roll are at rest after."""
        return self.brake_start_s + max(self.brake_s,
                                        self.spin_hold_s + self.spin_stop_s)

    @property
    def handoff_s(self) -> float:
        """When the catch's move takes over from the toss, the object long
        gone (it leaves as the deceleration passes g): the end of the roll's
        hold, [s]."""
        return self.brake_start_s + self.spin_hold_s

    @property
    def brake_s(self) -> float:
        """The brake's length, from the launch speed to rest, [s]."""
        return self.brake_ramp_s + self.launch_speed / self.brake_deceleration

    def palm_motion(self, t: float) -> tuple[float, float, float, float]:
        """(z, v_z, φ, ω_x) of the palm at throw time t: its rise above the
        start, [m], vertical speed, [m/s], roll about its x, [rad], and roll
        rate, [rad/s]. A negative delay shortens the lift, scaling its
        velocities (the same profile, ended early)."""
        T_l, V, W = self.lift_s, self.launch_speed, self.spin
        t0 = self.brake_start_s
        if t < min(T_l, t0):
            s, S = _smoothstep(t / T_l)
            p, dp = _roll_profile(t / T_l, self.forward_tilt)
            return V * T_l * S, V * s, W * T_l * p, W * dp
        # At the end of the lift (or of a shortened one).
        s_l, S_l = _smoothstep(min(T_l, t0) / T_l)
        p_l, dp_l = _roll_profile(min(T_l, t0) / T_l, self.forward_tilt)
        z0, phi0 = V * T_l * S_l, W * T_l * p_l
        v0, w0 = V * s_l, W * dp_l
        if t < t0:  # cruising
            return z0 + v0 * (t - T_l), v0, phi0 + w0 * (t - T_l), w0
        z0 += v0 * max(0.0, t0 - T_l)
        phi0 += w0 * max(0.0, t0 - T_l)
        u = t - t0
        dz, v = _brake(u, v0, self.brake_deceleration, self.brake_ramp_s)
        u_r = max(0.0, u - self.spin_hold_s)
        s_s, S_s = _smoothstep(u_r / self.spin_stop_s)
        u_s = min(u, self.spin_hold_s) + min(u_r, self.spin_stop_s)
        phi = phi0 + w0 * (u_s - self.spin_stop_s * S_s)
        return z0 + dz, v, phi, w0 * (1.0 - s_s)


    def sideways(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(t, y, v_y) of the coordinated palm's sideways motion on a
        _SIDEWAYS_DT_S grid from 0 to the brake's start, [s, m, m/s]: a_y
        = -(g + a_z) tan φ while it lifts (and cruises), so that gravity
        and the palm's acceleration press the object along the palm's
        normal however far it tilts."""
        t = np.arange(0.0, self.brake_start_s + _SIDEWAYS_DT_S / 2,
                      _SIDEWAYS_DT_S)
        motion = np.array([self.palm_motion(float(x)) for x in t])
        a_z = np.gradient(motion[:, 1], t)
        a_y = -(STANDARD_GRAVITY + a_z) * np.tan(motion[:, 2])
        v_y = np.concatenate(
            [[0.0], np.cumsum((a_y[1:] + a_y[:-1]) / 2 * _SIDEWAYS_DT_S)])
        y = np.concatenate(
            [[0.0], np.cumsum((v_y[1:] + v_y[:-1]) / 2 * _SIDEWAYS_DT_S)])
        return t, y, v_y

    def sideways_offset(self, t: float) -> float:
        """The coordinated palm's sideways offset at throw time t, [m]
        (0 if not coordinated); after the brake starts it goes on at the
        speed it had then (about 0: forward_tilt)."""
        if not self.coordinated:
            return 0.0
        times, y, v_y = _sideways_table(self)
        if t <= times[-1]:
            return float(np.interp(t, times, y))
        return float(y[-1] + v_y[-1] * (t - times[-1]))


@memo.lru_cache("forward tilts", maxsize=64)
def _forward_tilt(design: TossDesign) -> float:
    """The forward-first coefficient whose sideways motion has come back
    to rest when `design`'s lift ends (bisection: the sideways velocity
    then falls as the coefficient grows)."""
    lo, hi = 0.0, _FORWARD_TILT_MAX
    for _ in range(40):
        mid = (lo + hi) / 2
        if dc.replace(design, forward_tilt=mid).sideways()[2][-1] > 0.0:
            lo = mid
        else:
            hi = mid
    return (lo + hi) / 2


@memo.lru_cache("sideways tables", maxsize=64)
def _sideways_table(design: TossDesign):
    return design.sideways()


# The sideways motion's integration step, [s].
_SIDEWAYS_DT_S = 1e-4
# The largest forward-first coefficient tried, [-] (the shipped toss needs
# about 13: the palm tilts forward 10°, then back 16°).
_FORWARD_TILT_MAX = 40.0
# g of the coordinated palm's sideways acceleration, [m/s²]: the scenario's
# default gravity_m_per_s2.
STANDARD_GRAVITY = 9.81


def palm_pose_at(design: TossDesign, X_WP0: RigidTransform,
                 t: float) -> RigidTransform:
    """The palm's pose at throw time t, from its start pose X_WP0."""
    z, _, phi, _ = design.palm_motion(t)
    R_roll = RotationMatrix.MakeXRotation(phi)
    p_PA = np.array([0.0, 0.0, ROLL_AXIS_HEIGHT_M])  # a point of the axis
    # The palm turns by R_roll about the axis through A (in P0's frame).
    p_P0P = p_PA - R_roll @ p_PA
    return RigidTransform(
        X_WP0.rotation() @ R_roll,
        X_WP0.translation() + X_WP0.rotation() @ (
            p_P0P + [0.0, design.sideways_offset(t), 0.0]) + [0.0, 0.0, z])


def separation_s(design: TossDesign, gravity_m_per_s2: float) -> float:
    """When an object riding on the palm leaves it: the throw time at which
    the brake's deceleration, rising as a smoothstep over T_r, reaches g,
    [s] (the contacts then unload together; the roll's centripetal
    acceleration, Ω² times the centre of mass's distance from the roll's
    axis, up to about 6 % of g for the objects lying on the palm, is left
    out)."""
    ratio = gravity_m_per_s2 / design.brake_deceleration
    if not 0.0 < ratio < 1.0:
        raise ValueError(f"throw.toss.brake_deceleration_m_per_s2: "
                         f"{design.brake_deceleration!r}, expected more than "
                         f"g = {gravity_m_per_s2} m/s² for the object to "
                         "leave the palm")
    lo, hi = 0.0, 1.0
    for _ in range(60):
        mid = (lo + hi) / 2
        lo, hi = (mid, hi) if _smoothstep(mid)[0] < ratio else (lo, mid)
    return design.brake_start_s + design.brake_ramp_s * (lo + hi) / 2


# The time step of palm_twist_at's central differences, [s].
_TWIST_DT_S = 1e-6


def palm_twist_at(design: TossDesign, X_WP0: RigidTransform, t: float):
    """(X_WP, w_WP, v_WP): the palm's pose at throw time t, its angular
    velocity and the velocity of its origin, both in W, [rad/s, m/s]
    (central differences of palm_pose_at over ±_TWIST_DT_S)."""
    before = palm_pose_at(design, X_WP0, t - _TWIST_DT_S)
    after = palm_pose_at(design, X_WP0, t + _TWIST_DT_S)
    turn = (after.rotation() @ before.rotation().inverse()).ToAngleAxis()
    return (palm_pose_at(design, X_WP0, t),
            turn.axis() * turn.angle() / (2 * _TWIST_DT_S),
            (after.translation() - before.translation()) / (2 * _TWIST_DT_S))


@memo.lru_cache("toss trajectories", maxsize=16)
def _trajectory(design: TossDesign, ik) -> PiecewisePolynomial:
    X_WP0 = ik.palm_pose(np.array(design.start_q))
    n = int(np.ceil(design.duration_s / IK_PERIOD_S))
    times = np.linspace(0.0, design.duration_s, n + 1)
    q = np.array(design.start_q)
    knots = [q]
    for t in times[1:]:
        result = ik.solve(palm_pose_at(design, X_WP0, float(t)), q)
        if not result.success:
            raise ValueError(
                f"throw: the palm's pose at t = {t:.3f} s of the toss is "
                f"unreachable ({result.reason()}); expected a toss the arm "
                "can follow (lower throw.launch_speed_m_per_s or "
                "throw.spin_rad_per_s, or move throw.start_q_rad)")
        q = result.q
        knots.append(q)
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        times, np.array(knots).T, np.zeros(6), np.zeros(6))


def toss_trajectory(design: TossDesign, ik) -> PiecewisePolynomial:
    """The arm's joint trajectory of the toss (6 rows), t ∈ [0, duration]:
    computed once per design and solver."""
    return _trajectory(design, ik)
