"""A rigid body's free flight, in closed form for its centre of mass and by
integrating Euler's equations for its rotation: gravity only, no air drag
(the paper's assumptions, and the plant's).

States use the plant's layout for a free body (13 rows): the quaternion
(w, x, y, z) of R_WO, p_WO (m), the angular velocity w_WO (rad/s, in W) and
v_WO (m/s, the velocity of O's origin, in W).
"""

import dataclasses as dc

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RotationMatrix


def _R(quaternion_wxyz) -> np.ndarray:
    q = np.asarray(quaternion_wxyz, float)
    return RotationMatrix(Quaternion(q / np.linalg.norm(q))).matrix()


def _quaternion(R) -> np.ndarray:
    return RotationMatrix(R).ToQuaternion().wxyz()


def _hat(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]],
                     [-w[1], w[0], 0.0]])


def _rotation_step(R, L_W, I_inv_O, h):
    """One RK4 step of Ṙ = [w]× R, w = R I⁻¹ Rᵀ L (L constant), then the
    result projected back onto a rotation."""
    def f(R):
        return _hat(R @ I_inv_O @ R.T @ L_W) @ R
    k1 = f(R)
    k2 = f(R + 0.5 * h * k1)
    k3 = f(R + 0.5 * h * k2)
    k4 = f(R + h * k3)
    R = R + h / 6.0 * (k1 + 2 * k2 + 2 * k3 + k4)
    u, _, vt = np.linalg.svd(R)
    return u @ vt


def propagate(state, times, *, p_OCm, I_CmCm_O, gravity_W,
              max_step_s: float = 5e-4) -> np.ndarray:
    """The free flight from `state` at times[0] to every time in `times`
    (ascending, s): a (13, len(times)) array of states.

    p_OCm: the centre of mass in O (m); I_CmCm_O: the rotational inertia
    about it, in O (kg·m², 3×3; only its ratios matter); gravity_W (m/s²).
    """
    times = np.asarray(times, float)
    state = np.asarray(state, float)
    g = np.asarray(gravity_W, float)
    p_OCm = np.asarray(p_OCm, float)
    I_O = np.asarray(I_CmCm_O, float)
    I_inv_O = np.linalg.inv(I_O)
    R = _R(state[:4])
    w = state[7:10]
    p_Cm0 = state[4:7] + R @ p_OCm
    v_Cm0 = state[10:13] + np.cross(w, R @ p_OCm)
    L_W = R @ I_O @ R.T @ w
    out = np.empty((13, len(times)))
    t = times[0]
    for k, t_k in enumerate(times):
        while t < t_k - 1e-12:
            n = max(1, int(np.ceil((t_k - t) / max_step_s)))
            h = (t_k - t) / n
            for _ in range(n):
                R = _rotation_step(R, L_W, I_inv_O, h)
            t = t_k
        dt = t_k - times[0]
        w = R @ I_inv_O @ R.T @ L_W
        p_Cm = p_Cm0 + v_Cm0 * dt + 0.5 * g * dt * dt
        v_Cm = v_Cm0 + g * dt
        out[:4, k] = _quaternion(R)
        out[4:7, k] = p_Cm - R @ p_OCm
        out[7:10, k] = w
        out[10:13, k] = v_Cm - np.cross(w, R @ p_OCm)
    return out


def central_inertia(obj) -> np.ndarray:
    """The object's rotational inertia about its centre of mass, in O."""
    M = obj.spatial_inertia()
    return M.Shift(M.get_com()).CalcRotationalInertia().CopyToFullMatrix3()


def sampled_flight(state, t0, obj, scenario, duration_s: float = 1.6):
    """The free flight from `state` at t0 [s], sampled at the sensors'
    period for duration_s [s]: (t, states)."""
    period = scenario.sensors.period_s
    t = t0 + period * np.arange(int(duration_s / period) + 1)
    states = propagate(state, t, p_OCm=obj.p_OCm,
                       I_CmCm_O=central_inertia(obj),
                       gravity_W=[0.0, 0.0, -scenario.gravity_m_per_s2])
    return t, states


def flight_from_release(state, t0, obj, scenario):
    """The free flight from the object's state `state` (13, as logged) seen
    at t0 [s], in the shape plan_catch reads (.logs.t, .logs.object_state).

    The plant's discrete step (semi-implicit Euler: v += g·h, then p += h·v)
    keeps the centre of mass on the parabola through its position with
    velocity v + g·h/2, h the plant's time step: the flight is propagated from
    that velocity (measured: the plan from it is within 0.5 mm of the plan
    from the whole watched flight, on the five Table 1 objects)."""
    state = np.asarray(state, float).copy()
    state[10:13] += 0.5 * scenario.plant_config.time_step * np.array(
        [0.0, 0.0, -scenario.gravity_m_per_s2])
    return as_watched(*sampled_flight(state, t0, obj, scenario))


@dc.dataclass(frozen=True)
class FlightLogs:
    """A flight's object states at its sample times, as an episode logs
    them (episode.result.Logs' fields of the object)."""
    t: np.ndarray             # (n,) [s]
    object_state: np.ndarray  # (13, n): quaternion wxyz, p_WO, w_WO, v_WO


@dc.dataclass(frozen=True)
class WatchedFlight:
    """A flight seen or predicted, read by plan_catch as it reads a watching
    throw's EpisodeResult (its `.logs`)."""
    logs: FlightLogs


def as_watched(t, states) -> WatchedFlight:
    """(t, states) in the shape plan_catch reads: .logs.t, .logs.object_state."""
    return WatchedFlight(FlightLogs(t=t, object_state=states))
