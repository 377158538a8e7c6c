"""The first throw's rehearsal: what it simulates, and that it predicts
the throw it rehearses when nothing differs."""

import unittest

import torch

from regrasp_drake.learning.flight_predictor import FlightPredictor
from regrasp_drake.learning.learning_phase import learn
from regrasp_drake.learning.rehearsal import (
    LATTICE,
    LATTICE_COLUMNS,
    LATTICE_ROWS,
    MODES,
    mode_scenario,
    rehearsal_scenario,
)
from regrasp_drake.paths import MODELS_DIR
from regrasp_drake.planning.grasp import Target
from regrasp_drake.planning.ik import ArmIk
from regrasp_drake.station.mlp_system import load_weights
from regrasp_drake.station.scenario import Scenario, load_scenario, with_target
from regrasp_drake.world.objects import resolve_object


class RehearsalScenarioTest(unittest.TestCase):
    def test_no_noise_and_the_shipped_steps(self):
        judged = load_scenario(text="{landing_time_step_s: 0.0000625, "
                                    "target_catch_time_step_s: 0.00025, "
                                    "throw: "
                                    "{noise: {release_time_std_s: 0.002, "
                                    "seed: 3}}}")
        rehearsed = rehearsal_scenario(judged)
        shipped = Scenario()
        self.assertTrue(rehearsed.throw.noise.is_zero())
        self.assertEqual(
            (rehearsed.catch_time_step_s, rehearsed.target_catch_time_step_s,
             rehearsed.landing_time_step_s, rehearsed.plant_config.time_step),
            (shipped.catch_time_step_s, shipped.target_catch_time_step_s,
             shipped.landing_time_step_s, shipped.plant_config.time_step))
        # The judged scenario itself is left as it was.
        self.assertEqual(judged.throw.noise.release_time_std_s, 0.002)
        self.assertEqual(len(LATTICE), len(LATTICE_ROWS) * len(LATTICE_COLUMNS))

    def test_the_modes(self):
        scenario = load_scenario()
        for mode in MODES:
            catch = mode_scenario(scenario, mode).catch
            self.assertEqual((catch.follow_pitch, catch.follow_along),
                             (mode == "pitch", mode == "along"), mode)
        with self.assertRaisesRegex(ValueError, "mode: got 'spin'"):
            mode_scenario(scenario, "spin")


class RehearsedFirstThrowTest(unittest.TestCase):
    def test_the_rehearsal_predicts_the_throw_it_rehearses(self):
        # Without noise at the shipped steps the throw is what the
        # rehearsal simulated: its cell lands in the target grasp.
        torch.set_num_threads(1)
        scenario = with_target(load_scenario(), Target("flip"))
        model = load_weights(MODELS_DIR / scenario.catch.weights)[0]
        result = learn(scenario, resolve_object(name="table1-row2"),
                       model, ik=ArmIk(), max_throws=1, progress=None,
                       flight_predictor=FlightPredictor.load(
                           MODELS_DIR / "flight_predictor.json"),
                       rehearse=True)
        rehearsal = result.rehearsal
        self.assertIsNotNone(rehearsal["cell"])
        # Every catch mode rehearsed; the lattice is the picked mode's.
        self.assertEqual(set(rehearsal["by_mode"]), set(MODES))
        self.assertEqual(rehearsal["in_target"],
                         rehearsal["by_mode"][rehearsal["mode"]])
        i, j = rehearsal["cell"]
        self.assertEqual(rehearsal["lattice"][LATTICE_ROWS.index(i)]
                         [LATTICE_COLUMNS.index(j)], 1)
        first = result.attempts[0]
        self.assertEqual((first.chosen_by, tuple(first.cell)),
                         ("rehearsal", (i, j)))
        self.assertTrue(result.success, first.grasp_error)


if __name__ == "__main__":
    unittest.main()
