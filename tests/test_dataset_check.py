"""benchmarks/dataset_check.py: a data set generated again against the
shipped one (no simulation: the shipped set against copies of itself)."""

import contextlib
import io
import json
import shutil
import tempfile
import unittest
from pathlib import Path

from regrasp_drake.paths import MODELS_DIR
from tests.refusals import RefusalAssertions, load_script

dataset_check = load_script("benchmarks/dataset_check.py")
SHIPPED = MODELS_DIR / "dataset"


class DatasetCheckTest(RefusalAssertions, unittest.TestCase):
    main = staticmethod(dataset_check.main)

    @classmethod
    def setUpClass(cls):
        cls.tmp = tempfile.TemporaryDirectory()
        cls.root = Path(cls.tmp.name)
        cls.copy = cls.root / "copy"
        shutil.copytree(SHIPPED, cls.copy)

    @classmethod
    def tearDownClass(cls):
        cls.tmp.cleanup()

    def _run(self, generated, out):
        with contextlib.redirect_stdout(io.StringIO()):
            code = self.main([str(generated), "--out", str(out)])
        return code, json.loads(out.read_text())

    def test_a_copy_is_identical_and_its_runs_are_reported(self):
        code, result = self._run(self.copy, self.root / "same.json")
        self.assertEqual(code, 0)
        self.assertTrue(result["identical"])
        self.assertEqual(result["entries"], 48)
        self.assertEqual(result["cells_compared"], 7200)
        provenance = json.loads((SHIPPED / "provenance.json").read_text())
        self.assertEqual(result["runs"], provenance["runs"])

    def test_one_changed_cell_is_named(self):
        changed = self.root / "changed"
        shutil.copytree(self.copy, changed)
        path = sorted((changed / "cells").glob("*.jsonl"))[0]
        lines = path.read_text().splitlines()
        row = json.loads(lines[0])
        row["outcome"] = "caught" if row["outcome"] != "caught" else "dropped"
        path.write_text("\n".join([json.dumps(row)] + lines[1:]) + "\n")
        code, result = self._run(changed, self.root / "changed.json")
        self.assertEqual(code, 1)
        self.assertFalse(result["identical"])
        self.assertEqual(result["cells_differing"], {path.stem: 1})
        self.assertEqual(result["cells_with_another_outcome"],
                         {path.stem: [str(tuple(row["cell"]))]})
        self.assertEqual(result["cells_same_outcome"], 7199)

    def test_not_a_data_set_refused(self):
        self.assertRefused([str(self.root), "--out",
                            str(self.root / "x.json")], "no provenance.json")
