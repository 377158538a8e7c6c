"""studies/release_convergence/release_convergence.py: the committed figures
and bad input."""

import json
import tempfile
import unittest
from pathlib import Path

from tests.refusals import RefusalAssertions, load_script

release_convergence = load_script("studies/release_convergence/release_convergence.py")


class ReleaseConvergenceTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(release_convergence.main)

    def test_a_rerun_gives_the_committed_json(self):
        committed = json.loads(Path(release_convergence.__file__)
                               .with_suffix(".json").read_text())
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "r.json"
            self.assertEqual(self.main(["--out", str(out)]), 0)
            self.assertEqual(json.loads(out.read_text()), committed)
        shipped = committed["timestep_flights.json"]
        # Every object counted once, in one of the three bands.
        moved = shipped["catch_point_moved_mm"]
        self.assertEqual(moved["at_most_10"] + moved["10_to_30"]
                         + moved["over_30"], shipped["planned_at_both"])

    def test_counts_of_a_small_file(self):
        flights = {"steps_ms": [1.0, 0.25], "objects": {
            name: {"shift_from_finest": {"1": {
                "w_O_rad_per_s": w, "catch_p_mm": p, "catch_t_ms": t}}}
            for name, w, p, t in (("a", 0.1, 5.0, 0.0), ("b", 0.3, 20.0, -8.0),
                                  ("c", 2.0, 50.0, 4.0))}}
        r = release_convergence.summarize(flights)
        self.assertEqual(r["spin_shift_rad_per_s"]["median"], 0.3)
        self.assertEqual(r["catch_point_moved_mm"], {
            "median": 20.0, "at_most_10": 1, "10_to_30": 1, "over_30": 1})
        self.assertEqual(r["caught_8_ms_or_more_apart"], 1)

    def test_bad_input_is_refused(self):
        with tempfile.TemporaryDirectory() as d:
            bad = Path(d) / "bad.json"
            bad.write_text('{"objects": {}}')
            self.assertRefused(["--flights", str(bad), "--out",
                                str(Path(d) / "r.json")], str(bad), "steps_ms")
            self.assertRefused(["--flights", str(Path(d) / "none.json"),
                                "--out", str(Path(d) / "r.json")], "none.json")


if __name__ == "__main__":
    unittest.main()
