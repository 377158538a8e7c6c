"""The catch state machine of the paper's Fig. 9, as a LeafSystem.

Phases, in order:
  SETTLE  the fingers close on the object lying in the palm (palm toss:
          the object settles on the open palm);
  THROW   the arm tracks the fixed throw trajectory; the fingers open at the
          release time (palm toss, station/palm_toss.py: the fingers stay
          open and the object leaves the palm when it brakes);
  MOVE    the arm moves to the grasp position (or, when only watching, to a
          park pose out of the flight's way) (palm toss: from the toss's
          moving state, a quintic from its position, velocity and
          acceleration to rest, so the brake and the roll's stop blend into
          the move; the fingers pre-shape to a cage, catch.preshape_closure);
  WAIT    the hand waits, palm up, until an approach sensor (IR 4-13) sees
          the object closer than h_catch;
  LOWER   the fingers close at their maximum speed while the hand is lowered
          by |h_down|; lowering stops as soon as a palm sensor (IR 1-3) reads
          below the stop level (Fig. 9 line 13) (with
          catch.lower_ends_moving, the lowering ends moving down at twice
          its mean speed rather than at rest, so that the palm meets the
          falling object moving with it);
  RETURN  the hand goes back up to the grasp position (with
          catch.return_from_motion, from the lowering's moving state: the
          hand goes on down as the object lands and turns back smoothly, a
          cushion, rather than stopping dead under it);
  HOLD    the hand holds the object there.

With a follow (the `palm_follow` input: the catch moment and the palm's
twist there, planning/follow.py; zeros, none), the arm's references from
the move on carry the follow's offset G(t) q̇_f as well: the palm moves
with the object in its plane and turns with its pitch over the contact,
then comes back to the grasp pose.

The arm is commanded in joint space: every phase is a segment from q_a to q_b
with a quintic time law (zero end velocity and acceleration), except the
throw, which follows a C2 cubic spline through the scenario's knots (or the
palm toss's spline). The
grasp and lowered joint angles are solved by inverse kinematics once, when
the phase that needs them starts.

One periodic discrete update runs at the plant's time step: at the sensors'
rate it first makes the phase transitions, then, every step, it writes the
arm's and fingers' references for the next step into discrete state, which
the reference output ports expose directly. So no Python runs when the plant
or the controller reads a reference (a computed output port would run
several times per step), and the references are the same as if they were
evaluated at the step's time. They come from a table of the next
TABLE_STEPS steps' references, kept in discrete state and made again only
when a transition changes the machine's state or the table runs out: a
step between those only copies its row. Steps are counted from t = 0 (step
n at n dt), so the transitions are on the sensors' samples whatever plant
step the machine took over from (`continue_at`).

On a continuous plant (plant_config.time_step 0, integrated by CENIC) the
update runs at the sensors' rate and makes the transitions only; the
reference output ports are then computed from the time, so that the
integrator, which chooses its own steps, sees smooth references rather
than a hold.

Over 500 lines because it is one LeafSystem: the phases of Fig. 9 and the
arm's and fingers' references each phase commands, which share its state.
"""

import dataclasses as dc
import enum
import math

import numpy as np
from pydrake.common.value import AbstractValue
from pydrake.math import RigidTransform
from pydrake.systems.framework import BasicVector, EventStatus, LeafSystem
from pydrake.trajectories import PiecewisePolynomial

from regrasp_drake.planning.follow import (
    FOLLOW_SIZE,
    FollowLaw,
    follows,
    joint_follow,
)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.planning.time_law import ease_in, quintic, quintic_from
from regrasp_drake.station.palm_toss import TossDesign, toss_trajectory
from regrasp_drake.station.scenario import lowers_moving
from regrasp_drake.station.throw import end_s, free_time_s, let_go_time_s
from regrasp_drake.world.robot import CLOSING_ORDERS, HAND_JOINTS


class Phase(enum.IntEnum):
    SETTLE = 0
    THROW = 1
    MOVE = 2
    WAIT = 3
    LOWER = 4
    RETURN = 5
    HOLD = 6
    FAILED = 7  # the arm could not reach a commanded pose


# Plain numbers of the phases the per-step references test (faster than
# the enum's attribute lookup).
_THROW, _MOVE, _LOWER, _RETURN, _HOLD = (
    int(Phase.THROW), int(Phase.MOVE), int(Phase.LOWER), int(Phase.RETURN),
    int(Phase.HOLD))

# Layout of the discrete state vector. _TABLE_END: the first plant step
# (counted from t = 0) whose references the table no longer holds.
_PHASE, _T0, _T, _T_CLOSE, _T_OPEN, _H_DOWN, _TABLE_END = range(7)
_QA = slice(7, 13)
_QB = slice(13, 19)
_QGRASP = slice(19, 25)
# A segment's start velocity and acceleration (zero but for the move that
# takes over from the throw while the arm still moves).
_V0 = slice(25, 31)
_A0 = slice(31, 37)
# The follow (planning/follow.py): the catch moment t_c and the joint
# velocity q̇_f whose offset G(t) q̇_f the references add from the move on
# (zero: no follow).
_TC = 37
_QF = slice(38, 44)
_SIZE = 44

# The table of references holds about this many plant steps (rounded to
# whole sensor samples, at least one): long enough that it is made again
# every few samples only, short enough that the copies of the discrete
# state Drake makes at each update stay cheap.
TABLE_STEPS = 32


def lowered_pose(X_WG: RigidTransform, h_down: float,
                 along_normal: bool = False) -> RigidTransform:
    """The palm's pose at the end of the lowering (LOWER): the grasp pose
    X_WG moved |h_down| straight down (`along_normal`: along the palm's
    normal, so that the lowering does not move the palm in its own plane,
    where the follow matches the object's motion: planning/follow.py). Its
    joint angles are solved by inverse kinematics from the grasp pose's."""
    down = (X_WG.rotation().col(2) if along_normal
            else np.array([0.0, 0.0, 1.0]))
    return RigidTransform(X_WG.rotation(),
                          X_WG.translation() - abs(h_down) * down)


@dc.dataclass(frozen=True)
class ThrowPerturbation:
    """One throw's release noise: the fingers open `release_dt_s` late (the
    palm toss brakes that late: it cruises at the launch speed meanwhile;
    early, the lift ends sooner), and
    each arm joint's reference gets a smooth velocity pulse that peaks at
    `joint_dv_rad_per_s` at the release, v(τ) = dv · exp(-((τ - τ_r)/w)²)
    with w = PULSE_WIDTH_S (its position and acceleration follow)."""
    release_dt_s: float = 0.0
    joint_dv_rad_per_s: tuple = (0.0,) * 6

    PULSE_WIDTH_S = 0.04

    @staticmethod
    def draw(noise, throw_number: int) -> "ThrowPerturbation":
        """The perturbation of throw `throw_number` under scenario noise
        `noise` (a ThrowNoise); all zeros without noise."""
        if noise.is_zero():
            return ThrowPerturbation()
        rng = np.random.default_rng([noise.seed, throw_number])
        return ThrowPerturbation(
            release_dt_s=float(rng.normal(0.0, noise.release_time_std_s)),
            joint_dv_rad_per_s=tuple(float(v) for v in rng.normal(
                0.0, noise.joint_velocity_std_rad_per_s, 6)))

    def is_zero(self) -> bool:
        return self.release_dt_s == 0.0 and not any(self.joint_dv_rad_per_s)

    def pulse(self, tau, tau_release):
        """The reference offsets (dq, dv, da) at throw time tau."""
        w = self.PULSE_WIDTH_S
        u = (tau - tau_release) / w
        g = math.exp(-u * u)
        phi = 0.5 * w * math.sqrt(math.pi) * (
            math.erf(u) + math.erf(tau_release / w))
        dv = np.asarray(self.joint_dv_rad_per_s)
        return phi * dv, g * dv, (-2.0 * u / w * g) * dv


def preshape_closures(catch) -> np.ndarray:
    """The fingers' pre-shape, per hand joint (HAND_JOINTS order: each
    finger's knuckle j1 then distal j2), as a fraction of the closed
    posture: catch.preshape_closure for the knuckles, and for the distal
    joints catch.preshape_distal_closure (None: the knuckles')."""
    distal = catch.preshape_distal_closure
    closures = np.full(len(HAND_JOINTS), float(catch.preshape_closure))
    if distal is not None:
        closures[1::2] = distal
    return closures


def preshape_posture(catch, hand_open, hand_closed) -> np.ndarray:
    """The fingers' pre-shaped posture between `hand_open` and
    `hand_closed` (per joint, [rad]): `preshape_closures` of the way."""
    hand_open = np.asarray(hand_open, float)
    return hand_open + preshape_closures(catch) * (
        np.asarray(hand_closed, float) - hand_open)


def closing_delays(order: str, q_from, q_to, speed) -> np.ndarray | None:
    """Each hand joint's start delay, [s], for the fingers to close from
    q_from to q_to at `speed` in `order` (CLOSING_ORDERS); None: together.
    The ones that wait start as the others arrive."""
    if order == "together":
        return None
    if order not in CLOSING_ORDERS:
        raise ValueError(f"closing order: got {order!r}, expected one of "
                         f"{CLOSING_ORDERS}")
    time = np.abs(np.asarray(q_to, float) - np.asarray(q_from, float)) / speed
    thumb = np.array([j.startswith("thumb_") for j in HAND_JOINTS])
    first = thumb if order == "thumb_first" else ~thumb
    delay = np.zeros(len(HAND_JOINTS))
    delay[~first] = np.max(time[first])
    return delay


class FingerRamp:
    """The fingers from q_from toward q_to at their speed (rad/s), each
    joint starting `delay` s after the ramp's start (per joint; None: all at
    once), with what depends on the two postures only made once."""

    def __init__(self, q_from, q_to, speed, delay=None):
        delta = q_to - q_from
        self.q_from, self.q_to, self.speed = q_from, q_to, speed
        self.distance = np.abs(delta)
        self.longest = np.max(self.distance)
        self.sign = np.sign(delta)
        self.velocity = self.sign * speed
        self.delay = None if delay is None else np.asarray(delay, float)
        # How long until every joint has arrived, [s].
        self.duration = float(np.max(
            self.distance / speed + (0.0 if delay is None else self.delay)))

    def at(self, elapsed):
        """(q, v) `elapsed` s after the start (a number, or a column of k:
        k × n arrays)."""
        shape = np.shape(elapsed)[:1] + self.q_to.shape
        if self.delay is not None:
            # Each joint's own time since it started (n, or k × n).
            elapsed = np.asarray(elapsed, float) - self.delay
            arrived = self.speed * elapsed >= self.distance
        else:
            arrived = self.speed * elapsed >= self.longest
        if np.all(arrived):
            return np.broadcast_to(self.q_to, shape), np.zeros(shape)
        travel = np.minimum(self.distance,
                            self.speed * np.maximum(elapsed, 0.0))
        q = self.q_from + self.sign * travel
        moving = self.distance > travel
        if self.delay is not None:
            moving = moving & (elapsed >= 0.0)
        v = np.where(moving, self.velocity, 0.0)
        return np.where(arrived, self.q_to, q), np.where(arrived, 0.0, v)


class CatchStateMachine(LeafSystem):
    """Inputs: `ir_levels` (13 readings, IR 1-3 palm then IR 4-13 approach),
    `catch_parameters` (h_catch, h_down in m), `X_WG` (abstract RigidTransform:
    the palm frame's grasp pose), `arm_state` (q, v of the arm).
    Outputs: `arm_desired_state` (q, v), `arm_desired_acceleration`,
    `hand_desired_state` (q, v of the 10 finger joints), `phase`.
    """

    def __init__(self, scenario, ik: ArmIk, hand_open, hand_closed,
                 finger_speed_rad_per_s: float, park_q,
                 watching: bool = False,
                 perturbation: ThrowPerturbation = ThrowPerturbation()):
        """`park_q`: where the arm goes after the release on a watching
        throw, which never tries to catch. `watching`: whether this is one
        (a parameter: `set_watching` sets it in a context, so that one
        diagram serves watching and catching episodes alike).
        `perturbation`: this throw's release noise (default none)."""
        LeafSystem.__init__(self)
        self._ik = ik
        self._throw = scenario.throw
        self._catch = scenario.catch
        self._levels = scenario.sensors.levels
        self._approach_range = scenario.sensors.approach_range_m
        self._open = np.asarray(hand_open, float)
        self._closed = np.asarray(hand_closed, float)
        self._toss = scenario.throw.kind == "palm_toss"
        self._hold = self._open + scenario.throw.hold_closure * (
            self._closed - self._open)
        self._preshape = preshape_posture(scenario.catch, self._open,
                                          self._closed)
        self._open_to_hold = FingerRamp(self._open, self._hold,
                                   finger_speed_rad_per_s)
        self._hold_to_open = FingerRamp(self._hold, self._open,
                                   finger_speed_rad_per_s)
        order = scenario.catch.closing_order
        self._open_to_closed = FingerRamp(
            self._open, self._closed, finger_speed_rad_per_s,
            delay=closing_delays(order, self._open, self._closed,
                                 finger_speed_rad_per_s))
        self._open_to_preshape = FingerRamp(self._open, self._preshape,
                                       finger_speed_rad_per_s)
        self._preshape_to_closed = FingerRamp(
            self._preshape, self._closed, finger_speed_rad_per_s,
            delay=closing_delays(order, self._preshape, self._closed,
                                 finger_speed_rad_per_s))
        self._cushion = scenario.catch.return_from_motion
        self._follow_law = FollowLaw.of(scenario.catch)
        self._lower_along_normal = follows(scenario)[0]
        self._follow_fraction = scenario.catch.follow_max_torque_fraction
        self._lower_moving = lowers_moving(scenario)
        self._park_q = np.asarray(park_q, float)
        self._watching = self.DeclareNumericParameter(
            BasicVector([float(watching)]))
        t = scenario.throw
        self._t_throw = t.settle_s
        self._noise = None if perturbation.is_zero() else perturbation
        if self._toss:
            design = TossDesign.of(t.toss,
                                   brake_delay_s=perturbation.release_dt_s)
            self._tau_release = design.brake_start_s
            self._spline = toss_trajectory(design, ik)
            self._q_start = np.array(design.start_q)
        else:
            self._tau_release = t.release_time_s
            knots = np.array(t.knot_q_rad).T
            self._spline = (
                PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
                    t.knot_times_s, knots, np.zeros(6), np.zeros(6)))
            self._q_start = knots[:, 0]
        self._t_release = let_go_time_s(scenario, perturbation.release_dt_s)
        self._throw_s = end_s(t, perturbation.release_dt_s)
        self._t_throw_end = free_time_s(scenario, perturbation.release_dt_s)
        self._spline_v = self._spline.derivative(1)
        self._spline_a = self._spline.derivative(2)

        self._ir = self.DeclareVectorInputPort("ir_levels", 13)
        self._params = self.DeclareVectorInputPort("catch_parameters", 2)
        self._X_WG = self.DeclareAbstractInputPort(
            "X_WG", AbstractValue.Make(RigidTransform()))
        self._arm_state = self.DeclareVectorInputPort("arm_state", 12)
        self._follow = self.DeclareVectorInputPort("palm_follow", FOLLOW_SIZE)

        x0 = np.zeros(_SIZE)
        x0[_PHASE] = Phase.SETTLE
        x0[_T_CLOSE] = 0.0  # the fingers close on the object from the start
        x0[_T_OPEN] = self._t_release
        x0[_QA] = x0[_QB] = self._q_start
        x0[_T] = 1.0
        x0[_TABLE_END] = 0  # no table yet: the first update makes it
        self._state = self.DeclareDiscreteState(x0)
        # The references for the current step: arm (q, v), arm acceleration,
        # fingers (q, v).
        q_arm, v_arm, a_arm = self._arm_reference(x0, 0.0)
        self._arm_ref = self.DeclareDiscreteState(np.concatenate([q_arm, v_arm]))
        self._acc_ref = self.DeclareDiscreteState(a_arm)
        self._hand_ref = self.DeclareDiscreteState(
            np.concatenate(self._hand_reference(x0, 0.0)))
        self._dt = scenario.plant_config.time_step
        self._declare_references(scenario)
        self.DeclareVectorOutputPort(
            "phase", 1, self._calc_phase,
            prerequisites_of_calc={self.xd_ticket()})

    def _declare_references(self, scenario) -> None:
        """The reference output ports: on a discrete plant, the state groups
        the per-step update writes from its table of references (declared
        here); on a continuous one, computed from the time."""
        if self._dt > 0.0:
            self._ticks_per_sample = round(scenario.sensors.period_s / self._dt)
            self._table_steps = self._ticks_per_sample * max(
                1, round(TABLE_STEPS / self._ticks_per_sample))
            # The table of references (`_references`), flattened: plant
            # step n's references in row n % _table_steps, its columns the
            # arm's (q, v), its v̇ and the fingers' (q, v). Each row's three
            # reference groups are slices of the flattened table.
            n_hand = len(self._open)
            width = 18 + 2 * n_hand
            self._table = self.DeclareDiscreteState(self._table_steps * width)
            self._row_numbers = np.arange(self._table_steps, dtype=float)
            self._columns = (slice(0, 6), slice(6, 12), slice(12, 18),
                             slice(18, 18 + n_hand), slice(18 + n_hand, width))
            self._row_slices = [(slice(r * width, r * width + 12),
                                 slice(r * width + 12, r * width + 18),
                                 slice(r * width + 18, (r + 1) * width))
                                for r in range(self._table_steps)]
            self.DeclarePeriodicDiscreteUpdateEvent(self._dt, 0.0, self._update)
            self.DeclareStateOutputPort("arm_desired_state", self._arm_ref)
            self.DeclareStateOutputPort("arm_desired_acceleration",
                                        self._acc_ref)
            self.DeclareStateOutputPort("hand_desired_state", self._hand_ref)
        else:  # a continuous plant: references computed from the time
            self._ticks_per_sample = 1
            self.DeclarePeriodicDiscreteUpdateEvent(
                scenario.sensors.period_s, 0.0, self._update)
            depends = {self.time_ticket(), self.xd_ticket()}
            self.DeclareVectorOutputPort(
                "arm_desired_state", 12, self._calc_arm_state,
                prerequisites_of_calc=depends)
            self.DeclareVectorOutputPort(
                "arm_desired_acceleration", 6, self._calc_arm_acceleration,
                prerequisites_of_calc=depends)
            self.DeclareVectorOutputPort(
                "hand_desired_state", 2 * len(self._open), self._calc_hand,
                prerequisites_of_calc=depends)

    # ---- references ----------------------------------------------------
    def _references(self, x, step):
        """The table of references that the updates at the _table_steps
        plant steps from `step` on write for their next steps, in state x:
        step n's in row n % _table_steps, the arm's (q, v), its v̇ and the
        fingers' (q, v). Every row is what `_arm_reference` and
        `_hand_reference` give at that time, computed for all rows at once
        (palm toss) or row by row (the finger throw's references switch on
        the time)."""
        steps = step + (self._row_numbers - step) % self._table_steps
        t = steps[:, None] * self._dt + self._dt
        table = np.empty((self._table_steps, self._columns[-1].stop))
        q, v, a, hand_q, hand_v = self._columns
        if self._toss:
            table[:, q], table[:, v], table[:, a] = self._arm_reference(x, t)
            table[:, hand_q], table[:, hand_v] = self._hand_reference(x, t)
            return table
        for row, time in zip(table, t[:, 0].tolist()):
            row[q], row[v], row[a] = self._arm_reference(x, time)
            row[hand_q], row[hand_v] = self._hand_reference(x, time)
        return table

    def _arm_reference(self, x, t):
        """The arm's (q, v, v̇) reference at time t in state x: at a number,
        three 6-vectors; at a column of k times (the palm toss's
        `_references`), three k × 6 arrays. With a follow (x[_QF] not
        zero), the phase's reference plus the follow's offset G(t) q̇_f,
        blended in over the move (its quintic s(τ) times the offset)."""
        q, v, a = self._phase_reference(x, t)
        if x[_PHASE] < _MOVE or x[_PHASE] > _HOLD or not x[_QF].any():
            return q, v, a
        qf = x[_QF]
        G, dG, ddG = self._follow_law.at(t, x[_TC])
        if x[_PHASE] == _MOVE:
            T = x[_T]
            b, db, ddb = quintic((t - x[_T0]) / T)
            db, ddb = db / T, ddb / T**2
            G, dG, ddG = (b * G, db * G + b * dG,
                          ddb * G + 2.0 * db * dG + b * ddG)
        return q + G * qf, v + dG * qf, a + ddG * qf

    def _phase_reference(self, x, t):
        """The arm's (q, v, v̇) reference of the phase alone (no follow),
        as `_arm_reference`'s."""
        if x[_PHASE] == _THROW:
            tau = np.minimum(t - self._t_throw, self._throw_s)
            return self._throw_reference(tau)
        T = x[_T]
        tau = (t - x[_T0]) / T
        if self._lower_moving and x[_PHASE] == _LOWER:
            # The lowering ends moving down (and goes on so until the
            # return takes over from its motion).
            s, ds, dds = ease_in(tau)
            dq = x[_QB] - x[_QA]
            return x[_QA] + s * dq, ds / T * dq, dds / T**2 * dq
        if np.all(tau >= 1.0):  # the segment is done: rest at its end
            shape = np.shape(tau)[:1] + (6,)
            return (np.broadcast_to(x[_QB], shape), np.zeros(shape),
                    np.zeros(shape))
        if ((self._toss and x[_PHASE] == _MOVE)  # from the toss's motion
                or (self._cushion and x[_PHASE] == _RETURN)):  # the lowering's
            return quintic_from(tau, T, x[_QA], x[_V0], x[_A0], x[_QB])
        s, ds, dds = quintic(tau)
        dq = x[_QB] - x[_QA]
        q, v, a = x[_QA] + s * dq, ds / T * dq, dds / T**2 * dq
        if np.ndim(tau) == 0:
            return q, v, a
        done = tau >= 1.0
        return (np.where(done, x[_QB], q), np.where(done, 0.0, v),
                np.where(done, 0.0, a))

    def _throw_reference(self, tau):
        """The throw's (q, v, v̇) at throw time tau (a number, or a column
        of k: k × 6 arrays), with its noise pulse."""
        if np.ndim(tau) == 0:
            q = self._spline.value(tau).ravel()
            v = self._spline_v.value(tau).ravel()
            a = self._spline_a.value(tau).ravel()
        else:
            taus = tau[:, 0].tolist()
            q, v, a = (spline.vector_values(taus).T for spline in (
                self._spline, self._spline_v, self._spline_a))
        if self._noise is not None:
            dq, dv, da = (np.array(d) for d in zip(*(
                self._noise.pulse(float(u), self._tau_release)
                for u in np.ravel(tau))))
            if np.ndim(tau) == 0:
                dq, dv, da = dq[0], dv[0], da[0]
            q, v, a = q + dq, v + dv, a + da
        return q, v, a

    def _hand_reference(self, x, t):
        """The fingers' (q, v) reference at time t in state x: they ramp at
        their maximum speed toward the hold posture (from t_close while
        settling and throwing), open (from the release), or closed (from
        t_close once catching). Palm toss: open while settling and
        throwing; to the pre-shaped cage after the throw, and from there to
        closed from t_close once catching (t a number, or, for the palm
        toss, a column of k: k × 10 arrays)."""
        if not self._toss:
            if x[_PHASE] <= _THROW and t < self._t_release:
                return self._open_to_hold.at(t - x[_T_CLOSE])
            if x[_PHASE] < _LOWER:
                return self._hold_to_open.at(t - self._t_release)
            return self._open_to_closed.at(t - x[_T_CLOSE])
        if x[_PHASE] <= _THROW:
            shape = np.shape(t)[:1] + self._open.shape
            return np.broadcast_to(self._open, shape), np.zeros(shape)
        if x[_PHASE] < _LOWER:
            return self._open_to_preshape.at(t - self._t_throw_end)
        return self._preshape_to_closed.at(t - x[_T_CLOSE])

    def _calc_arm_state(self, context, output: BasicVector):
        q, v, _ = self._arm_reference(
            context.get_discrete_state(self._state).value(), context.get_time())
        output.SetFromVector(np.concatenate([q, v]))

    def _calc_arm_acceleration(self, context, output: BasicVector):
        output.SetFromVector(self._arm_reference(
            context.get_discrete_state(self._state).value(),
            context.get_time())[2])

    def _calc_hand(self, context, output: BasicVector):
        output.SetFromVector(np.concatenate(self._hand_reference(
            context.get_discrete_state(self._state).value(),
            context.get_time())))

    def _calc_phase(self, context, output: BasicVector):
        output.SetAtIndex(0, context.get_discrete_state(self._state)[_PHASE])

    def watching(self, context) -> bool:
        """Whether the episode in this machine's `context` only watches."""
        return context.get_numeric_parameter(self._watching)[0] != 0.0

    def set_watching(self, context, watching: bool) -> None:
        """Makes the episode in this machine's `context` a watching throw
        (True) or a catch (False)."""
        context.get_mutable_numeric_parameter(self._watching).SetAtIndex(
            0, float(watching))

    def continue_at(self, context) -> None:
        """Makes this machine's table of references in `context` (copied
        from a machine of another plant step, at a sensor sample:
        episode.diagram.continue_with) for this machine's step, from the last
        sensor sample on. (On a continuous plant there is no table.)"""
        if self._dt == 0.0:
            return
        x = context.get_discrete_state(self._state).value().copy()
        step = round(context.get_time() / self._dt)
        sample = step - step % self._ticks_per_sample
        x[_TABLE_END] = sample + self._table_steps
        context.SetDiscreteState(self._state, x)
        context.SetDiscreteState(self._table,
                                 self._references(x, sample).ravel())

    # ---- transitions ---------------------------------------------------
    def _update(self, context, discrete_state):
        """At every plant step (on a continuous plant, at every sensor
        sample): at a sensor sample, the transitions; then the references
        for the next step, this step's row of the table. Plant step n is at
        t = n dt; the sensors sample at every _ticks_per_sample-th. Returns
        None (success, to Drake) between samples."""
        t = context.get_time()
        if self._dt == 0.0:  # references computed from the time
            return self._transition(
                context, discrete_state.get_mutable_value(self._state), t)
        step = round(t / self._dt)
        row = step % self._table_steps
        status = None
        if row % self._ticks_per_sample:  # between samples
            table = discrete_state.get_value(self._table)
        else:
            x = discrete_state.get_mutable_value(self._state)
            before = x.tobytes()
            status = self._transition(context, x, t)
            if x.tobytes() != before or step >= x[_TABLE_END]:
                # The references read x and the time only: the table holds
                # until x changes or its end.
                table = self._references(x, step).ravel()
                x[_TABLE_END] = step + self._table_steps
                discrete_state.set_value(self._table, table)
            else:
                table = discrete_state.get_value(self._table)
        arm, acceleration, hand = self._row_slices[row]
        discrete_state.set_value(self._arm_ref, table[arm])
        discrete_state.set_value(self._acc_ref, table[acceleration])
        discrete_state.set_value(self._hand_ref, table[hand])
        return status

    def _transition(self, context, x, t):
        """Fig. 9's transitions, at the sensors' rate; updates x in place."""
        phase = Phase(int(x[_PHASE]))
        segment_done = t >= x[_T0] + x[_T]
        if phase == Phase.SETTLE and t >= self._t_throw:
            x[_PHASE] = Phase.THROW
        elif phase == Phase.THROW and t >= self._t_throw_end:
            q_end, v_end, a_end = self._throw_reference(self._throw_s)
            if self.watching(context):
                q_target = self._park_q
            else:
                X_WG = self._X_WG.Eval(context)
                result = self._ik.solve(
                    X_WG, q_end if self._toss else self._catch.ik_seed_q_rad)
                if not result.success:
                    return self._fail(x, f"grasp pose unreachable: "
                                      f"{result.reason()}")
                q_target = result.q
            x[_QGRASP] = q_target
            self._start_segment(x, t, q_end, q_target,
                                self._catch.move_to_grasp_s, Phase.MOVE)
            if self._toss:  # the move takes over from the moving arm
                x[_V0], x[_A0] = v_end, a_end
            if not self.watching(context):
                follow = self._follow.Eval(context)
                x[_TC] = follow[0]
                x[_QF], _ = joint_follow(self._ik, q_target, follow[1:],
                                         self._follow_law,
                                         self._follow_fraction)
        elif (phase == Phase.MOVE and segment_done
              and not self.watching(context) and self._at_grasp(context, x)):
            x[_PHASE] = Phase.WAIT
        elif phase == Phase.WAIT:
            h_catch, h_down = self._params.Eval(context)
            if self._approach_distance(context) < h_catch:
                x[_T_CLOSE] = t
                x[_H_DOWN] = h_down
                result = self._ik.solve(
                    lowered_pose(self._X_WG.Eval(context), h_down,
                                 self._lower_along_normal),
                    x[_QGRASP])
                if not result.success:
                    return self._fail(x, "lowered pose unreachable: "
                                      f"{result.reason()}")
                # A zero-length lowering (h_down = 0) still lasts 1 ms.
                duration = max(abs(h_down) / self._catch.lower_speed_m_per_s,
                               1e-3)
                self._start_segment(x, t, x[_QGRASP], result.q, duration,
                                    Phase.LOWER)
        elif phase == Phase.LOWER:
            stop = self._palm_level(context) < self._catch.palm_stop_level
            if segment_done or stop:
                q_now, v_now, a_now = self._phase_reference(x, t)
                self._start_segment(x, t, q_now, x[_QGRASP],
                                    self._catch.return_s, Phase.RETURN)
                if self._cushion:  # the hand turns back without stopping
                    x[_V0], x[_A0] = v_now, a_now
        elif phase == Phase.RETURN and segment_done:
            x[_PHASE] = Phase.HOLD
        return EventStatus.Succeeded()

    def _fail(self, x, message):
        """Ends the episode as failed. (Returning EventStatus.Failed from a
        Python event crashes pydrake 1.51; a termination with the message,
        and the phase set to FAILED, is read back by the episode.) The arm
        holds its last reference."""
        x[_PHASE] = Phase.FAILED
        return EventStatus.ReachedTermination(self, message)

    @staticmethod
    def _start_segment(x, t, q_a, q_b, duration, phase):
        """Starts a segment of the phase's reference (`_phase_reference`)
        from q_a to q_b."""
        x[_PHASE] = phase
        x[_T0] = t
        x[_T] = duration
        x[_QA] = q_a
        x[_QB] = q_b
        x[_V0] = x[_A0] = 0.0

    def _at_grasp(self, context, x):
        """Whether the palm is at the grasp pose (with a follow, where its
        offset puts the grasp pose now)."""
        q = self._arm_state.Eval(context)[:6]
        X_WP = self._ik.palm_pose(q)
        q_grasp = x[_QGRASP]
        if x[_QF].any():
            q_grasp = q_grasp + self._follow_law.at(
                context.get_time(), x[_TC])[0] * x[_QF]
        X_WG = self._ik.palm_pose(q_grasp)
        error = np.linalg.norm(X_WP.translation() - X_WG.translation())
        return error < self._catch.grasp_tolerance_m

    def _approach_distance(self, context):
        levels = self._ir.Eval(context)[3:]
        return float(np.min(levels)) / self._levels * self._approach_range

    def _palm_level(self, context):
        return float(np.min(self._ir.Eval(context)[:3]))
