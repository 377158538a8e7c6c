"""The grasp monitor: its verdict from the sensors alone, and against the
plant's contact results over a whole success map."""

import tempfile
import time
import unittest
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform
from pydrake.systems.analysis import Simulator

from regrasp_drake.grid import plan_object, run_map
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.grasp_monitor import DropReason, GraspMonitor, Outcome
from regrasp_drake.station.scenario import load_scenario
from regrasp_drake.world.robot import HAND_CLOSED, HAND_JOINTS
from tests.fixtures import Row2Fixture

_N = len(HAND_JOINTS)


class SensorVerdictTest(Row2Fixture, unittest.TestCase):
    """The monitor alone, its inputs held fixed, the hand in HOLD from t = 0:
    the verdict at t = hold_s from what the sensors read."""

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        # The monitor that reads the finger servos (not yet the default:
        # the shipped maps and tables were made without it).
        cls.scenario = load_scenario(text="{monitor: {read_fingers: true}}")

    # Readings of table1-row2 held upright off the palm's centre line
    # (studies/grasp_monitor/FINDINGS.md, cell (6, 12)): the first palm ray
    # passes beside it, the bumper is off; the thumb, index and middle
    # fingers stand 0.36-0.61 rad short of closed, the others closed.
    OFF_CENTRE_IR = [1000, 597, 361]
    SHORT_RAD = np.array([0.61, 0.0, 0.36, 0.0, 0.46, 0.0, 0.0, 0.0, 0.0, 0.0])

    def verdict(self, ir_palm, bumper, short_rad, finger_speed=0.0,
                scenario=None):
        scenario = scenario or self.scenario
        m = scenario.monitor
        monitor = GraspMonitor(scenario, 0, 1, RigidTransform(),
                               object_clearance_m=0.05, watching=False)
        context = monitor.CreateDefaultContext()
        monitor.GetInputPort("ir_levels").FixValue(
            context, list(ir_palm) + [1000] * 10)
        monitor.GetInputPort("bumper").FixValue(context, [bumper])
        goal = np.concatenate([HAND_CLOSED, np.zeros(_N)])
        monitor.GetInputPort("hand_desired_state").FixValue(context, goal)
        monitor.GetInputPort("hand_state").FixValue(context, np.concatenate(
            [HAND_CLOSED - short_rad, np.full(_N, finger_speed)]))
        monitor.GetInputPort("phase").FixValue(context, [Phase.HOLD])
        # The object rests 4 cm above the palm, far above the ground.
        monitor.GetInputPort("body_poses").FixValue(
            context, [RigidTransform([0, 0, 0.74]), RigidTransform([0, 0, 0.7])])
        simulator = Simulator(monitor, context)
        simulator.AdvanceTo(m.hold_s + 1.0)
        state = monitor.GetOutputPort("monitor_state").Eval(context)
        return GraspMonitor.outcome(state), GraspMonitor.drop_reason(state)

    def test_every_palm_ray_sees_it(self):
        self.assertEqual(self.verdict([300, 180, 60], 0, np.zeros(_N)),
                         (Outcome.CAUGHT, DropReason.NONE))

    def test_the_bumper_feels_it(self):
        self.assertEqual(self.verdict([1000] * 3, 1, np.zeros(_N)),
                         (Outcome.CAUGHT, DropReason.NONE))

    def test_off_centre_held_by_thumb_and_fingers(self):
        # Neither of the paper's two sensors reads a grasp; the fingers do.
        self.assertEqual(self.verdict(self.OFF_CENTRE_IR, 0, self.SHORT_RAD),
                         (Outcome.CAUGHT, DropReason.NONE))

    def test_paper_sensors_alone_miss_it(self):
        # monitor.read_fingers false: the monitor the shipped maps were
        # made with.
        paper = load_scenario(text="{monitor: {read_fingers: false}}")
        self.assertEqual(self.verdict(self.OFF_CENTRE_IR, 0, self.SHORT_RAD,
                                      scenario=paper),
                         (Outcome.DROPPED, DropReason.NOT_HELD))

    def test_fingers_without_the_palm_are_not_a_grasp(self):
        # Every finger stopped, but nothing within reach of a palm sensor.
        self.assertEqual(self.verdict([1000] * 3, 0, self.SHORT_RAD),
                         (Outcome.DROPPED, DropReason.NOT_HELD))

    def test_thumb_alone_is_not_a_grasp(self):
        # Row 4 lying against the wrist: only the thumb is stopped by it.
        short = np.zeros(_N)
        short[:2] = 0.3
        self.assertEqual(self.verdict(self.OFF_CENTRE_IR, 0, short),
                         (Outcome.DROPPED, DropReason.NOT_HELD))

    def test_moving_fingers_are_not_stopped(self):
        # Short of their goal but still closing: not (yet) on the object.
        self.assertEqual(
            self.verdict(self.OFF_CENTRE_IR, 0, self.SHORT_RAD,
                         finger_speed=2 * self.scenario.monitor
                         .finger_rest_rad_per_s),
            (Outcome.DROPPED, DropReason.NOT_HELD))


class ContactVerdictTest(unittest.TestCase):
    """held: the thumb and a finger facing it touch the object, which moves
    with the palm; with the palm touching too it is a power grasp."""

    def test_held_and_grasp_kind(self):
        from regrasp_drake.station.grasp_monitor import grasp_kind, held
        pinch = ["index_distal", "thumb_distal"]
        self.assertTrue(held(pinch, 0.001, 0.05))
        self.assertEqual(grasp_kind(pinch), "fingertip")
        self.assertEqual(grasp_kind(pinch + ["palm"]), "power")
        self.assertFalse(held(pinch, 0.03, 0.05))      # slipping
        self.assertFalse(held(pinch, 0.001, 0.6))      # turning
        self.assertFalse(held(["palm", "thumb_distal"], 0.0, 0.0))  # no opposing
        self.assertFalse(held(["palm", "index_distal"], 0.0, 0.0))  # no thumb


class MonitorAgainstContactsTest(Row2Fixture, unittest.TestCase):
    """table1-row2's whole success map (150 cells, the shipped scenario at
    1 ms, two workers): the monitor's verdict, caught or not, is the plant's
    contact results' verdict (`held_by_contact`: the thumb and another
    finger touching, the object at rest relative to the palm) in every
    cell but one, pinned below. Under the paper's two sensors alone 19
    cells of the finger throw's map were held yet dropped (FINDINGS.md)."""

    def test_monitor_verdict_equals_contact_verdict(self):
        start = time.perf_counter()
        plan = plan_object(self.scenario, self.obj, self.ik)
        with tempfile.TemporaryDirectory() as d:
            rows = run_map(self.scenario, self.obj, self.ik, plan,
                           Path(d) / "map.jsonl", workers=2, progress=False)
        self.assertEqual(len(rows), 150)
        disagree = {cell: (row["outcome"], row["drop_reason"],
                           row["held_by_contact"], row["touching"])
                    for cell, row in sorted(rows.items())
                    if (row["outcome"] == "caught") != row["held_by_contact"]}
        # With the 115 mm palm one cell disagrees, on the safe side: at
        # (0.12, -0.12) m the thumb and the little finger hold the object
        # against the palm at the end of the hold, and the monitor, which
        # reads the palm's infrared row, the bumper and the finger servos,
        # calls it not held. Every other cell agrees; any change fails here.
        self.assertEqual(
            disagree, {(2, 2): ("dropped", "not_held", True,
                                ["little_distal", "palm", "thumb_distal"])},
            "cells where the monitor and the contacts disagree: cell: "
            "(outcome, drop reason, held by contact, touching)")
        # Both verdicts occur: the test can fail either way.
        caught = sum(row["outcome"] == "caught" for row in rows.values())
        self.assertTrue(0 < caught < 150, caught)
        print(f"\n{type(self).__name__}: {caught} of 150 cells caught, "
              f"{time.perf_counter() - start:.0f} s", flush=True)


if __name__ == "__main__":
    unittest.main()
