"""studies/catch_timing/catch_timing.py: its shipped variant against the shipped maps,
and its summary on maps made up from them (no simulation)."""

import contextlib
import io
import json
import shutil
import tempfile
import unittest
from pathlib import Path

import numpy as np

from regrasp_drake.grid import read_rows
from regrasp_drake.paths import MODELS_DIR
from tests.refusals import RefusalAssertions, load_script

catch_timing = load_script("studies/catch_timing/catch_timing.py")


class CatchTimingTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(catch_timing.main)

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def test_the_shipped_variant_is_the_shipped_physics(self):
        # Its run recomputed the maps the data set and Table 1 ship.
        maps = catch_timing.load_maps(catch_timing.HERE, "shipped")
        objects = catch_timing.training_objects()
        self.assertEqual(len(objects), 19)
        self.assertEqual(sorted(maps), sorted(objects + catch_timing.TABLE1))
        with np.load(MODELS_DIR / "dataset" / "maps.npz") as d:
            shipped = dict(zip(d["objects"].tolist(), d["caught"]))
        for entry in objects:
            np.testing.assert_array_equal(maps[entry], shipped[entry], entry)
        for entry in catch_timing.TABLE1:
            rows = read_rows(MODELS_DIR / "results" / "maps" / f"{entry}.jsonl")
            self.assertEqual(int(maps[entry].sum()),
                             sum(r["outcome"] == "caught" for r in rows.values()))
            for cell, row in rows.items():
                self.assertEqual(bool(maps[entry][cell]),
                                 row["outcome"] == "caught", (entry, cell))

    def test_summary_counts_agreement_and_time(self):
        here = self.root / "catch_timing"
        shutil.copytree(catch_timing.HERE / "shipped", here / "shipped")
        variant = here / "return_0.6s"
        variant.mkdir()
        with np.load(here / "shipped" / "maps.npz") as d:
            names, caught = d["objects"], d["caught"].copy()
        objects = catch_timing.training_objects()
        k = names.tolist().index(objects[0])
        caught[k, 0, :3] = ~caught[k, 0, :3]  # three cells flipped
        np.savez_compressed(variant / "maps.npz", objects=names, caught=caught)
        provenance = json.loads((here / "shipped" / "provenance.json").read_text())
        first = provenance["runs"][0]
        runs = [first | {"wall_s": 2 * first["wall_s"]}]
        (variant / "provenance.json").write_text(
            json.dumps(provenance | {"runs": runs}))
        result = catch_timing.summarize(objects, here)
        self.assertEqual(set(result), {"shipped", "return_0.6s", "every_variant"})
        every = result["every_variant"]
        self.assertEqual(every["variants"], ["shipped", "return_0.6s"])
        # The three flipped cells catch in one variant: neither every nor none.
        self.assertEqual(every["training_cells_catching_in_every_variant"]
                         + every["training_cells_catching_in_none"], 19 * 150 - 3)
        self.assertEqual(every["table1"]["table1-row4"]
                         ["variants_in_which_the_network_cell_catches"], 0)
        ship, var = result["shipped"]["training"], result["return_0.6s"]["training"]
        self.assertEqual(ship["cells_agreeing_with_shipped"], 19 * 150)
        self.assertEqual(var["cells_agreeing_with_shipped"], 19 * 150 - 3)
        self.assertEqual(result["return_0.6s"]["wall_vs_shipped"], 2.0)
        # A map agrees with itself by chance p^2 + (1 - p)^2 of its cells.
        with np.load(MODELS_DIR / "dataset" / "maps.npz") as d:
            shipped = dict(zip(d["objects"].tolist(), d["caught"]))
        p = [shipped[e].mean() for e in objects]
        self.assertEqual(ship["agreement_by_chance"],
                         round(sum(150 * (q * q + (1 - q) ** 2) for q in p)))
        row4 = result["shipped"]["table1"]["table1-row4"]
        self.assertEqual((row4["catching_cells"], row4["throws"]), (35, 51))
        self.assertFalse(row4["network_cell_catches"])

    def test_bad_input_is_refused(self):
        self.assertRefused(["--workers", "0"], "--workers", "0")
        # --run would recompute into stored results (here a copy): refused.
        stored = self.root / "stored"
        shutil.copytree(catch_timing.HERE / "shipped", stored / "shipped")
        self.assertRefused(["--run", "--dir", str(stored), "--out",
                            str(self.root / "r.json")], "--dir", "stored results")
        self.assertRefused(["--dir", str(self.root / "none")], "no stored maps")
        out = self.root / "no_dir" / "x.json"
        self.assertRefused(["--out", str(out)], "--out")

    def test_a_corrupt_stored_file_is_refused(self):
        here = self.root / "corrupt"
        shutil.copytree(catch_timing.HERE / "shipped", here / "shipped")
        argv = ["--dir", str(here), "--out", str(self.root / "c.json")]
        (here / "shipped" / "maps.npz").write_bytes(b"not a zip file")
        self.assertRefused(argv, "maps.npz", "unreadable")
        shutil.copy(catch_timing.HERE / "shipped" / "maps.npz", here / "shipped")
        (here / "shipped" / "provenance.json").write_text("{}")
        self.assertRefused(argv, "provenance.json", "runs")

    def test_summary_writes_json_and_png(self):
        out = self.root / "summary.json"
        with contextlib.redirect_stdout(io.StringIO()):
            self.assertEqual(self.main(["--out", str(out)]), 0)
        self.assertIn("shipped", json.loads(out.read_text()))
        self.assertGreater(out.with_suffix(".png").stat().st_size, 0)


if __name__ == "__main__":
    unittest.main()
