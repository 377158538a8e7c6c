"""The studies failure_modes, catch_points and search_prior_sweep: their
committed figures follow from their committed rows and stored maps
(no simulation)."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

from regrasp_drake.grid import read_rows
from tests.refusals import load_script

failure_modes = load_script("studies/failure_modes/failure_modes.py")
catch_points = load_script("studies/catch_points/catch_points.py")
search_prior_sweep = load_script("studies/search_prior_sweep/search_prior_sweep.py")
FAILURE_MODES = Path(failure_modes.__file__).parent


class FailureModesTest(unittest.TestCase):
    def test_committed_summaries_follow_from_the_committed_rows(self):
        for name in ("failure_modes", "failure_modes_hold_0.5"):
            stored = json.loads((FAILURE_MODES / f"{name}.json").read_text())
            for result in stored["objects"]:
                rows = read_rows(FAILURE_MODES / name / f"{result['object']}.jsonl")
                self.assertEqual(len(rows), 150)
                start = (None if result["start_cell"] is None
                         else tuple(result["start_cell"]))
                again = failure_modes.summarize(result["object"], rows, start)
                self.assertEqual(again["endings"], result["endings"])
                self.assertEqual(again["in_fingers_touching_palm"],
                                 result["in_fingers_touching_palm"])
                self.assertEqual(again["start_cell_ending"],
                                 result["start_cell_ending"])
                # The shipped scenario reproduces the stored maps cell for
                # cell; a longer hold changes row 5's.
                if name == "failure_modes":
                    self.assertTrue(all(again["agrees_with_stored"].values()),
                                    again)
                    self.assertTrue(again["agrees_with_stored"], again)  # non-empty
        longer = json.loads(
            (FAILURE_MODES / "failure_modes_hold_0.5.json").read_text())
        self.assertEqual(longer["scenario"],
                         "studies/failure_modes/hold_0.5.yaml")

    def test_table1_row4_network_cell_ends_against_the_arm(self):
        rows = read_rows(FAILURE_MODES / "failure_modes" / "table1-row4.jsonl")
        row = rows[(6, 6)]
        self.assertEqual(row["outcome"], "dropped")
        self.assertEqual(row["drop_reason"], "not_held")
        self.assertIn("palm", row["touching"])
        self.assertFalse(any(b.endswith(("_distal", "_proximal"))
                             for b in row["touching"]))


class StoredMapStudiesTest(unittest.TestCase):
    def _rerun(self, module):
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "out.json"
            with contextlib.redirect_stdout(io.StringIO()):
                self.assertEqual(module.main(["--out", str(out)]), 0)
            return (json.loads(out.read_text()),
                    json.loads(Path(module.__file__).with_suffix(".json")
                               .read_text()))

    def test_output_in_a_missing_directory_refused_before_any_work(self):
        for module in (failure_modes, catch_points, search_prior_sweep):
            err = io.StringIO()
            with contextlib.redirect_stderr(err):
                code = module.main(["--out", "/nonexistent-dir/out.json"])
            self.assertEqual(code, 2, module.__name__)
            self.assertIn("--out: got '/nonexistent-dir/out.json', expected "
                          "a path in an existing directory", err.getvalue())

    def test_catch_points_reproduces_its_json(self):
        again, stored = self._rerun(catch_points)
        self.assertEqual(again, stored)
        self.assertEqual([again["table1"][f"table1-row4{k}"]["caught"]
                          for k in ("", "@2", "@3", "@4")], [35, 54, 67, 142])
        rules = again["training"]["share_caught_by_rule"]
        self.assertLessEqual(max(rules.values()), rules["best (oracle)"])

    def test_search_prior_sweep_reproduces_its_json(self):
        again, stored = self._rerun(search_prior_sweep)
        self.assertEqual(again, stored)
        shipped = [r for r in again["settings"] if r["eps"] == 0.2
                   and r["sigma_catch_cells"] == r["sigma_down_cells"] == 0.7]
        # The shipped setting gives row 4 the 14 cells search.py documents.
        self.assertEqual(shipped[0]["table1_cells"]["table1-row4"], 14)


if __name__ == "__main__":
    unittest.main()
