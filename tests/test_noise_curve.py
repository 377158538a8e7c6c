"""benchmarks/noise_curve.py: its catch-rate intervals, its refusals,
and one noiseless trial per mode from the shipped libraries."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

from tests.refusals import RefusalAssertions, load_script

noise_curve = load_script("benchmarks/noise_curve.py")


class WilsonIntervalTest(unittest.TestCase):
    def test_known_values(self):
        # 95 % Wilson intervals of 0/12, 12/12 and 6/12 (z = 1.96).
        low, high = noise_curve.wilson_interval(0, 12)
        self.assertEqual(low, 0.0)
        self.assertAlmostEqual(high, 0.2425, places=4)
        low, high = noise_curve.wilson_interval(12, 12)
        self.assertAlmostEqual(low, 0.7575, places=4)
        self.assertEqual(high, 1.0)
        low, high = noise_curve.wilson_interval(6, 12)
        self.assertAlmostEqual(low + high, 1.0, places=12)
        self.assertAlmostEqual(low, 0.2538, places=4)
        self.assertIsNone(noise_curve.wilson_interval(0, 0))

    def test_more_trials_narrow_it(self):
        few = noise_curve.wilson_interval(3, 6)
        many = noise_curve.wilson_interval(30, 60)
        self.assertLess(many[1] - many[0], few[1] - few[0])


class NoiseCurveTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(noise_curve.main)

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.out = Path(self.tmp.name) / "curve"

    def tearDown(self):
        self.tmp.cleanup()

    def test_bad_arguments_refused(self):
        out = ["--out", str(self.out)]
        self.assertRefused(["--trials", "0", *out], "--trials", "got 0")
        self.assertRefused(["--levels", "0", "-1", *out], "--levels", "got -1")
        self.assertRefused(["--workers", "0", *out], "--workers", "got 0")
        self.assertRefused(["--library", "/nonexistent.yaml", *out],
                           "--library", "/nonexistent.yaml")
        self.assertRefused(["--scenario-name", "Nope", *out],
                           "--scenario-name: got 'Nope'")
        self.assertFalse(self.out.with_suffix(".jsonl").exists())

    def test_trials_of_another_scenario_or_cell_are_not_resumed(self):
        # Rows already in the output are resumed only when they were made
        # under this scenario at the library's cell; otherwise the run is
        # refused before any trial (the rows stay as they were).
        from regrasp_drake.learning.library import load_library
        from regrasp_drake.paths import MODELS_DIR
        from regrasp_drake.station.scenario import load_scenario, scenario_digest
        entry = load_library(MODELS_DIR / "results" / "library_table1.yaml")[
            "table1-row5"]
        digest = scenario_digest(load_scenario())
        lines = self.out.with_suffix(".jsonl")
        args = ["--objects", "table1-row5", "--levels", "0", "--trials", "1",
                "--modes", "watch", "--out", str(self.out)]
        for row, said in (
                ({"scenario": "0123456789abcdef", "h_catch": entry.h_catch,
                  "h_down": entry.h_down}, "0123456789abcdef"),
                ({"h_catch": entry.h_catch, "h_down": entry.h_down},
                 "scenario None"),
                ({"scenario": digest, "h_catch": 0.04, "h_down": -0.14},
                 "(0.04, -0.14) m")):
            with self.subTest(row=row):
                text = json.dumps({"mode": "watch", "object": "table1-row5",
                                   "level": 0.0, "trial": 0, **row,
                                   "outcome": "caught"}) + "\n"
                lines.write_text(text)
                self.assertRefused(args, "--out", said)
                self.assertEqual(lines.read_text(), text)

    def test_unknown_mode_refused(self):
        with contextlib.redirect_stderr(io.StringIO()) as err, \
                self.assertRaises(SystemExit) as exit_:
            self.main(["--modes", "watch", "nope", "--out", str(self.out)])
        self.assertEqual(exit_.exception.code, 2)
        self.assertIn("--modes", err.getvalue())
        self.assertFalse(self.out.with_suffix(".jsonl").exists())

    def test_noiseless_trials_catch_as_the_learning_phase_did(self):
        # table1-row5 was caught in all three modes (models/results); the
        # same parameters without noise catch again on it, one throw per
        # mode (two when watching first).
        with contextlib.redirect_stdout(io.StringIO()), \
                contextlib.redirect_stderr(io.StringIO()):
            code = self.main([
                "--objects", "table1-row5", "--levels", "0", "--trials", "1",
                "--workers", "1", "--out", str(self.out)])
        self.assertEqual(code, 0)
        rows = [json.loads(line) for line in
                self.out.with_suffix(".jsonl").read_text().splitlines()]
        self.assertEqual(sorted(r["mode"] for r in rows),
                         ["at-release", "first-throw", "watch"])
        self.assertEqual({r["outcome"] for r in rows}, {"caught"})
        # Without noise the catching throw's release is the watched one bit
        # for bit: its correction changes nothing.
        watched = next(r for r in rows if r["mode"] == "watch")
        self.assertEqual(watched["release_correction"],
                         {"how": "same release", "shift_mm": 0.0,
                          "turn_deg": 0.0})
        summary = json.loads(self.out.with_suffix(".json").read_text())
        for mode in ("watch", "first-throw", "at-release"):
            point = summary["curves"][mode][0]
            self.assertEqual((point["trials"], point["caught"]), (1, 1))
            self.assertEqual(point["catch_rate_95"][1], 1.0)
        self.assertEqual(summary["scenario"], "defaults")  # the shipped one
        self.assertGreater(self.out.with_suffix(".png").stat().st_size, 10_000)


if __name__ == "__main__":
    unittest.main()
