"""The parameter space: 150 cells inside the paper's ranges."""

import json
import tempfile
import unittest
from pathlib import Path

from regrasp_drake.grid import (
    ENDINGS,
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    append_rows,
    cell_parameters,
    cells,
    ending,
    ending_counts,
    format_map,
    nearest_cell,
    read_rows,
)
from regrasp_drake.station.scenario import H_CATCH_RANGE, H_DOWN_RANGE


def _square(k):
    return {"k": k, "square": k * k}


class AppendRowsTest(unittest.TestCase):
    """Resumable JSON lines (open_rows, which append_rows and run_map use):
    rows appended as they finish, in the tasks' order; after a line cut by a
    kill, the cut line is gone and the next rows are whole lines, read
    back."""

    def test_rows_written_and_resumed(self):
        with tempfile.TemporaryDirectory() as d:
            path = Path(d) / "rows.jsonl"
            key = lambda row: row["k"]  # noqa: E731
            done = {}
            append_rows(_square, [3, 1, 2], path, done, key, workers=2,
                        label="test", unit="tasks")
            lines = path.read_text().splitlines()
            self.assertEqual(len(lines), 3)
            self.assertIn('"k": 3', lines[0])
            with path.open("a") as f:
                f.write('{"k": 4, "squ')  # a line cut by a kill
            resumed = read_rows(path, key=key)
            self.assertEqual(resumed, done)
            self.assertEqual(resumed[2], {"k": 2, "square": 4})
            todo = [k for k in range(1, 6) if k not in resumed]
            self.assertEqual(todo, [4, 5])
            append_rows(_square, todo, path, resumed, key, workers=2,
                        label="test", unit="tasks")
            self.assertEqual(read_rows(path, key=key),
                             {k: _square(k) for k in range(1, 6)})
            # Every line a whole row: a plain JSON-lines reader reads it.
            rows = [json.loads(line) for line in path.read_text().splitlines()]
            self.assertEqual(sorted(r["k"] for r in rows), [1, 2, 3, 4, 5])


class TestGrid(unittest.TestCase):
    def test_150_distinct_cells_in_range(self):
        all_cells = cells()
        self.assertEqual(len(all_cells), 150)
        params = {cell_parameters(c) for c in all_cells}
        self.assertEqual(len(params), 150)
        for h_catch, h_down in params:
            self.assertTrue(H_CATCH_RANGE[0] < h_catch <= H_CATCH_RANGE[1])
            self.assertTrue(H_DOWN_RANGE[0] <= h_down <= H_DOWN_RANGE[1])
        self.assertEqual((len(H_CATCH_VALUES), len(H_DOWN_VALUES)), (10, 15))

    def test_nearest_cell_round_trips(self):
        for cell in cells():
            self.assertEqual(nearest_cell(*cell_parameters(cell)), cell)
        self.assertEqual(nearest_cell(1.0, -1.0), (9, 0))

    def test_map_marks_outcomes(self):
        rows = {(0, 0): {"outcome": "caught"}, (0, 1): {"outcome": "dropped"}}
        text = format_map(rows)
        self.assertIn("1/2 cells catch", text)
        first_row = text.splitlines()[1].split()
        self.assertEqual(first_row[1:4], ["✓", "✗", "?"])
        # A row without a drop reason (an older file) is counted as other.
        self.assertIn("1 a timeout, or a row written without", text)

    def test_endings_from_reason_and_contacts(self):
        def row(outcome, reason=None, touching=()):
            return {"outcome": outcome, "drop_reason": reason,
                    "touching": list(touching)}
        cases = [
            (row("caught", touching=["palm", "index_distal"]), "caught"),
            (row("dropped", "not_held", ["palm", "thumb_proximal"]),
             "in_fingers"),
            (row("dropped", "not_held", ["link4", "palm"]), "on_arm"),
            (row("dropped", "not_held", ["palm"]), "loose"),
            (row("dropped", "below_palm"), "below_palm"),
            (row("dropped", "near_ground", ["world"]), "near_ground"),
            (row("failed"), "failed"),
            (row("timeout"), "other"),
        ]
        for r, expected in cases:
            self.assertEqual(ending(r), expected, r)
        counts = ending_counts(r for r, _ in cases)
        self.assertEqual(set(counts), set(ENDINGS))
        self.assertEqual(sum(counts.values()), len(cases))
        text = format_map({(0, j): r for j, (r, _) in enumerate(cases)})
        self.assertIn("1 not held: at rest against the arm", text)


if __name__ == "__main__":
    unittest.main()
