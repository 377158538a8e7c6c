"""The wavefront order of the search over the 150 cells (paper Figs. 7-8)."""

import unittest

from regrasp_drake.errors import InputError
from regrasp_drake.grid import H_CATCH_VALUES, H_DOWN_VALUES, cells
from regrasp_drake.learning.search import ring, wavefront_order

N_CATCH, N_DOWN = len(H_CATCH_VALUES), len(H_DOWN_VALUES)
CORNERS = [(0, 0), (0, N_DOWN - 1), (N_CATCH - 1, 0), (N_CATCH - 1, N_DOWN - 1)]


class TestWavefrontOrder(unittest.TestCase):
    def test_every_start_cell_covers_the_grid_once(self):
        everything = set(cells())
        for start in cells():
            order = wavefront_order(start)
            with self.subTest(start=start):
                self.assertEqual(order[0], start)
                self.assertEqual(len(order), 150)
                self.assertEqual(len(set(order)), 150)  # never a cell twice
                self.assertEqual(set(order), everything)  # none outside

    def test_rings_in_order_each_complete(self):
        for start in cells():
            rings = [ring(c, start) for c in wavefront_order(start)]
            with self.subTest(start=start):
                self.assertEqual(rings, sorted(rings))
                # Each ring holds every in-grid cell at that distance.
                for r in set(rings):
                    expected = sum(
                        max(abs(i - start[0]), abs(j - start[1])) == r
                        for i in range(N_CATCH) for j in range(N_DOWN))
                    self.assertEqual(rings.count(r), expected)

    def test_each_ring_grows_from_the_previous(self):
        """Fig. 8: a layer is made of neighbours (±1 unit in h_catch and/or
        h_down) of the layer before it."""
        for start in CORNERS + [(4, 7), (9, 3)]:
            order = wavefront_order(start)
            for k, cell in enumerate(order[1:], 1):
                inner = [c for c in order[:k]
                         if ring(c, start) == ring(cell, start) - 1]
                with self.subTest(start=start, cell=cell):
                    self.assertTrue(any(ring(cell, c) == 1 for c in inner))

    def test_documented_order_inside_a_ring(self):
        for start in cells():
            order = wavefront_order(start)
            keys = [(ring(c, start), (c[0] - start[0]) ** 2
                     + (c[1] - start[1]) ** 2, c[0], c[1]) for c in order]
            with self.subTest(start=start):
                self.assertEqual(keys, sorted(keys))

    def test_first_ring_examples(self):
        # An inner cell: the four edge neighbours, then the diagonals.
        self.assertEqual(wavefront_order((4, 7))[:9], [
            (4, 7), (3, 7), (4, 6), (4, 8), (5, 7),
            (3, 6), (3, 8), (5, 6), (5, 8)])
        # Corners: three neighbours, the diagonal last.
        self.assertEqual(wavefront_order((0, 0))[:4],
                         [(0, 0), (0, 1), (1, 0), (1, 1)])
        self.assertEqual(wavefront_order((0, 14))[:4],
                         [(0, 14), (0, 13), (1, 14), (1, 13)])
        self.assertEqual(wavefront_order((9, 14))[:4],
                         [(9, 14), (8, 14), (9, 13), (8, 13)])
        # The last cell from a corner is the opposite corner.
        self.assertEqual(wavefront_order((0, 0))[-1], (9, 14))

    def test_start_outside_the_grid_refused(self):
        for start in ((-1, 0), (0, N_DOWN), (N_CATCH, 3)):
            with self.subTest(start=start), self.assertRaises(InputError) as e:
                wavefront_order(start)
            self.assertIn("start_cell", str(e.exception))


if __name__ == "__main__":
    unittest.main()
