"""The offline stage: catch points from a watched flight, and the hand's pose.

A catch point is a moment of the descent where the object's symmetry axis y_O
is horizontal (|y_O · z_W| below a tolerance) and the object is at a height the
hand can wait at. The paper catches "where the object is horizontal,
otherwise the probability of catching is reduced" (§V).
"""

import dataclasses as dc

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix

from regrasp_drake.planning.ik import palm_up_pose


@dc.dataclass
class CatchPoint:
    t_s: float              # time of the episode, [s]
    p_WO: np.ndarray        # the object frame's origin, [m]
    y_W: np.ndarray         # the object's symmetry axis, unit, in W
    v_catch: float          # the object's vertical velocity there, [m/s]
    tilt: float             # |y_O · z_W|, [-]

    def as_dict(self) -> dict:
        return {"t_s": round(self.t_s, 4),
                "p_WO": [round(float(c), 5) for c in self.p_WO],
                "axis_W": [round(float(c), 5) for c in self.y_W],
                "v_catch": round(self.v_catch, 4), "tilt": round(self.tilt, 5)}


def find_catch_points(t, object_state, *, height_m: float,
                      tilt_tolerance: float = 0.1,
                      band_m: float = 0.08,
                      most_horizontal: bool = False) -> list[CatchPoint]:
    """Catch points of a logged flight (13-row object states: wxyz quaternion,
    p_WO, w_WO, v_WO), best first.

    In the descent, within `band_m` of `height_m`, the moments where the
    object's axis is horizontal: each horizontal passage (a run of samples
    with |y_O · z_W| < tilt_tolerance) gives its sample nearest `height_m`;
    the points are ordered by their distance to `height_m`.

    `most_horizontal`: when the axis is never horizontal in the band, the
    band's most horizontal moment of the descent is the one point returned
    (its `tilt` says how far from horizontal; the paper: away from
    horizontal "the probability of catching is reduced")."""
    t = np.asarray(t)
    p = object_state[4:7]
    v = object_state[10:13]
    y_W = np.array([_axis(object_state[:4, k]) for k in range(len(t))]).T
    tilt = np.abs(y_W[2])
    apex = int(np.argmax(p[2]))
    ok = np.zeros(len(t), bool)
    ok[apex:] = (np.abs(p[2, apex:] - height_m) <= band_m) & (
        tilt[apex:] < tilt_tolerance) & (v[2, apex:] < 0)
    points = []
    k = 0
    while k < len(t):
        if not ok[k]:
            k += 1
            continue
        run = [k]
        while k + 1 < len(t) and ok[k + 1]:
            k += 1
            run.append(k)
        k += 1
        run = np.array(run)
        # The horizontal moment nearest the preferred height.
        best = run[np.argmin(np.abs(p[2, run] - height_m))]
        points.append(_interpolate(t, p, v, y_W, best, 0.0))
    points.sort(key=lambda c: abs(c.p_WO[2] - height_m))
    if not points and most_horizontal:
        in_band = np.zeros(len(t), bool)
        in_band[apex:] = (np.abs(p[2, apex:] - height_m) <= band_m) & (
            v[2, apex:] < 0)
        if np.any(in_band):
            k = int(np.flatnonzero(in_band)[np.argmin(tilt[in_band])])
            points.append(_interpolate(t, p, v, y_W, k, 0.0))
    return points


def _axis(quaternion_wxyz) -> np.ndarray:
    q = np.asarray(quaternion_wxyz, float)
    R = RotationMatrix(Quaternion(q / np.linalg.norm(q)))
    return R.matrix()[:, 1]


def _interpolate(t, p, v, y_W, k, a) -> CatchPoint:
    y = (1 - a) * y_W[:, k] + a * y_W[:, k + 1]
    y /= np.linalg.norm(y)
    return CatchPoint(
        t_s=float((1 - a) * t[k] + a * t[k + 1]),
        p_WO=(1 - a) * p[:, k] + a * p[:, k + 1],
        y_W=y, v_catch=float((1 - a) * v[2, k] + a * v[2, k + 1]),
        tilt=float(abs(y[2])))


def palm_poses_for(catch_point: CatchPoint, grasp_radius_m: float,
                   palm_clearance_m: float = 0.002,
                   theta_rad: float = 0.3) -> list[RigidTransform]:
    """The palm's poses under a catch point, preferred first: palm up, centred
    under the object's origin, the fingertips (palm +x, the paper's z_k)
    perpendicular to the object's axis; first on the side the paper's θ
    construction picks (eqs. 2-5), then on the other side (used only when
    the arm cannot reach the first)."""
    y = catch_point.y_W.copy()
    y[2] = 0.0
    y /= np.linalg.norm(y)
    x = fingertip_direction(catch_point.p_WO, y, theta_rad)
    p_WP = catch_point.p_WO - np.array(
        [0.0, 0.0, grasp_radius_m + palm_clearance_m])
    return [palm_up_pose(p_WP, x), palm_up_pose(p_WP, -x)]


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
