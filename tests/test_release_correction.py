"""The catching throw's correction at its own release
(throw_catch.release_correction): none when the release repeats the watched
one; under release noise, the palm moved where the plan from the release
seen puts it."""

import dataclasses as dc
import unittest
from types import SimpleNamespace
from unittest import mock

import numpy as np

from regrasp_drake import throw_catch
from regrasp_drake.episode.episode import release_time, run_episode
from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.follow import NO_FOLLOW
from regrasp_drake.planning.free_flight import flight_from_release
from regrasp_drake.station.scenario import ThrowNoise
from regrasp_drake.throw_catch import (
    ReleaseCorrection,
    plan_at_moment,
    plan_catch,
    plan_watched,
    release_correction,
    watch,
    with_release,
)
from tests.fixtures import Row2Fixture

_CELL = (0.28, -0.12)


class ReleaseCorrectionTest(Row2Fixture, unittest.TestCase):

    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        watched = cls.watched = watch(cls.scenario, cls.obj, cls.ik)
        cls.plan = plan_watched(cls.scenario, cls.obj, cls.ik, watched)
        k = int(np.argmin(np.abs(watched.logs.t - release_time(cls.scenario))))
        cls.logged_at_release = watched.logs.object_state[:, k]

    def _catch(self, scenario, record, seen=None):
        """A catching throw of `scenario` corrected at its release; `seen`
        (a list) gets the state seen then and what the correction gave."""
        hook = release_correction(scenario, self.obj, self.ik, self.plan,
                                  _CELL, record)

        def at_release(state, t):
            planned = hook(state, t)
            if seen is not None:
                seen.append((state, planned))
            return planned
        return run_episode(scenario, self.obj, ik=self.ik, X_WG=self.plan.X_WG,
                           catch_parameters=_CELL, throw_number=2,
                           at_release=at_release)

    def test_the_plan_carries_the_watched_release(self):
        np.testing.assert_array_equal(self.plan.release_state,
                                      self.logged_at_release)
        # A flight with no sample at the release time: nothing to compare.
        shifted = SimpleNamespace(logs=SimpleNamespace(
            t=np.array([0.1, 0.2]), object_state=np.zeros((13, 2))))
        bare = dc.replace(self.plan, release_state=None)
        self.assertIsNone(with_release(bare, self.scenario,
                                       shifted).release_state)

    def test_same_release_changes_nothing(self):
        record = ReleaseCorrection()
        corrected = self._catch(self.scenario, record)
        self.assertEqual(record.how, "same release")
        plain = run_episode(self.scenario, self.obj, ik=self.ik,
                            X_WG=self.plan.X_WG, catch_parameters=_CELL,
                            throw_number=2)
        self.assertEqual(corrected.outcome, plain.outcome)
        np.testing.assert_array_equal(corrected.logs.object_state,
                                      plain.logs.object_state)

    def test_noisy_release_moves_the_palm_to_the_plan_from_it(self):
        noisy = dc.replace(self.scenario, throw=dc.replace(
            self.scenario.throw, noise=ThrowNoise(0.004, 0.06, 2)))
        record, seen = ReleaseCorrection(), []
        result = self._catch(noisy, record, seen)
        self.assertEqual(record.how, "shifted")
        self.assertEqual(len(seen), 1)
        state, (X_WG, parameters, follow) = seen[0]
        self.assertEqual(tuple(parameters), _CELL)
        # The paper's catch follows nothing (planning/follow.py).
        np.testing.assert_array_equal(follow, NO_FOLLOW)
        self.assertEqual(result.h_catch, _CELL[0])
        # Where the plan made at this release from what was seen puts the
        # palm: the noise moved it by centimetres, and the correction
        # follows it to within the closed-form flight's error (< 3 mm; the
        # watched plan is off the plan from its own release by as much).
        at_release = plan_catch(noisy, self.obj, self.ik, flight_from_release(
            state, release_time(noisy), self.obj, noisy)).X_WG
        moved = at_release.translation() - self.plan.X_WG.translation()
        self.assertGreater(np.linalg.norm(moved), 0.005)
        self.assertAlmostEqual(record.shift_m, np.linalg.norm(moved),
                               delta=0.003)
        self.assertLess(np.linalg.norm(X_WG.translation()
                                       - at_release.translation()), 0.003)

    def test_a_later_moment_corrected_at_that_moment(self):
        # The plan at the flight's second catch moment: a release off the
        # watched one moves its palm to the second moment's plan from the
        # release seen, not by the first moment's difference.
        later = with_release(plan_at_moment(self.scenario, self.obj, self.ik,
                                            self.watched, 2),
                             self.scenario, self.watched)
        self.assertEqual(later.moment, 2)
        state = self.logged_at_release.copy()
        state[10] += 0.1  # 10 cm/s faster along the world's x
        t = release_time(self.scenario)
        record = ReleaseCorrection()
        with mock.patch.object(throw_catch, "plan_at_moment",
                               wraps=plan_at_moment) as planned:
            X_WG, _, _ = release_correction(self.scenario, self.obj, self.ik,
                                            later, _CELL, record)(state, t)
        # the release seen and the plan's own, both at the second moment
        self.assertEqual([c.args[4] for c in planned.call_args_list], [2, 2])
        flight = flight_from_release(state, t, self.obj, self.scenario)
        at_second = plan_at_moment(self.scenario, self.obj, self.ik, flight,
                                   2).X_WG
        self.assertEqual(record.how, "shifted")
        self.assertGreater(record.shift_m, 0.005)
        self.assertLess(np.linalg.norm(X_WG.translation()
                                       - at_second.translation()), 0.003)


class PredictedPlanCorrectionTest(Row2Fixture, unittest.TestCase):
    """A first throw's plan, from the flight predictor, is corrected at its
    release the same way: its reference is the predicted state then."""

    def test_first_throw_moves_to_the_plan_from_its_release(self):
        predictor = FlightPredictor.load(MODELS_DIR / "flight_predictor.json")
        plan = predictor.plan(self.obj, self.scenario, self.ik)
        # The predicted flight's sample at the release time: the predicted
        # state there (through free_flight.propagate's round trip).
        np.testing.assert_allclose(
            plan.release_state, predictor.predict_state(self.obj,
                                                        self.scenario),
            rtol=0, atol=1e-12)
        record, seen = ReleaseCorrection(), []
        hook = release_correction(self.scenario, self.obj, self.ik, plan,
                                  _CELL, record)

        def at_release(state, t):
            seen.append((state, hook(state, t)))
            return seen[-1][1]
        run_episode(self.scenario, self.obj, ik=self.ik, X_WG=plan.X_WG,
                    catch_parameters=_CELL, throw_number=1,
                    at_release=at_release)
        # The prediction is not the release bit for bit: the palm moves, by
        # the predictor's error (millimetres), to within the closed-form
        # flight's error (< 3 mm, as above) of the plan from the release
        # seen.
        self.assertEqual(record.how, "shifted")
        state, (X_WG, _, _) = seen[0]
        at_release_plan = plan_catch(
            self.scenario, self.obj, self.ik, flight_from_release(
                state, release_time(self.scenario), self.obj,
                self.scenario)).X_WG
        self.assertLess(record.shift_m, 0.005)
        self.assertLess(np.linalg.norm(X_WG.translation()
                                       - at_release_plan.translation()), 0.003)


if __name__ == "__main__":
    unittest.main()
