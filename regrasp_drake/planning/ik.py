"""Inverse kinematics of the PUMA 560 for the hand's palm frame.

Damped least squares on the arm-only control plant: deterministic, ~1 ms a
solve, no optimizer. The task frame is the hand's `palm_surface` frame P
(origin at the centre of the palm, +z its normal, +x toward the fingertips).
"""

import dataclasses as dc

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.parsing import ModelDirective
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import JacobianWrtVariable

from regrasp_drake.world import robot


def palm_in_flange(directives: list[ModelDirective] | None = None
                   ) -> RigidTransform:
    """X_6P: the palm_surface frame in the PUMA's link6 frame (fixed weld),
    for the robot of the model directives (default: the shipped robot's)."""
    plant = MultibodyPlant(0.0)
    robot.add_puma_and_hand(plant, directives)
    plant.Finalize()
    context = plant.CreateDefaultContext()
    return plant.CalcRelativeTransform(
        context, plant.GetFrameByName("link6"),
        plant.GetFrameByName("palm_surface"))


@dc.dataclass
class IkResult:
    q: np.ndarray  # arm joint angles, [rad]
    position_error_m: float
    rotation_error_rad: float
    within_limits: bool

    @property
    def success(self) -> bool:
        # The paper's Fig. 9 tolerance on the wrist: 1 mm.
        return (self.position_error_m < 1e-3 and self.rotation_error_rad < 1e-3
                and self.within_limits)

    def reason(self) -> str:
        """Why the pose is not reachable ("" when it is)."""
        if not self.within_limits:
            return "the solution violates a joint limit"
        if not self.success:
            return (f"no solution within tolerance (position error "
                    f"{self.position_error_m * 1e3:.1f} mm, rotation error "
                    f"{self.rotation_error_rad:.3f} rad)")
        return ""


class ArmIk:
    """Solves q such that X_WP(q) = X_WP_desired for the hand's palm frame,
    on the arm-only plant of the robot's model directives (default: the
    shipped robot's; pass a scenario's `directives`)."""

    def __init__(self, directives: list[ModelDirective] | None = None):
        self._directives = list(directives or robot.robot_directives())
        self._plant = robot.arm_control_plant(self._directives)
        self._context = self._plant.CreateDefaultContext()
        self._frame6 = self._plant.GetFrameByName("link6")
        self._X_6P = palm_in_flange(self._directives)
        self._lower = self._plant.GetPositionLowerLimits()
        self._upper = self._plant.GetPositionUpperLimits()

    @property
    def directives(self) -> list[ModelDirective]:
        """The robot's model directives this was built for."""
        return self._directives

    @property
    def plant(self) -> MultibodyPlant:
        return self._plant

    @property
    def palm_in_flange(self) -> RigidTransform:
        """X_6P: the palm frame in link 6's (`palm_in_flange`)."""
        return self._X_6P

    def palm_pose(self, q) -> RigidTransform:
        """X_WP at arm joint angles q."""
        self._plant.SetPositions(self._context, q)
        X_W6 = self._frame6.CalcPoseInWorld(self._context)
        return X_W6 @ self._X_6P

    def solve(self, X_WP_desired: RigidTransform, q_seed,
              max_iterations: int = 200) -> IkResult:
        """Damped least squares from q_seed, within the joint limits."""
        q = np.clip(np.asarray(q_seed, float), self._lower, self._upper)
        p_6P = self._X_6P.translation()
        world = self._plant.world_frame()
        damping = 1e-4
        for _ in range(max_iterations):
            X_WP = self.palm_pose(q)
            error = _pose_error(X_WP, X_WP_desired)
            if np.linalg.norm(error[3:]) < 1e-6 and np.linalg.norm(error[:3]) < 1e-7:
                break
            J = self._plant.CalcJacobianSpatialVelocity(
                self._context, JacobianWrtVariable.kQDot, self._frame6, p_6P,
                world, world)
            dq = J.T @ np.linalg.solve(J @ J.T + damping * np.eye(6), error)
            step = np.linalg.norm(dq)
            if step > 0.3:
                dq *= 0.3 / step
            q = np.clip(q + dq, self._lower, self._upper)
        X_WP = self.palm_pose(q)
        error = _pose_error(X_WP, X_WP_desired)
        within = bool(np.all(q >= self._lower - 1e-9)
                      and np.all(q <= self._upper + 1e-9))
        return IkResult(q=q, position_error_m=float(np.linalg.norm(error[3:])),
                        rotation_error_rad=float(np.linalg.norm(error[:3])),
                        within_limits=within)


def _pose_error(X_WP: RigidTransform, X_WD: RigidTransform) -> np.ndarray:
    """Spatial error [w; v] in W that takes P to D (angle-axis, position)."""
    R_PD = X_WP.rotation().inverse() @ X_WD.rotation()
    aa = R_PD.ToAngleAxis()
    w_W = X_WP.rotation() @ (aa.axis() * aa.angle())
    return np.concatenate([w_W, X_WD.translation() - X_WP.translation()])


def palm_up_pose(p_WP, x_W) -> RigidTransform:
    """Palm frame at p_WP facing up (+z_W), its +x (toward the fingertips)
    along the horizontal part of x_W."""
    x = np.array([x_W[0], x_W[1], 0.0])
    norm = np.linalg.norm(x)
    if norm < 1e-9:
        raise ValueError(f"x_W={x_W} has no horizontal part")
    x /= norm
    z = np.array([0.0, 0.0, 1.0])
    y = np.cross(z, x)
    return RigidTransform(RotationMatrix(np.column_stack([x, y, z])), p_WP)
