"""benchmarks/map_noise.py: cells changed against chance, the noisy
scenario it writes, bad input."""

import unittest

import numpy as np

from tests.refusals import RefusalAssertions, load_script

sensitivity = load_script("benchmarks/map_noise.py")


def _row(caught, w_O=(0.0, 0.0, 0.0)):
    caught = np.asarray(caught, bool)
    return {"caught": caught.astype(int).tolist(),
            "cells_caught": int(caught.sum()), "release": {"w_O": list(w_O)}}


class ChangedTest(unittest.TestCase):
    def test_same_map_changes_nothing_and_complement_changes_all(self):
        a = np.zeros((10, 15), bool)
        a[:5] = True
        self.assertEqual(sensitivity.changed(a, a),
                         {"changed": 0, "chance": 75.0})
        self.assertEqual(sensitivity.changed(a, ~a)["changed"], 150)

    def test_summary_per_level_and_seed(self):
        plain = np.zeros((10, 15), bool)
        plain[:3] = True
        one = plain.copy()
        one[0, 0] = False
        maps = {"obj": {(0.0, 0): _row(plain),
                        (1e-3, 1): _row(one, (0.0, 0.3, 0.4)),
                        (1e-3, 2): _row(plain),
                        (1e-2, 1): _row(~plain)}}
        s = sensitivity.summarize(maps, [1e-3, 1e-2])["obj"]
        self.assertEqual(s["plain_cells_caught"], 45)
        self.assertEqual([r["seed"] for r in s["by_std"]["0.001"]], [1, 2])
        first = s["by_std"]["0.001"][0]
        self.assertEqual(first["changed"], 1)
        self.assertEqual(first["cells_caught"], 44)
        self.assertAlmostEqual(first["w_O_shift_rad_per_s"], 0.5)
        self.assertEqual(s["by_std"]["0.001"][1]["changed"], 0)
        self.assertEqual(s["by_std"]["0.01"][0]["changed"], 150)


class NoisyScenarioTest(unittest.TestCase):
    def test_the_named_scenario_with_only_the_noise_set(self):
        import dataclasses as dc
        import tempfile
        from pathlib import Path
        from types import SimpleNamespace

        from regrasp_drake import scenario_args
        from regrasp_drake.station.scenario import load_scenario
        args = SimpleNamespace(scenario=None, scenario_name="Fast")
        with tempfile.TemporaryDirectory() as d:
            base, label = scenario_args.load(args)
            path = sensitivity._write_scenario(
                Path(d), sensitivity.noisy(base, 0.01, 2), label)
            self.assertIn("--scenario-name Fast with release noise",
                          path.read_text().splitlines()[0])
            noisy, fast = load_scenario(path), load_scenario(name="Fast")
        self.assertEqual(noisy.throw.noise.joint_velocity_std_rad_per_s, 0.01)
        self.assertEqual(noisy.throw.noise.seed, 2)
        self.assertEqual(dc.replace(noisy, throw=dc.replace(
            noisy.throw, noise=fast.throw.noise)), fast)


class BadInputTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(sensitivity.main)

    def test_non_positive_or_out_of_range_noise_refused_naming_it(self):
        self.assertRefused(["--stds", "0"], "--stds 0: expected > 0 rad/s")
        self.assertRefused(["--stds", "50"], "--stds 50",
                           "joint_velocity_std_rad_per_s")

    def test_bad_step_refused_naming_the_flag(self):
        self.assertRefused(["--step-ms", "7"],
                           "--step-ms 7: catch_time_step_s: got 0.007")

    def test_bad_seeds_and_unknown_object_refused(self):
        self.assertRefused(["--seeds", "0"], "--seeds 0: expected >= 1")
        self.assertRefused(["--objects", "no-such-object"], "'no-such-object'")


if __name__ == "__main__":
    unittest.main()
