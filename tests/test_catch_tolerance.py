"""benchmarks/catch_tolerance.py: its offsets, its refusals, and one offset's
catch on the shipped scenario at 1 ms (Fast)."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

from regrasp_drake.errors import InputError
from tests.refusals import RefusalAssertions, load_script

catch_tolerance = load_script("benchmarks/catch_tolerance.py")


class OffsetsTest(unittest.TestCase):
    def test_all_is_the_25_offsets_of_a_20_mm_grid(self):
        offsets = catch_tolerance.parse_offsets("all")
        self.assertEqual(len(offsets), 25)
        self.assertEqual((offsets[0], offsets[-1]), ((-20, -20), (20, 20)))

    def test_listed_offsets_and_bad_ones(self):
        self.assertEqual(catch_tolerance.parse_offsets("0,0;10,-20"),
                         [(0, 0), (10, -20)])
        # Along the palm's normal too.
        self.assertEqual(catch_tolerance.parse_offsets("0,0,-20;10,0"),
                         [(0, 0, -20), (10, 0)])
        for bad in ("", "1", "1,2,3,4", "a,b", "1.5,0"):
            with self.subTest(bad=bad), self.assertRaises(InputError):
                catch_tolerance.parse_offsets(bad)


class CatchTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(catch_tolerance.main)

    def setUp(self):
        self.tmp = tempfile.TemporaryDirectory()
        self.out = Path(self.tmp.name) / "tolerance"

    def tearDown(self):
        self.tmp.cleanup()

    def test_bad_arguments_refused_before_any_work(self):
        cell = ["table1-row2", "0.20", "-0.13", "--out", str(self.out)]
        self.assertRefused(["no-such-object", "0.20", "-0.13"],
                           "'no-such-object'")
        self.assertRefused([*cell, "--offsets", "1;2"], "--offsets")
        self.assertRefused([*cell, "--scenario-name", "Nope"],
                           "--scenario-name: got 'Nope'")
        self.assertFalse(self.out.exists())

    def test_one_offset_caught_or_not_and_the_plan_cached(self):
        with contextlib.redirect_stdout(io.StringIO()) as printed:
            code = self.main(["table1-row2", "0.20", "-0.13",
                              "--scenario-name", "Fast", "--offsets", "0,10",
                              "--tag", "t", "--out", str(self.out)])
        self.assertEqual(code, 0)
        lines = printed.getvalue().splitlines()
        row = json.loads(lines[0])
        self.assertEqual((row["dx_mm"], row["dy_mm"], row["dz_mm"], row["tag"]),
                         (0, 10, 0, "t"))
        self.assertIn(row["outcome"], ("caught", "dropped", "failed"))
        self.assertTrue(lines[-1].startswith("SUMMARY t table1-row2"))
        written = (self.out / "table1-row2_0.2_-0.13_t.jsonl").read_text()
        self.assertEqual([json.loads(line) for line in written.splitlines()],
                         [row])
        self.assertEqual(len(list(self.out.glob("plan_table1-row2_*.json"))),
                         1)


if __name__ == "__main__":
    unittest.main()
