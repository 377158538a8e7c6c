"""One episode held through its stages (episode.Episode): started with a
placeholder task, at the release time, its task set there, advanced to its
outcome and read, it is the episode given that task from the start
(run_episode), bit for bit."""

import unittest

import numpy as np
from pydrake.math import RigidTransform

from regrasp_drake.episode.episode import (
    Episode,
    ThrowCache,
    release_time,
    run_episode,
)
from regrasp_drake.throw_catch import plan_watched, watch
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


if __name__ == "__main__":
    unittest.main()
