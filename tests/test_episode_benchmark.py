"""benchmarks/episode_benchmark.py: the physics it times alone is the
episode's physics, bit for bit (and benchmarks/plant_options.py's use of
it)."""

import dataclasses as dc
import unittest

from regrasp_drake.episode.episode import release_time, run_episode
from regrasp_drake.grid import plan_object
from regrasp_drake.station.scenario import load_scenario
from tests.fixtures import Row2Fixture
from tests.refusals import RefusalAssertions, load_script

episode_benchmark = load_script("benchmarks/episode_benchmark.py")
plant_options = load_script("benchmarks/plant_options.py")  # imports the above


class ReplayTest(Row2Fixture, unittest.TestCase):
    @classmethod
    def setUpClass(cls):
        super().setUpClass()
        cls.plan = plan_object(cls.scenario, cls.obj, cls.ik)
        cls.params = (cls.scenario.catch.h_catch_m, cls.scenario.catch.h_down_m)
        cls.episode = run_episode(cls.scenario, cls.obj, ik=cls.ik,
                                  X_WG=cls.plan.X_WG,
                                  catch_parameters=cls.params)
        cls.t_fork = 1.268
        segments, cls.p_WO_end = episode_benchmark.record_plant_inputs(
            cls.scenario, cls.obj, cls.ik, cls.plan.X_WG, cls.params)
        # "Fast" has one plant step throughout: one segment.
        (cls.segment,) = segments
        cls.k_fork = round(cls.t_fork / cls.scenario.plant_config.time_step)

    def test_recording_run_is_the_episode(self):
        """Stepping the episode to read the plant's inputs changes nothing:
        it ends where run_episode ends, at the same time."""
        self.assertEqual(self.episode.outcome, "caught")
        self.assertEqual(self.p_WO_end, self.episode.p_WO_final)
        steps = round(self.episode.sim_time_s / self.scenario.plant_config.time_step)
        self.assertEqual(len(self.segment.u_arm), steps + 1)

    def test_replay_ends_in_the_episodes_state(self):
        for k_start in (0, self.k_fork):
            wall, same = episode_benchmark.replayed_physics_wall_s(
                self.obj, self.segment, k_start)
            self.assertTrue(same, k_start)
            self.assertGreater(wall, 0.0)

    def test_replay_without_sampled_output_ports_is_the_same_physics(self):
        """benchmarks/plant_options.py's claim: with the plant's step a
        discrete update (no sampled output ports) the same inputs give the
        same state, bit for bit."""
        scenario = plant_options.with_plant(self.scenario,
                                            use_sampled_output_ports=False)
        _, same = episode_benchmark.replayed_physics_wall_s(
            self.obj, self.segment, self.k_fork, scenario=scenario)
        self.assertTrue(same)

    def test_replay_with_other_inputs_ends_elsewhere(self):
        """The check is not vacuous: one arm torque 1e-9 N·m off, one step
        after the fork, and the final state differs."""
        u_arm = self.segment.u_arm.copy()
        u_arm[self.k_fork + 1, 1] += 1e-9
        _, same = episode_benchmark.replayed_physics_wall_s(
            self.obj, dc.replace(self.segment, u_arm=u_arm), self.k_fork)
        self.assertFalse(same)

    def test_two_plant_steps_replay_segment_by_segment(self):
        """The throw at 0.5 ms, the catch at 1 ms (a cheap stand-in for the
        shipped 0.25 and 1 ms): two segments, split at the release time,
        each replayed bit for bit, and the recording ends where the episode
        does."""
        scenario = load_scenario(
            name="Fast", text="{plant_config: {time_step: 0.0005}, "
                              "catch_time_step_s: 0.001}")
        episode = run_episode(scenario, self.obj, ik=self.ik,
                              X_WG=self.plan.X_WG,
                              catch_parameters=self.params)
        segments, p_WO_end = episode_benchmark.record_plant_inputs(
            scenario, self.obj, self.ik, self.plan.X_WG, self.params)
        self.assertEqual(p_WO_end, episode.p_WO_final)
        self.assertEqual([s.dt for s in segments], [0.0005, 0.001])
        t_release = release_time(scenario)
        self.assertEqual(segments[0].k0, 0)
        self.assertEqual(len(segments[0].u_arm), round(t_release / 0.0005))
        self.assertEqual(segments[1].k0, round(t_release / 0.001))
        for segment in segments:
            _, same = episode_benchmark.replayed_physics_wall_s(self.obj,
                                                                segment)
            self.assertTrue(same, segment.dt)

    def test_callback_timer_counts_the_tail_and_restores(self):
        """Timed from the fork, the state machine runs once a plant step and
        the sensors once a sample; afterwards the callbacks are the
        originals again."""
        from regrasp_drake.station.catch_state_machine import CatchStateMachine
        original = CatchStateMachine._update
        with episode_benchmark.CallbackTimer() as timer:
            episode_benchmark.episode_from_wall_s(
                self.scenario, self.obj, self.ik, self.plan.X_WG,
                self.params, self.t_fork, timer)
        self.assertIs(CatchStateMachine._update, original)
        dt = self.scenario.plant_config.time_step
        period = self.scenario.sensors.period_s
        tail_s = self.episode.sim_time_s - self.t_fork
        self.assertEqual(timer.calls["catch state machine"],
                         round(tail_s / dt) + 1)
        self.assertEqual(timer.calls["infrared sensors"],
                         round(tail_s / period) + 1)
        self.assertGreater(timer.seconds["infrared sensors"], 0.0)


class BadInputTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(episode_benchmark.main)

    def test_refusals(self):
        self.assertRefused(["--runs", "0"], "--runs 0", "expected >= 1")
        self.assertRefused(["--object", "nope"], "--object nope", "expected")
        self.assertRefused(["--h-catch", "0.9"], "--h-catch", "0.9",
                           "expected")


class PlantOptionsBadInputTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(plant_options.main)

    def test_refusals(self):
        self.assertRefused(["--runs", "0"], "--runs 0", "expected >= 1")
        self.assertRefused(["--pairs", "-1"], "--pairs -1", "expected >= 1")
        self.assertRefused(["--map-objects", "nope"], "--map-objects nope",
                           "expected")


if __name__ == "__main__":
    unittest.main()
