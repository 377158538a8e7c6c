"""Tests of the PUMA 560 + hand models and of regrasp_drake.world.robot."""

import unittest
import xml.etree.ElementTree as ET

import numpy as np
from pydrake.common.yaml import yaml_load_typed
from pydrake.geometry import Cylinder
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialForce
from pydrake.multibody.parsing import ModelDirectives
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    ContactModel,
    CoulombFriction,
    DiscreteContactApproximation,
    ExternallyAppliedSpatialForce,
    MultibodyPlant,
)
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.analysis import Simulator
from pydrake.systems.framework import DiagramBuilder

from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.world import robot

# Standard DH table of puma560.md: (d, a, alpha), m and rad.
DH = (
    (0.67183, 0.0, np.pi / 2),
    (0.0, 0.4318, 0.0),
    (0.15005, 0.0203, -np.pi / 2),
    (0.4318, 0.0, np.pi / 2),
    (0.0, 0.0, -np.pi / 2),
    (0.0, 0.0, 0.0),
)
G = 9.81


def dh_link_poses(q):
    """Returns the 4x4 poses of DH frames 0..6 in the world (base at the origin)."""
    T = np.eye(4)
    poses = [T.copy()]
    for theta, (d, a, alpha) in zip(q, DH):
        ct, st, ca, sa = np.cos(theta), np.sin(theta), np.cos(alpha), np.sin(alpha)
        A = np.array(
            [
                [ct, -st * ca, st * sa, a * ct],
                [st, ct * ca, -ct * sa, a * st],
                [0.0, sa, ca, d],
                [0.0, 0.0, 0.0, 1.0],
            ]
        )
        T = T @ A
        poses.append(T.copy())
    return poses


def sdf_link_inertials(path):
    """Link name -> (mass kg, COM in the link frame m, [Ixx, Iyy, Izz] kg·m² about the
    COM), read straight from the SDF XML (every <inertial> pose there is unrotated)."""
    inertials = {}
    for link in ET.parse(path).getroot().iter("link"):
        inertial = link.find("inertial")
        pose = [float(x) for x in inertial.find("pose").text.split()]
        assert pose[3:] == [0.0, 0.0, 0.0], link.get("name")
        moments = [
            float(inertial.find(f"inertia/{k}").text) for k in ("ixx", "iyy", "izz")
        ]
        inertials[link.get("name")] = (
            float(inertial.find("mass").text),
            np.array(pose[:3]),
            np.array(moments),
        )
    return inertials


class TestArm(unittest.TestCase):
    """The arm alone against the published PUMA 560 figures."""

    @classmethod
    def setUpClass(cls):
        cls.plant = MultibodyPlant(time_step=0.0)
        cls.arm = robot.add_puma(cls.plant)
        cls.plant.Finalize()
        cls.context = cls.plant.CreateDefaultContext()

    def holding_torques(self, q):
        """Joint torques that hold the arm still against gravity at q, N·m."""
        self.plant.SetPositions(self.context, q)
        # Drake returns tau_g on the right-hand side of M v̇ + C v = tau_g + tau.
        return -self.plant.CalcGravityGeneralizedForces(self.context)

    def test_gravity_torques_match_published(self):
        published = {
            "qz": (robot.QZ, [0.0, 37.48, 0.249, 0.0, 0.0, 0.0]),
            "qs": (robot.QS, [0.0, 46.01, 8.772, 0.0, 0.028, 0.0]),
        }
        for name, (q, tau_published) in published.items():
            tau = self.holding_torques(q)
            for i, expected in enumerate(tau_published):
                with self.subTest(pose=name, joint=i + 1):
                    if expected == 0.0:
                        self.assertAlmostEqual(tau[i], 0.0, delta=1e-6)
                    else:
                        self.assertAlmostEqual(tau[i], expected, delta=0.01 * expected)

    def test_link_frames_are_dh_frames(self):
        rng = np.random.default_rng(0)
        poses = [robot.QZ, robot.QR, robot.QS, robot.QN]
        poses += [rng.uniform(-np.pi, np.pi, 6) for _ in range(3)]
        for q in poses:
            self.plant.SetPositions(self.context, q)
            for i, T_dh in enumerate(dh_link_poses(q)):
                X_WL = self.plant.EvalBodyPoseInWorld(
                    self.context, self.plant.GetBodyByName(f"link{i}", self.arm)
                )
                with self.subTest(q=q.round(3).tolist(), link=i):
                    np.testing.assert_allclose(
                        X_WL.translation(), T_dh[:3, 3], rtol=0, atol=1e-6
                    )
                    np.testing.assert_allclose(
                        X_WL.rotation().matrix(), T_dh[:3, :3], rtol=0, atol=1e-9
                    )

    def test_arm_joint_order_and_limits(self):
        joints = [self.plant.get_joint(i) for i in self.plant.GetJointIndices(self.arm)]
        revolute = [j.name() for j in joints if j.num_velocities() == 1]
        self.assertEqual(tuple(revolute), robot.ARM_JOINTS)
        lower = self.plant.GetPositionLowerLimits()
        upper = self.plant.GetPositionUpperLimits()
        np.testing.assert_allclose(
            np.rad2deg(lower), [-160, -45, -225, -110, -100, -266], atol=1e-6
        )
        np.testing.assert_allclose(
            np.rad2deg(upper), [160, 225, 45, 170, 100, 266], atol=1e-6
        )


class TestRobotModel(unittest.TestCase):
    """PUMA + hand as loaded from the model directives."""

    @classmethod
    def setUpClass(cls):
        builder = DiagramBuilder()
        cls.plant, cls.scene_graph = AddMultibodyPlantSceneGraph(
            builder, time_step=1e-3
        )
        cls.robot = robot.add_puma_and_hand(cls.plant)
        cls.plant.Finalize()
        robot.exclude_robot_self_collisions(cls.plant, cls.scene_graph)
        cls.context = cls.plant.CreateDefaultContext()

    def bodies(self, instance):
        return [self.plant.get_body(i) for i in self.plant.GetBodyIndices(instance)]

    def test_bodies_have_sdf_masses_and_valid_inertias(self):
        for instance, path in (
            (self.robot.arm, robot.PUMA_SDF),
            (self.robot.hand, robot.HAND_SDF),
        ):
            inertials = sdf_link_inertials(path)
            bodies = self.bodies(instance)
            self.assertEqual(sorted(b.name() for b in bodies), sorted(inertials))
            for body in bodies:
                mass, p_BoBcm, moments = inertials[body.name()]
                M_BBo_B = body.default_spatial_inertia()
                I_BBcm_B = M_BBo_B.Shift(M_BBo_B.get_com()).CalcRotationalInertia()
                with self.subTest(body=body.name()):
                    # Catches Drake silently replacing an invalid inertia by a sphere.
                    self.assertAlmostEqual(body.default_mass(), mass, places=12)
                    np.testing.assert_allclose(body.default_com(), p_BoBcm, atol=1e-12)
                    np.testing.assert_allclose(
                        I_BBcm_B.get_moments(), moments, rtol=1e-12
                    )
                    np.testing.assert_allclose(I_BBcm_B.get_products(), 0.0, atol=1e-15)
                    self.assertTrue(M_BBo_B.IsPhysicallyValid())
        hand_mass = sum(b.default_mass() for b in self.bodies(self.robot.hand))
        self.assertGreaterEqual(hand_mass, 0.6)
        self.assertLessEqual(hand_mass, 0.7)

    def test_mass_matrix_is_positive_definite(self):
        rng = np.random.default_rng(1)
        lower = np.nan_to_num(self.plant.GetPositionLowerLimits(), neginf=-np.pi)
        upper = np.nan_to_num(self.plant.GetPositionUpperLimits(), posinf=np.pi)
        for _ in range(5):
            self.plant.SetPositions(self.context, rng.uniform(lower, upper))
            M = self.plant.CalcMassMatrix(self.context)
            np.testing.assert_allclose(M, M.T, atol=1e-12)
            self.assertGreater(np.linalg.eigvalsh(M).min(), 0.0)

    def test_actuators_carry_the_papers_limits(self):
        actuators = [
            self.plant.get_joint_actuator(i)
            for i in self.plant.GetJointActuatorIndices()
        ]
        self.assertEqual(
            tuple(a.joint().name() for a in actuators),
            robot.ARM_JOINTS + robot.HAND_JOINTS,
        )
        efforts = [a.effort_limit() for a in actuators]
        np.testing.assert_allclose(efforts[:6], [150, 186.4, 89.4, 24.2, 20.1, 21.3])
        np.testing.assert_allclose(efforts[:6], robot.ARM_EFFORT_LIMITS)
        np.testing.assert_allclose(efforts[6:], robot.FINGER_EFFORT_LIMIT)
        self.assertEqual(robot.FINGER_EFFORT_LIMIT, 10.0)
        # The arm is torque controlled; the fingers are in-plant PD servos.
        self.assertFalse(any(a.has_controller() for a in actuators[:6]))
        self.assertTrue(all(a.has_controller() for a in actuators[6:]))
        # Reflected rotor inertia Jm G^2 of the published table (joint 2: 2.325).
        self.assertAlmostEqual(
            actuators[1].default_reflected_inertia(), 2.325, delta=1e-3
        )
        for name in robot.HAND_JOINTS:
            joint = self.plant.GetJointByName(name, self.robot.hand)
            self.assertAlmostEqual(
                joint.velocity_upper_limits()[0], robot.FINGER_MAX_SPEED, 2
            )

    def test_hand_mount(self):
        link6 = self.plant.GetFrameByName("link6", self.robot.arm)
        surface = self.plant.GetFrameByName("palm_surface", self.robot.hand)
        X_6S = self.plant.CalcRelativeTransform(self.context, link6, surface)
        R = X_6S.rotation().matrix()
        np.testing.assert_allclose(R[:, 0], [0, 0, 1], atol=1e-12)  # approach = z6
        np.testing.assert_allclose(R[:, 2], [1, 0, 0], atol=1e-12)  # normal = x6
        palm = self.plant.GetFrameByName("palm", self.robot.hand)
        p_6P = self.plant.CalcRelativeTransform(self.context, link6, palm).translation()
        np.testing.assert_allclose(p_6P, [0, 0, 0.116], atol=1e-12)

    def test_sensor_frames_and_bumper_on_palm(self):
        palm = self.plant.GetBodyByName("palm", self.robot.hand)
        surface = self.plant.GetFrameByName("palm_surface", self.robot.hand)
        for k in range(1, 14):
            ir = self.plant.GetFrameByName(f"ir{k}", self.robot.hand)
            with self.subTest(ir=k):
                self.assertEqual(ir.body().index(), palm.index())
                X_SI = self.plant.CalcRelativeTransform(self.context, surface, ir)
                self.assertAlmostEqual(X_SI.translation()[2], 0.0, places=12)
                z = X_SI.rotation().col(2)
                if k <= 3:  # palm sensors: along the palm normal
                    np.testing.assert_allclose(z, [0, 0, 1], atol=1e-12)
                    continue
                # Approach sensors: upward, in the palm's x-z plane, inclined
                # from their edge toward the palm's centre line, which the
                # ray crosses between 0.05 and 0.5 m above the palm.
                p = X_SI.translation()
                self.assertAlmostEqual(z[1], 0.0, places=12)
                self.assertGreater(z[2], 0.0)
                self.assertLess(z[0] * p[0], 0.0)
                crossing = -p[0] / z[0] * z[2]
                self.assertTrue(0.05 <= crossing <= 0.5, crossing)
        inspector = self.scene_graph.model_inspector()
        boxes = {
            inspector.GetName(g).split("::")[-1]: g
            for g in self.plant.GetCollisionGeometriesForBody(palm)
        }
        bumper, palm_box = boxes["bumper"], boxes["palm_collision"]
        np.testing.assert_allclose(
            inspector.GetShape(bumper).size(), [0.03, 0.06, 0.001]
        )
        top = {
            g: inspector.GetPoseInFrame(g).translation()[2]
            + inspector.GetShape(g).height() / 2
            for g in (bumper, palm_box)
        }
        self.assertAlmostEqual(top[bumper] - top[palm_box], 0.001, places=12)

    def test_self_collisions_are_filtered(self):
        inspector = self.scene_graph.model_inspector()
        arm_geometries, hand_geometries = (
            [
                g
                for b in self.bodies(i)
                for g in self.plant.GetCollisionGeometriesForBody(b)
            ]
            for i in (self.robot.arm, self.robot.hand)
        )
        self.assertGreater(len(arm_geometries), 6)
        self.assertGreater(len(hand_geometries), 10)
        for a in arm_geometries:
            for h in hand_geometries:
                self.assertTrue(inspector.CollisionFiltered(a, h))
        # Two fingertips of the same hand could otherwise touch.
        self.assertTrue(
            inspector.CollisionFiltered(hand_geometries[-1], hand_geometries[-3])
        )

    def test_control_plant_matches_arm_with_open_hand(self):
        control = robot.make_arm_control_plant()
        self.assertEqual((control.num_positions(), control.num_velocities()), (6, 6))
        self.assertEqual(control.num_actuators(), 6)
        self.assertEqual(control.time_step(), 0.0)
        hand_mass = sum(b.default_mass() for b in self.bodies(self.robot.hand))
        self.assertAlmostEqual(
            control.GetBodyByName("hand").default_mass(), hand_mass, 12
        )
        control_context = control.CreateDefaultContext()
        rng = np.random.default_rng(2)
        arm_v = slice(0, 6)
        for q in [robot.QZ, robot.QN, rng.uniform(-2, 2, 6)]:
            self.plant.SetPositions(self.context, self.robot.arm, q)
            self.plant.SetPositions(self.context, self.robot.hand, robot.HAND_OPEN)
            control.SetPositions(control_context, q)
            with self.subTest(q=q.round(3).tolist()):
                np.testing.assert_allclose(
                    control.CalcGravityGeneralizedForces(control_context),
                    self.plant.CalcGravityGeneralizedForces(self.context)[arm_v],
                    atol=1e-9,
                )
                np.testing.assert_allclose(
                    control.CalcMassMatrix(control_context),
                    self.plant.CalcMassMatrix(self.context)[arm_v, arm_v],
                    atol=1e-9,
                )
        # The hand's weight is felt: at qz joint 2 carries more than the bare arm.
        control.SetPositions(control_context, robot.QZ)
        self.assertGreater(
            -control.CalcGravityGeneralizedForces(control_context)[1], 37.48 + 0.5
        )



def _moved_robot_directives():
    """The shipped directives with the arm's base moved and turned and the
    hand mounted 3 cm further out, turned about the flange axis."""
    text = robot.directives_yaml(None)
    text = text.replace(
        "child: puma560::link0",
        "child: puma560::link0\n    X_PC:\n      translation: [0.2, -0.1, 0.05]"
        "\n      rotation: !Rpy\n        deg: [0.0, 0.0, 30.0]", 1)
    text = text.replace("[0.0, 0.0, 0.116]", "[0.0, 0.0, 0.146]", 1)
    return list(yaml_load_typed(schema=ModelDirectives, data=text).directives)


class TestControlPlantFromDirectives(unittest.TestCase):
    """The arm-only plant (inverse dynamics, inverse kinematics) is built
    from the scenario's model directives: a robot placed otherwise is
    controlled and planned as the plant it builds."""

    @classmethod
    def setUpClass(cls):
        cls.directives = _moved_robot_directives()
        cls.plant = MultibodyPlant(0.0)
        cls.robot = robot.add_puma_and_hand(cls.plant, cls.directives)
        cls.plant.Finalize()
        cls.context = cls.plant.CreateDefaultContext()
        cls.control = robot.make_arm_control_plant(cls.directives)
        cls.control_context = cls.control.CreateDefaultContext()

    def test_the_directives_are_not_the_shipped_ones(self):
        self.assertNotEqual(robot.directives_yaml(self.directives),
                            robot.directives_yaml(None))

    def test_dynamics_match_the_full_plant(self):
        rng = np.random.default_rng(3)
        for q in [robot.QZ, robot.QN, rng.uniform(-2, 2, 6)]:
            self.plant.SetPositions(self.context, self.robot.arm, q)
            self.plant.SetPositions(self.context, self.robot.hand,
                                    robot.HAND_OPEN)
            self.control.SetPositions(self.control_context, q)
            with self.subTest(q=q.round(3).tolist()):
                np.testing.assert_allclose(
                    self.control.CalcGravityGeneralizedForces(
                        self.control_context),
                    self.plant.CalcGravityGeneralizedForces(self.context)[:6],
                    atol=1e-9)
                np.testing.assert_allclose(
                    self.control.CalcMassMatrix(self.control_context),
                    self.plant.CalcMassMatrix(self.context)[:6, :6],
                    atol=1e-9)
        # The moved mount changes the dynamics: the shipped plant differs.
        shipped = robot.make_arm_control_plant()
        shipped_context = shipped.CreateDefaultContext()
        self.assertGreater(np.abs(
            shipped.CalcMassMatrix(shipped_context)
            - self.control.CalcMassMatrix(self.control_context)).max(), 1e-3)

    def test_inverse_kinematics_reaches_the_full_plant_s_palm_pose(self):
        ik = ArmIk(self.directives)
        q = np.array([0.3, 0.6, -0.4, 0.2, 0.5, -0.1])
        self.plant.SetPositions(self.context, self.robot.arm, q)
        X_WP = self.plant.GetFrameByName(
            "palm_surface", self.robot.hand).CalcPoseInWorld(self.context)
        self.assertTrue(X_WP.IsNearlyEqualTo(ik.palm_pose(q), 1e-12))
        result = ik.solve(X_WP, q + 0.05)
        self.assertTrue(result.success, result.reason())
        self.plant.SetPositions(self.context, self.robot.arm, result.q)
        reached = self.plant.GetFrameByName(
            "palm_surface", self.robot.hand).CalcPoseInWorld(self.context)
        self.assertLess(np.linalg.norm(
            reached.translation() - X_WP.translation()), 1e-3)
        # The shipped robot's inverse kinematics puts the palm elsewhere.
        self.assertGreater(np.linalg.norm(
            ArmIk().palm_pose(q).translation() - X_WP.translation()), 0.1)

    def test_a_hand_not_on_the_arm_is_refused(self):
        text = robot.directives_yaml(None).replace(
            "parent: puma560::link6", "parent: world")
        directives = yaml_load_typed(schema=ModelDirectives, data=text)
        with self.assertRaisesRegex(ValueError, "the hand is welded to"):
            robot.make_arm_control_plant(list(directives.directives))

class TestHandEnvelope(unittest.TestCase):
    """The hand, welded palm-up, wraps a cylinder lying across its palm and holds it
    when the load is reversed (as if the hand were turned upside down)."""

    def simulate(self, diameter, command, mass=0.1, length=0.12):
        """Closes the fingers toward `command` at FINGER_MAX_SPEED for 0.5 s, then pulls
        the cylinder away from the palm with 2 m g for 0.5 s (net: gravity reversed).

        Returns (fingers touching the cylinder at 0.5 s, cylinder displacement during
        the reversed load in m).
        """
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=1e-3)
        plant.set_contact_model(ContactModel.kPoint)
        plant.set_discrete_contact_approximation(DiscreteContactApproximation.kSap)
        hand = robot.add_hand(plant)  # palm frame = world: palm normal up
        radius = diameter / 2
        cylinder = plant.AddRigidBody(
            "cylinder",
            plant.AddModelInstance("cylinder"),
            SpatialInertia.SolidCylinderWithMass(mass, radius, length, [0, 1, 0]),
        )
        X_BG = RigidTransform(RotationMatrix.MakeXRotation(np.pi / 2))  # axis along y
        plant.RegisterCollisionGeometry(
            cylinder,
            X_BG,
            Cylinder(radius, length),
            "cylinder",
            CoulombFriction(0.8, 0.8),
        )
        plant.Finalize()
        robot.exclude_robot_self_collisions(plant, scene_graph)
        simulator = Simulator(builder.Build())
        context = plant.GetMyMutableContextFromRoot(simulator.get_mutable_context())
        # Resting on the bumper (top 0.011 m above the palm mid-plane), palm centre.
        plant.SetFreeBodyPose(
            context, cylinder, RigidTransform([0.045, 0, 0.011 + radius])
        )

        desired_state = plant.get_desired_state_input_port(hand)
        dt = 0.01
        for step in range(1, 51):
            q = np.minimum(command, robot.FINGER_MAX_SPEED * step * dt)
            v = np.where(q < command, robot.FINGER_MAX_SPEED, 0.0)
            desired_state.FixValue(context, np.concatenate([q, v]))
            simulator.AdvanceTo(step * dt)

        contacts = plant.get_contact_results_output_port().Eval(context)
        finger_of = {
            name: finger
            for finger, links in robot.FINGER_LINKS.items()
            for name in links
        }
        touching = set()
        for i in range(contacts.num_point_pair_contacts()):
            info = contacts.point_pair_contact_info(i)
            for body in (info.bodyA_index(), info.bodyB_index()):
                touching.add(finger_of.get(plant.get_body(body).name()))
        touching.discard(None)

        p_WC0 = plant.EvalBodyPoseInWorld(context, cylinder).translation().copy()
        pull = ExternallyAppliedSpatialForce()
        pull.body_index = cylinder.index()
        pull.p_BoBq_B = np.zeros(3)
        pull.F_Bq_W = SpatialForce(np.zeros(3), [0.0, 0.0, 2.0 * mass * G])
        plant.get_applied_spatial_force_input_port().FixValue(context, [pull])
        simulator.AdvanceTo(1.0)
        p_WC1 = plant.EvalBodyPoseInWorld(context, cylinder).translation()
        return touching, np.linalg.norm(p_WC1 - p_WC0)

    def test_closed_hand_holds_cylinders(self):
        # ~0.1 kg cylinders of 5 and 10 cm, and a 0.3 kg one (holding margin).
        for diameter, mass in ((0.05, 0.1), (0.10, 0.1), (0.10, 0.3)):
            with self.subTest(diameter=diameter, mass=mass):
                touching, displacement = self.simulate(
                    diameter, robot.HAND_CLOSED, mass
                )
                self.assertIn("thumb", touching)
                self.assertGreaterEqual(len(touching), 3)
                self.assertLess(displacement, 0.02)

    def test_open_hand_lets_cylinder_go(self):
        # The reversed load is strong enough to carry off an object that is not held.
        touching, displacement = self.simulate(0.10, robot.HAND_OPEN)
        self.assertEqual(touching, set())
        self.assertGreater(displacement, 0.5)


if __name__ == "__main__":
    unittest.main()
