"""studies/release_spin/release_spin.py: the state it reports is the data set's, and
bad input is refused."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

import numpy as np

from regrasp_drake.paths import MODELS_DIR
from tests.refusals import RefusalAssertions, load_script

release_spin = load_script("studies/release_spin/release_spin.py")


class ThrowTest(unittest.TestCase):
    def test_shipped_release_time_gives_the_data_sets_state(self):
        """At the shipped 0.31 s the throw's end state is the one the data
        set stored for the flight predictor; opening the fingers 50 ms later
        changes it."""
        plan = json.loads((MODELS_DIR / "dataset" / "plans" /
                           "can-d350-6.json").read_text())
        row = release_spin._throw(("can-d350-6", 0.31, 0.5))
        self.assertAlmostEqual(row["t_s"], plan["free_flight"]["t_s"])
        np.testing.assert_allclose(row["state"], plan["free_flight"]["state"],
                                   atol=1e-9)
        later = release_spin._throw(("can-d350-6", 0.36, 0.5))
        self.assertGreater(np.max(np.abs(np.subtract(later["state"],
                                                     row["state"]))), 1e-6)

    def test_summary_spreads(self):
        rows = [{"object": f"g-{k}", "geometry": "g", "release_time_s": 0.31,
                 "hold_closure": 0.5, "w_O": [0.0, w, 0.0]}
                for k, w in enumerate((-1.0, -3.0))]
        rows.append({"object": "h-1", "geometry": "h", "release_time_s": 0.31,
                     "hold_closure": 0.5, "w_O": [0.0, -8.0, 0.0]})
        # Another configuration's throw is not counted in this one's.
        rows.append({"object": "h-1", "geometry": "h", "release_time_s": 0.31,
                     "hold_closure": 0.8, "w_O": [0.0, 5.0, 0.0]})
        s = release_spin.summarize(rows, [(0.31, 0.5)])[
            "release 0.31 s, hold 0.5"]
        self.assertEqual(s["spin_std_within_geometry_rad_per_s"],
                         {"g": 1.0, "h": 0.0})
        self.assertEqual(s["mean_within_geometry_std_rad_per_s"], 0.5)
        self.assertEqual((s["spin_min_rad_per_s"], s["spin_max_rad_per_s"]),
                         (-8.0, -1.0))


class ResumeTest(unittest.TestCase):
    def test_a_rerun_throws_nothing_again(self):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "spin"
            argv = ["--objects", "can-d350-6", "--release-times-s", "0.31",
                    "--workers", "1", "--out", str(out)]
            with contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                self.assertEqual(release_spin.main(argv), 0)
                first = json.loads(out.with_suffix(".json").read_text())
                self.assertEqual(release_spin.main(argv), 0)
            lines = out.with_suffix(".jsonl").read_text().splitlines()
            self.assertEqual(len(lines), 1)  # thrown once, not twice
            self.assertEqual(json.loads(out.with_suffix(".json").read_text()),
                             first)
            self.assertTrue(out.with_suffix(".png").exists())


class BadInputTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(release_spin.main)

    def test_release_time_after_the_throw_refused_naming_it(self):
        self.assertRefused(["--release-times-s", "0.6"],
                           "--release-times-s 0.6: throw.release_time_s: "
                           "got 0.6, expected a number in [0.0, 0.564] s")

    def test_hold_closure_out_of_range_refused_naming_it(self):
        self.assertRefused(["--hold-closures", "1.5"],
                           "--hold-closures 1.5: throw.hold_closure: got 1.5")

    def test_unknown_object_and_bad_workers_refused(self):
        self.assertRefused(["--objects", "no-such-object"], "'no-such-object'")
        self.assertRefused(["--workers", "0"], "--workers 0: expected >= 1")


if __name__ == "__main__":
    unittest.main()
