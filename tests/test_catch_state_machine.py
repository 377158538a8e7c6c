"""The catch state machine's catch-tolerance fields: the cushioned return
(catch.return_from_motion), the distal joints' pre-shape
(catch.preshape_distal_closure) and the lowering that ends moving
(catch.lower_ends_moving)."""

import unittest

import numpy as np

from regrasp_drake.errors import InputError
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station import catch_state_machine as csm
from regrasp_drake.station.scenario import Scenario, load_scenario, validate
from regrasp_drake.world import robot


class CatchFieldsTest(unittest.TestCase):
    def test_refused_in_one_line_naming_the_field(self):
        for text, expected in (
                ("{catch: {preshape_distal_closure: 0.9}}",
                 "catch.preshape_distal_closure: got 0.9, expected a number "
                 "in [0.0, 0.8]"),
                ("{catch: {preshape_distal_closure: x}}",
                 "catch.preshape_distal_closure: got 'x', expected a number"),
                ("{catch: {return_from_motion: 2}}",
                 "catch.return_from_motion: got 2, expected true or false"),
                ("{catch: {closing_order: thumb}}",
                 "catch.closing_order: got 'thumb', expected one of "
                 "['together', 'thumb_first', 'fingers_first']")):
            with self.subTest(text=text):
                with self.assertRaises(InputError) as e:
                    load_scenario(text=text)
                self.assertIn(expected, str(e.exception))
                self.assertEqual(len(str(e.exception).splitlines()), 1)

    def test_default_cushions_and_the_finger_throw_keeps_the_papers(self):
        s = validate(Scenario())
        self.assertTrue(s.catch.return_from_motion)
        self.assertFalse(
            load_scenario(name="FingerThrow").catch.return_from_motion)
        self.assertIsNone(s.catch.preshape_distal_closure)
        np.testing.assert_array_equal(csm.preshape_closures(s.catch),
                                      np.full(10, s.catch.preshape_closure))

    def test_distal_joints_preshape_on_their_own(self):
        s = load_scenario(text="{catch: {preshape_closure: 0.5, "
                               "preshape_distal_closure: 0.2}}")
        closures = csm.preshape_closures(s.catch)
        for i, joint in enumerate(robot.HAND_JOINTS):
            self.assertEqual(closures[i], 0.2 if joint.endswith("_j2") else 0.5,
                             joint)


class ClosingOrderTest(unittest.TestCase):
    """catch.closing_order: from the cage the palm toss pre-shapes, the
    joints that wait start as the others arrive, each at full speed;
    "together" is the ramp without delays."""

    def _ramps(self, order):
        s = load_scenario(text=f"{{catch: {{closing_order: {order}}}}}")
        machine = csm.CatchStateMachine(
            s, ArmIk(), robot.HAND_OPEN, robot.HAND_CLOSED,
            robot.FINGER_MAX_SPEED, park_q=np.zeros(6))
        self.cage = csm.preshape_posture(s.catch, robot.HAND_OPEN,
                                         robot.HAND_CLOSED)
        return machine._preshape_to_closed

    def test_the_thumb_first_then_the_fingers(self):
        together, thumb_first, fingers_first = (
            self._ramps(o) for o in ("together", "thumb_first",
                                     "fingers_first"))
        self.assertIsNone(together.delay)
        thumb = np.array([j.startswith("thumb_") for j in robot.HAND_JOINTS])
        t_thumb = together.duration  # every joint travels as far
        self.assertAlmostEqual(thumb_first.duration, 2 * t_thumb)
        half = 0.5 * t_thumb
        for ramp, moving in ((together, np.ones(10, bool)),
                             (thumb_first, thumb), (fingers_first, ~thumb)):
            q, v = ramp.at(half)
            np.testing.assert_array_equal(v != 0.0, moving)
            np.testing.assert_allclose(q[moving], together.at(half)[0][moving])
            np.testing.assert_array_equal(q[~moving], self.cage[~moving])
        # The others start as the first arrive; all closed at the end.
        q, v = thumb_first.at(t_thumb + half)
        np.testing.assert_allclose(q[~thumb], together.at(half)[0][~thumb])
        np.testing.assert_array_equal(q[thumb], robot.HAND_CLOSED[thumb])
        q, v = fingers_first.at(2 * t_thumb)
        np.testing.assert_array_equal(q, robot.HAND_CLOSED)
        np.testing.assert_array_equal(v, np.zeros(10))


class CushionedReturnTest(unittest.TestCase):
    """Where the lowering stops (the object seen on the palm), the return
    starts from the arm's moving reference with return_from_motion, from
    rest without it."""

    @classmethod
    def setUpClass(cls):
        cls.ik = ArmIk()

    def _return_reference(self, cushion: bool, tau: float):
        s = load_scenario(
            text="{throw: {kind: palm_toss}, catch: {return_from_motion: "
                 f"{'true' if cushion else 'false'}}}}}")
        q_grasp = np.array(s.throw.toss.start_q_rad)
        machine = csm.CatchStateMachine(
            s, self.ik, robot.HAND_OPEN, robot.HAND_CLOSED,
            robot.FINGER_MAX_SPEED, park_q=q_grasp)
        q_low = q_grasp + [0.0, -0.05, 0.08, 0.0, -0.03, 0.0]
        x = np.zeros(csm._SIZE)
        x[csm._QGRASP] = q_grasp
        csm.CatchStateMachine._start_segment(x, 1.0, q_grasp, q_low, 0.1,
                                             csm.Phase.LOWER)
        t_stop = 1.04  # the palm sensor sees the object mid-lowering
        q, v, a = machine._arm_reference(x, t_stop)
        csm.CatchStateMachine._start_segment(x, t_stop, q, q_grasp,
                                             s.catch.return_s, csm.Phase.RETURN)
        if cushion:
            x[csm._V0], x[csm._A0] = v, a
        return v, machine._arm_reference(
            x, t_stop + tau * s.catch.return_s)

    def test_the_hand_turns_back_without_stopping(self):
        v_stop, (_, v0, _) = self._return_reference(True, 0.0)
        self.assertGreater(np.linalg.norm(v_stop), 0.5)
        np.testing.assert_allclose(v0, v_stop, atol=1e-12)
        _, (_, v0_paper, _) = self._return_reference(False, 0.0)
        np.testing.assert_array_equal(v0_paper, np.zeros(6))

    def test_the_cushioned_return_ends_at_rest_at_the_grasp_pose(self):
        _, (q1, v1, a1) = self._return_reference(True, 1.0)
        s = Scenario()
        np.testing.assert_allclose(q1, s.throw.toss.start_q_rad, atol=1e-12)
        np.testing.assert_array_equal(v1, np.zeros(6))
        np.testing.assert_array_equal(a1, np.zeros(6))


class LoweringThatEndsMovingTest(unittest.TestCase):
    """catch.lower_ends_moving: under a grasp target the lowering ends
    moving down at twice its mean speed and goes on so; under "any" (the
    paper's catch) it ends at rest."""

    @classmethod
    def setUpClass(cls):
        cls.ik = ArmIk()

    def _lowering(self, text: str, times):
        s = load_scenario(text=text)
        q_grasp = np.array(s.throw.toss.start_q_rad)
        machine = csm.CatchStateMachine(
            s, self.ik, robot.HAND_OPEN, robot.HAND_CLOSED,
            robot.FINGER_MAX_SPEED, park_q=q_grasp)
        dq = np.array([0.0, -0.05, 0.08, 0.0, -0.03, 0.0])
        x = np.zeros(csm._SIZE)
        csm.CatchStateMachine._start_segment(x, 1.0, q_grasp, q_grasp + dq,
                                             0.1, csm.Phase.LOWER)
        return dq, [machine._arm_reference(x, t) for t in times], s

    def test_under_a_target_it_ends_moving(self):
        dq, refs, s = self._lowering(
            "{regrasp: {target: flip}}", (1.0, 1.05, 1.1, 1.12))
        self.assertTrue(csm.lowers_moving(s))
        (q0, v0, _), (_, v_mid, _), (q1, v1, a1), (q2, v2, _) = refs
        np.testing.assert_array_equal(v0, np.zeros(6))
        # s(τ) = 2τ³ - τ⁴: at τ = 1/2, s' = 1; at τ = 1, s' = 2, s'' = 0.
        np.testing.assert_allclose(v_mid, dq / 0.1, atol=1e-9)
        np.testing.assert_allclose(q1, q0 + dq, atol=1e-12)
        np.testing.assert_allclose(v1, 2.0 * dq / 0.1, atol=1e-9)
        np.testing.assert_allclose(a1, np.zeros(6), atol=1e-9)
        # Past its end it goes on at that speed until the return.
        np.testing.assert_allclose(q2, q1 + 0.02 * v1, atol=1e-12)
        np.testing.assert_allclose(v2, v1, atol=1e-12)

    def test_under_any_it_ends_at_rest(self):
        _, refs, s = self._lowering("{regrasp: {target: any}}", (1.1,))
        self.assertFalse(csm.lowers_moving(s))
        np.testing.assert_array_equal(refs[0][1], np.zeros(6))

    def test_needs_the_cushioned_return(self):
        with self.assertRaises(InputError) as e:
            load_scenario(text="{catch: {lower_ends_moving: true, "
                               "return_from_motion: false}}")
        self.assertIn("catch.lower_ends_moving", str(e.exception))
        self.assertFalse(csm.lowers_moving(load_scenario(
            text="{regrasp: {target: flip}, catch: {return_from_motion: "
                 "false}}")))


if __name__ == "__main__":
    unittest.main()
