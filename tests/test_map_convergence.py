"""benchmarks/map_convergence.py: map agreement against chance, the named
scenario, bad input."""

import json
import unittest
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from tests.refusals import RefusalAssertions, load_script

study = load_script("benchmarks/map_convergence.py")


class AgreementTest(unittest.TestCase):
    def test_identical_maps_agree_everywhere(self):
        a = np.zeros((10, 15), bool)
        a[:4] = True
        self.assertEqual(study.agreement(a, a)["same"], 150)
        # 40 % caught: chance is 0.4² + 0.6² = 0.52 of 150 cells.
        self.assertAlmostEqual(study.agreement(a, a)["chance"], 78.0)

    def test_independent_maps_agree_about_by_chance(self):
        rng = np.random.default_rng(0)
        same, chance = [], []
        for _ in range(200):
            r = study.agreement(rng.random((10, 15)) < 0.3,
                                rng.random((10, 15)) < 0.6)
            same.append(r["same"])
            chance.append(r["chance"])
        # 0.3·0.6 + 0.7·0.4 = 0.46 of the cells, 69 of 150.
        self.assertAlmostEqual(np.mean(chance), 69.0, delta=1.5)
        self.assertAlmostEqual(np.mean(same), np.mean(chance), delta=1.5)

    def test_summary_orders_pairs_by_the_steps_given(self):
        def row(caught, w_O, t_s, x):
            return {"release": {"w_O": w_O},
                    "catch_point": {"t_s": t_s, "p_WO": [x, 0.0, 0.8]},
                    "caught": np.full((10, 15), caught, int).tolist()}
        results = {"x": {1.0: row(1, [0.0, 3.0, 4.0], 1.336, 0.90),
                         0.5: row(0, [0.0, 0.0, 0.0], 1.340, 0.88)}}
        s = study.summarize(results, [1.0, 0.5])["objects"]["x"]
        self.assertEqual(s["agreement_same"], [[150, 0], [0, 150]])
        self.assertEqual(s["agreement_chance"], [[150.0, 0.0], [0.0, 150.0]])
        self.assertEqual(list(s["by_step"]), ["1", "0.5"])
        # Shifts are from the finest step, 0.5 ms: |(0, 3, 4)| = 5 rad/s,
        # 4 ms earlier, 20 mm along x.
        self.assertEqual(s["shift_from_finest"]["1"],
                         {"w_O_rad_per_s": 5.0, "catch_t_ms": -4.0,
                          "catch_p_mm": 20.0})
        self.assertEqual(s["shift_from_finest"]["0.5"]["w_O_rad_per_s"], 0.0)

    def test_flights_without_maps_or_catch_points_have_no_agreement(self):
        results = {"x": {1.0: {"release": {"w_O": [1.0, 0.0, 0.0]},
                               "catch_point": None},
                         0.25: {"release": {"w_O": [0.0, 0.0, 0.0]},
                                "catch_point": None}}}
        s = study.summarize(results, [1.0, 0.25])["objects"]["x"]
        self.assertNotIn("agreement_same", s)
        self.assertEqual(s["shift_from_finest"]["1"], {"w_O_rad_per_s": 1.0})


class Table1ThrowsTest(unittest.TestCase):
    """The offline Table 1 count on a map: the watch, then the shipped
    network's cell, then each search's cells until one catches."""

    def setUp(self):
        from regrasp_drake.world.objects import load_catalogue
        self.obj = load_catalogue()["table1-row4"]
        # table1-row4's catch point at the shipped step, and the shipped
        # network's cell for it, from Table 1's run
        # (models/results/table1.json).
        self.plan = SimpleNamespace(catch_point=SimpleNamespace(
            v_catch=-3.555381))
        rows = json.loads((Path(__file__).parents[1] / "models" / "results"
                           / "table1.json").read_text())
        self.start = next(r["start_cell"] for r in rows
                          if r["object"] == "table1-row4")

    def test_catch_in_the_network_cell_is_two_throws(self):
        start = study.table1_throws(self.obj, self.plan,
                                    np.zeros((10, 15), bool))["network_cell"]
        self.assertEqual(start, self.start)  # as Table 1's run
        caught = np.zeros((10, 15), bool)
        caught[tuple(start)] = True
        t = study.table1_throws(self.obj, self.plan, caught)
        self.assertEqual((t["throws_wavefront"], t["throws_map_prior"]),
                         (2, 2))

    def test_far_catching_cell_and_no_catching_cell(self):
        from regrasp_drake.learning.search import wavefront_order
        caught = np.zeros((10, 15), bool)
        caught[wavefront_order(tuple(self.start))[-1]] = True  # its last
        t = study.table1_throws(self.obj, self.plan, caught)
        self.assertEqual(t["throws_wavefront"], 151)
        self.assertLessEqual(t["throws_map_prior"], 151)
        t = study.table1_throws(self.obj, self.plan, np.zeros((10, 15), bool))
        self.assertIsNone(t["throws_wavefront"])
        self.assertIsNone(t["throws_map_prior"])


class BadInputTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(study.main)

    def test_step_off_the_sensor_period_refused_naming_it(self):
        self.assertRefused(["--steps-ms", "0.3"], "--steps-ms 0.3",
                           "sensors.period_s")

    def test_step_out_of_range_and_unknown_object_refused(self):
        self.assertRefused(["--steps-ms", "7"], "catch_time_step_s: got 0.007")
        # The catch finer than the throw's 0.25 ms.
        self.assertRefused(["--steps-ms", "0.125"],
                           "--steps-ms 0.125: catch_time_step_s: got 0.000125")
        self.assertRefused(["--objects", "no-such-object"], "'no-such-object'")

    def test_bad_throw_step_refused_naming_the_flag(self):
        self.assertRefused(["--throw-step-ms", "0.3"], "--throw-step-ms 0.3")

    def test_missing_scenario_file_refused_naming_it(self):
        self.assertRefused(["--scenario", "/no/such/scenario.yaml"],
                           "--scenario: got '/no/such/scenario.yaml'")

    def test_unknown_scenario_name_refused_naming_it(self):
        self.assertRefused(["--scenario-name", "Nope"],
                           "--scenario-name: got 'Nope'")


class NamedScenarioTest(unittest.TestCase):
    def test_the_options_load_the_scenario_once_as_data(self):
        import pickle

        from regrasp_drake import scenario_args
        from regrasp_drake.station.scenario import load_scenario, scenario_yaml
        args = SimpleNamespace(scenario=None, scenario_name="Fast",
                               scenario_text="{monitor: {hold_s: 0.5}}")
        scenario, label = scenario_args.load(args)
        self.assertEqual(label, "--scenario-name Fast --scenario-text "
                                "{monitor: {hold_s: 0.5}}")
        fast = load_scenario(name="Fast", text="{monitor: {hold_s: 0.5}}")
        self.assertEqual(scenario_yaml(scenario), scenario_yaml(fast))
        # What a worker gets: the same scenario, as data.
        self.assertEqual(scenario_yaml(pickle.loads(pickle.dumps(scenario))),
                         scenario_yaml(fast))
        shipped = SimpleNamespace(scenario=None, scenario_name=None)
        scenario, label = scenario_args.load(shipped)
        self.assertEqual(label, "defaults")
        self.assertEqual(scenario_yaml(scenario), scenario_yaml(load_scenario()))


class OutDirTest(unittest.TestCase):
    def test_out_dir_refuses_another_scenario(self):
        import tempfile

        from regrasp_drake.errors import InputError
        from regrasp_drake.station.scenario import load_scenario
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "study"
            study.claim_out_dir(out)
            study.claim_out_dir(out)  # The same scenario again: resumes.
            other = load_scenario(
                text="{plant_config: {discrete_contact_approximation: sap}}")
            with self.assertRaisesRegex(InputError, r"--out .*study: holds "
                                        r"results of another scenario"):
                study.claim_out_dir(out, other)
            # Only the catch's step may differ: it is what the study varies.
            study.claim_out_dir(out, load_scenario(
                text="{catch_time_step_s: 0.0005}"))


if __name__ == "__main__":
    unittest.main()
