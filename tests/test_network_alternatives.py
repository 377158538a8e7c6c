"""studies/network_alternatives/network_alternatives.py: the predictors it
compares with the network, on the shipped data set's maps."""

import contextlib
import io
import json
import tempfile
import unittest
from pathlib import Path

import numpy as np
import torch

from regrasp_drake import grid
from regrasp_drake.learning.dataset import label_cell, load_samples, object_of
from regrasp_drake.learning.train import _arrays, split_indices
from tests.refusals import RefusalAssertions, load_script

alternatives = load_script("studies/network_alternatives/network_alternatives.py")


class NetworkAlternativesTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(alternatives.main)

    @classmethod
    def setUpClass(cls):
        samples = load_samples(alternatives.DATA_DIR)
        with np.load(alternatives.DATA_DIR / "maps.npz") as data:
            by_name = dict(zip(data["objects"].tolist(), data["caught"]))
        cls.maps = np.array([by_name[s["object"]] for s in samples], float)
        cls.x, _ = _arrays(samples)
        cls.split = split_indices(len(samples), 0, groups=[
            object_of(s["object"]) for s in samples])

    def test_every_training_map_as_neighbour_is_a_best_constant_cell(self):
        train_i, _, test_i = self.split
        cells = alternatives.nearest_maps_cells(
            self.x, self.maps, self.split, k=len(train_i))
        votes = self.maps[train_i].sum(axis=0)
        self.assertEqual(len(set(cells)), 1)
        self.assertEqual(votes[cells[0]], votes.max())
        self.assertEqual(len(cells), len(test_i))

    def test_one_neighbour_of_a_training_entry_is_its_own_label(self):
        # A training entry's nearest training map is its own.
        train_i = self.split[0][:10]
        cells = alternatives.nearest_maps_cells(
            self.x, self.maps, (self.split[0], [], train_i), k=1)
        labelled = [(t, c) for t, c in zip(train_i, cells)
                    if self.maps[t].any()]
        self.assertGreater(len(labelled), 5)
        for t, c in labelled:
            self.assertEqual(c, label_cell(self.maps[t] > 0))

    def test_smoothed_catch_chance_reads_the_map_at_a_cell_centre(self):
        caught = np.zeros((1, *self.maps.shape[1:]))
        caught[0, 3, 7] = 1.0
        at = torch.tensor([grid.cell_parameters((3, 7))], dtype=torch.float64)
        away = torch.tensor([grid.cell_parameters((6, 2))], dtype=torch.float64)
        sharp = alternatives.soft_catch(at, torch.as_tensor(caught), 0.1)
        self.assertAlmostEqual(float(sharp[0]), 1.0, places=9)
        self.assertLess(float(alternatives.soft_catch(
            away, torch.as_tensor(caught), 1.0)[0]), 1e-5)
        # Wider smoothing spreads the cell: less than 1 at its centre.
        self.assertLess(float(alternatives.soft_catch(
            at, torch.as_tensor(caught), 1.0)[0]), 0.5)

    def test_map_training_fits_its_maps_better_than_any_one_cell(self):
        # On the maps it is trained on, the network's cells catch more
        # often than the best constant cell's (0.88 against 0.76 on the
        # seed-0 split): it fits them (whether that carries over to unseen
        # objects is what the benchmark measures).
        train_i = self.split[0]
        best = self.maps[train_i].sum(axis=0).max() / len(train_i)
        cells = alternatives.map_trained_cells(
            self.x, self.maps, (train_i, train_i, train_i), 1.0, seed=0,
            epochs=300)
        trained = np.mean([self.maps[t][c] for t, c in zip(train_i, cells)])
        self.assertGreater(trained, best + 0.03)

    def test_a_rerun_keeps_the_splits_already_written(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "alt"
            args = ["--epochs", "20", "--out", str(out)]
            with contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                self.assertEqual(self.main(["--seeds", "1", *args]), 0)
                first = out.with_suffix(".jsonl").read_text()
                self.assertEqual(self.main(["--seeds", "2", *args]), 0)
            lines = out.with_suffix(".jsonl").read_text().splitlines()
            result = json.loads(out.with_suffix(".json").read_text())
        # The seed-0 line is kept as written, seed 1 is added once.
        self.assertEqual(lines[0] + "\n", first)
        self.assertEqual([json.loads(line)["seed"] for line in lines], [0, 1])
        rates = result["predictors"]["nearest maps (k 1)"]["catch_rates"]
        self.assertEqual(rates[0], round(json.loads(lines[0])["rates"][
            "nearest maps (k 1)"], 4))
        self.assertEqual(len(rates), 2)

    def test_a_split_of_another_data_set_is_not_reused(self):
        with tempfile.TemporaryDirectory() as d:
            out = Path(d) / "alt"
            args = ["--seeds", "1", "--epochs", "20", "--out", str(out)]
            lines = out.with_suffix(".jsonl")
            with contextlib.redirect_stdout(io.StringIO()), \
                    contextlib.redirect_stderr(io.StringIO()):
                self.assertEqual(self.main(args), 0)
                row = json.loads(lines.read_text())
                # As if written on a data set since regenerated.
                lines.write_text(json.dumps(row | {"data": "0" * 16}) + "\n")
                self.assertEqual(self.main(args), 0)
            rows = [json.loads(line) for line in lines.read_text().splitlines()]
        self.assertEqual([r["seed"] for r in rows], [0, 0])
        self.assertEqual(rows[1], row)

    def test_bad_arguments_refused(self):
        self.assertRefused(["--seeds", "0"], "--seeds", "got 0")
        self.assertRefused(["--epochs", "-3"], "--epochs", "got -3")
        self.assertRefused(["--data", "/nonexistent"], "/nonexistent")


if __name__ == "__main__":
    unittest.main()
