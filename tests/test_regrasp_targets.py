"""benchmarks/regrasp_targets.py and benchmarks/landing_convergence.py: the
landing figures over rows, the pair-by-pair comparison of two steps, and
their refusals (no simulation)."""

import json
import tempfile
import unittest
from pathlib import Path

from tests.refusals import RefusalAssertions, load_script

regrasp_targets = load_script("benchmarks/regrasp_targets.py")
landing_convergence = load_script("benchmarks/landing_convergence.py")


def _row(name, success, held, axis=None, offset=None, predicted=None,
         stopped="caught"):
    error = None if axis is None else {
        "axis_error_deg": axis, "offset_error_mm": offset, "side_ok": None}
    return {"object": name, "target": {"kind": "flip", "offset_mm": 0.0},
            "mode": "first-throw", "stopped": stopped, "success": success,
            "caught": held, "grasp_error": error,
            "achieved_grasp": None if not held else {
                "axis": "reversed", "offset_mm": offset, "tilt_deg": axis},
            "predicted_grasp": None if predicted is None else {
                "axis": "reversed", "offset_mm": predicted, "tilt_deg": 0.0}}


ROWS = [_row("a", True, True, 5.0, 2.0, predicted=1.0),
        _row("b", False, True, 30.0, 4.0, predicted=0.0),   # tilted
        _row("c", False, True, 8.0, -14.0, predicted=-10.0),  # off
        _row("d", False, True, 170.0, 0.0),                  # wrong way
        _row("e", False, False),                             # dropped
        _row("f", False, False, stopped="refused"),
        # refused after its rehearsal: a miss, kept in the denominator
        _row("g", False, False, stopped="unholdable")]


class LandingFiguresTest(unittest.TestCase):
    def test_share_medians_and_misses(self):
        figures = regrasp_targets.landing(ROWS)
        self.assertEqual((figures["pairs"], figures["refused"],
                          figures["in_target"]), (7, 1, 1))
        self.assertEqual(figures["share_in_target"], round(1 / 6, 3))
        # Held the right way round: a, b, c.
        self.assertEqual(figures["held_right_way_round"], 3)
        self.assertEqual(figures["median_abs_offset_error_mm"], 4.0)
        self.assertEqual(figures["median_tilt_deg"], 8.0)
        self.assertEqual(figures["misses"], {
            "no_catch_point": 0, "unholdable": 1, "dropped": 1,
            "wrong_way_round": 1, "tilted": 1, "off_offset": 1})
        # The landing model's error: |1-2|, |0-4|, |-10+14|.
        self.assertEqual(figures["median_abs_predicted_offset_error_mm"], 4.0)


class LandingConvergenceTest(unittest.TestCase):
    def test_pairs_compared_by_verdict_and_grasp(self):
        fine = [_row("a", True, True, 6.0, 8.0),     # 6 mm apart
                _row("b", False, True, 31.0, 3.0),   # within
                _row("e", True, True, 2.0, 0.0)]     # held only here
        key = landing_convergence._key
        result = landing_convergence.compare(
            {key(r): r for r in ROWS}, {key(r): r for r in fine}, 5.0, 5.0)
        self.assertEqual(result["compared"], 3)
        self.assertEqual(result["same_verdict"], 2)
        self.assertEqual(result["grasp_within"], 1)


class RefusalTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(regrasp_targets.main)

    def test_bad_counts_and_targets(self):
        with tempfile.TemporaryDirectory() as d:
            out = str(Path(d) / "r")
            self.assertRefused(["--workers", "0", "--out", out], "--workers",
                               "got 0", ">= 1")
            self.assertRefused(["--max-throws", "1", "--out", out],
                               "--max-throws", ">= 2")
            self.assertRefused(["--targets", "spin:0", "--out", out],
                               "--targets", "'spin:0'")
            self.assertFalse(Path(out).with_suffix(".jsonl").exists())

    def test_a_recorded_rehearsal_must_match(self):
        with tempfile.TemporaryDirectory() as d:
            out, recorded = str(Path(d) / "r"), Path(d) / "m.jsonl"
            recorded.write_text(json.dumps(
                ROWS[0] | {"level": 0.0, "trial": 0,
                           "scenario_digest": "another"}) + "\n")
            self.assertRefused(["--rehearsal-from", str(recorded),
                                "--out", out], "--rehearsal-from",
                               "without --rehearse")
            pair = ["--objects", ROWS[0]["object"], "--targets",
                    "{kind}:{offset_mm:g}".format(**ROWS[0]["target"]),
                    "--modes", ROWS[0]["mode"], "--max-throws", "1"]
            self.assertRefused(["--rehearse", "--rehearsal-from",
                                str(recorded), "--out", out] + pair,
                               "another scenario")
            # A row that records what its rehearsal simulated is checked on
            # that alone (the judged steps may differ), and refused here.
            recorded.write_text(json.dumps(
                ROWS[0] | {"level": 0.0, "trial": 0,
                           "scenario_digest": "another",
                           "rehearsal_digest": "another too"}) + "\n")
            self.assertRefused(["--rehearse", "--rehearsal-from",
                                str(recorded), "--out", out] + pair,
                               "rehearsed under another scenario")
            self.assertRefused(["--rehearse", "--rehearsal-from",
                                str(recorded), "--out", out, "--objects",
                                "table1-row5", "--targets", "flip:0",
                                "--modes", "first-throw",
                                "--max-throws", "1"], "has no row")
            self.assertFalse(Path(out).with_suffix(".jsonl").exists())

    def test_convergence_needs_two_files_of_rows(self):
        with tempfile.TemporaryDirectory() as d:
            rows = Path(d) / "rows.jsonl"
            rows.write_text(json.dumps(ROWS[0]) + "\n")
            self.main = landing_convergence.main
            self.assertRefused([str(rows), str(Path(d) / "none.jsonl")],
                               "fine", "none.jsonl")
            other = Path(d) / "other.jsonl"
            other.write_text(json.dumps(_row("z", True, True, 1.0, 0.0))
                             + "\n")
            self.assertRefused([str(rows), str(other)], "share no pair")


if __name__ == "__main__":
    unittest.main()
