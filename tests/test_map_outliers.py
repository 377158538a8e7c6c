"""studies/map_outliers/map_outliers.py: typicality of a map, the ending prior's
search, and the committed figures."""

import json
import tempfile
import unittest
from pathlib import Path

import numpy as np

from tests.refusals import RefusalAssertions, load_script

map_outliers = load_script("studies/map_outliers/map_outliers.py")
SHAPE = map_outliers.SHAPE
KEYS = map_outliers.ENDING_KEYS


def corner_map(cell, failure: str):
    """A prior map catching only at `cell`, every other cell ending `failure`;
    returns (caught, endings)."""
    caught = np.zeros(SHAPE, bool)
    caught[cell] = True
    endings = np.full(SHAPE, KEYS.index(failure))
    endings[cell] = KEYS.index("caught")
    return caught, endings


class TypicalityTest(unittest.TestCase):
    def test_correlation_with_the_training_frequency(self):
        frequency = np.zeros(SHAPE)
        frequency[5:] = 0.8
        frequency[:5] = 0.2
        like = frequency > 0.5
        self.assertAlmostEqual(map_outliers.typicality(like, frequency), 1.0)
        self.assertAlmostEqual(map_outliers.typicality(~like, frequency), -1.0)
        self.assertTrue(np.isnan(map_outliers.typicality(
            np.ones(SHAPE, bool), frequency)))

    def test_training_entries_are_measured_without_their_own_object(self):
        top = np.zeros(SHAPE, bool)
        top[5:] = True
        names = ["a", "a@2", "b", "c"]
        # a's two catch points agree with each other and disagree with b, c.
        maps = np.stack([~top, ~top, top, top])
        out = map_outliers.training_typicality(names, maps)
        self.assertAlmostEqual(out["a"], -1.0)
        # b agrees with c, but against a's two catch points and c the
        # frequency is 1/3 where b catches and 2/3 where it does not.
        self.assertAlmostEqual(out["b"], -1.0)


class ReadRowsTest(unittest.TestCase):
    def test_a_map_without_all_its_cells_is_refused(self):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "m.jsonl"
            path.write_text("".join(json.dumps(
                {"cell": [0, j], "outcome": "caught"}) + "\n" for j in range(3)))
            for bad in (path, Path(d) / "missing.jsonl"):
                with self.assertRaises(ValueError) as e:
                    map_outliers.read_rows(bad)
                self.assertIn("150 cells", str(e.exception))
                self.assertIn(str(bad), str(e.exception))


class EndingPriorTest(unittest.TestCase):
    def test_the_ending_points_to_the_maps_that_end_so(self):
        a_caught, a_end = corner_map((0, 0), "on_arm")
        b_caught, b_end = corner_map((9, 14), "below_palm")
        maps, endings = np.stack([a_caught, b_caught]), np.stack([a_end, b_end])
        start = (5, 7)
        for failure, target in (("on_arm", (0, 0)), ("below_palm", (9, 14))):
            observed = np.full(SHAPE, KEYS.index(failure))
            order = map_outliers.ending_prior_order(start, maps, endings,
                                                    observed)
            self.assertEqual(next(order), start)
            self.assertEqual(next(order), target, failure)

    def test_mismatched_endings_are_refused(self):
        maps = np.zeros((2, *SHAPE), bool)
        with self.assertRaises(ValueError) as e:
            next(map_outliers.ending_prior_order((0, 0), maps,
                                                 np.zeros((1, *SHAPE), int),
                                                 np.zeros(SHAPE, int)))
        self.assertIn("prior_endings", str(e.exception))


class CommittedFiguresTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(map_outliers.main)

    def test_a_rerun_gives_the_committed_json(self):
        committed = json.loads(Path(map_outliers.__file__)
                               .with_suffix(".json").read_text())
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "m.json"
            self.assertEqual(map_outliers.main(["--out", str(out)]), 0)
            self.assertEqual(json.loads(out.read_text()), committed)
            self.assertTrue(out.with_suffix(".png").stat().st_size > 10_000)
        # Row 4 is among the least typical maps of all: few training entries
        # catch less where most training maps catch.
        row4 = committed["typicality"]["table1"]["4"]
        self.assertLess(row4["typicality"], 0.0)
        self.assertLess(row4["frequency_where_caught"],
                        row4["frequency_where_failed"])

    def test_an_output_in_a_missing_directory_is_refused(self):
        self.assertRefused(["--out", "/nonexistent/dir/m.json"], "--out")


if __name__ == "__main__":
    unittest.main()
