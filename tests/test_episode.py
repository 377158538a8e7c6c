"""One episode held through its stages (episode.Episode): started with a
placeholder task, at the release time, its task set there, advanced to its
outcome and read, it is the episode given that task from the start
(run_episode), bit for bit."""

import unittest
from unittest import mock

import numpy as np
import torch
from pydrake.math import RigidTransform
from pydrake.systems.framework import LeafSystem
from pydrake.systems.primitives import LogVectorOutput

from regrasp_drake.episode import diagram
from regrasp_drake.episode.episode import (
    Episode,
    ThrowCache,
    release_time,
    run_episode,
)
from regrasp_drake.planning.grasp import Target
from regrasp_drake.station.scenario import load_scenario, with_target
from regrasp_drake.throw_catch import catch_once, plan_watched, watch
from regrasp_drake.world.objects import resolve_object
from tests.fixtures import Row2Fixture

_CELL = (0.28, -0.12)  # (h_catch, h_down), [m]


class EpisodeTest(Row2Fixture, unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        watched = watch(cls.scenario, cls.obj, cls.ik)
        cls.plan = plan_watched(cls.scenario, cls.obj, cls.ik, watched)

    def test_the_task_set_at_the_release_is_the_one_run(self):
        # No kept throw: this episode simulates its own from the start.
        episode = Episode(self.scenario, self.obj, ik=self.ik,
                          X_WG=RigidTransform(), catch_parameters=(0.0, 0.0),
                          throws=ThrowCache(size=0))
        episode.start()
        self.assertTrue(episode.running)
        release = episode.advance_to_release()
        self.assertEqual(release.t, release_time(self.scenario))
        self.assertEqual(release.object_state.shape, (13,))
        self.assertEqual(episode.outcome(), "running")
        episode.set_task(X_WG=self.plan.X_WG, catch_parameters=_CELL)
        self.assertEqual(episode.advance_to_outcome(), "")
        held = episode.result()
        whole = run_episode(self.scenario, self.obj, ik=self.ik,
                            X_WG=self.plan.X_WG, catch_parameters=_CELL)
        self.assertEqual(held.outcome, whole.outcome)
        self.assertEqual(held.sim_time_s, whole.sim_time_s)
        self.assertEqual(held.p_WO_final, whole.p_WO_final)
        self.assertEqual((held.h_catch, held.h_down), _CELL)
        np.testing.assert_array_equal(held.logs.object_state,
                                      whole.logs.object_state)
        np.testing.assert_array_equal(held.logs.arm_state,
                                      whole.logs.arm_state)


class _RaisingSystem(LeafSystem):
    """A system whose output raises `error` once the time passes 10 ms."""

    def __init__(self, error: Exception):
        super().__init__()
        self.error = error
        self.DeclareVectorOutputPort("y", 1, self._calc)

    def _calc(self, context, output):
        if context.get_time() > 0.01:
            raise self.error
        output.SetAtIndex(0, 0.0)


class ExceptionsTest(Row2Fixture, unittest.TestCase):
    """Only Drake's contact solver failing is an outcome ("failed"); any
    other exception in an episode's diagram propagates."""

    def run_with(self, error: Exception):
        """A watching throw whose diagram also holds a _RaisingSystem of
        `error`, logged at the sensors' rate (so evaluated)."""
        add_loggers = diagram.add_loggers

        def with_raising_system(builder, station, controller, period_s):
            system = builder.AddSystem(_RaisingSystem(error))
            LogVectorOutput(system.get_output_port(), builder, period_s)
            return add_loggers(builder, station, controller, period_s)

        with mock.patch.object(diagram, "add_loggers", with_raising_system):
            return run_episode(self.scenario, self.obj, ik=self.ik,
                               X_WG=None, throws=ThrowCache(size=0))

    def test_a_failing_system_raises(self):
        with self.assertRaisesRegex(ZeroDivisionError, "a bug of ours"):
            self.run_with(ZeroDivisionError("a bug of ours"))
        with self.assertRaisesRegex(RuntimeError, "a bad port"):
            self.run_with(RuntimeError("a bad port"))

    def test_the_contact_solver_failing_is_the_outcome_failed(self):
        result = self.run_with(RuntimeError(
            "The SAP solver failed to converge at simulation time = 0.011. "
            "Reasons for divergence and possible solutions include:\n"
            "  1. Externally applied actuation values diverged"))
        self.assertEqual(result.outcome, "failed")
        self.assertEqual(result.message, "The SAP solver failed to converge "
                         "at simulation time = 0.011. Reasons for divergence "
                         "and possible solutions include:")
        self.assertLess(result.sim_time_s, 0.05)



class LandingStepTest(unittest.TestCase):
    """A target catch lands in the same grasp at the shipped steps (0.125 ms
    through the landing, 0.5 ms around it) and at half of both (0.0625 and
    0.25 ms): one pair per throw kind, a spinning flip and a keep."""

    def test_the_same_grasp_at_half_the_step(self):
        torch.set_num_threads(1)
        half = ("{landing_time_step_s: 0.0000625, "
                "target_catch_time_step_s: 0.00025}")
        for name, target in (("table1-row2", Target("flip")),
                             ("table1-row4", Target("keep"))):
            obj = resolve_object(name=name)
            results = [catch_once(with_target(load_scenario(text=text),
                                              target), obj,
                                  h_catch=0.32, h_down=-0.07)[0]
                       for text in (None, half)]
            for result in results:
                self.assertTrue(result.success, (name, result.grasp_error))
            shipped, finer = (r.achieved_grasp for r in results)
            self.assertLess(abs(shipped["offset_mm"] - finer["offset_mm"]),
                            1.0, name)
            self.assertLess(abs(shipped["tilt_deg"] - finer["tilt_deg"]),
                            1.0, name)


if __name__ == "__main__":
    unittest.main()
