"""Forked cells give the same episodes as whole runs."""

import unittest
from unittest import mock

import numpy as np

from regrasp_drake.grid import plan_object
from regrasp_drake.station.branching import run_cells
from regrasp_drake.station.episode import read_ending, run_episode
from tests.fixtures import Row2Fixture


class RunCellsTest(Row2Fixture, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.plan = plan_object(cls.scenario, cls.obj, cls.ik)
        # Rows that trigger at different times, and a catch and drops.
        # (0.40 and 0.36 trigger at the same sample: one shared simulation.)
        cls.parameters = [(0.40, -0.05), (0.20, -0.09), (0.08, -0.13),
                          (0.20, 0.0), (0.36, -0.05)]
        cls.finished = []
        cls.rows = run_cells(cls.scenario, cls.obj, ik=cls.ik,
                             X_WG=cls.plan.X_WG, parameters=cls.parameters,
                             workers=2,
                             on_result=lambda i, row: cls.finished.append(i))

    def test_forked_cells_equal_whole_episodes(self):
        self.assertEqual(sorted(self.finished), [0, 1, 2, 3, 4])
        outcomes = set()
        for (h_catch, h_down), row in zip(self.parameters, self.rows):
            whole = run_episode(self.scenario, self.obj, ik=self.ik,
                                X_WG=self.plan.X_WG,
                                catch_parameters=(h_catch, h_down))
            self.assertEqual((row["h_catch"], row["h_down"]), (h_catch, h_down))
            self.assertEqual(row["outcome"], whole.outcome)
            self.assertEqual(row["sim_time_s"], round(whole.sim_time_s, 4))
            self.assertEqual(row["catch_time_s"], whole.catch_time_s)
            # Bit for bit: the object ends at exactly the same position.
            np.testing.assert_array_equal(row["p_WO_final"], whole.p_WO_final)
            # How it ended: the monitor's drop reason and the final contacts.
            self.assertEqual((row["drop_reason"], row["touching"]),
                             (whole.drop_reason, whole.touching))
            if row["outcome"] == "caught":
                self.assertIsNone(row["drop_reason"])
                self.assertIn("palm", row["touching"])
                self.assertTrue(any(b.endswith("_distal")
                                    for b in row["touching"]), row)
            else:
                self.assertIn(row["drop_reason"],
                              ("near_ground", "below_palm", "not_held"))
            outcomes.add(row["outcome"])
        self.assertEqual(outcomes, {"caught", "dropped"})

    def test_handoff_to_the_same_scenario_changes_nothing(self):
        # Handing the simulation over to a station built alike, when the
        # throw ends, goes on bit for bit.
        parameters = [(0.40, -0.05), (0.08, -0.13), (0.20, 0.0)]
        t_end = (self.scenario.throw.settle_s
                 + self.scenario.throw.knot_times_s[-1])
        # Without the handoff: the rows of setUpClass's run.
        plain = [self.rows[self.parameters.index(p)] for p in parameters]
        handed = run_cells(self.scenario, self.obj, ik=self.ik,
                           X_WG=self.plan.X_WG, parameters=parameters,
                           handoff=(t_end, self.scenario), workers=2)
        for a, b in zip(plain, handed):
            self.assertEqual((a["outcome"], a["sim_time_s"], a["catch_time_s"]),
                             (b["outcome"], b["sim_time_s"], b["catch_time_s"]))
            np.testing.assert_array_equal(a["p_WO_final"], b["p_WO_final"])

    def test_handoff_after_the_hand_waits_refused(self):
        with self.assertRaisesRegex(ValueError, "already waits"):
            run_cells(self.scenario, self.obj, ik=self.ik,
                      X_WG=self.plan.X_WG, parameters=[(0.2, -0.05)],
                      handoff=(1.3, self.scenario))


class ReadEndingTest(unittest.TestCase):
    def test_contacts_that_cannot_be_computed_read_none(self):
        # After a failed contact solve, evaluating the contact results
        # fails again: the ending has no contacts instead of raising.
        episode = mock.Mock()
        episode.station.plant.get_contact_results_output_port.return_value \
            .Eval.side_effect = RuntimeError("contact solver failed")
        self.assertEqual(read_ending(episode, mock.Mock(), "failed"),
                         {"drop_reason": None, "touching": None,
                          "held_by_contact": None, "slip_m_per_s": None,
                          "spin_rad_per_s": None})


if __name__ == "__main__":
    unittest.main()
