"""The static test: the object laid at rest in a target grasp, the fingers
closed on it; a target the closed hand does not hold is refused before the
throw."""

import contextlib
import copy
import io
import unittest
from unittest import mock

import torch

from regrasp_drake import cli
from regrasp_drake.episode import static_hold
from regrasp_drake.planning.grasp import Target
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.world.objects import resolve_object


class StaticHoldTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.scenario = load_scenario()

    def test_a_held_target_and_a_dropped_one(self):
        row2 = static_hold.static_hold(
            with_target(self.scenario, Target("flip")),
            resolve_object(name="table1-row2"))
        self.assertTrue(row2.success, row2.line())
        self.assertTrue(row2.held)
        self.assertEqual(row2.closed["kind"], "flip")
        self.assertLess(abs(row2.closed["offset_mm"]), 10.0)
        self.assertIn("held at rest", row2.line())
        # Laid at -30 mm, its centre of mass near the palm's edge: the
        # closing fingers push it off the wrist end (issue 60).
        row1 = static_hold.static_hold(
            with_target(self.scenario, Target("flip", -30.0)),
            resolve_object(name="table1-row1"))
        self.assertFalse(row1.success)
        self.assertEqual(row1.reason, "dropped")
        self.assertAlmostEqual(row1.rest["offset_mm"], -30.0, delta=3.0)
        self.assertEqual(row1.tried, len(static_hold.CLOSINGS))
        self.assertIn("no closing of the hand holds it at rest", row1.line())

    def test_refused_before_the_throw(self):
        err = io.StringIO()
        with contextlib.redirect_stderr(err):
            code = cli.main(["regrasp", "--object", "table1-row1", "--target",
                             "flip", "--offset-mm", "-30", "--first-throw",
                             "--max-throws", "1", "--scenario-text",
                             "{regrasp: {check_hold: true}}"])
        self.assertEqual(code, 2)
        line = err.getvalue().strip()
        self.assertEqual(len(line.splitlines()), 1)
        self.assertIn("object table1-row1, target flip, -30 mm: no closing "
                      "of the hand holds it at rest (10 tried", line)
        self.assertIn("regrasp.check_hold", line)

    def test_tested_only_when_asked_and_never_for_any(self):
        flip = with_target(self.scenario, Target("flip", -30.0))
        asked = copy.deepcopy(flip)
        asked.regrasp.check_hold = True
        any_asked = with_target(asked, Target("any"))
        row1 = resolve_object(name="table1-row1")
        with mock.patch.object(static_hold, "static_hold") as test:
            static_hold.check_holdable(flip, row1)
            static_hold.check_holdable(any_asked, row1)
        test.assert_not_called()


if __name__ == "__main__":
    unittest.main()
