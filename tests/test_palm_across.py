"""studies/palm_across/palm_across.py: grouping and counting stored success maps."""

import unittest

import numpy as np

from tests.refusals import load_script

palm_across = load_script("studies/palm_across/palm_across.py")


class PalmAcrossTest(unittest.TestCase):
    def test_groups_by_the_centre_of_mass_offset(self):
        self.assertEqual(palm_across.group_of(0.0), "r_cm = 0")
        self.assertEqual(palm_across.group_of(-0.012), "|r_cm| < 20 mm")
        self.assertEqual(palm_across.group_of(0.02), "|r_cm| >= 20 mm")
        self.assertEqual(palm_across.group_of(-0.043), "|r_cm| >= 20 mm")

    def test_counts_only_entries_every_fraction_has(self):
        full, empty = np.ones((10, 15), bool), np.zeros((10, 15), bool)
        one_cell = empty.copy()
        one_cell[3, 4] = True
        maps = {1.0: {"a": full, "a@2": one_cell, "b": empty, "c": full},
                0.0: {"a": one_cell, "a@2": full, "b": full}}
        r_cm = {"a": 0.03, "b": 0.005, "c": 0.0}
        out = palm_across.summarize(maps, r_cm)
        self.assertEqual(set(out), {"|r_cm| >= 20 mm", "|r_cm| < 20 mm"})
        big = out["|r_cm| >= 20 mm"]
        self.assertEqual(big["maps"], 2)
        self.assertEqual(big["by_fraction"]["1.0"]["catching_cells"], 151)
        self.assertEqual(big["by_fraction"]["0.0"]["catching_cells"], 151)
        small = out["|r_cm| < 20 mm"]["by_fraction"]
        self.assertEqual((small["1.0"]["maps_catching"],
                          small["0.0"]["maps_catching"]), (0, 1))


if __name__ == "__main__":
    unittest.main()
