"""The offline stage: catch points from a watched flight, and the hand's pose.

A catch point is a moment of the descent where the object's symmetry axis y_O
is horizontal (|y_O · z_W| below a tolerance) and the object is at a height the
hand can wait at. The paper catches "where the object is horizontal,
otherwise the probability of catching is reduced" (§V). `catch_moments` ranks
every moment the hand can be in place for, horizontal ones first (the plan's
choice, see throw_catch.plan_catch).

The palm waits under the object as it will be at that moment, parallel to its
axis: just below its lowest point (a piece hanging below the grasp piece lands
first), under its centre of mass across the axis, and along the axis under
the grasp piece unless that leaves the centre of mass near the palm's edge.
The arm must get there in time: `move_torque_ratio` checks that the move to
the grasp pose stays within the servos' torque limits (a saturated move
overshoots and arrives late).
"""

import dataclasses as dc

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.tree import MultibodyForces

from regrasp_drake.planning.free_flight import propagate
from regrasp_drake.planning.ik import ArmIk, palm_up_pose

# The state machine's time law of the move to the grasp pose.
from regrasp_drake.planning.time_law import quintic_from
from regrasp_drake.world.objects import ObjectSpec
from regrasp_drake.world.robot import ARM_EFFORT_LIMITS


@dc.dataclass
class CatchPoint:
    t_s: float              # time of the episode, [s]
    p_WO: np.ndarray        # the object frame's origin, [m]
    y_W: np.ndarray         # the object's symmetry axis, unit, in W
    v_catch: float          # the object's vertical velocity there, [m/s]
    tilt: float             # |y_O · z_W|, [-]
    R_WO: np.ndarray | None = None  # the object's orientation there, 3×3
    w_W: np.ndarray | None = None   # its angular velocity there, [rad/s]
    v_W: np.ndarray | None = None   # its frame origin's velocity, [m/s]

    def as_dict(self) -> dict:
        return {"t_s": round(self.t_s, 4),
                "p_WO": [round(float(c), 5) for c in self.p_WO],
                "axis_W": [round(float(c), 5) for c in self.y_W],
                "v_catch": round(self.v_catch, 4), "tilt": round(self.tilt, 5)}


def _rotation(quaternion_wxyz) -> np.ndarray:
    q = np.asarray(quaternion_wxyz, float)
    return RotationMatrix(Quaternion(q / np.linalg.norm(q))).matrix()


def _point(t, p, v, R_WO, k, w) -> CatchPoint:
    return CatchPoint(t_s=float(t[k]), p_WO=p[:, k].copy(),
                      y_W=R_WO[k][:, 1].copy(), v_catch=float(v[2, k]),
                      tilt=float(abs(R_WO[k][2, 1])), R_WO=R_WO[k],
                      w_W=w[:, k].copy(), v_W=v[:, k].copy())


def lowest_points_z(obj: ObjectSpec, object_state) -> np.ndarray:
    """The height of the object's lowest point at each sample of a logged
    flight (13-row object states), [m]."""
    return np.array([
        lowest_point_z(obj, _rotation(object_state[:4, k]),
                       object_state[4:7, k])
        for k in range(object_state.shape[1])])


def lowest_point_z(obj: ObjectSpec, R_WO, p_WO) -> float:
    """The height of the object's lowest surface point, [m], with its frame
    at (R_WO, p_WO)."""
    return lowest_point_along(obj, R_WO, p_WO, np.array([0.0, 0.0, 1.0]))


def lowest_point_along(obj: ObjectSpec, R_WO, p_WO, n_W) -> float:
    """min over the object's surface of p_WS · n_W, [m], for a unit vector
    n_W, with the object's frame at (R_WO, p_WO)."""
    R_WO = np.asarray(R_WO)
    n_W = np.asarray(n_W, float)
    n_O = R_WO.T @ n_W
    lowest = np.inf
    for piece in obj.pieces:
        d = (p_WO + R_WO @ piece.center) @ n_W
        if piece.shape == "box":
            d -= 0.5 * np.abs(n_O) @ piece.size
        elif piece.shape == "sphere":
            d -= piece.radius
        else:  # a cylinder or capsule: its axis's direction sets the extent
            u_n = abs(n_O[piece.axis])
            d -= u_n * piece.length / 2 + (
                piece.radius if piece.shape == "capsule"
                else piece.radius * np.sqrt(max(0.0, 1.0 - u_n**2)))
        lowest = min(lowest, d)
    return float(lowest)


def catch_moments(t, object_state, obj: ObjectSpec, *, height_m: float,
                  band_m: float, ready_s: float, fall_m: float,
                  tilt_tolerance: float,
                  flat_tolerance_m: float = 0.005,
                  gravity_m_per_s2: float = 9.81,
                  exact_crossings: bool = False) -> list[CatchPoint]:
    """The moments of a logged flight at which the hand can catch, best first.

    With `exact_crossings` (the palm toss), first the moments at which the
    axis is exactly horizontal (`horizontal_moments`), from `ready_s` on and
    within `band_m` of `height_m`; then the logged samples, ranked as
    follows.

    Candidates: the samples of the descent within `band_m` of `height_m`
    from `ready_s` on (the hand is in place). Order:
    1. the axis within `tilt_tolerance` of horizontal (|y_O · z_W|); the palm
       turns to lie parallel to it (`palm_poses_for`);
    2. the object lands flat: its centre of mass is at most
       `flat_tolerance_m` higher above the palm's plane (through the object's
       lowest point along the palm normal) than at the flattest candidate. A
       lopsided object arriving on its end, its centre of mass high above a
       small face, tips over in the hand;
    3. the most fall after `ready_s`, counted up to `fall_m`: every h_catch
       up to that can trigger after the hand is in place;
    4. the nearest to `height_m`."""
    t = np.asarray(t)
    p = object_state[4:7]
    v = object_state[10:13]
    R_WO = [_rotation(object_state[:4, k]) for k in range(len(t))]
    lowest = lowest_points_z(obj, object_state)
    apex = int(np.argmax(p[2]))
    ready = t >= ready_s
    k_ready = int(np.argmax(ready)) if ready.any() else len(t) - 1
    candidates = [k for k in range(apex, len(t)) if ready[k] and v[2, k] < 0
                  and abs(p[2, k] - height_m) <= band_m]
    if not candidates:
        return []
    max_tilt = np.arcsin(min(tilt_tolerance, 1.0))
    rest, tilted = {}, {}
    for k in candidates:
        n_W = palm_frame(R_WO[k][:, 1], max_tilt)[:, 2]
        p_WCm = p[:, k] + R_WO[k] @ obj.p_OCm
        rest[k] = p_WCm @ n_W - lowest_point_along(obj, R_WO[k], p[:, k], n_W)
        tilted[k] = abs(R_WO[k][2, 1]) >= tilt_tolerance
    flattest = min((rest[k] for k in candidates if not tilted[k]),
                   default=min(rest.values()))
    candidates.sort(key=lambda k: (
        tilted[k], rest[k] > flattest + flat_tolerance_m,
        -min(lowest[k_ready] - lowest[k], fall_m), abs(p[2, k] - height_m)))
    exact = [point for point in horizontal_moments(
        t, object_state, obj, gravity_m_per_s2=gravity_m_per_s2)
        if point.t_s >= ready_s and abs(point.p_WO[2] - height_m) <= band_m
    ] if exact_crossings else []
    return exact + [_point(t, p, v, R_WO, k, object_state[7:10])
                    for k in candidates]


def horizontal_moments(t, object_state, obj: ObjectSpec, *,
                       gravity_m_per_s2: float = 9.81,
                       iterations: int = 30) -> list[CatchPoint]:
    """The moments of a logged flight's descent at which the object's
    symmetry axis is exactly horizontal (y_O · z_W = 0), earliest first: the
    crossing between two samples is found by propagating the free flight
    from the sample before it (`free_flight.propagate`) and bisecting. So a
    catch point is a property of the flight, not of the logging rate nor of
    the time step: between a 1 ms and a 0.25 ms step its moment moves with
    the flight itself (sample-picking would move it by a whole 4 ms
    sample). Only stretches of free flight count (the centre of mass
    accelerating at g, checked between the two samples)."""
    t = np.asarray(t)
    a = np.array([_rotation(object_state[:4, k])[2, 1]
                  for k in range(len(t))])
    g_W = np.array([0.0, 0.0, -gravity_m_per_s2])
    inertia = obj.spatial_inertia()
    p_OCm = inertia.get_com()
    I_O = inertia.Shift(p_OCm).CalcRotationalInertia().CopyToFullMatrix3()
    points = []
    for k in range(len(t) - 1):
        if a[k] == 0.0 or a[k] * a[k + 1] > 0.0 or object_state[12, k] >= 0:
            continue
        start = object_state[:, k]

        def state_at(time):
            return propagate(start, [t[k], time], p_OCm=p_OCm,
                             I_CmCm_O=I_O, gravity_W=g_W)[:, -1]

        end = state_at(t[k + 1])
        if np.linalg.norm(end[4:7] - object_state[4:7, k + 1]) > 1e-4:
            continue  # not free flight between the two samples
        lo, hi = float(t[k]), float(t[k + 1])
        for _ in range(iterations):
            mid = 0.5 * (lo + hi)
            if _rotation(state_at(mid)[:4])[2, 1] * a[k] > 0.0:
                lo = mid
            else:
                hi = mid
        x = state_at(0.5 * (lo + hi))
        R = _rotation(x[:4])
        points.append(CatchPoint(
            t_s=0.5 * (lo + hi), p_WO=x[4:7].copy(), y_W=R[:, 1].copy(),
            v_catch=float(x[12]), tilt=float(abs(R[2, 1])), R_WO=R,
            w_W=x[7:10].copy(), v_W=x[10:13].copy()))
    return points


def palm_frame(axis_W, max_tilt_rad: float, x_W=None) -> np.ndarray:
    """The palm's axes [x y z] (columns) under an object with symmetry axis
    `axis_W`: +x (the fingertips) horizontal and perpendicular to the axis
    (`x_W`, or either such direction when None), +y along the axis turned
    up or down by at most `max_tilt_rad`, +z the palm normal."""
    axis_W = np.asarray(axis_W, float)
    if x_W is None:
        x_W = np.cross([0.0, 0.0, 1.0], axis_W)
        if np.linalg.norm(x_W) < 1e-12:  # a vertical axis
            x_W = np.array([1.0, 0.0, 0.0])
        x_W /= np.linalg.norm(x_W)
    y_up = np.cross([0.0, 0.0, 1.0], x_W)  # the palm-up pose's y
    axis = axis_W * (1.0 if axis_W @ y_up >= 0 else -1.0)
    tilt = np.clip(np.arctan2(axis[2], np.linalg.norm(axis[:2])),
                   -max_tilt_rad, max_tilt_rad)
    y_W = np.cos(tilt) * y_up + np.sin(tilt) * np.array([0.0, 0.0, 1.0])
    return np.column_stack([x_W, y_W, np.cross(x_W, y_W)])


def palm_poses_for(catch_point: CatchPoint, grasp_radius_m: float,
                   palm_clearance_m: float = 0.002,
                   theta_rad: float = 0.3, obj: ObjectSpec | None = None,
                   com_margin_m: float = 0.02,
                   max_palm_tilt_rad: float = 0.3,
                   across_com_fraction: float = 1.0,
                   toward_landing_end_m: float = 0.0,
                   toward_fingers_m: float = 0.0,
                   along_axis_m: float = 0.0,
                   com_along_normal: bool = False) -> list[RigidTransform]:
    """The palm's poses under a catch point, preferred first: the fingertips
    (palm +x, the paper's z_k) horizontal and perpendicular to the object's
    axis; first on the side the paper's θ construction picks (eqs. 2-5), then
    on the other side (used only when the arm cannot reach the first).

    Without `obj` (or without the point's orientation), the palm faces up,
    centred under the object's origin with the grasp piece (radius
    `grasp_radius_m`) resting on it. With `obj`, the palm is parallel to the
    object's axis (turned about the fingertip direction by the axis's tilt,
    at most `max_palm_tilt_rad`: the paper wants "the hand parallel with the
    object at the moment of catching"), `palm_clearance_m` below the object
    along its normal (a piece hanging below the grasp piece meets the palm
    first); across the axis it is centred under the centre of mass (or
    `across_com_fraction` of the way to it from the grasp piece's axis), and
    along the axis under the grasp piece, shifted only as far as it takes to
    bring the centre of mass within `com_margin_m` of the palm's centre (the
    palm is 11.5 cm across: a centre of mass much farther out tips the object
    over its edge), then `toward_landing_end_m` toward the end of the object
    that comes down first (the object turns end over end as it lands: the
    end coming down strikes first and the palm should be under it); and the
    palm moves `toward_fingers_m` toward its heel, so that the object lands
    that much nearer the fingers, inside the cage they close
    (studies/hand_design: both measured with the 115 mm palm). Last, the
    palm slides `along_axis_m` toward the object's +y end (a regrasp
    target's offset, planning/grasp.py).

    `com_along_normal`: the offsets above are kept along the palm's own
    (tilted) y rather than horizontally, so that a palm tilted by α does not
    put the centre of mass, h above it, h·tan α off its centre along y
    (studies/landing: +12 mm under keep for Table 1 rows 1-3)."""
    y = catch_point.y_W.copy()
    y[2] = 0.0
    y /= np.linalg.norm(y)
    x = fingertip_direction(catch_point.p_WO, y, theta_rad)
    if obj is None or catch_point.R_WO is None:
        p_WP = catch_point.p_WO - np.array(
            [0.0, 0.0, grasp_radius_m + palm_clearance_m])
        return [palm_up_pose(p_WP, x), palm_up_pose(p_WP, -x)]
    R_WO = catch_point.R_WO
    p_OCm_W = R_WO @ obj.p_OCm  # the centre of mass from the origin
    p_OCm_W[2] = 0.0
    along = p_OCm_W @ y
    # (At the fraction 1 these are the same floating-point operations as
    # p_WO + p_OCm_W - along * y: the same plans, bit for bit.)
    f = float(across_com_fraction)
    p_WP = catch_point.p_WO + f * p_OCm_W - (f * along) * y + np.sign(
        along) * max(0.0, abs(along) - com_margin_m) * y
    if toward_landing_end_m and catch_point.w_W is not None:
        # The +y end's vertical velocity relative to the centre of mass,
        # per metre along the axis: negative, the +y end comes down first.
        descent = np.cross(catch_point.w_W, y)[2]
        p_WP = p_WP - np.sign(descent) * toward_landing_end_m * y
    if along_axis_m:
        p_WP = p_WP + along_axis_m * y
    poses = []
    for x_W in (x, -x):
        R_WP = palm_frame(catch_point.y_W, max_palm_tilt_rad, x_W)
        z_W = R_WP[:, 2]
        # Height: the object's lowest point along the palm normal is
        # palm_clearance_m above the palm's plane.
        p = p_WP - toward_fingers_m * R_WP[:, 0]
        p[2] = (lowest_point_along(obj, R_WO, catch_point.p_WO, z_W)
                - palm_clearance_m - p[:2] @ z_W[:2]) / z_W[2]
        if com_along_normal:
            # Slide the palm in its own plane until the centre of mass's
            # offset along the tilted y is the horizontal plan's.
            y_W = R_WP[:, 1]
            y_h = np.array([y_W[0], y_W[1], 0.0]) / np.linalg.norm(y_W[:2])
            p_WC = catch_point.p_WO + R_WO @ obj.p_OCm
            p = p + ((p_WC - p) @ y_W - (p_WC - p_WP) @ y_h) * y_W
        poses.append(RigidTransform(RotationMatrix(R_WP), p))
    return poses


def move_torque_ratio(ik: ArmIk, q_start, q_end, duration_s: float,
                      samples: int = 41, v_start=None,
                      a_start=None, gravity: bool = False) -> float:
    """The largest |τ_i| / effort limit_i the arm needs to follow the state
    machine's move from q_start (with velocity v_start and acceleration
    a_start, default at rest: the throw hands over a moving arm) to q_end at
    rest in `duration_s` (`planning/time_law.quintic_from`), by inverse
    dynamics of the arm and hand (the object is in flight). Above 1 the
    servos saturate: the arm lags, overshoots and reaches the grasp position
    late. `gravity`: count the arm's weight too (the palm toss's plans, the
    shipped ones). The finger throw's plans (`FingerThrow`) are checked
    without it, as its data set was made, so that they stay reproducible
    (the controller does compensate gravity: a gap found with the palm
    toss)."""
    plant = ik.plant
    context = plant.CreateDefaultContext()
    forces = MultibodyForces(plant)
    q_start = np.asarray(q_start, float)
    zeros = np.zeros_like(q_start)
    v0 = zeros if v_start is None else np.asarray(v_start, float)
    a0 = zeros if a_start is None else np.asarray(a_start, float)
    q_end = np.asarray(q_end, float)
    worst = 0.0
    for tau in np.linspace(0.0, 1.0, samples):
        q, v, a = quintic_from(min(tau, 1.0 - 1e-12), duration_s, q_start,
                               v0, a0, q_end)
        plant.SetPositions(context, q)
        plant.SetVelocities(context, v)
        # CalcInverseDynamics counts only the forces given.
        forces.SetZero()
        if gravity:
            plant.CalcForceElementsContribution(context, forces)
        torque = plant.CalcInverseDynamics(context, a, forces)
        worst = max(worst, float(np.max(np.abs(torque) / ARM_EFFORT_LIMITS)))
    return worst


def fingertip_direction(p_WO, y_horizontal, theta_rad) -> np.ndarray:
    """The paper's eqs. (2)-(5), its y-up world mapped to our z-up world
    (x, y, z)_paper -> (x, -z, y): r_p is the catch point's horizontal
    projection, r_pr the same turned by θ about the vertical, r_R = r_pr - r_p
    points to the right of the axis, and z_k = y' × (y' × r_R) / |…| is the
    part of -r_R perpendicular to the axis: the fingertips point left."""
    r_p = np.array([p_WO[0], p_WO[1], 0.0])
    c, s = np.cos(theta_rad), np.sin(theta_rad)
    R_z = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
    r_R = R_z @ r_p - r_p
    z_k = np.cross(y_horizontal, np.cross(y_horizontal, r_R))
    if np.linalg.norm(z_k) < 1e-12:  # r_R along the axis: no side to prefer
        z_k = np.cross([0.0, 0.0, 1.0], y_horizontal)
    return z_k / np.linalg.norm(z_k)
