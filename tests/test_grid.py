"""The parameter space: 150 cells inside the paper's ranges."""

import unittest

from regrasp_drake.grid import (
    H_CATCH_VALUES,
    H_DOWN_VALUES,
    cell_parameters,
    cells,
    format_map,
    nearest_cell,
)
from regrasp_drake.station.scenario import H_CATCH_RANGE, H_DOWN_RANGE


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


if __name__ == "__main__":
    unittest.main()
