"""The palm toss (throw.kind: palm_toss): its motion, its scenario fields,
the padded palm and rounded boxes, and a watched toss."""

import unittest

import numpy as np

from regrasp_drake.episode.diagram import build_episode_diagram, initialize
from regrasp_drake.errors import InputError
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import throw
from regrasp_drake.station.palm_toss import (
    ROLL_AXIS_HEIGHT_M,
    TossDesign,
    palm_pose_at,
    toss_trajectory,
)
from regrasp_drake.station.scenario import (
    Scenario,
    load_scenario,
    validate,
    with_time_step,
)
from regrasp_drake.throw_catch import plan_catch, watch
from regrasp_drake.world.objects import load_catalogue


class TossMotionTest(unittest.TestCase):
    def setUp(self):
        self.design = TossDesign.of(Scenario().throw.toss)

    def test_velocity_is_the_derivative_and_ends_at_rest(self):
        d = self.design
        t = np.arange(0.0, d.duration_s + 0.05, 1e-4)
        z, v, phi, w = np.array([d.palm_motion(float(x)) for x in t]).T
        np.testing.assert_allclose(np.gradient(z, t)[2:-2], v[2:-2],
                                   atol=1e-3)
        np.testing.assert_allclose(np.gradient(phi, t)[2:-2], w[2:-2],
                                   atol=1e-3)
        a = np.gradient(v, t)
        # The lift's acceleration is at most 1.875 V / T_l, the brake's
        # deceleration reaches A and no more.
        self.assertLess(a.max(), 1.875 * d.launch_speed / d.lift_s * 1.01)
        self.assertAlmostEqual(-a.min(), d.brake_deceleration, delta=0.05)
        self.assertEqual((v[-1], w[-1]), (0.0, 0.0))

    def test_level_and_rolling_at_spin_when_it_brakes(self):
        d = self.design
        z, v, phi, w = d.palm_motion(d.brake_start_s)
        self.assertAlmostEqual(phi, 0.0, places=12)
        self.assertAlmostEqual(w, d.spin, places=12)
        self.assertAlmostEqual(v, d.launch_speed, places=12)
        # It rolls back before (at most 0.2 Ω T_l) and never beyond.
        phis = [d.palm_motion(t)[2] for t in np.linspace(0, d.lift_s, 200)]
        self.assertGreater(min(phis), -0.2 * d.spin * d.lift_s)

    def test_arm_follows_the_palm(self):
        ik = ArmIk()
        trajectory = toss_trajectory(self.design, ik)
        X_WP0 = ik.palm_pose(np.array(self.design.start_q))
        for t in np.linspace(0.0, self.design.duration_s, 13):
            X = ik.palm_pose(trajectory.value(t).ravel())
            X_want = palm_pose_at(self.design, X_WP0, float(t))
            self.assertLess(np.linalg.norm(
                X.translation() - X_want.translation()), 1e-3)
        # The roll turns about an axis ROLL_AXIS_HEIGHT_M above the palm:
        # a point of it only rises, and moves sideways with the
        # coordinated palm.
        p_PA = np.array([0.0, 0.0, ROLL_AXIS_HEIGHT_M])
        for t in (0.1, self.design.brake_start_s + 0.05):
            X = palm_pose_at(self.design, X_WP0, t)
            sideways = X_WP0.rotation() @ [
                0.0, self.design.sideways_offset(t), 0.0]
            np.testing.assert_allclose(
                X @ p_PA - X_WP0 @ p_PA,
                sideways + [0.0, 0.0, self.design.palm_motion(t)[0]],
                atol=1e-12)


class TossScenarioTest(unittest.TestCase):
    def test_fields_are_range_checked(self):
        for field, value in (("launch_speed_m_per_s", 9.0),
                             ("brake_deceleration_m_per_s2", 5.0),
                             ("spin_hold_s", -1.0)):
            with self.subTest(field=field):
                s = Scenario()
                setattr(s.throw.toss, field, value)
                with self.assertRaises(InputError) as e:
                    validate(s)
                self.assertIn(f"throw.toss.{field}: got", str(e.exception))
        s = Scenario()
        s.throw.kind = "catapult"
        with self.assertRaisesRegex(InputError, "throw.kind: got"):
            validate(s)

    def test_timing_of_either_throw(self):
        fingers = load_scenario(name="FingerThrow").throw
        self.assertEqual(throw.end_s(fingers), fingers.knot_times_s[-1])
        self.assertEqual(throw.release_s(fingers), fingers.release_time_s)
        toss = Scenario().throw
        d = TossDesign.of(toss.toss)
        self.assertEqual(throw.release_s(toss), d.lift_s)
        self.assertEqual(throw.end_s(toss), d.lift_s + d.spin_hold_s)
        np.testing.assert_array_equal(throw.start_q(toss),
                                      toss.toss.start_q_rad)


class ContactGeometryTest(unittest.TestCase):
    """contact.palm and contact.object_boxes pick the collision geometry."""

    def _world(self, palm, boxes):
        from pydrake.systems.framework import DiagramBuilder

        from regrasp_drake.station.plant import add_world
        s = Scenario()
        s.contact.palm, s.contact.object_boxes = palm, boxes
        plant, scene_graph, instances, body, ids = add_world(
            DiagramBuilder(), validate(s), load_catalogue()["table1-row4"])
        inspector = scene_graph.model_inspector()
        palm_body = plant.GetBodyByName("palm", instances.hand)
        names = sorted(
            inspector.GetName(g).split("::")[-1]
            for g in plant.GetCollisionGeometriesForBody(palm_body)
            if inspector.GetProximityProperties(g) is not None)
        return names, len(ids)

    def test_one_palm_kept(self):
        names, count = self._world("box", "exact")
        self.assertEqual(names, ["bumper", "palm_collision"])
        self.assertEqual(count, 2)  # table1-row4: a cylinder and a box
        names, count = self._world("pads", "rounded")
        self.assertEqual(len(names), 49)  # the base box and 6 x 8 pads
        self.assertTrue(all(n.startswith("pads_") for n in names))
        self.assertEqual(sum(n.startswith("pads_bumper_") for n in names), 8)
        self.assertEqual(count, 1 + 9)  # the box: inset box, 8 spheres

    def test_rounded_box_within_the_box(self):
        from pydrake.geometry import Box, Sphere
        box = next(p for p in load_catalogue()["table1-row4"].pieces
                   if p.shape == "box")
        shapes = box.collision_shapes(rounded=True)
        self.assertIsInstance(shapes[0][1], Box)
        half = box.size / 2
        for X, shape in shapes[1:]:
            self.assertIsInstance(shape, Sphere)
            # Each corner sphere touches the box's three faces there.
            reach = np.abs(X.translation() - box.center) + shape.radius()
            np.testing.assert_allclose(reach, half, atol=1e-12)


class WatchedTossTest(unittest.TestCase):
    """can-d100-1 tossed from the padded palm: it leaves with the palm's
    spin, and the catch is planned where its axis is exactly horizontal."""

    def test_spin_and_plan(self):
        scenario = load_scenario(name="Fast")
        ik = ArmIk()
        obj = load_catalogue()["can-d100-1"]
        watched = watch(scenario, obj, ik)
        t = scenario.throw.settle_s + throw.end_s(scenario.throw)
        k = int(np.searchsorted(watched.logs.t, t - 1e-9))
        w = watched.logs.object_state[7:10, k]
        spin = scenario.throw.toss.spin_rad_per_s
        self.assertAlmostEqual(w[0], spin, delta=0.1)  # about the palm's x
        plan = plan_catch(scenario, obj, ik, watched)
        self.assertLess(plan.catch_point.tilt, 1e-6)


class RestPoseTest(unittest.TestCase):
    """can-d250-5's centre of mass is 10 mm off its axis: laid with it over
    the palm's centre it rolled in the palm's trough at up to 13 rad/s
    through the whole toss. It now starts at its rest pose, the same
    whatever the scenario's step, and stays at rest through the settling."""

    def test_at_rest_and_the_same_at_every_step(self):
        obj = load_catalogue()["can-d250-5"]
        ik = ArmIk()
        scenario = with_time_step(load_scenario(name="Fast"), 0.001)
        episode = build_episode_diagram(scenario, obj, ik=ik, X_WG=None)
        station = episode.station
        finer = build_episode_diagram(with_time_step(scenario, 0.00025), obj,
                                      ik=ik, X_WG=None)
        np.testing.assert_array_equal(
            episode.X_WO_initial.GetAsMatrix34(),
            finer.X_WO_initial.GetAsMatrix34())
        # It rolled about its own axis (the palm's y) to put its centre of
        # mass low.
        tilt = episode.X_WO_initial.rotation().ToRollPitchYaw().pitch_angle()
        self.assertGreater(abs(tilt), 0.3)
        simulator = initialize(episode, scenario)
        plant = station.plant
        palm = plant.GetBodyByName("palm", station.hand)
        largest = 0.0
        for t in np.arange(0.02, scenario.throw.settle_s + 1e-9, 0.02):
            simulator.AdvanceTo(t)
            context = plant.GetMyContextFromRoot(simulator.get_context())
            w = (plant.EvalBodySpatialVelocityInWorld(
                     context, station.object_body).rotational()
                 - plant.EvalBodySpatialVelocityInWorld(
                     context, palm).rotational())
            largest = max(largest, np.linalg.norm(w))
        self.assertLess(largest, 0.05)


class CoordinatedPalmTest(unittest.TestCase):
    """The coordinated palm (throw.toss.coordinated): gravity and the palm's
    acceleration press along its normal through the lift, its sideways
    motion is at rest again when it brakes, and table1-row4, which tipped
    on its box head in the lift (2.1 rad/s relative to the palm), stays
    put."""

    def test_effective_gravity_along_the_normal(self):
        toss = load_scenario(name="Fast").throw.toss
        self.assertTrue(toss.coordinated)
        design = TossDesign.of(toss)
        self.assertGreater(design.forward_tilt, 1.0)
        t, y, v_y = design.sideways()
        self.assertLess(abs(v_y[-1]), 1e-6)
        ik = ArmIk()
        X_WP0 = ik.palm_pose(np.array(design.start_q))
        h = 1e-4
        for time_s in np.linspace(0.05, design.lift_s - 0.05, 9):
            # The roll axis's point (where an object's centre of mass
            # about is): its acceleration and gravity, along the normal.
            p = [palm_pose_at(design, X_WP0, time_s + k * h)
                 @ np.array([0.0, 0.0, ROLL_AXIS_HEIGHT_M]) for k in (-1, 0, 1)]
            a = (p[0] - 2 * p[1] + p[2]) / h**2
            pressed = a + [0.0, 0.0, 9.81]
            normal = palm_pose_at(design, X_WP0, time_s).rotation().col(2)
            angle = np.arccos(np.dot(pressed, normal) / np.linalg.norm(pressed))
            self.assertLess(angle, 0.005, time_s)

    def test_a_narrow_based_object_does_not_tip(self):
        obj = load_catalogue()["table1-row4"]
        ik = ArmIk()
        largest = {}
        for coordinated in (False, True):
            text = "{throw: {toss: {coordinated: %s}}}" % str(coordinated).lower()
            scenario = with_time_step(load_scenario(name="Fast", text=text), 0.001)
            episode = build_episode_diagram(scenario, obj, ik=ik, X_WG=None)
            simulator = initialize(episode, scenario)
            plant = episode.station.plant
            palm = plant.GetBodyByName("palm", episode.station.hand)
            end = scenario.throw.settle_s + throw.release_s(scenario.throw)
            largest[coordinated] = 0.0
            for t in np.arange(0.01, end + 1e-9, 0.005):
                simulator.AdvanceTo(t)
                context = plant.GetMyContextFromRoot(simulator.get_context())
                w = (plant.EvalBodySpatialVelocityInWorld(
                         context, episode.station.object_body).rotational()
                     - plant.EvalBodySpatialVelocityInWorld(
                         context, palm).rotational())
                largest[coordinated] = max(largest[coordinated],
                                           np.linalg.norm(w))
        self.assertGreater(largest[False], 1.0)
        self.assertLess(largest[True], 0.05)


if __name__ == "__main__":
    unittest.main()
