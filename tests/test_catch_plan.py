"""The offline stage: catch points on analytic flights, the hand's pose at a
catch point (paper eqs. 1-7 in Drake's z-up world), and the arm's inverse
kinematics there."""

import json
import subprocess
import sys
import tempfile
import types
import unittest
from pathlib import Path

import numpy as np
from pydrake.multibody.plant import MultibodyPlant

from regrasp_drake.errors import InputError
from regrasp_drake.planning.catch_plan import (
    CatchPoint,
    catch_moments,
    palm_poses_for,
)
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.throw_catch import plan_catch, plan_catches
from regrasp_drake.world import robot
from regrasp_drake.world.objects import load_catalogue

G = 9.81
DT = 0.001  # sample period of the analytic flights, [s]


def tumbling_flight(angle, p0=(0.85, -0.1, 0.8), v0=(0.0, 0.0, 3.0),
                    duration_s=0.9):
    """An analytic flight: a parabola under gravity and the object turning
    about the world x axis by angle(t) rad, so that its axis y_O is
    (0, cos angle, sin angle). Returns (t, 13-row object states)."""
    t = np.arange(0.0, duration_s, DT)
    p = np.array(p0)[:, None] + np.outer(v0, t)
    p[2] -= 0.5 * G * t ** 2
    v = np.repeat(np.array(v0, float)[:, None], len(t), axis=1)
    v[2] -= G * t
    phi = angle(t)
    quaternion = np.array([np.cos(phi / 2), np.sin(phi / 2), 0 * t, 0 * t])
    w = np.zeros((3, len(t)))
    w[0] = np.gradient(phi, t)
    return t, np.vstack([quaternion, p, w, v])


def crossing_time(height, z0=0.8, vz0=3.0):
    """When the parabola of `tumbling_flight` falls through height, [s]."""
    return (vz0 + np.sqrt(vz0 ** 2 + 2 * G * (z0 - height))) / G


def moments(t, x, *, height_m=0.78, band_m=0.3, tilt_tolerance=0.1,
            ready_s=0.0):
    """catch_moments on an analytic flight of a symmetric object (no fall
    preference, so that only tilt, flatness and height order them)."""
    obj = load_catalogue()["table1-row1"]
    return catch_moments(t, x, obj, height_m=height_m, band_m=band_m,
                         ready_s=ready_s, fall_m=0.0,
                         tilt_tolerance=tilt_tolerance)


class TestCatchMoments(unittest.TestCase):
    def test_horizontal_at_the_catch_height(self):
        """The axis turns horizontal exactly where the object falls through
        the catch height: the best moment is there, with v_catch = vz0 - g t."""
        t_h = crossing_time(0.78)
        t, x = tumbling_flight(lambda t: 8.0 * (t - t_h) + np.pi)
        c = moments(t, x)[0]
        self.assertAlmostEqual(c.t_s, t_h, delta=DT)
        self.assertAlmostEqual(c.p_WO[2], 0.78, delta=3.0 * DT * 3.1)
        self.assertAlmostEqual(c.v_catch, 3.0 - G * t_h, delta=G * DT)
        self.assertLess(c.v_catch, 0.0)
        np.testing.assert_allclose(np.abs(c.y_W), [0, 1, 0], atol=0.01)
        self.assertLess(c.tilt, 8.0 * DT)

    def test_horizontal_moments_first_descent_in_band_only(self):
        """The axis turns horizontal several times: every moment of the
        descent within the band is a candidate, those within the tilt
        tolerance first, each group nearest the catch height first; the
        ascent, the samples outside the band, and the moments before the hand
        is ready are not candidates."""
        t_near, t_far = crossing_time(0.80), crossing_time(1.0)
        rate = np.pi / (t_near - t_far)  # half a turn between the two
        t, x = tumbling_flight(lambda t: rate * (t - t_far))
        ready_s = 3.0 / G + 0.02  # just after the apex
        points = moments(t, x, ready_s=ready_s)
        z = x[6]
        expected = {round(tk, 6) for tk, zk, vk in zip(t, z, x[12])
                    if tk >= ready_s and vk < 0 and abs(zk - 0.78) <= 0.3}
        self.assertEqual({round(p.t_s, 6) for p in points}, expected)
        tilted = [p.tilt >= 0.1 for p in points]
        self.assertEqual(tilted, sorted(tilted))  # level ones first
        level = [p for p in points if p.tilt < 0.1]
        self.assertGreaterEqual(len(level), 2)
        # Each level moment is near a horizontal passage, angle = kπ.
        for p in level:
            k = round(rate * (p.t_s - t_far) / np.pi)
            self.assertLess(abs(rate * (p.t_s - t_far) - k * np.pi),
                            np.arcsin(0.1) + rate * DT)
            self.assertAlmostEqual(p.v_catch, 3.0 - G * p.t_s, delta=1e-9)
        heights = [abs(p.p_WO[2] - 0.78) for p in level]
        self.assertEqual(heights, sorted(heights))

    def test_none_when_the_flight_stays_below_the_band(self):
        """A low toss (apex 0.25 m) never comes within 0.2 m of 0.78 m."""
        t, x = tumbling_flight(lambda t: 4.0 * t, p0=(0.85, -0.1, 0.2),
                               v0=(0.0, 0.0, 1.0), duration_s=0.3)
        self.assertEqual(moments(t, x, band_m=0.2), [])


class TestPalmPose(unittest.TestCase):
    """Paper eqs. (1)-(7): palm up, the finger-closing direction (the palm's
    +x, the paper's z_k) perpendicular to the object's axis, on the side the
    θ = 0.3 rad construction picks."""

    def setUp(self):
        rng = np.random.default_rng(7)
        self.points = []
        for _ in range(200):
            y = rng.normal(size=3)
            y[2] *= 0.1  # catch points lie nearly horizontal
            p = rng.uniform([-1.0, -1.0, 0.5], [1.0, 1.0, 1.0])
            self.points.append(CatchPoint(t_s=1.0, p_WO=p,
                                          y_W=y / np.linalg.norm(y),
                                          v_catch=-3.0, tilt=0.0))

    def test_palm_up_and_fingers_across_the_axis(self):
        for c in self.points:
            for X_WG in palm_poses_for(c, 0.03):
                R = X_WG.rotation().matrix()
                np.testing.assert_allclose(R[:, 2], [0, 0, 1], atol=1e-12)
                self.assertLess(abs(R[:, 0] @ c.y_W), 1e-9)
                # Centred under the object, the grasp piece resting on it.
                np.testing.assert_allclose(
                    X_WG.translation(), c.p_WO - [0, 0, 0.03 + 0.002],
                    atol=1e-12)

    def test_side_from_the_theta_construction(self):
        """The fingertips point away from r_R (the catch point's horizontal
        projection turned by θ about the vertical, minus itself), across the
        axis: z_k = y' × (y' × r_R) / |…|; the second pose is the other
        side."""
        theta = 0.3
        for c in self.points:
            r_p = np.array([c.p_WO[0], c.p_WO[1], 0.0])
            r_R = np.array([[np.cos(theta), -np.sin(theta), 0],
                            [np.sin(theta), np.cos(theta), 0],
                            [0, 0, 1]]) @ r_p - r_p
            y = c.y_W * [1, 1, 0] / np.linalg.norm(c.y_W[:2])
            across = r_R - (r_R @ y) * y
            paper, mirrored = palm_poses_for(c, 0.03, theta_rad=theta)
            np.testing.assert_allclose(paper.rotation().matrix()[:, 0],
                                       -across / np.linalg.norm(across),
                                       atol=1e-9)
            np.testing.assert_allclose(mirrored.rotation().matrix()[:, 0],
                                       across / np.linalg.norm(across),
                                       atol=1e-9)

    def test_side_independent_of_the_axis_sign(self):
        """y_O and -y_O are the same symmetry axis: the same hand pose."""
        for c in self.points:
            flipped = CatchPoint(c.t_s, c.p_WO, -c.y_W, c.v_catch, c.tilt)
            for a, b in zip(palm_poses_for(c, 0.03),
                            palm_poses_for(flipped, 0.03)):
                self.assertTrue(a.IsExactlyEqualTo(b))


    def test_palm_across_the_axis_between_grasp_piece_and_com(self):
        # table1-row4: centre of mass 43 mm off the grasp piece's axis
        # (r_cm). Across the axis (the fingertip direction x), the palm's
        # centre sits at the fraction of the way from that axis to it.
        obj = load_catalogue()["table1-row4"]
        c = CatchPoint(t_s=1.0, p_WO=np.array([0.8, -0.1, 0.7]),
                       y_W=np.array([0.0, 1.0, 0.0]), v_catch=-3.0, tilt=0.0,
                       R_WO=np.eye(3))
        p_OCm = np.array(obj.p_OCm)
        self.assertAlmostEqual(abs(p_OCm[0]), 0.043, places=6)
        for fraction in (1.0, 0.5, 0.0):
            with self.subTest(fraction=fraction):
                X_WP = palm_poses_for(c, obj.grasp_radius, obj=obj,
                                      across_com_fraction=fraction)[0]
                across = X_WP.translation()[0] - c.p_WO[0]
                self.assertAlmostEqual(across, fraction * p_OCm[0], places=12)
        # The default is the fraction 1, bit for bit.
        np.testing.assert_array_equal(
            palm_poses_for(c, obj.grasp_radius, obj=obj)[0].translation(),
            palm_poses_for(c, obj.grasp_radius, obj=obj,
                           across_com_fraction=1.0)[0].translation())

    def test_palm_toward_the_landing_end_and_its_heel(self):
        # The object turns end over end about the world x axis as it lands
        # (w_W along x): with w_x > 0 its +y end rises, the -y end comes
        # down first, and the palm moves toward -y; then toward its heel
        # (-x of the palm), so that the object lands nearer the fingers.
        # Its height is set afterwards from the object's lowest point.
        obj = load_catalogue()["table1-row2"]
        base = dict(t_s=1.0, p_WO=np.array([0.8, -0.1, 0.7]),
                    y_W=np.array([0.0, 1.0, 0.0]), v_catch=-3.0, tilt=0.0,
                    R_WO=np.eye(3))
        plain = palm_poses_for(CatchPoint(**base), obj.grasp_radius,
                               obj=obj)[0]
        for w_x, side in ((5.5, -1.0), (-5.5, 1.0)):
            with self.subTest(w_x=w_x):
                c = CatchPoint(**base, w_W=np.array([w_x, 0.0, 0.0]))
                # Without the two shifts the angular velocity changes nothing.
                np.testing.assert_array_equal(
                    palm_poses_for(c, obj.grasp_radius, obj=obj)[0]
                    .translation(), plain.translation())
                moved = palm_poses_for(c, obj.grasp_radius, obj=obj,
                                       toward_landing_end_m=0.01,
                                       toward_fingers_m=0.01)[0]
                d = moved.translation() - plain.translation()
                x_palm = plain.rotation().matrix()[:, 0]
                expected = side * 0.01 * np.array([0.0, 1.0, 0.0]) \
                    - 0.01 * x_palm
                np.testing.assert_allclose(d[:2], expected[:2], atol=1e-9)
                np.testing.assert_allclose(
                    moved.rotation().matrix(), plain.rotation().matrix())
        # A catch point without its angular velocity is not moved along the
        # axis (only toward the heel).
        moved = palm_poses_for(CatchPoint(**base), obj.grasp_radius, obj=obj,
                               toward_landing_end_m=0.01)[0]
        np.testing.assert_array_equal(moved.translation(),
                                      plain.translation())
    def test_a_grasp_target_waits_for_the_resting_grasp(self):
        # Under a grasp target the palm is not shifted toward the landing
        # end (the object rests where it first touches, studies/landing);
        # under `any` it is, by catch.palm_toward_landing_end_m.
        from regrasp_drake.planning.grasp import Target
        from regrasp_drake.station.scenario import with_target
        from regrasp_drake.throw_catch import catch_palm_poses
        obj = load_catalogue()["table1-row2"]
        c = CatchPoint(t_s=1.0, p_WO=np.array([0.8, -0.1, 0.7]),
                       y_W=np.array([0.0, 1.0, 0.0]), v_catch=-3.0, tilt=0.0,
                       R_WO=np.eye(3), w_W=np.array([5.5, 0.0, 0.0]))
        scenario = load_scenario()
        plain = palm_poses_for(
            c, obj.grasp_radius, obj=obj,
            com_margin_m=scenario.catch.palm_com_margin_m,
            toward_fingers_m=scenario.catch.palm_toward_fingers_m
        )[0].translation()
        held = catch_palm_poses(scenario, c, obj)[0].translation()
        self.assertAlmostEqual(held[1] - plain[1],
                               -scenario.catch.palm_toward_landing_end_m)
        for kind in ("keep", "flip"):
            with self.subTest(kind=kind):
                target = with_target(scenario, Target(kind, 0.0))
                np.testing.assert_allclose(
                    catch_palm_poses(target, c, obj)[0].translation(), plain,
                    atol=1e-12)

    def test_offsets_along_a_tilted_palm(self):
        # An axis tilted 10° up toward +y: the palm tilts with it, and with
        # com_along_normal the centre of mass lies on the palm's normal
        # through its centre (offset 0 along the tilted y) instead of
        # h·tan α off it.
        obj = load_catalogue()["table1-row2"]
        a = np.radians(10.0)
        R_WO = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(a), -np.sin(a)],
                         [0.0, np.sin(a), np.cos(a)]])
        c = CatchPoint(t_s=1.0, p_WO=np.array([0.8, -0.1, 0.7]),
                       y_W=R_WO[:, 1], v_catch=-3.0, tilt=np.sin(a),
                       R_WO=R_WO)
        p_WC = c.p_WO + R_WO @ obj.p_OCm
        for along_normal in (False, True):
            X_WP = palm_poses_for(c, obj.grasp_radius, obj=obj,
                                  com_margin_m=0.0,
                                  com_along_normal=along_normal)[0]
            y_W = X_WP.rotation().matrix()[:, 1]
            self.assertAlmostEqual(abs(y_W[2]), np.sin(a), places=9)
            along = (p_WC - X_WP.translation()) @ y_W
            height = (p_WC - X_WP.translation()) @ X_WP.rotation().matrix()[
                :, 2]
            with self.subTest(along_normal=along_normal):
                if along_normal:
                    self.assertAlmostEqual(along, 0.0, places=9)
                else:
                    self.assertAlmostEqual(abs(along),
                                           height * np.tan(a), places=6)


class TestInverseKinematics(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        # The analytic flights fall through the finger throw's catch height,
        # 0.78 m (the palm toss catches at 0.45 m).
        cls.scenario = load_scenario(name="FingerThrow")
        cls.ik = ArmIk()
        # An independent forward kinematics: the whole robot (arm and hand)
        # as the station loads it, the palm frame read directly.
        cls.plant = MultibodyPlant(0.0)
        cls.instances = robot.add_puma_and_hand(cls.plant)
        cls.plant.Finalize()
        cls.context = cls.plant.CreateDefaultContext()

    def _palm_pose(self, q):
        self.plant.SetPositions(self.context, self.instances.arm, q)
        return self.plant.GetFrameByName("palm_surface").CalcPoseInWorld(
            self.context)

    def test_planned_poses_reached_within_1_mm_and_limits(self):
        """Random catch points in the catch region (seeded): every solution
        the IK accepts puts the palm within 1 mm and 1 mrad of the planned
        pose, by the full robot's kinematics, inside the joint limits; and
        most points have a reachable side (35 of 40 measured)."""
        rng = np.random.default_rng(1)
        lower = self.plant.GetPositionLowerLimits()[:6]
        upper = self.plant.GetPositionUpperLimits()[:6]
        arm_joints = [self.plant.GetJointByName(j).position_start()
                      for j in robot.ARM_JOINTS]
        self.assertEqual(arm_joints, list(range(6)))
        reachable = 0
        for _ in range(40):
            p = rng.uniform([0.75, -0.25, 0.65], [0.95, 0.15, 0.9])
            a = rng.uniform(-np.pi, np.pi)
            y = np.array([np.cos(a), np.sin(a), rng.uniform(-0.15, 0.15)])
            c = CatchPoint(1.0, p, y / np.linalg.norm(y), -3.0, 0.0)
            solved = False
            for X_WG in palm_poses_for(c, 0.025):
                result = self.ik.solve(X_WG, self.scenario.catch.ik_seed_q_rad)
                if not result.success:
                    self.assertTrue(result.reason())
                    continue
                solved = True
                X = self._palm_pose(result.q)
                self.assertLess(np.linalg.norm(
                    X.translation() - X_WG.translation()), 1e-3)
                R_error = X.rotation().inverse() @ X_WG.rotation()
                self.assertLess(abs(R_error.ToAngleAxis().angle()), 1e-3)
                self.assertTrue(np.all(result.q >= lower - 1e-12))
                self.assertTrue(np.all(result.q <= upper + 1e-12))
            reachable += solved
        self.assertGreaterEqual(reachable, 32)

    def test_unreachable_point_reported_not_crashed(self):
        far = CatchPoint(1.0, np.array([3.0, 0.0, 0.8]),
                         np.array([1.0, 0.0, 0.0]), -3.0, 0.0)
        for X_WG in palm_poses_for(far, 0.025):
            result = self.ik.solve(X_WG, self.scenario.catch.ik_seed_q_rad)
            self.assertFalse(result.success)
            self.assertIn("position error", result.reason())

    def test_plan_skips_unreachable_points_with_reasons(self):
        """A watched flight whose only catch point is out of reach: the plan
        is refused with the point and each side's reason."""
        t_h = crossing_time(0.78)
        t, x = tumbling_flight(lambda t: 8.0 * (t - t_h) + np.pi,
                               p0=(3.0, 0.0, 0.8))
        # The 30 ms seen around the crossing: every moment in the band is
        # tried on both sides (two failing IK solves each), 30 of them here
        # rather than the whole flight's 208.
        seen = (t >= t_h - 0.02) & (t <= t_h + 0.01)
        # On the episode's clock: released 1 s in, so that the object falls
        # past the catch height after the hand could be in place.
        watched = types.SimpleNamespace(logs=types.SimpleNamespace(
            t=t[seen] + 1.0, object_state=x[:, seen]))
        obj = load_catalogue()["table1-row2"]
        with self.assertRaises(InputError) as e:
            plan_catch(self.scenario, obj, self.ik, watched)
        message = str(e.exception)
        self.assertIn("no reachable catch point", message)
        self.assertIn("paper side", message)
        self.assertIn("mirrored side", message)
        self.assertEqual(len(message.splitlines()), 1)

    def test_several_plans_are_distinct_moments_best_first(self):
        """plan_catches: the first plan is plan_catch's; the others are
        other moments of the same flight, at least the separation apart."""
        t_h = crossing_time(0.78)
        t, x = tumbling_flight(lambda t: 3.0 * (t - t_h) + np.pi)
        watched = types.SimpleNamespace(
            logs=types.SimpleNamespace(t=t + 1.0, object_state=x))
        obj = load_catalogue()["table1-row2"]
        plans = plan_catches(self.scenario, obj, self.ik, watched, count=3,
                             min_separation_s=0.03)
        self.assertEqual(len(plans), 3)
        first = plan_catch(self.scenario, obj, self.ik, watched)
        self.assertEqual(plans[0].catch_point.t_s, first.catch_point.t_s)
        times = [p.catch_point.t_s for p in plans]
        for i in range(3):
            for j in range(i + 1, 3):
                self.assertGreaterEqual(abs(times[i] - times[j]), 0.03 - 1e-9)


class TestThrowCommand(unittest.TestCase):
    def test_throw_reports_catch_points_and_plan(self):
        """`regrasp-drake throw`: one watching throw, its catch points with
        v_catch and reachability, the one used, the planned hand pose."""
        with tempfile.TemporaryDirectory() as d:
            out, png = Path(d) / "throw.json", Path(d) / "throw.png"
            result = subprocess.run(
                [sys.executable, "-m", "regrasp_drake.cli", "throw",
                 "--object", "table1-row2", "--scenario-name", "Fast",
                 "--json", str(out), "--plot", str(png)],
                capture_output=True, text=True, timeout=300)
            self.assertEqual(result.returncode, 0, result.stderr)
            report = json.loads(out.read_text())
            self.assertGreater(png.stat().st_size, 10_000)
        self.assertEqual(report["watch"]["outcome"], "landed")
        points = report["catch_points"]
        self.assertGreaterEqual(len(points), 1)
        self.assertEqual(sum(p["used"] for p in points), 1)
        used = next(p for p in points if p["used"])
        self.assertLess(used["v_catch"], 0.0)  # falling
        self.assertLess(used["tilt"], load_scenario().catch.tilt_tolerance)
        self.assertTrue(any(s["reachable"] for s in used["sides"]))
        plan = report["plan"]
        self.assertEqual(plan["catch_point"]["t_s"], used["t_s"])
        self.assertEqual(len(plan["q_grasp"]), 6)
        # The palm faces up, parallel to the object's axis at the catch point
        # (its normal across the axis, its fingertips horizontal), tilted by
        # at most the tilt tolerance.
        R_WG = np.array(plan["R_WG"])
        axis = np.array(plan["catch_point"]["axis_W"])
        self.assertAlmostEqual(R_WG[:, 2] @ axis, 0.0, places=4)
        self.assertAlmostEqual(R_WG[2, 0], 0.0, places=6)
        self.assertGreaterEqual(R_WG[2, 2], np.sqrt(
            1.0 - load_scenario().catch.tilt_tolerance ** 2) - 1e-6)


if __name__ == "__main__":
    unittest.main()
