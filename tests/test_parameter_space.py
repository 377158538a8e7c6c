"""The parameter space: 150 cells within the paper's bounds."""

import unittest

from regrasp_drake.parameter_space import (
    H_CATCH_RANGE,
    H_CATCH_VALUES,
    H_DOWN_RANGE,
    H_DOWN_VALUES,
    cell_parameters,
    cells,
    is_cell,
    nearest_cell,
)


class ParameterSpaceTest(unittest.TestCase):
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

    def test_is_cell_only_within_the_grid(self):
        self.assertTrue(all(is_cell(c) for c in cells()))
        self.assertTrue(is_cell([9, 14]))
        for other in ([10, 0], [0, 15], [-1, 0], [True, 0], [1.0, 2],
                      [1, 2, 3], "12", None):
            self.assertFalse(is_cell(other), other)


if __name__ == "__main__":
    unittest.main()
