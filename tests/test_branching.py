"""Forked cells give the same episodes as whole runs."""

import copy
import dataclasses as dc
import unittest
from unittest import mock

import numpy as np
import torch

from regrasp_drake.episode.branching import CellError, _Children, run_cells
from regrasp_drake.episode.episode import Episode, release_time, run_episode
from regrasp_drake.episode.result import read_ending
from regrasp_drake.errors import InputError
from regrasp_drake.grid import plan_object
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import Phase
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.world.objects import resolve_object
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
            self.assertEqual((row.h_catch, row.h_down), (h_catch, h_down))
            # One result type: every field the whole episode's, bit for bit
            # (the object's final position too), but its logs and times.
            timings = dict(logs=None, wall_s=None, build_s=0.0)
            self.assertEqual(dc.replace(row, **timings),
                             dc.replace(whole, **timings))
            if row.outcome == "caught":
                self.assertIsNone(row.drop_reason)
                self.assertIn("palm", row.touching)
                self.assertTrue(any(b.endswith("_distal")
                                    for b in row.touching), row)
            else:
                self.assertIn(row.drop_reason,
                              ("near_ground", "below_palm", "not_held"))
            outcomes.add(row.outcome)
        self.assertEqual(outcomes, {"caught", "dropped"})

    def test_handover_to_the_same_step_changes_nothing(self):
        # Handing the episode over at the release time to a station built
        # alike goes on bit for bit: the whole episode, its logs included.
        parameters = (0.20, -0.09)
        plain = run_episode(self.scenario, self.obj, ik=self.ik,
                            X_WG=self.plan.X_WG, catch_parameters=parameters)
        same = copy.deepcopy(self.scenario)
        with mock.patch("regrasp_drake.episode.episode.catch_phase_scenario",
                        return_value=same):
            handed = run_episode(self.scenario, self.obj, ik=self.ik,
                                 X_WG=self.plan.X_WG,
                                 catch_parameters=parameters)
        self.assertEqual((plain.outcome, plain.sim_time_s, plain.catch_time_s),
                         (handed.outcome, handed.sim_time_s,
                          handed.catch_time_s))
        np.testing.assert_array_equal(plain.p_WO_final, handed.p_WO_final)
        for field in dc.fields(plain.logs):
            np.testing.assert_array_equal(getattr(plain.logs, field.name),
                                          getattr(handed.logs, field.name),
                                          err_msg=field.name)


class HandoverTest(unittest.TestCase):
    """The throw at 0.5 ms, the catch at 1 ms (a cheaper stand-in for the
    shipped 0.25 and 1 ms): forked cells still equal whole episodes, and
    the logs run on across the handover."""

    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.scenario = load_scenario(
            name="Fast", text="{plant_config: {time_step: 0.0005}, "
                              "catch_time_step_s: 0.001}")
        cls.obj = resolve_object(name="table1-row2")
        cls.ik = ArmIk()
        cls.plan = plan_object(cls.scenario, cls.obj, cls.ik)

    def test_forked_cells_equal_whole_episodes(self):
        parameters = [(0.40, -0.05), (0.08, -0.13)]
        rows = run_cells(self.scenario, self.obj, ik=self.ik,
                         X_WG=self.plan.X_WG, parameters=parameters,
                         workers=2)
        for (h_catch, h_down), row in zip(parameters, rows):
            whole = run_episode(self.scenario, self.obj, ik=self.ik,
                                X_WG=self.plan.X_WG,
                                catch_parameters=(h_catch, h_down))
            self.assertEqual((row.outcome, row.sim_time_s, row.catch_time_s),
                             (whole.outcome, whole.sim_time_s,
                              whole.catch_time_s))
            np.testing.assert_array_equal(row.p_WO_final, whole.p_WO_final)
            # One log sample per sensor period, across the handover too.
            steps = np.diff(whole.logs.t)
            np.testing.assert_allclose(
                steps, self.scenario.sensors.period_s, atol=1e-9)
            t_release = release_time(self.scenario)
            self.assertTrue(whole.logs.t[0] < t_release < whole.logs.t[-1])

    def test_catch_step_finer_than_the_throws_refused(self):
        with self.assertRaisesRegex(InputError, "catch_time_step_s"):
            load_scenario(name="Fast", text="{catch_time_step_s: 0.0005}")
        with self.assertRaisesRegex(InputError, "catch_time_step_s"):
            load_scenario(name="Fast", text="{catch_time_step_s: 0.0015}")
        # A continuous plant (CENIC) has no step to change.
        with self.assertRaisesRegex(InputError,
                                    "catch_time_step_s: got 0.001, expected "
                                    "null with a continuous plant"):
            load_scenario(text="{plant_config: {time_step: 0}, "
                               "simulator_config: {integration_scheme: "
                               "cenic}}")


class LandingHandoverTest(unittest.TestCase):
    """Under a grasp target the catch goes on at the landing's step before
    the landing (1 ms, then 0.5 ms: a cheaper stand-in for the shipped 1
    and 0.25 ms), and back at the catch's step after it: forked cells
    still equal whole episodes, the handovers come before any cell
    triggers, and the logs run on across them."""

    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.obj = resolve_object(name="table1-row2")
        cls.ik = ArmIk()
        cls.scenario = with_target(load_scenario(
            name="Fast", text="{landing_time_step_s: 0.0005}"),
            Target("flip"))
        cls.plan = plan_object(cls.scenario, cls.obj, cls.ik)

    def check_cells(self, scenario):
        parameters = [(0.40, -0.05), (0.08, -0.13)]
        rows = run_cells(scenario, self.obj, ik=self.ik, X_WG=self.plan.X_WG,
                         parameters=parameters, workers=2)
        for (h_catch, h_down), row in zip(parameters, rows):
            episode = Episode(scenario, self.obj, ik=self.ik,
                              X_WG=self.plan.X_WG,
                              catch_parameters=(h_catch, h_down))
            whole = episode.run()
            t_landing = episode.landing_at
            self.assertEqual((row.outcome, row.sim_time_s, row.catch_time_s),
                             (whole.outcome, whole.sim_time_s,
                              whole.catch_time_s))
            np.testing.assert_array_equal(row.p_WO_final, whole.p_WO_final)
            # Handed over at the landing: at a sensor sample, before the
            # hand lowers (before the highest h_catch triggers it).
            self.assertEqual(episode.scenario.plant_config.time_step,
                             scenario.plant_config.time_step
                             if scenario.landing_settle_s is not None
                             else 0.0005)
            i = np.searchsorted(whole.logs.t, t_landing)
            self.assertAlmostEqual(whole.logs.t[i], t_landing)
            self.assertLess(whole.logs.phase[i], Phase.LOWER)
            self.assertGreater(np.flatnonzero(
                whole.logs.phase == Phase.LOWER)[0], i)
            np.testing.assert_allclose(np.diff(whole.logs.t),
                                       scenario.sensors.period_s, atol=1e-9)
        return rows

    def test_forked_cells_equal_whole_episodes(self):
        self.check_cells(self.scenario)

    def test_handed_back_after_the_landing(self):
        settled = copy.deepcopy(self.scenario)
        settled.landing_settle_s = 0.1
        self.check_cells(settled)

    def test_any_catch_is_not_handed_over(self):
        any_catch = with_target(self.scenario, Target("any"))
        episode = Episode(any_catch, self.obj, ik=self.ik,
                          X_WG=self.plan.X_WG, catch_parameters=(0.2, -0.05))
        episode.run()
        self.assertIsNone(episode.landing_at)
        self.assertEqual(episode.scenario.plant_config.time_step, 0.001)


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

    def test_contacts_failing_after_another_ending_raise(self):
        # Only after a failed episode is a failing contact solve expected.
        episode = mock.Mock()
        episode.station.plant.get_contact_results_output_port.return_value \
            .Eval.side_effect = RuntimeError("a bad port")
        with self.assertRaisesRegex(RuntimeError, "a bad port"):
            read_ending(episode, mock.Mock(), "caught")


class ChildrenTest(unittest.TestCase):
    def test_an_exception_in_a_forked_cell_is_raised_in_the_parent(self):
        # Not recorded as "the simulation process died" (an outcome): the
        # parent raises it, with the child's traceback.
        def run():
            raise ZeroDivisionError("a bug of ours")

        children = _Children(1, report=mock.Mock(), died=mock.Mock())
        children.start([0], run)
        with self.assertRaisesRegex(CellError,
                                    "ZeroDivisionError: a bug of ours"):
            children.finish_all()
        children.kill_all()


if __name__ == "__main__":
    unittest.main()
