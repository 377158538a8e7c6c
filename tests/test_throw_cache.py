"""The throw simulated once and gone on from (episode.ThrowCache): a watch
and two catches with other poses and parameters give, bit for bit, the
episodes simulated from the start, the catches in the watch's diagram."""

import dataclasses as dc
import unittest
from unittest import mock

import numpy as np
import torch
from pydrake.math import RigidTransform

from regrasp_drake import memo
from regrasp_drake.episode import episode, static_hold  # noqa: F401
from regrasp_drake.episode.episode import THROWS, ThrowCache, run_episode
from regrasp_drake.episode.result import Logs
from regrasp_drake.learning.learning_phase import network_features, predict
from regrasp_drake.parameter_space import cell_parameters, nearest_cell
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.catch_state_machine import ThrowPerturbation
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import ThrowNoise, load_scenario
from regrasp_drake.station.start_pose import start_poses
from regrasp_drake.throw_catch import plan_catch
from regrasp_drake.world.objects import resolve_object


class ThrowCacheTest(unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        torch.set_num_threads(1)
        cls.scenario = load_scenario()  # handed over at the release time
        cls.obj = resolve_object(name="table1-row2")
        cls.ik = ArmIk()

    def tearDown(self):
        THROWS.enabled = True
        THROWS.clear()

    def episodes(self):
        """A watch, then two catches: at the plan with one cell, and 10 mm
        off it with another."""
        watched = run_episode(self.scenario, self.obj, ik=self.ik, X_WG=None)
        X_WG = plan_catch(self.scenario, self.obj, self.ik, watched).X_WG
        moved = RigidTransform(X_WG.rotation(),
                               X_WG.translation() + [0.0, 0.01, 0.0])
        return [watched] + [
            run_episode(self.scenario, self.obj, ik=self.ik, X_WG=pose,
                        catch_parameters=cell, throw_number=2)
            for pose, cell in ((X_WG, (0.28, -0.12)),
                               (moved, (0.20, -0.05)))]

    def test_reused_throw_gives_the_same_episodes(self):
        THROWS.clear()
        THROWS.enabled = False
        fresh = self.episodes()
        THROWS.enabled = True
        hits = THROWS.hits
        with mock.patch.object(episode, "build_episode_diagram",
                               wraps=episode.build_episode_diagram) as build:
            reused = self.episodes()
        self.assertEqual(THROWS.hits - hits, 2)  # both catches
        # Two diagrams built, the watch's (the throw's step, then the
        # catch's): the catches go on in the second.
        self.assertEqual(build.call_count, 2)
        for a, b in zip(fresh, reused, strict=True):
            with self.subTest(outcome=a.outcome):
                self.assertEqual(a.outcome, b.outcome)
                self.assertEqual(a.sim_time_s, b.sim_time_s)
                self.assertEqual(a.p_WO_final, b.p_WO_final)
                self.assertEqual((a.h_catch, a.h_down), (b.h_catch, b.h_down))
                for field in dc.fields(Logs):
                    np.testing.assert_array_equal(
                        getattr(a.logs, field.name),
                        getattr(b.logs, field.name), err_msg=field.name)
        # The reused catch skipped the throw's simulation.
        self.assertLess(reused[1].wall_s, fresh[1].wall_s)

    def test_a_cache_the_caller_owns(self):
        # The caller's own cache keeps the throw; the process's stays empty.
        THROWS.clear()
        hits = THROWS.hits
        mine = ThrowCache()
        parameters = (0.28, -0.12)
        watched = run_episode(self.scenario, self.obj, ik=self.ik, X_WG=None,
                              throws=mine)
        X_WG = plan_catch(self.scenario, self.obj, self.ik, watched).X_WG
        first = run_episode(self.scenario, self.obj, ik=self.ik, X_WG=X_WG,
                            catch_parameters=parameters, throws=mine)
        self.assertEqual((mine.hits, THROWS.hits - hits, len(THROWS._kept)),
                         (1, 0, 0))
        # Every cache of the package is listed, and clearing them all makes
        # the next episode compute everything again: the same episode.
        self.assertEqual(set(memo.caches()),
                         {"start poses", "rest poses", "throws",
                          "forward tilts", "sideways tables",
                          "toss trajectories", "arm joint limits",
                          "scenario digests", "static holds"})
        # (The episodes above place the object in their own plant: the
        # memo of start poses in a world of their own is filled here.)
        start_poses(self.scenario, self.obj)
        self.assertGreater(len(memo.caches()["start poses"]), 0)
        mine.clear()
        memo.clear_all()
        self.assertEqual(len(memo.caches()["start poses"]), 0)
        self.assertEqual(
            memo.caches()["arm joint limits"].cache_info().currsize, 0)
        again = run_episode(self.scenario, self.obj, ik=self.ik, X_WG=X_WG,
                            catch_parameters=parameters, throws=mine)
        self.assertEqual(mine.hits, 1)  # simulated from the start
        self.assertEqual((first.outcome, first.p_WO_final),
                         (again.outcome, again.p_WO_final))

    def test_noisy_throws_are_their_own(self):
        noisy = dc.replace(self.scenario, throw=dc.replace(
            self.scenario.throw, noise=ThrowNoise(0.002, 0.03, 1)))

        def key(scenario, n, parameters=(0.28, -0.12), meshcat=None):
            perturbation = ThrowPerturbation.draw(scenario.throw.noise, n)
            return THROWS.key(scenario, self.obj, perturbation, parameters,
                              meshcat)
        self.assertEqual(len({key(noisy, n) for n in (1, 2)}), 2)
        self.assertEqual(len({key(self.scenario, n) for n in (1, 2)}), 1)
        # The MLP's parameters: the same throw. Not reused: Meshcat, a
        # plant without a handover.
        self.assertEqual(key(self.scenario, 1, None), key(self.scenario, 1))
        self.assertIsNone(key(self.scenario, 1, (0.2, 0.0), object()))
        self.assertIsNone(key(load_scenario(name="Fast"), 1, (0.2, 0.0)))

    def test_network_catch_goes_on_from_the_kept_throw(self):
        """A catch whose cell the MLP system in its diagram predicts, with
        the caller's network, goes on from the watch's kept throw: the same
        episode, bit for bit, as simulated from the start and as the catch
        given that cell."""
        model = load_weights(MODELS_DIR / self.scenario.catch.weights)[0]
        THROWS.clear()
        watched = run_episode(self.scenario, self.obj, ik=self.ik, X_WG=None)
        plan = plan_catch(self.scenario, self.obj, self.ik, watched)
        features = network_features(self.obj, plan.catch_point)

        def catch(**parameters):
            return run_episode(self.scenario, self.obj, ik=self.ik,
                               X_WG=plan.X_WG, throw_number=2, **parameters)
        hits = THROWS.hits
        reused = catch(mlp_features=features, model=model)
        self.assertEqual(THROWS.hits - hits, 1)
        THROWS.enabled = False
        fresh = catch(mlp_features=features, model=model)
        cell = cell_parameters(nearest_cell(*predict(model, features)[1]))
        given = catch(catch_parameters=cell)
        self.assertEqual((reused.h_catch, reused.h_down), cell)
        for other in (fresh, given):
            self.assertEqual((reused.outcome, reused.sim_time_s,
                              reused.p_WO_final),
                             (other.outcome, other.sim_time_s,
                              other.p_WO_final))
            for field in dc.fields(Logs):
                np.testing.assert_array_equal(
                    getattr(reused.logs, field.name),
                    getattr(other.logs, field.name), err_msg=field.name)


if __name__ == "__main__":
    unittest.main()
